//! The shared projection stage: a surfel at an instant → what the camera sees of it, and the two
//! footprints made of such views: the sharp EWA splat ([`static_footprint`]) and the motion
//! ellipse of a sub-segment ([`motion_ellipse`], Guan & Mueller §3.3).
//!
//! Every splat renderer asks this module where a surfel is on screen at time t, with which
//! screen covariance (Σ = J W V Wᵀ Jᵀ, docs/math.md "Projected splat covariance"), how much
//! screen area it covers, how deep it is and which colour it has after shading. This is the only
//! visibility gate before the rasterizer: points behind the near plane are not projected, and
//! back faces and off-screen footprints are culled, each counted in [`Culled`].

use crate::math::Sym2;
use crate::raster::{
    Footprint, Profile, Rejection, ScreenSplat, TimeExtent, CUTOFF_SIGMAS, MIN_STREAK_SIGMAS,
    PREFILTER_VARIANCE_PX2,
};
use crate::scene::camera::Camera;
use crate::scene::motion::{Motion, Pose};
use crate::scene::shutter::{Shutter, TimeMoments};
use crate::scene::{Lighting, Object};
use crate::surfels::Surfel;
use glam::{DAffine3, DMat3, DVec2, DVec3};
use rayon::prelude::*;

/// Depth tolerance of the ternary depth test, in standard deviations of the surfel's Gaussian:
/// splats of one surface within this distance blend, farther ones are another surface. Surfaces
/// closer together than this (thin shells) need a finer sampling.
pub const DEPTH_TOLERANCE_SIGMAS: f64 = 3.0;

/// Object → camera transforms of one object at one instant.
#[derive(Clone, Copy, Debug)]
pub struct Instant {
    to_view: DAffine3,
    /// Object → world, for shading (spot lights need the position).
    to_world: DAffine3,
    /// Object → world rotation, for shading normals.
    rotation: DMat3,
}

impl Instant {
    /// The transforms for `pose` seen by `camera`.
    #[must_use]
    pub fn new(camera: &Camera, pose: &Pose) -> Self {
        let to_world = pose.to_affine();
        Instant {
            to_view: camera.view * to_world,
            to_world,
            rotation: pose.rotation_matrix(),
        }
    }

    /// An object-space point in camera space.
    #[must_use]
    pub fn view_point(&self, p: DVec3) -> DVec3 {
        self.to_view.transform_point3(p)
    }

    /// An object-space vector in camera space.
    #[must_use]
    pub fn view_vector(&self, v: DVec3) -> DVec3 {
        self.to_view.transform_vector3(v)
    }

    /// Where an object-space point is on screen, `None` when not in front of the near plane.
    #[must_use]
    pub fn screen_point(&self, camera: &Camera, p: DVec3) -> Option<DVec2> {
        camera.project(self.view_point(p)).map(|(screen, _)| screen)
    }

    /// An object-space point in world space.
    #[must_use]
    pub fn world_point(&self, p: DVec3) -> DVec3 {
        self.to_world.transform_point3(p)
    }

    /// An object-space unit normal turned into world space.
    #[must_use]
    pub fn world_normal(&self, normal: DVec3) -> DVec3 {
        (self.rotation * normal).normalize_or_zero()
    }
}

/// A surfel as seen at one instant: its screen splat (covariance without the pre-filter, weight
/// equal to the screen area it covers) and whether it faces the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfelView {
    /// The splat on screen.
    pub splat: ScreenSplat,
    /// Cosine between its normal and the direction to the camera: positive when it faces it.
    pub facing: f64,
}

/// View of `surfel` at `instant`, or `None` when its centre is not in front of the near plane.
#[must_use]
pub fn view_surfel(
    camera: &Camera,
    instant: &Instant,
    lighting: &Lighting,
    surfel: &Surfel,
) -> Option<SurfelView> {
    let located = Located::new(camera, instant, surfel)?;
    Some(located.view(camera, instant, lighting, surfel))
}

