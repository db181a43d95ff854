//! Motion blur in one pass of motion footprints (Guan & Mueller §3.3): for each sub-segment of a
//! moving object's plan, a surfel seen at both ends makes one footprint weighted by the shutter
//! mass of the sub-segment, so that a blurred splat carries the energy of the static one. Under a
//! box shutter it is the splat's exact streak (the splat convolved with its chord: Gaussian
//! across, an erf difference along); otherwise G&M's ellipse with the covariance of the projected
//! splat plus that of its projected motion. Both are [`crate::project::motion_ellipse`]; coverage
//! is composited in [`TIME_BINS`] bins of shutter time. Derivations, the widening of chained
//! ellipses and the known leaks (which `tests/stiff.rs` bounds): docs/math.md, "Motion ellipse by
//! summing covariances", "Exact streaks" and "Time bins for coverage". `analytic` draws its
//! scene's surfel objects here, over its triangles.

use super::{draw, Exposure, Render, Stats};
use crate::plan::{segment_ends, ObjectMotion, Plan};
use crate::project::{
    middle_instants, motion_ellipse, object_footprints_at, per_surfel, view_surfel, Cull, Instant,
    SubSegmentView, SurfelView,
};
use crate::raster::TimeBins;
use crate::scene::shutter::TimeMoments;
use crate::scene::Scene;

/// Bins of shutter time in which coverage is composited (see [`crate::raster::TimeBins`]). Where
/// one bin holds coverage of a surface from two depth groups it is still composited as layers,
/// and a little background leaks; measured against 16 bins, 32 lowered RMSE on every gallery
/// scene (falling sphere at τ = 1 px: 0.0073 → 0.0060; bunny at τ = 0.25 px: 0.019 → 0.016) for
/// about 10 % more time.
pub(super) const TIME_BINS: usize = 32;

pub(super) fn render(scene: &Scene, plan: &Plan) -> Render {
    let mut stats = Stats::default();
    let mut footprints = Vec::new();
    let camera = &scene.camera;
    let exact = super::draws_exact_streaks(plan.method(), &scene.shutter);
    for (object, object_plan, surfels) in plan.drawn() {
        let ObjectMotion::Moving { segments, .. } = &object_plan.motion else {
            object_footprints_at(
                camera,
                &scene.lighting,
                (object, surfels),
                scene.shutter.middle(),
                &mut footprints,
                &mut stats.culled,
            );
            continue;
        };
        let instants: Vec<Instant> = segment_ends(segments)
            .iter()
            .map(|&t| Instant::new(camera, &object.motion.pose_at(t)))
            .collect();
        // Where each surfel is at each sub-segment's middle: its path's bend (see
        // `motion_ellipse`).
        let middles = middle_instants(camera, &object.motion, segments.iter().copied());
        let chained = segments.len() > 1;
        let moments: Vec<TimeMoments> = segments
            .iter()
            .map(|&[t0, t1]| scene.shutter.moments(t0, t1))
            .collect();
        let culled = per_surfel(surfels.len(), &mut footprints, |i, kept, culled| {
            let surfel = &surfels[i];
            let views: Vec<Option<SurfelView>> = instants
                .iter()
                .map(|instant| view_surfel(camera, instant, &scene.lighting, surfel))
                .collect();
            for (k, &segment) in segments.iter().enumerate() {
                let result = match (&views[k], &views[k + 1]) {
                    (Some(start), Some(end)) => {
                        let seen = SubSegmentView {
                            start,
                            middle: middles[k].screen_point(camera, surfel.position),
                            end,
                        };
                        motion_ellipse(&scene.shutter, &seen, segment, &moments[k], chained, exact)
                            .and_then(|e| {
                                e.footprint(camera.width, camera.height)
                                    .map_err(Cull::Raster)
                            })
                    }
                    _ => Err(Cull::BehindNear),
                };
                culled.keep(result, kept);
            }
        });
        stats.culled.add(&culled);
    }
    // Coverage is composited per bin of shutter time only when something moves; a still scene is
    // an instant.
    let image = if plan.any_moving() {
        draw(
            plan,
            Exposure::Shutter,
            &footprints,
            &TimeBins::<TIME_BINS>::over(&scene.shutter),
            &mut stats,
        )
    } else {
        draw(
            plan,
            Exposure::Shutter,
            &footprints,
            &TimeBins::INSTANT,
            &mut stats,
        )
    };
    Render { image, stats }
}
