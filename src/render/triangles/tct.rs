//! Time-continuous triangles (Akenine-Möller et al. 2007; Gribel et al. 2010, summarised in
//! Palmér §2.1): each corner moves linearly in camera space over a sub-segment, p(s) = q + s·(r − q)
//! for s in [0, 1], and a spatial sample's ray is inside the triangle when its three edge functions
//! agree in sign. With the eye at the origin and the sample's ray direction d, the edge function
//! of edge (a, b) is the triple product e(s) = d · (a(s) × b(s)), a quadratic in s; the sample is
//! inside where all three are ≥ 0 or all ≤ 0 (either winding, so open meshes show both sides).
//! The visible depth along the ray is the rational function λ(s) = (n·a)/(n·d) with
//! n = (b − a) × (c − a), cubic over quadratic; docs/math.md, "Time-continuous triangles".

use crate::math::{keeps_sign, quadratic_roots};
use glam::DVec3;

/// Most pieces a covered interval's depth is cut into where a line does not follow it.
pub const MAX_DEPTH_PIECES: usize = 16;

/// A linear depth piece in the image may stray from the exact depth at its middle by this many
/// pixel widths at that depth (depth / focal length in px) before it is halved (Palmér §5,
/// "Adaptive depth sampling"): 6·10⁻⁴ of the depth for a 400 px focal length. Shadow maps
/// follow their own, looser [`super::shadow::DEPTH_TOLERANCE_TEXELS`].
pub const DEPTH_TOLERANCE_PX: f64 = 0.25;

/// Where a ray meets a triangle's plane at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Perspective-correct barycentric weights: each corner's is the opposite edge's triple
    /// product with the ray, normalized (a third each where the plane is edge-on to the ray).
    pub weights: [f64; 3],
    /// The depth along the ray; `None` when the plane is edge-on to it or not in front.
    pub depth: Option<f64>,
    /// Whether the ray meets the triangle's back: the side its winding's normal points away
    /// from.
    pub back: bool,
}

/// A triangle whose corners move linearly in camera space over one sub-segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovingTriangle {
    /// Corners at s = 0.
    pub start: [DVec3; 3],
    /// Corner displacement from s = 0 to s = 1.
    pub delta: [DVec3; 3],
}

/// An edge function's coefficients as vectors: e(s) = d·(a s² + b s + c).
#[derive(Clone, Copy, Debug)]
struct EdgeCoefficients {
    a: DVec3,
    b: DVec3,
    c: DVec3,
}

/// The three edge functions of a moving triangle, worked out once for all its samples.
#[derive(Clone, Copy, Debug)]
pub struct EdgeFunctions([EdgeCoefficients; 3]);

/// Largest camera-space corner coordinate (and corner motion) a triangle may have: its depth's
/// coefficients are sums of products of three, which overflow a double past about 10¹⁰².
pub const MAX_CORNER_COORDINATE: f64 = 1e100;

impl MovingTriangle {
    /// Whether every corner coordinate and displacement is within [`MAX_CORNER_COORDINATE`], so
    /// that its edge and depth functions are finite.
    #[must_use]
    pub fn within_double_range(&self) -> bool {
        self.start
            .iter()
            .chain(&self.delta)
            .all(|v| v.abs().max_element() <= MAX_CORNER_COORDINATE)
    }

    /// The corners at s.
    #[must_use]
    pub fn at(&self, s: f64) -> [DVec3; 3] {
        [0, 1, 2].map(|k| self.start[k] + self.delta[k] * s)
    }

    /// The part of [0, 1] when every corner lies at least `near` deep (camera-space −z), or
    /// `None` when there is none: a moving triangle is clipped in time, not in space, where a
    /// corner crosses the near plane ([`MovingTriangle::near_window`]).
    /// Whether no corner moves.
    #[must_use]
    pub fn is_still(&self) -> bool {
        self.delta == [DVec3::ZERO; 3]
    }

    /// What of [0, 1] the triangle is drawn over against the near plane `near` deep, and whether
    /// its samples' hits must be tested against that plane: [`MovingTriangle::in_front`] where
    /// that is some, untested; a still triangle reaching behind the near plane with a corner in
    /// front of it, all of [0, 1], tested (its edge tests hold on either side of the eye:
    /// docs/math.md, "The near plane"); `None` when none of it is drawn.
    #[must_use]
    pub fn near_window(&self, near: f64) -> Option<([f64; 2], bool)> {
        match self.in_front(near) {
            Some(window) => Some((window, false)),
            None if self.is_still() && self.start.iter().any(|corner| -corner.z >= near) => {
                Some(([0.0, 1.0], true))
            }
            None => None,
        }
    }

