//! Speed lines: tapered, fading, anti-aliased ribbons trailing a moving object, thick and opaque
//! at the object and thinning and fading towards their oldest end (after Schmid et al. 2010).
//!
//! Per line: validate, clip the centre line (in f64, so that far-off points draw their visible
//! part), build one ribbon outline with round joins and a round cap at the newest end, take its
//! 8-bit coverage from tiny-skia (filled once with the non-zero rule, so a line never doubles its
//! alpha where it overlaps itself), give each pixel the opacity, by arc length, of the
//! centre-line point whose half width reaches furthest past it, and composite colour "over" the
//! earlier lines in linear f32. The lines are drawn front to back, newest on top first, so that
//! a pixel the lines above have made opaque costs the lines below nothing. Bad geometry draws
//! nothing and never panics. Derivation and choices: docs/math.md, "Hint trails".

use crate::framebuffer::Framebuffer;
use crate::raster::over;
use glam::DVec2;
use rayon::prelude::*;
use tiny_skia::{FillRule, Mask, PathBuilder, Transform};

/// One speed line: the projected path of a point, in pixels (x right, y down,
/// pixel centres at +0.5), from its oldest point to its newest (the newest end
/// is at the object).
#[derive(Clone, Debug, PartialEq)]
pub struct SpeedLine {
    /// Centre line in pixels, oldest point first, newest (at the object) last.
    pub points: Vec<DVec2>,
    /// Colour in linear RGB.
    pub colour: [f32; 3],
}

/// How speed lines look.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineLook {
    /// Stroke width in pixels at the newest end (> 0). Lines are not drawn when
    /// it is not positive or is NaN. Widths above 65536 px count as 65536 px.
    pub width: f64,
    /// Width at the oldest end as a fraction of `width`, 0..=1 (0 = a point).
    pub taper: f64,
    /// Opacity at the oldest end as a fraction of the newest end's, 0..=1.
    pub fade: f64,
    /// Opacity at the newest end, 0..=1.
    pub opacity: f64,
}

/// Lines drawn into linear, premultiplied RGBA (alpha = coverage × opacity), the form in which
/// each line is composited over the ones before it.
#[derive(Clone, Debug, PartialEq)]
struct Strokes {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major `width × height` pixels: linear premultiplied RGB, then alpha.
    pub pixels: Vec<[f32; 4]>,
}

/// Widest stroke honoured, in pixels. It keeps the coordinates given to
/// tiny-skia (image size plus a margin of about one width) accurate in `f32`.
const MAX_WIDTH_PX: f64 = 65536.0;

/// Consecutive centre-line points closer than this are merged.
const MIN_SEGMENT_PX: f64 = 1e-6;

/// A centre-line point within this of the chord between its neighbours kept, in place, in arc
/// length and in where its outline lies, is left out: every covered pixel tests every segment
/// within reach, and a straight line 100 px wide sampled 32 times tested 32.
const CENTRE_TOLERANCE_PX: f64 = 0.01;

/// Most centre-line points one chord stands for, which bounds the test of those it leaves out.
const MAX_POINTS_PER_CHORD: usize = 64;

/// The speed lines' work is bounded by the larger of this many pixel tests and
/// [`TESTS_PER_PIXEL`] per image pixel: a test is a pixel tested against a segment of a line's
/// centre line, or a pixel of a line's coverage mask (filled, then checked against the lines
/// above), which measured about as costly (5–13 ns each). 10,000 lines 100 px wide along paths
/// of 100 turns (2,500 segments each) had asked for about 10¹¹ tests and 8 minutes on 128 × 96
/// pixels; the budget is a few seconds.
const MIN_TESTS: u64 = 1 << 29;

/// See [`MIN_TESTS`].
const TESTS_PER_PIXEL: u64 = 256;

/// How drawing the speed lines went against their budget of pixel tests (see [`MIN_TESTS`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineWork {
    /// Pixels tested against a segment.
    pub tests: u64,
    /// Pixels of coverage masks filled.
    pub mask_pixels: u64,
    /// The budget of pixel tests.
    pub budget: u64,
    /// Lines left out whole when the budget was spent: those drawn lowest, under the others.
    pub left_out: usize,
    /// Whether a line was drawn in part when the budget ran out: some pixels it reaches were
    /// tested against only some of its segments, or not at all.
    pub cut: bool,
}

impl LineWork {
    /// The budget of pixel tests for a `width × height` image.
    fn budget_for(width: u32, height: u32) -> u64 {
        let pixels = u64::from(width) * u64::from(height);
        MIN_TESTS.max(TESTS_PER_PIXEL.saturating_mul(pixels))
    }

    /// Whether the budget is spent.
    fn spent(&self) -> bool {
        self.tests + self.mask_pixels >= self.budget
    }
}

/// Largest gap between a round join or cap and its polygon, in pixels.
const ARC_TOLERANCE_PX: f64 = 0.02;

/// Most polygon edges for half of a round join or cap.
const MAX_ARC_STEPS: f64 = 64.0;

/// How far beyond the half width a pixel centre can be and still be covered:
/// half a pixel diagonal (≈ 0.71), rounded up.
const AA_REACH_PX: f64 = 1.0;

/// Once the lines above leave less than this share of a pixel showing, times the brightest line
/// colour (at least one), the lines below cannot change its 8-bit value and are not drawn there:
/// 10,000 lines 100 px wide, each covering a 96 × 72 image, took 24 s drawn back to front.
const SPENT_REMAINDER: f32 = 1e-4;

/// Draws `lines` over `image`, in slice order, each composited "over" the ones before it, as
/// one layer of strokes over the image (made at the image's size and dropped after: as a
/// [`crate::raster::Layer`] of its own it had held both).
///
/// Bad lines are skipped (see the module docs). If the strokes cannot be allocated, the image is
/// left as it is. Returns the work done against its budget.
pub fn draw_over(lines: &[SpeedLine], look: &LineLook, image: &mut Framebuffer) -> LineWork {
    let budget = LineWork::budget_for(image.width, image.height);
    let (strokes, work) = strokes(lines, look, image.width, image.height, budget);
    (image.pixels.par_iter_mut())
        .zip(&strokes.pixels)
        .for_each(|(behind, px)| *behind = over([px[0], px[1], px[2]], 1.0 - px[3], *behind));
    work
}

