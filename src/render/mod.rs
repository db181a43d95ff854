//! The splat renderers. All of them share projection and rasterization; they differ only in which
//! footprints they make (docs/architecture.md):
//!
//! - [`Method::Static`]: EWA surface splatting at one instant;
//! - [`Method::Reference`]: the shutter-weighted average of N static frames (the accumulation
//!   buffer), the ground truth every other method is measured against;
//! - [`Method::Blur`]: one pass of motion footprints: exact streaks under a box shutter, Guan &
//!   Mueller's motion ellipses (§3.3) otherwise;
//! - [`Method::Hint`]: the object sharp at the flash plus a styled trail of motion ellipses
//!   (Guan & Mueller §3.1, §4);
//! - [`Method::Kernel3d`]: 3D spatio-temporal kernels integrated along each pixel ray, with exact
//!   temporal visibility (Heinzle et al. 2010);
//! - [`Method::Analytic`]: triangle meshes with analytic visibility in time (time-continuous
//!   triangles, Gribel et al. 2010; Palmér §2.1–2.2).
//!
//! Objects made of triangles are drawn as triangles by `static`, `reference` and `analytic`
//! ([`triangles`]), and as their sampled surfels by the others.

mod abuffer;
mod blur;
mod hint;
mod kernel3d;
mod reference;
mod still;
pub mod triangles;

pub use crate::project::Culled;
pub use crate::raster::{
    opacity, CUTOFF_SIGMAS, OPACITY_KNEE, OPAQUE_COVERAGE, PREFILTER_VARIANCE_PX2, TILE_PX,
    TRUNCATION_GAIN,
};
pub use abuffer::MAX_FRAGMENTS_PER_PIXEL;
pub use blur::{time_bins_for, BlurStats, SHORT_PATH_PX};
pub(crate) use hint::trail_window;
pub use hint::HintStats;
pub use kernel3d::{KernelStats, Visibility, MAX_KERNELS_PER_PASS, SHAPED_SUBFRAME_PX};
pub use reference::ReferenceStats;
pub use triangles::{Exposure, TriangleStats, MAX_SHADOWED_LIGHTS, MAX_TRIANGLE_ITEMS};

use crate::error::{Error, Result};
use crate::framebuffer::Framebuffer;
use crate::plan::{Plan, TOLERANCE_RANGE_PX};
use crate::raster::{
    rasterize, rasterize_over, Footprint, Layer, Profile, RasterStats, Target, TimeBins,
};
use crate::scene::shutter::{Shutter, ShutterShape};
use crate::scene::Scene;
use crate::style::Style;
use std::sync::Arc;

/// Most frames the reference may average (and the study may ask for).
pub const MAX_SAMPLES: usize = 1 << 16;

/// Most sub-frames `kernel3d` may cut the exposure into.
pub const MAX_SUBFRAMES: usize = 1024;

/// The sub-segment tolerance a method uses unless told otherwise, px.
pub const DEFAULT_TOLERANCE_PX: f64 = 1.0;

/// `analytic`'s sub-segment tolerance unless told otherwise, px. Corners move along chords of
/// their curved paths, so the chords' departure is the method's only error in time: on a square
/// turning 90° (`streak study tests/data/turning-square.toml`), RMSE against 1,024 reference
/// frames is 0.032 at 1 px, 0.012 at 0.3, 0.0046 at 0.1 and 0.0016 at 0.03 px.
pub const ANALYTIC_TOLERANCE_PX: f64 = 0.1;

