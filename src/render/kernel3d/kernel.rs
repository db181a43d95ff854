//! The 3D spatio-temporal kernel of one surfel over one sub-frame (Heinzle et al. 2010, §4.1,
//! Fig. 3), its screen bound (§4.3, Fig. 5), and its fragment on one pixel ray (§4.2).
//!
//! The kernel is spanned by the splat axes a1, a2 and the motion axis a3 = m/2 (half the
//! sub-frame's motion m, so that kernel time s ∈ [−1, 1] spans the sub-frame): at time s the
//! splat sits at c + s·a3. Everything is in camera space and f64.

use super::integral::RayQuadratic;
use crate::math::Sym2;
use crate::project::plane_depth_gradient;
use crate::raster::{CUTOFF_SIGMAS, PREFILTER_VARIANCE_PX2, TRUNCATION_GAIN};
use crate::render::abuffer::{Coverage, Fragment};
use crate::scene::camera::Camera;
use glam::{DVec2, DVec3};

/// Squared cut-off radius of the kernel's cylinder, in standard deviations (as the rasterizer's).
const CUTOFF_SQ: f64 = CUTOFF_SIGMAS * CUTOFF_SIGMAS;

/// Most the object-space pre-filter may enlarge a splat axis before the kernel is evaluated with
/// the affine (EWA) map instead. A splat seen nearly edge-on would have to be stretched across
/// a long stretch of its plane, which then runs almost along the pixel rays: the ray–plane
/// intersection becomes singular within a pixel, and the stretched splat reaches depths where
/// the projection at its centre no longer describes it (measured: 17× too much light from a square
/// tilted 0.01 rad from edge-on). Heinzle §5.2 meets the same trouble with a minimum angle.
const MAX_PREFILTER_STRETCH: f64 = 2.0;

/// Below this |cos| between the splat normal and a pixel ray, the ray runs along the splat plane:
/// the splat covers no area there, and the intersection would divide by ~0.
const MIN_RAY_COSINE: f64 = 1e-9;

/// The depth tolerance grows as the ray grazes the splat, up to this cosine (20×).
const MIN_TOLERANCE_COSINE: f64 = 0.05;

/// Points projected around each end's cut-off ellipse to bound it on screen; the bound is
/// widened by [`BOUND_MARGIN`] for the arcs between them (1 − cos(π/16) < 2 %).
const BOUND_SAMPLES: usize = 16;
const BOUND_MARGIN: f64 = 0.02;

/// One surfel's kernel over one sub-frame.
#[derive(Clone, Copy, Debug)]
pub(super) struct Kernel {
    /// Splat centre at the sub-frame's middle (the chord's midpoint), camera space.
    pub centre: DVec3,
    /// a3: half the sub-frame's motion.
    pub half_motion: DVec3,
    /// a1, a2: the splat axes (σ-scaled), enlarged by the object-space pre-filter (§4.1).
    pub axes: [DVec3; 2],
    /// Coverage density at the splat centre: area / (2π |a1 × a2|), times the truncation gain.
    pub amplitude: f64,
    /// Shaded linear RGB at the sub-frame's middle.
    pub colour: [f32; 3],
    /// The sub-frame's interval on the shutter-mass axis.
    pub mass: [f64; 2],
    /// Depth distance within which another fragment counts as the same surface.
    pub tolerance: f64,
    /// The screen-space stand-in for a splat seen too nearly edge-on to intersect rays with.
    pub affine: Option<AffineKernel>,
}

/// A kernel evaluated with the affine map at its centre, as EWA splatting does: the screen
/// Gaussian Σ + σ_f² I moving along the projected chord.
#[derive(Clone, Copy, Debug)]
pub(super) struct AffineKernel {
    /// Screen position at the sub-frame's middle, px.
    centre: DVec2,
    /// Half the projected chord, px.
    half_motion: DVec2,
    /// Inverse of Σ + σ_f² I (xx, xy, yy).
    conic: [f64; 3],
    /// Coverage at the centre: screen area / (2π √det(Σ + σ_f² I)), times the truncation gain.
    amplitude: f64,
    /// Depth at the middle, and half its change over the sub-frame.
    depth: f64,
    half_depth_change: f64,
    /// Screen gradient of the splat plane's depth, per px: splats of one oblique surface meet a
    /// pixel at one depth, not at their centres' depths.
    depth_gradient: DVec2,
    /// How far the splat's cut-off disc reaches from its centre: no ray meets the disc farther
    /// from the centre's depth, so the plane's depth at a pixel is not taken beyond it (past the
    /// disc only the pre-filter carries the footprint).
    depth_reach: f64,
}

