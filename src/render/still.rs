//! `static`: EWA surface splatting of the whole scene at one instant (triangle objects drawn as
//! triangles with a z-buffer).

use super::{draw, Exposure, Render, Stats};
use crate::plan::Plan;
use crate::project::{object_footprints_at, Culled};
use crate::raster::{Footprint, TimeBins};
use crate::scene::Scene;

/// The scene at time `t`: surfels splatted with the plan's level of detail, triangles drawn as
/// triangles.
pub(super) fn render(scene: &Scene, plan: &Plan, t: f64) -> Render {
    let mut stats = Stats::default();
    let footprints = footprints_at(scene, plan, t, &mut stats.culled);
    let image = draw(
        plan,
        Exposure::Instant(t),
        &footprints,
        &TimeBins::INSTANT,
        &mut stats,
    );
    Render { image, stats }
}

/// Footprints at time `t` of every object as `plan` draws it, counting what is left out into
/// `culled`.
pub(super) fn footprints_at(
    scene: &Scene,
    plan: &Plan,
    t: f64,
    culled: &mut Culled,
) -> Vec<Footprint> {
    let mut footprints = Vec::new();
    for (object, _, surfels) in plan.drawn() {
        object_footprints_at(
            &scene.camera,
            &scene.lighting,
            (object, surfels),
            t,
            &mut footprints,
            culled,
        );
    }
    footprints
}
