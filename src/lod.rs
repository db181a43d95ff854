//! Level of detail: surfels merged where the image cannot tell them apart, chosen by the plan for
//! each render (docs/math.md, "Level of detail").
//!
//! A blurred image keeps no detail along the motion finer than a fraction of the streak, and no
//! image keeps detail finer than a pixel or than the surfels' own Gaussians. So, for each object,
//! the surfels' screen positions at the middle of the exposure are cut into cells: a share
//! [`ALONG_FRACTION`] of the surfel's screen path long along the motion, and across it the wider
//! of [`CELL_PX`] and [`ACROSS_SIGMAS`] standard deviations of the object's median surfel
//! (square cells of [`CELL_PX`] for an instant). Surfels of one cell that also share a normal
//! bucket and a depth layer are one patch of one surface; each such group becomes one surfel with
//! the group's projected area |Σ aᵢ nᵢ|, its area-weighted mean position, normal and colour, and
//! the moment-matched Gaussian (the group's second moments about the mean, in the plane of the
//! mean normal). Across the motion a cell never reaches beyond what the surfels' own
//! reconstruction already blurs, and surfaces at different depths or facing different ways never
//! merge. Merging is done in object space, so every renderer draws the merged surfels as it draws
//! any others.
//!
//! The grid is rotated to one of `DIRECTION_BUCKETS` directions nearest each surfel's screen
//! motion, and its length quantized to quarter octaves of the path, so that neighbours moving
//! alike fall into the same cells. Surfels the render never draws, facing away at every instant
//! it culls at, are left out first (docs/math.md, "Only what is drawn").

use crate::math::{floor_to_i64, round_to_i64, Sym2};
use crate::project::{faces_camera, Instant, DEPTH_TOLERANCE_SIGMAS};
use crate::scene::camera::Camera;
use crate::scene::Object;
use crate::surfels::Surfel;
use glam::{DMat3, DVec2, DVec3};
use rayon::prelude::*;
use std::sync::Arc;

/// What the label of a render drawn at [`Lod::Off`] ends in, where the same method is also drawn
/// with its level of detail (the gallery's captions, the study's series).
pub const FULL_DETAIL_LABEL: &str = " full detail";

/// Whether the plan may merge surfels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Lod {
    /// Full detail: every surfel is drawn.
    Off,
    /// Merge where the image cannot show the difference: cells [`ALONG_FRACTION`] of the path
    /// long, [`ALONG_FRACTION_KERNELS`] for `kernel3d`.
    #[default]
    Auto,
    /// Merge with cells this share of the screen path long (for measuring the rule).
    Along(f64),
}

impl Lod {
    /// The level of detail of a reference that other renders' errors are measured against (the
    /// gallery's, the study's converged one): none, so that what the level of detail leaves out
    /// counts as error.
    pub const GROUND_TRUTH: Lod = Lod::Off;

    /// The cells an object drawn blurred is merged in, if any, for `kernel3d` (`kernels`) or
    /// another method.
    #[must_use]
    pub fn blurred_cells(self, kernels: bool) -> Option<Cells> {
        match self {
            Lod::Off => None,
            Lod::Auto if kernels => Some(Cells::AlongMotion(ALONG_FRACTION_KERNELS)),
            Lod::Auto => Some(Cells::AlongMotion(ALONG_FRACTION)),
            Lod::Along(f) => Some(Cells::AlongMotion(f)),
        }
    }
}

/// The shape of the cells surfels are merged in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cells {
    /// [`CELL_PX`] squares: what an instant cannot resolve (`static`, each reference frame, still
    /// objects).
    Square,
    /// [`CELL_PX`] across the motion and this share of each surfel's screen path along it.
    AlongMotion(f64),
}

/// Share of a surfel's screen path that its cell may span along the motion in `blur` and a hint's
/// trail (from the sweeps in docs/math.md, "Level of detail": on the torus knot, with exact
/// streaks and depth layers of the surfels' own depth, RMSE against the converged reference
/// +2.6 % and ꟻLIP against full detail 0.0046).
pub const ALONG_FRACTION: f64 = 0.2;

