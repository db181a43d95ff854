//! Interval lists and their resolve (Gribel et al. 2010; Palmér §2.1, Fig. 2.1): a spatial
//! sample collects, from every triangle that covers it, the times it covers it with the depth
//! over that time (linear pieces); the resolve sweeps the exposure and keeps, at every instant,
//! only the nearest piece.

/// Two pieces of one item join when the joined line misses their meeting depth by at most this
/// share of it.
pub const JOIN_TOLERANCE: f64 = 1e-9;

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
}

/// A list's interval as it is: for lists whose depths are already linear pieces.
pub fn as_is(interval: &Interval, out: &mut Vec<Interval>) {
    out.push(*interval);
}

/// The visible pieces of `intervals` (each an interval over which its item is nearest), in time
/// order, appended to `out`; adjacent pieces of the same item are joined (Gribel's compression of
/// one surface's pieces). Where intervals overlap in time and some bend, `pieces` first cuts each
/// into the linear depth pieces the sweep compares (a list in time order without overlaps needs
/// no depth, and is returned as it is).
///
/// The interval ends cut the exposure into spans over which the set of active pieces is fixed
/// (kept incrementally as the sweep passes starts and ends), and each piece is a line in time:
/// their lower envelope is found by starting from the nearest at the span's start and stepping to
/// the earliest line that crosses below the current one, so a span with k active pieces costs
/// O(k²) and yields at most k visible pieces.
pub fn resolve(
    intervals: &[Interval],
    scratch: &mut ResolveScratch,
    out: &mut Vec<Interval>,
    pieces: impl Fn(&Interval, &mut Vec<Interval>),
) {
    if intervals
        .windows(2)
        .all(|pair| pair[0].t[1] <= pair[1].t[0])
    {
        // Already in time order without overlaps (one interval, or one surface's pieces over
        // consecutive sub-segments): what the sweep below gives, without its sorting.
        let first = out.len();
        for interval in intervals.iter().filter(|i| i.t[1] > i.t[0]) {
            push_visible(out, first, interval, interval.t);
        }
        return;
    }
    let ResolveScratch {
        events,
        by_start,
        active,
        pieces: cut,
    } = scratch;
    let intervals = if intervals.iter().any(|i| i.bends) {
        cut.clear();
        for interval in intervals {
            pieces(interval, cut);
        }
        &cut[..]
    } else {
        intervals
    };
    events.clear();
    for i in intervals {
        events.extend_from_slice(&i.t);
    }
    events.sort_unstable_by(f64::total_cmp);
    events.dedup();
    by_start.clear();
    by_start.extend(0..intervals.len() as u32);
    by_start.sort_unstable_by(|&a, &b| {
        intervals[a as usize].t[0].total_cmp(&intervals[b as usize].t[0])
    });
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
            // The earliest time in (start, v) at which another line passes below the current one.
            let (z, slope) = (current.depth_at(start), current.slope());
            let mut next: Option<(f64, &Interval)> = None;
            for other in pieces() {
                let gap = other.depth_at(start) - z;
                let closing = slope - other.slope();
                if closing > 0.0 && gap >= 0.0 {
                    let when = start + gap / closing;
                    if when > start && when < v && next.is_none_or(|(w, _)| when < w) {
                        next = Some((when, other));
                    }
                }
            }
            let end = next.map_or(v, |(w, _)| w);
            push_visible(out, first_out, current, [start, end]);
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
        let mut out = Vec::new();
        resolve(intervals, &mut ResolveScratch::default(), &mut out, as_is);
        out
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
        let (blue, still) = blue_and_red();
        let bent = Interval {
            bends: true,
            ..blue
        };
        let pieces = |interval: &Interval, out: &mut Vec<Interval>| {
            if interval.bends {
                for (t, depth) in [([0.0, 0.5], [1.0, 1.4]), ([0.5, 1.0], [1.4, 3.0])] {
                    out.push(line(t, depth, interval.item));
                }
            } else {
                out.push(*interval);
            }
        };
        let mut out = Vec::new();
        resolve(
            &[still, bent],
            &mut ResolveScratch::default(),
            &mut out,
            pieces,
        );
        assert_eq!(out.len(), 3, "{out:?}");
        assert_eq!(out.iter().map(|p| p.item).collect::<Vec<_>>(), [0, 0, 1]);
        assert!((out[1].t[1] - 0.6875).abs() < 1e-12 && out[2].t == [out[1].t[1], 1.0]);
        // Alone, it overlaps nothing: no depth is compared, and it stays one line.
        out.clear();
        resolve(&[bent], &mut ResolveScratch::default(), &mut out, pieces);
        assert_eq!(out, [bent]);
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
}