impl AffineKernel {
    /// Screen boxes of the cut-off ellipse at the sub-frame's two ends: the covariance's
    /// diagonal (the conic's, divided by its determinant) gives the half-extents.
    fn end_boxes(&self) -> [[f64; 4]; 2] {
        let [xx, xy, yy] = self.conic;
        let det = xx * yy - xy * xy;
        let half = DVec2::new((yy / det).sqrt(), (xx / det).sqrt()) * CUTOFF_SIGMAS + 1.0;
        [-1.0, 1.0].map(|sign| {
            let c = self.centre + self.half_motion * sign;
            [c.x - half.x, c.y - half.y, c.x + half.x, c.y + half.y]
        })
    }
}

/// The plane and dual basis of a kernel, made once per kernel and tile.
pub(super) struct Prepared<'a> {
    kernel: &'a Kernel,
    normal: DVec3,
    /// |normal|.
    normal_length: f64,
    dual: [DVec3; 2],
    index: u32,
}

impl Kernel {
    /// The kernel of a splat seen at the sub-frame's start (`p0`) and end (`p1`) with camera-space
    /// axes `axes` at its middle; `density` is the surfel's area over the area of its axes'
    /// parallelogram (both in object space, so that a keyframe's scale cancels). `None` when it
    /// has no area.
    pub fn new(
        camera: &Camera,
        p0: DVec3,
        p1: DVec3,
        axes: [DVec3; 2],
        density: f64,
        colour: [f32; 3],
        mass: [f64; 2],
    ) -> Option<Kernel> {
        let centre = 0.5 * (p0 + p1);
        let depth = -centre.z;
        if !(depth > 0.0) {
            return None;
        }
        // §4.1: the screen pre-filter stood in for in object space. With M the 2×2 map from the
        // splat's own coordinates (in standard deviations) to pixels, the screen covariance is
        // M Mᵀ; widening the splat's covariance from I to C = I + σ_f² (MᵀM)⁻¹ makes it
        // M C Mᵀ = M Mᵀ + σ_f² I, the EWA splat's Σ + σ_f² I, in whichever direction the splat is
        // foreshortened.
        let jacobian = camera.jacobian(centre);
        let [m1, m2] = axes.map(|axis| jacobian.apply(axis));
        let gram = [m1.dot(m1), m1.dot(m2), m2.dot(m2)];
        let det = gram[0] * gram[2] - gram[1] * gram[1];
        if !(det > 0.0) {
            // Seen exactly edge-on (or degenerate): it covers no area on screen.
            return None;
        }
        let k = PREFILTER_VARIANCE_PX2 / det;
        let widened = Sym2 {
            xx: 1.0 + k * gram[2],
            xy: -k * gram[1],
            yy: 1.0 + k * gram[0],
        };
        let (values, vectors) = widened.eigen();
        let limit = MAX_PREFILTER_STRETCH * MAX_PREFILTER_STRETCH;
        let view_area = axes[0].cross(axes[1]).length();
        // The affine stand-in projects the chord's ends; one that crosses the near plane is
        // ray-traced instead, whose fragments keep the part in front (dropped, the whole
        // sub-frame of a nearly edge-on splat was lost).
        let in_front = [p0, p1].iter().all(|p| -p.z >= camera.near);
        let affine = if values[0] > limit && in_front {
            let normal = axes[0].cross(axes[1]);
            let reach = CUTOFF_SIGMAS * axes[0].length().max(axes[1].length());
            let gradient = plane_depth_gradient(camera, centre, normal, depth, reach);
            Some(affine_kernel(
                camera,
                p0,
                p1,
                [m1, m2],
                density,
                gradient,
                reach,
            )?)
        } else {
            None
        };
        let axes = [0, 1].map(|i| {
            (axes[0] * vectors[i].x + axes[1] * vectors[i].y) * values[i].min(limit).sqrt()
        });
        let spread = axes[0].cross(axes[1]).length();
        let amplitude = TRUNCATION_GAIN * density * view_area / (std::f64::consts::TAU * spread);
        let kernel = Kernel {
            centre,
            half_motion: 0.5 * (p1 - p0),
            axes,
            amplitude,
            colour,
            mass,
            tolerance: CUTOFF_SIGMAS * axes[0].length().max(axes[1].length()),
            affine,
        };
        (amplitude.is_finite()
            && amplitude > 0.0
            && centre.is_finite()
            && kernel.half_motion.is_finite())
        .then_some(kernel)
    }