/// The share that suits `kernel3d`, whose error is several times lower than `blur`'s, so that the
/// same merging shows. At 8 sub-frames, RMSE against the converged reference over full detail's:
/// 0.05 took the knot +6 % and `approaching` +18 %, but the armadillo and the bunnies of
/// `crossing_depth`, which turn, +90 % and +82 %; 0.03 keeps them to +1 %, +5 %, 0 % (nothing
/// merges) and +20 %, and still draws the knot 2.3× and `approaching` 3.3× faster (docs/math.md,
/// "Level of detail").
pub const ALONG_FRACTION_KERNELS: f64 = 0.03;

/// Least cell width across the motion, and the side of a cell for an instant, px.
pub const CELL_PX: f64 = 1.0;

/// Cell width across the motion in standard deviations of the object's median surfel on screen,
/// where that is wider than [`CELL_PX`] (and never wider than the cell is long). Members spread
/// across a width w add at most w²/12 to the merged Gaussian's variance there, a third of a
/// surfel's own at 2σ. From the sweep in docs/math.md, "Level of detail": at 2σ objects whose
/// surfels are 1.4–4.5 px wide merge and `blur` on the gallery scenes takes 1.1–3.9× less time;
/// RMSE against the converged reference rises by up to 21 % (`engine_rotating`, 2× faster), by
/// up to 1.9 % at half size; at 3σ the bunny's rose 15 % more.
pub const ACROSS_SIGMAS: f64 = 2.0;

/// Longest cell along the motion, px: a merged surfel is a flat ellipse, and a long one would
/// stand for a patch that is no longer flat.
pub const MAX_CELL_PX: f64 = 32.0;

/// Screen directions of motion the grid is aligned to.
const DIRECTION_BUCKETS: f64 = 16.0;

/// Buckets per octave of screen path length.
const LENGTH_BUCKETS_PER_OCTAVE: f64 = 4.0;

/// Normal buckets per cube-face axis: normals within about 30° may merge.
const NORMAL_BUCKETS: f64 = 3.0;

/// Surfels are merged in square cells only when the median one is smaller than this share of
/// the cell's side (so that a cell gathers about four): the pass that finds the cells costs
/// about as much as projecting the surfels, and on the torus knot at 512² (surfels 0.95 px)
/// merging two into one made `static` 2.2× slower.
const MERGE_SHARE: f64 = 0.5;

/// The same share for cells along the motion, of the geometric mean of their length and width
/// (so that a cell gathers about two): a blurred surfel is drawn as a streak its path long, which
/// costs far more than the pass, so halving their number pays. The Stanford bunny turning at
/// 512², surfels 1.45 px, full detail against merged (docs/math.md, "Level of detail"): with
/// cells 7.6 px long (this share lets them merge, the square cells' does not) `blur` took 0.17 s
/// against 0.32 s, for RMSE +19 %.
const MERGE_SHARE_ALONG: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Largest cell index along, across and in depth kept apart (beyond it, say for a surfel grazing
/// the camera plane, cells join): under 2⁵³, so that [`PackedKey`] holds it in 54 bits.
const CELL_INDEX_CAP: f64 = 9e15;

/// Surfels sampled to decide whether an object has anything to merge.
const SIZE_PROBES: usize = 256;

/// Most instants a surfel's screen path is measured at.
pub const MAX_PATH_SAMPLES: usize = 9;

/// What the level of detail did to one object.
#[derive(Clone, Debug, PartialEq)]
pub enum LodOutcome {
    /// `--lod off`.
    Off,
    /// Drawn sharp at full detail (a hint's object layer).
    Sharp,
    /// A sparse trail: each surfel is a stroke of its own.
    Strokes,
    /// Left at full detail: its surfels cover at least a cell each.
    Kept {
        /// Median screen size of its surfels (the square root of their screen area), px.
        surfel_px: f64,
    },
    /// Merged.
    Merged {
        /// Surfels before.
        surfels_in: usize,
        /// Of them, facing away wherever the render culls, left out before merging.
        back_facing: usize,
        /// Surfels after.
        surfels_out: usize,
        /// Whether cells followed the motion (or were square, for an instant).
        along_motion: bool,
        /// Longest cell along the motion, px.
        longest_cell_px: f64,
        /// Widest cell across the motion, px.
        widest_cell_px: f64,
    },
}

impl LodOutcome {
    /// One line for `--explain`.
    #[must_use]
    pub fn explain(&self) -> String {
        match self {
            LodOutcome::Off => "level of detail off: full detail".to_string(),
            LodOutcome::Sharp => "full detail: drawn sharp".to_string(),
            LodOutcome::Strokes => {
                "full detail: a sparse trail draws each surfel as a stroke".to_string()
            }
            LodOutcome::Kept { surfel_px } => {
                format!("full detail: its surfels are {surfel_px:.2} px across, too large to merge")
            }
            LodOutcome::Merged {
                surfels_in,
                back_facing,
                surfels_out,
                along_motion,
                longest_cell_px,
                widest_cell_px,
            } => {
                let cells = if *along_motion {
                    format!("cells up to {widest_cell_px:.1} px across the motion and {longest_cell_px:.1} px along it")
                } else {
                    format!("{CELL_PX} px cells (sub-pixel surfels)")
                };
                let left_out = if *back_facing > 0 {
                    format!(
                        "; {back_facing} facing away at every instant drawn were left out first"
                    )
                } else {
                    String::new()
                };
                format!(
                    "level of detail: {surfels_in} surfels merged into {surfels_out} ({:.1}×) in {cells}{left_out}",
                    *surfels_in as f64 / (*surfels_out).max(1) as f64
                )
            }
        }
    }
}

/// An object's surfels as one render draws them.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectLod {
    /// The merged surfels (or those resampled from a simplified mesh, shared with the plan's
    /// cache), or `None` for the object's own.
    pub merged: Option<Arc<Vec<Surfel>>>,
    /// What was done, for `--explain`.
    pub outcome: LodOutcome,
}

