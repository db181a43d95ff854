//! The splat renderers. All of them share projection ([`crate::project`]) and rasterization
//! ([`crate::raster`]); they differ only in which footprints they make:
//!
//! - [`Method::Static`]: EWA surface splatting at one instant;
//! - [`Method::Reference`]: the shutter-weighted average of N static frames (the accumulation
//!   buffer), the ground truth every other method is measured against;
//! - [`Method::Blur`]: one pass of motion ellipses (Guan & Mueller §3.3);
//! - [`Method::Hint`]: the object sharp at the flash plus a styled trail of motion ellipses
//!   (Guan & Mueller §3.1, §4);
//! - [`Method::Kernel3d`]: 3D spatio-temporal kernels integrated along each pixel ray, with exact
//!   temporal visibility (Heinzle et al. 2010).

mod blur;
mod hint;
mod kernel3d;
mod reference;

pub use hint::HintStats;
pub use kernel3d::{KernelStats, Visibility};

use crate::framebuffer::Framebuffer;
use crate::plan::Plan;
use crate::project::{object_footprints_at, Culled};
use crate::raster::{rasterize, Footprint, Layer, RasterStats, Target, TimeBins};
use crate::scene::Scene;
use crate::style::Style;
use indicatif::ProgressBar;
use std::sync::Arc;

/// A rendering method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// Sharp EWA splatting at one instant.
    Static,
    /// Motion ellipses from summed covariances, one pass.
    Blur,
    /// Average of N static frames at stratified shutter times.
    Reference,
    /// The object sharp at the flash over a styled trail (a motion hint).
    Hint,
    /// 3D spatio-temporal kernels integrated along pixel rays, with an A-buffer.
    Kernel3d,
}

impl Method {
    /// The name used on the command line and in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Method::Static => "static",
            Method::Blur => "blur",
            Method::Reference => "reference",
            Method::Hint => "hint",
            Method::Kernel3d => "kernel3d",
        }
    }
}

/// Most frames the reference may average (and the study may ask for).
pub const MAX_SAMPLES: usize = 1 << 16;

/// Most sub-frames `kernel3d` may cut the exposure into.
pub const MAX_SUBFRAMES: usize = 1024;

/// What to render and at which quality.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The renderer.
    pub method: Method,
    /// Instant drawn by `static` (default: the middle of the exposure).
    pub time: Option<f64>,
    /// Frames averaged by `reference`.
    pub samples: usize,
    /// The look of `hint` (default: [`Style::default`]).
    pub style: Option<Arc<Style>>,
    /// Equal sub-frames of `kernel3d` (default: the plan's sub-segments).
    pub subframes: Option<usize>,
    /// How `kernel3d` resolves visibility.
    pub visibility: Visibility,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            method: Method::Blur,
            time: None,
            samples: 64,
            style: None,
            subframes: None,
            visibility: Visibility::Exact,
        }
    }
}

/// What a render did, for `--explain` and the study.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Surfels (or surfel sub-segments) left out, by reason.
    pub culled: Culled,
    /// Footprints rasterized, over all frames.
    pub footprints: usize,
    /// Frames rasterized (1 except for the reference).
    pub frames: usize,
    /// Footprints of still objects reused across reference frames instead of projected again.
    pub reused_footprints: usize,
    /// The largest per-tile footprint list seen.
    pub max_per_tile: usize,
    /// The most footprint–tile pairs binned for one frame (4 bytes each).
    pub tile_entries: usize,
    /// What `hint` left out and drew.
    pub hint: HintStats,
    /// What `kernel3d` made and held.
    pub kernel3d: KernelStats,
}

impl Stats {
    fn add_raster(&mut self, raster: &RasterStats) {
        self.footprints += raster.footprints;
        self.frames += 1;
        self.max_per_tile = self.max_per_tile.max(raster.max_per_tile);
        self.tile_entries = self.tile_entries.max(raster.tile_entries);
    }
}

/// An image and how it was made.
#[derive(Clone, Debug)]
pub struct Render {
    /// Linear RGB.
    pub image: Framebuffer,
    /// What was drawn and left out.
    pub stats: Stats,
}

/// Render `scene` as `plan` and `settings` say. `progress`, when given, advances once per frame.
#[must_use]
pub fn render(
    scene: &Scene,
    plan: &Plan,
    settings: &Settings,
    progress: Option<&ProgressBar>,
) -> Render {
    match settings.method {
        Method::Static => render_static(
            scene,
            settings.time.unwrap_or_else(|| scene.shutter.middle()),
        ),
        Method::Reference => reference::render(
            scene,
            plan,
            settings.samples.clamp(1, MAX_SAMPLES),
            progress,
        ),
        Method::Blur => blur::render(scene, plan),
        Method::Hint => match &settings.style {
            Some(style) => hint::render(scene, plan, style),
            None => hint::render(scene, plan, &Style::default()),
        },
        Method::Kernel3d => kernel3d::render(
            scene,
            plan,
            settings.subframes.map(|n| n.clamp(1, MAX_SUBFRAMES)),
            settings.visibility,
        ),
    }
}

/// EWA surface splatting of the whole scene at time `t`.
#[must_use]
pub fn render_static(scene: &Scene, t: f64) -> Render {
    let mut stats = Stats::default();
    let image = instant_layer(scene, t, &mut stats).over_colour(scene.background);
    Render { image, stats }
}

/// The whole scene splatted at time `t`, as a layer, counting into `stats`.
fn instant_layer(scene: &Scene, t: f64, stats: &mut Stats) -> Layer {
    let mut footprints = Vec::new();
    for object in &scene.objects {
        object_footprints_at(
            &scene.camera,
            &scene.lighting,
            object,
            t,
            &mut footprints,
            &mut stats.culled,
        );
    }
    rasterize_counted(scene, &footprints, &TimeBins::INSTANT, stats)
}

/// Rasterize footprints with the scene's size and background in time bins `bins`, counting into
/// `stats`.
fn draw<const B: usize>(
    scene: &Scene,
    footprints: &[Footprint],
    bins: &TimeBins<B>,
    stats: &mut Stats,
) -> Framebuffer {
    rasterize_counted(scene, footprints, bins, stats).over_colour(scene.background)
}

/// Rasterize footprints at the scene's size in time bins `bins`, counting into `stats`.
fn rasterize_counted<const B: usize>(
    scene: &Scene,
    footprints: &[Footprint],
    bins: &TimeBins<B>,
    stats: &mut Stats,
) -> Layer {
    let (layer, raster) = rasterize(
        footprints,
        &Target::new(scene.camera.width, scene.camera.height),
        bins,
    );
    stats.add_raster(&raster);
    layer
}
