//! `static`: EWA surface splatting of the whole scene at one instant.

use super::{instant_layer, Render, Stats};
use crate::project::{object_footprints_at, Culled};
use crate::raster::Footprint;
use crate::scene::Scene;

/// The scene splatted at time `t`.
pub(super) fn render(scene: &Scene, t: f64) -> Render {
    let mut stats = Stats::default();
    let image = instant_layer(scene, t, &mut stats).over_colour(scene.background);
    Render { image, stats }
}

/// Footprints of every object at time `t`, counting what is left out into `culled`.
pub(super) fn footprints_at(scene: &Scene, t: f64, culled: &mut Culled) -> Vec<Footprint> {
    let mut footprints = Vec::new();
    for object in &scene.objects {
        object_footprints_at(
            &scene.camera,
            &scene.lighting,
            object,
            t,
            &mut footprints,
            culled,
        );
    }
    footprints
}