    #[must_use]
    pub fn in_front(&self, near: f64) -> Option<[f64; 2]> {
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for k in 0..3 {
            // depth(s) = −(z0 + s·dz) ≥ near.
            let (z0, dz) = (self.start[k].z, self.delta[k].z);
            let depth0 = -z0;
            let slope = -dz;
            if slope == 0.0 {
                if !(depth0 >= near) {
                    return None;
                }
            } else {
                let crossing = (near - depth0) / slope;
                if slope > 0.0 {
                    lo = lo.max(crossing);
                } else {
                    hi = hi.min(crossing);
                }
            }
        }
        (lo < hi && lo.is_finite() && hi.is_finite()).then_some([lo, hi])
    }

    /// Whether the triangle faces away from the eye (at the origin) for all of [0, 1], wound
    /// counter-clockwise seen from its front. It faces the eye where det[a, b, c] < 0; the
    /// determinant of three linearly moving corners is a cubic in s whose Bernstein coefficients
    /// are the means of the determinants with each corner taken at s = 0 or 1 (it is trilinear),
    /// so when all four are positive it is positive throughout.
    #[must_use]
    pub fn back_facing_throughout(&self) -> bool {
        let end = self.at(1.0);
        let [a, b, c] = self.start;
        let [a1, b1, c1] = end;
        let det = |p: DVec3, q: DVec3, r: DVec3| p.dot(q.cross(r));
        let bernstein = [
            det(a, b, c),
            (det(a1, b, c) + det(a, b1, c) + det(a, b, c1)) / 3.0,
            (det(a, b1, c1) + det(a1, b, c1) + det(a1, b1, c)) / 3.0,
            det(a1, b1, c1),
        ];
        bernstein.iter().all(|&x| x > 0.0)
    }

    /// Its edge functions.
    #[must_use]
    pub fn edge_functions(&self) -> EdgeFunctions {
        EdgeFunctions([(0, 1), (1, 2), (2, 0)].map(|(i, j)| {
            let (p, q) = (self.start[i], self.start[j]);
            let (dp, dq) = (self.delta[i], self.delta[j]);
            EdgeCoefficients {
                a: dp.cross(dq),
                b: p.cross(dq) + dp.cross(q),
                c: p.cross(q),
            }
        }))
    }

    /// Depth along the ray `d` (whose depth component is 1) where it meets the triangle's plane
    /// at s: (n·a)/(n·d). `None` when the plane is edge-on to the ray or not in front.
    #[must_use]
    pub fn depth(&self, d: DVec3, s: f64) -> Option<f64> {
        self.plane_hit(d, s).depth
    }

    /// Where the ray `d` (whose depth component is 1) meets the triangle's plane at s.
    #[must_use]
    #[inline]
    pub fn ray_hit(&self, d: DVec3, s: f64) -> RayHit {
        let [a, b, c] = self.at(s);
        let w = [d.dot(b.cross(c)), d.dot(c.cross(a)), d.dot(a.cross(b))];
        // b × c + c × a + a × b = (b − a) × (c − a), the winding's normal: the weights' sum is
        // its dot product with the ray.
        let sum = w[0] + w[1] + w[2];
        if !(sum != 0.0 && sum.is_finite()) {
            return RayHit {
                weights: [1.0 / 3.0; 3],
                depth: None,
                back: sum > 0.0,
            };
        }
        let weights = w.map(|x| x / sum);
        // The weighted corners are the hit point itself, d times its depth.
        let depth = -(a * weights[0] + b * weights[1] + c * weights[2]).z;
        RayHit {
            weights,
            depth: (depth.is_finite() && depth > 0.0).then_some(depth),
            back: sum > 0.0,
        }
    }

