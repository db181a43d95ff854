//! Interval lists and their resolve (Gribel et al. 2010; Palmér §2.1, Fig. 2.1): a spatial
//! sample collects, from every triangle that covers it, the times it covers it with the depth
//! over that time (linear pieces); the resolve sweeps the exposure and keeps, at every instant,
//! only the nearest piece.

/// Two pieces of one item join when the joined line misses their meeting depth by at most this
/// share of it.
pub const JOIN_TOLERANCE: f64 = 1e-9;

/// Longest list of intervals whose hidden members [`resolve`] looks for before sweeping.
const MOST_SCANNED_FOR_HIDDEN: usize = 32;

/// One linear piece of a surface's depth over a time interval at one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Start and end time.
    pub t: [f64; 2],
    /// Depth at the start and at the end.
    pub depth: [f64; 2],
    /// What covers the sample then (the renderer's triangle item).
    pub item: u32,
    /// Whether the depth strays from the line between the ends by more than the renderer's
    /// tolerance: held as that line until something needs its linear pieces.
    pub bends: bool,
}

impl Interval {
    /// The depth at time t (on the piece's line).
    #[must_use]
    pub fn depth_at(&self, t: f64) -> f64 {
        let span = self.t[1] - self.t[0];
        if span > 0.0 {
            self.depth[0] + (self.depth[1] - self.depth[0]) * (t - self.t[0]) / span
        } else {
            self.depth[0]
        }
    }

    fn slope(&self) -> f64 {
        let span = self.t[1] - self.t[0];
        if span > 0.0 {
            (self.depth[1] - self.depth[0]) / span
        } else {
            0.0
        }
    }
}

/// Working memory of [`resolve`], reused from sample to sample.
#[derive(Default)]
pub struct ResolveScratch {
    events: Vec<f64>,
    by_start: Vec<u32>,
    active: Vec<u32>,
    pieces: Vec<Interval>,
    ranges: Vec<Option<Option<[f64; 2]>>>,
    layers: Vec<Layer>,
    hidden: Vec<bool>,
    behind: Vec<Interval>,
    kept: Vec<Interval>,
}

/// Where an interval lies in depth against the intervals it overlaps in time, by their depth
/// bounds, when a list is made of two layers ([`two_layers`]).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Layer {
    /// It overlaps nothing.
    Alone,
    /// Nearer than all it overlaps: seen all along.
    Front,
    /// Farther than all it overlaps: seen where none of them is.
    Behind,
}

/// Whether `intervals` form two layers: no instant within three of them, and of every two that
/// overlap, one lies wholly nearer by their depth bounds (`depth`'s where they bend, their lines'
/// ends where not, worked out into `ranges` when first asked for). Then each one's [`Layer`] is
/// in `layers`. `by_start` orders the intervals by start time.
fn two_layers(
    intervals: &[Interval],
    by_start: &[u32],
    depth: &impl BentDepth,
    ranges: &mut Vec<Option<Option<[f64; 2]>>>,
    layers: &mut Vec<Layer>,
) -> bool {
    ranges.clear();
    ranges.resize(intervals.len(), None);
    let mut range = |k: usize| {
        *ranges[k].get_or_insert_with(|| {
            let [a, b] = intervals[k].depth;
            if intervals[k].bends {
                depth.bounds(&intervals[k])
            } else {
                Some([a.min(b), a.max(b)])
            }
        })
    };
    layers.clear();
    layers.resize(intervals.len(), Layer::Alone);
    let mut set = |k: usize, layer: Layer| {
        let ok = layers[k] == Layer::Alone || layers[k] == layer;
        layers[k] = layer;
        ok
    };
    // The intervals still open where the next one starts: with two, it would make a third.
    let mut open: [Option<usize>; 2] = [None; 2];
    for &n in by_start {
        let n = n as usize;
        let [t0, t1] = intervals[n].t;
        if !(t1 > t0) {
            continue;
        }
        for slot in &mut open {
            *slot = slot.filter(|&o| intervals[o].t[1] > t0);
        }
        match open {
            [Some(_), Some(_)] => return false,
            [Some(o), None] | [None, Some(o)] => {
                let (Some([near_o, far_o]), Some([near_n, far_n])) = (range(o), range(n)) else {
                    return false;
                };
                let (front, behind) = if far_o < near_n {
                    (o, n)
                } else if far_n < near_o {
                    (n, o)
                } else {
                    return false;
                };
                if !(set(front, Layer::Front) && set(behind, Layer::Behind)) {
                    return false;
                }
                open = [Some(o), Some(n)];
            }
            [None, None] => open = [Some(n), None],
        }
    }
    layers
        .iter()
        .zip(intervals)
        .all(|(layer, i)| *layer != Layer::Behind || !i.bends)
}