    /// Pixel bounds [x0, y0, x1, y1) of the kernel's cylinder, clipped to the image, and the
    /// convex hull of its two end ellipses' bounding boxes (§4.3, Fig. 5); `None` when off-screen.
    /// A kernel reaching behind the near plane is bounded by the whole image.
    pub fn screen_bound(&self, camera: &Camera) -> Option<([u32; 4], Vec<DVec2>)> {
        let (w, h) = (f64::from(camera.width), f64::from(camera.height));
        let boxes = match &self.affine {
            Some(affine) => affine.end_boxes(),
            None => match self.projected_end_boxes(camera) {
                Some(boxes) => boxes,
                None => {
                    let hull = vec![
                        DVec2::ZERO,
                        DVec2::new(w, 0.0),
                        DVec2::new(w, h),
                        DVec2::new(0.0, h),
                    ];
                    return Some(([0, 0, camera.width, camera.height], hull));
                }
            },
        };
        let union = [
            boxes[0][0].min(boxes[1][0]),
            boxes[0][1].min(boxes[1][1]),
            boxes[0][2].max(boxes[1][2]),
            boxes[0][3].max(boxes[1][3]),
        ];
        let clip = |v: f64, max: f64| v.clamp(0.0, max) as u32;
        let bounds = [
            clip(union[0].floor(), w),
            clip(union[1].floor(), h),
            clip(union[2].ceil(), w),
            clip(union[3].ceil(), h),
        ];
        (bounds[0] < bounds[2] && bounds[1] < bounds[3])
            .then(|| (bounds, hull_of_boxes(boxes[0], boxes[1])))
    }

    /// Screen boxes [x0, y0, x1, y1] of the cut-off ellipses at the sub-frame's two ends, from
    /// points projected around them (1 px wider, for the pre-filter's tail and rounding); `None`
    /// when a point lies behind the near plane.
    fn projected_end_boxes(&self, camera: &Camera) -> Option<[[f64; 4]; 2]> {
        let mut boxes = [[0.0; 4]; 2];
        for (bound, sign) in boxes.iter_mut().zip([-1.0, 1.0]) {
            *bound = [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ];
            let centre = self.centre + self.half_motion * sign;
            for i in 0..BOUND_SAMPLES {
                let angle = std::f64::consts::TAU * i as f64 / BOUND_SAMPLES as f64;
                let p = centre
                    + CUTOFF_SIGMAS
                        * (1.0 + BOUND_MARGIN)
                        * (self.axes[0] * angle.cos() + self.axes[1] * angle.sin());
                let (px, _) = camera.project(p)?;
                *bound = [
                    bound[0].min(px.x - 1.0),
                    bound[1].min(px.y - 1.0),
                    bound[2].max(px.x + 1.0),
                    bound[3].max(px.y + 1.0),
                ];
            }
        }
        Some(boxes)
    }

    /// The plane and dual basis for evaluating rays; `index` names the kernel in fragments.
    pub fn prepare(&self, index: u32) -> Prepared<'_> {
        let [a1, a2] = self.axes;
        let normal = a1.cross(a2);
        // Dual basis: (x·dual[i]) is x's coordinate along axis i, for x in the splat plane.
        let d1 = a2.cross(normal);
        let d2 = normal.cross(a1);
        Prepared {
            kernel: self,
            normal,
            normal_length: normal.length(),
            dual: [d1 / a1.dot(d1), d2 / a2.dot(d2)],
            index,
        }
    }
}