/// Cosine between a view-space normal at `p_view` and the direction to the camera: positive when
/// the surface faces it.
#[inline]
pub(crate) fn facing(p_view: DVec3, normal_view: DVec3) -> f64 {
    -normal_view.dot(p_view) / (normal_view.length() * p_view.length())
}

/// Whether `surfel` faces the camera at `instant`, as the renderers cull it (by the same
/// arithmetic, so the two never disagree).
pub(crate) fn faces_camera(instant: &Instant, surfel: &Surfel) -> bool {
    facing(
        instant.view_point(surfel.position),
        instant.view_vector(surfel.normal),
    ) > 0.0
}

/// Where a surfel's centre is at one instant and whether it faces the camera: the cheap part of a
/// [`SurfelView`], enough to cull it.
struct Located {
    p_view: DVec3,
    normal_view: DVec3,
    center: DVec2,
    depth: f64,
    facing: f64,
}

impl Located {
    /// `None` when the centre is not in front of the near plane.
    fn new(camera: &Camera, instant: &Instant, surfel: &Surfel) -> Option<Located> {
        let p_view = instant.view_point(surfel.position);
        let (center, depth) = camera.project(p_view)?;
        let normal_view = instant.view_vector(surfel.normal);
        Some(Located {
            p_view,
            normal_view,
            center,
            depth,
            facing: facing(p_view, normal_view),
        })
    }

    /// The whole view.
    fn view(
        self,
        camera: &Camera,
        instant: &Instant,
        lighting: &Lighting,
        surfel: &Surfel,
    ) -> SurfelView {
        let Located {
            p_view,
            normal_view,
            center,
            depth,
            facing,
        } = self;
        let u_view = instant.view_vector(surfel.axis_u);
        let v_view = instant.view_vector(surfel.axis_v);
        let jacobian = camera.jacobian(p_view);
        let (ju, jv) = (jacobian.apply(u_view), jacobian.apply(v_view));
        // Ratio of the axes' parallelogram areas on screen and in object space = the area scale.
        let object_area = surfel.axis_u.cross(surfel.axis_v).length();
        let disc_depth = DEPTH_TOLERANCE_SIGMAS * u_view.length().max(v_view.length());
        let depth_gradient = plane_depth_gradient(camera, p_view, normal_view, depth, disc_depth);
        // The pre-filter spreads the footprint beyond the disc; over that spread the plane's depth
        // moves by |∇D|·(cut-off radius of the pre-filter), which the ternary test must allow too.
        let prefilter_reach = CUTOFF_SIGMAS * PREFILTER_VARIANCE_PX2.sqrt();
        let depth_tolerance = disc_depth + depth_gradient.length() * prefilter_reach;
        SurfelView {
            splat: ScreenSplat {
                center,
                covariance: Sym2::outer(ju) + Sym2::outer(jv),
                weight: surfel.area * ju.perp_dot(jv).abs() / object_area,
                colour: lighting.shade(
                    surfel.colour,
                    instant.world_normal(surfel.normal),
                    instant.world_point(surfel.position),
                ),
                depth,
                depth_gradient,
                depth_tolerance,
                depth_rate: 0.0,
                time: TimeExtent::WHOLE_FRAME,
                profile: Profile::Gaussian,
                sweep: DVec2::ZERO,
                sweep_change: 0.0,
                colour_change: 0.0,
                additive: false,
            },
            facing,
        }
    }
}

/// Screen gradient of the depth of the plane through `p_view` with normal `normal_view`.
///
/// Along the ray through pixel offset (X, Y) from the image centre the plane lies at depth
/// D = (n·p) / (n_x X/f − n_y Y/f − n_z), so at the splat's centre ∂D/∂x = −D² n_x / (f n·p)
/// and ∂D/∂y = D² n_y / (f n·p). Near edge-on (n·p → 0) the plane is steep and the splat carries
/// almost no weight; the gradient is capped at a thousand disc depths per pixel so that it stays
/// finite.
pub(crate) fn plane_depth_gradient(
    camera: &Camera,
    p_view: DVec3,
    normal_view: DVec3,
    depth: f64,
    disc_depth: f64,
) -> DVec2 {
    let k = normal_view.dot(p_view);
    let gradient =
        DVec2::new(-normal_view.x, normal_view.y) * (depth * depth / (camera.focal_px * k));
    if gradient.is_finite() {
        gradient.clamp_length_max(1e3 * disc_depth)
    } else {
        DVec2::ZERO
    }
}

