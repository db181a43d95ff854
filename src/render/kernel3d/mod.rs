//! Motion blur with 3D spatio-temporal kernels and exact temporal visibility (Heinzle et al.
//! 2010, §3–5). The exposure is cut into sub-frames (§5.5), each weighted by its share of the
//! shutter; per surfel and sub-frame a kernel spans the splat's two axes and its motion
//! ([`kernel`], §4.1), is bounded on screen (§4.3), integrated along each pixel's ray in closed
//! form ([`integral`], §4.2), and its fragments are resolved per pixel by the A-buffer
//! ([`crate::render::abuffer`], §4.4, or the GPU approximation of §5). Kernels of all sub-frames
//! are binned together into tiles; a worker resolves a tile one row of pixels and one time bin
//! of sub-frames at a time (the parts of the exposure add up), so fragments never outlive their
//! row and bin.
//!
//! One choice differs from the paper: a kernel's weight over its sub-frame is uniform in time
//! (the shutter's own weight), not a truncated Gaussian, so consecutive sub-frames add up to the
//! shutter exactly and zero motion is the static splat. Details: docs/math.md, "3D kernel along a
//! ray".

pub(super) mod integral;
mod kernel;

use super::{instant_layer, MethodStats, Render, Stats, Subframes, MAX_SUBFRAMES};
use crate::framebuffer::Framebuffer;
use crate::plan::{ObjectMotion, Plan};
use crate::project::{facing, Cull, Culled, Instant};
use crate::raster::{Rejection, TileGrid, TileLists, TILE_PX};
use crate::render::abuffer::{
    compact, resolve_approximate, resolve_exact, Compaction, Fragment, Resolved, SubFrameBins,
    MAX_FRAGMENTS_PER_PIXEL, TABLE_PARTS,
};
use crate::scene::{Object, Scene, ShutterShape};
use crate::surfels::Surfel;
use glam::{DVec2, DVec3};
use kernel::{hull_overlaps, Kernel, Prepared};
use rayon::prelude::*;

/// How fragments are resolved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Visibility {
    /// The A-buffer: exact temporal visibility (§4.4).
    #[default]
    Exact,
    /// The paper's GPU approximation: start/end depth buffers and the earliest-to-latest covered
    /// time (§5).
    Approximate,
}

/// Sub-frames shorter than this share of the exposure get no kernels: they hold none of its
/// weight that an 8-bit image could show, and a kernel across a jump between two nearly
/// coincident keyframes would draw the jump as a smear.
const SHORTEST_SUBFRAME: f64 = 1e-12;

/// Most depth-buffer pixels the GPU approximation holds at once (256 MiB of f32): its sub-frames
/// are rendered in passes of as many as fit.
const MAX_DEPTH_BUFFER_PIXELS: usize = 1 << 26;

/// Longest screen path, in px, of a planned sub-frame under a tent or Gaussian shutter. Within a
/// sub-frame a kernel's weight is uniform in time (the shutter's shape enters through each
/// sub-frame's mass), which misplaces light along the sub-frame's path where the weight changes:
/// a ball sliding 43 px under a tent shutter, against 1,024 frames, had RMSE 1.7·10⁻² in the two
/// sub-frames planned before this rule, 1.1·10⁻³ in 8 equal ones (5.4 px each), 3.4·10⁻⁴ in 16,
/// and 4.8·10⁻⁴ in the 12 it plans now; `blur` 1.0·10⁻² (docs/history.md, "Shaped shutters in
/// `kernel3d`, and an affine kernel's depth").
pub const SHAPED_SUBFRAME_PX: f64 = 4.0;

/// Most kernels held at once (about 250 bytes each, so about 500 MB). Sub-frames are rendered in
/// passes of as many as fit.
pub const MAX_KERNELS_PER_PASS: usize = 1 << 21;

