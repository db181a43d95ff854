//! The shared rasterizer: screen-space Gaussian footprints → tiles → depth order → pixels.
//!
//! Every splat renderer ends here. A footprint is an elliptical Gaussian in pixels whose integral
//! is the (time-weighted) screen area its surfel covers. Footprints are binned into the [`tiles`]
//! in their own order and each tile sorts its list by depth (the index breaking ties); tiles render
//! in parallel, each owning its pixels and working sequentially inside, so the image bits do not
//! depend on the thread count. Per pixel, [`composite`] groups footprints into surfaces and
//! composites them front to back into a premultiplied [`Layer`]. Conventions:
//! docs/conventions.md, "Premultiplied layers" and "Depth tests".

mod composite;
mod profile;
mod streak;
mod tiles;

pub use composite::TimeBins;
pub use profile::{Profile, Texture};
pub use streak::{Streak, MIN_STREAK_SIGMAS};

use crate::framebuffer::Framebuffer;
use crate::math::Sym2;
use composite::PixelState;
use glam::DVec2;
use profile::Sampler;
use rayon::prelude::*;
use streak::{StreakGeometry, StreakRows};
pub(crate) use tiles::{TileGrid, TileLists};

/// Variance of the screen-space anti-aliasing pre-filter in px² (the EWA low-pass σ_f², docs/math.md "Projected splat covariance").
/// 0.3 px² keeps every footprint at least ~0.55 px wide, so sampling at pixel centres sums even the
/// narrowest footprint to within 2 % of its weight: the samples of a Gaussian ripple by
/// ±2·exp(−2π²·0.3) = ±0.54 % per axis (Poisson summation), and [`TRUNCATION_GAIN`] restores the
/// continuous Gaussian's mass beyond the cut-off, which the samples lose differently. Measured:
/// +1.8 % centred on a pixel, −0.1 % on a pixel corner; wider footprints converge to their weight.
pub const PREFILTER_VARIANCE_PX2: f64 = 0.3;

/// Footprints are evaluated out to this many standard deviations (the Mahalanobis radius). A 2D
/// Gaussian holds exp(−r²/2) of its weight beyond radius r (1.1 % at 3σ); the amplitude is raised
/// by [`TRUNCATION_GAIN`] so that the truncated footprint still integrates to its weight, which
/// keeps coverage of a densely sampled surface at 1 and energy exact under motion.
pub const CUTOFF_SIGMAS: f64 = 3.0;

/// 1 / (1 − exp(−r²/2)) for r = [`CUTOFF_SIGMAS`]: the mass a truncated 2D Gaussian must regain.
pub const TRUNCATION_GAIN: f64 = 1.0 / (1.0 - 0.011_108_996_538_242_306);

/// The cut-off as a squared Mahalanobis distance.
pub(crate) const CUTOFF_Q: f32 = (CUTOFF_SIGMAS * CUTOFF_SIGMAS) as f32;

/// A surface's summed weights at a pixel start counting as more than their face value from here
/// (see [`opacity`]).
pub const OPACITY_KNEE: f64 = 0.8;

/// Summed weights of one surface from this value up make it opaque (see [`opacity`]).
pub const OPAQUE_COVERAGE: f64 = 0.94;

/// How much of a pixel one surface hides, from the summed weights of its footprints there (its
/// coverage estimate). The weights of an irregularly sampled surface do not form a partition of
/// unity (Heinzle et al. 2010, §3): inside a dense closed surface they sum to 0.955–1.0 (measured
/// on spheres from meshes, point clouds, volumes and primitives), so taken at face value the
/// background would show through by up to 4.5 %. Estimates from [`OPAQUE_COVERAGE`] up therefore
/// count as full; below [`OPACITY_KNEE`] they count as they are, so faint and thin surfaces keep
/// their exact energy; in between a straight line joins the two (slope 1.43). Only the inner part
/// of a silhouette's anti-aliasing ramp steepens, by at most 0.06. docs/math.md, "Opacity".
#[must_use]
pub fn opacity(coverage: f64) -> f64 {
    if coverage <= OPACITY_KNEE {
        larger(coverage, 0.0)
    } else {
        let slope = (1.0 - OPACITY_KNEE) / (OPAQUE_COVERAGE - OPACITY_KNEE);
        smaller(OPACITY_KNEE + (coverage - OPACITY_KNEE) * slope, 1.0)
    }
}

/// Tile side in pixels: of every tiled renderer, and of the splat rasterizer on small images.
pub const TILE_PX: u32 = 16;

/// Tile side of the splat rasterizer where the image has [`MIN_TILE_ROWS_PER_THREAD`] rows of such
/// tiles for every worker: a footprint a few pixels wide then straddles fewer tiles, and each
/// tile it reaches sets it up and clips it again (the knot's `static` at 512² and 1024² 5–9 %
/// faster, its `blur` 2–6 %; docs/history.md, "Packed cell keys, the mesh key in runs, and larger
/// tiles for large images").
/// `analytic` and `kernel3d` keep [`TILE_PX`]: larger tiles made them slower and `analytic`
/// larger in memory.
const LARGE_TILE_PX: u32 = 32;

/// Rows of tiles per worker thread below which the splat rasterizer keeps [`TILE_PX`] tiles:
/// rows are its units of parallel work, and with fewer a thread is left waiting on another's
/// last heavy row (the knot's `blur` at 160 × 120 took 8–14 % longer in four rows of 32 px than
/// in eight of 16, on two threads). The image does not depend on the tile size.
const MIN_TILE_ROWS_PER_THREAD: u32 = 8;

/// The splat rasterizer's tile grid over a `width` × `height` image ([`LARGE_TILE_PX`] where it
/// has enough rows of them for the worker threads, else [`TILE_PX`]).
fn splat_grid(width: u32, height: u32) -> TileGrid {
    let threads = u32::try_from(rayon::current_num_threads()).unwrap_or(u32::MAX);
    let rows = height / LARGE_TILE_PX;
    let tile_px = if rows >= MIN_TILE_ROWS_PER_THREAD.saturating_mul(threads) {
        LARGE_TILE_PX
    } else {
        TILE_PX
    };
    TileGrid::with_tile_px(width, height, tile_px)
}

/// A screen-space elliptical Gaussian ready to rasterize.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Centre in pixels.
    pub center: [f32; 2],
    /// Inverse covariance (xx, xy, yy).
    pub conic: [f32; 3],
    /// Weight / (the profile's integral in unit coordinates · √det Σ): for a Gaussian, its value at
    /// the centre, weight · [`TRUNCATION_GAIN`] / (2π √det Σ).
    pub amplitude: f32,
    /// Linear RGB.
    pub colour: [f32; 3],
    /// Camera-space depth at the centre, used for ordering.
    pub depth: f32,
    /// Screen-space gradient of the splat plane's depth (per px), so the ternary depth test
    /// compares the depths of the splat planes at each pixel rather than at their centres: on a
    /// surface seen at a grazing angle, centres of one surface's splats differ in depth far more
    /// than their planes do at a common pixel.
    pub depth_gradient: [f32; 2],
    /// Depth distance within which another footprint counts as the same surface.
    pub depth_tolerance: f32,
    /// How fast the surface's depth at a fixed pixel changes with exposure time: at time t the
    /// splat plane lies at `depth` + gradient · offset + `depth_rate` · (t − `time_center`)
    /// (see [`ScreenSplat::depth_rate`]).
    pub depth_rate: f32,
    /// When it covers which pixel: see [`TimeExtent`].
    pub time_center: f32,
    /// Screen gradient of the covering time, per px.
    pub time_gradient: [f32; 2],
    /// Half the time it takes to pass over one pixel.
    pub time_half_width: f32,
    /// The time interval the footprint stands for.
    pub time_span: [f32; 2],
    /// Pixel bounds [x0, y0, x1, y1), clipped to the image.
    pub bounds: [u32; 4],
    /// The shape of its value across the ellipse.
    pub profile: Profile,
    /// The exact streak it is drawn as, if it is one (see [`ScreenSplat::sweep`]); `conic` is
    /// then the splat's own.
    pub streak: Option<Streak>,
    /// Whether it adds light instead of covering what lies behind (see [`ScreenSplat::additive`]).
    pub additive: bool,
}

