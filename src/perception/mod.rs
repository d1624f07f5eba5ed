//! The paper's plane-segment estimation (§4): normals, Filter 1 (slope), voxel grid and
//! Filter 2 (sparse voxels), supervoxel clustering, clusters and Filter 3 (smaller than a
//! foot), RANSAC planes, and the staircase's step rectangles.
//!
//! Each phase is a public function of its own module, so it can be called and timed alone;
//! [`perceive`] chains them and times each. Beside the paper's pipeline, [`Method::Cells`]
//! grows the planes on the sweep's scan grid ([`cells`]) and draws the same step rectangles
//! from them, an order of magnitude faster.

pub mod cells;
pub mod free_space;
pub mod metrics;
pub mod noise;
pub mod normals;
pub mod ransac;
pub mod ray_walk;
pub mod riser;
pub mod staircase;
pub mod step_map;
pub mod supervoxel;
pub mod surroundings;
pub mod voxel;

use crate::cloud::PointCloud;
use nalgebra::{Point3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use std::time::Instant;

pub use normals::NeighbourSearch;

/// Most neighbours of a normal (k as given, or grown with the noise).
pub const MAX_NEIGHBOURS: usize = 100;

/// How the planes are found before the staircase is drawn from them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The paper's §4: normals, Filters 1 and 2, supervoxels, clusters, RANSAC.
    Paper,
    /// Planes grown over cells of the scan grid ([`cells`]), the default: the same steps
    /// (every suite passes on it) in a tenth of the paper's time. A cloud without a scan
    /// grid (a file of points) runs the paper's pipeline, and [`Perception::method`] says so.
    #[default]
    Cells,
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Method::Paper => "paper",
            Method::Cells => "cells",
        })
    }
}

/// Parameters of the perception, with the paper's Table 1 values as defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PerceptionParams {
    /// How the planes are found: the paper's pipeline (`paper`) or cells of the scan grid
    /// (`cells`). The rest of these parameters serve both, but for the paper's phases
    /// (normals to RANSAC), which `cells` does not run.
    pub method: Method,
    /// The cell-based extraction's own parameters ([`cells`]).
    pub cells: cells::CellParams,
    /// R_seed (§4.2, Table 1: 0.1 m): spacing of the supervoxel seeds, metres.
    pub seed_resolution_m: f64,
    /// v (§4.1, Table 1: 0.02 m): edge of a voxel, metres.
    pub voxel_resolution_m: f64,
    /// T (§4.1, Table 1: 1 + cos 15 deg): Filter 1 keeps a point when D_n(n, g) = 1 - n.g
    /// is at least T, i.e. its normal is within 15 degrees of "up".
    pub normal_distance_threshold: f64,
    /// mu (§4.2 Eq. 1, Table 1: 0.2): weight of the spatial term of the distance D.
    pub distance_impact_factor: f64,
    /// n_t (§4.1 Algorithm 1, Table 1: 5): Filter 2 keeps a voxel when its adjacency size
    /// (occupied cells of its 3 x 3 x 3 block, itself included) exceeds n_t.
    pub min_adjacent_voxels: usize,
    /// k (§5: 10): neighbours in the normal estimation (`k` in a parameters file too).
    #[serde(alias = "k")]
    pub normal_neighbours: usize,
    /// How the k neighbours are found.
    pub neighbour_search: NeighbourSearch,
    /// Beyond the paper: the range noise at which k was chosen, metres. The paper's k = 10
    /// is for the UTM-30LX-EW, whose range noise is about 10 mm (its datasheet's
    /// repeatability below 10 m; the bench's default sensor noise). A sweep measured
    /// noisier ([`noise::range_noise_m`]) gets k grown in proportion
    /// ([`noise::neighbours_for`]): on k = 10 under 20 mm of noise the normals of the near,
    /// steeply seen treads are noise, Filter 1 keeps a small share of the points it keeps
    /// noise-free, and a step goes unseen (regression `step-1-never-perceived`; on the
    /// paper's Exp. 1 flight the first step from the start view in most noise draws, in
    /// none with k = 20). A cloud without scan rows (a file) keeps k.
    pub reference_noise_m: f64,
    /// Whether k grows with the sweep's measured range noise (see `reference_noise_m`);
    /// `false` runs the paper's k whatever the noise.
    pub k_grows_with_noise: bool,
    /// epsilon (§4.3: 3 cm): largest height extent of a step's plane segment, metres.
    pub max_height_extent_m: f64,
    /// Filter 3 (§4.2): clusters covering less than the robot's sole are dropped; sole
    /// length, metres (HRP-4: 0.24).
    pub foot_length_m: f64,
    /// Sole width, metres (HRP-4: 0.13).
    pub foot_width_m: f64,
    /// RANSAC (§4.3): largest distance of an inlier supervoxel centre from the plane, metres.
    pub ransac_distance_m: f64,
    /// RANSAC: most draws per plane (fewer when the adaptive count is reached).
    pub ransac_iterations: usize,
    /// RANSAC: most planes drawn.
    pub ransac_max_planes: usize,
    /// RANSAC: seed of the draws (the result is deterministic).
    pub ransac_seed: u64,
    /// §4.3: segments whose (depth, width) differ by less than this are clustered together;
    /// the biggest cluster is the staircase. Metres.
    pub shape_tolerance_m: f64,
    /// Beyond §4.3: a segment of another shape continues the flight (a top landing, a
    /// deeper first step) when it rises from the flight's end step by at most this, metres
    /// (above the 28 cm the legs climb: perception reports, the planner judges).
    pub flight_max_rise_m: f64,
    /// ... and its near edge is within this of that step's far edge along the ascent,
    /// metres (the treads of a continuous flight meet at the riser; perception leaves up to
    /// about 6 cm between them, see the gait's `max_gap_m`).
    pub flight_gap_m: f64,
    /// Beyond §4.2's Filter 3: a segment's voxels must cover at least this share of its
    /// footprint (its convex hull), or it is a few scattered voxels, not a surface: a few
    /// voxels of floor spread over a sole's footprint pass the footprint test and would join
    /// a flight as a turned step (regression `scattered-floor-voxels-joined-the-flight`). A
    /// tread seen from afar, sampled every 3-5 cm in range by a 2 cm voxel grid, covers
    /// 30 % or more.
    pub min_segment_cover: f64,
    /// Beyond §4.3: a step's rectangle leaves out the points beyond an empty row at either
    /// end (rows: strips a voxel wide, across the ascent and along it) whose rows hold less
    /// than this share of the segment's median row: they are strays apart from the tread.
    /// Under range noise the top of a riser scatters along the rays, and the returns within
    /// the tread's plane join it a few voxels a row up to 6 cm ahead of the nose, and its
    /// front so far toward the robot leaves the step below it short up to it (regression
    /// `riser-strays-moved-a-front-edge`). The sparse row next to the tread stays: a
    /// tread's own edge, cut by the voxel grid, holds any part of a row. A far tread
    /// sampled one row in two has empty rows between full ones: not sparse, kept.
    pub min_edge_row_fill: f64,
    /// Beyond §4: each step's front edge placed on the riser below it, from the whole
    /// cloud's returns there (see [`riser`]); `[perception.riser]` in a parameters file.
    pub riser: riser::RiserParams,
}