impl ObjectLod {
    /// Full detail, by request.
    pub const OFF: ObjectLod = ObjectLod {
        merged: None,
        outcome: LodOutcome::Off,
    };
}

/// Merge `surfels` (of `object`: its own, or resampled from its simplified mesh) for a render that
/// sees it at the instants `times` (increasing; the middle one is where cells are laid out), in
/// `cells`: along the motion they follow each surfel's screen path through the instants. A render
/// that culls back faces at the instants `culled_at` alone (empty: not known) never draws a
/// surfel facing away at all of them, which is left out.
#[must_use]
pub fn merge(
    camera: &Camera,
    object: &Object,
    surfels: &[Surfel],
    times: &[f64],
    cells: Cells,
    culled_at: &[f64],
) -> ObjectLod {
    let instant_at = |&t: &f64| Instant::new(camera, &object.motion.pose_at(t));
    let instants: Vec<Instant> = times.iter().map(instant_at).collect();
    let culling: Vec<Instant> = culled_at.iter().map(instant_at).collect();
    let middle = instants.len() / 2;
    // Cells are laid out at the middle instant but must hold at the nearest: shrink them by the
    // object's largest growth on screen over the instants.
    let depth_of_origin = |instant: &Instant| -instant.view_point(DVec3::ZERO).z;
    let middle_depth = depth_of_origin(&instants[middle]);
    let nearest = instants
        .iter()
        .map(depth_of_origin)
        .fold(f64::INFINITY, f64::min);
    let shrink = if nearest > 0.0 && middle_depth > 0.0 {
        (nearest / middle_depth).min(1.0)
    } else {
        1.0
    };
    let cell = CELL_PX * shrink;

    // The depth layer: the ternary depth test's tolerance for a typical surfel, doubled.
    let layer = 2.0 * DEPTH_TOLERANCE_SIGMAS * median_sigma(&instants[middle], surfels);
    let probes = probe_sizes(camera, &instants, middle, surfels);
    let grid = Grid {
        camera,
        instants: &instants,
        middle,
        cell,
        across: probes.map_or(cell, |p| cell.max(ACROSS_SIGMAS * p.sigma_px * shrink)),
        longest: MAX_CELL_PX * shrink,
        layer,
        along_fraction: match cells {
            Cells::AlongMotion(share) => Some(share),
            Cells::Square => None,
        },
        axes: std::array::from_fn(|bucket| {
            DVec2::from_angle(bucket as f64 / DIRECTION_BUCKETS * std::f64::consts::TAU)
        }),
    };
    // A merge must gather several surfels to pay for the pass that finds it.
    match probes {
        Some(probes) if grid.worth_merging(&probes) => {}
        probes => {
            return ObjectLod {
                merged: None,
                outcome: LodOutcome::Kept {
                    surfel_px: probes.map_or(f64::INFINITY, |p| p.surfel_px),
                },
            }
        }
    }

    // A surfel facing away at every instant the renderer culls at is never drawn: merging it
    // would cost its share of the pass, and could only pull a group's normal away from what
    // full detail shows.
    let drawn = |s: &Surfel| culling.is_empty() || culling.iter().any(|i| faces_camera(i, s));
    // Sorted by key and then index, the key packed: cells, and surfels within each, come in
    // the order of (CellKey, index). The length bucket rides along for the summary.
    let mut keyed: Vec<Keyed> = surfels
        .par_iter()
        .enumerate()
        .filter(|(_, s)| drawn(s))
        .map(|(i, s)| {
            let key = grid.key(s);
            (PackedKey::of(&key), i as u32, key.fields().map(|f| f.1))
        })
        .collect();
    let back_facing = surfels.len() - keyed.len();
    keyed.par_sort_unstable_by_key(|&(key, i, _)| (key, i));
    // Runs of about RUN_ITEMS sorted items, cut between groups, merge in parallel; joined in
    // order they give what one pass would, whatever the thread count.
    let mut cuts = vec![0];
    while let Some(&last) = cuts.last().filter(|&&c| c < keyed.len()) {
        cuts.push(group_end(&keyed, (last + RUN_ITEMS).min(keyed.len()) - 1));
    }
    let runs: Vec<(Vec<Surfel>, f64, f64)> = cuts
        .par_windows(2)
        .map(|run| merge_run(&keyed[run[0]..run[1]], surfels, &grid))
        .collect();
    let mut merged = Vec::with_capacity(runs.iter().map(|r| r.0.len()).sum());
    let (mut longest_cell_px, mut widest_cell_px) = (0.0f64, 0.0f64);
    for (run, longest, widest) in runs {
        merged.extend(run);
        longest_cell_px = longest_cell_px.max(longest);
        widest_cell_px = widest_cell_px.max(widest);
    }
    ObjectLod {
        outcome: LodOutcome::Merged {
            surfels_in: surfels.len(),
            back_facing,
            surfels_out: merged.len(),
            along_motion: grid.along_fraction.is_some(),
            longest_cell_px,
            widest_cell_px,
        },
        merged: Some(Arc::new(merged)),
    }
}