/// When a footprint covers a pixel, in exposure time: 0 when the shutter opens, 1 when it
/// closes, whatever the shutter's length (absolute frame times in f32 could not tell apart the
/// moments of a shutter open for 10⁻⁷ of the frame). A motion ellipse stands for a splat sliding
/// along a chord during its sub-segment: a pixel is covered around the time the splat's centre
/// passes its projection on the chord (a linear function of the pixel, clamped to the
/// sub-segment), for as long as the splat takes to pass. A footprint of an instant or of a still
/// object covers the pixel for its whole span.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeExtent {
    /// Covering time at the footprint's centre.
    pub center: f64,
    /// Screen gradient of the covering time, per px.
    pub gradient: DVec2,
    /// Half the covering duration.
    pub half_width: f64,
    /// The interval the footprint stands for.
    pub span: [f64; 2],
}

impl TimeExtent {
    /// Covers every pixel it touches for the whole exposure.
    pub const WHOLE_FRAME: TimeExtent = TimeExtent {
        center: 0.5,
        gradient: DVec2::ZERO,
        half_width: 1.0,
        span: [0.0, 1.0],
    };
}

/// When a footprint covers a pixel, and the depth of its surface there over time.
#[derive(Clone, Copy, Debug)]
pub(super) struct Passage {
    /// The exposure times [start, end] during which it covers the pixel.
    pub window: [f32; 2],
    /// The middle of the window, clamped to the footprint's span.
    pub time: f32,
    /// The surface's depth at the pixel at `time`.
    pub depth: f32,
    /// Its change per unit of exposure time (see [`Footprint::depth_rate`]).
    pub depth_rate: f32,
}

impl Passage {
    /// The surface's depth at the pixel at exposure time `t`.
    #[inline]
    pub fn depth_then(&self, t: f32) -> f32 {
        self.depth + self.depth_rate * (t - self.time)
    }
}

/// Why a footprint was not made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    /// Its whole extent lies outside the image.
    OffScreen,
    /// It carries no weight (seen edge-on, or no shutter time) or its numbers are not finite in
    /// the `f32` it is drawn in.
    Degenerate,
}

/// An elliptical Gaussian on screen with the surface it stands for, in f64, before it is clipped
/// and packed for rasterization.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenSplat {
    /// Centre in pixels.
    pub center: DVec2,
    /// Covariance in px².
    pub covariance: Sym2,
    /// Integral of the Gaussian over the plane: the screen area (times shutter mass) it covers.
    pub weight: f64,
    /// Linear RGB.
    pub colour: [f32; 3],
    /// Camera-space depth at the centre.
    pub depth: f64,
    /// Screen gradient of the splat plane's depth, per px.
    pub depth_gradient: DVec2,
    /// Depth distance within which another splat counts as the same surface.
    pub depth_tolerance: f64,
    /// How fast the surface's depth at a fixed pixel changes with exposure time, per unit of it:
    /// at time t the splat's plane lies at `depth` + `depth_gradient` · offset + `depth_rate` ·
    /// (t − `time.center`). Zero for a still splat. A moving one's plane slides with it, so one
    /// depth per pixel would be the surface's at the time the splat passes it, and two of the
    /// surface's footprints passing a pixel at different times of one time bin would look like
    /// two surfaces (docs/math.md, "Depth along a motion footprint").
    pub depth_rate: f64,
    /// When it covers which pixel.
    pub time: TimeExtent,
    /// The shape of its value across the ellipse (Gaussian for every physically based renderer).
    pub profile: Profile,
    /// The chord the splat's centre slides along, at constant speed, over its time span,
    /// centred on `center` (zero for a splat that stands still). A Gaussian splat sliding at
    /// least [`MIN_STREAK_SIGMAS`] is drawn as its exact streak, `covariance` being the splat's
    /// own; a shorter slide, or another profile, as the ellipse of `covariance` + chord
    /// chordᵀ/12, which has the streak's moments (docs/math.md, "Exact streaks").
    pub sweep: DVec2,
    /// How much the light the splat leaves along `sweep` changes from its start to its end, as a
    /// share of its mean: its density along the chord is 1 + change · x at x chord lengths from
    /// the middle (x ∈ [−½, ½]), which keeps the weight. A surfel whose screen area grows or
    /// shrinks, or that slows down or speeds up, leaves such a streak; only exact streaks use it
    /// (docs/math.md, "A streak whose light changes along it").
    pub sweep_change: f64,
    /// How much its colour changes along `sweep` from start to end, as a share of `colour` (its
    /// value at the chord's middle): the colour is `colour` × (1 + colour_change · x) at x chord
    /// lengths from the middle. A surfel turning towards or away from a light leaves such a
    /// streak (its shading scales its albedo); only exact streaks use it (docs/math.md, "A
    /// streak whose colour changes along it").
    pub colour_change: f64,
    /// Emits light instead of covering: it adds weight × colour, dimmed by what lies in front of
    /// it, and hides nothing (additive motion trails, Guan & Mueller §4).
    pub additive: bool,
}

impl ScreenSplat {
    /// Clip to a `width`×`height` image and pack for the rasterizer. The covariance must already
    /// include the pre-filter.
    pub fn footprint(&self, width: u32, height: u32) -> Result<Footprint, Rejection> {
        let streak = if self.sweep != DVec2::ZERO && self.profile == Profile::Gaussian {
            StreakGeometry::of(
                &self.covariance,
                self.sweep,
                self.sweep_change,
                self.colour_change,
            )
        } else {
            None
        };
        let covariance = match streak {
            Some(_) => self.covariance,
            None => self.covariance + Sym2::outer(self.sweep).scaled(1.0 / 12.0),
        };
        let conic = covariance.inverse().ok_or(Rejection::Degenerate)?;
        let integral = streak
            .as_ref()
            .map_or_else(|| self.profile.integral(), |s| s.integral);
        let amplitude = self.weight / (integral * covariance.det().sqrt());
        // Finite in the f32 they are packed into: a depth of 10³⁹ (a scene scaled by 10³⁸) is
        // finite in f64 but infinite there, where the depth test's ∞ − ∞ is NaN. The covering
        // time's gradient (1/chord for a motion ellipse) may overflow: the time is clamped to
        // the span. The conic's diagonal must be a normal f32: a footprint wider than about 10¹⁸
        // px (a surfel scaled by 10¹⁹ in front of the camera) has one below it, where its rows
        // lose their precision and the footprint its pixels.
        let packs = |v: f64| (v as f32).is_finite();
        let normal = |v: f64| (v as f32) >= f32::MIN_POSITIVE;
        if !(amplitude > 1e-12
            && normal(conic.xx)
            && normal(conic.yy)
            && self.time.gradient.is_finite()
            && [
                amplitude,
                self.center.x,
                self.center.y,
                self.depth,
                self.depth_gradient.x,
                self.depth_gradient.y,
                self.depth_tolerance,
                self.depth_rate,
                self.time.center,
                self.time.half_width,
                self.time.span[0],
                self.time.span[1],
            ]
            .into_iter()
            .all(packs))
        {
            return Err(Rejection::Degenerate);
        }
        let center = self.center;
        let half = streak.as_ref().map_or_else(
            || DVec2::new(covariance.xx.sqrt(), covariance.yy.sqrt()) * CUTOFF_SIGMAS,
            |s| s.extent,
        );
        let clip = |v: f64, max: u32| v.clamp(0.0, f64::from(max)) as u32;
        let x0 = clip((center.x - half.x).floor(), width);
        let x1 = clip((center.x + half.x).ceil() + 1.0, width);
        let y0 = clip((center.y - half.y).floor(), height);
        let y1 = clip((center.y + half.y).ceil() + 1.0, height);
        if x0 >= x1 || y0 >= y1 {
            return Err(Rejection::OffScreen);
        }
        Ok(Footprint {
            center: [center.x as f32, center.y as f32],
            conic: [conic.xx as f32, conic.xy as f32, conic.yy as f32],
            amplitude: amplitude as f32,
            colour: self.colour,
            depth: self.depth as f32,
            depth_gradient: self.depth_gradient.as_vec2().to_array(),
            depth_tolerance: self.depth_tolerance as f32,
            depth_rate: self.depth_rate as f32,
            time_center: self.time.center as f32,
            time_gradient: self.time.gradient.as_vec2().to_array(),
            time_half_width: self.time.half_width as f32,
            time_span: self.time.span.map(|t| t as f32),
            bounds: [x0, y0, x1, y1],
            profile: self.profile,
            streak: streak.map(|s| s.streak),
            additive: self.additive,
        })
    }
}