impl Default for PerceptionParams {
    fn default() -> Self {
        Self {
            method: Method::default(),
            cells: cells::CellParams::default(),
            seed_resolution_m: 0.1,
            voxel_resolution_m: 0.02,
            normal_distance_threshold: 1.0 + 15f64.to_radians().cos(),
            distance_impact_factor: 0.2,
            min_adjacent_voxels: 5,
            normal_neighbours: 10,
            neighbour_search: NeighbourSearch::Auto,
            reference_noise_m: 0.01,
            k_grows_with_noise: true,
            max_height_extent_m: 0.03,
            foot_length_m: 0.24,
            foot_width_m: 0.13,
            ransac_distance_m: 0.015,
            ransac_iterations: 500,
            ransac_max_planes: 64,
            ransac_seed: 0,
            shape_tolerance_m: 0.10,
            flight_max_rise_m: 0.30,
            flight_gap_m: 0.10,
            min_segment_cover: 0.1,
            min_edge_row_fill: 0.25,
            riser: riser::RiserParams::default(),
        }
    }
}

impl PerceptionParams {
    /// Checks the parameters; the error names the field.
    pub fn validate(&self) -> Result<(), PerceptionError> {
        let bad = |field: &str, reason: &str| {
            Err(PerceptionError::InvalidParameter { field: field.into(), reason: reason.into() })
        };
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(self.seed_resolution_m) {
            return bad("seed_resolution_m", "must be > 0");
        }
        if !pos(self.voxel_resolution_m) || self.voxel_resolution_m > self.seed_resolution_m {
            return bad("voxel_resolution_m", "must be > 0 and at most seed_resolution_m");
        }
        if !(self.normal_distance_threshold.is_finite()
            && (1.0..=2.0).contains(&self.normal_distance_threshold))
        {
            return bad("normal_distance_threshold", "must be in [1, 2] (1 + cos of the largest slope)");
        }
        if !(self.distance_impact_factor > 0.0 && self.distance_impact_factor < 1.0) {
            return bad("distance_impact_factor", "must be in (0, 1)");
        }
        if !(3..=MAX_NEIGHBOURS).contains(&self.normal_neighbours) {
            return bad("normal_neighbours", &format!("must be in [3, {MAX_NEIGHBOURS}]"));
        }
        if self.min_adjacent_voxels > 26 {
            return bad("min_adjacent_voxels", "must be at most 26 (a voxel has 26 neighbours)");
        }
        if let Some((field, reason)) = self.riser.invalid().or_else(|| self.cells.invalid()) {
            return bad(field, reason);
        }
        for (f, v) in [
            ("max_height_extent_m", self.max_height_extent_m),
            ("foot_length_m", self.foot_length_m),
            ("foot_width_m", self.foot_width_m),
            ("ransac_distance_m", self.ransac_distance_m),
            ("shape_tolerance_m", self.shape_tolerance_m),
            ("flight_max_rise_m", self.flight_max_rise_m),
            ("flight_gap_m", self.flight_gap_m),
            ("reference_noise_m", self.reference_noise_m),
        ] {
            if !pos(v) {
                return bad(f, "must be > 0");
            }
        }
        if !(self.min_segment_cover >= 0.0 && self.min_segment_cover <= 1.0) {
            return bad("min_segment_cover", "must be in [0, 1] (a share of a segment's footprint)");
        }
        if !(self.min_edge_row_fill >= 0.0 && self.min_edge_row_fill < 1.0) {
            return bad("min_edge_row_fill", "must be in [0, 1) (a share of a segment's median row)");
        }
        if self.flight_max_rise_m <= self.max_height_extent_m {
            return bad(
                "flight_max_rise_m",
                "must exceed max_height_extent_m (a rise is more than a tread's own height extent)",
            );
        }
        if self.ransac_iterations == 0 || self.ransac_max_planes == 0 {
            return bad("ransac_iterations", "ransac_iterations and ransac_max_planes must be > 0");
        }
        Ok(())
    }
}