    /// The least and the greatest depth (camera-space −z) any of its points reaches over the
    /// segment: its corners' at either end, since every point is a weighted mean of the corners
    /// and they move linearly.
    #[must_use]
    pub fn depth_bounds(&self) -> [f64; 2] {
        (0..3)
            .flat_map(|k| [-self.start[k].z, -(self.start[k] + self.delta[k]).z])
            .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], z| {
                [lo.min(z), hi.max(z)]
            })
    }

    /// Bounds on its plane's depth at s = 0 along the rays between `rays` (the rays through a
    /// screen rectangle's corners): 1/depth is linear across the image, so over the rectangle
    /// the depth lies between its values along the corner rays. `None` where a corner ray does
    /// not meet the plane in front (it may turn edge-on to a ray within the rectangle).
    #[must_use]
    pub fn plane_depths_within(&self, rays: [DVec3; 4]) -> Option<[f64; 2]> {
        rays.iter()
            .try_fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], &d| {
                let depth = self.plane_hit(d, 0.0).depth?;
                Some([lo.min(depth), hi.max(depth)])
            })
    }

    /// [`MovingTriangle::ray_hit`] for a triangle whose corners share everything the weights
    /// would blend (one normal, one colour): its depth, (n·a)/(n·d) with n = (b − a) × (c − a),
    /// and its side from the plane alone, and the centroid's weights.
    #[must_use]
    #[inline]
    pub fn plane_hit(&self, d: DVec3, s: f64) -> RayHit {
        let [a, b, c] = self.at(s);
        let normal = (b - a).cross(c - a);
        let facing = d.dot(normal);
        let depth = normal.dot(a) / facing;
        RayHit {
            weights: [1.0 / 3.0; 3],
            depth: (depth.is_finite() && depth > 0.0).then_some(depth),
            back: facing > 0.0,
        }
    }

    /// Its depth along any ray as a function of s, worked out once for all its samples.
    #[must_use]
    pub fn depth_function(&self) -> DepthFunction {
        let [a, b, c] = self.start;
        let [da, db, dc] = self.delta;
        // n(s) = (b − a)(s) × (c − a)(s), quadratic; n(s)·a(s), cubic.
        let (e, f) = (b - a, c - a);
        let (de, df) = (db - da, dc - da);
        let normal = [e.cross(f), e.cross(df) + de.cross(f), de.cross(df)];
        let offset = [
            normal[0].dot(a),
            normal[0].dot(da) + normal[1].dot(a),
            normal[1].dot(da) + normal[2].dot(a),
            normal[2].dot(da),
        ];
        DepthFunction { normal, offset }
    }
}

/// A moving triangle's plane as polynomials in s: its normal n(s) = n₀ + n₁s + n₂s² and
/// n(s)·a(s) = o₀ + o₁s + o₂s² + o₃s³ for a corner a, so that the depth along a ray d,
/// λ(s) = (n·a)/(n·d), costs three dot products per ray and a few multiplications per s.
#[derive(Clone, Copy, Debug)]
pub struct DepthFunction {
    normal: [DVec3; 3],
    offset: [f64; 4],
}

impl DepthFunction {
    /// The depth along the ray `d` (whose depth component is 1).
    #[must_use]
    pub fn along(&self, d: DVec3) -> RayDepth {
        RayDepth {
            numerator: self.offset,
            denominator: self.normal.map(|n| n.dot(d)),
        }
    }

    /// Where the ray `d` meets the plane at s = 0, as [`MovingTriangle::plane_hit`] finds it
    /// (the same bits): all a still triangle needs, without its corners.
    #[must_use]
    pub fn hit_at_start(&self, d: DVec3) -> RayHit {
        let facing = d.dot(self.normal[0]);
        let depth = self.offset[0] / facing;
        RayHit {
            weights: [1.0 / 3.0; 3],
            depth: (depth.is_finite() && depth > 0.0).then_some(depth),
            back: facing > 0.0,
        }
    }

    /// [`DepthFunction::hit_at_start`] where its `depth` is known already (a still triangle's
    /// interval keeps it): the side the ray meets, without the division.
    #[must_use]
    pub fn hit_at_start_with(&self, d: DVec3, depth: f64) -> RayHit {
        RayHit {
            weights: [1.0 / 3.0; 3],
            depth: Some(depth),
            back: d.dot(self.normal[0]) > 0.0,
        }
    }
}

/// A moving triangle's depth along one ray: cubic over quadratic in s.
#[derive(Clone, Copy, Debug)]
pub struct RayDepth {
    numerator: [f64; 4],
    denominator: [f64; 3],
}

impl RayDepth {
    /// The depth at s; `None` when the plane is edge-on to the ray or not in front.
    #[must_use]
    pub fn at(&self, s: f64) -> Option<f64> {
        let [o0, o1, o2, o3] = self.numerator;
        let [q0, q1, q2] = self.denominator;
        let depth = (((o3 * s + o2) * s + o1) * s + o0) / ((q2 * s + q1) * s + q0);
        (depth.is_finite() && depth > 0.0).then_some(depth)
    }

