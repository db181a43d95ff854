//! Per-pixel temporal visibility of fragments: the exact A-buffer (Heinzle et al. 2010, §4.4)
//! and the paper's GPU approximation (§5). A fragment is what one primitive leaves on one pixel
//! ray: an interval of time (as shutter mass, so that lengths are weights), a coverage over it,
//! a depth, a colour. `kernel3d`'s kernels make fragments of Gaussian coverage, and a pixel's
//! fragments of one surface merged under the cap are tabulated ([`Coverage`]). (Moving triangles
//! keep interval lists of their own: `render/triangles/intervals.rs`.)
//!
//! Exact: the fragments' ends cut the window into pieces; within each, fragments are grouped
//! into surfaces by the ternary depth test, nearest first, and each covers by its closed-form
//! coverage integral, hiding that share of what lies behind. Approximate: fragments in front of
//! the visible surface at either sub-frame end are blended with their whole integrals, and the
//! background shows only outside the earliest-to-latest covered time. Details and the
//! departures from the paper: docs/math.md, "A-buffer visibility".

use super::kernel3d::integral::Primitive;
use crate::raster::opacity;

/// What a primitive leaves on one pixel ray: the part of the exposure it covers the ray and how
/// much.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fragment {
    /// The covered interval on the shutter-mass axis.
    pub mass: [f64; 2],
    /// How much of the pixel it covers over that interval.
    pub coverage: Coverage,
    /// Depth along the ray at the interval's ends.
    pub depth: [f64; 2],
    /// Linear RGB.
    pub colour: [f32; 3],
    /// Depth distance within which another fragment counts as the same surface.
    pub tolerance: f64,
    /// The primitive's index: a total order for ties.
    pub id: u32,
}

/// A fragment's coverage of its pixel over time.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Coverage {
    /// A 3D kernel integrated along the ray (Heinzle §4.2).
    Kernel {
        /// The kernel's own interval on the shutter-mass axis (maps mass to kernel time s).
        kernel_mass: [f64; 2],
        /// Antiderivative of the kernel along the ray, in kernel time.
        primitive: Primitive,
        /// Coverage density at the splat centre × shutter mass per unit of kernel time.
        scale: f64,
    },
    /// Fragments of one surface merged by [`compact`]: coverage × mass over each of
    /// [`TABLE_PARTS`] equal parts of the fragment's interval, uniform within a part.
    Table {
        /// Coverage × mass per part, in time order.
        parts: [f32; TABLE_PARTS],
    },
}

impl Fragment {
    /// Coverage × shutter mass from a fixed start to `m` (within the fragment's interval), up to
    /// a constant: differences are the integral of the coverage over that part of its time.
    pub fn cumulative(&self, m: f64) -> f64 {
        match self.coverage {
            Coverage::Kernel {
                kernel_mass: [k0, k1],
                primitive,
                scale,
            } => scale * primitive.at(-1.0 + 2.0 * (m - k0) / (k1 - k0)),
            Coverage::Table { parts } => {
                let [m0, m1] = self.mass;
                if !(m1 > m0) {
                    return 0.0;
                }
                let u = ((m - m0) / (m1 - m0) * TABLE_PARTS as f64).clamp(0.0, TABLE_PARTS as f64);
                let whole = (u as usize).min(TABLE_PARTS - 1);
                let before: f64 = parts[..whole].iter().map(|&p| f64::from(p)).sum();
                before + f64::from(parts[whole]) * (u - whole as f64)
            }
        }
    }

    /// Coverage × mass over the part of the fragment within `window`, and that part's interval.
    pub fn within(&self, window: [f64; 2]) -> Option<(f64, [f64; 2])> {
        let (m0, m1) = (self.mass[0].max(window[0]), self.mass[1].min(window[1]));
        (m1 > m0).then(|| (self.cumulative(m1) - self.cumulative(m0), [m0, m1]))
    }

    /// The fragment over the part of its interval within `window`, if any: the same coverage
    /// there (a kernel's keeps its own time axis; a table is re-tabulated over the part from its
    /// cumulative coverage, uniform within each new part).
    pub fn clipped(&self, window: [f64; 2]) -> Option<Fragment> {
        let mass = [self.mass[0].max(window[0]), self.mass[1].min(window[1])];
        if !(mass[1] > mass[0]) {
            return None;
        }
        if mass == self.mass {
            return Some(*self);
        }
        let coverage = match self.coverage {
            Coverage::Kernel { .. } => self.coverage,
            Coverage::Table { .. } => {
                let part = (mass[1] - mass[0]) / TABLE_PARTS as f64;
                let at = |p: usize| self.cumulative(mass[0] + part * p as f64);
                Coverage::Table {
                    parts: std::array::from_fn(|p| (at(p + 1) - at(p)) as f32),
                }
            }
        };
        Some(Fragment {
            mass,
            coverage,
            depth: mass.map(|m| self.depth_at(m)),
            ..*self
        })
    }

    /// Depth along the ray at shutter mass `m`.
    pub fn depth_at(&self, m: f64) -> f64 {
        let [m0, m1] = self.mass;
        if m1 > m0 {
            self.depth[0] + (self.depth[1] - self.depth[0]) * ((m - m0) / (m1 - m0))
        } else {
            self.depth[0]
        }
    }
}

