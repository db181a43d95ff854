//! Motion blur in one pass of motion footprints (Guan & Mueller §3.3): for each sub-segment of a
//! moving object's plan, a surfel seen at both ends makes one footprint weighted by the shutter
//! mass of the sub-segment, so that a blurred splat carries the energy of the static one. Under a
//! box shutter it is the splat's exact streak (the splat convolved with its chord: Gaussian
//! across, an erf difference along); otherwise G&M's ellipse with the covariance of the projected
//! splat plus that of its projected motion. Both are [`crate::project::motion_ellipse`]; coverage
//! is composited in [`TIME_BINS`] bins of shutter time. Derivations, the widening of chained
//! ellipses and the known leaks (which `tests/stiff.rs` bounds): docs/math.md, "Motion ellipse by
//! summing covariances", "Exact streaks" and "Time bins for coverage" (and [`time_bins_for`] for
//! paths shorter than [`SHORT_PATH_PX`]). `analytic` draws its scene's surfel objects here, over
//! its triangles.

use super::{draw, Exposure, MethodStats, Render, Stats};
use crate::plan::{segment_ends, ObjectMotion, Plan};
use crate::project::{
    middle_instants, motion_ellipse, object_footprints_at, per_surfel, view_surfel, Cull, Instant,
    SubSegmentView, SurfelView,
};
use crate::raster::{Footprint, TimeBins};
use crate::scene::shutter::TimeMoments;
use crate::scene::Scene;

/// Bins of shutter time in which coverage is composited (see [`crate::raster::TimeBins`]). Where
/// one bin holds coverage of a surface from two depth groups it is still composited as layers,
/// and a little background leaks; measured against 16 bins, 32 lowered RMSE on every gallery
/// scene (falling sphere at τ = 1 px: 0.0073 → 0.0060; bunny at τ = 0.25 px: 0.019 → 0.016) for
/// about 10 % more time.
pub(super) const TIME_BINS: usize = 32;

/// Below this longest screen path (px), 16 bins are enough (see [`time_bins_for`]): each of 32
/// would span less than half a pixel of motion.
pub const SHORT_PATH_PX: f64 = 16.0;

/// Bins of shutter time where every path is shorter than [`SHORT_PATH_PX`]: a bin spans at most a
/// pixel of motion. On the torus knot at 160 × 120 (15.8 px) they took a tenth less time than 32
/// at 4 % lower RMSE; two quads sliding 12 px, one passing off a pixel as the other comes on, gave
/// the same RMSE with 8, 16 and 32 bins and half again as much with 4 (docs/history.md, "Time
/// bins for short paths").
const SHORT_PATH_TIME_BINS: usize = 16;

/// The bins of shutter time `blur` composites in, for a scene whose longest screen path is
/// `longest_path_px`.
#[must_use]
pub fn time_bins_for(longest_path_px: f64) -> usize {
    if longest_path_px < SHORT_PATH_PX {
        SHORT_PATH_TIME_BINS
    } else {
        TIME_BINS
    }
}

/// What `blur` did beyond the shared counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BlurStats {
    /// Bins of shutter time coverage was composited in (1 where nothing moves).
    pub time_bins: usize,
}

impl BlurStats {
    /// Human-readable account for `--explain`.
    #[must_use]
    pub fn explain(&self) -> String {
        match self.time_bins {
            1 => "time bins: none, nothing moves (one instant)\n".to_string(),
            SHORT_PATH_TIME_BINS => format!(
                "time bins: {SHORT_PATH_TIME_BINS} of the shutter, as every screen path is under {SHORT_PATH_PX} px (a bin spans at most a pixel of motion); {TIME_BINS} otherwise\n"
            ),
            bins => format!("time bins: {bins} of the shutter\n"),
        }
    }
}

pub(super) fn render(scene: &Scene, plan: &Plan) -> Render {
    // Coverage is composited per bin of shutter time only when something moves; a still scene is
    // an instant.
    if !plan.any_moving() {
        return render_in(scene, plan, &TimeBins::INSTANT);
    }
    match time_bins_for(plan.longest_path_px()) {
        SHORT_PATH_TIME_BINS => render_in(
            scene,
            plan,
            &TimeBins::<SHORT_PATH_TIME_BINS>::over(&scene.shutter),
        ),
        _ => render_in(scene, plan, &TimeBins::<TIME_BINS>::over(&scene.shutter)),
    }
}

/// [`render`] with coverage composited in `bins`.
fn render_in<const B: usize>(scene: &Scene, plan: &Plan, bins: &TimeBins<B>) -> Render {
    let mut stats = Stats::default();
    let footprints = motion_footprints(scene, plan, &mut stats);
    let image = draw(plan, Exposure::Shutter, &footprints, bins, &mut stats);
    // `analytic` draws triangle objects elsewhere; the bins are the surfels' alone.
    if plan.drawn().next().is_some() {
        stats.method = MethodStats::Blur(BlurStats { time_bins: B });
    }
    Render { image, stats }
}