/// What the projection and culling left out, by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Culled {
    /// Facing away from the camera (for the whole interval, for moving renderers).
    pub back_facing: usize,
    /// Entirely outside the image.
    pub off_screen: usize,
    /// Centre behind the near plane.
    pub behind_near: usize,
    /// No weight: seen almost edge-on (exactly edge-on counts as back-facing), too faint, no
    /// shutter time, or not finite.
    pub degenerate: usize,
}

/// Why one surfel (or one of its segments) made no footprint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cull {
    /// Facing away from the camera.
    BackFacing,
    /// Centre not in front of the near plane.
    BehindNear,
    /// Refused by the rasterizer.
    Raster(Rejection),
}

impl Culled {
    /// Keep a footprint (or kernel) or count why there is none.
    pub(crate) fn keep<T>(&mut self, result: Result<T, Cull>, kept: &mut Vec<T>) {
        match result {
            Ok(f) => kept.push(f),
            Err(Cull::BackFacing) => self.back_facing += 1,
            Err(Cull::BehindNear) => self.behind_near += 1,
            Err(Cull::Raster(Rejection::OffScreen)) => self.off_screen += 1,
            Err(Cull::Raster(Rejection::Degenerate)) => self.degenerate += 1,
        }
    }

    /// Add another tally to this one.
    pub(crate) fn add(&mut self, other: &Culled) {
        self.back_facing += other.back_facing;
        self.off_screen += other.off_screen;
        self.behind_near += other.behind_near;
        self.degenerate += other.degenerate;
    }
}

/// Surfels per parallel task of [`per_surfel`].
const SURFEL_CHUNK: usize = 1024;

/// Run `make` for surfels 0..`count` in parallel, each keeping footprints or counting why not,
/// and append the results to `out` in surfel order (so the list does not depend on the thread
/// count); returns what was left out. Collecting per chunk of surfels keeps only what survives:
/// with hundreds of sub-segments per surfel, most of them off screen, collecting every result
/// first would cost gigabytes. The chunks go straight into `out`, each copied by the thread
/// that is free, into its own stretch: copied in turn on one thread, they took 3 ms of the knot's
/// 46 ms `static` render at 1024² (docs/history.md, "Footprints gathered in parallel, and
/// x86-64-v2").
pub fn per_surfel(
    count: usize,
    out: &mut Vec<Footprint>,
    make: impl Fn(usize, &mut Vec<Footprint>, &mut Culled) + Sync,
) -> Culled {
    let parts: Vec<(Vec<Footprint>, Culled)> = (0..count.div_ceil(SURFEL_CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let (mut kept, mut culled) = (Vec::with_capacity(SURFEL_CHUNK), Culled::default());
            for i in chunk * SURFEL_CHUNK..((chunk + 1) * SURFEL_CHUNK).min(count) {
                make(i, &mut kept, &mut culled);
            }
            (kept, culled)
        })
        .collect();
    let kept: Vec<&[Footprint]> = parts.iter().map(|(kept, _)| kept.as_slice()).collect();
    gather(&kept, out);
    let mut culled = Culled::default();
    for (_, c) in &parts {
        culled.add(c);
    }
    culled
}

/// Append `parts` to `out` in order, each part copied in parallel into its own stretch of
/// `out`'s new room.
fn gather<T: Copy + Send + Sync>(parts: &[&[T]], out: &mut Vec<T>) {
    let start = out.len();
    let total: usize = parts.iter().map(|p| p.len()).sum();
    out.reserve(total);
    let mut room = &mut out.spare_capacity_mut()[..total];
    let mut stretches = Vec::with_capacity(parts.len());
    for part in parts {
        let (stretch, rest) = room.split_at_mut(part.len());
        stretches.push(stretch);
        room = rest;
    }
    stretches
        .into_par_iter()
        .zip(parts)
        .for_each(|(stretch, part)| {
            // SAFETY: `stretch` is as long as `part` and lies in `out`'s spare room, which `part`
            // cannot overlap; `T: Copy`. One copy of the whole part: item by item, each footprint
            // was a call to `memmove`.
            unsafe {
                std::ptr::copy_nonoverlapping(
                    part.as_ptr(),
                    stretch.as_mut_ptr().cast::<T>(),
                    part.len(),
                );
            }
        });
    // SAFETY: the stretches tile the first `total` slots of the spare room, each as long as its
    // part, and every slot of each was written just above.
    unsafe { out.set_len(start + total) };
}