/// Most pieces a pixel's window is cut into. Fragment ends closer than 1/`MAX_PIECES` of the
/// window to the previous cut are merged: within a piece each fragment's coverage is still
/// integrated exactly over its own part of it; only the order of surfaces is taken once per piece
/// (at its middle) and a surface's coverage at its mean, as a reference of `MAX_PIECES` frames
/// takes the order. The sweep costs about pieces × active fragments, so a pixel cut at each of its
/// n fragments' ends costs n²: at 512 pieces, 82 % of the samples of a `kernel3d` render of the
/// knot at 160×120 were here. At 64 its 8 sub-frames render 2× faster (1.41 s → 0.71 s) at the
/// same RMSE against the converged reference (0.00208 → 0.00207); at 16 an approaching square's
/// area in `tests/stiff.rs` leaves its 1 % (docs/math.md, "A-buffer visibility").
const MAX_PIECES: usize = 64;

/// Most fragments one pixel holds. A pixel that reaches it has its fragments merged, one per
/// surface and sub-frame, which leaves at most half of it; the A-buffer's memory per worker is
/// one tile row of such pixels, and its sweep (pieces × active fragments, each piece sorting
/// them) is bounded with it. Without it, 2,802 fragments reached one pixel of the torus knot at
/// 160×120 and 8 sub-frames (`--explain`), and half a million each of a dozen pixels in
/// `tests/stiff.rs`.
pub const MAX_FRAGMENTS_PER_PIXEL: usize = 256;

/// Parts of a merged fragment's coverage table. Fragments merged within one of 8 sub-frames keep
/// their coverage in eighths of it, as fine as the [`MAX_PIECES`] pieces of the whole window.
pub(crate) const TABLE_PARTS: usize = 8;

/// Most time bins fragments are merged within: more sub-frames than this share bins (a table's
/// interval then spans several sub-frames), so that merging all of a bin's surfaces into one
/// always leaves fewer than half of [`MAX_FRAGMENTS_PER_PIXEL`].
const MAX_TIME_BINS: usize = MAX_FRAGMENTS_PER_PIXEL / 4;

/// Share of the depth tolerance within which [`compact`] takes fragments for one surface. The
/// A-buffer chains a surface through its fragments' depths; a merged surface has one depth, so only
/// fragments much closer than the chain's steps are merged: at the full tolerance, the knot at
/// 160×120 (constant colour) had 2.9× the RMSE against the converged reference, at 1/4 1.10×, at
/// 1/8 1.03× (docs/history.md, "Issue 10, fifth part").
const SURFACE_SHARE: f64 = 0.125;

/// Doublings of the surface tolerance [`compact`] tries before merging each time bin into one
/// surface.
const MAX_WIDENINGS: usize = 64;

/// How [`compact`] got a pixel below half of [`MAX_FRAGMENTS_PER_PIXEL`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Compaction {
    /// Fragments of one surface and time bin were merged.
    Surfaces,
    /// There were so many surfaces that ones farther apart than the depth tolerance were merged
    /// too: their order in depth within a time bin is lost.
    Widened,
}

/// The time bins [`compact`] merges within, and that `kernel3d` resolves one at a time:
/// consecutive sub-frames, at most [`MAX_TIME_BINS`].
pub(crate) struct SubFrameBins {
    /// Each bin's shutter-mass span.
    spans: Vec<[f64; 2]>,
    /// The first sub-frame of each bin, then the number of sub-frames.
    starts: Vec<usize>,
}

impl SubFrameBins {
    /// Bins of the sub-frames `windows` (at least one).
    pub fn new(windows: &[[f64; 2]]) -> SubFrameBins {
        let bins = windows.len().clamp(1, MAX_TIME_BINS);
        let mut spans = vec![[f64::INFINITY, f64::NEG_INFINITY]; bins];
        let mut starts = vec![windows.len(); bins + 1];
        for (w, window) in windows.iter().enumerate().rev() {
            let b = w * bins / windows.len();
            let span = &mut spans[b];
            span[0] = span[0].min(window[0]);
            span[1] = span[1].max(window[1]);
            starts[b] = w;
        }
        SubFrameBins { spans, starts }
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.spans.len()
    }

    /// Bin `b`'s shutter-mass span.
    pub fn span(&self, b: usize) -> [f64; 2] {
        self.spans[b]
    }

    /// The sub-frames bin `b` holds.
    pub fn windows(&self, b: usize) -> std::ops::Range<usize> {
        self.starts[b]..self.starts[b + 1]
    }

    /// The bin the shutter-mass interval `mass` lies in; one past the last for an interval
    /// reaching beyond its bin (a still object's, which spans the exposure).
    pub fn of(&self, mass: [f64; 2]) -> usize {
        let spans = &self.spans;
        let middle = 0.5 * (mass[0] + mass[1]);
        let b = spans
            .partition_point(|span| span[1] <= middle)
            .min(spans.len() - 1);
        let [start, end] = spans[b];
        let slack = 1e-9 * (end - start);
        if mass[0] < start - slack || mass[1] > end + slack {
            spans.len()
        } else {
            b
        }
    }
}