/// The visible pieces of `intervals` in two layers ([`two_layers`]), appended to `out` as
/// [`resolve`] appends them: each front interval whole, each one behind (a line) where no front
/// one covers its time. Fronts overlap no front, nor those behind one another, since each pair
/// that overlaps is one nearer than the other; so both come in time order from `by_start`, the
/// intervals' order by start time, and merge in one pass.
fn resolve_layers(
    intervals: &[Interval],
    by_start: &[u32],
    layers: &[Layer],
    out: &mut Vec<Interval>,
) {
    let first = out.len();
    let in_layer = |behind: bool| {
        by_start.iter().map(|&k| k as usize).filter(move |&k| {
            (layers[k] == Layer::Behind) == behind && intervals[k].t[1] > intervals[k].t[0]
        })
    };
    let mut fronts = in_layer(false).peekable();
    // Where the fronts shown so far end.
    let mut covered_until = f64::NEG_INFINITY;
    for b in in_layer(true) {
        let back = &intervals[b];
        let mut from = back.t[0].max(covered_until);
        while let Some(f) = fronts.next_if(|&f| intervals[f].t[0] < back.t[1]) {
            let front = &intervals[f];
            if front.t[0] > from {
                push_visible(out, first, back, [from, front.t[0]]);
            }
            push_visible(out, first, front, front.t);
            covered_until = front.t[1];
            from = from.max(covered_until);
        }
        if back.t[1] > from {
            push_visible(out, first, back, [from, back.t[1]]);
        }
    }
    for f in fronts {
        push_visible(out, first, &intervals[f], intervals[f].t);
    }
}

/// What [`resolve`] needs of the intervals whose depth bends ([`Interval::bends`]).
pub trait BentDepth {
    /// The linear depth pieces of `interval`, appended to `out` in time order.
    fn pieces(&self, interval: &Interval, out: &mut Vec<Interval>);
    /// Bounds [nearest, farthest] on the depth of `interval` over its span, its ends included;
    /// `None` where none can be had.
    fn bounds(&self, interval: &Interval) -> Option<[f64; 2]>;
}

/// For lists whose depths are already linear pieces: nothing bends.
pub struct AsIs;

impl BentDepth for AsIs {
    fn pieces(&self, interval: &Interval, out: &mut Vec<Interval>) {
        out.push(*interval);
    }

    fn bounds(&self, _: &Interval) -> Option<[f64; 2]> {
        None
    }
}