/// What the kernel renderer did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct KernelStats {
    /// Sub-frames the exposure was cut into.
    pub subframes: usize,
    /// The sub-frames the plan asked for, when more than [`MAX_SUBFRAMES`] (equal sub-frames
    /// were drawn instead).
    pub planned_subframes: Option<usize>,
    /// Equal sub-frames added to the plan's so that a shutter of varying weight, which a
    /// sub-frame draws as uniform, changes little within each ([`SHAPED_SUBFRAME_PX`]).
    pub shaped_subframes: Option<usize>,
    /// Passes the sub-frames were rendered in (more than one when their kernels would not fit
    /// in [`MAX_KERNELS_PER_PASS`]).
    pub passes: usize,
    /// The most kernels held at once.
    pub peak_kernels: usize,
    /// Kernels made, over all sub-frames.
    pub kernels: usize,
    /// Fragments made, over all sub-frames.
    pub fragments: usize,
    /// Fragments resolved: those made, less those merged away.
    pub resolved_fragments: usize,
    /// The most fragments one pixel held (at most [`MAX_FRAGMENTS_PER_PIXEL`]).
    pub peak_fragments_per_pixel: usize,
    /// The most fragments held at once by one worker: one tile row's (the A-buffer's working
    /// memory, per thread).
    pub peak_fragments_held: usize,
    /// Pixels that reached [`MAX_FRAGMENTS_PER_PIXEL`] and had their fragments merged, one per
    /// surface and sub-frame (counted once per pass).
    pub merged_pixels: usize,
    /// Of those, pixels with so many surfaces that ones farther apart than their depth tolerance
    /// were merged too (their depth order within a sub-frame lost).
    pub widened_pixels: usize,
}

impl KernelStats {
    /// Where the kernels departed from the plan: its sub-frames capped at [`MAX_SUBFRAMES`].
    #[must_use]
    pub fn departures(&self) -> Vec<String> {
        self.planned_subframes
            .map(|planned| {
                format!("the plan's {planned} sub-frames capped at {MAX_SUBFRAMES} equal ones")
            })
            .into_iter()
            .collect()
    }

    /// Human-readable account for `--explain`.
    #[must_use]
    pub fn explain(&self) -> String {
        let capped = match self.planned_subframes {
            Some(planned) => format!(
                "  the plan's {planned} sub-frames are more than {MAX_SUBFRAMES}: {MAX_SUBFRAMES} equal sub-frames drawn instead\n"
            ),
            None => String::new(),
        };
        let shaped = match self.shaped_subframes {
            Some(n) => format!(
                "  the shutter's weight varies and a sub-frame draws it as uniform: {n} equal sub-frames added, the fastest path at most {SHAPED_SUBFRAME_PX} px in each\n"
            ),
            None => String::new(),
        };
        let merged = if self.merged_pixels > 0 {
            format!(
                "  {} pixel(s) reached {MAX_FRAGMENTS_PER_PIXEL} fragments: each surface's fragments of one sub-frame merged into one per stretch of time they cover, with its coverage in {TABLE_PARTS} parts of it\n",
                self.merged_pixels
            )
        } else {
            String::new()
        };
        let widened = if self.widened_pixels > 0 {
            format!(
                "  {} of them had more surfaces than that leaves room for: surfaces beyond the depth tolerance merged too, their order within a sub-frame lost\n",
                self.widened_pixels
            )
        } else {
            String::new()
        };
        format!(
            "kernel3d: {} sub-frame(s) in {} pass(es) of at most {} kernels (held at once: {}), {} kernels, {} fragments ({} resolved); peak {} fragments on one pixel, {} held at once by a worker (one tile row, {} KiB)\n{shaped}{capped}{merged}{widened}",
            self.subframes,
            self.passes,
            MAX_KERNELS_PER_PASS,
            self.peak_kernels,
            self.kernels,
            self.fragments,
            self.resolved_fragments,
            self.peak_fragments_per_pixel,
            self.peak_fragments_held,
            self.peak_fragments_held * std::mem::size_of::<Fragment>() / 1024
        )
    }
}

/// Render `scene` with kernels over the sub-frames `subframes` says, resolving visibility as
/// `visibility` says.
pub(super) fn render(
    scene: &Scene,
    plan: &Plan,
    subframes: Subframes,
    visibility: Visibility,
) -> Render {
    render_in_passes(scene, plan, subframes, visibility, MAX_KERNELS_PER_PASS)
}