/// Why perception gave no staircase.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PerceptionError {
    /// A parameter is out of range.
    #[error("invalid perception parameter `{field}`: {reason}")]
    InvalidParameter {
        /// The parameter.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The cloud holds no staircase the pipeline can find; the reason says where it stopped.
    #[error("no staircase found: {0}")]
    NoStaircase(NoStaircase),
}

/// Where the pipeline stopped finding a staircase, with its figures.
#[derive(Debug, Clone, PartialEq, thiserror::Error, Serialize, Deserialize)]
#[serde(tag = "stage", rename_all = "snake_case")]
pub enum NoStaircase {
    /// No points at all.
    #[error("the cloud is empty")]
    EmptyCloud,
    /// Filters 1 and 2 left nothing.
    #[error("no near-horizontal surface: {after_filter1} of {points} points passed the slope filter, {after_filter2} voxels the sparse filter")]
    NoHorizontalSurface {
        /// Points in.
        points: usize,
        /// Points after Filter 1.
        after_filter1: usize,
        /// Voxels after Filter 2.
        after_filter2: usize,
    },
    /// No plane's foot-sized cluster is flat within epsilon.
    #[error("no flat segment: {planes} planes, none within epsilon = {epsilon_m} m in height over a foot-sized cluster")]
    NoFlatSegment {
        /// Planes RANSAC drew.
        planes: usize,
        /// The height extent allowed (Table 1's epsilon), metres.
        epsilon_m: f64,
    },
    /// Every flat segment is at or below the ground's height.
    #[error(
        "only the ground: {segments} flat segment(s), all at or below the ground's height {ground_m:.3} m"
    )]
    OnlyGround {
        /// Flat segments found.
        segments: usize,
        /// The ground's height, metres.
        ground_m: f64,
    },
}

/// Where a step's front edge was measured, by how much it is believed (least first).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord)]
pub enum FrontMark {
    /// From the tread's voxels or cells.
    #[default]
    Voxels,
    /// On the tread's own face, no riser seen whole under it (an open riser's slab;
    /// [`riser`]): the nose, measured, with nothing known to stand under it.
    Face,
    /// On the riser below it (or the nose before it, where a nosing was seen; [`riser`]).
    Riser,
}

/// One step of the staircase: a rectangle in the world frame. Valid once built: four
/// finite corners forming a rectangle, counter-clockwise seen from above. Read back from JSON
/// (a recording), it is checked again and keeps its figures bit for bit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "PlaneSegmentData", into = "PlaneSegmentData")]
pub struct PlaneSegment {
    corners: [Point3<f64>; 4],
    normal: Vector3<f64>,
    height_m: f64,
    voxel_count: usize,
    front: FrontMark,
    nosing_m: f64,
    back_on_riser: bool,
}

/// A [`PlaneSegment`]'s fields as written (the front's mark as two flags, as recordings
/// have it), before they are checked.
#[derive(Clone, Serialize, Deserialize)]
struct PlaneSegmentData {
    corners: [Point3<f64>; 4],
    normal: Vector3<f64>,
    height_m: f64,
    voxel_count: usize,
    /// Absent from recordings made before fronts were placed on risers.
    #[serde(default)]
    front_on_riser: bool,
    /// Absent from recordings made before fronts were placed on faces.
    #[serde(default)]
    front_on_face: bool,
    /// Absent from recordings made before a nosing's projection was kept.
    #[serde(default)]
    nosing_m: f64,
    /// Absent from recordings made before backs were placed on risers.
    #[serde(default)]
    back_on_riser: bool,
}

impl TryFrom<PlaneSegmentData> for PlaneSegment {
    type Error = String;

    fn try_from(d: PlaneSegmentData) -> Result<Self, String> {
        let finite = d.corners.iter().all(|c| c.coords.iter().all(|v| v.is_finite()))
            && d.normal.iter().all(|v| v.is_finite())
            && d.height_m.is_finite()
            && d.nosing_m.is_finite();
        if !finite {
            return Err("a step rectangle has a non-finite figure".into());
        }
        let [a, b, _, e] = d.corners;
        let (along, across) = (b - a, e - a);
        let (depth, width) = (along.norm(), across.norm());
        // Opposite corners meet, edges are at right angles, the turn is counter-clockwise.
        let closes = (d.corners[2] - (b + across)).norm() <= 1e-9 * (1.0 + depth + width);
        let square = along.dot(&across).abs() <= 1e-9 * depth * width;
        let ccw = along.x * across.y - along.y * across.x > 0.0;
        if depth <= 0.0 || width <= 0.0 || !closes || !square || !ccw || d.normal.norm() < 1e-9 {
            return Err("a step rectangle's corners are not a counter-clockwise rectangle".into());
        }
        let front = match (d.front_on_riser, d.front_on_face) {
            (true, false) => FrontMark::Riser,
            (false, true) => FrontMark::Face,
            (false, false) => FrontMark::Voxels,
            (true, true) => return Err("a step's front is marked both on its riser and on its face".into()),
        };
        Ok(Self {
            corners: d.corners,
            normal: d.normal,
            height_m: d.height_m,
            voxel_count: d.voxel_count,
            front,
            nosing_m: d.nosing_m,
            back_on_riser: d.back_on_riser,
        })
    }
}