/// A disc, ring or texture footprint narrower than this (its minor standard deviation, px) is
/// weighed by its own pixel samples. Below it their hard-edged shapes are too coarse for the
/// pixel grid: the samples of a ring at the narrowest footprint sum to 0.75–1.25 of its weight as
/// its centre moves within a pixel, of a disc 0.92–1.17 (0.88–1.11 at 0.75 px); at 2 px both
/// stay within 1 % (the Gaussian within 2 % at any width: [`PREFILTER_VARIANCE_PX2`]).
const PIXEL_WEIGHED_BELOW_SIGMA_PX: f64 = 2.0;

/// A narrow footprint is weighed by its samples only where its cut-off ellipse's bounding box
/// holds at most this many pixels: a larger box around so narrow an ellipse belongs to a long one
/// across the pixel grid's axes, whose rows sample every offset and average out. It bounds the
/// work, a few thousand samples.
const PIXEL_WEIGHED_MAX_BOX_PX: f64 = 4096.0;

impl Footprint {
    /// Make a narrow disc, ring or texture footprint's samples at pixel centres sum to its weight
    /// (below 2 px of minor standard deviation, within a bounding box of 4,096 pixels), so that
    /// its coverage and light do not jump with where its centre falls within a pixel. Every pixel
    /// of its ellipse counts, also those beyond the image, so a footprint at the edge is weighed
    /// as one inside; each is valued as the rasterizer values it. `texture` is the image a
    /// texture profile maps. Gaussians, streaks and footprints with no sample inside are left as
    /// they are.
    pub fn weigh_by_pixel_samples(&mut self, texture: Option<&Texture>) {
        if self.profile == Profile::Gaussian || self.streak.is_some() {
            return;
        }
        let [a, b, c] = self.conic.map(f64::from);
        let det = a * c - b * b;
        // Σ = Q⁻¹; its minor variance is 1 / Q's larger eigenvalue.
        let largest = 0.5 * (a + c) + (0.25 * (a - c) * (a - c) + b * b).sqrt();
        if !(det > 0.0 && a > 0.0 && largest * PIXEL_WEIGHED_BELOW_SIGMA_PX.powi(2) > 1.0) {
            return;
        }
        // The ellipse dᵀ Q d ≤ cut-off reaches √(cut-off · Σ_yy) up and down, Σ_yy = a / det.
        let cutoff = f64::from(CUTOFF_Q);
        let [cx, cy] = self.center.map(f64::from);
        let half = [(cutoff * c / det).sqrt(), (cutoff * a / det).sqrt()];
        let rows = [(cy - half[1]).floor(), (cy + half[1]).ceil()];
        if !((2.0 * half[0] + 2.0) * (rows[1] - rows[0] + 1.0) <= PIXEL_WEIGHED_MAX_BOX_PX) {
            return;
        }
        let shape = Ellipse::new(self, texture);
        let mut sum = 0.0;
        for y in (rows[0] as i64)..=(rows[1] as i64) {
            let dy = y as f64 + 0.5 - cy;
            // The row's offsets inside, a·dx² + 2b·dy·dx + c·dy² ≤ cut-off, a pixel wider each way
            // (the shape's value is zero beyond the cut-off).
            let discriminant = b * b * dy * dy - a * (c * dy * dy - cutoff);
            if !(discriminant >= 0.0) {
                continue;
            }
            let reach = discriminant.sqrt() / a;
            let middle = cx - 0.5 - b * dy / a;
            let row = shape.row(dy as f32);
            for x in ((middle - reach).floor() as i64)..=((middle + reach).ceil() as i64) {
                sum += f64::from(shape.value(row, (x as f64 + 0.5 - cx) as f32).0);
            }
        }
        // The continuous footprint holds amplitude · integral · √det Σ, its weight.
        let weight = f64::from(self.amplitude) * self.profile.integral() / det.sqrt();
        if sum > 0.0 {
            self.amplitude = (weight / sum) as f32;
        }
    }

    /// Offset of the centre of pixel (x, y) from the footprint's centre.
    #[inline]
    fn offset(&self, x: u32, y: u32) -> [f32; 2] {
        [
            x as f32 + 0.5 - self.center[0],
            y as f32 + 0.5 - self.center[1],
        ]
    }

    /// The footprint's value at the centre of pixel (x, y), zero beyond the cut-off; `texture`
    /// is the image a [`Profile::Texture`] footprint maps.
    #[cfg(test)]
    pub fn weight_at(&self, x: u32, y: u32, texture: Option<&Texture>) -> f32 {
        self.sample_at(x, y, texture).0
    }

    /// The footprint's weight times its colour at the centre of pixel (x, y), as the compositor
    /// adds it.
    #[cfg(test)]
    pub fn light_at(&self, x: u32, y: u32) -> [f32; 3] {
        let (weight, change) = self.sample_at(x, y, None);
        [0, 1, 2].map(|c| weight * self.colour[c] + change[c])
    }

    /// The footprint's weight at the centre of pixel (x, y), and what its colour's change along
    /// a streak adds to its light there.
    #[cfg(test)]
    fn sample_at(&self, x: u32, y: u32, texture: Option<&Texture>) -> (f32, [f32; 3]) {
        let [dx, dy] = self.offset(x, y);
        let ((value, moment), slope) = match self.streak {
            Some(streak) => {
                let shape = StreakRows::new(streak, self.center, self.bounds);
                (shape.value(shape.row(dy), dx), shape.colour_slope())
            }
            None => {
                let shape = Ellipse::new(self, texture);
                (shape.value(shape.row(dy), dx), shape.colour_slope())
            }
        };
        (
            self.amplitude * value,
            self.colour_change_at(moment, slope.unwrap_or(0.0)),
        )
    }

    /// What a streak's colour changing by `slope` of itself per standard deviation along its chord
    /// adds to its light at a pixel where the shape's first moment is `moment` (see
    /// [`Shape::value`]).
    #[inline(always)]
    fn colour_change_at(&self, moment: f32, slope: f32) -> [f32; 3] {
        let shift = self.amplitude * moment * slope;
        self.colour.map(|c| shift * c)
    }

    /// When the footprint covers pixel (x, y), and its surface's depth there.
    #[inline]
    pub(super) fn passage_at(&self, x: u32, y: u32) -> Passage {
        let offset = self.offset(x, y);
        let [lo, hi] = self.time_span;
        let time = self.covering_time(offset);
        Passage {
            window: [
                larger(time - self.time_half_width, lo),
                smaller(time + self.time_half_width, hi),
            ],
            time,
            depth: self.surface_depth(offset, time),
            depth_rate: self.depth_rate,
        }
    }