impl Prepared<'_> {
    /// The fragment the kernel leaves on the camera-space ray with direction `ray` (z = −1, so
    /// the ray parameter is the depth) through the centre of pixel `pixel`, in front of `near`;
    /// `None` when the ray misses the kernel's cylinder.
    pub fn fragment(
        &self,
        (ray, ray_length): (DVec3, f64),
        pixel: DVec2,
        near: f64,
    ) -> Option<Fragment> {
        let k = self.kernel;
        // `depth0 + s·depth1` is the depth of the splat's centre at kernel time s, which decides
        // the near plane; `offset(s)` is how far the depth the ternary test compares lies from it.
        let (quadratic, amplitude, depth0, depth1, offset, tolerance) = match &k.affine {
            Some(affine) => {
                // (x − c − s h)ᵀ K (x − c − s h): a = hᵀKh, b = −dᵀKh, c = dᵀKd with d = x − c.
                let [xx, xy, yy] = affine.conic;
                let form = |u: DVec2, v: DVec2| {
                    xx * u.x * v.x + xy * (u.x * v.y + u.y * v.x) + yy * u.y * v.y
                };
                let (d, h) = (pixel - affine.centre, affine.half_motion);
                let quadratic = RayQuadratic {
                    a: form(h, h),
                    b: -form(d, h),
                    c: form(d, d),
                };
                // The plane's depth at the pixel, under the centre as it is at kernel time s (the
                // plane slides with it, as a motion footprint's does: project.rs); as for EWA
                // footprints it moves across the pre-filter's reach, which the ternary test must
                // allow, but it is taken no farther than the disc's own depth range. A splat seen
                // nearly edge-on has a steep plane: unbounded, its depth a pixel away landed
                // metres in front of or behind the surface, between other surfaces.
                let offset = Offset::Plane {
                    gradient: affine.depth_gradient,
                    from_centre: d,
                    half_motion: h,
                    limit: affine.depth_reach,
                };
                let reach = CUTOFF_SIGMAS * PREFILTER_VARIANCE_PX2.sqrt();
                let tolerance = k.tolerance + affine.depth_gradient.length() * reach;
                (
                    quadratic,
                    affine.amplitude,
                    affine.depth,
                    affine.half_depth_change,
                    offset,
                    tolerance,
                )
            }
            None => {
                let along = self.normal.dot(ray);
                let cosine = along.abs() / (self.normal_length * ray_length);
                if !(cosine > MIN_RAY_COSINE) {
                    return None;
                }
                // Depth of the hit at kernel time s: λ(s) = n·(c + s a3) / n·d, affine in s.
                let depth0 = self.normal.dot(k.centre) / along;
                let depth1 = self.normal.dot(k.half_motion) / along;
                // Splat coordinates of the hit: (λ(s) d − c − s a3)·dual, affine in s: p + s q.
                let coordinate = |dual: DVec3| {
                    let ray_dual = ray.dot(dual);
                    (
                        depth0 * ray_dual - k.centre.dot(dual),
                        depth1 * ray_dual - k.half_motion.dot(dual),
                    )
                };
                let (u0, u1) = coordinate(self.dual[0]);
                let (v0, v1) = coordinate(self.dual[1]);
                let quadratic = RayQuadratic {
                    a: u1 * u1 + v1 * v1,
                    b: u0 * u1 + v0 * v1,
                    c: u0 * u0 + v0 * v0,
                };
                // Hits of one surface's neighbouring splat planes spread in depth as the ray
                // grazes them.
                let tolerance = k.tolerance / cosine.max(MIN_TOLERANCE_COSINE);
                (
                    quadratic,
                    k.amplitude,
                    depth0,
                    depth1,
                    Offset::None,
                    tolerance,
                )
            }
        };
        // The part of the kernel's time [−1, 1] in front of the near plane.
        let [k0, k1] = k.mass;
        let (mut lo, mut hi) = (-1.0f64, 1.0f64);
        if depth1 != 0.0 {
            let crossing = (near - depth0) / depth1;
            if depth1 > 0.0 {
                lo = lo.max(crossing);
            } else {
                hi = hi.min(crossing);
            }
        } else if !(depth0 >= near) {
            return None;
        }
        let [s0, s1] = quadratic.support(CUTOFF_SQ, lo, hi)?;
        let to_mass = |s: f64| k0 + 0.5 * (s + 1.0) * (k1 - k0);
        let fragment = Fragment {
            mass: [to_mass(s0), to_mass(s1)],
            coverage: Coverage::Kernel {
                kernel_mass: k.mass,
                primitive: quadratic.primitive([s0, s1]),
                scale: amplitude * 0.5 * (k1 - k0),
            },
            depth: [s0, s1].map(|s| depth0 + s * depth1 + offset.at(s)),
            colour: k.colour,
            tolerance,
            id: self.index,
        };
        (fragment.mass[1] > fragment.mass[0] && fragment.depth.iter().all(|d| d.is_finite()))
            .then_some(fragment)
    }
}