/// Sorted items per run of the merge, at least: enough that a run's start-up is nothing beside
/// its merges.
const RUN_ITEMS: usize = 1 << 14;

/// A cell-key-sorted item with its surfel's index and length bucket.
type Keyed = (PackedKey, u32, Option<i16>);

/// The end of the group holding item `i` of `keyed`: a group holds a few surfels, so a scan reads
/// only them, where a binary search over the rest of the list missed the cache at every step.
fn group_end(keyed: &[Keyed], i: usize) -> usize {
    let key = keyed[i].0;
    keyed[i..]
        .iter()
        .position(|&(k, ..)| k != key)
        .map_or(keyed.len(), |n| i + n)
}

/// Merge each group of the sorted items `keyed` (whole groups only) of `surfels`; with the
/// longest and widest cell that merged more than one surfel, px.
fn merge_run(keyed: &[Keyed], surfels: &[Surfel], grid: &Grid) -> (Vec<Surfel>, f64, f64) {
    let mut merged = Vec::new();
    let (mut longest_cell_px, mut widest_cell_px) = (0.0f64, 0.0f64);
    let mut start = 0;
    while start < keyed.len() {
        let end = group_end(keyed, start);
        let group = keyed[start..end]
            .iter()
            .map(|&(_, i, _)| &surfels[i as usize]);
        match keyed[start].2 {
            None => merged.extend(group.copied()),
            Some(length) => {
                if end - start > 1 {
                    let length_px = grid.cell_length(grid.bucket_path(length));
                    longest_cell_px = longest_cell_px.max(length_px);
                    widest_cell_px = widest_cell_px.max(grid.across_of(length_px));
                }
                merge_group(group, end - start, &mut merged);
            }
        }
        start = end;
    }
    (merged, longest_cell_px, widest_cell_px)
}