/// The footprint of a surfel view drawn sharp (the static EWA splat).
pub fn static_footprint(camera: &Camera, view: &SurfelView) -> Result<Footprint, Cull> {
    if !(view.facing > 0.0) {
        return Err(Cull::BackFacing);
    }
    let splat = ScreenSplat {
        covariance: view.splat.covariance + Sym2::isotropic(PREFILTER_VARIANCE_PX2),
        ..view.splat
    };
    splat
        .footprint(camera.width, camera.height)
        .map_err(Cull::Raster)
}

/// Sharp footprints at time `t` of `surfels` moving with `object` (its own, or merged by the
/// level of detail), appended to `footprints`. Back faces are culled before the rest of their
/// view is worked out.
pub fn object_footprints_at(
    camera: &Camera,
    lighting: &Lighting,
    (object, surfels): (&Object, &[Surfel]),
    t: f64,
    footprints: &mut Vec<Footprint>,
    culled: &mut Culled,
) {
    let instant = Instant::new(camera, &object.motion.pose_at(t));
    let tally = per_surfel(surfels.len(), footprints, |i, kept, culled| {
        let surfel = &surfels[i];
        let result = match Located::new(camera, &instant, surfel) {
            None => Err(Cull::BehindNear),
            Some(located) if !(located.facing > 0.0) => Err(Cull::BackFacing),
            Some(located) => {
                static_footprint(camera, &located.view(camera, &instant, lighting, surfel))
            }
        };
        culled.keep(result, kept);
    });
    culled.add(&tally);
}

/// The splat a share `s` of the way from `a` to `b`: every quantity interpolated linearly.
fn between(a: &ScreenSplat, b: &ScreenSplat, s: f64) -> ScreenSplat {
    let lerp = |x: f64, y: f64| x + (y - x) * s;
    ScreenSplat {
        center: a.center.lerp(b.center, s),
        covariance: Sym2 {
            xx: lerp(a.covariance.xx, b.covariance.xx),
            xy: lerp(a.covariance.xy, b.covariance.xy),
            yy: lerp(a.covariance.yy, b.covariance.yy),
        },
        weight: lerp(a.weight, b.weight),
        colour: [0, 1, 2].map(|c| lerp(f64::from(a.colour[c]), f64::from(b.colour[c])) as f32),
        depth: lerp(a.depth, b.depth),
        depth_gradient: a.depth_gradient.lerp(b.depth_gradient, s),
        depth_tolerance: lerp(a.depth_tolerance, b.depth_tolerance),
        ..*a
    }
}

/// Where the middle of a sub-segment's screen path through `[start, middle, end]` (where a
/// surfel is at t0, (t0 + t1)/2 and t1) lies from its chord's middle: the part across the chord
/// (px), and the part along it in chord lengths. Zero for a chord of no length.
fn sagitta([start, middle, end]: [DVec2; 3]) -> (DVec2, f64) {
    let chord = end - start;
    let length_sq = chord.length_squared();
    if !(length_sq > 0.0) {
        return (DVec2::ZERO, 0.0);
    }
    let offset = middle - 0.5 * (start + end);
    let along = offset.dot(chord) / length_sq;
    (offset - chord * along, along)
}

