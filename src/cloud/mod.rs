//! Point clouds: the assembled sweep in a gravity-aligned frame, with the scan's row x beam
//! organization kept when the cloud comes from a lidar (neighbours in the grid are neighbours
//! on the surface, which perception may use).

pub mod io;

use nalgebra::{Point3, Unit, Vector3};

/// Row x beam organization of a cloud that came from a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanGrid {
    rows: usize,
    beams: usize,
    cell_to_point: Vec<u32>,
    /// Where each row was seen from, when the sensor moved during the sweep; empty when
    /// every row was seen from the cloud's viewpoint.
    row_origins: Vec<Point3<f64>>,
}

impl ScanGrid {
    /// Marker of a cell with no point.
    pub const EMPTY: u32 = u32::MAX;

    /// A grid of `rows` x `beams` cells; `cell_to_point[row * beams + beam]` is the index of
    /// the cell's point or [`ScanGrid::EMPTY`]. Points are numbered in scan order, so the
    /// indices of non-empty cells increase in row-major order. `None` when the table's size is
    /// not `rows * beams` or the indices do not increase.
    pub fn new(rows: usize, beams: usize, cell_to_point: Vec<u32>) -> Option<Self> {
        let increasing = cell_to_point
            .iter()
            .filter(|&&c| c != Self::EMPTY)
            .try_fold(None, |prev: Option<u32>, &c| match prev {
                Some(p) if c <= p => Err(()),
                _ => Ok(Some(c)),
            })
            .is_ok();
        (increasing && cell_to_point.len() == rows.checked_mul(beams)?).then_some(Self {
            rows,
            beams,
            cell_to_point,
            row_origins: Vec::new(),
        })
    }

    /// The grid of a sensor that moved during the sweep: row `k` seen from `origins[k]` (the
    /// scanner's optical centre at the row's middle beam). `None` unless there is one origin
    /// a row.
    pub fn with_row_origins(self, origins: Vec<Point3<f64>>) -> Option<Self> {
        (origins.len() == self.rows).then_some(Self { row_origins: origins, ..self })
    }

    /// Where each row was seen from, when the sensor moved during the sweep (one a row);
    /// empty when every row was seen from the cloud's viewpoint.
    pub fn row_origins(&self) -> &[Point3<f64>] {
        &self.row_origins
    }

    /// Rows in the grid.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Beams per row.
    pub fn beams(&self) -> usize {
        self.beams
    }

    /// The index of the point at (`row`, `beam`), if the beam returned.
    pub fn point_at(&self, row: usize, beam: usize) -> Option<usize> {
        if row >= self.rows || beam >= self.beams {
            return None;
        }
        let v = self.cell_to_point[row * self.beams + beam];
        (v != Self::EMPTY).then_some(v as usize)
    }

    /// The flat cell table (row-major).
    pub fn cells(&self) -> &[u32] {
        &self.cell_to_point
    }
}

/// A point cloud in a gravity-aligned frame (the world frame in simulation).
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloud {
    points: Vec<Point3<f32>>,
    viewpoint: Point3<f64>,
    gravity: Unit<Vector3<f64>>,
    grid: Option<ScanGrid>,
}

impl PointCloud {
    /// A cloud of `points` seen from `viewpoint`, with `gravity` the unit direction of gravity.
    pub fn new(
        points: Vec<Point3<f32>>,
        viewpoint: Point3<f64>,
        gravity: Unit<Vector3<f64>>,
        grid: Option<ScanGrid>,
    ) -> Self {
        Self { points, viewpoint, gravity, grid }
    }

    /// A cloud without organization, gravity along -z.
    pub fn unorganized(points: Vec<Point3<f32>>, viewpoint: Point3<f64>) -> Self {
        Self::new(points, viewpoint, -Vector3::z_axis(), None)
    }

    /// The points, metres.
    pub fn points(&self) -> &[Point3<f32>] {
        &self.points
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the cloud has no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The sensor's (mean) optical centre, for orienting normals.
    pub fn viewpoint(&self) -> Point3<f64> {
        self.viewpoint
    }

    /// Where the sensor was when the sweep ended: the last row's origin for a sweep whose
    /// head moved ([`ScanGrid::row_origins`]), else the viewpoint. It is where the robot
    /// stands when it acts on the cloud: what "under the sensor" and "ahead of it" mean.
    pub fn sensor_at_end(&self) -> Point3<f64> {
        self.grid.as_ref().and_then(|g| g.row_origins().last().copied()).unwrap_or(self.viewpoint)
    }

    /// Unit direction of gravity in the cloud's frame.
    pub fn gravity(&self) -> Unit<Vector3<f64>> {
        self.gravity
    }

    /// The scan organization, when the cloud came from a lidar sweep.
    pub fn grid(&self) -> Option<&ScanGrid> {
        self.grid.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sweep taken walking up a step is seen from along the head's path: its viewpoint
    /// (the mean) lies behind and below where the head ended, which is where the robot
    /// stands when it plans; a standing sweep's is its viewpoint.
    #[test]
    fn a_moving_sweep_ends_where_its_last_row_was_cast() {
        let points = vec![Point3::new(1.0f32, 0.0, 0.0), Point3::new(1.3, 0.0, 0.2)];
        let origins = vec![Point3::new(0.0, 0.0, 1.4), Point3::new(0.3, 0.0, 1.6)];
        let grid = ScanGrid::new(2, 1, vec![0, 1]).expect("a grid");
        let standing = PointCloud::new(
            points.clone(),
            Point3::new(0.15, 0.0, 1.5),
            -Vector3::z_axis(),
            Some(grid.clone()),
        );
        assert_eq!(standing.sensor_at_end(), Point3::new(0.15, 0.0, 1.5));
        let walked = grid.with_row_origins(origins).expect("an origin a row");
        let moving = PointCloud::new(points, Point3::new(0.15, 0.0, 1.5), -Vector3::z_axis(), Some(walked));
        assert_eq!(moving.sensor_at_end(), Point3::new(0.3, 0.0, 1.6));
    }
}