/// Which group a surfel belongs to. `Alone` surfels (behind the near plane at some instant, or
/// with non-finite numbers) are kept as they are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CellKey {
    Cell {
        /// Direction bucket of the screen motion ([`DIRECTION_BUCKETS`] for none).
        direction: u8,
        /// Length bucket of the screen path.
        length: i16,
        /// Cell along and across the (rotated) grid.
        along: i64,
        across: i64,
        /// Depth layer of the surfel (its own depth).
        layer: i64,
        /// Normal bucket.
        normal: u8,
    },
    Alone,
}

impl CellKey {
    /// A cell's fields in the order keys sort by: direction, length, along, across, layer and
    /// normal; `None` for `Alone`.
    fn fields(&self) -> Option<(u8, i16, i64, i64, i64, u8)> {
        match *self {
            CellKey::Cell {
                direction,
                length,
                along,
                across,
                layer,
                normal,
            } => Some((direction, length, along, across, layer, normal)),
            CellKey::Alone => None,
        }
    }
}

/// A [`CellKey`] as one 192-bit number, most significant word first and, within it, field
/// first (from the top: two bits for `Alone`, then direction 5, length 15, along, across and
/// layer 54 each, offset to be non-negative, normal 8), so that keys compare as three integers
/// and sort as 32-byte items with their index. Sorting the keys as an enum, field by field, in
/// 48-byte items took a sixth of `blur`'s time on the torus knot at 160 × 120.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct PackedKey([u64; 3]);

impl PackedKey {
    /// Cell indices are capped to ±[`CELL_INDEX_CAP`]: offset by 2⁵³ they fit 54 bits.
    const OFFSET: i64 = 1 << 53;

    fn of(key: &CellKey) -> PackedKey {
        let Some((direction, length, along, across, layer, normal)) = key.fields() else {
            return PackedKey([1 << 62, 0, 0]);
        };
        let mut packed = PackedKey([0; 3]);
        packed.push(u64::from(direction), 5);
        packed.push(length as u64, 15);
        for index in [along, across, layer] {
            packed.push((index + Self::OFFSET) as u64, 54);
        }
        packed.push(u64::from(normal), 8);
        packed
    }

    /// Shift in `value`'s low `bits` (1 to 63) below what is there.
    fn push(&mut self, value: u64, bits: u32) {
        let [high, middle, low] = self.0;
        self.0 = [
            high << bits | middle >> (64 - bits),
            middle << bits | low >> (64 - bits),
            low << bits | value & ((1 << bits) - 1),
        ];
    }
}

/// The cells of one object for one render.
struct Grid<'a> {
    camera: &'a Camera,
    instants: &'a [Instant],
    middle: usize,
    /// Side of a square cell, and the least width of a cell across the motion, px.
    cell: f64,
    /// Width across the motion of a cell that follows it, at least `cell`, px.
    across: f64,
    /// Longest cell along the motion, px.
    longest: f64,
    /// Depth layer thickness, scene units.
    layer: f64,
    /// Share of the path a cell spans along the motion, or `None` for square cells.
    along_fraction: Option<f64>,
    /// The unit axis of each direction bucket (a sine and cosine per surfel took 3 % of `blur`
    /// on the knot at 160 × 120).
    axes: [DVec2; DIRECTION_BUCKETS as usize],
}