    /// The middle of the footprint's covering time at `offset` from its centre.
    #[inline]
    fn covering_time(&self, [dx, dy]: [f32; 2]) -> f32 {
        let [lo, hi] = self.time_span;
        let t = self.time_center + self.time_gradient[0] * dx + self.time_gradient[1] * dy;
        smaller(larger(t, lo), hi)
    }

    /// Depth of the splat plane at `offset` from its centre, at `time_center`.
    #[inline]
    fn plane_depth(&self, [dx, dy]: [f32; 2]) -> f32 {
        self.depth + self.depth_gradient[0] * dx + self.depth_gradient[1] * dy
    }

    /// Depth of the splat plane at `offset` from its centre at exposure time `time`.
    #[inline]
    fn surface_depth(&self, offset: [f32; 2], time: f32) -> f32 {
        self.plane_depth(offset) + self.depth_rate * (time - self.time_center)
    }

    /// Call `visit` with the index of every tile (in a row of `tiles_x`) whose pixels the
    /// footprint reaches. A long tilted motion ellipse crosses a thin diagonal band of its bounding
    /// box's tiles, so footprints spanning at least three tile rows and columns are binned by the
    /// row spans of each tile row; smaller ones take their whole box, which costs less to find.
    fn for_each_tile(&self, grid: &TileGrid, visit: &mut dyn FnMut(usize)) {
        match self.streak {
            Some(streak) => {
                self.tiles_within(
                    &StreakRows::new(streak, self.center, self.bounds),
                    grid,
                    visit,
                );
            }
            None => self.tiles_within(&Ellipse::new(self, None), grid, visit),
        }
    }

    /// [`Self::for_each_tile`] for the footprint's `shape`.
    fn tiles_within(&self, shape: &impl Shape, grid: &TileGrid, visit: &mut dyn FnMut(usize)) {
        let [x0, y0, x1, y1] = self.bounds;
        let tile_px = grid.tile_px();
        let (tx0, tx1) = (x0 / tile_px, (x1 - 1) / tile_px);
        let (ty0, ty1) = (y0 / tile_px, (y1 - 1) / tile_px);
        for ty in ty0..=ty1 {
            let (lo, hi) = if tx1 - tx0 < 2 || ty1 - ty0 < 2 {
                (x0, x1)
            } else {
                let rows = y0.max(ty * tile_px)..y1.min((ty + 1) * tile_px);
                rows.map(|y| shape.span(y))
                    .filter(|(a, b)| a < b)
                    .fold((u32::MAX, 0), |(lo, hi), (a, b)| (lo.min(a), hi.max(b)))
            };
            if lo < hi {
                for tx in lo / tile_px..=(hi - 1) / tile_px {
                    visit(grid.index(tx, ty));
                }
            }
        }
    }

    /// Depth of the splat plane at the centre of pixel (x, y) while the footprint covers it.
    #[inline]
    #[must_use]
    pub fn depth_at(&self, x: u32, y: u32) -> f32 {
        let offset = self.offset(x, y);
        if self.depth_rate == 0.0 {
            self.plane_depth(offset)
        } else {
            self.surface_depth(offset, self.covering_time(offset))
        }
    }

    /// Pixel columns [x0, x1) of row `y` whose centres lie inside the cut-off ellipse (clipped
    /// to the bounds): an elongated, tilted motion ellipse fills a small part of its bounding box.
    #[inline]
    #[must_use]
    #[cfg(test)]
    pub fn row_span(&self, y: u32) -> (u32, u32) {
        RowSpans::new(self).span(y)
    }
}

/// A footprint's cut-off ellipse row by row, with what does not depend on the row worked out
/// once: a·dx² + 2b·dy·dx + c·dy² ≤ Q holds for dx within √(Q/a − (ac − b²)/a² · dy²) of
/// −(b/a)·dy. Footprints are small (2.4 pixels per row on average on the torus knot at 1024²),
/// so the per-row cost counts.
struct RowSpans {
    /// Centre column less ½ (pixel x covers the ellipse where x + ½ lies inside).
    centre: f32,
    shear: f32,
    /// Q/a and (ac − b²)/a².
    reach: f32,
    narrowing: f32,
    centre_y: f32,
    /// The bounds' first and last column.
    first: f32,
    last: f32,
}

impl RowSpans {
    #[inline]
    fn new(f: &Footprint) -> RowSpans {
        let [a, b, c] = f.conic;
        let (shear, reach, narrowing) = if a > 0.0 {
            let shear = b / a;
            // (ac − b²)/a²; where a² is below f32's normal range (a footprint wider than about
            // 10⁹ px, a surfel scaled past 10¹¹ in front of the camera), as c/a − (b/a)², which
            // does not underflow to 0/0 and lose the whole footprint.
            let narrowing = if a * a >= f32::MIN_POSITIVE {
                (a * c - b * b) / (a * a)
            } else {
                c / a - shear * shear
            };
            (shear, CUTOFF_Q / a, narrowing)
        } else {
            (0.0, -1.0, 0.0)
        };
        RowSpans {
            centre: f.center[0] - 0.5,
            shear,
            reach,
            narrowing,
            centre_y: f.center[1],
            first: f.bounds[0] as f32,
            last: f.bounds[2] as f32 - 1.0,
        }
    }

    /// Columns [x0, x1) of row `y` inside the ellipse and the bounds.
    #[inline]
    fn span(&self, y: u32) -> (u32, u32) {
        let dy = y as f32 + 0.5 - self.centre_y;
        let squared = self.reach - self.narrowing * dy * dy;
        if !(squared >= 0.0) {
            return (0, 0);
        }
        let half_width = squared.sqrt();
        let centre = self.centre - self.shear * dy;
        columns_within(
            centre - half_width,
            centre + half_width,
            self.first,
            self.last,
        )
    }
}

/// Columns [⌈lo⌉, ⌊hi⌋ + 1) clamped to the columns [first, last] (whole numbers, 0 ≤ first ≤
/// last < 2²²); (0, 0) where none is left. Clamped before rounding, so that a NaN or huge `lo` or
/// `hi` meets the bounds.
#[inline]
fn columns_within(lo: f32, hi: f32, first: f32, last: f32) -> (u32, u32) {
    let (lo, hi) = (larger(lo, first), smaller(hi, last));
    if hi >= lo {
        (ceil_small(lo) as u32, floor_small(hi) as u32 + 1)
    } else {
        (0, 0)
    }
}

/// A footprint's outline and value, pixel by pixel: an ellipse with its profile, or an exact
/// streak.
trait Shape {
    /// What the pixels of one row share.
    type Row: Copy;
    /// Columns [x0, x1) of row `y` inside the cut-off and the bounds.
    fn span(&self, y: u32) -> (u32, u32);
    /// The row `dy` below the centre (pixel centres' offset).
    fn row(&self, dy: f32) -> Self::Row;
    /// The value before the amplitude at offset `dx` from the centre in `row` (zero beyond the
    /// cut-off), and its first moment along the shape: the value times where along a streak's
    /// chord its light there comes from on average, in standard deviations (zero for an ellipse;
    /// needed only where [`Shape::colour_slope`] is some).
    fn value(&self, row: Self::Row, dx: f32) -> (f32, f32);
    /// How much its colour changes per unit along it, as a share of itself, where it changes
    /// (see [`Shape::value`]): `None` for an ellipse and for a streak whose colour is even.
    fn colour_slope(&self) -> Option<f32>;
    /// The value below which the shape is faint at a pixel ([`composite::FAINT_VALUE`] of its
    /// peak).
    fn faint_below(&self) -> f32;
}