    /// The depth over [s0, s1] as linear pieces (s, depth at s) joined end to end: halved where
    /// the line between a piece's ends misses the exact depth at its middle by more than
    /// `tolerance` × the depth, up to [`MAX_DEPTH_PIECES`]. Hands each knot to `knot` in order,
    /// the first included. `None` when the depth is undefined somewhere (some knots may have
    /// been handed by then).
    pub fn knots(
        &self,
        [s0, s1]: [f64; 2],
        tolerance: f64,
        knot: &mut impl FnMut([f64; 2]),
    ) -> Option<()> {
        let first = [s0, self.at(s0)?];
        let last = [s1, self.at(s1)?];
        knot(first);
        self.refine([first, last], tolerance, MAX_DEPTH_PIECES, knot)
    }

    /// [`MovingTriangle::plane_hit`] at s from the polynomials: the same depth and side (up to
    /// rounding), without the corners.
    #[must_use]
    pub fn plane_hit(&self, s: f64) -> RayHit {
        let [q0, q1, q2] = self.denominator;
        RayHit {
            weights: [1.0 / 3.0; 3],
            depth: self.at(s),
            back: (q2 * s + q1) * s + q0 > 0.0,
        }
    }

    /// The depth at s0 and s1, and whether [`RayDepth::knots`] would cut [s0, s1] (the line
    /// between them misses the depth at the middle by more than `tolerance` × the depth).
    /// `None` when the depth is undefined at one of the three.
    pub fn line(&self, [s0, s1]: [f64; 2], tolerance: f64) -> Option<([f64; 2], bool)> {
        let ends = [[s0, self.at(s0)?], [s1, self.at(s1)?]];
        let (_, bends) = self.middle(ends, tolerance)?;
        Some(([ends[0][1], ends[1][1]], bends))
    }

    /// The knot at the middle of a piece between `ends`, and whether the piece's line misses it
    /// by more than `tolerance` × its depth.
    fn middle(
        &self,
        [[s0, z0], [s1, z1]]: [[f64; 2]; 2],
        tolerance: f64,
    ) -> Option<([f64; 2], bool)> {
        let sm = 0.5 * (s0 + s1);
        let zm = self.at(sm)?;
        Some(([sm, zm], (zm - 0.5 * (z0 + z1)).abs() > tolerance * zm))
    }

    fn refine(
        &self,
        ends @ [start, end]: [[f64; 2]; 2],
        tolerance: f64,
        budget: usize,
        knot: &mut impl FnMut([f64; 2]),
    ) -> Option<()> {
        if budget >= 2 {
            let (middle, bends) = self.middle(ends, tolerance)?;
            if bends {
                self.refine([start, middle], tolerance, budget / 2, knot)?;
                return self.refine([middle, end], tolerance, budget / 2, knot);
            }
        }
        knot(end);
        Some(())
    }

    /// Bounds [lowest, highest] on the depth over [s0, s1], from the convex hull of the
    /// rational Bézier form: with the numerator (cubic) and the denominator (quadratic,
    /// degree-raised) in the Bernstein basis of [s0, s1], the depth is a convex combination of
    /// the coefficients' ratios wherever the denominator's coefficients share one sign, and lies
    /// between the least and the greatest. Exact at the ends; tight as the span shrinks. `None`
    /// when the denominator's coefficients change sign (the plane may turn edge-on to the ray).
    #[must_use]
    pub fn range(&self, [s0, s1]: [f64; 2]) -> Option<[f64; 2]> {
        let [o0, o1, o2, o3] = self.numerator;
        let [q0, q1, q2] = self.denominator;
        let h = s1 - s0;
        // Taylor coefficients at s0 in u = (s − s0)/h: p(s0), p′(s0)·h, p″(s0)/2·h²,
        // p‴(s0)/6·h³.
        let numerator = [
            ((o3 * s0 + o2) * s0 + o1) * s0 + o0,
            ((3.0 * o3 * s0 + 2.0 * o2) * s0 + o1) * h,
            (3.0 * o3 * s0 + o2) * h * h,
            o3 * h * h * h,
        ];
        let denominator = [
            (q2 * s0 + q1) * s0 + q0,
            (2.0 * q2 * s0 + q1) * h,
            q2 * h * h,
            0.0,
        ];
        // Power basis in u to the cubic Bernstein basis.
        let bernstein = |[a0, a1, a2, a3]: [f64; 4]| {
            [
                a0,
                a0 + a1 / 3.0,
                a0 + (2.0 * a1 + a2) / 3.0,
                a0 + a1 + a2 + a3,
            ]
        };
        let (n, q) = (bernstein(numerator), bernstein(denominator));
        let same_sign = q.iter().all(|&x| x > 0.0) || q.iter().all(|&x| x < 0.0);
        if !same_sign {
            return None;
        }
        let ratios = [0, 1, 2, 3].map(|i| n[i] / q[i]);
        let lowest = ratios.iter().copied().fold(f64::INFINITY, f64::min);
        let highest = ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lowest.is_finite() && highest.is_finite() && lowest > 0.0).then_some([lowest, highest])
    }
}

