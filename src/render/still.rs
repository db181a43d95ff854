//! `static`: EWA surface splatting of the whole scene at one instant.

use super::{instant_layer, Render, Stats};
use crate::plan::Plan;
use crate::project::{object_footprints_at, Culled};
use crate::raster::Footprint;
use crate::scene::Scene;

/// The scene splatted at time `t`, with the plan's level of detail.
pub(super) fn render(scene: &Scene, plan: &Plan, t: f64) -> Render {
    let mut stats = Stats::default();
    let image = instant_layer(scene, plan, t, &mut stats).over_colour(scene.background);
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