/// Merge one pixel's `fragments` so that at most half of [`MAX_FRAGMENTS_PER_PIXEL`] remain.
///
/// Fragments are grouped by their time bin (`bins`), sorted by depth at their middle, and a run
/// of fragments within [`SURFACE_SHARE`] of the smaller tolerance of the run's first is one
/// surface. Each stretch of time a surface covers without a gap becomes one fragment, a
/// [`Coverage::Table`] where it has two or more (see [`merge_in_time`] and [`merge`]).
/// When that leaves too many, the share is doubled until it does not (at most [`MAX_WIDENINGS`]
/// times, then each bin is one surface); beyond the whole tolerance the outcome is
/// [`Compaction::Widened`].
pub(crate) fn compact(fragments: &mut Vec<Fragment>, bins: &SubFrameBins) -> Compaction {
    let mut outcome = Compaction::Surfaces;
    let mut widen = SURFACE_SHARE;
    let mut merged = Vec::with_capacity(fragments.len());
    for widening in 0..=MAX_WIDENINGS + 1 {
        // (bin, depth at the middle, index), in that order; the id breaks ties.
        let mut order: Vec<(usize, f64, usize)> = fragments
            .iter()
            .enumerate()
            .map(|(i, f)| {
                (
                    bins.of(f.mass),
                    f.depth_at(0.5 * (f.mass[0] + f.mass[1])),
                    i,
                )
            })
            .collect();
        order.sort_unstable_by(|a, b| {
            (a.0.cmp(&b.0))
                .then(a.1.total_cmp(&b.1))
                .then(fragments[a.2].id.cmp(&fragments[b.2].id))
        });
        // Each run of `order` within the share of the tolerance is one surface.
        let mut start = 0;
        while let Some(&(bin, depth, first)) = order.get(start) {
            let tolerance = fragments[first].tolerance;
            let same_surface = |&&(other_bin, other_depth, other): &&(usize, f64, usize)| {
                other_bin == bin
                    && (widening > MAX_WIDENINGS
                        || other_depth - depth <= widen * tolerance.min(fragments[other].tolerance))
            };
            let end = start + 1 + order[start + 1..].iter().take_while(same_surface).count();
            let surface = order[start..end].iter().map(|e| e.2);
            if widening > MAX_WIDENINGS {
                // The last resort keeps the bound: one fragment per bin.
                merged.push(merge(surface.map(|i| &fragments[i])));
            } else {
                merge_in_time(surface, fragments, &mut merged);
            }
            start = end;
        }
        std::mem::swap(fragments, &mut merged);
        merged.clear();
        if fragments.len() <= MAX_FRAGMENTS_PER_PIXEL / 2 {
            break;
        }
        widen *= 2.0;
        if widen > 1.0 {
            outcome = Compaction::Widened;
        }
    }
    outcome
}

/// One fragment per stretch of time that the `surface`'s fragments (indices into `fragments`)
/// cover without a gap, appended to `out`. Where a surface's depth at a pixel falls and rises
/// again (a sphere passing over it), it meets one depth as it arrives and as it leaves; one table
/// over both would span the time between, overlapping the same surface's tables at other depths,
/// and the resolve would take those for surfaces hiding each other (a sphere crossing a pixel at
/// one sub-frame came out 7 % less opaque there).
fn merge_in_time(
    surface: impl Iterator<Item = usize>,
    fragments: &[Fragment],
    out: &mut Vec<Fragment>,
) {
    let mut members: Vec<usize> = surface.collect();
    members.sort_unstable_by(|&a, &b| {
        (fragments[a].mass[0].total_cmp(&fragments[b].mass[0]))
            .then(fragments[a].id.cmp(&fragments[b].id))
    });
    let (mut first, mut reach) = (0, f64::NEG_INFINITY);
    for (k, &i) in members.iter().enumerate() {
        let [start, end] = fragments[i].mass;
        if k > first && start > reach {
            out.push(merge(members[first..k].iter().map(|&j| &fragments[j])));
            first = k;
        }
        reach = reach.max(end);
    }
    out.push(merge(members[first..].iter().map(|&j| &fragments[j])));
}

/// One fragment standing for `members` (at least one) of one surface: a single member as it is;
/// several as a [`Coverage::Table`] over the union of their intervals, each part holding the sum
/// of their coverage × mass over it, with their coverage-weighted mean colour and depths at the
/// union's ends, the smallest tolerance and the smallest id (so that ties still break alike).
fn merge<'a>(all: impl Iterator<Item = &'a Fragment> + Clone) -> Fragment {
    let first = *all.clone().next().expect("a surface has a fragment");
    if all.clone().nth(1).is_none() {
        return first;
    }
    let mass = all
        .clone()
        .fold([f64::INFINITY, f64::NEG_INFINITY], |m, f| {
            [m[0].min(f.mass[0]), m[1].max(f.mass[1])]
        });
    let part_length = (mass[1] - mass[0]) / TABLE_PARTS as f64;
    let mut parts = [0.0f64; TABLE_PARTS];
    let (mut weight, mut colour, mut depth) = (0.0, [0.0; 3], [0.0; 2]);
    let (mut tolerance, mut id) = (f64::INFINITY, u32::MAX);
    for f in all {
        // The member's cumulative coverage at its ends and at the part boundaries inside it.
        let first_part = (((f.mass[0] - mass[0]) / part_length) as usize).min(TABLE_PARTS - 1);
        let start = f.cumulative(f.mass[0]);
        let (mut at, mut before) = (f.mass[0], start);
        for (p, part) in parts.iter_mut().enumerate().skip(first_part) {
            let end = (mass[0] + part_length * (p + 1) as f64).min(f.mass[1]);
            let end = if p == TABLE_PARTS - 1 { f.mass[1] } else { end };
            if end > at {
                let after = f.cumulative(end);
                *part += after - before;
                (at, before) = (end, after);
            }
            if at >= f.mass[1] {
                break;
            }
        }
        let w = before - start;
        weight += w;
        for (c, v) in colour.iter_mut().zip(f.colour) {
            *c += w * f64::from(v);
        }
        for (d, m) in depth.iter_mut().zip(mass) {
            *d += w * f.depth_at(m);
        }
        tolerance = tolerance.min(f.tolerance);
        id = id.min(f.id);
    }
    let (colour, depth) = if weight > 0.0 {
        (
            colour.map(|c| (c / weight) as f32),
            depth.map(|d| d / weight),
        )
    } else {
        (
            first.colour,
            [first.depth_at(mass[0]), first.depth_at(mass[1])],
        )
    };
    Fragment {
        mass,
        coverage: Coverage::Table {
            parts: parts.map(|p| p as f32),
        },
        depth,
        colour,
        tolerance,
        id,
    }
}