/// The motion footprints of every surfel object as `plan` draws it (still objects' footprints at
/// the shutter's middle), counting what is left out into `stats`.
fn motion_footprints(scene: &Scene, plan: &Plan, stats: &mut Stats) -> Vec<Footprint> {
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
    footprints
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::framebuffer::{root_mean_square_difference, Framebuffer};
    use crate::render::Method;
    use std::path::Path;

    /// Two quads sliding left by `path_px`, side by side, the red one in front: each pixel the
    /// seam passes is covered by red until its edge leaves and by blue from then on, so it shows
    /// the background only where bins mix the two times.
    fn seam_passing(path_px: f64) -> Scene {
        // 64 × 32 px at fov 3° from 50 units: 12.22 px per unit at the far quad.
        let shift = path_px / 12.22;
        let quad = |name: &str, colour: &str, x: f64, z: f64| {
            format!(
                "[[object]]\nname = \"{name}\"\nshape = {{ type = \"quad\", size = [4.0, 4.0] }}\n\
                 spacing = 0.05\ncolour = {colour}\n\
                 [[object.keyframe]]\nt = 0\ntranslate = [{x}, 0, {z}]\n\
                 [[object.keyframe]]\nt = 1\ntranslate = [{}, 0, {z}]\n",
                x - shift
            )
        };
        let text = format!(
            "background = [0, 0, 0]\n\
             [camera]\neye = [0, 0, 50]\ntarget = [0, 0, 0]\nfov_y = 3\nwidth = 64\nheight = 32\n{}{}",
            quad("near", "[1, 0.2, 0.1]", -2.0, 0.5),
            quad("far", "[0.1, 0.3, 1]", 2.0, 0.0),
        );
        Scene::parse(&text, Path::new("seam.toml")).unwrap()
    }

    /// The reference at N = 256, and `blur`'s plan.
    fn reference_and_plan(scene: &Scene) -> (Framebuffer, Plan<'_>) {
        let reference = Plan::new(scene, &Method::Reference { samples: 256 })
            .unwrap()
            .render(None)
            .image;
        (reference, Plan::new(scene, &Method::BLUR).unwrap())
    }

    /// RMSE against `reference` of `blur` as `plan` draws it, in `B` bins.
    fn error_in<const B: usize>(scene: &Scene, plan: &Plan, reference: &Framebuffer) -> f64 {
        let image = render_in(scene, plan, &TimeBins::<B>::over(&scene.shutter)).image;
        root_mean_square_difference(&image.pixels, &reference.pixels)
    }

    /// RMSE against `reference` of `blur` in the bins it chooses, with them.
    fn chosen_error(plan: &Plan, reference: &Framebuffer) -> (f64, MethodStats) {
        let chosen = plan.render(None);
        let error = root_mean_square_difference(&chosen.image.pixels, &reference.pixels);
        (error, chosen.stats.method)
    }

    #[test]
    fn short_paths_take_sixteen_bins_and_lose_nothing_by_them() {
        assert_eq!(time_bins_for(15.9), SHORT_PATH_TIME_BINS);
        assert_eq!(time_bins_for(SHORT_PATH_PX), TIME_BINS);
        let bins_chosen = |time_bins| MethodStats::Blur(BlurStats { time_bins });
        // At 12 px, 16 bins are as good as 32 (RMSE 0.01186 against 0.01184), and 4 are not
        // (0.0178): the scene tells what the bins keep.
        let short = seam_passing(12.0);
        let (reference, plan) = reference_and_plan(&short);
        let (chosen, stats) = chosen_error(&plan, &reference);
        let thirty_two = error_in::<TIME_BINS>(&short, &plan, &reference);
        assert_eq!(stats, bins_chosen(SHORT_PATH_TIME_BINS));
        assert!(chosen <= 1.05 * thirty_two, "{chosen} against {thirty_two}");
        let four = error_in::<4>(&short, &plan, &reference);
        assert!(four >= 1.3 * thirty_two, "{four} against {thirty_two}");
        // At 48 px, 16 bins would not do (0.0096 against 0.0066).
        let long = seam_passing(48.0);
        let (reference, plan) = reference_and_plan(&long);
        let (chosen, stats) = chosen_error(&plan, &reference);
        let sixteen = error_in::<SHORT_PATH_TIME_BINS>(&long, &plan, &reference);
        assert_eq!(stats, bins_chosen(TIME_BINS));
        assert!(sixteen >= 1.2 * chosen, "{sixteen} against {chosen}");
    }
}
