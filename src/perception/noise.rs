//! The range noise of a sweep, measured on the sweep itself, and the normals' neighbourhood
//! it calls for (beyond the paper, which ran one sensor at one noise).
//!
//! Along a scan row, neighbouring beams see neighbouring points of one surface, whose range
//! changes smoothly: the second difference of three consecutive ranges is that of the
//! noise, `n0 - 2 n1 + n2`, of variance `6 sigma^2`, plus a jump where a row crosses an
//! edge. The median of its magnitude ignores the edges (a few beams in a row of a thousand)
//! and gives sigma as `1.4826 * median / sqrt(6)` for normal noise.

use crate::cloud::{PointCloud, ScanGrid};
use rayon::prelude::*;

/// Fewest second differences for a measure: below this the sweep says nothing of its noise.
const MIN_SAMPLES: usize = 100;

/// The range noise of `cloud`'s sweep (one standard deviation), metres, from the second
/// differences of ranges along its scan rows (from the cloud's viewpoint). `None` for a
/// cloud with no scan grid, or with fewer than [`MIN_SAMPLES`] runs of three beams.
pub fn range_noise_m(cloud: &PointCloud) -> Option<f64> {
    let grid = cloud.grid()?;
    let width = grid.beams().saturating_sub(2);
    let mut second = vec![f64::NAN; grid.rows() * width];
    if width > 0 {
        second
            .par_chunks_mut(width)
            .zip(grid.cells().par_chunks(grid.beams()))
            .for_each(|(out, row)| second_differences(cloud, row, out));
    }
    sigma_of(&second)
}

/// A scan row's second differences of range into `out` (one per run of three beams), NaN
/// where a beam of the three is missing.
fn second_differences(cloud: &PointCloud, row: &[u32], out: &mut [f64]) {
    let v = cloud.viewpoint().cast::<f32>();
    let points = cloud.points();
    let range = |c: u32| {
        let p = points.get(c as usize).filter(|_| c != ScanGrid::EMPTY)?;
        let r = (p - v).norm();
        r.is_finite().then_some(f64::from(r))
    };
    let (mut a, mut b) = (range(row[0]), range(row[1]));
    for (o, &cell) in out.iter_mut().zip(&row[2..]) {
        let c = range(cell);
        if let (Some(a), Some(b), Some(c)) = (a, b, c) {
            *o = (a - 2.0 * b + c).abs();
        }
        (a, b) = (b, c);
    }
}

/// Sigma from a sweep's second differences (see the module's doc).
fn sigma_of(second: &[f64]) -> Option<f64> {
    median_of_non_negative(second, MIN_SAMPLES).map(sigma_of_median)
}

/// Sigma from the median magnitude of a sweep's second differences (normal noise).
fn sigma_of_median(median: f64) -> f64 {
    1.4826 * median / 6f64.sqrt()
}

/// [`range_noise_m`] over a sweep whose rows arrive one after another: each row's second
/// differences are taken, and counted into the median's histogram, as it arrives; only the
/// selection within the median's bin is left for the end. It gives exactly what
/// [`range_noise_m`] gives on the whole sweep.
#[derive(Debug, Clone)]
pub struct Stream {
    second: Vec<f64>,
    /// The second differences so far, counted by [`count_into`].
    histogram: Vec<u32>,
    rows_done: usize,
}

impl Stream {
    /// For `cloud`'s sweep (the rows not yet arrived are not read); `None` without a scan grid.
    pub fn new(cloud: &PointCloud) -> Option<Self> {
        let grid = cloud.grid()?;
        let width = grid.beams().saturating_sub(2);
        Some(Self { second: vec![f64::NAN; grid.rows() * width], histogram: vec![0; BINS], rows_done: 0 })
    }