/// How far a footprint must move off its chord, across it, to lie on its path's mean position
/// over the part of [t0, t1] and the shutter weight that `moments` describe, for a path
/// quadratic in time whose middle lies `across` (the [`sagitta`]'s part across the chord) off
/// the chord's middle: its departure from the chord is `across` × 4u(1 − u) at a share u of
/// [t0, t1], whose mean is 4(E[u] − E[u²]): ⅔ of it under a box shutter over the whole interval.
/// The part along the chord is a change of speed (a surfel moving in depth), which moves light
/// within the streak rather than the streak. docs/math.md, "A bent path's mean".
fn path_bend(across: DVec2, [t0, t1]: [f64; 2], moments: &TimeMoments) -> DVec2 {
    let duration = t1 - t0;
    if !(duration > 0.0) {
        return DVec2::ZERO;
    }
    let mean = (moments.mean - t0) / duration;
    let mean_square = moments.variance / (duration * duration) + mean * mean;
    across * (4.0 * (mean - mean_square))
}

/// How much a quantity changes from `start` to `end` as a share of its `middle` value; zero where
/// that is not positive.
fn share_of_change([start, middle, end]: [f64; 3]) -> f64 {
    if middle > 0.0 {
        (end - start) / middle
    } else {
        0.0
    }
}

/// Where an object is seen at the middle of each of `spans` (time intervals).
pub(crate) fn middle_instants(
    camera: &Camera,
    motion: &Motion,
    spans: impl IntoIterator<Item = [f64; 2]>,
) -> Vec<Instant> {
    spans
        .into_iter()
        .map(|[t0, t1]| Instant::new(camera, &motion.pose_at(0.5 * (t0 + t1))))
        .collect()
}

/// A surfel seen over one sub-segment [t0, t1]: at its two ends, and where its centre is on
/// screen at (t0 + t1)/2 (`None` when not in front of the near plane).
pub(crate) struct SubSegmentView<'a> {
    pub(crate) start: &'a SurfelView,
    pub(crate) middle: Option<DVec2>,
    pub(crate) end: &'a SurfelView,
}