/// The visible pieces of `intervals` (each an interval over which its item is nearest), in time
/// order, appended to `out`; adjacent pieces of the same item are joined (Gribel's compression of
/// one surface's pieces).
///
/// Three ways, cheapest first: a list in time order without overlaps needs no depth, and is
/// returned as it is; a list in two layers ([`two_layers`]: a moving object over a still floor)
/// shows its front intervals whole, whatever their depth does between its bounds, and the ones
/// behind them where no front one is; any other list is swept ([`sweep`]), each interval that
/// bends first cut into the linear depth pieces the sweep compares (`depth`).
pub fn resolve(
    intervals: &[Interval],
    scratch: &mut ResolveScratch,
    out: &mut Vec<Interval>,
    depth: &impl BentDepth,
) {
    if let [only] = intervals {
        // Most samples: one surface all along.
        if only.t[1] > only.t[0] {
            push_visible(out, out.len(), only, only.t);
        }
        return;
    }
    if intervals
        .windows(2)
        .all(|pair| pair[0].t[1] <= pair[1].t[0])
    {
        // Already in time order without overlaps (one interval, or one surface's pieces over
        // consecutive sub-segments): what the sweep gives, without its sorting.
        let first = out.len();
        for interval in intervals.iter().filter(|i| i.t[1] > i.t[0]) {
            push_visible(out, first, interval, interval.t);
        }
        return;
    }
    order_by_start(intervals, &mut scratch.by_start);
    if two_layers(
        intervals,
        &scratch.by_start,
        depth,
        &mut scratch.ranges,
        &mut scratch.layers,
    ) {
        resolve_layers(intervals, &scratch.by_start, &scratch.layers, out);
        return;
    }
    let mut kept = std::mem::take(&mut scratch.kept);
    // Leaving out what is hidden pays where a few faces meet at an edge (a cube's corner). It
    // compares every pair, and on a long list (many small faces passing the sample) the sweep
    // alone costs less (docs/history.md, "Long lists left to the sweep").
    let left_out = intervals.len() <= MOST_SCANNED_FOR_HIDDEN
        && without_hidden(intervals, depth, scratch, &mut kept);
    let layered = left_out && {
        order_by_start(&kept, &mut scratch.by_start);
        two_layers(
            &kept,
            &scratch.by_start,
            depth,
            &mut scratch.ranges,
            &mut scratch.layers,
        )
    };
    if layered {
        resolve_layers(&kept, &scratch.by_start, &scratch.layers, out);
    }
    scratch.kept = kept;
    if layered {
        return;
    }
    if left_out {
        // The sweep reads the whole list's order.
        order_by_start(intervals, &mut scratch.by_start);
    }
    if intervals.iter().any(|i| i.bends) {
        let mut cut = std::mem::take(&mut scratch.pieces);
        cut.clear();
        for interval in intervals {
            if interval.bends {
                depth.pieces(interval, &mut cut);
            } else {
                cut.push(*interval);
            }
        }
        order_by_start(&cut, &mut scratch.by_start);
        sweep(&cut, scratch, out);
        scratch.pieces = cut;
    } else {
        sweep(intervals, scratch, out);
    }
}

/// `intervals` without those hidden all along behind one other, into `kept`; whether any was
/// left out. An interval is hidden behind a line whose span holds its own where each of its
/// linear depth pieces (`depth`'s where it bends) lies no nearer than the line at both ends, as
/// near as [`JOIN_TOLERANCE`] of the depth allows (two faces that meet at an edge start there at
/// one depth, up to rounding), and somewhere deeper (two coplanar intervals at one depth hide
/// neither): the pieces the sweep would compare. One left out hides no other, so one of two
/// that would hide each other within the tolerance is kept. What is left out could show only
/// within the tolerance: a sliver of time between crossings its rounding makes.
fn without_hidden(
    intervals: &[Interval],
    depth: &impl BentDepth,
    scratch: &mut ResolveScratch,
    kept: &mut Vec<Interval>,
) -> bool {
    let ResolveScratch { hidden, behind, .. } = scratch;
    hidden.clear();
    hidden.resize(intervals.len(), false);
    for (k, i) in intervals.iter().enumerate() {
        if !(i.t[1] > i.t[0]) {
            continue;
        }
        behind.clear();
        for (m, line) in intervals.iter().enumerate() {
            if m == k || hidden[m] || line.bends || line.t[0] > i.t[0] || line.t[1] < i.t[1] {
                continue;
            }
            if behind.is_empty() {
                if i.bends {
                    depth.pieces(i, behind);
                } else {
                    behind.push(*i);
                }
            }
            let mut deeper = false;
            let no_nearer = behind.iter().all(|piece| {
                (0..2).all(|end| {
                    let front = line.depth_at(piece.t[end]);
                    deeper |= piece.depth[end] > front;
                    piece.depth[end] >= front - JOIN_TOLERANCE * front.abs()
                })
            });
            if no_nearer && deeper {
                hidden[k] = true;
                break;
            }
        }
    }
    kept.clear();
    kept.extend(
        intervals
            .iter()
            .zip(hidden.iter())
            .filter(|(_, &hidden)| !hidden)
            .map(|(i, _)| *i),
    );
    kept.len() < intervals.len()
}

/// The indices of `intervals` in order of their start times, into `by_start`.
fn order_by_start(intervals: &[Interval], by_start: &mut Vec<u32>) {
    by_start.clear();
    by_start.extend(0..intervals.len() as u32);
    by_start.sort_unstable_by(|&a, &b| {
        intervals[a as usize].t[0].total_cmp(&intervals[b as usize].t[0])
    });
}

