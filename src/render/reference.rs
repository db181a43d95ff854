//! The reference: an accumulation buffer of static frames (Haeberli & Akeley; Heinzle §6's
//! temporal supersampling). Frame i is drawn at the midpoint of the i-th of N equal strata of the
//! shutter interval and weighted by the shutter's mass in that stratum, so any shutter shape
//! converges as N grows. Still objects are projected once and their footprints reused by every
//! frame: the plan says they cannot change.

use super::{draw, Exposure, MethodStats, Progress, Render, Stats};
use crate::framebuffer::Framebuffer;
use crate::plan::{ObjectMotion, Plan};
use crate::project::object_footprints_at;
use crate::raster::TimeBins;
use crate::scene::Scene;
use rayon::prelude::*;

/// What the reference did beyond the shared counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReferenceStats {
    /// Footprints of still objects reused across frames instead of projected again.
    pub reused_footprints: usize,
}

impl ReferenceStats {
    /// Human-readable account for `--explain`.
    #[must_use]
    pub fn explain(&self) -> String {
        format!(
            "reference: {} footprints of still objects reused across frames instead of projected again\n",
            self.reused_footprints
        )
    }
}

pub(super) fn render(
    scene: &Scene,
    plan: &Plan,
    samples: usize,
    progress: Option<Progress>,
) -> Render {
    let mut stats = Stats::default();
    let mut still = Vec::new();
    for (object, _, surfels) in plan
        .drawn()
        .filter(|(_, p, _)| p.motion == ObjectMotion::Still)
    {
        object_footprints_at(
            &scene.camera,
            &scene.lighting,
            (object, surfels),
            scene.shutter.middle(),
            &mut still,
            &mut stats.culled,
        );
    }
    let (width, height) = (scene.camera.width, scene.camera.height);
    let mut sum = vec![[0.0f64; 3]; width as usize * height as usize];
    let mut footprints = Vec::new();
    for (t, mass) in scene.shutter.strata(samples) {
        footprints.clear();
        footprints.extend_from_slice(&still);
        for (object, _, surfels) in plan
            .drawn()
            .filter(|(_, p, _)| p.motion != ObjectMotion::Still)
        {
            object_footprints_at(
                &scene.camera,
                &scene.lighting,
                (object, surfels),
                t,
                &mut footprints,
                &mut stats.culled,
            );
        }
        let frame = draw(
            plan,
            Exposure::Instant(t),
            &footprints,
            &TimeBins::INSTANT,
            &mut stats,
        );
        // Each pixel adds its own frames in order, so the sum does not depend on the threads.
        sum.par_iter_mut().zip(&frame.pixels).for_each(|(acc, p)| {
            for c in 0..3 {
                acc[c] += mass * f64::from(p[c]);
            }
        });
        if let Some(progress) = progress {
            progress();
        }
    }
    stats.method = MethodStats::Reference(ReferenceStats {
        reused_footprints: still.len() * samples.saturating_sub(1),
    });
    let image = Framebuffer {
        width,
        height,
        pixels: sum.into_iter().map(|p| p.map(|c| c as f32)).collect(),
    };
    Render { image, stats }
}