/// The motion ellipse of one surfel over [t0, t1] of the exposure `shutter`, `seen` there, with
/// the shutter `moments` of the interval; `chained` when it is one of several consecutive
/// sub-segments. With `exact_streak` (for a shutter of uniform weight over the interval, see
/// [`crate::render::draws_exact_streaks`]), a splat that slides at least [`MIN_STREAK_SIGMAS`]
/// is drawn as its exact streak instead (see [`ScreenSplat::sweep`]). Where the surfel is at the
/// middle moves the footprint off its chord onto the bent path's mean position under the
/// shutter (docs/math.md, "A bent path's mean").
pub(crate) fn motion_ellipse(
    shutter: &Shutter,
    seen: &SubSegmentView,
    [t0, t1]: [f64; 2],
    moments: &TimeMoments,
    chained: bool,
    exact_streak: bool,
) -> Result<ScreenSplat, Cull> {
    let SubSegmentView {
        start: a,
        middle,
        end: b,
    } = *seen;
    // A surfel turning edge-on within the sub-segment shows its face only until (or from) the
    // turn, its facing cosine taken as linear in time: the ellipse is clipped to that part, and
    // at the turn its projected area is zero. (Weighting the whole sub-segment by the share of
    // time it faces counted the far end's area as if it faced the camera: twice the energy.)
    let (mut a_splat, mut b_splat, mut span, mut moments) = (a.splat, b.splat, [t0, t1], *moments);
    match (a.facing > 0.0, b.facing > 0.0) {
        (true, true) => {}
        (false, false) => return Err(Cull::BackFacing),
        (a_faces, _) => {
            let turn_at = a.facing / (a.facing - b.facing);
            let mut turn = between(&a.splat, &b.splat, turn_at);
            turn.weight = 0.0;
            let t_turn = t0 + (t1 - t0) * turn_at;
            if a_faces {
                (b_splat, span) = (turn, [t0, t_turn]);
            } else {
                (a_splat, span) = (turn, [t_turn, t1]);
            }
            moments = shutter.moments(span[0], span[1]);
            if !(span[1] > span[0] && moments.mass > 0.0) {
                return Err(Cull::BackFacing);
            }
        }
    }
    // A clipped ellipse's ends lie on the chord, so its path bends from the same line.
    let (across, along) = middle.map_or((DVec2::ZERO, 0.0), |middle| {
        sagitta([a.splat.center, middle, b.splat.center])
    });
    let bend = path_bend(across, [t0, t1], &moments);
    // A path whose middle lies c chord lengths past the chord's middle moves along the chord at
    // 1 + 4c(1 − 2u) at a share u of the sub-segment, so it leaves 1 + 8c·x of its light at x
    // chord lengths from the middle, to first order (docs/math.md, "A streak whose light changes
    // along it"). A clipped piece's middle is not the sub-segment's: left out there.
    let speed_change = if span == [t0, t1] { 8.0 * along } else { 0.0 };
    let ([t0, t1], moments) = (span, &moments);
    let (a, b) = (&a_splat, &b_splat);
    // The splat at the sub-segment's mean time.
    let s = ((moments.mean - t0) / (t1 - t0)).clamp(0.0, 1.0);
    let mean = between(a, b, s);
    let chord = b.center - a.center;
    let splat = mean.covariance + Sym2::isotropic(PREFILTER_VARIANCE_PX2);
    let duration = t1 - t0;
    // In exposure time (0 at shutter open, 1 at close), as the rasterizer counts it.
    let exposure = shutter.duration();
    let exposure_time = |t: f64| (t - shutter.open) / exposure;
    // The splat's plane slides with it: at a pixel its depth changes by what the surfel moves in
    // depth beyond what the plane's slope along the chord accounts for (docs/math.md, "Depth
    // along a motion footprint"). Per unit of exposure time:
    let depth_rate = (b.depth - a.depth - mean.depth_gradient.dot(chord)) / (duration / exposure);
    let conic = splat.inverse();
    let length_sq = conic.map_or(0.0, |q| q.quadratic(chord));
    let (covariance, sweep, time) =
        if exact_streak && length_sq >= MIN_STREAK_SIGMAS * MIN_STREAK_SIGMAS {
            // A pixel is passed when the splat's centre is nearest it in the splat's own metric, at
            // v/k chord lengths from the middle (docs/math.md, "Exact streaks"), for √3 of the
            // splat's standard deviations along the chord either side.
            let conic = conic.unwrap_or_default();
            let time = TimeExtent {
                center: exposure_time(moments.mean),
                gradient: conic.apply(chord) * (duration / length_sq / exposure),
                half_width: (3.0 / length_sq).sqrt().min(1.0) * duration / exposure,
                span: [exposure_time(t0), exposure_time(t1)],
            };
            (splat, chord, time)
        } else {
            let uniform_variance = moments.variance / (duration * duration);
            let mut motion_variance = uniform_variance;
            let chord_sq = chord.length_squared();
            // Variance of the splat along the chord, in chord lengths squared (∞ without motion).
            let along = if chord_sq > 0.0 {
                splat.quadratic(chord) / (chord_sq * chord_sq)
            } else {
                f64::INFINITY
            };
            if chained && along.is_finite() {
                motion_variance = motion_variance.max(0.25 - along);
            }
            // A pixel on the chord is covered while the splat passes: about √3 standard deviations
            // of the splat either side of its passing time (a box of the same variance), within the
            // sub-segment. Widening spreads a chained ellipse past its chord's ends, into its
            // neighbours' time; the span grows by as much (√3 × the added standard deviation), or
            // that coverage would pile into the sub-segment's first and last bins.
            let reach = (3.0 * (motion_variance - uniform_variance)).sqrt() * duration;
            let time = TimeExtent {
                center: exposure_time(moments.mean),
                gradient: if chord_sq > 0.0 {
                    chord * (duration / chord_sq / exposure)
                } else {
                    DVec2::ZERO
                },
                half_width: (3.0 * along).sqrt().min(1.0) * duration / exposure,
                span: [
                    exposure_time((t0 - reach).max(shutter.open)),
                    exposure_time((t1 + reach).min(shutter.close)),
                ],
            };
            let covariance = splat + Sym2::outer(chord).scaled(motion_variance);
            (covariance, DVec2::ZERO, time)
        };
    let weight_change = share_of_change([a.weight, mean.weight, b.weight]);
    // Shading scales a surfel's albedo by its irradiance (white lights), so its colour changes
    // by one share in every channel: taken over the channels' sum.
    let colour_change =
        share_of_change([a, &mean, b].map(|splat| f64::from(splat.colour.iter().sum::<f32>())));
    Ok(ScreenSplat {
        center: a.center + chord * s + bend,
        covariance,
        sweep,
        sweep_change: weight_change + speed_change,
        colour_change,
        weight: mean.weight * moments.mass,
        colour: mean.colour,
        depth: mean.depth,
        depth_gradient: mean.depth_gradient,
        depth_tolerance: a.depth_tolerance.max(b.depth_tolerance),
        depth_rate,
        time,
        ..*a
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn gathered_parts_follow_what_was_there_in_order() {
        let parts: [&[u32]; 4] = [&[1, 2], &[], &[3], &[4, 5, 6]];
        let mut out = vec![0];
        gather(&parts, &mut out);
        assert_eq!(out, [0, 1, 2, 3, 4, 5, 6]);
        gather(&[], &mut out);
        assert_eq!(out.len(), 7);
    }

    /// A 200 × 200 camera 5 units up the z axis looking at the origin.
    pub(crate) fn camera() -> Camera {
        Camera::new(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
            45.0,
            200,
            200,
        )
        .unwrap()
        .with_near(0.01)
        .unwrap()
    }

    fn surfel(normal: DVec3) -> Surfel {
        Surfel::isotropic(DVec3::ZERO, normal, 0.01, None, [1.0; 3])
    }

    #[test]
    fn a_motion_footprint_s_depth_follows_its_surface_at_every_pixel_and_time() {
        // A tilted surfel sliding 1.1 units towards the camera and across it, drawn as an exact
        // streak and as a motion ellipse. Wherever its splat covers a pixel at time t, the ray
        // through that pixel meets the surfel's plane at t at the depth the footprint gives for
        // (pixel, t), a plane in screen and time: to within 5 % of its tolerance (perspective
        // bends a plane's depth across the screen, by 4 % at the chord's ends here) besides
        // where the splat is, while the plane's depth at a fixed pixel moves by 7 tolerances
        // over the exposure.
        let cam = camera();
        let lighting = Lighting::default();
        let normal = DVec3::new(0.5, 0.3, 0.8).normalize();
        let surfel = surfel(normal);
        let pose = |t: f64| Pose {
            translation: DVec3::new(-0.3, 0.0, -0.5).lerp(DVec3::new(0.3, 0.1, 0.6), t),
            ..Pose::IDENTITY
        };
        let view = |t: f64| view_surfel(&cam, &Instant::new(&cam, &pose(t)), &lighting, &surfel);
        let (start, end) = (view(0.0).unwrap(), view(1.0).unwrap());
        let seen = SubSegmentView {
            start: &start,
            middle: None,
            end: &end,
        };
        let shutter = Shutter::default();
        let moments = shutter.moments(0.0, 1.0);
        let chord = end.splat.center - start.splat.center;
        assert!(chord.length() > 30.0, "{chord}");
        let sigma = start
            .splat
            .covariance
            .xx
            .max(start.splat.covariance.yy)
            .sqrt();
        for exact in [true, false] {
            let footprint =
                motion_ellipse(&shutter, &seen, [0.0, 1.0], &moments, false, exact).unwrap();
            assert_eq!(footprint.sweep != DVec2::ZERO, exact);
            let tolerance = footprint.depth_tolerance;
            let model = |pixel: DVec2, t: f64| {
                footprint.depth
                    + footprint.depth_gradient.dot(pixel - footprint.center)
                    + footprint.depth_rate * (t - footprint.time.center)
            };
            for i in 0..=40 {
                let t = f64::from(i) / 40.0;
                let instant = Instant::new(&cam, &pose(t));
                let point = instant.view_point(surfel.position);
                let plane_normal = instant.view_vector(surfel.normal);
                let centre = instant.screen_point(&cam, surfel.position).unwrap();
                // The footprint slides its splat at one speed; perspective does not quite (the
                // plan's sub-segments bound the difference), and the plane's depth moves with it.
                let slide = centre.distance(start.splat.center + chord * t);
                // Nearer, the plane's gradient on screen steepens: the footprint keeps its
                // middle's.
                let steepening =
                    (view(t).unwrap().splat.depth_gradient - footprint.depth_gradient).length();
                for (dx, dy) in [(0.0, 0.0), (3.0, 0.0), (-3.0, 2.0), (1.0, -3.0)] {
                    let pixel = centre + DVec2::new(dx, dy) * sigma;
                    let ray = cam.ray(pixel.x, pixel.y);
                    let exact_depth = plane_normal.dot(point) / plane_normal.dot(ray);
                    let off = (model(pixel, t) - exact_depth).abs();
                    assert!(
                        off <= slide * footprint.depth_gradient.length()
                            + steepening * pixel.distance(centre)
                            + 0.05 * tolerance,
                        "exact {exact}, t = {t}, pixel {pixel}: off by {off}, tolerance {tolerance}"
                    );
                }
            }
            let middle = footprint.center;
            let drift = (model(middle, 1.0) - model(middle, 0.0)).abs();
            assert!(drift > 5.0 * tolerance, "{drift} against {tolerance}");
        }
    }

    #[test]
    fn facing_surfel_area_scales_by_focal_over_depth_squared() {
        let cam = camera();
        let instant = Instant::new(&cam, &Pose::IDENTITY);
        let view = view_surfel(&cam, &instant, &Lighting::default(), &surfel(DVec3::Z)).unwrap();
        let scale = cam.focal_px / 5.0;
        assert!((view.splat.weight - 0.01 * scale * scale).abs() < 1e-9 * view.splat.weight);
        assert!((view.facing - 1.0).abs() < 1e-12);
        assert!((view.splat.center - DVec2::new(100.0, 100.0)).length() < 1e-9);
    }

    #[test]
    fn tilted_surfel_area_shrinks_by_the_cosine_and_edge_on_vanishes() {
        let cam = camera();
        let instant = Instant::new(&cam, &Pose::IDENTITY);
        let lighting = Lighting::default();
        let facing = view_surfel(&cam, &instant, &lighting, &surfel(DVec3::Z))
            .unwrap()
            .splat
            .weight;
        let tilted = DVec3::new(0.6, 0.0, 0.8);
        let view = view_surfel(&cam, &instant, &lighting, &surfel(tilted)).unwrap();
        // At the image centre the projection is orthographic to first order: area × cos θ.
        assert!((view.splat.weight / facing - 0.8).abs() < 1e-9);
        // Exactly edge-on counts as not facing; a hair off edge-on faces but carries no weight.
        let edge_on = view_surfel(&cam, &instant, &lighting, &surfel(DVec3::X)).unwrap();
        assert!(edge_on.splat.weight < 1e-12 * facing);
        assert_eq!(static_footprint(&cam, &edge_on), Err(Cull::BackFacing));
        let grazing = view_surfel(
            &cam,
            &instant,
            &lighting,
            &surfel(DVec3::new(1.0, 0.0, 1e-14).normalize()),
        )
        .unwrap();
        assert_eq!(
            static_footprint(&cam, &grazing),
            Err(Cull::Raster(Rejection::Degenerate))
        );
    }

    #[test]
    fn back_facing_and_behind_camera_surfels_are_culled() {
        let cam = camera();
        let lighting = Lighting::default();
        let instant = Instant::new(&cam, &Pose::IDENTITY);
        let back = view_surfel(&cam, &instant, &lighting, &surfel(-DVec3::Z)).unwrap();
        assert_eq!(static_footprint(&cam, &back), Err(Cull::BackFacing));
        let behind = Pose {
            translation: DVec3::new(0.0, 0.0, 6.0),
            ..Pose::IDENTITY
        };
        assert!(view_surfel(
            &cam,
            &Instant::new(&cam, &behind),
            &lighting,
            &surfel(DVec3::Z)
        )
        .is_none());
    }
}