impl From<PlaneSegment> for PlaneSegmentData {
    fn from(s: PlaneSegment) -> Self {
        Self {
            corners: s.corners,
            normal: s.normal,
            height_m: s.height_m,
            voxel_count: s.voxel_count,
            front_on_riser: s.front == FrontMark::Riser,
            front_on_face: s.front == FrontMark::Face,
            nosing_m: s.nosing_m,
            back_on_riser: s.back_on_riser,
        }
    }
}

impl PlaneSegment {
    /// A rectangle from its centre, its unit axis `along` (horizontal, direction of ascent),
    /// its depth along that axis and width across it, and the plane's normal. `None` for
    /// non-finite or non-positive sizes.
    pub fn new(
        center: Point3<f64>,
        along: Vector3<f64>,
        depth_m: f64,
        width_m: f64,
        normal: Vector3<f64>,
        voxel_count: usize,
    ) -> Option<Self> {
        let along = Vector3::new(along.x, along.y, 0.0).try_normalize(1e-9)?;
        let normal = normal.try_normalize(1e-9)?;
        let ok = center.coords.iter().all(|v| v.is_finite()) && depth_m > 0.0 && width_m > 0.0;
        if !ok || !depth_m.is_finite() || !width_m.is_finite() {
            return None;
        }
        let left = Vector3::new(-along.y, along.x, 0.0);
        let (a, b) = (along * depth_m / 2.0, left * width_m / 2.0);
        let corners = [center - a - b, center + a - b, center + a + b, center - a + b];
        Some(Self {
            corners,
            normal,
            height_m: center.z,
            voxel_count,
            front: FrontMark::Voxels,
            nosing_m: 0.0,
            back_on_riser: false,
        })
    }

    /// Corners counter-clockwise seen from above: front-right, back-right, back-left,
    /// front-left (front = the nose, toward the robot).
    pub fn corners(&self) -> &[Point3<f64>; 4] {
        &self.corners
    }

    /// Centre of the rectangle.
    pub fn center(&self) -> Point3<f64> {
        Point3::from(self.corners.iter().map(|c| c.coords).sum::<Vector3<f64>>() / 4.0)
    }

    /// Unit normal of the fitted plane (up).
    pub fn normal(&self) -> Unit<Vector3<f64>> {
        Unit::new_normalize(self.normal)
    }

    /// Height of the tread, metres.
    pub fn height_m(&self) -> f64 {
        self.height_m
    }

    /// Depth along the direction of ascent, metres.
    pub fn depth_m(&self) -> f64 {
        (self.corners[1] - self.corners[0]).norm()
    }

    /// Width across the direction of ascent, metres.
    pub fn width_m(&self) -> f64 {
        (self.corners[3] - self.corners[0]).norm()
    }

    /// Area of the rectangle, square metres.
    pub fn area_m2(&self) -> f64 {
        self.depth_m() * self.width_m()
    }

    /// Unit direction of ascent (horizontal).
    pub fn along(&self) -> Vector3<f64> {
        (self.corners[1] - self.corners[0]).normalize()
    }

    /// Voxels the segment was estimated from (Eq. 3's n_i).
    pub fn voxel_count(&self) -> usize {
        self.voxel_count
    }

    /// Whether the front edge (corners 0 and 3) was placed on the riser below it
    /// ([`riser`]) rather than taken from the tread's voxels.
    pub fn front_on_riser(&self) -> bool {
        self.front == FrontMark::Riser
    }

    /// Where the front edge was measured.
    pub fn front_mark(&self) -> FrontMark {
        self.front
    }

    /// Whether the front edge was placed on the tread's own face, no riser seen whole under
    /// it (an open riser's slab; [`riser`]): the nose, measured, with nothing known to stand
    /// under it.
    pub fn front_on_face(&self) -> bool {
        self.front == FrontMark::Face
    }

    /// Whether the front edge was measured on the nose (on its riser, or on its face) rather
    /// than taken from the tread's voxels or cells.
    pub fn front_measured(&self) -> bool {
        self.front != FrontMark::Voxels
    }

    /// Whether the back edge (corners 1 and 2) was placed on the riser above it
    /// ([`riser::place_edges`]) rather than taken from the tread's voxels or cells.
    pub fn back_on_riser(&self) -> bool {
        self.back_on_riser
    }

    /// How far the front edge, placed on a nose, stands past the riser below it, metres (0
    /// for a front on its riser or from voxels): the riser is `nosing_m` up the ascent from
    /// the front. Views see a nosing's nose differently (from afar its top's returns spread
    /// along the tread), its riser alike.
    pub fn nosing_m(&self) -> f64 {
        self.nosing_m
    }