/// [`render`] holding at most `kernels_per_pass` kernels at once.
fn render_in_passes(
    scene: &Scene,
    plan: &Plan,
    subframes: Subframes,
    visibility: Visibility,
    kernels_per_pass: usize,
) -> Render {
    let camera = &scene.camera;
    let (width, height) = (camera.width, camera.height);
    let (times, planned_subframes, shaped_subframes) = subframe_times(scene, plan, subframes);
    let mut stats = Stats::default();
    let mut kernel3d = KernelStats {
        subframes: times.len() - 1,
        planned_subframes,
        shaped_subframes,
        ..KernelStats::default()
    };
    // Sub-frame windows on the shutter-mass axis.
    let mut windows = Vec::with_capacity(times.len() - 1);
    let mut mass = 0.0;
    for pair in times.windows(2) {
        let next = mass + scene.shutter.mass(pair[0], pair[1]);
        windows.push([mass, next]);
        mass = next;
    }
    let exposure = [0.0, mass];
    // A still object has one kernel for the exposure, whose fragments each time bin clips to its
    // own part of it (`resolve_tile`); a moving one a kernel per sub-frame.
    let mut still_kernels = Vec::new();
    let mut moving_surfels = 0;
    for (object, object_plan, surfels) in plan.drawn() {
        if object_plan.motion == ObjectMotion::Still {
            let span = [scene.shutter.open, scene.shutter.close];
            still_kernels.extend(kernels_over(
                scene,
                (object, surfels),
                span,
                exposure,
                &mut stats.culled,
            ));
        } else {
            moving_surfels += surfels.len();
        }
    }
    // Passes of consecutive sub-frames, as many as keep the kernels within `kernels_per_pass`
    // (and, for the GPU approximation, its depth buffers within MAX_DEPTH_BUFFER_PIXELS).
    // Fragments of different passes cover disjoint parts of the exposure, so resolving each pass
    // over its own part and adding them up is exact.
    let pixel_count = width as usize * height as usize;
    let depth_buffers = match visibility {
        Visibility::Exact => usize::MAX,
        Visibility::Approximate => (MAX_DEPTH_BUFFER_PIXELS / pixel_count).saturating_sub(1),
    };
    let per_pass = (kernels_per_pass.saturating_sub(still_kernels.len()))
        .checked_div(moving_surfels)
        .unwrap_or(windows.len())
        .min(depth_buffers)
        .clamp(1, windows.len());
    let passes = windows.len().div_ceil(per_pass);
    let still_off_screen = if passes > 1 {
        still_kernels
            .iter()
            .filter(|k| k.screen_bound(camera).is_none())
            .count()
    } else {
        0
    };
    let shortest = SHORTEST_SUBFRAME * (scene.shutter.close - scene.shutter.open);
    let grid = TileGrid::new(width, height);
    let mut sums = vec![Resolved::default(); pixel_count];
    for (pass, first) in (0..windows.len()).step_by(per_pass).enumerate() {
        let last = (first + per_pass).min(windows.len());
        let mut kernels = still_kernels.clone();
        for (object, object_plan, surfels) in plan.drawn() {
            if object_plan.motion != ObjectMotion::Still {
                for k in first..last {
                    let span = [times[k], times[k + 1]];
                    // A sub-frame too short to hold any of the exposure is where keyframes
                    // nearly coincide (a jump): a kernel across it would smear the jump.
                    if !(span[1] - span[0] > shortest) {
                        continue;
                    }
                    kernels.extend(kernels_over(
                        scene,
                        (object, surfels),
                        span,
                        windows[k],
                        &mut stats.culled,
                    ));
                }
            }
        }
        let mut culled = Culled::default();
        let (lists, bounds) = bin(scene, &grid, &kernels, &mut culled);
        // Still kernels are in every pass: count them, and those off screen, once.
        let (repeated, repeated_off_screen) = if pass == 0 {
            (0, 0)
        } else {
            (still_kernels.len(), still_off_screen)
        };
        stats.culled.off_screen += culled.off_screen - repeated_off_screen;
        kernel3d.kernels += (kernels.len() - repeated) - (culled.off_screen - repeated_off_screen);
        // §5.1's depth buffers, one per sub-frame end of the pass (shared by the sub-frames that
        // meet there).
        let visible_depth: Option<Vec<Vec<f32>>> =
            (visibility == Visibility::Approximate).then(|| {
                times[first..=last]
                    .iter()
                    .map(|&t| instant_layer(scene, plan, t, &mut Stats::default()).front_depth)
                    .collect()
            });
        // Each row of tiles adds its pixels into its own band of the sums as its tiles are
        // resolved: collected for the whole image first, the tiles' results held 32 bytes a
        // pixel more (docs/history.md, "Peak memory of `kernel3d` and `hint` on large images").
        let bands: Vec<&mut [Resolved]> = sums.chunks_mut(grid.band_len()).collect();
        let rows = lists.by_rows_costliest_first(&grid, bands, |ty, band| {
            let mut tiles = Vec::with_capacity(grid.row(ty).len());
            for tile in grid.row(ty) {
                let work = TileWork {
                    kernels: &kernels,
                    bounds: &bounds,
                    list: lists.list(tile),
                };
                let mut result = resolve_tile(
                    scene,
                    &work,
                    grid.pixels(tile),
                    (&windows[first..last], mass),
                    visible_depth.as_deref(),
                );
                for (at, resolved) in grid.in_band(tile).zip(&result.resolved) {
                    band[at].add(resolved);
                }
                // Its counts are kept for the pass's totals, its pixels are in the sums.
                result.resolved = Vec::new();
                tiles.push(result);
            }
            tiles
        });
        for tile in rows.into_iter().flatten() {
            kernel3d.fragments += tile.fragments;
            kernel3d.resolved_fragments += tile.resolved_fragments;
            kernel3d.peak_fragments_per_pixel =
                kernel3d.peak_fragments_per_pixel.max(tile.peak_pixel);
            kernel3d.peak_fragments_held = kernel3d.peak_fragments_held.max(tile.peak_held);
            kernel3d.merged_pixels += tile.merged;
            kernel3d.widened_pixels += tile.widened;
        }
        kernel3d.passes += 1;
        kernel3d.peak_kernels = kernel3d.peak_kernels.max(kernels.len());
    }
    let bg = scene.background.map(f64::from);
    let pixels = sums
        .iter()
        .map(|r| [0, 1, 2].map(|c| (r.colour[c] + r.background * bg[c]) as f32))
        .collect();
    stats.frames = 1;
    stats.footprints = kernel3d.kernels;
    stats.method = MethodStats::Kernel3d(kernel3d);
    let image = Framebuffer {
        width,
        height,
        pixels,
    };
    Render { image, stats }
}

