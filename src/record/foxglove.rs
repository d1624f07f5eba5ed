//! Foxglove's well-known message schemas (JSON encoding), written out as JSON Schemas so the
//! recorded files open in Foxglove as they are, and one serde type per message the bench
//! writes (its writer and the readers share them). Only the fields the bench fills are
//! described; Foxglove picks its panels by the schema's name.

use base64::Engine;
use nalgebra::{Isometry3, Point3};
use serde::{Deserialize, Serialize};

/// `foxglove.Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: u64,
    /// Nanoseconds.
    pub nsec: u64,
}

impl Time {
    /// The time of a stamp in seconds (negative stamps clamp to 0).
    pub fn of(stamp_s: f64) -> Self {
        let s = stamp_s.max(0.0);
        let sec = s.floor();
        let nsec = ((s - sec) * 1e9).round().min(999_999_999.0);
        Self { sec: sec as u64, nsec: nsec as u64 }
    }
}

/// `foxglove.Vector3`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl Vector3 {
    /// The vector to a point.
    pub fn of(p: &Point3<f64>) -> Self {
        Self { x: p.x, y: p.y, z: p.z }
    }
}

/// `foxglove.Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

/// `foxglove.Pose`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

impl Pose {
    /// The pose of an isometry.
    pub fn of(p: &Isometry3<f64>) -> Self {
        let (position, orientation) = parts(p);
        Self { position, orientation }
    }
}

/// An isometry's translation and rotation.
fn parts(p: &Isometry3<f64>) -> (Vector3, Quaternion) {
    let t = p.translation.vector;
    let q = p.rotation;
    (Vector3 { x: t.x, y: t.y, z: t.z }, Quaternion { x: q.i, y: q.j, z: q.k, w: q.w })
}

/// `foxglove.Color`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Color {
    /// Red, 0-1.
    pub r: f64,
    /// Green.
    pub g: f64,
    /// Blue.
    pub b: f64,
    /// Alpha.
    pub a: f64,
}

impl Color {
    /// A colour from `[r, g, b, a]`.
    pub fn rgba(c: [f64; 4]) -> Self {
        Self { r: c[0], g: c[1], b: c[2], a: c[3] }
    }
}

/// `foxglove.LinePrimitive`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinePrimitive {
    /// 0 LINE_STRIP, 1 LINE_LOOP, 2 LINE_LIST.
    #[serde(rename = "type")]
    pub kind: u8,
    /// Origin of the points.
    pub pose: Pose,
    /// Thickness, metres.
    pub thickness: f64,
    /// Thickness in pixels instead.
    pub scale_invariant: bool,
    /// The points.
    pub points: Vec<Vector3>,
    /// The colour.
    pub color: Color,
    /// Per-point colours (unused: empty).
    pub colors: Vec<Color>,
    /// Indices into `points` (unused: empty).
    pub indices: Vec<u32>,
}

impl LinePrimitive {
    /// A closed polyline (LINE_LOOP) through `points`.
    pub fn closed(points: &[Point3<f64>], rgba: [f64; 4], thickness_m: f64) -> Self {
        Self {
            kind: 1,
            pose: Pose::of(&Isometry3::identity()),
            thickness: thickness_m,
            scale_invariant: false,
            points: points.iter().map(Vector3::of).collect(),
            color: Color::rgba(rgba),
            colors: Vec::new(),
            indices: Vec::new(),
        }
    }

    /// An open polyline (LINE_STRIP) through `points`.
    pub fn open(points: &[Point3<f64>], rgba: [f64; 4], thickness_m: f64) -> Self {
        Self { kind: 0, ..Self::closed(points, rgba, thickness_m) }
    }
}

/// `foxglove.CubePrimitive`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CubePrimitive {
    /// Centre and orientation.
    pub pose: Pose,
    /// Full sizes, metres.
    pub size: Vector3,
    /// The colour.
    pub color: Color,
}

impl CubePrimitive {
    /// A box of full sizes `size_m` at `at`.
    pub fn new(at: &Isometry3<f64>, size_m: [f64; 3], rgba: [f64; 4]) -> Self {
        Self {
            pose: Pose::of(at),
            size: Vector3 { x: size_m[0], y: size_m[1], z: size_m[2] },
            color: Color::rgba(rgba),
        }
    }
}