    /// Where the riser under the front edge is along `along` (a unit horizontal direction
    /// near the ascent): the front edge's middle, moved up the ascent by the nosing.
    pub fn riser_along(&self, along: &Vector3<f64>) -> f64 {
        (self.center() - self.along() * (self.depth_m() / 2.0 - self.nosing_m)).coords.dot(along)
    }

    /// A level tread 1 m wide ascending along x, its nose at `front_m`, its top at `z_m`
    /// (for tests).
    #[cfg(test)]
    pub(crate) fn level_along_x(front_m: f64, z_m: f64, depth_m: f64) -> Self {
        Self::new(
            Point3::new(front_m + depth_m / 2.0, 0.0, z_m),
            Vector3::x(),
            depth_m,
            1.0,
            Vector3::z(),
            100,
        )
        .expect("valid rectangle")
    }

    /// The same rectangle moved by `offset` (a view's frame corrected).
    pub fn moved(self, offset: &Vector3<f64>) -> Self {
        self.transformed(&nalgebra::Translation3::from(*offset).into())
    }

    /// The same rectangle moved rigidly by `pose` (a view's frame corrected).
    pub fn transformed(mut self, pose: &nalgebra::Isometry3<f64>) -> Self {
        for c in &mut self.corners {
            *c = pose * *c;
        }
        self.normal = pose.rotation * self.normal;
        self.height_m = self.corners.iter().map(|c| c.z).sum::<f64>() / 4.0;
        self
    }

    /// The same rectangle, its front edge marked as measured there.
    pub fn with_front(mut self, mark: FrontMark) -> Self {
        self.front = mark;
        self
    }

    /// The same rectangle, its back edge marked as placed on the riser above it (or not).
    pub fn with_back_on_riser(mut self, on: bool) -> Self {
        self.back_on_riser = on;
        self
    }

    /// The same rectangle, its front edge `nosing_m` past the riser below it (a nose).
    pub fn with_nosing_m(mut self, nosing_m: f64) -> Self {
        self.nosing_m = nosing_m;
        self
    }
}

/// Wall time of each phase (its names in records and JSON without the unit).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PhaseTimings {
    /// Normal estimation (with the measure of the sweep's range noise).
    #[serde(rename = "normals")]
    pub normals_ms: f64,
    /// Filter 1 (slope).
    #[serde(rename = "filter1")]
    pub filter1_ms: f64,
    /// Voxel grid and Filter 2.
    #[serde(rename = "voxels")]
    pub voxels_ms: f64,
    /// Supervoxel clustering.
    #[serde(rename = "supervoxels")]
    pub supervoxels_ms: f64,
    /// Clustering of supervoxels and Filter 3.
    #[serde(rename = "clusters")]
    pub clusters_ms: f64,
    /// RANSAC planes.
    #[serde(rename = "ransac")]
    pub ransac_ms: f64,
    /// Staircase extraction and rectangles (their fronts on the risers included).
    #[serde(rename = "staircase")]
    pub staircase_ms: f64,
    /// [`Method::Cells`]: the sweep's noise measured, the cells' planes fitted.
    #[serde(rename = "cells", default)]
    pub cells_ms: f64,
    /// [`Method::Cells`]: regions grown, points given to them, columns binned.
    #[serde(rename = "regions", default)]
    pub regions_ms: f64,
    /// Sum of the phases.
    #[serde(rename = "total")]
    pub total_ms: f64,
}

impl PhaseTimings {
    /// The phases' times added up, milliseconds.
    pub fn sum(&self) -> f64 {
        self.normals_ms
            + self.filter1_ms
            + self.voxels_ms
            + self.supervoxels_ms
            + self.clusters_ms
            + self.ransac_ms
            + self.staircase_ms
            + self.cells_ms
            + self.regions_ms
    }
}

/// Sizes of the intermediate results.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Counts {
    /// Points in.
    pub points: usize,
    /// Points after Filter 1.
    pub after_filter1: usize,
    /// Voxels before Filter 2.
    pub voxels: usize,
    /// Voxels after Filter 2.
    pub after_filter2: usize,
    /// Supervoxels.
    pub supervoxels: usize,
    /// Attachment passes of the supervoxel clustering.
    pub supervoxel_passes: usize,
    /// Clusters of supervoxels before Filter 3.
    pub clusters: usize,
    /// Clusters kept by Filter 3.
    pub after_filter3: usize,
    /// Planes drawn by RANSAC.
    pub planes: usize,
    /// Plane segments before the staircase is chosen.
    pub segments: usize,
    /// The sweep's range noise as measured on it, millimetres (none for a cloud without
    /// scan rows).
    #[serde(default)]
    pub range_noise_mm: Option<f64>,
    /// The neighbours the normals were estimated on (k, grown with the noise).
    #[serde(default)]
    pub normal_neighbours: usize,
    /// Steps whose front edge was placed on the riser below it ([`riser`]).
    #[serde(default)]
    pub riser_fronts: usize,
    /// Steps whose front edge was placed on the tread's own face, no riser seen under it.
    #[serde(default)]
    pub face_fronts: usize,
    /// Steps whose back edge was placed on the riser above it ([`riser::place_edges`]).
    #[serde(default)]
    pub riser_backs: usize,
    /// [`Method::Cells`]: cells with enough points to fit.
    #[serde(default)]
    pub cells: usize,
    /// [`Method::Cells`]: cells that are level planes.
    #[serde(default)]
    pub level_cells: usize,
}