/// An elliptical footprint: its rows, conic and profile.
struct Ellipse<'a> {
    spans: RowSpans,
    conic: [f32; 3],
    sampler: Sampler<'a>,
}

impl<'a> Ellipse<'a> {
    #[inline]
    fn new(f: &Footprint, texture: Option<&'a Texture>) -> Self {
        Ellipse {
            spans: RowSpans::new(f),
            conic: f.conic,
            sampler: Sampler::new(f.profile, f.conic, f.time_gradient, texture),
        }
    }
}

impl Shape for Ellipse<'_> {
    /// dy, c·dy² and 2b·dy.
    type Row = [f32; 3];

    #[inline]
    fn span(&self, y: u32) -> (u32, u32) {
        self.spans.span(y)
    }

    #[inline]
    fn row(&self, dy: f32) -> [f32; 3] {
        let [_, b, c] = self.conic;
        [dy, c * dy * dy, 2.0 * b * dy]
    }

    #[inline]
    fn value(&self, [dy, row_q, row_slope]: [f32; 3], dx: f32) -> (f32, f32) {
        let q = dx * (self.conic[0] * dx + row_slope) + row_q;
        if q > CUTOFF_Q {
            (0.0, 0.0)
        } else {
            (self.sampler.value([dx, dy], q), 0.0)
        }
    }

    fn colour_slope(&self) -> Option<f32> {
        None
    }

    fn faint_below(&self) -> f32 {
        composite::FAINT_VALUE * self.sampler.peak()
    }
}

/// What the rasterizer did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RasterStats {
    /// Footprints rasterized.
    pub footprints: usize,
    /// Footprint–tile pairs binned.
    pub tile_entries: usize,
    /// Largest number of footprints in one tile.
    pub max_per_tile: usize,
}

/// A rasterized layer, to be composited over what lies behind it.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB, premultiplied: what the layer adds to the pixel.
    pub colour: Vec<[f32; 3]>,
    /// The share of what lies behind that still shows, in [0, 1].
    pub transmittance: Vec<f32>,
    /// Depth of the visible surface: the first where the transmittance fell below ½ (+∞ where
    /// it never did).
    pub front_depth: Vec<f32>,
}

impl Layer {
    /// Draw the layer over `image`, of the same size, in place (a new image for each layer would
    /// hold two at once).
    pub fn draw_over(&self, image: &mut Framebuffer) {
        (image.pixels.par_iter_mut())
            .zip(&self.colour)
            .zip(&self.transmittance)
            .for_each(|((b, &c), &t)| *b = over(c, t, *b));
    }

    /// The layer with what it holds beyond `base` (a layer of some of its footprints, of the same
    /// size) seen through `opacity` in [0, 1]: its premultiplied colour and transmittance taken
    /// `opacity` of the way from `base`'s to its own. Where only its other footprints show they
    /// fade toward what lies behind, where `base`'s are in front they stay as they are, and where
    /// the others pass in front of `base`'s, those show through them.
    #[must_use]
    pub fn faded_beyond(mut self, base: &Layer, opacity: f32) -> Layer {
        let lerp = |from: f32, to: f32| from + opacity * (to - from);
        for ((c, t), (&base_c, &base_t)) in (self.colour.iter_mut().zip(&mut self.transmittance))
            .zip(base.colour.iter().zip(&base.transmittance))
        {
            *c = [0, 1, 2].map(|i| lerp(base_c[i], c[i]));
            *t = lerp(base_t, *t);
        }
        self
    }
}

/// Where footprints are drawn: the image size, and what some renderers add.
#[derive(Clone, Copy, Debug)]
pub struct Target<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The image [`Profile::Texture`] footprints map.
    pub texture: Option<&'a Texture>,
    /// Per-pixel depth of surfaces drawn elsewhere (a [`Layer::front_depth`]): a footprint is
    /// left out of a pixel where its plane lies at or behind that depth less its own tolerance.
    pub occluder: Option<&'a [f32]>,
}

impl Target<'_> {
    /// A plain `width`×`height` target.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        Target {
            width,
            height,
            texture: None,
            occluder: None,
        }
    }
}

/// Rasterize `footprints` into a layer the size of `target`, compositing coverage in the time
/// bins `bins` (one bin for an instant).
#[must_use]
pub fn rasterize<const B: usize>(
    footprints: &[Footprint],
    target: &Target,
    bins: &TimeBins<B>,
) -> (Layer, RasterStats) {
    let (width, height) = (target.width, target.height);
    let grid = splat_grid(width, height);
    // Every pixel is written by the tile pass, so the layer starts as zeroed memory, whose pages
    // are faulted in by the tasks that first write them rather than filled serially here.
    let size = width as usize * height as usize;
    let mut layer = Layer {
        width,
        height,
        colour: vec![[0.0; 3]; size],
        transmittance: vec![0.0; size],
        front_depth: vec![0.0; size],
    };
    let band = grid.band_len();
    let bands = (layer.colour.par_chunks_mut(band))
        .zip(layer.transmittance.par_chunks_mut(band))
        .zip(layer.front_depth.par_chunks_mut(band));
    let stats = tile_pass(
        footprints,
        target,
        &grid,
        bins,
        bands,
        |((colour, transmittance), front_depth), i, _, (c, t, d)| {
            colour[i] = c;
            transmittance[i] = t;
            front_depth[i] = d;
        },
    );
    (layer, stats)
}

/// Rasterize `footprints` like [`rasterize`] and composite the layer at once over `behind`
/// (what lies behind pixel i), without keeping the layer: what a renderer whose image is one
/// layer over its background needs, without the layer's memory (20 MB at 1024²) and a second
/// pass over it.
#[must_use]
pub fn rasterize_over<const B: usize>(
    footprints: &[Footprint],
    target: &Target,
    bins: &TimeBins<B>,
    behind: impl Fn(usize) -> [f32; 3] + Sync,
) -> (Framebuffer, RasterStats) {
    let grid = splat_grid(target.width, target.height);
    rasterize_over_grid(footprints, target, &grid, bins, behind)
}

/// [`rasterize_over`] in the tiles of `grid`.
fn rasterize_over_grid<const B: usize>(
    footprints: &[Footprint],
    target: &Target,
    grid: &TileGrid,
    bins: &TimeBins<B>,
    behind: impl Fn(usize) -> [f32; 3] + Sync,
) -> (Framebuffer, RasterStats) {
    let (width, height) = (target.width, target.height);
    let mut pixels = vec![[0.0; 3]; width as usize * height as usize];
    let bands = pixels.par_chunks_mut(grid.band_len());
    let stats = tile_pass(
        footprints,
        target,
        grid,
        bins,
        bands,
        |band, i, pixel, (c, t, _)| {
            band[i] = over(c, t, behind(pixel));
        },
    );
    let image = Framebuffer {
        width,
        height,
        pixels,
    };
    (image, stats)
}

/// A premultiplied `colour` with `transmittance` over `behind`.
#[inline]
pub(crate) fn over(colour: [f32; 3], transmittance: f32, behind: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|k| colour[k] + transmittance * behind[k])
}