/// `foxglove.SceneEntity` (lines and cubes are the primitives the bench uses; the other
/// lists are always empty).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneEntity {
    /// When.
    pub timestamp: Time,
    /// Its frame.
    pub frame_id: String,
    /// Its id (a later entity with the same id replaces it).
    pub id: String,
    /// How long it lives (0: until replaced).
    pub lifetime: Time,
    /// Whether it moves with its frame.
    pub frame_locked: bool,
    /// Key-value pairs (unused).
    pub metadata: Vec<serde_json::Value>,
    /// Arrows (unused).
    pub arrows: Vec<serde_json::Value>,
    /// Boxes.
    pub cubes: Vec<CubePrimitive>,
    /// Spheres (unused).
    pub spheres: Vec<serde_json::Value>,
    /// Cylinders (unused).
    pub cylinders: Vec<serde_json::Value>,
    /// Lines.
    pub lines: Vec<LinePrimitive>,
    /// Triangles (unused).
    pub triangles: Vec<serde_json::Value>,
    /// Texts (unused).
    pub texts: Vec<serde_json::Value>,
    /// Models (unused).
    pub models: Vec<serde_json::Value>,
}

impl SceneEntity {
    /// An entity in the world frame with lines and cubes.
    pub fn new(stamp_s: f64, id: &str, lines: Vec<LinePrimitive>, cubes: Vec<CubePrimitive>) -> Self {
        Self {
            timestamp: Time::of(stamp_s),
            frame_id: "world".into(),
            id: id.into(),
            lifetime: Time { sec: 0, nsec: 0 },
            frame_locked: false,
            metadata: Vec::new(),
            arrows: Vec::new(),
            cubes,
            spheres: Vec::new(),
            cylinders: Vec::new(),
            lines,
            triangles: Vec::new(),
            texts: Vec::new(),
            models: Vec::new(),
        }
    }
}

/// `foxglove.SceneUpdate`: entities replacing those of the same id.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneUpdate {
    /// Deletions (unused).
    pub deletions: Vec<serde_json::Value>,
    /// The entities.
    pub entities: Vec<SceneEntity>,
}

impl SceneUpdate {
    /// An update replacing `entities`.
    pub fn of(entities: Vec<SceneEntity>) -> Self {
        Self { deletions: Vec::new(), entities }
    }
}

/// `foxglove.PackedElementField`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackedElementField {
    /// Name.
    pub name: String,
    /// Byte offset in a point.
    pub offset: u32,
    /// Type: 5 UINT32, 7 FLOAT32.
    #[serde(rename = "type")]
    pub kind: u8,
}

/// `foxglove.PointCloud`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointCloud {
    /// When.
    pub timestamp: Time,
    /// Its frame.
    pub frame_id: String,
    /// Origin of the points.
    pub pose: Pose,
    /// Bytes per point.
    pub point_stride: u32,
    /// The fields of a point.
    pub fields: Vec<PackedElementField>,
    /// The points, base64.
    pub data: String,
}

impl PointCloud {
    /// A cloud in the world frame: x, y, z as float32, then one uint32 field per entry of
    /// `extra` (name, one value per point).
    pub fn new(stamp_s: f64, points: &[Point3<f32>], extra: &[(&str, &[u32])]) -> Self {
        let stride = 12 + 4 * extra.len();
        let mut data = Vec::with_capacity(points.len() * stride);
        for (i, p) in points.iter().enumerate() {
            for c in [p.x, p.y, p.z] {
                data.extend_from_slice(&c.to_le_bytes());
            }
            for (_, values) in extra {
                data.extend_from_slice(&values.get(i).copied().unwrap_or(u32::MAX).to_le_bytes());
            }
        }
        let field = |name: &str, offset: usize, kind: u8| PackedElementField {
            name: name.into(),
            offset: offset as u32,
            kind,
        };
        let mut fields = vec![field("x", 0, 7), field("y", 4, 7), field("z", 8, 7)];
        for (k, (name, _)) in extra.iter().enumerate() {
            fields.push(field(name, 12 + 4 * k, 5));
        }
        Self {
            timestamp: Time::of(stamp_s),
            frame_id: "world".into(),
            pose: Pose::of(&Isometry3::identity()),
            point_stride: stride as u32,
            fields,
            data: base64::engine::general_purpose::STANDARD.encode(&data),
        }
    }