/// The intermediate results, for views and logs.
#[derive(Debug, Clone, Default)]
pub struct Detail {
    /// Voxels after Filter 2.
    pub voxels: voxel::VoxelCloud,
    /// Supervoxels of those voxels.
    pub supervoxels: supervoxel::Supervoxels,
    /// Clusters and Filter 3.
    pub clusters: supervoxel::Clusters,
}

/// What perception found.
#[derive(Debug, Clone)]
pub struct Perception {
    /// The method that ran (the paper's for a cloud without a scan grid, whatever asked).
    pub method: Method,
    /// The staircase's steps, nearest (lowest) first.
    pub segments: Vec<PlaneSegment>,
    /// Height of the ground, metres: the segment under the sensor (the floor, or the tread
    /// the robot stands on), else the lowest.
    pub ground_m: f64,
    /// Time per phase.
    pub timings: PhaseTimings,
    /// Sizes of the intermediate results.
    pub counts: Counts,
    /// The intermediate results.
    pub detail: Detail,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Filter 1 (Algorithm 1, lines 2-8): indices of the points whose normal n satisfies
/// D_n(n, g) = 1 - n.g >= T, g being the unit gravity vector.
pub fn filter_slope(normals: &[[f32; 3]], gravity: &Unit<Vector3<f64>>, threshold: f64) -> Vec<u32> {
    let g = gravity.into_inner().cast::<f32>();
    let t = threshold as f32;
    (0..normals.len() as u32)
        .filter(|&i| {
            let n = Vector3::from(normals[i as usize]);
            1.0 - n.dot(&g) >= t // false for NaN (no normal)
        })
        .collect()
}

/// The whole pipeline on a point cloud, by `p.method`.
pub fn perceive(cloud: &PointCloud, p: &PerceptionParams) -> Result<Perception, PerceptionError> {
    p.validate()?;
    let (counts, noise_m, noise_ms) = noise_of(cloud, || noise::range_noise_m(cloud))?;
    let found = match p.method {
        Method::Cells if cloud.grid().is_some() => {
            by_cells(cloud, noise_m, noise_ms, p, counts, |s| cells::extract(cloud, s))?
        }
        Method::Paper | Method::Cells => by_paper(cloud, noise_m, noise_ms, p, counts)?,
    };
    Ok(on_risers(found, cloud, noise_m, p))
}

/// `run` made `repeat` times (at least once), one result alive at a time, as in a loop that
/// perceives sweep after sweep and keeps the last (runs kept side by side would each take
/// fresh memory, and time its first touch): the last result with the timings of the
/// median run by total time. Perception is deterministic, so every run finds the same
/// steps; the first error ends the runs.
pub fn median_timed<E>(
    repeat: usize,
    mut run: impl FnMut() -> Result<Perception, E>,
) -> Result<Perception, E> {
    let mut timings = Vec::with_capacity(repeat.max(1));
    let mut last = run()?;
    timings.push(last.timings.clone());
    for _ in 1..repeat {
        drop(last);
        last = run()?;
        timings.push(last.timings.clone());
    }
    timings.sort_by(|a, b| a.total_ms.total_cmp(&b.total_ms));
    last.timings = timings.swap_remove(timings.len() / 2);
    Ok(last)
}

/// Perception of a sweep whose rows arrive one after another (a tilting lidar's, a row every
/// 25 ms), by the cell method: the work that needs only the rows in (each row's range
/// differences for the noise, each row of cells' sums) is done as they arrive, and the rest
/// once the last is in ([`PerceptionStream::finish`]). It gives exactly what [`perceive`]
/// gives on the whole sweep. With the paper's method, or a cloud without a scan grid,
/// everything waits for the end.
#[derive(Debug, Clone)]
pub struct PerceptionStream {
    p: PerceptionParams,
    /// Both `None` where nothing is streamed.
    noise: Option<noise::Stream>,
    cells: Option<cells::Stream>,
}

impl PerceptionStream {
    /// A stream over `cloud`'s sweep, none of its rows yet arrived.
    pub fn new(cloud: &PointCloud, p: &PerceptionParams) -> Result<Self, PerceptionError> {
        p.validate()?;
        let streamed = p.method == Method::Cells;
        Ok(Self {
            p: p.clone(),
            noise: noise::Stream::new(cloud).filter(|_| streamed),
            cells: cells::Stream::new(cloud).filter(|_| streamed),
        })
    }

    /// `cloud`'s first `rows` scan rows (the cloud given to `new`) have arrived; the rows
    /// after them are not read.
    pub fn arrived(&mut self, cloud: &PointCloud, rows: usize) {
        if let (Some(noise), Some(cells)) = (&mut self.noise, &mut self.cells) {
            noise.arrived(cloud, rows);
            cells.arrived(cloud, rows, &self.p.cells);
        }
    }