/// Once this share of a piece is left unoccluded, farther surfaces cannot change an 8-bit value.
const OPAQUE_REMAINDER: f64 = 1e-4;

/// A resolved pixel: premultiplied colour and the share of the window showing the background.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Resolved {
    pub colour: [f64; 3],
    pub background: f64,
}

impl Resolved {
    /// Add `other`, resolved over another part of the exposure.
    pub fn add(&mut self, other: &Resolved) {
        for (c, o) in self.colour.iter_mut().zip(other.colour) {
            *c += o;
        }
        self.background += other.background;
    }
}

/// Exact temporal visibility of `fragments` over the shutter-mass window `window`, a part of an
/// exposure `exposure` long: pieces are cut no shorter than 1/[`MAX_PIECES`] of it when there
/// are more, so that a pixel resolved in parts is cut as finely as one resolved whole.
///
/// Pieces in which every active fragment belongs to one surface need no occlusion test: a run of
/// such pieces is composited as one span, each fragment's coverage over it integrated in one
/// closed-form difference. Only pieces where two or more surfaces overlap are resolved one by
/// one. Within one surface the run's coverage is taken at its mean, as a piece's is: the mean
/// over the time the surface is there, so a run ends where no fragment is active. (Over the
/// whole window, a surface summing to 0.955 for half of it, opaque by [`opacity`], came out
/// 0.4775 opaque; and a mean over shorter pieces is no better, since a kernel's coverage in time
/// is Gaussian and its sum ripples about the surface's: each piece's peak above full is lost
/// while its dips stay. docs/history.md, "A surface's coverage over the time it is there".)
pub(crate) fn resolve_exact(fragments: &[Fragment], window: [f64; 2], exposure: f64) -> Resolved {
    let mut out = Resolved::default();
    if one_surface(fragments) {
        // No fragment can ever hide another: the time from the first fragment's start to the
        // last one's end is one run (a gap within it, a surface passing twice, is taken as
        // there).
        let (mut weight, mut colour) = (0.0, [0.0; 3]);
        let (mut first, mut last) = (window[1], window[0]);
        for f in fragments.iter() {
            let w = f.cumulative(f.mass[1]) - f.cumulative(f.mass[0]);
            weight += w;
            for (c, v) in colour.iter_mut().zip(f.colour) {
                *c += w * f64::from(v);
            }
            first = first.min(f.mass[0].max(window[0]));
            last = last.max(f.mass[1].min(window[1]));
        }
        let length = window[1] - window[0];
        let present = (last - first).max(0.0);
        let shown = composite(weight, colour, present, 1.0, &mut out);
        out.background = shown * present + (length - present);
        return out;
    }
    let mut cuts: Vec<f64> = Vec::with_capacity(2 * fragments.len() + 2);
    cuts.extend(window);
    for f in fragments.iter() {
        cuts.extend(f.mass);
        // A table's parts are where its merged fragments' ends were: pieces end there too, or a
        // piece would take the surface's coverage at its mean over the whole table.
        if let Coverage::Table { .. } = f.coverage {
            let part = (f.mass[1] - f.mass[0]) / TABLE_PARTS as f64;
            cuts.extend((1..TABLE_PARTS).map(|p| f.mass[0] + part * p as f64));
        }
    }
    sort_total(&mut cuts);
    cuts.dedup();
    let shortest = exposure / MAX_PIECES as f64;
    if (cuts.len() - 1) as f64 * shortest > window[1] - window[0] {
        merge_cuts(&mut cuts, shortest);
    }
    // Fragments by start, so that the active set is swept in order (keys sorted, not the
    // fragments: a fragment is 112 bytes).
    let mut by_start: Vec<(i64, u32, u32)> = (fragments.iter().enumerate())
        .map(|(i, f)| (total_order_key(f.mass[0]), f.id, i as u32))
        .collect();
    by_start.sort_unstable();
    let mut cache = Cumulative::new(fragments);
    let mut run = Run::new(fragments.len());
    let mut next = 0;
    // Active fragments with their depth in the current piece.
    let mut active: Vec<Active> = Vec::new();
    for piece in cuts.windows(2) {
        let (m0, m1) = (piece[0], piece[1]);
        if !(m1 > m0) {
            continue;
        }
        while let Some(i) =
            (by_start.get(next).map(|&(_, _, i)| i as usize)).filter(|&i| fragments[i].mass[0] < m1)
        {
            active.push((0, fragments[i].id, i as u32));
            next += 1;
        }
        active.retain(|&(_, _, i)| fragments[i as usize].mass[1] > m0);
        if active.is_empty() {
            run.close(m0, &mut cache, &mut out);
            out.background += m1 - m0;
            continue;
        }
        let mid = 0.5 * (m0 + m1);
        let (mut near, mut far, mut tolerance) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
        for entry in active.iter_mut() {
            let f = &fragments[entry.2 as usize];
            let depth = f.depth_at(mid.clamp(f.mass[0], f.mass[1]));
            entry.0 = total_order_key(depth);
            near = near.min(depth);
            far = far.max(depth);
            tolerance = tolerance.min(f.tolerance);
        }
        // Within the smallest tolerance of each other, all active fragments are one surface
        // (the ternary test, which compares each with the nearest, would say so too).
        if far - near <= tolerance {
            run.extend(m0, &active);
            continue;
        }
        run.close(m0, &mut cache, &mut out);
        active.sort_unstable();
        // Surfaces front to back; coverage is integrated only until the piece is opaque.
        let length = m1 - m0;
        let mut transmittance = 1.0;
        let mut start = 0;
        while start < active.len() && transmittance > OPAQUE_REMAINDER {
            let end = same_surface_end(&active, start, fragments);
            let (mut weight, mut colour) = (0.0, [0.0; 3]);
            for &(_, _, i) in &active[start..end] {
                let i = i as usize;
                let [f0, f1] = fragments[i].mass;
                let w = cache.over(i, m0.max(f0), m1.min(f1));
                weight += w;
                for (c, v) in colour.iter_mut().zip(fragments[i].colour) {
                    *c += w * f64::from(v);
                }
            }
            transmittance *= composite(weight, colour, length, transmittance, &mut out);
            start = end;
        }
        out.background += transmittance * length;
    }
    run.close(window[1], &mut cache, &mut out);
    out
}