    /// The x, y, z of every point (`None` when the data does not decode).
    pub fn xyz(&self) -> Option<Vec<Point3<f32>>> {
        let stride = self.point_stride as usize;
        let data = base64::engine::general_purpose::STANDARD.decode(&self.data).ok()?;
        if stride < 12 || data.len() % stride != 0 {
            return None;
        }
        let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        Some(data.chunks_exact(stride).map(|c| Point3::new(f(&c[0..4]), f(&c[4..8]), f(&c[8..12]))).collect())
    }
}

/// `foxglove.FrameTransform`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameTransform {
    /// When.
    pub timestamp: Time,
    /// The parent frame.
    pub parent_frame_id: String,
    /// The child frame.
    pub child_frame_id: String,
    /// The child's origin in the parent.
    pub translation: Vector3,
    /// The child's orientation in the parent.
    pub rotation: Quaternion,
}

impl FrameTransform {
    /// The transform from `parent` to `child` at `stamp_s`.
    pub fn new(stamp_s: f64, parent: &str, child: &str, p: &Isometry3<f64>) -> Self {
        let (translation, rotation) = parts(p);
        Self {
            timestamp: Time::of(stamp_s),
            parent_frame_id: parent.into(),
            child_frame_id: child.into(),
            translation,
            rotation,
        }
    }
}

/// `foxglove.LaserScan` of one lidar row, with the raw reading the bench needs to rebuild
/// the row as extra fields (Foxglove ignores them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LaserScan {
    /// When the row's first beam was measured.
    pub timestamp: Time,
    /// The frame of `pose` (`lidar_mount`, the servo base).
    pub frame_id: String,
    /// The scan plane's origin and orientation in that frame (at the servo's reading).
    pub pose: Pose,
    /// First beam's angle, radians.
    pub start_angle: f64,
    /// Last beam's angle, radians.
    pub end_angle: f64,
    /// Ranges, metres (0: no return; a `null` read back is no return too).
    #[serde(deserialize_with = "nulls_as_no_return")]
    pub ranges: Vec<f32>,
    /// Intensities (empty when not measured).
    pub intensities: Vec<f32>,
    /// The row's stamp on the source's clock, seconds (exact, unlike `timestamp`).
    pub stairbench_stamp_s: f64,
    /// The servo's reading, radians.
    pub stairbench_tilt_rad: f64,
    /// The IMU's gravity direction in the mount frame.
    pub stairbench_gravity_mount: [f64; 3],
    /// The servo base's pose in the world at the row, when the head moved during the sweep
    /// ([`crate::sensor::ScanRow::mount_to_world`]); absent when it stood.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stairbench_mount_to_world: Option<super::messages::PoseMsg>,
}

/// Ranges where `null` (what JSON makes of a non-finite number) reads as 0, no return.
fn nulls_as_no_return<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<f32>, D::Error> {
    Ok(Vec::<Option<f32>>::deserialize(d)?.into_iter().map(|r| r.unwrap_or(0.0)).collect())
}

// The JSON Schemas. Shared pieces first.
const TIME: &str = r#"{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}}"#;
const VECTOR3: &str =
    r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}}"#;
const QUATERNION: &str = r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}"#;
const COLOR: &str = r#"{"type":"object","properties":{"r":{"type":"number"},"g":{"type":"number"},"b":{"type":"number"},"a":{"type":"number"}}}"#;

