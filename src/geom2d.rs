//! Plane geometry in the transverse (x, y) plane: convex hulls, minimum-area rectangles,
//! convex polygon clipping and overlap. Used by perception (step rectangles, their scores)
//! and planning (support areas).

use nalgebra::Vector2;

/// A 2-D point or vector, metres.
pub type P2 = Vector2<f64>;

fn cross(o: &P2, a: &P2, b: &P2) -> f64 {
    (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
}

/// Convex hull, counter-clockwise, without collinear points (Andrew's monotone chain).
/// Non-finite points are ignored. Large sets are first thinned by Akl and Toussaint's
/// heuristic: points strictly inside the polygon of the eight extreme points (along x, y,
/// x + y, x - y) cannot be hull vertices, and the sort only sees the rest.
pub fn convex_hull(points: &[P2]) -> Vec<P2> {
    let all: Vec<P2> = points.iter().copied().filter(|p| p.x.is_finite() && p.y.is_finite()).collect();
    if all.len() <= THIN_ABOVE {
        return monotone_chain(all);
    }
    let octagon = extreme_polygon(&all);
    monotone_chain(all.into_iter().filter(|p| !strictly_inside(&octagon, p)).collect())
}

/// Andrew's monotone chain on finite points.
fn monotone_chain(mut pts: Vec<P2>) -> Vec<P2> {
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let mut hull: Vec<P2> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &P2>> =
            if pass == 0 { Box::new(pts.iter()) } else { Box::new(pts.iter().rev()) };
        for p in iter {
            while hull.len() >= start + 2 && cross(&hull[hull.len() - 2], &hull[hull.len() - 1], p) <= 0.0 {
                hull.pop();
            }
            hull.push(*p);
        }
        hull.pop();
    }
    hull
}

/// Point sets at most this big go to the monotone chain as they are.
const THIN_ABOVE: usize = 64;

/// The distinct extreme points of `pts` along x, y, x + y and x - y, counter-clockwise.
fn extreme_polygon(pts: &[P2]) -> Vec<P2> {
    let Some(&first) = pts.first() else { return Vec::new() };
    // Counter-clockwise from the lowest y: min y, max x - y, max x, max x + y, max y,
    // max y - x, min x, min x + y.
    let keys: [fn(&P2) -> f64; 8] =
        [|p| -p.y, |p| p.x - p.y, |p| p.x, |p| p.x + p.y, |p| p.y, |p| p.y - p.x, |p| -p.x, |p| -p.x - p.y];
    let mut best = [first; 8];
    for p in pts {
        for (b, key) in best.iter_mut().zip(&keys) {
            if key(p) > key(b) {
                *b = *p;
            }
        }
    }
    let mut poly: Vec<P2> = Vec::with_capacity(8);
    for b in best {
        if poly.last() != Some(&b) && poly.first() != Some(&b) {
            poly.push(b);
        }
    }
    poly
}

/// Whether `p` is strictly inside the convex counter-clockwise polygon `poly`, by a margin
/// far above rounding (a point on or near an edge is never called inside).
fn strictly_inside(poly: &[P2], p: &P2) -> bool {
    let n = poly.len();
    n >= 3
        && (0..n).all(|i| {
            let (a, b) = (&poly[i], &poly[(i + 1) % n]);
            let scale = (b - a).norm_squared() + (p - a).norm_squared();
            cross(a, b, p) > 1e-12 * scale
        })
}

/// Signed area (positive when counter-clockwise), square metres.
pub fn signed_area(poly: &[P2]) -> f64 {
    let n = poly.len();
    (0..n).map(|i| poly[i].x * poly[(i + 1) % n].y - poly[(i + 1) % n].x * poly[i].y).sum::<f64>() / 2.0
}

/// Area of a simple polygon, square metres.
pub fn area(poly: &[P2]) -> f64 {
    signed_area(poly).abs()
}

/// The minimum-area rectangle enclosing `points`: its unit axis `u` (the second axis is `u`
/// turned by +90 degrees) and the extents [min, max] of the points along both axes.
pub fn min_area_rect(points: &[P2]) -> Option<(P2, [f64; 2], [f64; 2])> {
    min_area_rect_of_hull(&convex_hull(points))
}

/// [`min_area_rect`] of points whose convex hull (counter-clockwise) is `hull`.
pub fn min_area_rect_of_hull(hull: &[P2]) -> Option<(P2, [f64; 2], [f64; 2])> {
    if hull.len() < 3 {
        return None;
    }
    let mut best: Option<(f64, P2, [f64; 2], [f64; 2])> = None;
    for i in 0..hull.len() {
        let e = hull[(i + 1) % hull.len()] - hull[i];
        let Some(u) = e.try_normalize(1e-15) else { continue };
        let (ra, rb) = extents(hull, &u);
        let a = (ra[1] - ra[0]) * (rb[1] - rb[0]);
        if best.is_none_or(|b| a < b.0) {
            best = Some((a, u, ra, rb));
        }
    }
    best.map(|(_, u, ra, rb)| (u, ra, rb))
}