impl Grid<'_> {
    /// The shortest screen path of length bucket `length`, px.
    fn bucket_path(&self, length: i16) -> f64 {
        self.cell * (f64::from(length) / LENGTH_BUCKETS_PER_OCTAVE).exp2()
    }

    /// Length along the motion of the cell of a surfel whose screen path is `path_px` long. Below
    /// two cells of motion a cell is square, as for an instant, so a barely moving object is
    /// merged exactly as a still one.
    fn cell_length(&self, path_px: f64) -> f64 {
        match self.along_fraction {
            Some(share) if path_px >= 2.0 * self.cell => {
                (share * path_px).clamp(self.cell, self.longest)
            }
            _ => self.cell,
        }
    }

    /// Whether cells gather enough of the surfels that `probes` describe to pay for the pass
    /// that finds them ([`MERGE_SHARE`], [`MERGE_SHARE_ALONG`] for cells longer than wide).
    fn worth_merging(&self, probes: &Probes) -> bool {
        let length = self.cell_length(probes.path_px);
        let share = if length > self.cell {
            MERGE_SHARE_ALONG
        } else {
            MERGE_SHARE
        };
        probes.surfel_px < share * (self.across_of(length) * length).sqrt()
    }

    /// Width across the motion of a cell `length_px` long (square cells are `cell` wide).
    fn across_of(&self, length_px: f64) -> f64 {
        if length_px > self.cell {
            self.across.min(length_px)
        } else {
            self.cell
        }
    }

    fn key(&self, surfel: &Surfel) -> CellKey {
        let alone = CellKey::Alone;
        // The screen path's length, and where the surfel is at the middle instant and at the
        // instants either side of it (the middle itself at an end).
        let (mut path, mut depth) = (0.0, f64::NAN);
        let (mut previous, mut p, mut before, mut after) =
            (None, DVec2::ZERO, DVec2::ZERO, DVec2::ZERO);
        let (just_before, just_after) = (
            self.middle.saturating_sub(1),
            (self.middle + 1).min(self.instants.len() - 1),
        );
        for (i, instant) in self.instants.iter().enumerate() {
            let Some((q, d)) = self
                .camera
                .project(instant.view_point(surfel.position))
                .filter(|(q, _)| q.is_finite())
            else {
                return alone;
            };
            if let Some(previous) = previous {
                path += q.distance(previous);
            }
            previous = Some(q);
            if i == just_before {
                before = q;
            }
            if i == self.middle {
                (p, depth) = (q, d);
            }
            if i == just_after {
                after = q;
            }
        }
        let (direction, length, frame, along_px) =
            if self.along_fraction.is_some() && path >= 2.0 * self.cell {
                let d = after - before;
                let turns = d.y.atan2(d.x) / std::f64::consts::TAU;
                // turns ∈ [−½, ½], so the bucket is 0 to 15.
                let bucket = round_to_i64(turns * DIRECTION_BUCKETS)
                    .rem_euclid(DIRECTION_BUCKETS as i64) as u8;
                let length = (path / self.cell).log2() * LENGTH_BUCKETS_PER_OCTAVE;
                let length = floor_to_i64(length).clamp(0, i64::from(i16::MAX)) as i16;
                (
                    bucket,
                    length,
                    self.axes[usize::from(bucket)],
                    self.cell_length(self.bucket_path(length)),
                )
            } else {
                (DIRECTION_BUCKETS as u8, 0, DVec2::X, self.cell)
            };
        let (u, v) = (p.dot(frame), p.perp_dot(frame));
        let (along, across) = (u / along_px, v / self.across_of(along_px));
        // The surfel's own depth, so that a layer of a cell is one run of a surface along it.
        // Its tangent plane's depth at the cell's centre, which a sloping plane's surfels share,
        // put both ends of a long cell on a ball in one layer (their planes pass alike in front
        // of the centre) and its middle in another: docs/math.md, "Level of detail".
        let layer = depth / self.layer;
        if !(along.is_finite() && across.is_finite() && layer.is_finite()) {
            return alone;
        }
        // ⌊x⌋ within the cap, whose ends are whole numbers.
        let cap = |x: f64| floor_to_i64(x.clamp(-CELL_INDEX_CAP, CELL_INDEX_CAP));
        CellKey::Cell {
            direction,
            length,
            along: cap(along),
            across: cap(across),
            layer: cap(layer),
            normal: normal_bucket(surfel.normal),
        }
    }
}

/// A bucket of unit normals: the cube face the normal points to and a cell of that face.
fn normal_bucket(n: DVec3) -> u8 {
    let a = n.abs();
    let (face, u, v, m) = if a.x >= a.y && a.x >= a.z {
        (u8::from(n.x < 0.0), n.y, n.z, a.x)
    } else if a.y >= a.z {
        (2 + u8::from(n.y < 0.0), n.x, n.z, a.y)
    } else {
        (4 + u8::from(n.z < 0.0), n.x, n.y, a.z)
    };
    if !(m > 0.0) {
        return 255;
    }
    let cell =
        |c: f64| ((c / m + 1.0) * 0.5 * NORMAL_BUCKETS).clamp(0.0, NORMAL_BUCKETS - 1.0) as u8;
    face * 16 + cell(u) * 4 + cell(v)
}