/// How far the depth a fragment's ternary test compares lies from the depth of its splat's
/// centre, at kernel time s.
enum Offset {
    /// Nowhere: the depth is the ray's hit on the splat's plane.
    None,
    /// The affine stand-in's plane at the pixel, `from_centre` away from the centre at s = 0,
    /// while the centre moves by `half_motion` per unit of s; at most `limit` either way.
    Plane {
        gradient: DVec2,
        from_centre: DVec2,
        half_motion: DVec2,
        limit: f64,
    },
}

impl Offset {
    fn at(&self, s: f64) -> f64 {
        match *self {
            Offset::None => 0.0,
            Offset::Plane {
                gradient,
                from_centre,
                half_motion,
                limit,
            } => gradient
                .dot(from_centre - s * half_motion)
                .clamp(-limit, limit),
        }
    }
}

/// The affine stand-in for a kernel whose splat at its centre maps to the screen by the columns
/// `m` (px per standard deviation) and covers `density` of its object-space parallelogram.
fn affine_kernel(
    camera: &Camera,
    p0: DVec3,
    p1: DVec3,
    [m1, m2]: [DVec2; 2],
    density: f64,
    depth_gradient: DVec2,
    depth_reach: f64,
) -> Option<AffineKernel> {
    let (s0, d0) = camera.project(p0)?;
    let (s1, d1) = camera.project(p1)?;
    let covariance = [
        m1.x * m1.x + m2.x * m2.x + PREFILTER_VARIANCE_PX2,
        m1.x * m1.y + m2.x * m2.y,
        m1.y * m1.y + m2.y * m2.y + PREFILTER_VARIANCE_PX2,
    ];
    let det = covariance[0] * covariance[2] - covariance[1] * covariance[1];
    let screen_area = density * m1.perp_dot(m2).abs();
    let affine = AffineKernel {
        centre: 0.5 * (s0 + s1),
        half_motion: 0.5 * (s1 - s0),
        conic: [
            covariance[2] / det,
            -covariance[1] / det,
            covariance[0] / det,
        ],
        amplitude: TRUNCATION_GAIN * screen_area / (std::f64::consts::TAU * det.sqrt()),
        depth: 0.5 * (d0 + d1),
        half_depth_change: 0.5 * (d1 - d0),
        depth_gradient,
        depth_reach,
    };
    (det > 0.0 && affine.amplitude.is_finite()).then_some(affine)
}