impl EdgeFunctions {
    /// The sub-intervals of `window` (within [0, 1]) during which the ray along `d` is inside
    /// the triangle, each handed to `span` (its start and end) in time order, apart. The roots
    /// of the three edge quadratics cut the window; each piece is tested at its middle, so an
    /// inaccurate or double root can move a boundary by its error but never turn a piece inside
    /// out.
    #[inline]
    pub fn covered(&self, d: DVec3, window: [f64; 2], mut span: impl FnMut(f64, f64)) {
        let mut cuts = [0.0f64; 8];
        let mut n = 0;
        cuts[n] = window[0];
        n += 1;
        let coefficients = self.0.map(|e| [d.dot(e.a), d.dot(e.b), d.dot(e.c)]);
        let [w0, w1] = window;
        for [a, b, c] in coefficients {
            // Most edges keep one sign over the window.
            if keeps_sign(a, b, c, window) {
                continue;
            }
            let (roots, count) = quadratic_roots(a, b, c);
            for &r in &roots[..count] {
                if r > w0 && r < w1 {
                    cuts[n] = r;
                    n += 1;
                }
            }
        }
        cuts[n] = window[1];
        n += 1;
        let cuts = &mut cuts[..n];
        // Only the roots, all inside the window, can be out of order.
        if n > 3 {
            cuts[1..n - 1].sort_unstable_by(f64::total_cmp);
        }
        let inside = |s: f64| {
            let values = coefficients.map(|[a, b, c]| (a * s + b) * s + c);
            let positive = values.iter().all(|&v| v >= 0.0);
            let negative = values.iter().all(|&v| v <= 0.0);
            // All three zero: the ray lies in the plane of an edge-on triangle, which covers
            // nothing.
            (positive || negative) && values.iter().any(|&v| v != 0.0)
        };
        // Each cut read once, on its own, and the span being joined kept out of memory: a wider
        // load of what was just stored a cut at a time waits for the stores to drain (no store
        // forwarding), which was the hottest line of the coverage test.
        let mut open: Option<[f64; 2]> = None;
        let mut s0 = cuts[0];
        for &s1 in &cuts[1..] {
            if s1 > s0 && inside(0.5 * (s0 + s1)) {
                open = match open {
                    Some([start, end]) if end == s0 => Some([start, s1]),
                    Some([start, end]) => {
                        span(start, end);
                        Some([s0, s1])
                    }
                    None => Some([s0, s1]),
                };
            }
            s0 = s1;
        }
        if let Some([start, end]) = open {
            span(start, end);
        }
    }