/// Add a surface of coverage `weight` (× mass) and weighted colour sum `colour` over a span of
/// mass `length` behind `transmittance`; returns the share of what lies behind that still shows.
fn composite(
    weight: f64,
    colour: [f64; 3],
    length: f64,
    transmittance: f64,
    out: &mut Resolved,
) -> f64 {
    if !(weight > 0.0) {
        return 1.0;
    }
    let alpha = opacity(weight / length);
    let k = transmittance * alpha * length / weight;
    for (o, c) in out.colour.iter_mut().zip(colour) {
        *o += k * c;
    }
    1.0 - alpha
}

/// Drop cuts closer than `gap` to the previous kept one (the window's ends are kept).
fn merge_cuts(cuts: &mut Vec<f64>, gap: f64) {
    let Some(&last) = cuts.last() else {
        return;
    };
    let mut kept = 0;
    for i in 0..cuts.len() {
        let c = cuts[i];
        if i == 0 || (c - cuts[kept - 1] >= gap && last - c >= gap) || c == last {
            cuts[kept] = c;
            kept += 1;
        }
    }
    cuts.truncate(kept);
}

/// Whether all fragments lie within one surface's depth tolerance of each other whenever they
/// meet: true when their depth ranges, widened by their tolerances, chain into one cluster whose
/// whole extent is within the tolerance of its nearest point (so any two of them pass the ternary
/// test at any time).
fn one_surface(fragments: &[Fragment]) -> bool {
    let mut near = f64::INFINITY;
    let mut far = f64::NEG_INFINITY;
    let mut tolerance = f64::INFINITY;
    for f in fragments {
        near = near.min(f.depth[0].min(f.depth[1]));
        far = far.max(f.depth[0].max(f.depth[1]));
        tolerance = tolerance.min(f.tolerance);
    }
    fragments.is_empty() || far - near <= tolerance
}

/// The end of the surface that starts at `active[start]`: each following fragment within the
/// depth tolerance of the deepest one before it (the ternary depth test, chained, as the
/// compositor of footprints does: raster/composite.rs). Unlike there, the chain keeps the smaller
/// tolerance as it steps on: fragments come here in their depth order at the pixel, where a splat
/// seen nearly edge-on, whose depth is uncertain by its large tolerance, falls between the
/// surfaces; taking on its tolerance let one surface's chain step through to the next.
fn same_surface_end(active: &[Active], start: usize, fragments: &[Fragment]) -> usize {
    let Some(&(front, _, first)) = active.get(start) else {
        return start;
    };
    let (mut deepest, mut tolerance) = (
        from_total_order_key(front),
        fragments[first as usize].tolerance,
    );
    let mut end = start;
    while let Some(&(key, _, i)) = active.get(end) {
        let depth = from_total_order_key(key);
        let own = fragments[i as usize].tolerance;
        if depth - deepest > tolerance.max(own) {
            break;
        }
        if depth > deepest && depth - deepest <= tolerance.min(own) {
            (deepest, tolerance) = (depth, tolerance.min(own));
        }
        end += 1;
    }
    end
}

/// Each fragment's cumulative coverage at the last cut it was evaluated at: a fragment seen
/// over consecutive spans costs one closed-form evaluation per span.
struct Cumulative<'a> {
    fragments: &'a [Fragment],
    last: Vec<(f64, f64)>,
}

impl<'a> Cumulative<'a> {
    fn new(fragments: &'a [Fragment]) -> Self {
        Cumulative {
            fragments,
            last: vec![(f64::NAN, 0.0); fragments.len()],
        }
    }

    /// Cumulative coverage of fragment `i` at `m`.
    fn at(&mut self, i: usize, m: f64) -> f64 {
        if self.last[i].0 == m {
            return self.last[i].1;
        }
        let value = self.fragments[i].cumulative(m);
        self.last[i] = (m, value);
        value
    }

    /// Coverage × mass of fragment `i` over [m0, m1] (within its interval).
    fn over(&mut self, i: usize, m0: f64, m1: f64) -> f64 {
        let start = self.at(i, m0);
        self.at(i, m1) - start
    }
}

/// A run of pieces with a single surface: where it starts, and the fragments seen in it with
/// where each entered.
struct Run {
    start: Option<f64>,
    members: Vec<(usize, f64)>,
    /// Per fragment, the number of the run it last joined (runs are numbered from 1).
    joined: Vec<u32>,
    number: u32,
}

impl Run {
    fn new(fragments: usize) -> Self {
        Run {
            start: None,
            members: Vec::new(),
            joined: vec![0; fragments],
            number: 1,
        }
    }