/// Bin `footprints` into the tiles of `grid` and render them, one row of tiles per task:
/// `write(band, i, pixel, finished)` stores pixel `i` of the `bands` item of its tile row (image
/// pixel index `pixel`) as (premultiplied colour, transmittance, depth of the visible surface).
fn tile_pass<const B: usize, T: Send>(
    footprints: &[Footprint],
    target: &Target,
    grid: &TileGrid,
    bins: &TimeBins<B>,
    bands: impl IndexedParallelIterator<Item = T>,
    write: impl Fn(&mut T, usize, usize, ([f32; 3], f32, f32)) + Sync,
) -> RasterStats {
    // Binned in footprint order; each tile sorts its own list by depth (docs/architecture.md,
    // "The rasterizer"): a global sort would leave every tile reading its footprints in random
    // memory order.
    let lists = TileLists::new(grid, footprints.len(), |index, visit| {
        footprints[index as usize].for_each_tile(grid, visit);
    });
    // A tile no footprint reaches is clear, without setting up and finishing its pixel states.
    let mut empty = PixelState::<B>::EMPTY;
    let clear = empty.finish(bins);
    lists.by_rows_costliest_first(grid, bands.collect(), |ty, mut band: T| {
        let mut scratch = TileScratch::default();
        let band_start = ty * grid.band_len();
        for tile in grid.row(ty) {
            let list = lists.list(tile);
            let pixels: &mut [PixelState<B>] = if list.is_empty() {
                &mut []
            } else {
                render_tile(
                    footprints,
                    list,
                    grid.pixels(tile),
                    target,
                    bins,
                    &mut scratch,
                )
            };
            for (k, at) in grid.in_band(tile).enumerate() {
                let finished = pixels.get_mut(k).map_or(clear, |p| p.finish(bins));
                write(&mut band, at, band_start + at, finished);
            }
        }
    });
    RasterStats {
        footprints: footprints.len(),
        tile_entries: lists.entries(),
        max_per_tile: lists.longest(),
    }
}

/// What rendering a tile needs and can reuse from one tile to the next.
#[derive(Default)]
struct TileScratch<const B: usize> {
    /// The tile's footprints as depth keys.
    order: Vec<u64>,
    /// The tile's pixels, row by row.
    pixels: Vec<PixelState<B>>,
}

/// A key whose unsigned order is the total order of f32 (`f32::total_cmp`).
#[inline]
fn order_key(value: f32) -> u32 {
    let bits = value.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | 1 << 31
    }
}

/// 2²³: a float in [0, 2²²) plus this is rounded to an integer, which its low mantissa bits hold.
const ROUNDING: f32 = 8_388_608.0;

/// The integer nearest to `u` ≥ 0 (below 2²²), as an index and as a float: by rounding, which
/// costs fewer instructions than the saturating float-to-integer conversion `as` makes (the
/// table lookups of every pixel).
#[inline]
pub(crate) fn nearest_step(u: f32) -> (usize, f32) {
    let rounded = u + ROUNDING;
    ((rounded.to_bits() & 0x7f_ffff) as usize, rounded - ROUNDING)
}

/// ⌊u⌋ for 0 ≤ u < 2²², by rounding as [`nearest_step`] does: without the libm call
/// `f32::floor` becomes on baseline x86-64, and without the saturating conversion of `as`.
#[inline]
pub(crate) fn floor_small(u: f32) -> usize {
    let (i, nearest) = nearest_step(u);
    i - usize::from(nearest > u)
}

/// ⌈u⌉ for 0 ≤ u < 2²²: the counterpart of [`floor_small`].
#[inline]
pub(crate) fn ceil_small(u: f32) -> usize {
    let (i, nearest) = nearest_step(u);
    i + usize::from(nearest < u)
}

/// `a.max(b)` for a `b` that is not NaN (a NaN `a` gives `b`, as there), in one compare: on
/// x86-64 `f32::max` adds four instructions for the case of a NaN `b`. The footprint loop takes
/// several per pixel of every footprint.
#[inline]
pub(crate) fn larger<T: PartialOrd>(a: T, b: T) -> T {
    if a > b {
        a
    } else {
        b
    }
}

/// `a.min(b)` for a `b` that is not NaN: the counterpart of [`larger`].
#[inline]
pub(crate) fn smaller<T: PartialOrd>(a: T, b: T) -> T {
    if a < b {
        a
    } else {
        b
    }
}

/// Composite the footprints binned to one tile, in depth order (the footprint's index breaking
/// ties, so the order is total); returns the tile's open pixel states row by row.
fn render_tile<'s, const B: usize>(
    footprints: &[Footprint],
    list: &[u32],
    tile @ [x0, y0, x1, y1]: [u32; 4],
    target: &Target,
    bins: &TimeBins<B>,
    scratch: &'s mut TileScratch<B>,
) -> &'s mut [PixelState<B>] {
    let w = (x1 - x0) as usize;
    let size = w * (y1 - y0) as usize;
    let TileScratch { order, pixels } = scratch;
    pixels.clear();
    pixels.resize(size, PixelState::<B>::EMPTY);
    order.clear();
    order.extend(
        list.iter()
            .map(|&i| u64::from(order_key(footprints[i as usize].depth)) << 32 | u64::from(i)),
    );
    order.sort_unstable();
    for (k, &key) in order.iter().enumerate() {
        if let Some(&ahead) = order.get(k + 4) {
            crate::memory::prefetch(&footprints[ahead as u32 as usize]);
        }
        let f = &footprints[key as u32 as usize];
        match f.streak {
            Some(streak) => {
                let shape = StreakRows::new(streak, f.center, f.bounds);
                composite_footprint(f, &shape, pixels, tile, target, bins);
            }
            None => {
                let shape = Ellipse::new(f, target.texture);
                composite_footprint(f, &shape, pixels, tile, target, bins);
            }
        }
    }
    pixels
}