/// Sub-frame boundaries over the exposure: equal sub-frames, or the union of the plan's
/// sub-segment ends of every moving object (one sub-frame when nothing moves) and, under a
/// shutter whose weight varies, of equal sub-frames each holding at most [`SHAPED_SUBFRAME_PX`] of
/// the fastest path (their count returned second), unless that is more than [`MAX_SUBFRAMES`],
/// when [`MAX_SUBFRAMES`] equal ones stand in and the plan's count is returned first.
fn subframe_times(
    scene: &Scene,
    plan: &Plan,
    subframes: Subframes,
) -> (Vec<f64>, Option<usize>, Option<usize>) {
    let (open, close) = (scene.shutter.open, scene.shutter.close);
    let equal = |n: usize| -> Vec<f64> {
        (0..=n)
            .map(|i| open + (close - open) * i as f64 / n as f64)
            .collect()
    };
    let mut shaped = None;
    let mut times = match subframes {
        Subframes::Equal(n) => equal(n),
        Subframes::Planned { .. } => {
            let mut times = vec![open, close];
            for object in &plan.objects {
                if let ObjectMotion::Moving { segments, .. } = &object.motion {
                    times.extend(segments.iter().map(|s| s[1]));
                }
            }
            let fastest = plan.longest_path_px();
            if scene.shutter.shape != ShutterShape::Box && fastest > SHAPED_SUBFRAME_PX {
                // An even count, so that a tent's peak at mid-exposure is a cut.
                let n = (fastest / SHAPED_SUBFRAME_PX / 2.0)
                    .ceil()
                    .min(MAX_SUBFRAMES as f64);
                let n = 2 * n as usize;
                times.extend(equal(n));
                shaped = Some(n);
            }
            times
        }
    };
    times.sort_by(f64::total_cmp);
    // Keyframes closer together than a sub-frame can hold stay apart: the sub-frame between them
    // is skipped, and its neighbours end and start at the poses either side of the jump.
    times.dedup();
    let planned = times.len() - 1;
    if planned > MAX_SUBFRAMES {
        return (equal(MAX_SUBFRAMES), Some(planned), shaped);
    }
    (times, None, shaped)
}