/// A rendering method with its own settings. [`Plan::new`] checks the values.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// Sharp EWA splatting at one instant.
    Static {
        /// Normalized frame time in [0, 1] (`None`: the middle of the exposure).
        time: Option<f64>,
    },
    /// The average of `samples` static frames at stratified shutter times, each weighted by the
    /// shutter's mass in its stratum.
    Reference {
        /// Frames averaged, 1 to [`MAX_SAMPLES`].
        samples: usize,
    },
    /// Motion blur in one pass: each sub-segment of a surfel's path as its exact streak under a
    /// box shutter, else as the motion ellipse of summed covariances.
    Blur {
        /// Largest distance of a curved screen path from its linear sub-segments, px (within
        /// [`TOLERANCE_RANGE_PX`]).
        tolerance_px: f64,
    },
    /// The object sharp at the flash over a styled trail (a motion hint).
    Hint {
        /// The look.
        style: Arc<Style>,
        /// Largest distance of a curved trail from its linear sub-segments, px.
        tolerance_px: f64,
    },
    /// 3D spatio-temporal kernels integrated along pixel rays.
    Kernel3d {
        /// How the exposure is cut into sub-frames.
        subframes: Subframes,
        /// How fragments are resolved.
        visibility: Visibility,
    },
    /// Triangles with analytic visibility in time; surfel objects of the scene are drawn by
    /// `blur` in front of them where they are nearer.
    Analytic {
        /// Largest distance of a curved screen path from its linear sub-segments, px.
        tolerance_px: f64,
        /// How receivers that sweep shadow-map texels are shadowed.
        receivers: Receivers,
    },
}

/// How `analytic` shadows a receiver that sweeps shadow-map texels during a visible piece.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Receivers {
    /// Point-sampled max(2|pₑ − pₛ|, 5) times (Palmér §4.1).
    #[default]
    Sampled,
    /// Its path intersected with the texel grid and each texel's occluders (Palmér's future
    /// work): exact but for the bilinear weights.
    Traced,
}

/// How `kernel3d` cuts the exposure into sub-frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Subframes {
    /// At the ends of every moving object's linear sub-segments, planned to `tolerance_px`.
    Planned {
        /// Largest distance of a curved screen path from its sub-segments, px.
        tolerance_px: f64,
    },
    /// This many equal sub-frames, 1 to [`MAX_SUBFRAMES`].
    Equal(usize),
}

impl Method {
    /// `blur` at the default tolerance.
    pub const BLUR: Method = Method::Blur {
        tolerance_px: DEFAULT_TOLERANCE_PX,
    };

    /// `static` at the middle of the exposure.
    pub const STATIC: Method = Method::Static { time: None };

    /// `kernel3d` with the A-buffer at the plan's sub-frames.
    pub const KERNEL3D: Method = Method::Kernel3d {
        subframes: Subframes::Planned {
            tolerance_px: DEFAULT_TOLERANCE_PX,
        },
        visibility: Visibility::Exact,
    };

    /// `analytic` at its default tolerance.
    pub const ANALYTIC: Method = Method::Analytic {
        tolerance_px: ANALYTIC_TOLERANCE_PX,
        receivers: Receivers::Sampled,
    };

    /// `hint` in `style` at the default tolerance.
    #[must_use]
    pub fn hint(style: Style) -> Method {
        Method::Hint {
            style: Arc::new(style),
            tolerance_px: DEFAULT_TOLERANCE_PX,
        }
    }