/// The strokes of `lines`, as [`draw_over`] composites them. A zero-sized image gives empty
/// strokes, and so do no lines, a look that draws nothing and an image whose strokes cannot be
/// allocated (0 × 0); with the work done within `budget` pixel tests.
fn strokes(
    lines: &[SpeedLine],
    look: &LineLook,
    width: u32,
    height: u32,
    budget: u64,
) -> (Strokes, LineWork) {
    let mut work = LineWork {
        budget,
        ..LineWork::default()
    };
    // Checked before the layer is made, so that speed lines switched off cost nothing: they
    // took 16 bytes a pixel and a pass over the image in every hint (1.4 s at 8192²).
    let Some(style) = Style::new(look).filter(|_| !lines.is_empty()) else {
        return (Strokes::transparent(0, 0), work);
    };
    let mut layer = Strokes::transparent(width, height);
    if layer.pixels.is_empty() {
        return (layer, work);
    }
    let brightest = (lines.iter().flat_map(|line| line.colour))
        .filter(|c| c.is_finite())
        .fold(1.0, f32::max);
    let spent = SPENT_REMAINDER / brightest;
    for (drawn, line) in lines.iter().rev().enumerate() {
        if work.spent() {
            work.left_out = lines.len() - drawn;
            break;
        }
        layer.add_line_under(line, &style, spent, &mut work);
    }
    (layer, work)
}

impl Strokes {
    /// A fully transparent layer, or an empty 0 × 0 one if it cannot be
    /// allocated.
    fn transparent(width: u32, height: u32) -> Self {
        let empty = Strokes {
            width: 0,
            height: 0,
            pixels: Vec::new(),
        };
        let Some(count) = (width as usize).checked_mul(height as usize) else {
            return empty;
        };
        let mut pixels = Vec::new();
        if pixels.try_reserve_exact(count).is_err() {
            return empty;
        }
        pixels.resize(count, [0.0; 4]);
        Strokes {
            width,
            height,
            pixels,
        }
    }

    /// Draws one line under the layer's contents, where they leave at least `spent` of the pixel
    /// showing; skips it if it is invalid or misses the image. Lines added under in reverse order
    /// composite as lines added over in order. Its tests are counted in `work`, and stop where
    /// its budget is spent.
    fn add_line_under(&mut self, line: &SpeedLine, style: &Style, spent: f32, work: &mut LineWork) {
        if !line.colour.iter().all(|c| c.is_finite()) {
            return;
        }
        let Some(centre) = centre_line(&line.points, style.half_width) else {
            return;
        };
        let length = centre[centre.len() - 1].s;

        // Anything dropped by the clip lies at least `AA_REACH_PX + 1` outside
        // the image, even after widening by the half width.
        let reach = style.half_width + AA_REACH_PX;
        let size = DVec2::new(f64::from(self.width), f64::from(self.height));
        let runs = clip_runs(&centre, DVec2::splat(-reach - 1.0), size + reach + 1.0);

        // The line's bounding box, in whole pixels, inside the image.
        let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for node in runs.iter().flat_map(|run| &run.nodes) {
            lo = lo.min(node.p);
            hi = hi.max(node.p);
        }
        let lo = (lo - reach).floor().max(DVec2::ZERO);
        let hi = (hi + reach).ceil().min(size);
        if !(lo.x < hi.x && lo.y < hi.y) {
            return;
        }
        // Exact: both are whole numbers in 0..=u32::MAX.
        let (x0, y0) = (lo.x as usize, lo.y as usize);
        let (box_width, box_height) = ((hi.x - lo.x) as u32, (hi.y - lo.y) as u32);

        // Coverage of the whole line, filled once.
        let mut builder = PathBuilder::new();
        for run in &runs {
            let outline = ribbon_outline(run, style, length);
            let mut points = outline.iter().map(|&p| p - lo);
            if let Some(first) = points.next() {
                builder.move_to(first.x as f32, first.y as f32);
                for p in points {
                    builder.line_to(p.x as f32, p.y as f32);
                }
                builder.close();
            }
        }
        let (Some(path), Some(mut mask)) = (builder.finish(), Mask::new(box_width, box_height))
        else {
            return;
        };
        mask.fill_path(&path, FillRule::Winding, true, Transform::identity());

        // Pixels the lines above have spent are left out as if uncovered.
        work.mask_pixels += u64::from(box_width) * u64::from(box_height);
        let (image_width, box_width) = (self.width as usize, box_width as usize);
        let mut shows = false;
        for (row, coverage) in mask.data_mut().chunks_exact_mut(box_width).enumerate() {
            let start = (y0 + row) * image_width + x0;
            for (cov, px) in coverage.iter_mut().zip(&self.pixels[start..]) {
                if 1.0 - px[3] < spent {
                    *cov = 0;
                }
                shows |= *cov != 0;
            }
        }
        if !shows {
            return;
        }

        // Opacity by arc length, then colour and "under", one row at a time.
        let segments = Segment::all(&runs, lo, style, length);
        let mut nearest = NearestSweep::new(&segments, box_width, reach, work);
        let coverage_rows = mask.data().chunks_exact(box_width);
        for (row, coverage) in coverage_rows.enumerate() {
            let (first, nearest_s) = nearest.row(row, coverage);
            let start = (y0 + row) * image_width + x0 + first;
            let pixels = &mut self.pixels[start..start + nearest_s.len()];
            let coverage = &coverage[first..];
            for ((px, &cov), &(beyond, s)) in pixels.iter_mut().zip(coverage).zip(nearest_s) {
                if cov == 0 || !beyond.is_finite() {
                    continue;
                }
                let alpha = (f64::from(cov) / 255.0 * style.opacity_at(s / length)) as f32;
                let showing = 1.0 - px[3];
                for (c, &colour) in px.iter_mut().zip(&line.colour) {
                    *c += showing * alpha * colour;
                }
                px[3] += showing * alpha;
            }
        }
    }
}

/// A [`LineLook`] with its values checked and clamped.
struct Style {
    /// Half the stroke width at the newest end, in pixels, finite and > 0.
    half_width: f64,
    /// In 0..=1.
    taper: f64,
    /// In 0..=1.
    fade: f64,
    /// In 0..=1.
    opacity: f64,
}

impl Style {
    /// `None` when nothing would be drawn: the width is not positive or the
    /// opacity is zero. NaN fractions count as 0.
    fn new(look: &LineLook) -> Option<Self> {
        let opacity = unit(look.opacity);
        let positive = look.width > 0.0; // false for NaN
        if !positive || opacity == 0.0 {
            return None;
        }
        Some(Style {
            half_width: 0.5 * look.width.min(MAX_WIDTH_PX),
            taper: unit(look.taper),
            fade: unit(look.fade),
            opacity,
        })
    }

    /// Half width at fraction `u` of the arc length (0 = oldest, 1 = newest).
    fn half_width_at(&self, u: f64) -> f64 {
        self.half_width * (self.taper + (1.0 - self.taper) * u)
    }

    /// Opacity at fraction `u` of the arc length (0 = oldest, 1 = newest).
    fn opacity_at(&self, u: f64) -> f64 {
        self.opacity * (self.fade + (1.0 - self.fade) * u)
    }
}

/// Clamps to 0..=1, with NaN giving 0.
fn unit(x: f64) -> f64 {
    if x > 0.0 {
        x.min(1.0)
    } else {
        0.0
    }
}