/// Typical screen sizes of an object's surfels, from a sample of them.
#[derive(Clone, Copy)]
struct Probes {
    /// Median screen size (√ of the screen area of a facing surfel) at the middle instant, px.
    surfel_px: f64,
    /// Median screen path through the instants, px.
    path_px: f64,
    /// Median standard deviation of a surfel's Gaussian on screen along its longer axis, px.
    sigma_px: f64,
}

/// The [`Probes`] of `surfels` seen at `instants`, or `None` when none is in front of the camera
/// at every instant.
fn probe_sizes(
    camera: &Camera,
    instants: &[Instant],
    middle: usize,
    surfels: &[Surfel],
) -> Option<Probes> {
    let step = (surfels.len() / SIZE_PROBES).max(1);
    let scale = instants[middle].view_vector(DVec3::X).length();
    let screen = |instant: &Instant, s: &Surfel| camera.project(instant.view_point(s.position));
    let probed: Vec<[f64; 3]> = surfels
        .iter()
        .step_by(step)
        .filter_map(|s| {
            let (_, depth) = screen(&instants[middle], s)?;
            let points: Option<Vec<DVec2>> = instants
                .iter()
                .map(|i| screen(i, s).map(|(p, _)| p))
                .collect();
            let path: f64 = points?.windows(2).map(|w| w[0].distance(w[1])).sum();
            let px_per_unit = scale * camera.focal_px / depth;
            Some([
                s.area.sqrt() * px_per_unit,
                path,
                longer_axis(s) * px_per_unit,
            ])
        })
        .collect();
    let median_of = |k: usize| median(probed.iter().map(|p| p[k]).collect());
    Some(Probes {
        surfel_px: median_of(0)?,
        path_px: median_of(1)?,
        sigma_px: median_of(2)?,
    })
}

/// The median of `values` (the upper one of an even count), `None` when there are none.
fn median(mut values: Vec<f64>) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
}

/// A surfel's standard deviation along its longer axis, scene units.
fn longer_axis(s: &Surfel) -> f64 {
    s.axis_u.length().max(s.axis_v.length())
}

/// Median standard deviation of the surfels' Gaussians in scene units.
fn median_sigma(instant: &Instant, surfels: &[Surfel]) -> f64 {
    let step = (surfels.len() / SIZE_PROBES).max(1);
    let scale = instant.view_vector(DVec3::X).length();
    median(
        surfels
            .iter()
            .step_by(step)
            .map(|s| longer_axis(s) * scale)
            .collect(),
    )
    .unwrap_or(0.0)
}

