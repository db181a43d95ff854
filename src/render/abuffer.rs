//! Per-pixel temporal visibility of fragments: the exact A-buffer (Heinzle et al. 2010, §4.4)
//! and the paper's GPU approximation (§5). A fragment is what one primitive leaves on one pixel
//! ray: an interval of time (as shutter mass, so that lengths are weights), a coverage over it,
//! a depth, a colour. `kernel3d`'s kernels make fragments of Gaussian coverage; a renderer of
//! moving triangles adds a [`Coverage`] for samples a triangle covers over an interval, and its
//! fragments resolve by the same code.
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
        }
    }

    /// Coverage × mass over the part of the fragment within `window`, and that part's interval.
    pub fn within(&self, window: [f64; 2]) -> Option<(f64, [f64; 2])> {
        let (m0, m1) = (self.mass[0].max(window[0]), self.mass[1].min(window[1]));
        (m1 > m0).then(|| (self.cumulative(m1) - self.cumulative(m0), [m0, m1]))
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

/// Work allowed for one pixel's sweep, in fragment × piece steps (each piece sorts its active
/// fragments by depth, about n·log₂n steps for n of them). A pixel with so many fragments that
/// [`MAX_PIECES`] pieces would take more is cut into fewer: each fragment's coverage is still
/// integrated exactly over each piece, only the order of surfaces is taken once per piece.
/// A million surfels in one pixel, all active all the exposure, took 176 s at 512 pieces; at
/// this bound they get 3 pieces.
pub(crate) const SWEEP_WORK_PER_PIXEL: usize = 1 << 26;

/// How many pieces a pixel with `fragments` fragments may be cut into: [`MAX_PIECES`], fewer when
/// that would exceed [`SWEEP_WORK_PER_PIXEL`], at least one.
fn piece_limit(fragments: usize) -> usize {
    let steps_per_piece =
        fragments.max(1) * (usize::BITS - fragments.leading_zeros()).max(1) as usize;
    (SWEEP_WORK_PER_PIXEL / steps_per_piece).clamp(1, MAX_PIECES)
}

/// Once this share of a piece is left unoccluded, farther surfaces cannot change an 8-bit value.
const OPAQUE_REMAINDER: f64 = 1e-4;

/// A resolved pixel: premultiplied colour and the share of the window showing the background.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Resolved {
    pub colour: [f64; 3],
    pub background: f64,
    /// Whether the pixel had so many fragments that its sweep was cut into fewer than
    /// [`MAX_PIECES`] pieces to stay within [`SWEEP_WORK_PER_PIXEL`].
    pub coarse: bool,
}

/// Exact temporal visibility of `fragments` over the shutter-mass window `window`.
///
/// Pieces in which every active fragment belongs to one surface need no occlusion test: a run of
/// such pieces is composited as one span, each fragment's coverage over it integrated in one
/// closed-form difference. Only pieces where two or more surfaces overlap are resolved one by
/// one. (Within one surface the run's coverage is taken at its mean, as a piece's is.)
pub(crate) fn resolve_exact(fragments: &mut [Fragment], window: [f64; 2]) -> Resolved {
    let mut out = Resolved::default();
    if one_surface(fragments) {
        // No fragment can ever hide another: the whole window is one run.
        let (mut weight, mut colour) = (0.0, [0.0; 3]);
        for f in fragments.iter() {
            let w = f.cumulative(f.mass[1]) - f.cumulative(f.mass[0]);
            weight += w;
            for (c, v) in colour.iter_mut().zip(f.colour) {
                *c += w * f64::from(v);
            }
        }
        let length = window[1] - window[0];
        out.background = composite(weight, colour, length, 1.0, &mut out) * length;
        return out;
    }
    let mut cuts: Vec<f64> = Vec::with_capacity(2 * fragments.len() + 2);
    cuts.extend(window);
    for f in fragments.iter() {
        cuts.extend(f.mass);
    }
    cuts.sort_unstable_by(f64::total_cmp);
    cuts.dedup();
    let limit = piece_limit(fragments.len());
    out.coarse = limit < MAX_PIECES;
    if cuts.len() > limit + 1 {
        merge_cuts(&mut cuts, (window[1] - window[0]) / limit as f64);
    }
    // Fragments by start, so that the active set is swept in order.
    fragments.sort_unstable_by(|a, b| a.mass[0].total_cmp(&b.mass[0]).then(a.id.cmp(&b.id)));
    let fragments: &[Fragment] = fragments;
    let mut cache = Cumulative::new(fragments);
    let mut run = Run::new(fragments.len());
    let mut next = 0;
    // Active fragments with their depth in the current piece.
    let mut active: Vec<(f64, usize)> = Vec::new();
    for piece in cuts.windows(2) {
        let (m0, m1) = (piece[0], piece[1]);
        if !(m1 > m0) {
            continue;
        }
        while next < fragments.len() && fragments[next].mass[0] < m1 {
            active.push((0.0, next));
            next += 1;
        }
        active.retain(|&(_, i)| fragments[i].mass[1] > m0);
        let mid = 0.5 * (m0 + m1);
        let (mut near, mut far, mut tolerance) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
        for entry in active.iter_mut() {
            let f = &fragments[entry.1];
            entry.0 = f.depth_at(mid.clamp(f.mass[0], f.mass[1]));
            near = near.min(entry.0);
            far = far.max(entry.0);
            tolerance = tolerance.min(f.tolerance);
        }
        // Within the smallest tolerance of each other, all active fragments are one surface
        // (the ternary test, which compares each with the nearest, would say so too).
        if far - near <= tolerance {
            run.extend(m0, &active);
            continue;
        }
        run.close(m0, &mut cache, &mut out);
        active.sort_unstable_by(|&a, &b| nearer(a, b, fragments));
        // Surfaces front to back; coverage is integrated only until the piece is opaque.
        let length = m1 - m0;
        let mut transmittance = 1.0;
        let mut start = 0;
        while start < active.len() && transmittance > OPAQUE_REMAINDER {
            let end = same_surface_end(&active, start, fragments);
            let (mut weight, mut colour) = (0.0, [0.0; 3]);
            for &(_, i) in &active[start..end] {
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
fn same_surface_end(active: &[(f64, usize)], start: usize, fragments: &[Fragment]) -> usize {
    let Some(&(front, first)) = active.get(start) else {
        return start;
    };
    let (mut deepest, mut tolerance) = (front, fragments[first].tolerance);
    let mut end = start;
    while let Some(&(depth, i)) = active.get(end) {
        let own = fragments[i].tolerance;
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

    fn extend(&mut self, m0: f64, active: &[(f64, usize)]) {
        self.start.get_or_insert(m0);
        for &(_, i) in active {
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

/// Depth order of active fragments, the kernel index breaking ties (a total order, so the
/// result does not depend on the order fragments arrived in).
fn nearer(a: (f64, usize), b: (f64, usize), fragments: &[Fragment]) -> std::cmp::Ordering {
    a.0.total_cmp(&b.0)
        .then(fragments[a.1].id.cmp(&fragments[b.1].id))
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
            coarse: false,
        };
    }
    let covered = (last - first) * opacity(weight / active);
    Resolved {
        colour: colour.map(|c| c * covered / weight),
        background: length - covered,
        coarse: false,
    }
}