/// [`resolve`] of linear pieces (none bends) by sweeping, `scratch.by_start` their order by
/// start time.
///
/// The interval ends cut the exposure into spans over which the set of active pieces is fixed
/// (kept incrementally as the sweep passes starts and ends), and each piece is a line in time:
/// their lower envelope is found by starting from the nearest at the span's start and stepping to
/// the earliest line that crosses below the current one, so a span with k active pieces costs
/// O(k²) and yields at most k visible pieces.
fn sweep(intervals: &[Interval], scratch: &mut ResolveScratch, out: &mut Vec<Interval>) {
    let ResolveScratch {
        events,
        by_start,
        active,
        ..
    } = scratch;
    events.clear();
    for i in intervals {
        events.extend_from_slice(&i.t);
    }
    events.sort_unstable_by(f64::total_cmp);
    events.dedup();
    active.clear();
    let mut next_start = 0;
    let first_out = out.len();
    for span in events.windows(2) {
        let (u, v) = (span[0], span[1]);
        while next_start < by_start.len() && intervals[by_start[next_start] as usize].t[0] <= u {
            active.push(by_start[next_start]);
            next_start += 1;
        }
        active.retain(|&i| intervals[i as usize].t[1] > u);
        if !(v > u) || active.is_empty() {
            continue;
        }
        let pieces = || active.iter().map(|&i| &intervals[i as usize]);
        // Nearest at u; ties go to the one receding more slowly, which stays nearest just after.
        let Some(mut current) = pieces().min_by(|a, b| {
            a.depth_at(u)
                .total_cmp(&b.depth_at(u))
                .then(a.slope().total_cmp(&b.slope()))
                .then(a.item.cmp(&b.item))
        }) else {
            continue;
        };
        let mut start = u;
        loop {
            // The earliest time in [start, v) at which another line passes below the current
            // one; of several at once, the one receding most slowly, which is nearest just
            // after. One already as near at `start` (lines through one point, or nearer by the
            // rounding of `start`) and receding more slowly takes over at once: each such step
            // lowers the slope, so they end.
            let (z, slope) = (current.depth_at(start), current.slope());
            let mut next: Option<(f64, &Interval)> = None;
            for other in pieces() {
                let gap = other.depth_at(start) - z;
                let closing = slope - other.slope();
                if closing > 0.0 {
                    let when = start + gap.max(0.0) / closing;
                    if when < v
                        && next.is_none_or(|(w, o)| {
                            when < w || (when == w && other.slope() < o.slope())
                        })
                    {
                        next = Some((when, other));
                    }
                }
            }
            let end = next.map_or(v, |(w, _)| w);
            if end > start {
                push_visible(out, first_out, current, [start, end]);
            }
            match next {
                Some((w, other)) => {
                    start = w;
                    current = other;
                }
                None => break,
            }
        }
    }
}