/// Extents [min, max] of `points` along `u` and along `u` turned by +90 degrees.
pub fn extents(points: &[P2], u: &P2) -> ([f64; 2], [f64; 2]) {
    let v = P2::new(-u.y, u.x);
    let mut a = [f64::INFINITY, f64::NEG_INFINITY];
    let mut b = a;
    for p in points {
        let (s, t) = (p.dot(u), p.dot(&v));
        a = [a[0].min(s), a[1].max(s)];
        b = [b[0].min(t), b[1].max(t)];
    }
    (a, b)
}

/// The part of the convex polygon `poly` where n . p <= b + tol (one Sutherland-Hodgman
/// step).
pub fn clip_half_plane(poly: &[P2], n: &P2, b: f64, tol: f64) -> Vec<P2> {
    let f = |p: &P2| n.x * p.x + n.y * p.y - b;
    let mut out = Vec::with_capacity(poly.len() + 1);
    for j in 0..poly.len() {
        let (p, q) = (poly[j], poly[(j + 1) % poly.len()]);
        let (fp, fq) = (f(&p), f(&q));
        let (ip, iq) = (fp <= tol, fq <= tol);
        if ip {
            out.push(p);
        }
        if ip != iq {
            let t = fp / (fp - fq);
            out.push(p + (q - p) * t);
        }
    }
    out
}

/// Intersection of two convex counter-clockwise polygons (Sutherland-Hodgman).
pub fn clip_convex(subject: &[P2], clip: &[P2]) -> Vec<P2> {
    let mut out: Vec<P2> = subject.to_vec();
    let n = clip.len();
    for i in 0..n {
        if out.is_empty() {
            break;
        }
        // Left of the edge a -> b: cross(a, b, p) >= 0, i.e. (dy, -dx) . p <= (dy, -dx) . a.
        let (a, b) = (clip[i], clip[(i + 1) % n]);
        let normal = P2::new(b.y - a.y, a.x - b.x);
        out = clip_half_plane(&out, &normal, normal.x * a.x + normal.y * a.y, 1e-12);
    }
    // Clipping leaves near-duplicate vertices where an edge passes through a vertex, and
    // where two edges nearly coincide, a micro-edge turning the wrong way.
    drop_reflex(dedup_vertices(&out, 1e-9))
}

/// The polygon without its reflex vertices (a clockwise turn in a counter-clockwise polygon),
/// removed until none is left. The intersection of convex polygons is convex: a reflex vertex
/// is rounding, yet one such vertex makes [`contains`] reject the whole interior. (Two feet's
/// stability polygons sharing an edge to within 1e-6 m gave a 1.2 micrometre edge pointing
/// backwards, and the planner refused a stance whose CoM lay 5 cm inside.)
pub fn drop_reflex(mut poly: Vec<P2>) -> Vec<P2> {
    loop {
        let n = poly.len();
        if n < 3 {
            return poly;
        }
        let reflex = (0..n).find(|&i| cross(&poly[(i + n - 1) % n], &poly[i], &poly[(i + 1) % n]) < 0.0);
        match reflex {
            Some(i) => {
                poly.remove(i);
            }
            None => return poly,
        }
    }
}

/// The polygon without consecutive vertices closer than `tol` (the last against the first
/// too).
pub fn dedup_vertices(poly: &[P2], tol: f64) -> Vec<P2> {
    let mut v: Vec<P2> = Vec::with_capacity(poly.len());
    for p in poly {
        if v.last().is_none_or(|l: &P2| (p - l).norm() > tol) {
            v.push(*p);
        }
    }
    while v.len() > 1 && (v[0] - v[v.len() - 1]).norm() <= tol {
        v.pop();
    }
    v
}

/// Intersection over union of two convex polygons (either orientation).
pub fn iou(a: &[P2], b: &[P2]) -> f64 {
    let ccw = |p: &[P2]| if signed_area(p) < 0.0 { p.iter().rev().copied().collect() } else { p.to_vec() };
    let (a, b) = (ccw(a), ccw(b));
    let inter = area(&clip_convex(&a, &b));
    let union = area(&a) + area(&b) - inter;
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}