/// Composite footprint `f`, drawn as `shape`, into the open pixel states of `tile`.
#[inline]
fn composite_footprint<const B: usize>(
    f: &Footprint,
    shape: &impl Shape,
    pixels: &mut [PixelState<B>],
    [x0, y0, x1, y1]: [u32; 4],
    target: &Target,
    bins: &TimeBins<B>,
) {
    let w = (x1 - x0) as usize;
    let [_, fy0, _, fy1] = f.bounds;
    let colour_slope = shape.colour_slope();
    let faint_below = shape.faint_below();
    for y in fy0.max(y0)..fy1.min(y1) {
        let row = (y - y0) as usize * w;
        let (sx0, sx1) = shape.span(y);
        let row_shape = shape.row(y as f32 + 0.5 - f.center[1]);
        for x in sx0.max(x0)..sx1.min(x1) {
            let state = &mut pixels[row + (x - x0) as usize];
            if state.is_opaque() {
                continue;
            }
            if let Some(occluder) = target.occluder {
                let front = occluder[y as usize * target.width as usize + x as usize];
                if f.depth_at(x, y) >= front - f.depth_tolerance {
                    continue;
                }
            }
            let dx = x as f32 + 0.5 - f.center[0];
            let (value, moment) = shape.value(row_shape, dx);
            let weight = f.amplitude * value;
            if weight > 0.0 {
                let faint = value < faint_below;
                let counted = state.add(f, weight, faint, [x, y], bins);
                if let Some(slope) = colour_slope {
                    let change = f.colour_change_at(moment, slope);
                    state.add_colour_change(f.additive, change, counted);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gaussian(
        center: DVec2,
        covariance: Sym2,
        weight: f64,
        colour: [f32; 3],
        depth: f64,
    ) -> ScreenSplat {
        ScreenSplat {
            center,
            covariance,
            weight,
            colour,
            depth,
            depth_gradient: DVec2::ZERO,
            depth_tolerance: 0.01,
            depth_rate: 0.0,
            time: TimeExtent::WHOLE_FRAME,
            profile: Profile::Gaussian,
            sweep: DVec2::ZERO,
            sweep_change: 0.0,
            colour_change: 0.0,
            additive: false,
        }
    }

    fn draw(
        footprints: &[Footprint],
        width: u32,
        height: u32,
        background: [f32; 3],
    ) -> Framebuffer {
        let target = Target::new(width, height);
        rasterize_over(footprints, &target, &TimeBins::INSTANT, |_| background).0
    }

    fn splat(center: DVec2, variance: f64, weight: f64, colour: [f32; 3], depth: f64) -> Footprint {
        gaussian(center, Sym2::isotropic(variance), weight, colour, depth)
            .footprint(64, 64)
            .unwrap()
    }

    #[test]
    fn row_spans_cover_exactly_the_pixels_inside_the_cut_off() {
        let covariance = Sym2 {
            xx: 90.0,
            xy: 55.0,
            yy: 40.0,
        };
        let f = gaussian(DVec2::new(30.2, 27.9), covariance, 1.0, [1.0; 3], 1.0)
            .footprint(64, 64)
            .unwrap();
        for y in 0..64 {
            let (x0, x1) = f.row_span(y);
            for x in 0..64 {
                let dx = x as f32 + 0.5 - f.center[0];
                let dy = y as f32 + 0.5 - f.center[1];
                let q = f.conic[0] * dx * dx + 2.0 * f.conic[1] * dx * dy + f.conic[2] * dy * dy;
                // Points on the cut-off itself may round either way in f32; all others must agree.
                if (q - CUTOFF_Q).abs() > 1e-3 {
                    assert_eq!(
                        q <= CUTOFF_Q,
                        (x0..x1).contains(&x),
                        "pixel ({x}, {y}), span {x0}..{x1}"
                    );
                }
            }
        }
    }

    #[test]
    fn small_disc_ring_and_texture_footprints_sum_to_their_weight_wherever_they_fall() {
        // The narrowest footprints, round and stretched along a diagonal: unweighed, their pixel
        // samples sum to 0.75–1.25 of the weight as the centre moves within a pixel.
        let texture = Texture::new(2, 2, vec![1.0, 0.2, 0.6, 0.0]).unwrap();
        let stretched = Sym2 {
            xx: 2.0,
            xy: 1.7,
            yy: 2.0,
        };
        for profile in [Profile::Disc, Profile::Ring, Profile::Texture] {
            for covariance in [Sym2::isotropic(PREFILTER_VARIANCE_PX2), stretched] {
                for offset in 0..7 {
                    let center = DVec2::new(20.0, 30.0) + DVec2::new(0.13, 0.07) * offset as f64;
                    let mut splat = gaussian(center, covariance, 0.8, [1.0; 3], 1.0);
                    splat.profile = profile;
                    let sum = summed_weight(&splat, [64, 64], &texture);
                    // f32 sums of a few dozen samples.
                    assert!(
                        (sum - 0.8).abs() < 1e-5,
                        "{profile:?} {covariance:?} at {center}: {sum}"
                    );
                }
            }
        }
    }

    /// The weights of `splat`'s footprint in a `width` × `height` image, each pixel weighed by
    /// its own samples of `texture`, summed.
    fn summed_weight(splat: &ScreenSplat, [width, height]: [u32; 2], texture: &Texture) -> f32 {
        let mut f = splat.footprint(width, height).unwrap();
        f.weigh_by_pixel_samples(Some(texture));
        (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| f.weight_at(x, y, Some(texture)))
            .sum()
    }

    /// A texture lit at one texel of 64², on round and turned footprints whose texture square
    /// spans 6 to 48 px: each pixel takes the mean over the texels it covers, so the samples sum
    /// to the weight wherever the footprint falls. Sampled at pixel centres, the lit texel was
    /// caught or missed by chance (none of it at σ = 1 px).
    #[test]
    fn texture_detail_finer_than_a_pixel_keeps_its_weight() {
        let mut values = vec![0.0; 64 * 64];
        values[32 * 64 + 32] = 1.0;
        let texture = Texture::new(64, 64, values).unwrap();
        let round = [1.0, 2.0, 4.0, 8.0].map(|sigma: f64| Sym2::isotropic(sigma * sigma));
        let turned = [1.0, 4.0, 16.0].map(|variance| Sym2 {
            xx: variance,
            xy: 0.85 * variance,
            yy: variance,
        });
        for covariance in round.into_iter().chain(turned) {
            let sigma = covariance.xx.sqrt();
            for offset in 0..7 {
                let center = DVec2::new(40.0, 30.0) + DVec2::new(0.13, 0.07) * offset as f64;
                let mut splat = gaussian(center, covariance, 0.8, [1.0; 3], 1.0);
                splat.profile = Profile::Texture;
                let sum = summed_weight(&splat, [80, 64], &texture);
                // The pixels' boxes tile the texture where its axes are the pixel grid's and
                // nearly so where they are turned; the rest is f32 summing.
                assert!(
                    (sum / 0.8 - 1.0).abs() < 5e-3,
                    "σ = {sigma} px at {center}: {sum} of 0.8"
                );
            }
        }
    }

    #[test]
    fn pixel_samples_of_a_footprint_sum_to_its_weight() {
        let f = splat(
            DVec2::new(20.3, 31.7),
            PREFILTER_VARIANCE_PX2,
            0.8,
            [1.0; 3],
            1.0,
        );
        let sum: f32 = (0..64)
            .flat_map(|y| (0..64).map(move |x| (x, y)))
            .map(|(x, y)| f.weight_at(x, y, None))
            .sum();
        // Pixel-centre sampling of the narrowest allowed Gaussian at this offset: 0.4 % (2 % at
        // worst, see PREFILTER_VARIANCE_PX2).
        assert!((sum - 0.8).abs() < 0.8 * 0.004, "{sum}");
    }

    #[test]
    fn a_nearer_opaque_surface_hides_a_farther_one() {
        let red = splat(DVec2::new(32.0, 32.0), 40.0, 400.0, [1.0, 0.0, 0.0], 1.0);
        let blue = splat(DVec2::new(32.0, 32.0), 40.0, 400.0, [0.0, 0.0, 1.0], 2.0);
        for list in [vec![red, blue], vec![blue, red]] {
            let image = draw(&list, 64, 64, [0.0; 3]);
            let p = image.pixels[32 * 64 + 32];
            assert!(p[0] > 0.999 && p[2] < 1e-3, "{p:?}");
        }
    }

    #[test]
    fn splats_of_one_surface_blend_by_normalized_weight() {
        let mut a = splat(DVec2::new(32.0, 32.0), 40.0, 400.0, [1.0, 0.0, 0.0], 1.0);
        let mut b = splat(DVec2::new(32.0, 32.0), 40.0, 400.0, [0.0, 0.0, 1.0], 1.005);
        a.depth_tolerance = 0.01;
        b.depth_tolerance = 0.01;
        let image = draw(&[a, b], 64, 64, [0.0; 3]);
        let p = image.pixels[32 * 64 + 32];
        assert!(
            (p[0] - 0.5).abs() < 1e-5 && (p[2] - 0.5).abs() < 1e-5,
            "{p:?}"
        );
    }

    #[test]
    fn partial_coverage_blends_with_the_background() {
        // A footprint spread far wider than the image, whose value is ≈ 0.25 on every pixel.
        let f = splat(
            DVec2::new(32.0, 32.0),
            1e6,
            0.25 * std::f64::consts::TAU * 1e6 / TRUNCATION_GAIN,
            [1.0, 0.0, 0.0],
            1.0,
        );
        let image = draw(&[f], 64, 64, [0.0, 0.0, 1.0]);
        let p = image.pixels[0];
        assert!(
            (p[0] - 0.25).abs() < 1e-3 && (p[2] - 0.75).abs() < 1e-3,
            "{p:?}"
        );
    }

    #[test]
    fn a_footprint_a_trillion_pixels_wide_still_covers_the_image_and_past_f32_is_rejected() {
        // σ = 10¹² px: the conic's a² (10⁻⁴⁸) underflows f32, where the rows' narrowing once
        // became 0/0 and the footprint lost every pixel (a surfel scaled by 10¹² in front of the
        // camera made one 10¹¹ px wide, and lost them too).
        let wide = |variance: f64| {
            gaussian(
                DVec2::new(32.0, 32.0),
                Sym2::isotropic(variance),
                0.25 * std::f64::consts::TAU * variance / TRUNCATION_GAIN,
                [1.0, 0.0, 0.0],
                1.0,
            )
            .footprint(64, 64)
        };
        let image = draw(&[wide(1e24).unwrap()], 64, 64, [0.0, 0.0, 1.0]);
        for p in [image.pixels[0], image.pixels[64 * 64 - 1]] {
            assert!(
                (p[0] - 0.25).abs() < 1e-3 && (p[2] - 0.75).abs() < 1e-3,
                "{p:?}"
            );
        }
        // σ = 10²⁰ px: the conic itself is below f32's normal range.
        assert_eq!(wide(1e40), Err(Rejection::Degenerate));
    }

    #[test]
    fn off_screen_and_degenerate_footprints_are_rejected() {
        let off = gaussian(
            DVec2::new(-100.0, 10.0),
            Sym2::isotropic(1.0),
            1.0,
            [1.0; 3],
            1.0,
        );
        assert_eq!(off.footprint(64, 64), Err(Rejection::OffScreen));
        let flat = gaussian(
            DVec2::new(10.0, 10.0),
            Sym2::outer(DVec2::X),
            1.0,
            [1.0; 3],
            1.0,
        );
        assert_eq!(flat.footprint(64, 64), Err(Rejection::Degenerate));
        let nan = gaussian(
            DVec2::new(f64::NAN, 10.0),
            Sym2::isotropic(1.0),
            1.0,
            [1.0; 3],
            1.0,
        );
        assert_eq!(nan.footprint(64, 64), Err(Rejection::Degenerate));
    }

    /// Packing is where f64 becomes f32 (docs/conventions.md, "Precision: f64 and f32"): a
    /// number finite in f64 but beyond f32's range cannot be represented there and is degenerate,
    /// like a non-finite one. Packed as infinity, a depth of 10³⁹ (a scene scaled by 10³⁸) made
    /// every footprint a surface of its own (∞ − ∞ is NaN in the depth test), and an amplitude
    /// of ∞ painted NaN.
    #[test]
    fn numbers_beyond_f32_are_rejected_when_packed() {
        let s = gaussian(
            DVec2::new(32.0, 32.0),
            Sym2::isotropic(1.0),
            1.0,
            [1.0, 0.0, 0.0],
            1.0,
        );
        let huge = 1e39;
        for beyond in [
            ScreenSplat { depth: huge, ..s },
            ScreenSplat {
                depth_tolerance: huge,
                ..s
            },
            ScreenSplat {
                depth_rate: huge,
                ..s
            },
            ScreenSplat {
                depth_gradient: DVec2::new(huge, 0.0),
                ..s
            },
            ScreenSplat {
                weight: 100.0 * huge,
                ..s
            },
        ] {
            let packed = beyond.footprint(64, 64);
            assert_eq!(
                packed.as_ref().err(),
                Some(&Rejection::Degenerate),
                "{beyond:?} packed as {packed:?}"
            );
        }
    }

    #[test]
    fn rounding_gives_floor_and_ceil_at_and_between_whole_numbers() {
        // Whole numbers, the points half-way (where rounding to even goes either way) and the
        // floats next to them, up to the largest image side and beyond it.
        for whole in (0..70).chain([4095, 4096, 8191, 8192, 1 << 21, (1 << 22) - 1]) {
            let w = whole as f32;
            for u in [w, w + 0.5, w + 0.25, w + 0.75, w.next_up(), w.next_down()] {
                if (0.0..(1 << 22) as f32).contains(&u) {
                    assert_eq!(floor_small(u), u.floor() as usize, "⌊{u}⌋");
                    assert_eq!(ceil_small(u), u.ceil() as usize, "⌈{u}⌉");
                }
            }
        }
    }

    /// The tile size changes which tasks composite a pixel, never its footprints or their
    /// order: still splats and sliding streaks in time bins, over an image whose sides are no
    /// multiple of either tile, come out the same to the bit in tiles of 16 and 32 px.
    #[test]
    fn the_image_does_not_depend_on_the_tile_size() {
        let (width, height) = (150, 100);
        let mut state = 0x2545_f491_u64;
        let mut random = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let footprints: Vec<Footprint> = (0..400)
            .filter_map(|i| {
                let center = DVec2::new(random() * 170.0 - 10.0, random() * 120.0 - 10.0);
                let mut s = gaussian(
                    center,
                    Sym2::isotropic(0.3 + 6.0 * random()),
                    1.0 + 20.0 * random(),
                    [random() as f32, random() as f32, random() as f32],
                    1.0 + random(),
                );
                if i % 2 == 0 {
                    let sweep = DVec2::new(random() - 0.5, random() - 0.5) * 60.0;
                    s.sweep = sweep;
                    s.time = TimeExtent {
                        center: 0.5,
                        gradient: sweep / sweep.length_squared(),
                        half_width: 0.05 + 0.1 * random(),
                        span: [0.0, 1.0],
                    };
                }
                s.footprint(width, height).ok()
            })
            .collect();
        let target = Target::new(width, height);
        let bins = TimeBins::<32>::over(&crate::scene::shutter::Shutter::default());
        let image = |tile_px| {
            let grid = TileGrid::with_tile_px(width, height, tile_px);
            rasterize_over_grid(&footprints, &target, &grid, &bins, |_| [0.1, 0.2, 0.3]).0
        };
        let bits = |f: Framebuffer| -> Vec<[u32; 3]> {
            f.pixels.iter().map(|p| p.map(f32::to_bits)).collect()
        };
        assert!(footprints.iter().filter(|f| f.streak.is_some()).count() > 100);
        assert_eq!(bits(image(TILE_PX)), bits(image(LARGE_TILE_PX)));
    }

    #[test]
    fn textured_footprints_in_time_bins_keep_their_depth_order() {
        // Two wide textured splats over one pixel, red in front of green, composited in 32 bins
        // as a textured trail is. A white texture is scaled to integrate to one, so its values are
        // about 0.035 everywhere: measured against 1 rather than its own peak, every pixel was
        // faint, no chain formed, and both joined one group (½ red, ½ green).
        let texture = Texture::new(16, 16, vec![1.0; 256]).unwrap();
        let textured = |colour, depth| {
            let mut s = gaussian(
                DVec2::new(32.0, 32.0),
                Sym2::isotropic(40.0),
                2000.0,
                colour,
                depth,
            );
            s.profile = Profile::Texture;
            s.footprint(64, 64).unwrap()
        };
        let footprints = [
            textured([1.0, 0.0, 0.0], 1.0),
            textured([0.0, 1.0, 0.0], 2.0),
        ];
        let target = Target {
            texture: Some(&texture),
            ..Target::new(64, 64)
        };
        let bins = TimeBins::<32>::over(&crate::scene::shutter::Shutter::default());
        let image = rasterize_over(&footprints, &target, &bins, |_| [0.0; 3]).0;
        let p = image.pixels[32 * 64 + 32];
        assert!(p[0] > 0.99 && p[1] < 0.01, "{p:?}");
    }

    #[test]
    fn image_sizes_that_are_not_multiples_of_the_tile_work() {
        let f = gaussian(
            DVec2::new(36.0, 20.0),
            Sym2::isotropic(4.0),
            50.0,
            [1.0; 3],
            1.0,
        );
        let image = draw(&[f.footprint(37, 21).unwrap()], 37, 21, [0.0; 3]);
        assert_eq!(image.pixels.len(), 37 * 21);
        assert!(image.pixels[20 * 37 + 36][0] > 0.5);
    }
}