/// The kernels over [t0, t1], whose shutter-mass interval is `window`, of `surfels` moving with
/// `object` (its own, or merged by the level of detail).
fn kernels_over(
    scene: &Scene,
    (object, surfels): (&Object, &[Surfel]),
    [t0, t1]: [f64; 2],
    window: [f64; 2],
    culled: &mut Culled,
) -> Vec<Kernel> {
    let camera = &scene.camera;
    let mut kernels = Vec::new();
    let instants =
        [t0, 0.5 * (t0 + t1), t1].map(|t| Instant::new(camera, &object.motion.pose_at(t)));
    let [start, middle, end] = &instants;
    let results: Vec<Result<Kernel, Cull>> = surfels
        .par_iter()
        .map(|surfel| {
            let (p0, p1) = (
                start.view_point(surfel.position),
                end.view_point(surfel.position),
            );
            if !(-p0.z >= camera.near || -p1.z >= camera.near) {
                return Err(Cull::BehindNear);
            }
            // Facing cosines at the ends, positive towards the camera.
            let cosine =
                |instant: &Instant, p: DVec3| facing(p, instant.view_vector(surfel.normal));
            let (c0, c1) = (cosine(start, p0), cosine(end, p1));
            let density = surfel.area / surfel.axis_u.cross(surfel.axis_v).length();
            let kernel = |[p0, p1]: [DVec3; 2], middle: &Instant, window: [f64; 2]| {
                let axes = [surfel.axis_u, surfel.axis_v].map(|a| middle.view_vector(a));
                let colour = scene.lighting.shade(
                    surfel.colour,
                    middle.world_normal(surfel.normal),
                    middle.world_point(surfel.position),
                );
                Kernel::new(camera, p0, p1, axes, density, colour, window)
                    .ok_or(Cull::Raster(Rejection::Degenerate))
            };
            match (c0 > 0.0, c1 > 0.0) {
                (true, true) => kernel([p0, p1], middle, window),
                // Culled when it faces away at both ends, as blur does (and Heinzle §5.2).
                (false, false) => Err(Cull::BackFacing),
                // Turning edge-on within the sub-frame (its cosine taken as linear in time): the
                // kernel spans the part that faces the camera, as blur's ellipse does. Spanning
                // the whole sub-frame, its splat axes were those of the middle, where it may be
                // seen exactly edge-on, with no area at all.
                (first_half, _) => {
                    let turn = t0 + (t1 - t0) * c0 / (c0 - c1);
                    let turn_mass = window[0] + scene.shutter.mass(t0, turn);
                    let (span, window) = if first_half {
                        ([t0, turn], [window[0], turn_mass])
                    } else {
                        ([turn, t1], [turn_mass, window[1]])
                    };
                    if !(span[1] > span[0] && window[1] > window[0]) {
                        return Err(Cull::BackFacing);
                    }
                    let at = |t: f64| Instant::new(camera, &object.motion.pose_at(t));
                    let ends = span.map(|t| at(t).view_point(surfel.position));
                    kernel(ends, &at(0.5 * (span[0] + span[1])), window)
                }
            }
        })
        .collect();
    for result in results {
        culled.keep(result, &mut kernels);
    }
    kernels
}