    fn extend(&mut self, m0: f64, active: &[Active]) {
        self.start.get_or_insert(m0);
        for &(_, _, i) in active {
            let i = i as usize;
            if self.joined[i] != self.number {
                self.joined[i] = self.number;
                self.members.push((i, m0));
            }
        }
    }

    /// Composite the run over [start, `m`] as one surface.
    fn close(&mut self, m: f64, cache: &mut Cumulative, out: &mut Resolved) {
        let Some(start) = self.start.take() else {
            return;
        };
        let (mut weight, mut colour) = (0.0, [0.0; 3]);
        for &(i, entered) in &self.members {
            let f = &cache.fragments[i];
            let w = cache.over(i, entered.max(f.mass[0]), m.min(f.mass[1]));
            weight += w;
            for (c, v) in colour.iter_mut().zip(f.colour) {
                *c += w * f64::from(v);
            }
        }
        let length = m - start;
        let transmittance = composite(weight, colour, length, 1.0, out);
        out.background += transmittance * length;
        self.members.clear();
        self.number += 1;
    }
}

/// A fragment active in a piece: its depth there as a [`total_order_key`], its id and its index
/// (a pixel holds at most [`MAX_FRAGMENTS_PER_PIXEL`]). Ordered as a tuple: nearest first, the id
/// breaking ties (a total order, so the result does not depend on the order fragments arrived
/// in). Sorted as integers, the sweep's sorts took about a third less time than sorting indices by
/// a comparison that read the fragments (docs/history.md, "Sorting keys in the A-buffer").
type Active = (i64, u32, u32);

/// An integer whose order is `f64::total_cmp`'s (the standard library's own mapping: negative
/// values have their bits below the sign flipped). It is its own inverse.
fn total_order_key(x: f64) -> i64 {
    let bits = x.to_bits() as i64;
    bits ^ (((bits >> 63) as u64) >> 1) as i64
}

/// The value whose [`total_order_key`] is `key`.
fn from_total_order_key(key: i64) -> f64 {
    f64::from_bits(total_order_key(f64::from_bits(key as u64)) as u64)
}

/// Sort `values` by `f64::total_cmp`, comparing integers.
fn sort_total(values: &mut [f64]) {
    let mut keys: Vec<i64> = values.iter().map(|&v| total_order_key(v)).collect();
    keys.sort_unstable();
    for (v, k) in values.iter_mut().zip(keys) {
        *v = from_total_order_key(k);
    }
}