/// The convex hull of two axis-aligned boxes [x0, y0, x1, y1], counter-clockwise in screen
/// coordinates (§4.3, Fig. 5): each corner of one box is kept unless it lies in the inside quadrant
/// of the other box's corresponding corner.
fn hull_of_boxes(a: [f64; 4], b: [f64; 4]) -> Vec<DVec2> {
    // Corners in order: top-left, bottom-left, bottom-right, top-right, each with the direction
    // pointing out of the box there.
    let corners = |r: [f64; 4]| {
        [
            DVec2::new(r[0], r[1]),
            DVec2::new(r[0], r[3]),
            DVec2::new(r[2], r[3]),
            DVec2::new(r[2], r[1]),
        ]
    };
    const OUT: [DVec2; 4] = [
        DVec2::new(-1.0, -1.0),
        DVec2::new(-1.0, 1.0),
        DVec2::new(1.0, 1.0),
        DVec2::new(1.0, -1.0),
    ];
    let (ca, cb) = (corners(a), corners(b));
    let mut hull = Vec::with_capacity(8);
    for i in 0..4 {
        let (p, q, out) = (ca[i], cb[i], OUT[i]);
        // p is inside q's quadrant when it is not farther out than q along both axes.
        let p_inside = (p.x - q.x) * out.x <= 0.0 && (p.y - q.y) * out.y <= 0.0;
        let q_inside = (q.x - p.x) * out.x <= 0.0 && (q.y - p.y) * out.y <= 0.0;
        match (p_inside, q_inside) {
            (true, _) => hull.push(q),
            (false, true) => hull.push(p),
            // Neither dominates: both are on the hull, in the order that keeps it convex.
            (false, false) => {
                let ordered = if (q - p).perp_dot(out) > 0.0 {
                    [p, q]
                } else {
                    [q, p]
                };
                hull.extend(ordered);
            }
        }
    }
    hull
}