/// Per tile, the kernels whose screen bound (the hull of their end ellipses' boxes) reaches it,
/// in kernel order; and each kernel's pixel bounds (empty when off-screen).
fn bin(
    scene: &Scene,
    grid: &TileGrid,
    kernels: &[Kernel],
    culled: &mut Culled,
) -> (TileLists, Vec<[u32; 4]>) {
    let camera = &scene.camera;
    let per_kernel: Vec<Option<([u32; 4], Vec<usize>)>> = kernels
        .par_iter()
        .map(|k| {
            let (bounds, hull) = k.screen_bound(camera)?;
            let [x0, y0, x1, y1] = bounds;
            let mut tiles = Vec::new();
            for ty in y0 / TILE_PX..=(y1 - 1) / TILE_PX {
                for tx in x0 / TILE_PX..=(x1 - 1) / TILE_PX {
                    let rect = [tx, ty, tx + 1, ty + 1].map(|v| f64::from(v * TILE_PX));
                    if hull_overlaps(&hull, rect) {
                        tiles.push(grid.index(tx, ty));
                    }
                }
            }
            Some((bounds, tiles))
        })
        .collect();
    let mut all_bounds = Vec::with_capacity(kernels.len());
    for entry in &per_kernel {
        match entry {
            Some((bounds, _)) => all_bounds.push(*bounds),
            None => {
                culled.off_screen += 1;
                all_bounds.push([0; 4]);
            }
        }
    }
    let lists = TileLists::new(grid, kernels.len(), |index, visit| {
        if let Some((_, tiles)) = &per_kernel[index as usize] {
            tiles.iter().for_each(|&tile| visit(tile));
        }
    });
    (lists, all_bounds)
}

/// The kernels, their pixel bounds, and the ones reaching one tile.
struct TileWork<'a> {
    kernels: &'a [Kernel],
    bounds: &'a [[u32; 4]],
    list: &'a [u32],
}