    /// The name used on the command line and in reports.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Method::Static { .. } => "static",
            Method::Blur { .. } => "blur",
            Method::Reference { .. } => "reference",
            Method::Hint { .. } => "hint",
            Method::Kernel3d { .. } => "kernel3d",
            Method::Analytic { .. } => "analytic",
        }
    }

    /// The tolerance the plan cuts curved paths to: the method's own, or the default for the
    /// methods that draw instants (the plan then only tells still objects from moving ones).
    #[must_use]
    pub fn tolerance_px(&self) -> f64 {
        match *self {
            Method::Blur { tolerance_px }
            | Method::Analytic { tolerance_px, .. }
            | Method::Hint { tolerance_px, .. }
            | Method::Kernel3d {
                subframes: Subframes::Planned { tolerance_px },
                ..
            } => tolerance_px,
            Method::Static { .. }
            | Method::Reference { .. }
            | Method::Kernel3d {
                subframes: Subframes::Equal(_),
                ..
            } => DEFAULT_TOLERANCE_PX,
        }
    }

    /// Check every setting; an error names the setting (as the command line spells it) and the
    /// range that would be right. Nothing is clamped.
    pub fn check(&self) -> Result<()> {
        let invalid = |field: &str, message: String| Err(Error::invalid(field, message));
        match *self {
            Method::Static { time: Some(t) } if !(0.0..=1.0).contains(&t) => {
                invalid("time", format!("{t}: frame time is normalized to [0, 1]"))
            }
            Method::Reference { samples } if !(1..=MAX_SAMPLES).contains(&samples) => invalid(
                "samples",
                format!("{samples}: average between 1 and {MAX_SAMPLES} frames"),
            ),
            Method::Kernel3d {
                subframes: Subframes::Equal(n),
                ..
            } if !(1..=MAX_SUBFRAMES).contains(&n) => invalid(
                "subframes",
                format!("{n}: use between 1 and {MAX_SUBFRAMES} sub-frames"),
            ),
            _ if !TOLERANCE_RANGE_PX.contains(&self.tolerance_px()) => invalid(
                "tolerance",
                format!(
                    "{}: must be between {} and {} pixels",
                    crate::error::shown(self.tolerance_px()),
                    TOLERANCE_RANGE_PX.start(),
                    TOLERANCE_RANGE_PX.end()
                ),
            ),
            _ => Ok(()),
        }
    }
}

/// What a render did, for `--explain` and the study: the counts every method shares, and its own.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Surfels (or surfel sub-segments) left out, by reason.
    pub culled: Culled,
    /// Footprints rasterized, over all frames.
    pub footprints: usize,
    /// Frames rasterized (1 except for the reference).
    pub frames: usize,
    /// The largest per-tile footprint list seen.
    pub max_per_tile: usize,
    /// The most footprint–tile pairs binned for one frame (4 bytes each).
    pub tile_entries: usize,
    /// What drawing triangles did (`static`, `reference`, `analytic` on triangle objects).
    pub triangles: TriangleStats,
    /// What the method did beyond the shared counts.
    pub method: MethodStats,
}

/// What one method did beyond the shared counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MethodStats {
    /// Nothing beyond them (`static`).
    #[default]
    Shared,
    /// `blur`, and `analytic` for a scene's surfel objects.
    Blur(BlurStats),
    /// `reference`.
    Reference(ReferenceStats),
    /// `hint`.
    Hint(HintStats),
    /// `kernel3d`.
    Kernel3d(KernelStats),
}

impl MethodStats {
    /// Human-readable account for `--explain` (empty when there is nothing beyond the shared
    /// counts).
    #[must_use]
    pub fn explain(&self) -> String {
        match self {
            MethodStats::Shared => String::new(),
            MethodStats::Blur(s) => s.explain(),
            MethodStats::Reference(s) => s.explain(),
            MethodStats::Hint(s) => s.explain(),
            MethodStats::Kernel3d(s) => s.explain(),
        }
    }
}

impl Stats {
    fn add_raster(&mut self, raster: &RasterStats) {
        self.footprints += raster.footprints;
        self.frames += 1;
        self.max_per_tile = self.max_per_tile.max(raster.max_per_tile);
        self.tile_entries = self.tile_entries.max(raster.tile_entries);
    }

    /// Where the render departed from the scene or its plan, one short line each (triangles
    /// left out, shadow maps fitted to their budget, sub-frames capped, speed lines left out of
    /// their budget); the `explain` accounts
    /// say more.
    #[must_use]
    pub fn departures(&self) -> Vec<String> {
        let mut out = self.triangles.departures();
        match &self.method {
            MethodStats::Kernel3d(kernels) => out.extend(kernels.departures()),
            MethodStats::Hint(hint) => out.extend(hint.departures()),
            _ => {}
        }
        out
    }

    /// What `hint` did, if it was a hint.
    #[must_use]
    pub fn hint(&self) -> Option<&HintStats> {
        match &self.method {
            MethodStats::Hint(s) => Some(s),
            _ => None,
        }
    }

