//! Space geometry shared by perception and planning: a capsule (a segment swept by a
//! sphere, the robot's limbs as the clearance constraints and the self-filter see them) and
//! a point's distance to it.

use nalgebra::{Point3, Vector3};

/// A segment from `a` to `b` swept by a sphere of `radius_m`, world frame, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    /// One end of the axis.
    pub a: Point3<f64>,
    /// The other end of the axis.
    pub b: Point3<f64>,
    /// Radius, metres.
    pub radius_m: f64,
}

impl Capsule {
    /// The point of the axis nearest `p`.
    pub fn axis_point_nearest(&self, p: &Point3<f64>) -> Point3<f64> {
        let ab = self.b - self.a;
        let len2 = ab.norm_squared();
        let t = if len2 > 0.0 { ((p - self.a).dot(&ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
        self.a + ab * t
    }

    /// Distance from `p` to the capsule's surface, metres (negative inside).
    pub fn distance_m(&self, p: &Point3<f64>) -> f64 {
        (p - self.axis_point_nearest(p)).norm() - self.radius_m
    }
}

/// The box (least and greatest corners) around `capsules`, grown by `margin_m`; inverted
/// (least +inf) when there are none.
pub fn capsules_box(capsules: &[Capsule], margin_m: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
    for c in capsules {
        let reach = Vector3::repeat(c.radius_m + margin_m);
        lo = lo.inf(&(c.a.coords.inf(&c.b.coords) - reach));
        hi = hi.sup(&(c.a.coords.sup(&c.b.coords) + reach));
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_points_distance_is_to_the_axis_inside_and_to_the_ends_beyond() {
        let c = Capsule { a: Point3::new(0.0, 0.0, 0.0), b: Point3::new(0.0, 0.0, 1.0), radius_m: 0.1 };
        assert!((c.distance_m(&Point3::new(0.5, 0.0, 0.3)) - 0.4).abs() < 1e-12);
        assert!((c.distance_m(&Point3::new(0.0, 0.0, 1.5)) - 0.4).abs() < 1e-12);
        assert!((c.distance_m(&Point3::new(0.0, 0.3, -0.4)) - 0.4).abs() < 1e-12);
        assert!(c.distance_m(&Point3::new(0.05, 0.0, 0.5)) < 0.0);
        let dot = Capsule { b: c.a, ..c };
        assert!((dot.distance_m(&Point3::new(0.0, 0.0, 0.5)) - 0.4).abs() < 1e-12);
    }
}