/// The fragments of the tile over pixels [x0, x1) × [y0, y1) resolved per pixel, the number of
/// fragments in the tile, the most on one pixel, and the most held at once. `windows` are the
/// pass's sub-frames, of an exposure `exposure` long: pieces are cut as finely whatever part of it
/// the pass holds.
///
/// Fragments are made and resolved one row of the tile at a time, and within a row one time bin
/// of sub-frames at a time ([`SubFrameBins`]): a moving kernel's fragments lie within its sub-frame,
/// so each bin's resolve is exact over its own part of the exposure and the parts add up, as the
/// passes do. Kernels spanning the pass (still objects') leave fragments that are made once per
/// row and clipped to each bin. A worker holds at most one row's: [`TILE_PX`] pixels of at most
/// [`MAX_FRAGMENTS_PER_PIXEL`] each of the bin and as many of the still kernels (a list that
/// reaches it has its fragments merged by surface, [`compact`]).
fn resolve_tile(
    scene: &Scene,
    work: &TileWork,
    [x0, y0, x1, y1]: [u32; 4],
    (windows, exposure): (&[[f64; 2]], f64),
    visible_depth: Option<&[Vec<f32>]>,
) -> TileResult {
    let camera = &scene.camera;
    let w = (x1 - x0) as usize;
    // A pixel's ray and its length, worked out once a row for all the kernels that reach it.
    let ray = |x: u32, y: u32| {
        let ray = camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
        (ray, ray.length())
    };
    let bins = SubFrameBins::new(windows);
    // The tile's kernels by the bin holding them (those spanning the pass last), in kernel order
    // within each.
    let bin_of: Vec<usize> = (work.list.iter())
        .map(|&index| bins.of(work.kernels[index as usize].mass))
        .collect();
    let mut order: Vec<usize> = (0..work.list.len()).collect();
    order.sort_by_key(|&j| bin_of[j]);
    let prepared: Vec<_> = order
        .into_iter()
        .map(|j| {
            let index = work.list[j];
            (
                bin_of[j],
                work.kernels[index as usize].prepare(index),
                work.bounds[index as usize],
            )
        })
        .collect();
    let group = |bin: usize| {
        let start = prepared.partition_point(|p| p.0 < bin);
        let end = prepared.partition_point(|p| p.0 <= bin);
        &prepared[start..end]
    };
    let each_bin: Vec<SubFrameBins> = (0..bins.len())
        .map(|b| SubFrameBins::new(&[bins.span(b)]))
        .collect();
    let pass = SubFrameBins::new(&[[bins.span(0)[0], bins.span(bins.len() - 1)[1]]]);
    let mut out = TileResult {
        resolved: Vec::with_capacity(w * (y1 - y0) as usize),
        ..TileResult::default()
    };
    // Per pixel of a row: the fragments of still kernels and of the bin being resolved, each
    // with how it was merged if it reached the cap; and the pixel's sum.
    let mut still: Vec<(Vec<Fragment>, Option<Compaction>)> = vec![(Vec::new(), None); w];
    let mut pixels = still.clone();
    let mut sums = vec![Resolved::default(); w];
    // Fragments of `kernels` on row y added to `lists`, each compacted within `bins` when full.
    let make = |kernels: &[(usize, Prepared, [u32; 4])],
                rays: &[(DVec3, f64)],
                y: u32,
                lists: &mut [(Vec<Fragment>, Option<Compaction>)],
                bins: &SubFrameBins,
                out: &mut TileResult| {
        for (_, kernel, [bx0, by0, bx1, by1]) in kernels {
            if !(*by0..*by1).contains(&y) {
                continue;
            }
            for x in x0.max(*bx0)..x1.min(*bx1) {
                let pixel = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                let Some(f) = kernel.fragment(rays[(x - x0) as usize], pixel, camera.near) else {
                    continue;
                };
                out.fragments += 1;
                push_capped(&mut lists[(x - x0) as usize], f, bins, out);
            }
        }
    };
    let mut rays = Vec::with_capacity(w);
    for y in y0..y1 {
        rays.clear();
        rays.extend((x0..x1).map(|x| ray(x, y)));
        make(group(bins.len()), &rays, y, &mut still, &pass, &mut out);
        for (b, bin) in each_bin.iter().enumerate() {
            make(group(b), &rays, y, &mut pixels, bin, &mut out);
            let span = bins.span(b);
            for (pixel, (still, _)) in pixels.iter_mut().zip(&still) {
                for f in still.iter().filter_map(|f| f.clipped(span)) {
                    push_capped(pixel, f, bin, &mut out);
                }
            }
            let held: usize = (pixels.iter().chain(&still))
                .map(|(list, _)| list.len())
                .sum();
            out.peak_held = out.peak_held.max(held);
            for (i, (list, _)) in pixels.iter_mut().enumerate() {
                out.resolved_fragments += list.len();
                out.peak_pixel = out.peak_pixel.max(list.len());
                match visible_depth {
                    None => sums[i].add(&resolve_exact(list, span, exposure)),
                    Some(depths) => {
                        let p = y as usize * camera.width as usize + x0 as usize + i;
                        // §5.5: the passes run per sub-frame and add up, weighted by the shutter.
                        for k in bins.windows(b) {
                            let ends = [depths[k][p], depths[k + 1][p]];
                            sums[i].add(&resolve_approximate(list, windows[k], ends));
                        }
                    }
                }
                list.clear();
            }
        }
        for ((sum, (_, merged)), (still, still_merged)) in
            sums.iter_mut().zip(&mut pixels).zip(&mut still)
        {
            let merged = merged.take().max(still_merged.take());
            out.merged += usize::from(merged.is_some());
            out.widened += usize::from(merged == Some(Compaction::Widened));
            out.resolved.push(std::mem::take(sum));
            still.clear();
        }
    }
    out
}