/// A centre-line point and its arc length from the oldest point.
#[derive(Clone, Copy, Debug)]
struct Node {
    p: DVec2,
    s: f64,
}

/// The centre line with arc lengths, its straight runs drawn as one segment for a line whose
/// half width is at most `half_width`. `None` if a coordinate is not finite, there are fewer than
/// two distinct points, or the length overflows.
fn centre_line(points: &[DVec2], half_width: f64) -> Option<Vec<Node>> {
    if !points.iter().all(|p| p.is_finite()) {
        return None;
    }
    let mut nodes: Vec<Node> = Vec::with_capacity(points.len());
    for &p in points {
        match nodes.last() {
            None => nodes.push(Node { p, s: 0.0 }),
            Some(last) => {
                let step = last.p.distance(p);
                if step >= MIN_SEGMENT_PX {
                    nodes.push(Node {
                        p,
                        s: last.s + step,
                    });
                }
            }
        }
    }
    let length = nodes.last()?.s;
    (nodes.len() >= 2 && length.is_finite()).then(|| without_straight_runs(nodes, half_width))
}

/// `nodes` with the points left out that lie on the chord between the points kept, within
/// [`CENTRE_TOLERANCE_PX`] in place and in arc length (so half width and opacity, linear in arc
/// length, stay within it too), and whose segments turn from the chord by so little that the
/// outline, `half_width` out along their normals, stays within it as well. Greedy from the
/// oldest end, each chord over at most [`MAX_POINTS_PER_CHORD`] points.
fn without_straight_runs(nodes: Vec<Node>, half_width: f64) -> Vec<Node> {
    let largest_sine = CENTRE_TOLERANCE_PX / half_width.max(CENTRE_TOLERANCE_PX);
    // `span`: the chord's ends and the points between.
    let on_chord = |span: &[Node]| {
        let (a, b) = (span[0], span[span.len() - 1]);
        let d = b.p - a.p;
        let along = d.normalize_or_zero();
        let held = |q: &Node| {
            let t = ((q.p - a.p).dot(d) / d.length_squared()).clamp(0.0, 1.0);
            q.p.distance(a.p + t * d) <= CENTRE_TOLERANCE_PX
                && (q.s - (a.s + t * (b.s - a.s))).abs() <= CENTRE_TOLERANCE_PX
        };
        let parallel = |w: &[Node]| {
            let step = (w[1].p - w[0].p).normalize_or_zero();
            step.dot(along) > 0.0 && step.perp_dot(along).abs() <= largest_sine
        };
        span.iter().all(held) && span.windows(2).all(parallel)
    };
    let last = nodes.len() - 1;
    let mut kept = vec![nodes[0]];
    let mut anchor = 0;
    while anchor < last {
        let mut end = anchor + 1;
        while end < last
            && end - anchor < MAX_POINTS_PER_CHORD
            && on_chord(&nodes[anchor..=end + 1])
        {
            end += 1;
        }
        kept.push(nodes[end]);
        anchor = end;
    }
    kept
}

/// A piece of the centre line inside the clip rectangle, with at least two
/// distinct points.
struct Run {
    nodes: Vec<Node>,
    /// Whether the run ends at the line's newest point (which gets the round cap).
    ends_at_newest: bool,
}

/// Splits the centre line into the runs inside the rectangle `lo..hi`,
/// keeping each point's arc length on the whole line.
fn clip_runs(centre: &[Node], lo: DVec2, hi: DVec2) -> Vec<Run> {
    let mut runs = Vec::new();
    let mut current = Vec::new();
    for pair in centre.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let Some((t0, t1)) = clip_segment(a.p, b.p, lo, hi) else {
            end_run(&mut runs, &mut current, false);
            continue;
        };
        if t0 > 0.0 {
            end_run(&mut runs, &mut current, false);
        }
        push_distinct(&mut current, lerp_node(a, b, t0));
        push_distinct(&mut current, lerp_node(a, b, t1));
        if t1 < 1.0 {
            end_run(&mut runs, &mut current, false);
        }
    }
    end_run(&mut runs, &mut current, true);
    runs
}

/// Moves `current` into `runs` if it has a segment, else drops it.
fn end_run(runs: &mut Vec<Run>, current: &mut Vec<Node>, ends_at_newest: bool) {
    let nodes = std::mem::take(current);
    if nodes.len() >= 2 {
        runs.push(Run {
            nodes,
            ends_at_newest,
        });
    }
}

/// Appends `node` unless it repeats the last point.
fn push_distinct(nodes: &mut Vec<Node>, node: Node) {
    if nodes
        .last()
        .is_none_or(|last| last.p.distance(node.p) >= MIN_SEGMENT_PX)
    {
        nodes.push(node);
    }
}

/// The point at parameter `t` of the segment `a → b`, exact at the ends.
fn lerp_node(a: Node, b: Node, t: f64) -> Node {
    if t <= 0.0 {
        a
    } else if t >= 1.0 {
        b
    } else {
        Node {
            p: a.p.lerp(b.p, t),
            s: a.s + (b.s - a.s) * t,
        }
    }
}