    /// The perception of the whole sweep, once its last row has arrived.
    pub fn finish(self, cloud: &PointCloud) -> Result<Perception, PerceptionError> {
        let (Some(noise), Some(cells)) = (self.noise, self.cells) else {
            return perceive(cloud, &self.p);
        };
        let p = &self.p;
        let (counts, noise_m, noise_ms) = noise_of(cloud, || noise.finish(cloud))?;
        let found = by_cells(cloud, noise_m, noise_ms, p, counts, |s| cells.finish(cloud, s))?;
        Ok(on_risers(found, cloud, noise_m, p))
    }
}

/// The counts a perception of `cloud` starts from, with the sweep's range noise from
/// `noise` and the milliseconds it took; an empty cloud is refused.
fn noise_of(
    cloud: &PointCloud,
    noise: impl FnOnce() -> Option<f64>,
) -> Result<(Counts, Option<f64>, f64), PerceptionError> {
    if cloud.is_empty() {
        return Err(PerceptionError::NoStaircase(NoStaircase::EmptyCloud));
    }
    let t = Instant::now();
    let noise_m = noise();
    let noise_ms = ms(t);
    let counts =
        Counts { points: cloud.len(), range_noise_mm: noise_m.map(|s| s * 1e3), ..Default::default() };
    Ok((counts, noise_m, noise_ms))
}

/// `found`'s steps with their fronts and backs placed on the risers of `cloud`.
fn on_risers(
    mut found: Perception,
    cloud: &PointCloud,
    noise_m: Option<f64>,
    p: &PerceptionParams,
) -> Perception {
    let t = Instant::now();
    let placed = riser::place_edges(
        &mut found.segments,
        cloud.points(),
        &cloud.sensor_at_end(),
        Some(found.ground_m),
        noise_m,
        &p.riser,
    );
    found.counts.riser_fronts = placed.riser_fronts;
    found.counts.face_fronts = placed.face_fronts;
    found.counts.riser_backs = placed.riser_backs;
    let riser_ms = ms(t);
    found.timings.staircase_ms += riser_ms;
    found.timings.total_ms += riser_ms;
    found
}

/// The paper's pipeline (§4) up to the steps, their fronts not yet on the risers.
fn by_paper(
    cloud: &PointCloud,
    noise_m: Option<f64>,
    noise_ms: f64,
    p: &PerceptionParams,
    mut counts: Counts,
) -> Result<Perception, PerceptionError> {
    let mut timings = PhaseTimings::default();
    let t = Instant::now();
    let k = if p.k_grows_with_noise {
        noise::neighbours_for(p.normal_neighbours, noise_m, p.reference_noise_m, MAX_NEIGHBOURS)
    } else {
        p.normal_neighbours
    };
    counts.normal_neighbours = k;
    let normals = normals::estimate(cloud, k, p.neighbour_search);
    timings.normals_ms = noise_ms + ms(t);

    let t = Instant::now();
    let kept = filter_slope(&normals, &cloud.gravity(), p.normal_distance_threshold);
    timings.filter1_ms = ms(t);
    counts.after_filter1 = kept.len();

    let t = Instant::now();
    let all = voxel::voxelize(cloud.points(), &normals, &kept, p.voxel_resolution_m as f32, None);
    counts.voxels = all.len();
    let voxels = voxel::filter_sparse(&all, p.min_adjacent_voxels);
    timings.voxels_ms = ms(t);
    counts.after_filter2 = voxels.len();
    from_voxels(voxels, cloud.sensor_at_end(), cloud.gravity(), p, timings, counts)
}

/// The planes grown on the scan grid ([`cells`]) up to the steps, their fronts not yet on
/// the risers: `regions` (the whole sweep's, or a stream's) in their setting. A sweep whose
/// noise could not be measured is taken at the reference noise.
fn by_cells(
    cloud: &PointCloud,
    noise_m: Option<f64>,
    noise_ms: f64,
    p: &PerceptionParams,
    mut counts: Counts,
    regions: impl FnOnce(&cells::Setting) -> Option<cells::Regions>,
) -> Result<Perception, PerceptionError> {
    let setting = cells::Setting {
        voxel_m: p.voxel_resolution_m,
        cos_slope: p.normal_distance_threshold - 1.0,
        noise_m: noise_m.unwrap_or(p.reference_noise_m),
        params: &p.cells,
    };
    let Some(found) = regions(&setting) else {
        return by_paper(cloud, noise_m, noise_ms, p, counts);
    };
    let mut timings = PhaseTimings {
        cells_ms: noise_ms + found.cells_ms,
        regions_ms: found.regions_ms,
        ..Default::default()
    };
    counts.cells = found.cells;
    counts.level_cells = found.level_cells;
    counts.after_filter1 = found.points_in_regions;
    counts.voxels = found.voxels.len();
    counts.after_filter2 = found.voxels.len();
    counts.planes = found.surfaces.len();
    if found.voxels.is_empty() {
        return Err(PerceptionError::NoStaircase(NoStaircase::NoHorizontalSurface {
            points: counts.points,
            after_filter1: counts.after_filter1,
            after_filter2: counts.after_filter2,
        }));
    }
    let t = Instant::now();
    let (sensor, gravity) = (cloud.sensor_at_end(), cloud.gravity());
    let result = staircase::from_surfaces(&found.voxels, found.surfaces, counts.planes, &sensor, &gravity, p);
    timings.staircase_ms = ms(t);
    let detail = Detail { voxels: found.voxels, ..Default::default() };
    finish(Method::Cells, result, timings, counts, detail)
}

/// The perception of `method` from the staircase's `result`, the phases' times totalled.
fn finish(
    method: Method,
    result: Result<(Vec<PlaneSegment>, usize, f64), PerceptionError>,
    mut timings: PhaseTimings,
    mut counts: Counts,
    detail: Detail,
) -> Result<Perception, PerceptionError> {
    timings.total_ms = timings.sum();
    let (segments, n_segments, ground_m) = result?;
    counts.segments = n_segments;
    Ok(Perception { method, segments, ground_m, timings, counts, detail })
}

/// The pipeline from voxel representatives that already passed Filters 1 and 2 (such as the
/// paper's `voxels.txt`): normals by kNN on them, voxels at resolution v, no filter repeated.
/// Where kNN gives no normal (points along one scan line are collinear), the voxel takes
/// "up", which Filter 1 already established for every point of such a file.
pub fn perceive_voxels(cloud: &PointCloud, p: &PerceptionParams) -> Result<Perception, PerceptionError> {
    p.validate()?;
    let mut timings = PhaseTimings::default();
    let mut counts = Counts {
        points: cloud.len(),
        after_filter1: cloud.len(),
        normal_neighbours: p.normal_neighbours,
        ..Default::default()
    };
    if cloud.is_empty() {
        return Err(PerceptionError::NoStaircase(NoStaircase::EmptyCloud));
    }
    let t = Instant::now();
    let normals = normals::by_kdtree(cloud.points(), p.normal_neighbours, cloud.viewpoint().cast());
    timings.normals_ms = ms(t);
    let t = Instant::now();
    let all: Vec<u32> = (0..cloud.len() as u32).collect();
    let up = -cloud.gravity().into_inner().cast::<f32>();
    let voxels = voxel::voxelize(cloud.points(), &normals, &all, p.voxel_resolution_m as f32, Some(up));
    timings.voxels_ms = ms(t);
    counts.voxels = voxels.len();
    counts.after_filter2 = voxels.len();
    from_voxels(voxels, cloud.sensor_at_end(), cloud.gravity(), p, timings, counts)
}

fn from_voxels(
    voxels: voxel::VoxelCloud,
    sensor: Point3<f64>,
    gravity: Unit<Vector3<f64>>,
    p: &PerceptionParams,
    mut timings: PhaseTimings,
    mut counts: Counts,
) -> Result<Perception, PerceptionError> {
    if voxels.is_empty() {
        return Err(PerceptionError::NoStaircase(NoStaircase::NoHorizontalSurface {
            points: counts.points,
            after_filter1: counts.after_filter1,
            after_filter2: counts.after_filter2,
        }));
    }
    let t = Instant::now();
    let sv = supervoxel::supervoxels(&voxels, p);
    timings.supervoxels_ms = ms(t);
    counts.supervoxels = sv.centres.len();
    counts.supervoxel_passes = sv.rounds;

    let t = Instant::now();
    let clusters = supervoxel::cluster(&voxels, &sv, p);
    timings.clusters_ms = ms(t);
    counts.clusters = clusters.before_filter;
    counts.after_filter3 = clusters.voxel_counts.len();

    let t = Instant::now();
    let candidates: Vec<u32> = (0..sv.centres.len() as u32)
        .filter(|&l| clusters.of_supervoxel[l as usize] != supervoxel::UNLABELLED)
        .collect();
    let planes = ransac::planes(&sv.centres, &candidates, &gravity, p);
    timings.ransac_ms = ms(t);
    counts.planes = planes.len();

    let t = Instant::now();
    let result = staircase::extract(&voxels, &sv, &clusters, &planes, &sensor, &gravity, p);
    timings.staircase_ms = ms(t);
    finish(Method::Paper, result, timings, counts, Detail { voxels, supervoxels: sv, clusters })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step's front mark is written as the two flags recordings have, and read back the
    /// same; a recording from before the marks reads as voxels; both flags at once is no
    /// front a perception gives, and is refused.
    #[test]
    fn a_fronts_mark_reads_back_as_written() {
        for mark in [FrontMark::Voxels, FrontMark::Face, FrontMark::Riser] {
            let s = PlaneSegment::level_along_x(1.0, 0.2, 0.28).with_front(mark);
            let json = serde_json::to_value(&s).unwrap();
            assert_eq!(json["front_on_riser"], mark == FrontMark::Riser);
            assert_eq!(json["front_on_face"], mark == FrontMark::Face);
            assert_eq!(serde_json::from_value::<PlaneSegment>(json).unwrap(), s);
        }
        let mut json = serde_json::to_value(PlaneSegment::level_along_x(1.0, 0.2, 0.28)).unwrap();
        let fields = json.as_object_mut().unwrap();
        fields.remove("front_on_riser");
        fields.remove("front_on_face");
        assert_eq!(
            serde_json::from_value::<PlaneSegment>(json.clone()).unwrap().front_mark(),
            FrontMark::Voxels
        );
        json["front_on_riser"] = true.into();
        json["front_on_face"] = true.into();
        let err = serde_json::from_value::<PlaneSegment>(json).unwrap_err().to_string();
        assert!(err.contains("both on its riser and on its face"), "{err}");
    }
}