/// Whether the convex polygon `hull` overlaps the rectangle [x0, y0, x1, y1] (separating axes).
pub(super) fn hull_overlaps(hull: &[DVec2], rect: [f64; 4]) -> bool {
    let xs = hull.iter().map(|p| p.x);
    let ys = hull.iter().map(|p| p.y);
    if xs.clone().fold(f64::INFINITY, f64::min) > rect[2]
        || xs.fold(f64::NEG_INFINITY, f64::max) < rect[0]
        || ys.clone().fold(f64::INFINITY, f64::min) > rect[3]
        || ys.fold(f64::NEG_INFINITY, f64::max) < rect[1]
    {
        return false;
    }
    let corners = [
        DVec2::new(rect[0], rect[1]),
        DVec2::new(rect[2], rect[1]),
        DVec2::new(rect[2], rect[3]),
        DVec2::new(rect[0], rect[3]),
    ];
    for i in 0..hull.len() {
        let (p, q) = (hull[i], hull[(i + 1) % hull.len()]);
        let normal = (q - p).perp();
        let side = |c: DVec2| (c - p).dot(normal);
        let inside_sign = hull
            .iter()
            .map(|&v| side(v))
            .find(|s| s.abs() > 1e-9)
            .unwrap_or(0.0);
        if inside_sign != 0.0 && corners.iter().all(|&c| side(c) * inside_sign < 0.0) {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_affine_kernel_s_depth_is_its_plane_s_under_the_centre_as_it_moves() {
        // A nearly edge-on splat drawn by its affine stand-in slides 20 px along x over a plane
        // whose depth rises 0.1 per px: at a pixel 5 px right of the middle, the depth the
        // ternary test compares is the plane's under the centre where it is at each end of the
        // fragment, within the disc's reach of 0.3 (it was the plane's under the middle
        // position, 5.3 at both ends).
        let affine = AffineKernel {
            centre: DVec2::new(50.0, 50.0),
            half_motion: DVec2::new(10.0, 0.0),
            conic: [0.25, 0.0, 0.25],
            amplitude: 1.0,
            depth: 5.0,
            half_depth_change: 0.0,
            depth_gradient: DVec2::new(0.1, 0.0),
            depth_reach: 0.3,
        };
        let kernel = Kernel {
            centre: DVec3::new(0.0, 0.0, -5.0),
            half_motion: DVec3::ZERO,
            axes: [DVec3::X, DVec3::Z],
            amplitude: 1.0,
            colour: [1.0; 3],
            mass: [0.0, 1.0],
            tolerance: 0.01,
            affine: Some(affine),
        };
        let ray = DVec3::new(0.0, 0.0, -1.0);
        let fragment = (kernel.prepare(0))
            .fragment((ray, 1.0), DVec2::new(55.0, 50.0), 0.1)
            .unwrap();
        for (m, depth) in fragment.mass.into_iter().zip(fragment.depth) {
            let s = 2.0 * m - 1.0;
            let plane = 5.0 + (0.1 * (5.0 - 10.0 * s)).clamp(-0.3, 0.3);
            assert!(
                (depth - plane).abs() < 1e-12,
                "s = {s}: {depth} against {plane}"
            );
        }
        assert!(
            fragment.depth[0] > fragment.depth[1],
            "{:?}",
            fragment.depth
        );
    }

    #[test]
    fn a_nearly_edge_on_splat_crossing_the_near_plane_keeps_the_part_in_front() {
        // A splat nearly edge-on (its affine stand-in's case) moving from in front of the
        // camera's near plane to behind it keeps a kernel, and rays through its path in front
        // meet it.
        let camera = Camera::new(DVec3::ZERO, -DVec3::Z, DVec3::Y, 60.0, 64, 64)
            .unwrap()
            .with_near(0.5)
            .unwrap();
        let tilt = 89.9f64.to_radians();
        let axes = [
            DVec3::X * 0.05,
            DVec3::new(0.0, tilt.cos(), tilt.sin()) * 0.05,
        ];
        // Below the eye, so that rays below the image's middle meet its plane in front.
        let (p0, p1) = (DVec3::new(0.02, -0.1, -3.0), DVec3::new(0.02, -0.1, -0.2));
        let edge_on = |p1: DVec3| Kernel::new(&camera, p0, p1, axes, 1.0, [1.0; 3], [0.0, 1.0]);
        let in_front = edge_on(DVec3::new(0.02, -0.1, -0.6)).expect("in front all along");
        assert!(in_front.affine.is_some(), "the affine stand-in's case");
        let crossing = edge_on(p1).expect("crossing the near plane");
        let (bounds, _) = crossing.screen_bound(&camera).expect("on screen");
        let prepared = crossing.prepare(0);
        let hits = (bounds[0]..bounds[2])
            .flat_map(|x| (bounds[1]..bounds[3]).map(move |y| (x, y)))
            .filter(|&(x, y)| {
                let pixel = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                let ray = camera.ray(pixel.x, pixel.y);
                prepared
                    .fragment((ray, ray.length()), pixel, camera.near)
                    .is_some_and(|f| f.depth.iter().all(|&d| d >= camera.near))
            })
            .count();
        assert!(hits > 0);
    }

    fn is_convex_and_contains(hull: &[DVec2], points: &[DVec2]) -> bool {
        let n = hull.len();
        let mut sign = 0.0;
        for i in 0..n {
            let (p, q) = (hull[i], hull[(i + 1) % n]);
            for &x in points.iter().chain(hull) {
                let s = (q - p).perp_dot(x - p);
                if s.abs() < 1e-9 {
                    continue;
                }
                if sign == 0.0 {
                    sign = s.signum();
                } else if s.signum() != sign {
                    return false;
                }
            }
        }
        true
    }

    #[test]
    fn the_hull_of_two_boxes_is_convex_and_contains_both() {
        let cases = [
            ([0.0, 0.0, 2.0, 1.0], [5.0, 4.0, 7.0, 5.0]),
            ([5.0, 4.0, 7.0, 5.0], [0.0, 0.0, 2.0, 1.0]),
            ([0.0, 4.0, 2.0, 5.0], [5.0, 0.0, 7.0, 1.0]),
            ([0.0, 0.0, 4.0, 4.0], [1.0, 1.0, 2.0, 2.0]),
            ([0.0, 0.0, 4.0, 1.0], [1.0, -3.0, 2.0, 5.0]),
        ];
        for (a, b) in cases {
            let hull = hull_of_boxes(a, b);
            let corners: Vec<DVec2> = [a, b]
                .iter()
                .flat_map(|r| {
                    [
                        DVec2::new(r[0], r[1]),
                        DVec2::new(r[2], r[1]),
                        DVec2::new(r[2], r[3]),
                        DVec2::new(r[0], r[3]),
                    ]
                })
                .collect();
            assert!(
                is_convex_and_contains(&hull, &corners),
                "{a:?} {b:?}: {hull:?}"
            );
        }
        // Diagonal boxes: the hull is tighter than their union's bounding box.
        let hull = hull_of_boxes([0.0, 0.0, 1.0, 1.0], [9.0, 9.0, 10.0, 10.0]);
        assert!(!hull_overlaps(&hull, [8.0, 0.0, 10.0, 2.0]));
        assert!(hull_overlaps(&hull, [4.0, 4.0, 6.0, 6.0]));
    }
}