/// Liang–Barsky: the parameter range of `a → b` inside the rectangle `lo..hi`.
fn clip_segment(a: DVec2, b: DVec2, lo: DVec2, hi: DVec2) -> Option<(f64, f64)> {
    let d = b - a;
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    // Each pair is (p, q) with "inside" meaning p·t <= q.
    for (p, q) in [
        (-d.x, a.x - lo.x),
        (d.x, hi.x - a.x),
        (-d.y, a.y - lo.y),
        (d.y, hi.y - a.y),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else if p < 0.0 {
            t0 = t0.max(q / p);
        } else {
            t1 = t1.min(q / p);
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// The closed outline of one run's ribbon: the `+normal` side from oldest to
/// newest, the cap, the `−normal` side back.
fn ribbon_outline(run: &Run, style: &Style, length: f64) -> Vec<DVec2> {
    let p: Vec<DVec2> = run.nodes.iter().map(|n| n.p).collect();
    let h: Vec<f64> = run
        .nodes
        .iter()
        .map(|n| style.half_width_at(n.s / length))
        .collect();
    let d: Vec<DVec2> = p
        .windows(2)
        .map(|w| (w[1] - w[0]).normalize_or_zero())
        .collect();
    let n: Vec<DVec2> = d.iter().map(|d| d.perp()).collect();
    let last = p.len() - 1;

    let mut out = Vec::with_capacity(4 * p.len() + 16);
    out.push(p[0] + h[0] * n[0]);
    for i in 1..last {
        let inner = d[i - 1].perp_dot(d[i]) > 0.0;
        join(&mut out, p[i], h[i], n[i - 1], n[i], d[i - 1], inner);
    }
    out.push(p[last] + h[last] * n[last - 1]);
    if run.ends_at_newest {
        round_arc(
            &mut out,
            p[last],
            h[last],
            n[last - 1],
            d[last - 1],
            -n[last - 1],
        );
    } else {
        out.push(p[last] - h[last] * n[last - 1]);
    }
    for i in (1..last).rev() {
        let inner = d[i - 1].perp_dot(d[i]) < 0.0;
        join(&mut out, p[i], h[i], -n[i], -n[i - 1], -d[i], inner);
    }
    out.push(p[0] - h[0] * n[0]);
    out
}

/// Appends one side's join at vertex `p`, going from the offset direction
/// `from` (unit) to `to`, with `towards` the direction of travel into the
/// vertex. The inner side passes through the vertex; the outer side is round.
fn join(
    out: &mut Vec<DVec2>,
    p: DVec2,
    h: f64,
    from: DVec2,
    to: DVec2,
    towards: DVec2,
    inner: bool,
) {
    out.push(p + h * from);
    if inner {
        out.push(p);
        out.push(p + h * to);
    } else {
        // When the line turns straight back, `from + to` vanishes and the
        // round end bulges forwards, along the travel direction.
        let middle = (from + to).try_normalize().unwrap_or(towards);
        round_arc(out, p, h, from, middle, to);
    }
}

/// Appends the arc of radius `h` around `centre` from direction `from`
/// through `middle` to `to` (all unit; each half under a half turn), without
/// its first point.
fn round_arc(out: &mut Vec<DVec2>, centre: DVec2, h: f64, from: DVec2, middle: DVec2, to: DVec2) {
    // Sagitta h·(1 − cos(step/2)) equals the tolerance.
    let step = if h > ARC_TOLERANCE_PX {
        2.0 * (1.0 - ARC_TOLERANCE_PX / h).acos()
    } else {
        std::f64::consts::PI
    };
    for (a, b) in [(from, middle), (middle, to)] {
        let angle = a.perp_dot(b).atan2(a.dot(b));
        let steps = (angle.abs() / step).ceil().clamp(1.0, MAX_ARC_STEPS);
        // `steps` is a whole number in 1..=64.
        let count = steps as u32;
        for k in 1..count {
            let turn = DVec2::from_angle(angle * f64::from(k) / steps);
            out.push(centre + h * turn.rotate(a));
        }
        out.push(centre + h * b);
    }
}

/// A centre-line segment in mask coordinates, with arc lengths and half widths at its ends.
struct Segment {
    a: DVec2,
    b: DVec2,
    s_a: f64,
    s_b: f64,
    h_a: f64,
    h_b: f64,
}

impl Segment {
    /// All segments of `runs` of a line `length` long drawn as `style`, shifted by `-origin`,
    /// sorted by top edge.
    fn all(runs: &[Run], origin: DVec2, style: &Style, length: f64) -> Vec<Segment> {
        let mut segments: Vec<Segment> = runs
            .iter()
            .flat_map(|run| run.nodes.windows(2))
            .map(|w| Segment {
                a: w[0].p - origin,
                b: w[1].p - origin,
                s_a: w[0].s,
                s_b: w[1].s,
                h_a: style.half_width_at(w[0].s / length),
                h_b: style.half_width_at(w[1].s / length),
            })
            .collect();
        segments.sort_by(|x, y| x.top().total_cmp(&y.top()));
        segments
    }

    fn top(&self) -> f64 {
        self.a.y.min(self.b.y)
    }

    fn bottom(&self) -> f64 {
        self.a.y.max(self.b.y)
    }

    /// At the segment's point nearest `q`: how far `q` lies beyond the half width there
    /// (negative inside), and the arc length. (Where that is least lies k·|y|/√(1 − k²) further
    /// on, k the half width's slope and |y| the distance across; it would lower the value by
    /// about |y|·k²/2, under 0.02 px on lines 20 times longer than their width.)
    fn nearest(&self, q: DVec2) -> (f64, f64) {
        let d = self.b - self.a;
        let t = ((q - self.a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
        let beyond = q.distance(self.a + t * d) - (self.h_a + t * (self.h_b - self.h_a));
        (beyond, self.s_a + t * (self.s_b - self.s_a))
    }

    /// An x range holding every point of the row `y` within `reach` of the
    /// segment, or `None` if there is none.
    fn row_span(&self, y: f64, reach: f64) -> Option<(f64, f64)> {
        let d = self.b - self.a;
        let (t0, t1) = if d.y.abs() < MIN_SEGMENT_PX {
            if (self.a.y - y).abs() > reach {
                return None;
            }
            (0.0, 1.0)
        } else {
            let ta = (y - reach - self.a.y) / d.y;
            let tb = (y + reach - self.a.y) / d.y;
            (ta.min(tb).max(0.0), ta.max(tb).min(1.0))
        };
        let (xa, xb) = (self.a.x + t0 * d.x, self.a.x + t1 * d.x);
        (t0 <= t1).then(|| (xa.min(xb) - reach, xa.max(xb) + reach))
    }
}

/// Finds, row by row, the centre-line point whose half width reaches furthest
/// past each covered pixel (the least [`Segment::nearest`] "beyond"), looking
/// only at segments whose `reach`-wide band crosses the row: a covered pixel
/// lies within [`AA_REACH_PX`] beyond some point's half width, and more than
/// that beyond any point out of reach. By distance alone, a thin, faded older
/// part running beside or back over a wide newer part took pixels that only
/// the newer part covers.
struct NearestSweep<'a> {
    segments: &'a [Segment],
    reach: f64,
    /// Next segment (by top edge) not yet active.
    next: usize,
    active: Vec<usize>,
    /// Per column: "beyond" ([`Segment::nearest`]) and arc length of the point found.
    best: Vec<(f64, f64)>,
    /// The columns of `best` the last row set.
    reached: std::ops::Range<usize>,
    /// The budget the tests count against.
    work: &'a mut LineWork,
}

impl<'a> NearestSweep<'a> {
    fn new(segments: &'a [Segment], width: usize, reach: f64, work: &'a mut LineWork) -> Self {
        NearestSweep {
            segments,
            reach,
            next: 0,
            active: Vec::new(),
            best: vec![(f64::INFINITY, 0.0); width],
            reached: 0..0,
            work,
        }
    }

    /// For row `row` (rows in increasing order): the first column a segment
    /// reaches, and from there to the last, per column, "beyond" and the arc
    /// length of the point found, or an infinite "beyond" where `coverage` is
    /// 0 or no segment is within reach. Only those columns are visited, so
    /// that a line costs about its own pixels rather than its bounding box's
    /// (a diagonal across 8192² took 400 ms, now 90). Once the budget is spent, no more
    /// segments are tested: the columns are left as far as they were found.
    fn row(&mut self, row: usize, coverage: &[u8]) -> (usize, &[(f64, f64)]) {
        let y = row as f64 + 0.5;
        let (segments, reach) = (self.segments, self.reach);
        while let Some(segment) = segments.get(self.next) {
            if segment.top() - reach > y {
                break;
            }
            self.active.push(self.next);
            self.next += 1;
        }
        self.active.retain(|&i| segments[i].bottom() + reach >= y);

        self.best[self.reached.clone()].fill((f64::INFINITY, 0.0));
        let (mut reached_start, mut reached_end) = (usize::MAX, 0);
        let last_column = self.best.len() as f64 - 1.0;
        for &i in &self.active {
            let Some((x_lo, x_hi)) = segments[i].row_span(y, reach) else {
                continue;
            };
            // Columns whose centre (column + 0.5) is in x_lo..=x_hi.
            let (first, last) = (
                (x_lo - 0.5).ceil().max(0.0),
                (x_hi - 0.5).floor().min(last_column),
            );
            if first > last {
                continue;
            }
            if self.work.spent() {
                self.work.cut = true;
                break;
            }
            // Whole numbers inside 0..width.
            let columns = first as usize..last as usize + 1;
            self.work.tests += columns.len() as u64;
            reached_start = reached_start.min(columns.start);
            reached_end = reached_end.max(columns.end);
            let best = &mut self.best[columns.clone()];
            for ((column, best), &cov) in columns.clone().zip(best).zip(&coverage[columns]) {
                if cov == 0 {
                    continue;
                }
                let found = segments[i].nearest(DVec2::new(column as f64 + 0.5, y));
                if found.0 < best.0 {
                    *best = found;
                }
            }
        }
        self.reached = reached_start.min(reached_end)..reached_end;
        (self.reached.start, &self.best[self.reached.clone()])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WHITE: [f32; 3] = [1.0, 1.0, 1.0];

    /// A look neither tapered nor faded.
    fn uniform(width: f64, opacity: f64) -> LineLook {
        LineLook {
            width,
            taper: 1.0,
            fade: 1.0,
            opacity,
        }
    }

    fn drawn(lines: &[SpeedLine], look: &LineLook, width: u32, height: u32) -> Strokes {
        strokes(lines, look, width, height, u64::MAX).0
    }

    fn alpha(layer: &Strokes, x: u32, y: u32) -> f32 {
        layer.pixels[(y * layer.width + x) as usize][3]
    }

    fn column_sum(layer: &Strokes, x: u32) -> f32 {
        (0..layer.height).map(|y| alpha(layer, x, y)).sum()
    }

    fn column_peak(layer: &Strokes, x: u32) -> f32 {
        (0..layer.height)
            .map(|y| alpha(layer, x, y))
            .fold(0.0, f32::max)
    }

    /// The pixel containing `p`.
    fn alpha_at(layer: &Strokes, p: DVec2) -> f32 {
        alpha(layer, p.x.floor() as u32, p.y.floor() as u32)
    }

    fn assert_sane(layer: &Strokes) {
        assert_eq!(
            layer.pixels.len(),
            layer.width as usize * layer.height as usize
        );
        for px in &layer.pixels {
            assert!(px.iter().all(|c| c.is_finite()), "{px:?}");
            assert!((0.0..=1.0 + 1e-6).contains(&px[3]), "{px:?}");
        }
    }

    /// Distance from `q` to the polyline `points`.
    fn distance_to_polyline(points: &[DVec2], q: DVec2) -> f64 {
        points
            .windows(2)
            .map(|w| {
                let d = w[1] - w[0];
                let t = ((q - w[0]).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                q.distance(w[0] + t * d)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The brief's test line: x = 20 → 200 at y = 50.5, sampled at 10 points
    /// so that it also goes through (straight) joins.
    fn straight_line(colour: [f32; 3]) -> SpeedLine {
        SpeedLine {
            points: (0..10)
                .map(|i| DVec2::new(20.0 + 20.0 * f64::from(i), 50.5))
                .collect(),
            colour,
        }
    }

    const TAPERED: LineLook = LineLook {
        width: 6.0,
        taper: 0.25,
        fade: 0.2,
        opacity: 1.0,
    };

    /// Fraction of arc length at the centre of column `x` of `straight_line`.
    fn straight_u(x: u32) -> f64 {
        (f64::from(x) + 0.5 - 20.0) / 180.0
    }

    fn style(look: &LineLook) -> Style {
        Style::new(look).unwrap()
    }

    // Tolerances: tiny-skia anti-aliases with 4 sub-scanlines per pixel, so a
    // nearly horizontal edge's coverage of a pixel is a multiple of 1/4, off by
    // at most 1/8 px per edge, and a column's sum by at most 1/4 (times the
    // local opacity). Also the column's own width (taper) and opacity (fade)
    // are a little below the newest end's, which is why a sum "≈ 6" is only
    // within ~10 %.
    #[test]
    fn straight_line_has_the_right_width_opacity_extent_and_colour() {
        let layer = drawn(&[straight_line(WHITE)], &TAPERED, 240, 100);
        assert_sane(&layer);
        let s = style(&TAPERED);

        // Near the newest end: width 6, opacity 1.
        let x = 197;
        let u = straight_u(x);
        let sum = column_sum(&layer, x);
        assert!((sum - 6.0).abs() < 0.6, "newest column sum {sum}");
        let expected = 2.0 * s.half_width_at(u) * s.opacity_at(u);
        assert!(
            (f64::from(sum) - expected).abs() < 0.25,
            "{sum} vs {expected}"
        );
        let peak = column_peak(&layer, x);
        assert!((peak - 1.0).abs() < 0.03, "newest peak {peak}");
        assert!((f64::from(peak) - s.opacity_at(u)).abs() < 0.005);
        // The round cap reaches 2.6 px up and down at x = 201.5.
        assert!(column_peak(&layer, 201) > 0.99, "no round cap");

        // Near the oldest end: width 1.5, opacity 0.2. The brief's "sum ≈ 1.5"
        // is the coverage; alpha is that times the local opacity.
        let x = 22;
        let u = straight_u(x);
        let coverage = f64::from(column_sum(&layer, x)) / s.opacity_at(u);
        assert!((coverage - 1.5).abs() < 0.25, "oldest coverage {coverage}");
        assert!((coverage - 2.0 * s.half_width_at(u)).abs() < 0.25);
        let peak = column_peak(&layer, x);
        assert!((peak - 0.2).abs() < 0.015, "oldest peak {peak}");
        assert!((f64::from(peak) - s.opacity_at(u)).abs() < 0.005);

        // Nothing outside the ribbon's box (round cap to x = 203) + 2 px.
        for y in 0..layer.height {
            for x in 0..layer.width {
                let (cx, cy) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                let inside = (18.0..=205.0).contains(&cx) && (45.5..=55.5).contains(&cy);
                assert!(
                    inside || alpha(&layer, x, y) == 0.0,
                    "stray alpha at {x},{y}"
                );
            }
        }
        // Premultiplied white: every channel equals alpha.
        for px in &layer.pixels {
            assert!(px[..3].iter().all(|&c| (c - px[3]).abs() < 1e-6), "{px:?}");
        }
    }

    #[test]
    fn column_sums_decrease_from_newest_to_oldest() {
        let layer = drawn(&[straight_line(WHITE)], &TAPERED, 240, 100);
        let sums: Vec<f32> = (22..=197)
            .rev()
            .step_by(15)
            .map(|x| column_sum(&layer, x))
            .collect();
        for pair in sums.windows(2) {
            assert!(pair[1] < pair[0], "{sums:?}");
        }
    }

    #[test]
    fn quarter_arc_is_covered_along_the_arc_not_across_the_chord() {
        let (centre, radius) = (DVec2::new(120.0, 120.0), 100.0);
        let at = |f: f64| centre + radius * DVec2::from_angle(-f * std::f64::consts::FRAC_PI_2);
        let line = SpeedLine {
            points: (0..32).map(|i| at(f64::from(i) / 31.0)).collect(),
            colour: WHITE,
        };
        let layer = drawn(&[line], &TAPERED, 240, 240);
        assert_sane(&layer);
        // From just past the butt oldest end to the newest end.
        for i in 1..=40 {
            let f = f64::from(i) / 40.0;
            assert!(alpha_at(&layer, at(f)) > 0.15, "arc gap at f = {f}");
        }
        let (a, b) = (at(0.0), at(1.0));
        for i in 1..10 {
            let q = a.lerp(b, f64::from(i) / 10.0);
            assert_eq!(alpha_at(&layer, q), 0.0, "chord covered at {q}");
        }
    }

    /// On three quarters of a circle the chord's projection (what a linear
    /// gradient would give) is far from the arc length: at a quarter of the
    /// arc it is clamped to 0.
    #[test]
    fn fade_follows_arc_length_not_the_chord() {
        let (centre, radius) = (DVec2::new(100.0, 100.0), 80.0);
        let sweep = 1.5 * std::f64::consts::PI;
        let at = |f: f64| centre + radius * DVec2::from_angle(f * sweep);
        let line = SpeedLine {
            points: (0..64).map(|i| at(f64::from(i) / 63.0)).collect(),
            colour: WHITE,
        };
        let look = LineLook {
            width: 8.0,
            taper: 1.0,
            fade: 0.0,
            opacity: 1.0,
        };
        let layer = drawn(&[line], &look, 200, 200);
        for f in [0.1, 0.25, 0.5, 0.75, 0.9] {
            let got = alpha_at(&layer, at(f));
            assert!((f64::from(got) - f).abs() < 0.01, "f = {f}: alpha {got}");
        }
    }

    /// A path that goes out and comes straight back (motion that reverses), and one whose thin
    /// old part runs 6 px beside its wide new part (a hairpin): each pixel that only the new part
    /// covers takes the new part's opacity, however close the old part's centre line is.
    #[test]
    fn a_thin_old_part_beside_or_under_a_wide_new_part_leaves_it_opaque() {
        let look = LineLook {
            width: 12.0,
            taper: 0.1,
            fade: 0.0,
            opacity: 1.0,
        };
        let s = style(&look);
        let back = SpeedLine {
            points: vec![
                DVec2::new(20.0, 50.5),
                DVec2::new(180.0, 50.5),
                DVec2::new(20.0, 50.5),
            ],
            colour: WHITE,
        };
        let layer = drawn(&[back], &look, 200, 100);
        // On the way back at x = 25.5, near the newest end.
        let u = (160.0 + 154.5) / 320.0;
        let got = alpha(&layer, 25, 50);
        assert!((f64::from(got) - s.opacity_at(u)).abs() < 0.01, "{got}");

        let hairpin = SpeedLine {
            points: vec![
                DVec2::new(180.0, 56.0),
                DVec2::new(20.0, 56.0),
                DVec2::new(20.0, 50.0),
                DVec2::new(180.0, 50.0),
            ],
            colour: WHITE,
        };
        let layer = drawn(&[hairpin], &look, 200, 100);
        // At x = 150.5 the new part (u ≈ 0.91) is 5.5 px wide each way, to y = 55.5, and the
        // old part (u ≈ 0.09) 1.1 px, from y = 54.9: rows 53 and 54 are the new part's alone.
        let u = (166.0 + 130.5) / 326.0;
        for y in [53, 54] {
            let got = alpha(&layer, 150, y);
            assert!(
                (f64::from(got) - s.opacity_at(u)).abs() < 0.01,
                "row {y}: {got}"
            );
        }
    }

    #[test]
    fn overlapping_lines_composite_over() {
        let look = uniform(6.0, 0.6);
        let red = SpeedLine {
            points: vec![DVec2::new(10.0, 50.5), DVec2::new(90.0, 50.5)],
            colour: [1.0, 0.0, 0.0],
        };
        let green = SpeedLine {
            points: vec![DVec2::new(50.5, 10.0), DVec2::new(50.5, 90.0)],
            colour: [0.0, 1.0, 0.0],
        };
        let layer = drawn(&[red, green], &look, 100, 100);
        let px = |x: u32, y: u32| layer.pixels[(y * 100 + x) as usize];
        // Red alone: colour × alpha.
        let only_red = px(20, 50);
        assert!(only_red
            .iter()
            .zip([0.6, 0.0, 0.0, 0.6])
            .all(|(a, b)| (a - b).abs() < 1e-6));
        // Green over red: src + (1 − α_src)·dst.
        let (a, red_under) = (0.6_f32, [0.6_f32, 0.0, 0.0, 0.6]);
        let green_src = [0.0, 0.6, 0.0, 0.6];
        let both = px(50, 50);
        for c in 0..4 {
            let expected = green_src[c] + (1.0 - a) * red_under[c];
            assert!((both[c] - expected).abs() < 1e-6, "{both:?}");
        }
    }

    #[test]
    fn the_layer_shows_background_where_clear_and_colour_where_opaque() {
        let colour = [0.9, 0.1, 0.5];
        let look = uniform(6.0, 1.0);
        // The top edge at y = 47.25 leaves row 47 partly covered.
        let line = SpeedLine {
            points: vec![DVec2::new(10.0, 50.25), DVec2::new(90.0, 50.25)],
            colour,
        };
        let layer = drawn(std::slice::from_ref(&line), &look, 100, 100);
        let background = [0.2, 0.3, 0.4];
        let mut image = Framebuffer::filled(100, 100, background);
        draw_over(&[line], &look, &mut image);
        let image = image.pixels;
        assert_eq!(image[10 * 100 + 50], background);
        for (got, want) in image[50 * 100 + 50].iter().zip(colour) {
            assert!((got - want).abs() < 1e-6);
        }
        let edge = 47 * 100 + 50;
        let a = layer.pixels[edge][3];
        assert!(a > 0.1 && a < 0.9, "row 47 alpha {a}");
        for c in 0..3 {
            let expected = a * colour[c] + (1.0 - a) * background[c];
            assert!((image[edge][c] - expected).abs() < 1e-6);
        }
    }

    /// A 176° bend, a full reversal, and a hairpin through a segment shorter
    /// than the half width. A miter would spike ~115 px out, per-segment
    /// strokes would double alpha at the joints, and a wrong winding or inner
    /// join would leave holes near the bends.
    #[test]
    fn sharp_bends_have_no_spikes_no_doubling_and_no_holes() {
        let points = vec![
            DVec2::new(20.0, 30.0),
            DVec2::new(150.0, 30.0),
            DVec2::new(30.0, 38.5),
            DVec2::new(150.0, 47.0),
            DVec2::new(150.0, 80.0),
            DVec2::new(40.0, 80.0),
            DVec2::new(150.0, 80.0),
            DVec2::new(100.0, 80.0),
            DVec2::new(100.0, 100.0),
            DVec2::new(170.0, 100.0),
            DVec2::new(168.0, 103.0),
            DVec2::new(60.0, 105.0),
        ];
        let look = uniform(8.0, 0.5);
        let line = SpeedLine {
            points: points.clone(),
            colour: WHITE,
        };
        let layer = drawn(&[line], &look, 200, 130);
        assert_sane(&layer);
        for y in 0..layer.height {
            for x in 0..layer.width {
                let q = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                let distance = distance_to_polyline(&points, q);
                let a = alpha(&layer, x, y);
                assert!(a <= 0.5 + 1e-6, "doubled alpha {a} at {q}");
                assert!(distance <= 4.0 + AA_REACH_PX || a == 0.0, "spike at {q}");
                // Well inside, away from the butt oldest end: fully covered.
                if distance <= 4.0 - 1.0 && q.distance(points[0]) > 5.0 {
                    assert!((a - 0.5).abs() < 1e-6, "hole: alpha {a} at {q}");
                }
            }
        }
    }

    /// Random polylines with short segments and near-reversals, against the
    /// ideal stroke (all points within the half width of the centre line):
    /// well inside is fully covered once, well outside is clear.
    #[test]
    fn random_polylines_cover_exactly_their_stroke() {
        let mut random = crate::math::test_sequence(0x5eed);
        let size = 120;
        for _ in 0..40 {
            let mut points = vec![DVec2::new(40.0 + 40.0 * random(), 40.0 + 40.0 * random())];
            let mut heading = std::f64::consts::TAU * random();
            for _ in 0..2 + (6.0 * random()) as usize {
                // Turn back: a full reversal ± 0.75 rad.
                heading += std::f64::consts::PI + 1.5 * (random() - 0.5);
                let step = if random() < 0.5 {
                    0.2 + 3.0 * random()
                } else {
                    5.0 + 30.0 * random()
                };
                points.push(*points.last().unwrap() + step * DVec2::from_angle(heading));
            }
            let look = LineLook {
                width: 4.0 + 12.0 * random(),
                taper: 1.0,
                fade: 1.0,
                opacity: 0.7,
            };
            let line = SpeedLine {
                points: points.clone(),
                colour: WHITE,
            };
            let layer = drawn(&[line], &look, size, size);
            let h = look.width / 2.0;
            for y in 0..size {
                for x in 0..size {
                    let q = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                    let distance = distance_to_polyline(&points, q);
                    let a = alpha(&layer, x, y);
                    assert!(a <= 0.7 + 1e-6, "doubled alpha {a} at {q} in {points:?}");
                    assert!(
                        distance <= h + AA_REACH_PX || a == 0.0,
                        "stray at {q} in {points:?}"
                    );
                    // The butt oldest end does not cover the disc behind it.
                    if distance <= h - 1.0 && q.distance(points[0]) > h + 1.0 {
                        assert!((a - 0.7).abs() < 1e-6, "hole at {q} in {points:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn far_off_screen_line_is_clipped_not_dropped() {
        let line = SpeedLine {
            points: vec![DVec2::new(-1e9, 50.5), DVec2::new(1e9, 50.5)],
            colour: WHITE,
        };
        let layer = drawn(&[line], &TAPERED, 200, 100);
        assert_sane(&layer);
        // Half way along: width 6·(0.25 + 0.75/2) = 3.75, opacity 0.6.
        let sum = column_sum(&layer, 100);
        assert!((sum - 3.75 * 0.6).abs() < 0.25 * 0.6 + 0.01, "sum {sum}");
        assert!((column_peak(&layer, 100) - 0.6).abs() < 0.005);
    }

    #[test]
    fn degenerate_inputs_neither_panic_nor_produce_nan() {
        let p = DVec2::new(30.0, 30.0);
        let bad_lines = [
            vec![],
            vec![p],
            vec![p, p, p],
            vec![p, p + DVec2::splat(1e-9)],
            vec![p, DVec2::new(f64::NAN, 40.0), p + 10.0],
            vec![p, DVec2::new(f64::INFINITY, 40.0)],
            vec![DVec2::new(-1e9, -1e9), DVec2::new(1e9, 1e9)],
            vec![DVec2::new(1e9, 1e9), DVec2::new(1e9 + 50.0, 1e9)],
            vec![DVec2::new(-1e300, 30.0), DVec2::new(1e300, 30.0)],
            vec![DVec2::new(-f64::MAX, 30.0), DVec2::new(f64::MAX, 30.0)],
            vec![p, p + DVec2::X, p, p + DVec2::X, p],
        ];
        let mut lines: Vec<SpeedLine> = bad_lines
            .into_iter()
            .map(|points| SpeedLine {
                points,
                colour: WHITE,
            })
            .collect();
        lines.push(SpeedLine {
            points: vec![p, p + 20.0],
            colour: [f32::NAN, 0.0, 1.0],
        });
        let looks = [
            TAPERED,
            LineLook {
                width: f64::NAN,
                ..TAPERED
            },
            LineLook {
                width: 0.0,
                ..TAPERED
            },
            LineLook {
                width: -3.0,
                ..TAPERED
            },
            LineLook {
                width: 1e12,
                ..TAPERED
            },
            LineLook {
                width: 1e-9,
                ..TAPERED
            },
            LineLook {
                width: 6.0,
                taper: f64::NAN,
                fade: f64::INFINITY,
                opacity: 7.0,
            },
            LineLook {
                taper: 0.0,
                fade: 0.0,
                ..TAPERED
            },
        ];
        for look in &looks {
            for (width, height) in [(64, 48), (0, 48), (64, 0), (1, 1)] {
                assert_sane(&drawn(&lines, look, width, height));
            }
        }
        let huge = drawn(&lines, &TAPERED, u32::MAX, u32::MAX);
        assert!(huge.pixels.is_empty());
        let empty = drawn(&lines, &TAPERED, 0, 100);
        assert_eq!((empty.width, empty.height, empty.pixels.len()), (0, 100, 0));
    }

    /// Speed lines switched off, or drawn with nothing to see, make no layer of the image's
    /// size (README, "What the plan leaves out": they cost nothing).
    #[test]
    fn no_lines_or_an_invisible_look_make_no_layer() {
        let lines = [straight_line(WHITE)];
        let invisible = LineLook {
            opacity: 0.0,
            ..TAPERED
        };
        for (lines, look) in [(&lines[..0], &TAPERED), (&lines[..], &invisible)] {
            let layer = drawn(lines, look, 240, 100);
            assert_eq!(layer.pixels.len(), 0, "{look:?}");
        }
    }

    #[test]
    fn output_is_deterministic() {
        let lines = [
            straight_line([0.3, 0.6, 0.9]),
            SpeedLine {
                points: vec![
                    DVec2::new(5.0, 90.0),
                    DVec2::new(80.0, 10.0),
                    DVec2::new(150.0, 95.0),
                ],
                colour: [0.9, 0.2, 0.1],
            },
        ];
        let bits = |layer: Strokes| -> Vec<u32> {
            layer.pixels.iter().flatten().map(|c| c.to_bits()).collect()
        };
        let first = bits(drawn(&lines, &TAPERED, 240, 100));
        assert_eq!(first, bits(drawn(&lines, &TAPERED, 240, 100)));
        assert!(first.iter().any(|&b| b != 0));
    }

    /// A straight line sampled at 64 points is drawn as one segment: it looks as the line through
    /// its two ends (within one of tiny-skia's 16 coverage levels at its edges) and tests its
    /// pixels as often; at 1,001 points, as 16 chords of 64 segments and one of 40. A bend keeps
    /// its corner, and so does a line turning back over itself.
    #[test]
    fn a_straight_run_is_one_segment_and_a_bend_keeps_its_corner() {
        let look = LineLook {
            width: 30.0,
            ..TAPERED
        };
        let ends = [DVec2::new(20.0, 30.5), DVec2::new(180.0, 70.5)];
        let sampled = |count: u32| -> Vec<DVec2> {
            (0..count)
                .map(|i| ends[0].lerp(ends[1], f64::from(i) / f64::from(count - 1)))
                .collect()
        };
        let line = |points: Vec<DVec2>| SpeedLine {
            points,
            colour: WHITE,
        };
        let (two, two_work) = strokes(&[line(ends.to_vec())], &look, 200, 100, u64::MAX);
        let (many, many_work) = strokes(&[line(sampled(65))], &look, 200, 100, u64::MAX);
        assert_eq!(many_work, two_work);
        for (a, b) in two.pixels.iter().zip(&many.pixels) {
            assert!((a[3] - b[3]).abs() <= 1.0 / 16.0 + 1e-6, "{a:?} {b:?}");
        }
        assert_eq!(centre_line(&sampled(1001), 15.0).unwrap().len(), 17);

        // 0.005 px off the chord, but turning by 0.005 rad: 0.075 px at 15 px out.
        let corner = [
            DVec2::new(100.0, 50.5),
            DVec2::new(101.0, 50.505),
            DVec2::new(102.0, 50.5),
        ];
        assert_eq!(centre_line(&corner, 15.0).unwrap().len(), 3);
        assert_eq!(centre_line(&corner, 0.5).unwrap().len(), 2);
        let back = [ends[0], ends[1], ends[0].lerp(ends[1], 0.5)];
        assert_eq!(centre_line(&back, 0.5).unwrap().len(), 3, "turning back");
    }

    /// Lines drawn front to back: pixels an opaque line on top has spent test no line below, and
    /// the layer is the same as the top line's alone.
    #[test]
    fn lines_under_an_opaque_line_cost_no_pixel_tests() {
        let look = uniform(30.0, 1.0);
        // The top line goes out and back 10 px lower: opaque from y = 30.5 to 70.5.
        let top = SpeedLine {
            points: vec![
                DVec2::new(20.0, 45.5),
                DVec2::new(180.0, 45.5),
                DVec2::new(180.0, 55.5),
                DVec2::new(20.0, 55.5),
            ],
            colour: [0.2, 0.9, 0.4],
        };
        // Shorter lines within it, in slice order before it.
        let under = SpeedLine {
            points: vec![DVec2::new(60.0, 50.5), DVec2::new(140.0, 50.5)],
            colour: [0.9, 0.1, 0.1],
        };
        let mut lines = vec![under; 50];
        lines.push(top.clone());
        let (alone, alone_work) = strokes(&[top], &look, 200, 100, u64::MAX);
        let (all, all_work) = strokes(&lines, &look, 200, 100, u64::MAX);
        assert!(all.pixels == alone.pixels);
        assert_eq!(all_work.tests, alone_work.tests);
        assert!(all_work.mask_pixels > alone_work.mask_pixels);
    }

    /// Out of budget, the lowest lines are left out and the one drawn when it ran out is cut,
    /// and the lines drawn are drawn as without a budget.
    #[test]
    fn a_spent_budget_leaves_out_the_lowest_lines_and_says_so() {
        let look = LineLook {
            width: 4.0,
            ..TAPERED
        };
        let lines: Vec<SpeedLine> = (0..10)
            .map(|i| SpeedLine {
                points: vec![
                    DVec2::new(10.0, 5.5 + 10.0 * f64::from(i)),
                    DVec2::new(190.0, 5.5 + 10.0 * f64::from(i)),
                ],
                colour: WHITE,
            })
            .collect();
        let (whole, work) = strokes(&lines, &look, 200, 100, u64::MAX);
        assert_eq!((work.left_out, work.cut), (0, false));
        let per_line = (work.tests + work.mask_pixels) / 10;
        let (part, cut) = strokes(&lines, &look, 200, 100, 5 * per_line / 2);
        assert!(cut.cut, "{cut:?}");
        assert_eq!(cut.left_out, 7, "{cut:?}");
        // The top two lines (the last two) are drawn whole, the lowest seven not at all.
        let rows = |layer: &Strokes, ys: std::ops::Range<u32>| -> Vec<f32> {
            ys.flat_map(|y| (0..200).map(move |x| (x, y)))
                .map(|(x, y)| alpha(layer, x, y))
                .collect()
        };
        assert_eq!(rows(&part, 80..100), rows(&whole, 80..100));
        assert!(rows(&part, 0..70).iter().all(|&a| a == 0.0));
        assert!(rows(&whole, 0..70).iter().any(|&a| a > 0.0));
    }
}