    /// What `kernel3d` did, if it was `kernel3d`.
    #[must_use]
    pub fn kernel3d(&self) -> Option<&KernelStats> {
        match &self.method {
            MethodStats::Kernel3d(s) => Some(s),
            _ => None,
        }
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

/// Told after each frame a render finishes (the reference draws many; the others one).
pub type Progress<'a> = &'a dyn Fn();

/// Plan `scene` for `method` and render it. `progress`, when given, is called once per frame.
///
/// # Errors
/// A setting of `method` out of its range ([`Method::check`]).
pub fn render(scene: &Scene, method: &Method, progress: Option<Progress>) -> Result<Render> {
    Ok(Plan::new(scene, method)?.render(progress))
}

/// Whether `method` draws its moving surfels' sub-segments as exact streaks (docs/math.md,
/// "Exact streaks"), which need a uniform weight over each: `blur`, and the surfel objects
/// `analytic` draws with it, under a box `shutter`; a hint's trail with the Gaussian profile,
/// whose copies are timed by a box of their own (other profiles map onto the motion ellipse).
pub(crate) fn draws_exact_streaks(method: &Method, shutter: &Shutter) -> bool {
    match method {
        Method::Blur { .. } | Method::Analytic { .. } => shutter.shape == ShutterShape::Box,
        Method::Hint { style, .. } => style.trail.profile == Profile::Gaussian,
        _ => false,
    }
}

/// Render as `plan` says, with the method it was made for.
pub(crate) fn render_planned(plan: &Plan, progress: Option<Progress>) -> Render {
    let scene = plan.scene();
    let render = match plan.method() {
        Method::Static { time } => {
            still::render(scene, plan, time.unwrap_or_else(|| scene.shutter.middle()))
        }
        Method::Reference { samples } => reference::render(scene, plan, *samples, progress),
        Method::Blur { .. } => blur::render(scene, plan),
        Method::Hint { style, .. } => hint::render(scene, plan, style),
        Method::Kernel3d {
            subframes,
            visibility,
        } => kernel3d::render(scene, plan, *subframes, *visibility),
        Method::Analytic { .. } => blur::render(scene, plan),
    };
    // The reference tells each of its frames itself; the others are one frame.
    if let (Some(progress), false) = (progress, matches!(plan.method(), Method::Reference { .. })) {
        progress();
    }
    render
}

/// The surfels of the scene as `plan` draws them (with its level of detail) splatted at time `t`,
/// as a layer, counting into `stats`.
fn instant_layer(scene: &Scene, plan: &Plan, t: f64, stats: &mut Stats) -> Layer {
    let footprints = still::footprints_at(scene, plan, t, &mut stats.culled);
    let target = Target::new(scene.camera.width, scene.camera.height);
    let (layer, raster) = rasterize(&footprints, &target, &TimeBins::INSTANT);
    stats.add_raster(&raster);
    layer
}

/// The image: `footprints` (of the surfel objects) rasterized in time bins `bins` over the
/// objects `plan` draws as triangles, seen at `exposure`, counting into `stats`. Splats are left
/// out of a pixel where triangles hide everything beyond their depth at every sample and
/// instant, and composited over the triangles' image; without triangles, over the background.
fn draw<const B: usize>(
    plan: &Plan,
    exposure: Exposure,
    footprints: &[Footprint],
    bins: &TimeBins<B>,
    stats: &mut Stats,
) -> Framebuffer {
    let scene = plan.scene();
    let target = Target::new(scene.camera.width, scene.camera.height);
    let (image, raster) = if plan.any_triangles() {
        let drawn = triangles::draw(plan, exposure);
        stats.triangles.add(&drawn.stats);
        match &drawn.hidden_beyond {
            Some(hidden) => {
                let target = Target {
                    occluder: Some(hidden),
                    ..target
                };
                rasterize_over(footprints, &target, bins, |i| drawn.image.pixels[i])
            }
            // No surfels are drawn: the triangles' image is the image.
            None => (drawn.image, RasterStats::default()),
        }
    } else {
        rasterize_over(footprints, &target, bins, |_| scene.background)
    };
    stats.add_raster(&raster);
    image
}