    /// The sweep's first `rows` rows have arrived (of `cloud`, the one given to `new`).
    pub fn arrived(&mut self, cloud: &PointCloud, rows: usize) {
        let Some(grid) = cloud.grid() else { return };
        let (beams, width) = (grid.beams(), grid.beams().saturating_sub(2));
        let rows = rows.min(grid.rows());
        if width > 0 {
            for r in self.rows_done..rows {
                let row = &grid.cells()[r * beams..(r + 1) * beams];
                let out = &mut self.second[r * width..(r + 1) * width];
                second_differences(cloud, row, out);
                count_into(&mut self.histogram, out);
            }
        }
        self.rows_done = self.rows_done.max(rows);
    }

    /// The sweep's range noise once every row has arrived (the rest are taken now).
    pub fn finish(mut self, cloud: &PointCloud) -> Option<f64> {
        self.arrived(cloud, usize::MAX);
        median_in_bins(&self.second, &self.histogram, MIN_SAMPLES).map(sigma_of_median)
    }
}

/// The values each thread takes of `values` (a chunk per thread).
fn share_of(values: &[f64]) -> usize {
    values.len().div_ceil(rayon::current_num_threads().max(1)).max(1)
}

/// The median's histogram has a bin for each value of a float's top 16 bits.
const SHIFT: u32 = 48;
const BINS: usize = 1 << (64 - SHIFT);

/// The bin of a non-negative float (for those the bits order as the values do).
fn bin(x: f64) -> usize {
    (x.to_bits() >> SHIFT) as usize
}

/// Counts the `values` that are not NaN (all non-negative) into `histogram`'s bins.
fn count_into(histogram: &mut [u32], values: &[f64]) {
    for &x in values.iter().filter(|x| !x.is_nan()) {
        histogram[bin(x)] += 1;
    }
}

/// The median (the element at rank `n / 2` of the `n` that are not NaN) of `values`, all
/// non-negative or NaN, found in two parallel passes (a histogram on the top 16 bits, then
/// a selection among the values of the bin that holds it) where a selection over all of
/// them is serial. `None` with fewer than `min_count` values.
fn median_of_non_negative(values: &[f64], min_count: usize) -> Option<f64> {
    let histogram = values
        .par_chunks(share_of(values))
        .map(|c| {
            let mut h = vec![0u32; BINS];
            count_into(&mut h, c);
            h
        })
        .reduce_with(|mut a, b| {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
            a
        })?;
    median_in_bins(values, &histogram, min_count)
}

/// The median of `values` (non-negative or NaN) from their `histogram` ([`count_into`]):
/// the bin that holds rank `n / 2`, then a selection among the values in it. `None` with
/// fewer than `min_count` values.
fn median_in_bins(values: &[f64], histogram: &[u32], min_count: usize) -> Option<f64> {
    let n: usize = histogram.iter().map(|&c| c as usize).sum();
    if n < min_count {
        return None;
    }
    let mut rank = n / 2;
    let mut at = 0;
    for (i, &c) in histogram.iter().enumerate() {
        if rank < c as usize {
            at = i;
            break;
        }
        rank -= c as usize;
    }
    // Each thread's share of the values gathered on its own, the shares then joined (a
    // parallel filter's collect is slower; CHANGELOG.md has the figures).
    let mut in_bin: Vec<f64> = values
        .par_chunks(share_of(values))
        .map(|c| c.iter().copied().filter(|&x| !x.is_nan() && bin(x) == at).collect::<Vec<f64>>())
        .reduce_with(|mut a, b| {
            a.extend(b);
            a
        })
        .unwrap_or_default();
    let (_, median, _) = in_bin.select_nth_unstable_by(rank, f64::total_cmp);
    Some(*median)
}