fn pose_schema() -> String {
    format!(r#"{{"type":"object","properties":{{"position":{VECTOR3},"orientation":{QUATERNION}}}}}"#)
}

/// `foxglove.LaserScan`.
pub fn laser_scan_schema() -> String {
    format!(
        r#"{{"title":"foxglove.LaserScan","type":"object","properties":{{"timestamp":{TIME},"frame_id":{{"type":"string"}},"pose":{},"start_angle":{{"type":"number"}},"end_angle":{{"type":"number"}},"ranges":{{"type":"array","items":{{"type":"number"}}}},"intensities":{{"type":"array","items":{{"type":"number"}}}}}}}}"#,
        pose_schema()
    )
}

/// `foxglove.PointCloud`.
pub fn point_cloud_schema() -> String {
    format!(
        r#"{{"title":"foxglove.PointCloud","type":"object","properties":{{"timestamp":{TIME},"frame_id":{{"type":"string"}},"pose":{},"point_stride":{{"type":"integer","minimum":0}},"fields":{{"type":"array","items":{{"type":"object","properties":{{"name":{{"type":"string"}},"offset":{{"type":"integer","minimum":0}},"type":{{"type":"integer"}}}}}}}},"data":{{"type":"string","contentEncoding":"base64"}}}}}}"#,
        pose_schema()
    )
}

/// `foxglove.SceneUpdate` (lines and cubes are the primitives the bench uses).
pub fn scene_update_schema() -> String {
    let line = format!(
        r#"{{"type":"object","properties":{{"type":{{"type":"integer"}},"pose":{},"thickness":{{"type":"number"}},"scale_invariant":{{"type":"boolean"}},"points":{{"type":"array","items":{VECTOR3}}},"color":{COLOR},"colors":{{"type":"array","items":{COLOR}}},"indices":{{"type":"array","items":{{"type":"integer"}}}}}}}}"#,
        pose_schema()
    );
    let cube = format!(
        r#"{{"type":"object","properties":{{"pose":{},"size":{VECTOR3},"color":{COLOR}}}}}"#,
        pose_schema()
    );
    let any = r#"{"type":"array","items":{"type":"object"}}"#;
    format!(
        r#"{{"title":"foxglove.SceneUpdate","type":"object","properties":{{"deletions":{any},"entities":{{"type":"array","items":{{"type":"object","properties":{{"timestamp":{TIME},"frame_id":{{"type":"string"}},"id":{{"type":"string"}},"lifetime":{TIME},"frame_locked":{{"type":"boolean"}},"metadata":{any},"arrows":{any},"cubes":{{"type":"array","items":{cube}}},"spheres":{any},"cylinders":{any},"lines":{{"type":"array","items":{line}}},"triangles":{any},"texts":{any},"models":{any}}}}}}}}}}}"#
    )
}

/// `foxglove.FrameTransform`.
pub fn frame_transform_schema() -> String {
    format!(
        r#"{{"title":"foxglove.FrameTransform","type":"object","properties":{{"timestamp":{TIME},"parent_frame_id":{{"type":"string"}},"child_frame_id":{{"type":"string"}},"translation":{VECTOR3},"rotation":{QUATERNION}}}}}"#
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    #[test]
    fn schemas_are_json_and_name_themselves() {
        for (s, name) in [
            (laser_scan_schema(), "foxglove.LaserScan"),
            (point_cloud_schema(), "foxglove.PointCloud"),
            (scene_update_schema(), "foxglove.SceneUpdate"),
            (frame_transform_schema(), "foxglove.FrameTransform"),
        ] {
            let v: Value = serde_json::from_str(&s).expect("valid JSON");
            assert_eq!(v["title"], name);
        }
    }

    #[test]
    fn a_point_cloud_round_trips_and_time_splits_seconds() {
        let pts = vec![Point3::new(1.0f32, -2.5, 0.25), Point3::new(0.0, 3.0, -1.0)];
        let msg = PointCloud::new(1.5, &pts, &[("label", &[7, 9])]);
        assert_eq!(msg.point_stride, 16);
        let json = serde_json::to_string(&msg).expect("serializable");
        let back: PointCloud = serde_json::from_str(&json).expect("readable");
        assert_eq!(back.xyz().expect("decodes"), pts);
        assert_eq!(Time::of(12.25), Time { sec: 12, nsec: 250_000_000 });
    }
}