    /// Whether the ray along `d` is inside the triangle at s = 0 (a still triangle's test).
    #[must_use]
    pub fn inside_at_start(&self, d: DVec3) -> bool {
        let values = self.0.map(|e| d.dot(e.c));
        let positive = values.iter().all(|&v| v >= 0.0);
        let negative = values.iter().all(|&v| v <= 0.0);
        (positive || negative) && values.iter().any(|&v| v != 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triangle in the plane z = −2 with the ray d = (0, 0, −1) through (0, 0).
    fn translating(from_x: f64, to_x: f64) -> MovingTriangle {
        let start = [
            DVec3::new(from_x - 0.5, -0.5, -2.0),
            DVec3::new(from_x + 0.5, -0.5, -2.0),
            DVec3::new(from_x, 0.5, -2.0),
        ];
        MovingTriangle {
            start,
            delta: [DVec3::X * (to_x - from_x); 3],
        }
    }

    #[test]
    fn a_translating_triangle_covers_the_sample_for_the_closed_form_time() {
        // The triangle's base is 1 wide; at the ray's height y = 0 it is 0.5 wide, centred on
        // its x. Moving from x = −1 to 1 it covers x = 0 while |x| ≤ 0.25: s in [0.375, 0.625].
        let d = DVec3::new(0.0, 0.0, -1.0);
        let mut out = Vec::new();
        translating(-1.0, 1.0)
            .edge_functions()
            .covered(d, [0.0, 1.0], |start, end| out.push([start, end]));
        assert_eq!(out.len(), 1);
        assert!(
            (out[0][0] - 0.375).abs() < 1e-12 && (out[0][1] - 0.625).abs() < 1e-12,
            "{out:?}"
        );
        let z = translating(-1.0, 1.0).depth(d, 0.5).unwrap();
        assert!((z - 2.0).abs() < 1e-12);
    }

    #[test]
    fn covered_spans_agree_with_the_corners_tested_at_each_instant() {
        // Corners far apart that move far and every way, so that many edges cross the ray twice
        // within a window or dip to it and back: the spans must hold exactly the instants at
        // which the ray passes inside the corners of that instant, up to the roots' rounding.
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let d = DVec3::new(0.1, -0.05, -1.0);
        let mut out = Vec::new();
        let (mut covered_somewhere, mut split) = (0, 0);
        for _ in 0..2000 {
            let corner =
                |next: &mut dyn FnMut() -> f64| DVec3::new(next(), next(), -2.0 + 0.5 * next());
            let start = [(); 3].map(|()| corner(&mut next));
            let delta = [(); 3].map(|()| DVec3::new(2.0 * next(), 2.0 * next(), 0.3 * next()));
            let triangle = MovingTriangle { start, delta };
            let window = [0.2 * next().abs(), 1.0 - 0.2 * next().abs()];
            out.clear();
            triangle
                .edge_functions()
                .covered(d, window, |start, end| out.push([start, end]));
            covered_somewhere += usize::from(!out.is_empty());
            split += usize::from(out.len() > 1);
            for i in 0..=4000 {
                let s = window[0] + (window[1] - window[0]) * f64::from(i) / 4000.0;
                let [a, b, c] = triangle.at(s);
                let values = [a.cross(b), b.cross(c), c.cross(a)].map(|n| d.dot(n));
                let inside = values.iter().all(|&v| v > 0.0) || values.iter().all(|&v| v < 0.0);
                let near_an_end = out.iter().flatten().any(|&e| (e - s).abs() < 1e-9);
                let in_spans = out.iter().any(|&[s0, s1]| s >= s0 && s <= s1);
                assert!(
                    near_an_end || inside == in_spans,
                    "s = {s}: inside {inside}, spans {out:?}, {triangle:?}"
                );
            }
        }
        // The cases the test is for did occur.
        assert!(
            covered_somewhere > 500 && split > 40,
            "{covered_somewhere} {split}"
        );
    }

    #[test]
    fn a_still_triangle_covers_all_or_nothing_and_edge_on_covers_nothing() {
        let d = DVec3::new(0.0, 0.0, -1.0);
        let mut out = Vec::new();
        translating(0.0, 0.0)
            .edge_functions()
            .covered(d, [0.0, 1.0], |start, end| out.push([start, end]));
        assert_eq!(out, vec![[0.0, 1.0]]);
        out.clear();
        translating(3.0, 3.0)
            .edge_functions()
            .covered(d, [0.0, 1.0], |start, end| out.push([start, end]));
        assert!(out.is_empty());
        // Edge-on: the triangle lies in the plane x = 0, which contains the ray.
        let edge_on = MovingTriangle {
            start: [
                DVec3::new(0.0, -0.5, -1.0),
                DVec3::new(0.0, -0.5, -3.0),
                DVec3::new(0.0, 0.5, -2.0),
            ],
            delta: [DVec3::ZERO; 3],
        };
        out.clear();
        edge_on
            .edge_functions()
            .covered(d, [0.0, 1.0], |start, end| out.push([start, end]));
        assert!(out.is_empty(), "{out:?}");
        assert!(edge_on.depth(d, 0.5).is_none());
    }

    /// Corners moving in depth and across, so that n(s) and n·a(s) use every coefficient and the
    /// depth bends along each ray.
    fn turning_in_depth() -> MovingTriangle {
        MovingTriangle {
            start: [
                DVec3::new(-0.5, -0.4, -2.0),
                DVec3::new(0.6, -0.3, -2.5),
                DVec3::new(0.1, 0.7, -1.8),
            ],
            delta: [
                DVec3::new(0.3, 0.1, -0.9),
                DVec3::new(-0.2, 0.4, 0.6),
                DVec3::new(0.5, -0.2, -0.3),
            ],
        }
    }

    #[test]
    fn the_depth_polynomials_give_the_depth_of_the_corners_plane() {
        let triangle = turning_in_depth();
        let function = triangle.depth_function();
        for d in [
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::new(0.12, -0.05, -1.0),
            DVec3::new(-0.2, 0.15, -1.0),
        ] {
            let along = function.along(d);
            for step in 0..=10 {
                let s = f64::from(step) / 10.0;
                let (exact, fast) = (triangle.depth(d, s).unwrap(), along.at(s).unwrap());
                assert!(
                    (exact - fast).abs() <= 1e-12 * exact,
                    "{d} {s}: {exact} {fast}"
                );
            }
        }
    }

    #[test]
    fn the_plane_hit_gives_the_depth_and_side_of_the_ray_hit() {
        let triangle = turning_in_depth();
        for (x, y) in [(0.0, 0.0), (0.05, 0.1), (-0.1, -0.05), (2.0, 3.0)] {
            let d = DVec3::new(x, y, -1.0);
            let along = triangle.depth_function().along(d);
            for s in [0.0, 0.3, 0.7, 1.0] {
                let full = triangle.ray_hit(d, s);
                // From the corners at s, and from the plane's polynomials in s.
                for plane in [triangle.plane_hit(d, s), along.plane_hit(s)] {
                    assert_eq!(full.back, plane.back);
                    let (z, z_plane) = (full.depth.unwrap(), plane.depth.unwrap());
                    assert!((z - z_plane).abs() <= 1e-12 * z, "{z} {z_plane}");
                }
            }
        }
        // Seen from behind, the side flips.
        let flipped = MovingTriangle {
            start: [2, 1, 0].map(|k| triangle.start[k]),
            delta: [2, 1, 0].map(|k| triangle.delta[k]),
        };
        let d = DVec3::new(0.0, 0.0, -1.0);
        assert_ne!(
            triangle.plane_hit(d, 0.5).back,
            flipped.plane_hit(d, 0.5).back
        );
        assert_ne!(
            triangle.depth_function().along(d).plane_hit(0.5).back,
            flipped.depth_function().along(d).plane_hit(0.5).back
        );
    }

    /// A still face's samples are inserted and shaded from its depth function alone; the image
    /// must not change by a bit against its corners' hit, on either side of the plane and where
    /// the ray misses it edge-on or behind.
    #[test]
    fn the_hit_at_the_start_is_the_corners_plane_hit_to_the_bit() {
        let triangle = turning_in_depth();
        let flipped = MovingTriangle {
            start: [2, 1, 0].map(|k| triangle.start[k]),
            delta: [2, 1, 0].map(|k| triangle.delta[k]),
        };
        let mut sides = [0, 0];
        for triangle in [triangle, flipped] {
            let function = triangle.depth_function();
            for (x, y) in [
                (0.0, 0.0),
                (0.05, 0.1),
                (-0.1, -0.05),
                (2.0, 3.0),
                (-7.0, 0.3),
            ] {
                let d = DVec3::new(x, y, -1.0);
                let (corners, plane) = (triangle.plane_hit(d, 0.0), function.hit_at_start(d));
                assert_eq!(corners.back, plane.back, "{d}");
                assert_eq!(
                    corners.depth.map(f64::to_bits),
                    plane.depth.map(f64::to_bits),
                    "{d}"
                );
                sides[usize::from(plane.back)] += 1;
            }
        }
        assert_eq!(sides, [5, 5], "both sides are met");
        // A ray along the plane meets it nowhere, from the corners and from the function.
        let [a, b, c] = triangle.start;
        let along_plane = (b - a).lerp(c - a, 0.5);
        let d = along_plane / -along_plane.z;
        assert_eq!(triangle.plane_hit(d, 0.0).depth.map(f64::to_bits), {
            triangle
                .depth_function()
                .hit_at_start(d)
                .depth
                .map(f64::to_bits)
        });
    }

    #[test]
    fn a_still_planes_depths_over_a_rectangle_of_rays_lie_between_its_corners() {
        let triangle = MovingTriangle {
            start: [
                DVec3::new(-1.0, -0.5, -3.0),
                DVec3::new(1.5, -0.2, -6.0),
                DVec3::new(0.1, 1.2, -4.0),
            ],
            delta: [DVec3::ZERO; 3],
        };
        let ray = |x: f64, y: f64| DVec3::new(x, y, -1.0);
        let [x0, y0, x1, y1] = [-0.2, -0.15, 0.25, 0.1];
        let corners = [ray(x0, y0), ray(x1, y0), ray(x0, y1), ray(x1, y1)];
        let [lo, hi] = triangle.plane_depths_within(corners).unwrap();
        assert!(hi > lo * 1.1, "a plane in depth: {lo} {hi}");
        for i in 0..=10 {
            for j in 0..=10 {
                let (u, v) = (f64::from(i) / 10.0, f64::from(j) / 10.0);
                let d = ray(x0 + (x1 - x0) * u, y0 + (y1 - y0) * v);
                let z = triangle.plane_hit(d, 0.0).depth.unwrap();
                assert!(
                    z >= lo * (1.0 - 1e-12) && z <= hi * (1.0 + 1e-12),
                    "{z} in {lo}..{hi}"
                );
            }
        }
        // Seen edge-on from one corner ray (it runs along the plane): nothing is bounded.
        let along = triangle.start[1] - triangle.start[0];
        let edge_on = along / -along.z;
        assert!(triangle
            .plane_depths_within([edge_on, corners[1], corners[2], corners[3]])
            .is_none());
    }

    #[test]
    fn the_depth_range_holds_every_depth_of_its_span_and_is_exact_for_a_line() {
        let turning = turning_in_depth();
        let d = DVec3::new(0.05, 0.02, -1.0);
        let along = turning.depth_function().along(d);
        let mut widths = Vec::new();
        for span in [[0.0, 1.0], [0.2, 0.6], [0.4, 0.45], [0.7, 0.7001]] {
            let [lowest, highest] = along.range(span).unwrap();
            let (mut least, mut most) = (f64::INFINITY, f64::NEG_INFINITY);
            for step in 0..=1000 {
                let s = span[0] + (span[1] - span[0]) * f64::from(step) / 1000.0;
                let z = along.at(s).unwrap();
                (least, most) = (least.min(z), most.max(z));
            }
            assert!(lowest <= least * (1.0 + 1e-12) && highest >= most * (1.0 - 1e-12));
            widths.push((highest - lowest) / (most - least));
        }
        // The bound closes in on the depth's own range as the span shrinks.
        assert!(widths[3] < 1.0 + 1e-3, "{widths:?}");
        // A translation keeps the plane's normal: the depth is a line and its range is its ends.
        let sliding = MovingTriangle {
            start: turning.start,
            delta: [DVec3::new(0.4, -0.1, -0.5); 3],
        };
        let along = sliding.depth_function().along(d);
        let [lowest, highest] = along.range([0.25, 0.75]).unwrap();
        let ends = [along.at(0.25).unwrap(), along.at(0.75).unwrap()];
        assert!((lowest - ends[0].min(ends[1])).abs() <= 1e-12 * lowest);
        assert!((highest - ends[0].max(ends[1])).abs() <= 1e-12 * highest);
    }

    #[test]
    fn back_facing_throughout_needs_every_instant_back_facing() {
        // Counter-clockwise seen from +z: facing the eye at the origin from z = −2.
        let facing = translating(-1.0, 1.0);
        assert!(!facing.back_facing_throughout());
        let mut away = facing;
        away.start.swap(0, 1);
        away.delta.swap(0, 1);
        assert!(away.back_facing_throughout());
        // Turning over during the segment: corner 2 passes through the plane of the others'
        // line of sight, so it faces the eye part of the time and is kept.
        let mut turning = away;
        turning.delta[2] =
            DVec3::new(0.0, -1.0, 0.0) - turning.start[2] + DVec3::new(0.0, 0.0, -2.0);
        assert!(!turning.back_facing_throughout());
    }

    #[test]
    fn near_plane_crossings_clip_the_time() {
        // Corner 0 goes from depth 2 to depth 0: it reaches the near plane 0.5 at s = 0.75.
        let mut t = translating(0.0, 0.0);
        t.delta[0] = DVec3::new(0.0, 0.0, 2.0);
        let [lo, hi] = t.in_front(0.5).unwrap();
        assert!(lo == 0.0 && (hi - 0.75).abs() < 1e-12);
        t.delta = [DVec3::new(0.0, 0.0, 5.0); 3];
        let [lo, hi] = t.in_front(0.5).unwrap();
        assert!(lo == 0.0 && (hi - 0.3).abs() < 1e-12);
        t.start = [DVec3::new(0.0, 0.0, 1.0); 3];
        assert!(t.in_front(0.5).is_none());
    }
}