/// The neighbours of the normal estimation for a sweep of range noise `noise_m`: `k` (the
/// paper's, chosen at `reference_noise_m`) grown in proportion to the noise above it,
/// rounded (a sweep measured at the reference's own noise keeps k), at most `max_k`. A
/// normal is a plane fitted to its neighbours; its tilt from the range noise falls as the
/// neighbours' count times their spread, which for the k nearest on a scan grid both grow
/// with k: a tilt of the paper's size at `noise_m` needs `k * noise_m / reference_noise_m`.
pub fn neighbours_for(k: usize, noise_m: Option<f64>, reference_noise_m: f64, max_k: usize) -> usize {
    match noise_m {
        Some(s) if s > reference_noise_m => {
            ((k as f64 * s / reference_noise_m).round() as usize).min(max_k).max(k)
        }
        _ => k,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Unit, Vector3};

    /// A sweep of a floor 1.4 m under the sensor, 60 rows by 400 beams 0.25 degrees apart,
    /// each range off by a normal draw of `sigma_m` (seeded), one beam in fifty missing.
    fn floor_sweep(sigma_m: f64) -> PointCloud {
        let mut seed = 7u64;
        let mut uniform = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let viewpoint = Point3::new(0.0, 0.0, 1.4);
        let (rows, beams) = (60, 400);
        let mut points = Vec::new();
        let mut cells = Vec::new();
        for r in 0..rows {
            let tilt = (30.0 + 0.25 * r as f64).to_radians();
            for b in 0..beams {
                let yaw = (-50.0 + 0.25 * b as f64).to_radians();
                let ray = Vector3::new(tilt.cos() * yaw.cos(), tilt.cos() * yaw.sin(), -tilt.sin());
                let gauss = (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos();
                if uniform() < 0.02 {
                    cells.push(ScanGrid::EMPTY);
                    continue;
                }
                let range = 1.4 / tilt.sin() + sigma_m * gauss;
                cells.push(points.len() as u32);
                points.push((viewpoint + ray * range).cast::<f32>());
            }
        }
        let grid = ScanGrid::new(rows, beams, cells).expect("a valid grid");
        PointCloud::new(points, viewpoint, Unit::new_normalize(-Vector3::z()), Some(grid))
    }

    #[test]
    fn the_range_noise_is_measured_on_the_sweep() {
        for sigma_m in [0.005, 0.01, 0.02, 0.025] {
            let measured = range_noise_m(&floor_sweep(sigma_m)).expect("a measure");
            assert!((measured / sigma_m - 1.0).abs() < 0.1, "{measured:.4} m for {sigma_m} m");
        }
        assert!(range_noise_m(&floor_sweep(0.0)).expect("a measure") < 1e-3, "a noise-free sweep");
        let unorganized = PointCloud::unorganized(vec![Point3::origin(); 500], Point3::origin());
        assert_eq!(range_noise_m(&unorganized), None, "no scan rows, no measure");
    }

    #[test]
    fn the_median_in_bins_is_the_selections_median() {
        let mut seed = 3u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for n in [1usize, 2, 3, 100, 1001, 50_000] {
            // Values over many octaves, some equal, some NaN.
            let values: Vec<f64> = (0..n)
                .map(|i| match i % 17 {
                    0 => f64::NAN,
                    1 => 0.25,
                    2 => 0.0,
                    _ => next().powi(6) * 3.0,
                })
                .collect();
            let mut finite: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
            let expected = (!finite.is_empty()).then(|| {
                let mid = finite.len() / 2;
                *finite.select_nth_unstable_by(mid, f64::total_cmp).1
            });
            assert_eq!(median_of_non_negative(&values, 1), expected, "{n} values");
        }
        assert_eq!(median_of_non_negative(&[1.0, f64::NAN], 2), None, "fewer than the least count");
    }

    #[test]
    fn the_neighbours_grow_with_the_noise_above_the_reference() {
        assert_eq!(neighbours_for(10, None, 0.01, 100), 10);
        assert_eq!(neighbours_for(10, Some(0.004), 0.01, 100), 10, "never fewer than k");
        assert_eq!(neighbours_for(10, Some(0.02), 0.01, 100), 20);
        assert_eq!(neighbours_for(10, Some(0.0101), 0.01, 100), 10, "the reference's own noise");
        assert_eq!(neighbours_for(10, Some(0.0206), 0.01, 100), 21);
        assert_eq!(neighbours_for(10, Some(0.5), 0.01, 100), 100, "at most max_k");
    }
}
