//! Foxglove's well-known message schemas (JSON encoding), written out as JSON Schemas so the
//! recorded files open in Foxglove as they are, and builders turning the bench's data into
//! them. Only the fields the bench fills are described; Foxglove picks its panels by the
//! schema's name.

use base64::Engine;
use nalgebra::{Isometry3, Point3};
use serde_json::{json, Value};

/// `foxglove.Time` of a stamp in seconds (negative stamps clamp to 0).
pub fn time(stamp_s: f64) -> Value {
    let s = stamp_s.max(0.0);
    let sec = s.floor();
    let nsec = ((s - sec) * 1e9).round().min(999_999_999.0);
    json!({ "sec": sec as u64, "nsec": nsec as u64 })
}

/// `foxglove.Vector3` of a point.
pub fn vector3(x: f64, y: f64, z: f64) -> Value {
    json!({ "x": x, "y": y, "z": z })
}

/// `foxglove.Pose` of an isometry.
pub fn pose(p: &Isometry3<f64>) -> Value {
    let [position, orientation] = parts(p);
    json!({ "position": position, "orientation": orientation })
}

/// An isometry's translation (`foxglove.Vector3`) and rotation (`foxglove.Quaternion`).
fn parts(p: &Isometry3<f64>) -> [Value; 2] {
    let t = p.translation.vector;
    let q = p.rotation;
    [vector3(t.x, t.y, t.z), json!({ "x": q.i, "y": q.j, "z": q.k, "w": q.w })]
}

/// `foxglove.Color`.
pub fn color(r: f64, g: f64, b: f64, a: f64) -> Value {
    json!({ "r": r, "g": g, "b": b, "a": a })
}

/// A closed polyline (`foxglove.LinePrimitive`, LINE_LOOP) through `points`.
pub fn line_loop(points: &[Point3<f64>], rgba: [f64; 4], thickness_m: f64) -> Value {
    json!({
        "type": 1,
        "pose": pose(&Isometry3::identity()),
        "thickness": thickness_m,
        "scale_invariant": false,
        "points": points.iter().map(|p| vector3(p.x, p.y, p.z)).collect::<Vec<_>>(),
        "color": color(rgba[0], rgba[1], rgba[2], rgba[3]),
        "colors": [],
        "indices": [],
    })
}

/// An open polyline (`foxglove.LinePrimitive`, LINE_STRIP).
pub fn line_strip(points: &[Point3<f64>], rgba: [f64; 4], thickness_m: f64) -> Value {
    let mut v = line_loop(points, rgba, thickness_m);
    v["type"] = json!(0);
    v
}

/// A box (`foxglove.CubePrimitive`) of full sizes `size_m` at `at`.
pub fn cube(at: &Isometry3<f64>, size_m: [f64; 3], rgba: [f64; 4]) -> Value {
    json!({
        "pose": pose(at),
        "size": vector3(size_m[0], size_m[1], size_m[2]),
        "color": color(rgba[0], rgba[1], rgba[2], rgba[3]),
    })
}

/// A `foxglove.SceneEntity` in the world frame with lines and cubes.
pub fn entity(stamp_s: f64, id: &str, lines: Vec<Value>, cubes: Vec<Value>) -> Value {
    json!({
        "timestamp": time(stamp_s),
        "frame_id": "world",
        "id": id,
        "lifetime": { "sec": 0, "nsec": 0 },
        "frame_locked": false,
        "metadata": [],
        "arrows": [], "cubes": cubes, "spheres": [], "cylinders": [],
        "lines": lines, "triangles": [], "texts": [], "models": [],
    })
}

/// A `foxglove.SceneUpdate` replacing the entities `entities`.
pub fn scene_update(entities: Vec<Value>) -> Value {
    json!({ "deletions": [], "entities": entities })
}

/// A `foxglove.PointCloud` in the world frame: x, y, z as float32, then one uint32 field per
/// entry of `extra` (name, one value per point).
pub fn point_cloud(stamp_s: f64, points: &[Point3<f32>], extra: &[(&str, &[u32])]) -> Value {
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
    let mut fields = vec![
        json!({ "name": "x", "offset": 0, "type": 7 }),
        json!({ "name": "y", "offset": 4, "type": 7 }),
        json!({ "name": "z", "offset": 8, "type": 7 }),
    ];
    for (k, (name, _)) in extra.iter().enumerate() {
        fields.push(json!({ "name": name, "offset": 12 + 4 * k, "type": 5 }));
    }
    json!({
        "timestamp": time(stamp_s),
        "frame_id": "world",
        "pose": pose(&Isometry3::identity()),
        "point_stride": stride,
        "fields": fields,
        "data": base64::engine::general_purpose::STANDARD.encode(&data),
    })
}

/// Decodes the x, y, z of a [`point_cloud`] message (for readers and tests).
pub fn point_cloud_xyz(msg: &Value) -> Option<Vec<Point3<f32>>> {
    let stride = msg.get("point_stride")?.as_u64()? as usize;
    let data = base64::engine::general_purpose::STANDARD.decode(msg.get("data")?.as_str()?).ok()?;
    if stride < 12 || data.len() % stride != 0 {
        return None;
    }
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    Some(data.chunks_exact(stride).map(|c| Point3::new(f(&c[0..4]), f(&c[4..8]), f(&c[8..12]))).collect())
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

/// A `foxglove.FrameTransform` from `parent` to `child`.
pub fn frame_transform(stamp_s: f64, parent: &str, child: &str, p: &Isometry3<f64>) -> Value {
    let [translation, rotation] = parts(p);
    json!({
        "timestamp": time(stamp_s),
        "parent_frame_id": parent,
        "child_frame_id": child,
        "translation": translation,
        "rotation": rotation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let msg = point_cloud(1.5, &pts, &[("label", &[7, 9])]);
        assert_eq!(msg["point_stride"], 16);
        assert_eq!(point_cloud_xyz(&msg).unwrap(), pts);
        assert_eq!(time(12.25), json!({"sec": 12, "nsec": 250_000_000}));
    }
}