/// The GPU approximation over the sub-frame `window`: `visible_depth` is the visible surface's
/// depth at the sub-frame's start and end (+∞ where nothing covers the pixel then). Fragments
/// reaching beyond the window (those of still objects) count with their part inside it.
pub(crate) fn resolve_approximate(
    fragments: &[Fragment],
    window: [f64; 2],
    visible_depth: [f32; 2],
) -> Resolved {
    let (mut weight, mut colour) = (0.0, [0.0; 3]);
    let mut spans: Vec<[f64; 2]> = Vec::new();
    for f in fragments {
        let Some((w, [m0, m1])) = f.within(window) else {
            continue;
        };
        let nearest = f.depth_at(m0).min(f.depth_at(m1));
        let visible = visible_depth
            .iter()
            .any(|&d| nearest <= f64::from(d) + f.tolerance);
        if !visible {
            continue;
        }
        weight += w;
        for (c, v) in colour.iter_mut().zip(f.colour) {
            *c += w * f64::from(v);
        }
        spans.push([m0, m1]);
    }
    let length = window[1] - window[0];
    // [t_min, t_max], and the time during which some fragment covers the pixel.
    spans.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]));
    let (first, last) = (
        spans.first().map_or(0.0, |s| s[0]),
        spans.iter().fold(f64::NEG_INFINITY, |m, s| m.max(s[1])),
    );
    let mut active = 0.0;
    let mut reach = f64::NEG_INFINITY;
    for &[m0, m1] in &spans {
        active += (m1 - m0.max(reach)).max(0.0);
        reach = reach.max(m1);
    }
    if !(weight > 0.0 && active > 0.0) {
        return Resolved {
            colour: [0.0; 3],
            background: length,
        };
    }
    let covered = (last - first) * opacity(weight / active);
    Resolved {
        colour: colour.map(|c| c * covered / weight),
        background: length - covered,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fragment of constant coverage `rate` over `mass` at `depth`.
    fn flat(mass: [f64; 2], rate: f64, depth: f64, colour: [f32; 3], id: u32) -> Fragment {
        Fragment {
            mass,
            coverage: Coverage::Kernel {
                kernel_mass: mass,
                primitive: Primitive::Flat { rate },
                scale: 0.5 * (mass[1] - mass[0]),
            },
            depth: [depth; 2],
            colour,
            tolerance: 0.05,
            id,
        }
    }

    #[test]
    fn a_surface_there_for_part_of_the_window_hides_what_lies_behind_it_meanwhile() {
        // A surface summing to 0.955 (opaque by `opacity`) crosses the pixel over the first half
        // of the window in five fragments, one after another. Its coverage taken at its mean
        // over the whole window, 0.4775, let 0.0225 of the background through; over the time it
        // is there, it hides it.
        let red = [1.0, 0.0, 0.0];
        let near: Vec<Fragment> = (0..5)
            .map(|j| {
                let t = 0.1 * f64::from(j);
                flat([t, t + 0.1], 0.955, 1.0, red, j)
            })
            .collect();
        let alone = resolve_exact(&near, [0.0, 1.0], 1.0);
        assert!((alone.colour[0] - 0.5).abs() < 1e-12, "{alone:?}");
        assert!((alone.background - 0.5).abs() < 1e-12, "{alone:?}");
        // With a farther surface later in the window, the near one is a run within the sweep.
        let far = flat([0.9, 1.0], 0.5, 10.0, [0.0, 0.0, 1.0], 9);
        let both = resolve_exact(&[near.clone(), vec![far]].concat(), [0.0, 1.0], 1.0);
        assert!((both.colour[0] - 0.5).abs() < 1e-12, "{both:?}");
        assert!((both.colour[2] - 0.05).abs() < 1e-12, "{both:?}");
        assert!((both.background - 0.45).abs() < 1e-12, "{both:?}");
        // A faint surface keeps its coverage as it is: 0.6 of its half.
        let faint: Vec<Fragment> = (near.iter())
            .map(|f| flat(f.mass, 0.6, 1.0, red, f.id))
            .collect();
        let faint = resolve_exact(&faint, [0.0, 1.0], 1.0);
        assert!((faint.colour[0] - 0.3).abs() < 1e-12, "{faint:?}");
        assert!((faint.background - 0.7).abs() < 1e-12, "{faint:?}");
    }

    #[test]
    fn merging_at_the_cap_keeps_a_passing_sphere_s_coverage() {
        // A sphere passing a pixel within one sub-frame: its depth there falls and rises, so
        // fragments arriving and leaving meet at one depth. Merged into one table over both,
        // that table overlapped the surface's own nearer ones in time and the resolve took them
        // for two surfaces (red 0.498 → 0.477); merged per stretch of time, the colour stays.
        let n = MAX_FRAGMENTS_PER_PIXEL;
        let fragments: Vec<Fragment> = (0..n)
            .map(|i| {
                let t0 = 0.225 + 0.5 * i as f64 / n as f64;
                let x = ((t0 + 0.025 - 0.5) / 0.28).clamp(-0.999, 0.999);
                let cosine = (1.0 - x * x).sqrt();
                let rate = 0.96 * 0.5 / (0.05 * n as f64);
                Fragment {
                    tolerance: 0.05 / cosine.max(0.05),
                    ..flat(
                        [t0, t0 + 0.05],
                        rate,
                        5.0 - 0.4 * cosine,
                        [1.0, 0.0, 0.0],
                        i as u32,
                    )
                }
            })
            .collect();
        let mut merged = fragments.clone();
        compact(&mut merged, &SubFrameBins::new(&[[0.0, 1.0]]));
        assert!(merged.len() <= n / 2);
        let (whole, compacted) = (
            resolve_exact(&fragments, [0.0, 1.0], 1.0),
            resolve_exact(&merged, [0.0, 1.0], 1.0),
        );
        assert!(
            (whole.colour[0] - compacted.colour[0]).abs() < 0.005,
            "{whole:?} → {compacted:?}"
        );
    }

    /// Coverage × mass of `fragments` within `window`.
    fn weight(fragments: &[Fragment], window: [f64; 2]) -> f64 {
        fragments
            .iter()
            .filter_map(|f| f.within(window).map(|(w, _)| w))
            .sum()
    }

    /// Eight sub-frames of equal mass.
    fn windows() -> Vec<[f64; 2]> {
        (0..8)
            .map(|i| [i as f64 / 8.0, (i + 1) as f64 / 8.0])
            .collect()
    }

    #[test]
    fn merging_keeps_each_surface_s_coverage_in_time_and_its_place_in_depth() {
        // A red surface at depth 1 in front of a blue one at depth 2, each made of short
        // fragments scattered over eight sub-frames (as a streak's kernels reach a pixel).
        let windows = windows();
        let mut fragments = Vec::new();
        let mut random = crate::math::test_sequence(12345);
        for id in 0..MAX_FRAGMENTS_PER_PIXEL as u32 {
            let window = windows[(id / 2) as usize % 8];
            let start = window[0] + random() * 0.1;
            let mass = [start, (start + 0.02 + random() * 0.05).min(window[1])];
            let (depth, colour) = if id % 2 == 0 {
                (1.0 + 0.001 * random(), [1.0, 0.0, 0.0])
            } else {
                (2.0 + 0.001 * random(), [0.0, 0.0, 1.0])
            };
            fragments.push(flat(mass, 0.3 + random(), depth, colour, id));
        }
        let before = fragments.clone();
        assert_eq!(
            compact(&mut fragments, &SubFrameBins::new(&windows)),
            Compaction::Surfaces
        );
        // One fragment per surface and sub-frame.
        assert_eq!(fragments.len(), 16);
        for f in &fragments {
            let red = f.colour[0] == 1.0;
            assert!(red || f.colour[2] == 1.0, "colours of two surfaces mixed");
            let depth = if red { 1.0 } else { 2.0 };
            assert!((f.depth[0] - depth).abs() < 0.001 && (f.depth[1] - depth).abs() < 0.001);
        }
        // Each surface's coverage over each eighth of a sub-frame is kept: the parts of a table
        // start where its members' union does, so compare over whole sub-frames and the whole
        // exposure.
        for window in windows.iter().copied().chain([[0.0, 1.0]]) {
            let (a, b) = (weight(&before, window), weight(&fragments, window));
            assert!((a - b).abs() < 1e-6 * a, "{window:?}: {a} → {b}");
        }
        // And the pixel resolves as before (measured: 0.0015 apart at most). Both are cut into at
        // most MAX_PIECES pieces; the tables' parts put cuts where their members' ends were
        // (without them, a piece took a surface's coverage at its mean over a whole sub-frame:
        // 0.018 less red).
        let exact = resolve_exact(&before, [0.0, 1.0], 1.0);
        let merged = resolve_exact(&fragments, [0.0, 1.0], 1.0);
        for c in 0..3 {
            assert!(
                (exact.colour[c] - merged.colour[c]).abs() < 0.005,
                "{exact:?} vs {merged:?}"
            );
        }
        assert!((exact.background - merged.background).abs() < 0.005);
    }

    #[test]
    fn a_pixel_resolved_one_sub_frame_at_a_time_adds_up_to_the_whole() {
        // Two surfaces crossing in depth within each of eight sub-frames, and a still one behind
        // them all spanning the exposure (clipped to each sub-frame): kernel3d resolves a pixel
        // bin by bin and adds the parts up, which is exact when no piece is merged away.
        let windows = windows();
        let mut fragments = Vec::new();
        for (k, w) in windows.iter().enumerate() {
            let id = 2 * k as u32;
            let middle = 0.5 * (w[0] + w[1]);
            let mut near = flat([w[0], middle + 0.02], 0.7, 1.0, [1.0, 0.0, 0.0], id);
            near.depth = [1.0, 3.0];
            fragments.push(near);
            fragments.push(flat(
                [middle - 0.03, w[1]],
                0.9,
                2.0,
                [0.0, 1.0, 0.0],
                id + 1,
            ));
        }
        let still = flat([0.0, 1.0], 0.95, 5.0, [0.0, 0.0, 1.0], 100);
        let mut all = fragments.clone();
        all.push(still);
        let whole = resolve_exact(&all, [0.0, 1.0], 1.0);
        let mut sum = Resolved::default();
        for &w in &windows {
            let part: Vec<Fragment> = (fragments.iter())
                .filter(|f| f.mass[0] >= w[0] && f.mass[1] <= w[1])
                .copied()
                .chain(still.clipped(w))
                .collect();
            sum.add(&resolve_exact(&part, w, 1.0));
        }
        for c in 0..3 {
            assert!(
                (whole.colour[c] - sum.colour[c]).abs() < 1e-12,
                "{whole:?} vs {sum:?}"
            );
        }
        assert!((whole.background - sum.background).abs() < 1e-12);
        assert!(whole.colour.iter().all(|&c| c > 0.01), "{whole:?}");
    }

    #[test]
    fn total_order_keys_sort_as_total_cmp_and_map_back() {
        let values = [
            f64::NAN,
            -f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            1.5,
            -1.5,
            1e-310,
            -1e-310,
            f64::MAX,
            -f64::MAX,
            0.1 + 0.2,
            0.3,
        ];
        for a in values {
            assert_eq!(
                from_total_order_key(total_order_key(a)).to_bits(),
                a.to_bits()
            );
            for b in values {
                assert_eq!(
                    total_order_key(a).cmp(&total_order_key(b)),
                    a.total_cmp(&b),
                    "{a} against {b}"
                );
            }
        }
        let mut sorted = values;
        sort_total(&mut sorted);
        let mut expected = values;
        expected.sort_by(f64::total_cmp);
        assert_eq!(sorted.map(f64::to_bits), expected.map(f64::to_bits));
    }

    #[test]
    fn a_clipped_fragment_keeps_its_coverage_over_each_part() {
        let mut kernel = flat([0.1, 0.9], 0.6, 1.0, [1.0; 3], 0);
        kernel.depth = [1.0, 1.002];
        let mut table = vec![kernel, flat([0.2, 0.7], 0.3, 1.001, [1.0; 3], 1)];
        compact(&mut table, &SubFrameBins::new(&[[0.0, 1.0]]));
        assert!(matches!(
            table[..],
            [Fragment {
                coverage: Coverage::Table { .. },
                ..
            }]
        ));
        for f in [kernel, table[0]] {
            let whole = f.within([0.0, 1.0]).unwrap().0;
            let (a, b) = (
                f.clipped([0.0, 0.4]).unwrap(),
                f.clipped([0.4, 1.0]).unwrap(),
            );
            let parts = a.within([0.0, 1.0]).unwrap().0 + b.within([0.0, 1.0]).unwrap().0;
            assert!((parts - whole).abs() < 1e-6 * whole, "{parts} vs {whole}");
            // The depth runs on along the same line.
            assert!((a.depth[1] - f.depth_at(0.4)).abs() < 1e-12);
            assert!((b.depth[0] - f.depth_at(0.4)).abs() < 1e-12);
            assert!(f.clipped([0.95, 1.0]).is_none());
        }
    }

    #[test]
    fn a_pixel_of_more_surfaces_than_the_cap_allows_is_bounded_and_keeps_its_coverage() {
        // 256 surfaces one depth unit apart, all in one sub-frame: merging by surface leaves
        // them all, so the tolerance widens until at most half the cap remain.
        let windows = windows();
        let mut fragments: Vec<Fragment> = (0..MAX_FRAGMENTS_PER_PIXEL as u32)
            .map(|i| flat([0.0, 0.125], 0.5, 1.0 + f64::from(i), [1.0; 3], i))
            .collect();
        let total = weight(&fragments, [0.0, 1.0]);
        assert_eq!(
            compact(&mut fragments, &SubFrameBins::new(&windows)),
            Compaction::Widened
        );
        assert!(fragments.len() <= MAX_FRAGMENTS_PER_PIXEL / 2);
        let after = weight(&fragments, [0.0, 1.0]);
        assert!((after - total).abs() < 1e-6 * total, "{total} → {after}");
        // Still in depth order: the nearest merged surface starts at the nearest depth.
        let nearest = fragments
            .iter()
            .map(|f| f.depth[0])
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 2.0, "{nearest}");
    }
}