/// Whether `p` lies inside the convex counter-clockwise polygon `poly` (boundary included,
/// within 1 nm). Edges shorter than 1 nm (rounding left-overs of clipping) are skipped: their
/// direction is noise.
pub fn contains(poly: &[P2], p: &P2) -> bool {
    poly.len() >= 3
        && (0..poly.len()).all(|i| {
            let (a, b) = (&poly[i], &poly[(i + 1) % poly.len()]);
            let len = (b - a).norm();
            len < 1e-9 || cross(a, b, p) / len >= -1e-9
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x0: f64, y0: f64, s: f64) -> Vec<P2> {
        vec![P2::new(x0, y0), P2::new(x0 + s, y0), P2::new(x0 + s, y0 + s), P2::new(x0, y0 + s)]
    }

    #[test]
    fn contains_ignores_a_reversed_sliver_edge() {
        // A clipping left-over: two vertices 1.6e-11 apart, their edge pointing the wrong way.
        let poly = [
            P2::new(0.105439363289512, 0.1663767865130676),
            P2::new(0.10543936328918548, 0.1663767865288894),
            P2::new(0.10813584385722272, 0.03640480784422101),
            P2::new(0.3480841614435224, 0.04138306033585633),
            P2::new(0.34538768087575095, 0.1713550390074572),
        ];
        assert!(contains(&poly, &P2::new(0.2129, 0.0937)));
        assert!(!contains(&poly, &P2::new(0.2129, 0.01)));
    }

    #[test]
    fn thinning_keeps_the_hull() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
        let mut rnd = || rng.random::<f64>();
        for shape in 0..4 {
            for trial in 0..50 {
                let n = 65 + trial * 40;
                let (yaw, sx, sy) = (rnd() * 6.3, 0.2 + rnd(), 0.05 + rnd());
                let pts: Vec<P2> = (0..n)
                    .map(|_| {
                        let (a, b) = match shape {
                            0 => (rnd() - 0.5, rnd() - 0.5), // filled box
                            1 => ((rnd() * 20.0).round() / 40.0, (rnd() * 8.0).round() / 16.0), // grid, repeats
                            2 => {
                                let t = rnd() * 6.3;
                                (t.cos() / 2.0, t.sin() / 2.0) // all on a circle
                            }
                            _ => (rnd() - 0.5, 0.0), // collinear
                        };
                        let (x, y) = (a * sx, b * sy);
                        P2::new(x * yaw.cos() - y * yaw.sin() + 3.0, x * yaw.sin() + y * yaw.cos() - 1.0)
                    })
                    .collect();
                assert_eq!(convex_hull(&pts), monotone_chain(pts.clone()), "shape {shape}, {n} points");
            }
        }
    }

    #[test]
    fn hull_of_a_grid_is_its_square() {
        let pts: Vec<P2> = (0..100).map(|i| P2::new((i % 10) as f64, (i / 10) as f64)).collect();
        let h = convex_hull(&pts);
        assert_eq!(h.len(), 4);
        assert!((signed_area(&h) - 81.0).abs() < 1e-12);
    }

    #[test]
    fn min_area_rect_of_a_turned_rectangle() {
        let a = 0.5f64;
        let (u, v) = (P2::new(a.cos(), a.sin()), P2::new(-a.sin(), a.cos()));
        let pts: Vec<P2> =
            (0..200).map(|i| u * ((i % 20) as f64 * 0.1) + v * ((i / 20) as f64 * 0.05)).collect();
        let (axis, ra, rb) = min_area_rect(&pts).unwrap();
        let area = (ra[1] - ra[0]) * (rb[1] - rb[0]);
        assert!((area - 1.9 * 0.45).abs() < 1e-9, "{area}");
        assert!(axis.dot(&u).abs() > 1.0 - 1e-9 || axis.dot(&v).abs() > 1.0 - 1e-9);
    }

    #[test]
    fn iou_of_shifted_squares() {
        assert!((iou(&square(0.0, 0.0, 1.0), &square(0.5, 0.0, 1.0)) - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(iou(&square(0.0, 0.0, 1.0), &square(2.0, 0.0, 1.0)), 0.0);
        let mut cw = square(0.0, 0.0, 1.0);
        cw.reverse();
        assert!((iou(&cw, &square(0.0, 0.0, 1.0)) - 1.0).abs() < 1e-12);
    }

    /// Two feet's polygons from the planner (Exp. 1, the stance after a teleported floor
    /// step): the double-support polygon and the left foot's share an edge to within a
    /// micrometre. Their intersection is the left foot's polygon, with the CoM target 5 cm
    /// inside it; a reflex micro-edge left by the clipping put it "outside".
    #[test]
    fn nearly_coincident_edges_leave_no_reflex_vertex() {
        let p = |x: f64, y: f64| P2::new(x, y);
        let both = [
            p(0.34990232505920504, 0.16590760487186798),
            p(0.10990247886451954, 0.1661793152454365),
            p(0.10952592456907478, -0.1664277376821174),
            p(0.3495257707637301, -0.16669944808268577),
        ];
        let left = [
            p(0.34975514860685486, 0.03590768818308029),
            p(0.3499023250592046, 0.16590760487186174),
            p(0.10990247886452242, 0.1661793152454365),
            p(0.10975530241217277, 0.03617939855664884),
        ];
        let region = clip_convex(&both, &left);
        let com = p(0.215817501446459, 0.09105935790542716);
        assert!(contains(&region, &com), "{region:?}");
        assert!((area(&region) - area(&left)).abs() < 1e-6, "the left foot's polygon, to a micrometre");
        for i in 0..region.len() {
            let n = region.len();
            assert!(cross(&region[(i + n - 1) % n], &region[i], &region[(i + 1) % n]) >= 0.0, "{region:?}");
        }
        // A convex polygon keeps every vertex, collinear ones included.
        let square = vec![p(0.0, 0.0), p(0.5, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)];
        assert_eq!(drop_reflex(square.clone()), square);
    }
}