/// Add `f` to a pixel's list, merging the list's fragments within `bins` ([`compact`]) when it
/// reaches [`MAX_FRAGMENTS_PER_PIXEL`].
fn push_capped(
    (list, merged): &mut (Vec<Fragment>, Option<Compaction>),
    f: Fragment,
    bins: &SubFrameBins,
    out: &mut TileResult,
) {
    list.push(f);
    if list.len() == MAX_FRAGMENTS_PER_PIXEL {
        out.peak_pixel = MAX_FRAGMENTS_PER_PIXEL;
        *merged = (*merged).max(Some(compact(list, bins)));
    }
}

/// One tile resolved, and what it took.
#[derive(Default)]
struct TileResult {
    /// The tile's pixels, row by row.
    resolved: Vec<Resolved>,
    /// Fragments made, and resolved (after merging).
    fragments: usize,
    resolved_fragments: usize,
    /// The most fragments on one pixel.
    peak_pixel: usize,
    /// The most fragments held at once (one row's).
    peak_held: usize,
    /// Pixels whose fragments were merged, and of those, with the depth tolerance widened.
    merged: usize,
    widened: usize,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Camera, Keyframe, Motion, Pose};
    use crate::surfels::from_mesh;
    use crate::surfels::mesh::tests::square;
    use crate::Method;

    #[test]
    fn sub_frames_capped_are_a_note_and_added_ones_are_not() {
        let shaped = KernelStats {
            shaped_subframes: Some(12),
            ..KernelStats::default()
        };
        assert!(shaped.departures().is_empty());
        let capped = KernelStats {
            planned_subframes: Some(2467),
            ..shaped
        };
        assert_eq!(
            capped.departures(),
            vec![format!(
                "the plan's 2467 sub-frames capped at {MAX_SUBFRAMES} equal ones"
            )]
        );
    }

    /// Squares at several depths sliding across each other, densely sampled, so that a pixel
    /// holds more fragment ends within a sub-frame than its share of the pieces.
    fn overlapping_squares() -> Scene {
        let camera = Camera::new(
            DVec3::new(0.0, 0.0, 10.0),
            DVec3::ZERO,
            DVec3::Y,
            20.0,
            24,
            24,
        )
        .unwrap();
        (0..4).fold(Scene::new(camera), |scene, i| {
            let (z, shift) = (0.3 * f64::from(i), if i % 2 == 0 { 1.0 } else { -1.0 });
            let mut surfels = from_mesh(&square(2.0), 3000, false).unwrap();
            let c = i as f32;
            for s in &mut surfels {
                s.colour = [0.2 * c + 0.2, 0.5, 1.0 - 0.2 * c];
            }
            let key = |t: f64, x: f64| Keyframe {
                t,
                pose: Pose {
                    translation: DVec3::new(x - 1.0, -1.0, z),
                    ..Pose::IDENTITY
                },
            };
            let motion = Motion::new(vec![key(0.0, -shift), key(1.0, shift)]).unwrap();
            scene.with_object(Object::new(format!("square {i}"), surfels, motion))
        })
    }

    #[test]
    fn a_render_in_passes_cuts_its_pixels_as_one_pass_does() {
        // Eight sub-frames, each its own time bin in one pass as in four: the passes' bins resolve
        // the same fragments over the same spans, so the images agree to the bit only if each
        // pass cuts its pieces at the whole exposure's shortest, not at its own share's.
        let scene = overlapping_squares();
        let method = Method::Kernel3d {
            subframes: Subframes::Equal(8),
            visibility: Visibility::Exact,
        };
        let plan = Plan::new(&scene, &method).unwrap();
        let moving: usize = plan.drawn().map(|(_, _, surfels)| surfels.len()).sum();
        let draw = |kernels_per_pass| {
            let render = render_in_passes(
                &scene,
                &plan,
                Subframes::Equal(8),
                Visibility::Exact,
                kernels_per_pass,
            );
            (render.image, render.stats.kernel3d().unwrap().passes)
        };
        let (whole, one) = draw(MAX_KERNELS_PER_PASS);
        let (parts, four) = draw(2 * moving);
        assert_eq!((one, four), (1, 4));
        let differing = (whole.pixels.iter().zip(&parts.pixels))
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(differing, 0, "of {} pixels", whole.pixels.len());
    }
}