/// Append `interval` visible over `[t0, t1]`, joined to the last piece when it continues it on
/// the same line (the same item, meeting end to end, with its depth where the joined line puts it
/// to within [`JOIN_TOLERANCE`] of the depth): a depth that bends stays in pieces, because shadow
/// maps compare it.
fn push_visible(out: &mut Vec<Interval>, first: usize, interval: &Interval, [t0, t1]: [f64; 2]) {
    let depth = [interval.depth_at(t0), interval.depth_at(t1)];
    if out.len() > first {
        if let Some(last) = out.last_mut() {
            let joined =
                last.depth[0] + (depth[1] - last.depth[0]) * (t0 - last.t[0]) / (t1 - last.t[0]);
            let straight = (joined - depth[0]).abs() <= JOIN_TOLERANCE * depth[0].abs();
            if last.item == interval.item && last.t[1] == t0 && straight {
                last.t[1] = t1;
                last.depth[1] = depth[1];
                last.bends |= interval.bends;
                return;
            }
        }
    }
    out.push(Interval {
        t: [t0, t1],
        depth,
        item: interval.item,
        bends: interval.bends,
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An interval of `item` whose depth is the line between `depth` over `t`.
    fn line(t: [f64; 2], depth: [f64; 2], item: u32) -> Interval {
        Interval {
            t,
            depth,
            item,
            bends: false,
        }
    }

    /// Palmér Fig. 2.1, with a crossing: blue recedes from depth 1 to 3 over [0, 1]; red stays at
    /// depth 2 from t = 0.2 on.
    fn blue_and_red() -> (Interval, Interval) {
        (
            line([0.0, 1.0], [1.0, 3.0], 0),
            line([0.2, 1.0], [2.0, 2.0], 1),
        )
    }

    fn resolved(intervals: &[Interval]) -> Vec<Interval> {
        resolved_with(intervals, &AsIs)
    }

    fn resolved_with(intervals: &[Interval], depth: &impl BentDepth) -> Vec<Interval> {
        let mut out = Vec::new();
        resolve(intervals, &mut ResolveScratch::default(), &mut out, depth);
        out
    }

    /// Blue of [`blue_and_red`] marked as bending ([`BluePieces`]).
    fn bent_blue() -> Interval {
        Interval {
            bends: true,
            ..blue_and_red().0
        }
    }

    #[test]
    fn a_list_in_time_order_resolves_as_the_sweep_resolves_it_shuffled() {
        // One surface over three sub-segments (the first two on one line, so joined), an empty
        // piece, and another surface after a gap.
        let ordered = [
            line([0.0, 0.25], [1.0, 1.5], 0),
            line([0.25, 0.5], [1.5, 2.0], 0),
            line([0.5, 0.5], [2.0, 2.0], 1),
            line([0.5, 0.7], [2.0, 1.0], 0),
            line([0.8, 0.9], [3.0, 3.0], 2),
        ];
        let mut shuffled = ordered;
        shuffled.reverse();
        let out = resolved(&ordered);
        assert_eq!(out, resolved(&shuffled));
        assert_eq!(out.len(), 3, "{out:?}");
        assert_eq!((out[0].t, out[0].depth), ([0.0, 0.5], [1.0, 2.0]));
    }

    #[test]
    fn overlapping_intervals_are_swept_on_their_depth_pieces_and_a_lone_one_is_kept_whole() {
        // Blue held as its line from depth 1 to 3 while its depth bends through 1.4 at t = 0.5,
        // and red: the line would cross 2 at t = 0.5, the bent depth crosses it at
        // 0.5 + 0.5 · 0.6 / 1.6 = 0.6875.
        let (_, still) = blue_and_red();
        let bent = bent_blue();
        let out = resolved_with(&[still, bent], &BluePieces);
        assert_eq!(out.len(), 3, "{out:?}");
        assert_eq!(out.iter().map(|p| p.item).collect::<Vec<_>>(), [0, 0, 1]);
        assert!((out[1].t[1] - 0.6875).abs() < 1e-12 && out[2].t == [out[1].t[1], 1.0]);
        // Alone, it overlaps nothing: no depth is compared, and it stays one line.
        assert_eq!(resolved_with(&[bent], &BluePieces), [bent]);
    }

    /// Blue's depth bending through 1.4 at t = 0.5 (its two linear pieces), bounded by [1, 3].
    struct BluePieces;

    impl BentDepth for BluePieces {
        fn pieces(&self, interval: &Interval, out: &mut Vec<Interval>) {
            for (t, depth) in [([0.0, 0.5], [1.0, 1.4]), ([0.5, 1.0], [1.4, 3.0])] {
                out.push(line(t, depth, interval.item));
            }
        }

        fn bounds(&self, _: &Interval) -> Option<[f64; 2]> {
            Some([1.0, 3.0])
        }
    }

    #[test]
    fn a_bent_interval_nearer_than_all_it_overlaps_stays_whole_and_one_that_may_cross_is_cut() {
        // Behind blue's bounds all along, a still surface at depth 3.5 is hidden while blue
        // covers it: blue stays the one line it was given, and no piece of it is asked for.
        let bent = bent_blue();
        let behind = line([0.2, 1.0], [3.5, 3.5], 1);
        assert_eq!(resolved_with(&[behind, bent], &BluePieces), [bent]);
        // At depth 2.9, within blue's bounds, it is crossed at t = 0.96875: blue is cut.
        let crossed = line([0.2, 1.0], [2.9, 2.9], 1);
        let out = resolved_with(&[crossed, bent], &BluePieces);
        assert_eq!(out.len(), 3, "{out:?}");
        assert_eq!((out[0].depth, out[1].item, out[2].item), ([1.0, 1.4], 0, 1));
        assert!((out[2].t[0] - 0.96875).abs() < 1e-12, "{out:?}");
        // At depth 3, on blue's farthest bound, it might be crossed: blue is cut, and wholly
        // nearer than it anyway (only a line is taken to hide what lies behind it).
        let touching = line([0.2, 1.0], [3.0, 3.0], 1);
        let out = resolved_with(&[touching, bent], &BluePieces);
        assert_eq!(out.len(), 2, "{out:?}");
        assert_eq!((out[0].depth, out[1].depth), ([1.0, 1.4], [1.4, 3.0]));
    }

    #[test]
    fn a_face_met_at_its_edge_behind_the_face_in_front_is_left_out_and_the_rest_in_two_layers() {
        // The sample passes a cube's edge at t = 0.25: the top face (a line at depth 2) and a
        // side face turning towards the eye (from 2 to 2.5, met two ulps nearer at the edge by
        // rounding) start there together, over a floor at depth 5. Three at once, so not two
        // layers; without the side face they are, and the floor shows where the top face is
        // not.
        let floor = line([0.0, 1.0], [5.0, 5.0], 0);
        let top = line([0.25, 0.75], [2.0, 2.0], 1);
        let side = |start: f64| Interval {
            bends: true,
            ..line([0.25, 0.5], [start, 2.5], 2)
        };
        let expected = [
            line([0.0, 0.25], [5.0, 5.0], 0),
            top,
            line([0.75, 1.0], [5.0, 5.0], 0),
        ];
        let edge = 2.0 - 2.0 * f64::EPSILON;
        assert_eq!(resolved_with(&[side(edge), floor, top], &AsIs), expected);
        // Nearer by more than rounding at the edge, the side face shows until it crosses the
        // top face, a sixth of its span later: swept.
        let out = resolved_with(&[side(1.9), floor, top], &AsIs);
        assert_eq!(out.len(), 4, "{out:?}");
        assert_eq!((out[1].item, out[2].item), (2, 1));
        assert!((out[1].t[1] - (0.25 + 0.25 / 6.0)).abs() < 1e-12, "{out:?}");
    }

    #[test]
    fn leaving_out_hidden_intervals_keeps_every_surface_s_visible_time() {
        // Random lines, some starting where and at the depth another starts (a cube's faces
        // met at their edge), many hidden behind others: each item is seen as long as the
        // sweep of the whole list shows it, to rounding.
        let mut random = crate::math::test_sequence(2014);
        let mut left_out = 0;
        for _ in 0..500 {
            let mut list: Vec<Interval> = Vec::new();
            for item in 0..6 {
                let interval = match list.last() {
                    Some(last) if random() < 0.4 => {
                        let end = last.t[0] + (last.t[1] - last.t[0]) * random();
                        line(
                            [last.t[0], end],
                            [last.depth[0], 1.0 + 3.0 * random()],
                            item,
                        )
                    }
                    _ => {
                        let start = random() * 0.8;
                        let end = start + random() * (1.0 - start);
                        line([start, end], [0, 1].map(|_| 1.0 + 3.0 * random()), item)
                    }
                };
                list.push(interval);
            }
            let mut scratch = ResolveScratch::default();
            let mut kept = Vec::new();
            left_out += usize::from(without_hidden(&list, &AsIs, &mut scratch, &mut kept));
            let seen = |out: &[Interval], item: u32| -> f64 {
                out.iter()
                    .filter(|p| p.item == item)
                    .map(|p| p.t[1] - p.t[0])
                    .sum()
            };
            let resolved = resolved(&list);
            let mut swept = Vec::new();
            order_by_start(&list, &mut scratch.by_start);
            sweep(&list, &mut scratch, &mut swept);
            for item in 0..6 {
                let (a, b) = (seen(&resolved, item), seen(&swept, item));
                assert!(
                    (a - b).abs() < 1e-9,
                    "item {item}: {a} against {b} in {list:?}"
                );
            }
        }
        assert!(left_out > 100, "{left_out}");
    }

    #[test]
    fn a_list_in_two_layers_resolves_as_the_sweep_resolves_it() {
        // Random lists of two layers: fronts back to back or apart at depths within [1, 2],
        // behind them lines within [3, 4]; some touch end to end, some last no time. The layers'
        // shortcut must give the sweep's pieces exactly.
        let mut random = crate::math::test_sequence(2010);
        let mut layered = 0;
        for _ in 0..500 {
            let mut list = Vec::new();
            for (layer, depths) in [(0, [1.0, 2.0]), (1, [3.0, 4.0])] {
                let mut t = random() * 0.3;
                while t < 1.0 {
                    let end = if random() < 0.1 {
                        t
                    } else {
                        t + random() * 0.4
                    };
                    let depth = [0, 1].map(|_| depths[0] + random() * (depths[1] - depths[0]));
                    let item = list.len() as u32 + 100 * layer;
                    list.push(line([t, end], depth, item));
                    t = if random() < 0.3 {
                        end
                    } else {
                        end + random() * 0.2
                    };
                }
            }
            list.sort_by_key(|_| (random() * 1e6) as u64);
            let mut scratch = ResolveScratch::default();
            order_by_start(&list, &mut scratch.by_start);
            if two_layers(
                &list,
                &scratch.by_start,
                &AsIs,
                &mut scratch.ranges,
                &mut scratch.layers,
            ) {
                layered += 1;
            }
            let mut swept = Vec::new();
            sweep(&list, &mut scratch, &mut swept);
            assert_eq!(resolved(&list), swept, "{list:?}");
        }
        // Most lists have no instant within three intervals.
        assert!(layered > 250, "{layered}");
    }

    #[test]
    fn three_intervals_at_one_instant_or_layers_that_meet_in_depth_are_swept() {
        let front = line([0.0, 1.0], [1.0, 1.0], 0);
        let behind = line([0.0, 1.0], [3.0, 3.0], 1);
        let mut scratch = ResolveScratch::default();
        let mut layers = |list: &[Interval]| {
            order_by_start(list, &mut scratch.by_start);
            two_layers(
                list,
                &scratch.by_start,
                &AsIs,
                &mut scratch.ranges,
                &mut scratch.layers,
            )
        };
        assert!(layers(&[behind, front]));
        // A third at once: one of them could be between the others.
        assert!(!layers(&[behind, front, line([0.4, 0.6], [2.0, 2.0], 2)]));
        // Two whose depths' bounds meet: who is nearer changes with time.
        assert!(!layers(&[behind, line([0.0, 1.0], [1.0, 3.0], 2)]));
        // A bent interval without bounds cannot be placed.
        assert!(!layers(&[
            Interval {
                bends: true,
                ..front
            },
            behind
        ]));
    }

    #[test]
    fn two_surfaces_crossing_in_depth_each_get_their_visible_time() {
        // Blue is nearer until it passes depth 2 at t = 0.5.
        let (blue, red) = blue_and_red();
        for list in [[blue, red], [red, blue]] {
            let out = resolved(&list);
            assert_eq!(out.len(), 2, "{out:?}");
            assert_eq!((out[0].item, out[1].item), (0, 1));
            assert!((out[0].t[0] - 0.0).abs() < 1e-12 && (out[0].t[1] - 0.5).abs() < 1e-12);
            assert!((out[1].t[0] - 0.5).abs() < 1e-12 && (out[1].t[1] - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn a_hidden_interval_leaves_nothing_and_gaps_stay_gaps() {
        let near = line([0.0, 0.4], [1.0, 1.0], 0);
        let far = line([0.1, 0.3], [5.0, 5.0], 1);
        let late = line([0.6, 0.9], [5.0, 4.0], 2);
        let out = resolved(&[far, late, near]);
        assert_eq!(out.len(), 2, "{out:?}");
        assert_eq!(out[0].t, [0.0, 0.4]);
        assert_eq!(out[0].item, 0);
        assert_eq!(out[1].t, [0.6, 0.9]);
    }

    /// Three lines through one point (t = 0.5, depth 2): after it the steepest is nearest. The
    /// sweep steps from the flat one to whichever crossing it meets first in the active order,
    /// and from there never sees the other (its gap at the crossing is 0).
    #[test]
    fn three_lines_through_one_point_hand_over_to_the_steepest() {
        let flat = line([0.0, 1.0], [2.0, 2.0], 0);
        let steep = line([0.0, 1.0], [3.0, 1.0], 1);
        let mild = line([0.0, 1.0], [2.5, 1.5], 2);
        for list in [
            [flat, steep, mild],
            [flat, mild, steep],
            [mild, steep, flat],
            [steep, mild, flat],
        ] {
            let out = resolved(&list);
            let last = out.last().unwrap();
            assert_eq!(last.item, 1, "{list:?} -> {out:?}");
            assert!((last.t[0] - 0.5).abs() < 1e-12, "{out:?}");
        }
    }
}