/// Append the merge of `group` (`count` surfels) to `out`: one surfel with the group's projected
/// area |Σ aᵢ nᵢ|, its area-weighted mean position, normal and colour, and the Gaussian whose
/// covariance in the plane of the mean normal is the group's (each member's own plus the spread of
/// the members' centres about the mean). A group whose normals cancel is kept as it is.
fn merge_group<'s>(
    group: impl Iterator<Item = &'s Surfel> + Clone,
    count: usize,
    out: &mut Vec<Surfel>,
) {
    if count == 1 {
        out.extend(group);
        return;
    }
    let area: f64 = group.clone().map(|s| s.area).sum();
    let mean = |f: &dyn Fn(&Surfel) -> DVec3| {
        group
            .clone()
            .fold(DVec3::ZERO, |sum, s| sum + f(s) * s.area)
            / area
    };
    let position = mean(&|s| s.position);
    let mean_normal = mean(&|s| s.normal);
    let normal = mean_normal.normalize_or_zero();
    let colour = mean(&|s| DVec3::from_array(s.colour.map(f64::from)));
    if !(area > 0.0 && normal != DVec3::ZERO && position.is_finite()) {
        out.extend(group);
        return;
    }
    let outer = |v: DVec3| DMat3::from_cols(v * v.x, v * v.y, v * v.z);
    let covariance = group.clone().fold(DMat3::ZERO, |sum, s| {
        let d = s.position - position;
        sum + (outer(s.axis_u) + outer(s.axis_v) + outer(d)) * s.area
    }) * (1.0 / area);
    let (t1, t2) = normal.any_orthonormal_pair();
    let in_plane = Sym2 {
        xx: t1.dot(covariance * t1),
        xy: t1.dot(covariance * t2),
        yy: t2.dot(covariance * t2),
    };
    let (values, vectors) = in_plane.eigen();
    let axis = |k: usize| (t1 * vectors[k].x + t2 * vectors[k].y) * values[k].max(0.0).sqrt();
    let (axis_u, axis_v) = (axis(0), axis(1));
    if !(axis_u.cross(axis_v).length() > 0.0) {
        out.extend(group);
        return;
    }
    out.push(Surfel {
        position,
        normal,
        axis_u,
        axis_v,
        // |Σ aᵢ nᵢ|: what the members project to from any side they all face, Σ aᵢ (nᵢ · ω) =
        // |Σ aᵢ nᵢ| (n̄ · ω); the sum of the areas would add light where the normals fan out.
        area: area * mean_normal.length(),
        colour: colour.to_array().map(|c| c as f32),
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The packed keys sort as the cells' fields in order, with `Alone` last, across the whole
    /// range of each field: a wrong shift or offset would reorder, or join, cells.
    #[test]
    fn packed_keys_order_as_the_fields() {
        let cap = CELL_INDEX_CAP as i64;
        let indices = [-cap, -cap + 1, -1, 0, 1, cap - 1, cap];
        let n = indices.len();
        let mut keys = vec![CellKey::Alone];
        for direction in [0, 7, DIRECTION_BUCKETS as u8] {
            for length in [0, 1, i16::MAX] {
                // Each index in each of the three places, beside others.
                for (i, j) in (0..n).flat_map(|i| (0..n).map(move |j| (i, j))) {
                    for normal in [0, 5, u8::MAX] {
                        keys.push(CellKey::Cell {
                            direction,
                            length,
                            along: indices[i],
                            across: indices[j],
                            layer: indices[(i + j) % n],
                            normal,
                        });
                    }
                }
            }
        }
        // `Alone` after every cell.
        let order = |key: &CellKey| (key.fields().is_none(), key.fields());
        for a in &keys {
            for b in &keys {
                assert_eq!(
                    PackedKey::of(a).cmp(&PackedKey::of(b)),
                    order(a).cmp(&order(b)),
                    "{a:?} against {b:?}"
                );
            }
        }
    }

    /// Two surfels whose normals fan out by ±18° merge into one that the camera sees with the
    /// weight of both together: with the sum of their areas instead of |Σ aᵢ nᵢ| it carries
    /// 1/cos 18° = 5 % more.
    #[test]
    fn a_merge_of_fanned_normals_keeps_the_projected_weight() {
        use crate::project::{tests::camera, view_surfel};
        use crate::scene::{Lighting, Pose};
        let camera = camera();
        let instant = Instant::new(&camera, &Pose::IDENTITY);
        let tilt = 18f64.to_radians();
        let members: Vec<Surfel> = [-tilt, tilt]
            .iter()
            .map(|&a| {
                Surfel::isotropic(
                    DVec3::new(0.01 * a.signum(), 0.0, 0.0),
                    DVec3::new(a.sin(), 0.0, a.cos()),
                    0.01,
                    None,
                    [1.0; 3],
                )
            })
            .collect();
        assert_eq!(
            normal_bucket(members[0].normal),
            normal_bucket(members[1].normal)
        );
        let mut merged = Vec::new();
        merge_group(members.iter(), 2, &mut merged);
        let weight = |s: &Surfel| {
            view_surfel(&camera, &instant, &Lighting::default(), s)
                .unwrap()
                .splat
                .weight
        };
        let sum: f64 = members.iter().map(weight).sum();
        let ratio = weight(&merged[0]) / sum;
        // The members sit 0.02 apart at 5 units: their perspective differs by well under 0.1 %.
        assert!((ratio - 1.0).abs() < 1e-3, "{ratio}");
    }
}
