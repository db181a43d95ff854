//! Per-pixel compositing of depth-sorted footprints, in bins of shutter time.
//!
//! The ternary depth test groups footprints into surfaces (a footprint within the larger of its
//! own and the open group's depth tolerance of the group's depth belongs to it; in time bins a
//! footprint's faint tail has no say in it); a group's colour is the normalized Σwc/Σw, each
//! member's w counted for the share of its time the groups in front leave it seen, and the share
//! of the pixel it covers is counted per time bin: it hides what lies behind it only in the bins
//! in which it covers the pixel, so that time-disjoint coverage of a sliding surface adds up
//! instead of stacking as transparent layers. With one bin (an instant) this is plain
//! front-to-back compositing with α = opacity(Σw). Why bins, with the measurements: docs/math.md,
//! "Time bins for coverage".

use super::{ceil_small, floor_small, larger, opacity, smaller, Footprint, Passage};
use crate::scene::shutter::Shutter;

/// Once this share of the exposure is left unoccluded at a pixel, farther surfaces cannot change
/// its 8-bit value.
const OPAQUE_REMAINDER: f32 = 1e-4;

/// The visible surface of a pixel is the first that leaves less than this share unoccluded.
const VISIBLE_REMAINDER: f32 = 0.5;

/// A footprint whose profile at a pixel is below this share of its peak is faint there: it has
/// no say in which footprints form a surface ([`PixelState::add`]; docs/math.md, "Faint
/// footprints").
pub(super) const FAINT_VALUE: f32 = 0.05;

/// The exposure cut into `B` equal bins of time, with the shutter's mass in each. Times are
/// exposure times ([`super::TimeExtent`]): 0 at shutter open, 1 at close.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeBins<const B: usize> {
    start: f32,
    bins_per_time: f32,
    mass: [f32; B],
    /// The mass of the bins before each: Σ mass[..b].
    mass_before: [f32; B],
}

impl TimeBins<1> {
    /// One bin holding the whole exposure: for instants, where every footprint covers all of it.
    pub const INSTANT: TimeBins<1> = TimeBins {
        start: 0.0,
        bins_per_time: 1.0,
        mass: [1.0],
        mass_before: [0.0],
    };
}

impl<const B: usize> TimeBins<B> {
    /// `B` bins over the open interval of `shutter`, weighted by its shape.
    #[must_use]
    pub fn over(shutter: &Shutter) -> Self {
        let step = shutter.duration() / B as f64;
        let mass: [f64; B] = std::array::from_fn(|b| {
            let t0 = shutter.open + step * b as f64;
            shutter.mass(t0, t0 + step)
        });
        TimeBins {
            start: 0.0,
            bins_per_time: B as f32,
            mass: mass.map(|m| m as f32),
            mass_before: std::array::from_fn(|b| mass[..b].iter().sum::<f64>() as f32),
        }
    }
}

/// The bins that the time window [lo, hi] overlaps.
fn bin_span<const B: usize>([lo, hi]: [f32; 2], bins: &TimeBins<B>) -> BinSpan {
    let end = B as f32;
    let u0 = smaller(larger((lo - bins.start) * bins.bins_per_time, 0.0), end);
    let u1 = smaller(larger((hi - bins.start) * bins.bins_per_time, 0.0), end);
    let first = floor_small(u0).min(B - 1);
    let last = ceil_small(u1).clamp(first + 1, B);
    BinSpan {
        first,
        last,
        u0,
        u1,
    }
}

/// The depth of a footprint's surface at a pixel in each bin of `span`, at the bin's middle time
/// (the first bin's, and the step from one bin to the next): every footprint is compared there,
/// so two of one surface's footprints passing the pixel at different times of one bin agree
/// (docs/math.md, "Depth along a motion footprint").
#[inline(always)]
fn depths_in_bins<const B: usize>(
    passage: &Passage,
    span: &BinSpan,
    bins: &TimeBins<B>,
) -> (f32, f32) {
    if passage.depth_rate == 0.0 {
        return (passage.depth, 0.0);
    }
    let width = 1.0 / bins.bins_per_time;
    let middle = bins.start + (span.first as f32 + 0.5) * width;
    (passage.depth_then(middle), passage.depth_rate * width)
}

/// A group's coverage beyond full and what its bins not full hold, tallied bin by bin
/// ([`PixelState::spill_overflow`]).
#[derive(Default)]
struct Overflow {
    excess: f32,
    held: f32,
}

impl Overflow {
    /// Count a bin holding `coverage` of its `mass`; whether it is beyond full.
    #[inline]
    fn count(&mut self, coverage: f32, mass: f32) -> bool {
        if coverage > mass {
            self.excess += coverage - mass;
            return true;
        }
        if coverage < mass {
            self.held += coverage;
        }
        false
    }

    /// Whether the excess can be spilled into the bins not full.
    fn spills(&self) -> bool {
        self.excess > 1e-6 && self.held > 0.0
    }
}

/// Front-to-back compositing state of one pixel.
#[derive(Clone, Copy)]
pub(super) struct PixelState<const B: usize> {
    colour: [f32; 3],
    /// Per bin, the fraction not yet hidden by nearer surfaces.
    transmittance: [f32; B],
    /// Σ transmittance · mass: the share of the exposure still unoccluded.
    remaining: f32,
    /// Depth of the group that first left less than [`VISIBLE_REMAINDER`] unoccluded.
    front_depth: f32,
    /// The open group's members.
    group: Members<B>,
    /// Faint footprints that met the open group off its surface, held aside to join the next
    /// group (docs/math.md, "Faint footprints").
    held: Members<B>,
    /// Per bin, the depth and tolerance the group's chain of footprints has reached there (∞ where
    /// none covers it): the surface's depth at that time.
    group_depth: [f32; B],
    group_tolerance: [f32; B],
}

/// What the footprints counted into one group add up to at a pixel.
#[derive(Clone, Copy)]
struct Members<const B: usize> {
    /// Σ w · seen · colour over the members ([`PixelState::add`]).
    colour: [f32; 3],
    /// Light added by additive members.
    emission: [f32; 3],
    /// Σ w · seen: what `colour` is normalized by.
    weight: f32,
    /// The deepest member's depth at the pixel: the group's depth where it has no chain.
    deepest: f32,
    coverage: [f32; B],
    /// Per bin, the change from the bin before in the coverage per unit of mass over the bins
    /// that footprints' time windows cover whole: [`Self::deposit`] marks a run of whole bins at
    /// its two ends, and closing the group sums the marks into `coverage`
    /// ([`Self::settle_whole_bins`]).
    whole_bins: [f32; B],
    /// The bins the members touch, [first, last): the only ones closing the group must visit.
    bins: [usize; 2],
}

/// Where [`PixelState::add`] counted a footprint, for [`PixelState::add_colour_change`].
#[derive(Clone, Copy)]
pub(super) struct Counted {
    /// The share of its time window that the groups in front leave unoccluded (0 when left
    /// out; 1 with one bin, where every member of a group sees the same).
    seen: f32,
    held: bool,
}

/// The bins a footprint's time window overlaps, and the window in bin units.
struct BinSpan {
    first: usize,
    last: usize,
    u0: f32,
    u1: f32,
}

impl BinSpan {
    /// The bins, [first, last).
    #[inline]
    fn bins(&self) -> std::ops::Range<usize> {
        self.first..self.last
    }

    /// Overlap × shutter mass in the first and the last bin, where the window spans two bins or
    /// more: it covers the first from u0 and the last up to u1, and every bin between them whole.
    /// `None` for a window within one bin (or too short to spread).
    #[inline]
    fn end_masses<const B: usize>(&self, bins: &TimeBins<B>) -> Option<[f32; 2]> {
        let Self {
            first,
            last,
            u0,
            u1,
        } = *self;
        if last == first + 1 || u1 - u0 < 1e-4 {
            return None;
        }
        Some([
            larger(first as f32 + 1.0 - u0, 0.0) * bins.mass[first],
            larger(u1 - (last - 1) as f32, 0.0) * bins.mass[last - 1],
        ])
    }
}

impl<const B: usize> PixelState<B> {
    pub(super) const EMPTY: Self = PixelState {
        colour: [0.0; 3],
        transmittance: [1.0; B],
        remaining: 1.0,
        front_depth: f32::INFINITY,
        group: Members::EMPTY,
        held: Members::EMPTY,
        group_depth: [f32::INFINITY; B],
        group_tolerance: [0.0; B],
    };

    /// Whether nothing behind can show any more.
    #[inline]
    pub(super) fn is_opaque(&self) -> bool {
        self.remaining < OPAQUE_REMAINDER
    }

    /// Add footprint `f` with weight `w` at this pixel, (x, y); `faint` when its profile there is
    /// below [`FAINT_VALUE`] of its peak.
    ///
    /// The ternary depth test is made per time bin, against the surface's depth in that bin, each
    /// at the bin's middle time: `f` belongs to the open group when, in every bin its time window
    /// overlaps, it lies within the larger of its own and the group's tolerance there. The
    /// group's depth in a bin moves on to each member that steps less than the smaller of the two
    /// tolerances behind it, so a surface whose depth drifts over the exposure (the sloping side
    /// of a sliding sphere passes a pixel at ever other depths) stays one group, while a surface
    /// that meets it at the same time farther back starts a new one. A footprint that meets the
    /// group at no time cannot be hidden by it and joins. With one bin this is the ternary test
    /// chained from each footprint to the next.
    ///
    /// In time bins a faint footprint, the far tail of a splat or a streak, has no say in the
    /// groups: it moves no chain, and where it lies off the open group's surface it is held aside
    /// and joins the next group, rather than closing the open one (docs/math.md, "Faint
    /// footprints").
    ///
    /// What groups closed before leave unoccluded over the footprint's time window, its share
    /// `seen`, weights its colour in the group's mean: a surface passing behind another shows
    /// the colour it has while it is seen, not while it is hidden. A footprint hidden over its
    /// whole window is left out: it can neither show nor split the group in front (docs/math.md,
    /// "Time bins for coverage").
    #[inline(always)]
    pub(super) fn add(
        &mut self,
        f: &Footprint,
        w: f32,
        faint: bool,
        [x, y]: [u32; 2],
        bins: &TimeBins<B>,
    ) -> Counted {
        const LEFT_OUT: Counted = Counted {
            seen: 0.0,
            held: false,
        };
        // One bin is an instant: the footprint's depth at the pixel holds all of it.
        let (span, depth, step, mut seen) = if B == 1 {
            let whole = BinSpan {
                first: 0,
                last: 1,
                u0: 0.0,
                u1: 1.0,
            };
            (whole, f.depth_at(x, y), 0.0, 1.0)
        } else {
            let passage = f.passage_at(x, y);
            let span = bin_span(passage.window, bins);
            let seen = self.seen_share(&span, bins);
            if seen < OPAQUE_REMAINDER {
                return LEFT_OUT;
            }
            let (depth, step) = depths_in_bins(&passage, &span, bins);
            (span, depth, step, seen)
        };
        let faint = B > 1 && faint;
        let mut in_bin = depth;
        let same_surface = self.group_depth[span.bins()]
            .iter()
            .zip(&self.group_tolerance[span.bins()])
            .all(|(&group_depth, &group_tolerance)| {
                let near = in_bin - group_depth <= larger(group_tolerance, f.depth_tolerance);
                in_bin += step;
                near
            });
        let held = !same_surface && faint;
        if !same_surface && !faint {
            self.close_group(bins);
            if self.held.counts_any() {
                // What was held aside starts the next group; the group just closed left its
                // sums empty for holding.
                std::mem::swap(&mut self.group, &mut self.held);
                self.reweigh_held(bins);
            }
            // The group just closed lies in front of `f`.
            if B > 1 {
                seen = self.seen_share(&span, bins);
                if seen < OPAQUE_REMAINDER {
                    return LEFT_OUT;
                }
            }
        }
        if !faint {
            self.follow([depth, step], f.depth_tolerance, &span);
        }
        self.members(held).count(f, w, seen, depth, &span, bins);
        Counted { seen, held }
    }

    /// Weigh the open group, footprints that were held aside, by what the groups closed so far
    /// leave of their coverage, not by what they left when each arrived: the group that closed
    /// after them lies in front of them. Their weight Σ w·seen becomes Σ over bins of coverage ×
    /// transmittance (exact, as each footprint's `seen` is its coverage's share per bin), and
    /// their colour sum scales with it (exact for one footprint; for several, as if each one's
    /// share changed alike). A tail hidden all its time then has no say in the surface it joins.
    fn reweigh_held(&mut self, bins: &TimeBins<B>) {
        let group = &mut self.group;
        if B == 1 || !(group.weight > 0.0) {
            return;
        }
        group.settle_whole_bins(bins);
        let [first, last] = group.bins;
        let seen: f32 = (group.coverage[first..last].iter())
            .zip(&self.transmittance[first..last])
            .map(|(&coverage, &t)| coverage * t)
            .sum();
        let scale = larger(seen, 0.0) / group.weight;
        group.weight *= scale;
        for c in &mut group.colour {
            *c *= scale;
        }
    }

    /// The share of `span` that the groups closed so far leave unoccluded, each bin counted by
    /// its overlap × shutter mass, as [`Members::deposit`] spreads a footprint's weight.
    #[inline]
    fn seen_share(&self, span: &BinSpan, bins: &TimeBins<B>) -> f32 {
        // Nothing in front yet: the first surface at a pixel, most footprints, sees it all.
        if self.remaining == 1.0 {
            return 1.0;
        }
        let transmittance = &self.transmittance;
        let Some([head, tail]) = span.end_masses(bins) else {
            return transmittance[span.first];
        };
        let (first, last) = (span.first, span.last);
        let (mut seen, mut mass) = (
            head * transmittance[first] + tail * transmittance[last - 1],
            head + tail,
        );
        for (&t, &m) in transmittance[first + 1..last - 1]
            .iter()
            .zip(&bins.mass[first + 1..last - 1])
        {
            seen += t * m;
            mass += m;
        }
        if mass > 0.0 {
            seen / mass
        } else {
            transmittance[first]
        }
    }

    /// The footprints held aside, or the open group's.
    #[inline(always)]
    fn members(&mut self, held: bool) -> &mut Members<B> {
        if held {
            &mut self.held
        } else {
            &mut self.group
        }
    }

    /// Add `change` to the colour of the footprint just added (its colour's change along a
    /// streak, weighted by its light there), as emission when it is `additive`; `counted` is what
    /// [`Self::add`] returned for it, which weights its colour as it weighted the rest.
    #[inline(always)]
    pub(super) fn add_colour_change(&mut self, additive: bool, change: [f32; 3], counted: Counted) {
        if counted.seen == 0.0 {
            return;
        }
        let members = self.members(counted.held);
        let (sums, scale) = if additive {
            (&mut members.emission, 1.0)
        } else {
            (&mut members.colour, counted.seen)
        };
        for (sum, change) in sums.iter_mut().zip(change) {
            *sum += scale * change;
        }
    }

    /// Move the group's depth in the bins of `span` on to a member at `depth` in its first bin and
    /// `step` more in each next one: in bins it did not cover yet, taking its tolerance, and where
    /// it lies behind by less than the smaller tolerance, taking that one in time bins (its own in
    /// an instant).
    #[inline]
    fn follow(&mut self, [depth, step]: [f32; 2], tolerance: f32, span: &BinSpan) {
        let mut in_bin = depth;
        for (group_depth, group_tolerance) in self.group_depth[span.bins()]
            .iter_mut()
            .zip(&mut self.group_tolerance[span.bins()])
        {
            let behind = in_bin - *group_depth;
            if *group_depth == f32::INFINITY {
                *group_depth = in_bin;
                *group_tolerance = tolerance;
            } else if behind > 0.0 && behind <= smaller(*group_tolerance, tolerance) {
                *group_depth = in_bin;
                // In time bins a bin keeps the smaller tolerance: a splat seen nearly edge-on,
                // whose tolerance spans more than one surface, must not lend it to the chain
                // for the footprints after it to join by (docs/math.md, "Faint footprints").
                if B == 1 {
                    *group_tolerance = tolerance;
                } else {
                    *group_tolerance = smaller(*group_tolerance, tolerance);
                }
            }
            in_bin += step;
        }
    }

    fn close_group(&mut self, bins: &TimeBins<B>) {
        let group = &mut self.group;
        // Light emitted at this depth is dimmed by what lies in front, not by its own surface.
        for c in 0..3 {
            self.colour[c] += self.remaining * group.emission[c];
        }
        let [first, last] = group.bins;
        if group.weight > 0.0 {
            // One bin (an instant) has no run of whole bins to mark and no other bin to spill
            // into. Unspilled coverage beyond full is as opaque as full: its excess is left.
            if B > 1 {
                let overflow = group.settle_whole_bins(bins);
                group.spill_overflow(overflow, bins);
            }
            let mut visible = 0.0;
            for b in first..last {
                let mass = bins.mass[b];
                let coverage = std::mem::take(&mut group.coverage[b]);
                if mass > 0.0 {
                    let alpha = opacity(f64::from(coverage / mass)) as f32;
                    visible += self.transmittance[b] * alpha * mass;
                    self.transmittance[b] *= 1.0 - alpha;
                }
            }
            // The bins the group does not touch keep their transmittance: what it hides is what
            // it shows.
            let remaining = larger(self.remaining - visible, 0.0);
            let k = visible / group.weight;
            for c in 0..3 {
                self.colour[c] += k * group.colour[c];
            }
            if self.remaining >= VISIBLE_REMAINDER && remaining < VISIBLE_REMAINDER {
                // The surface's depth as far as its chain reached (its nearest footprint may be
                // the soft edge of something in front that the chain joined); a group of faint
                // footprints alone has no chain.
                let chain = self.group_depth[first..last]
                    .iter()
                    .filter(|d| d.is_finite())
                    .fold(f32::NEG_INFINITY, |a, &d| a.max(d));
                self.front_depth = if chain.is_finite() {
                    chain
                } else {
                    group.deepest
                };
            }
            self.remaining = remaining;
        } else if first < last {
            // Without weight the group deposited no coverage, but for weights that underflow.
            group.coverage[first..last].fill(0.0);
            group.whole_bins[first..last].fill(0.0);
        }
        if first < last {
            self.group_depth[first..last].fill(f32::INFINITY);
        }
        group.clear_sums();
    }

    /// The pixel's premultiplied colour, the share of the exposure that shows what lies behind,
    /// and the depth of its visible surface.
    pub(super) fn finish(&mut self, bins: &TimeBins<B>) -> ([f32; 3], f32, f32) {
        self.close_group(bins);
        if self.held.counts_any() {
            // Faint footprints behind the last group, with none after them to join.
            self.group = self.held;
            self.reweigh_held(bins);
            self.close_group(bins);
        }
        (self.colour, self.remaining, self.front_depth)
    }
}

impl<const B: usize> Members<B> {
    const EMPTY: Self = Members {
        colour: [0.0; 3],
        emission: [0.0; 3],
        weight: 0.0,
        deepest: f32::NEG_INFINITY,
        coverage: [0.0; B],
        whole_bins: [0.0; B],
        bins: [B, 0],
    };

    /// Whether any footprint was counted since the sums were last emptied.
    fn counts_any(&self) -> bool {
        self.bins[0] < self.bins[1]
    }

    /// Empty the sums but for the coverage and its marks, which closing the group left empty
    /// (they are the most to write).
    fn clear_sums(&mut self) {
        self.colour = [0.0; 3];
        self.emission = [0.0; 3];
        self.weight = 0.0;
        self.deepest = f32::NEG_INFINITY;
        self.bins = [B, 0];
    }

    /// Count footprint `f` with weight `w` in the bins of `span`, a share `seen` of it
    /// unoccluded, at `depth`.
    #[inline(always)]
    fn count(
        &mut self,
        f: &Footprint,
        w: f32,
        seen: f32,
        depth: f32,
        span: &BinSpan,
        bins: &TimeBins<B>,
    ) {
        self.bins = [self.bins[0].min(span.first), self.bins[1].max(span.last)];
        self.deepest = larger(self.deepest, depth);
        if f.additive {
            for c in 0..3 {
                self.emission[c] += w * f.colour[c];
            }
            return;
        }
        let shown = w * seen;
        for c in 0..3 {
            self.colour[c] += shown * f.colour[c];
        }
        self.weight += shown;
        if B == 1 {
            self.coverage[0] += w;
        } else {
            self.deposit(w, span, bins);
        }
    }

    /// Spread `w` over the bins of `span`, in proportion to the overlap × shutter mass there.
    #[inline]
    fn deposit(&mut self, w: f32, span: &BinSpan, bins: &TimeBins<B>) {
        let (first, last) = (span.first, span.last);
        let Some([head, tail]) = span.end_masses(bins) else {
            self.coverage[first] += w;
            return;
        };
        // Every bin between the first and the last gets `scale` × its mass, marked at the run's
        // ends only, so a wide window costs no more than a narrow one.
        let inner = bins.mass_before[last - 1] - bins.mass_before[first + 1];
        let total = head + tail + inner;
        if total > 0.0 {
            let scale = w / total;
            self.coverage[first] += scale * head;
            self.coverage[last - 1] += scale * tail;
            if last > first + 2 {
                self.whole_bins[first + 1] += scale;
                self.whole_bins[last - 1] -= scale;
            }
        }
    }

    /// Add to each bin of the group the coverage its marks in `whole_bins` stand for
    /// (their running sum times the bin's mass), and clear the marks. Returns the bins' tally of
    /// coverage beyond full and held in bins not full, with which [`Self::spill_overflow`] starts,
    /// so that a group with nothing to spill reads its bins once only.
    fn settle_whole_bins(&mut self, bins: &TimeBins<B>) -> Overflow {
        let [first, last] = self.bins;
        let (mut per_mass, mut largest) = (0.0f32, 0.0f32);
        let mut overflow = Overflow::default();
        for b in first..last {
            let mark = std::mem::take(&mut self.whole_bins[b]);
            per_mass += mark;
            largest = larger(largest, mark.abs());
            // Where every run has ended the sum is zero but for rounding, which must not leave
            // coverage in bins the group never covered (`spill_overflow` would fill them).
            if per_mass.abs() <= 1e-5 * largest {
                per_mass = 0.0;
            }
            let mass = bins.mass[b];
            self.coverage[b] += per_mass * mass;
            overflow.count(self.coverage[b], mass);
        }
        overflow
    }

    /// Move the group's coverage beyond full in some bins into its bins that are not full, in
    /// proportion to what they hold, so that the group's coverage over the exposure is kept. A
    /// motion ellipse deposits the weight of a Gaussian along its chord where the sliding splat
    /// leaves a flat-topped streak: at a pixel inside a sliding surface, the bins in which the
    /// surfels pass mid-chord get too much (up to 1.4×) and those at the chords' ends too little
    /// (0.3×). Clipped bin by bin, 20 % of the background showed through a sliding sphere; the
    /// total is right, only its spread in time is not.
    ///
    /// `overflow` is the tally of the bins as they are. Each round clips the bins beyond full,
    /// scales those not full by what the tally says, and tallies the result for the next round,
    /// in one pass. A bin clipped after the last round was beyond full, which is as opaque as
    /// full ([`opacity`] of either is 1).
    fn spill_overflow(&mut self, mut overflow: Overflow, bins: &TimeBins<B>) {
        let [first, last] = self.bins;
        let coverages = &mut self.coverage[first..last];
        let masses = &bins.mass[first..last];
        // Each round fills at least one more bin or places all the excess: at most B rounds.
        for _ in 0..B {
            if !overflow.spills() {
                return;
            }
            let scale = 1.0 + overflow.excess / overflow.held;
            overflow = Overflow::default();
            for (coverage, &mass) in coverages.iter_mut().zip(masses) {
                if *coverage > mass {
                    *coverage = mass;
                } else if *coverage < mass {
                    *coverage *= scale;
                }
                if overflow.count(*coverage, mass) {
                    *coverage = mass;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Sym2;
    use crate::raster::{ScreenSplat, TimeExtent, OPACITY_KNEE, OPAQUE_COVERAGE};
    use glam::DVec2;

    /// A footprint at `depth` covering the pixel during `span`, with the weight `value` it is
    /// given at the pixel.
    fn layer(value: f32, colour: [f32; 3], depth: f64, span: [f64; 2]) -> (Footprint, f32) {
        let splat = ScreenSplat {
            center: DVec2::new(0.5, 0.5),
            covariance: Sym2::isotropic(100.0),
            weight: 1.0,
            colour,
            depth,
            depth_gradient: DVec2::ZERO,
            depth_tolerance: 0.01,
            depth_rate: 0.0,
            time: TimeExtent {
                center: 0.5 * (span[0] + span[1]),
                gradient: DVec2::ZERO,
                half_width: 0.5 * (span[1] - span[0]),
                span,
            },
            profile: crate::raster::Profile::Gaussian,
            sweep: DVec2::ZERO,
            sweep_change: 0.0,
            colour_change: 0.0,
            additive: false,
        };
        (splat.footprint(1, 1).unwrap(), value)
    }

    fn composite<const B: usize>(layers: &[(Footprint, f32)], bins: &TimeBins<B>) -> [f32; 3] {
        let marked: Vec<_> = layers.iter().map(|&(f, w)| (f, w, false)).collect();
        composite_marked(&marked, bins)
    }

    /// Assert that `p` is `expected` in every channel, within the rounding of a few f32 sums.
    #[track_caller]
    fn assert_near(p: [f32; 3], expected: [f32; 3], context: &str) {
        assert!(
            (0..3).all(|c| (p[c] - expected[c]).abs() < 1e-5),
            "{context}{p:?} against {expected:?}"
        );
    }

    /// [`composite`] of layers each marked faint or not, over a blue background.
    fn composite_marked<const B: usize>(
        layers: &[(Footprint, f32, bool)],
        bins: &TimeBins<B>,
    ) -> [f32; 3] {
        let mut pixel = PixelState::<B>::EMPTY;
        for (f, w, faint) in layers {
            pixel.add(f, *w, *faint, [0, 0], bins);
        }
        let (colour, remaining, _) = pixel.finish(bins);
        [0, 1, 2].map(|c| colour[c] + remaining * [0.0, 0.0, 1.0][c])
    }

    #[test]
    fn coverage_spreads_over_a_window_by_overlap_times_mass_and_nowhere_else() {
        // Under a tent shutter the bins' masses differ. Windows of many widths, overlapping and
        // ending at different bins, each spread their weight over the bins they overlap in
        // proportion to overlap × mass; bins no window reaches keep nothing, not even what
        // rounding leaves of the runs' marks.
        let shutter = Shutter::new(0.0, 1.0, crate::scene::shutter::ShutterShape::Tent).unwrap();
        let bins = TimeBins::<32>::over(&shutter);
        // Two hundred windows, from a fixed linear congruential sequence, half within
        // [0.05, 0.35] and half within [0.5, 0.75]: the bins between lie within the group's
        // bins but outside every window.
        let mut next = crate::math::test_sequence(12345);
        let windows: Vec<([f64; 2], f32)> = (0..200)
            .map(|k| {
                let start = if k % 2 == 0 { 0.05 } else { 0.5 } + 0.05 * next();
                ([start, start + 0.2 * next()], 0.001 + next() as f32)
            })
            .collect();
        let mut pixel = PixelState::<32>::EMPTY;
        let mut expected = [0.0f64; 32];
        for &(window, w) in &windows {
            let (f, _) = layer(1.0, [1.0; 3], 1.0, window);
            pixel.add(&f, w, false, [0, 0], &bins);
            let overlap = |b: usize| {
                let (lo, hi) = (b as f64 / 32.0, (b + 1) as f64 / 32.0);
                (window[1].min(hi) - window[0].max(lo)).max(0.0) * f64::from(bins.mass[b])
            };
            let total: f64 = (0..32).map(overlap).sum();
            for (b, e) in expected.iter_mut().enumerate() {
                *e += f64::from(w) * overlap(b) / total;
            }
        }
        let _ = pixel.group.settle_whole_bins(&bins);
        for (b, &e) in expected.iter().enumerate() {
            let got = f64::from(pixel.group.coverage[b]);
            // f32 sums of 200 deposits: within 10⁻⁵ relative.
            assert!(
                (got - e).abs() <= 1e-5 * e.max(1.0),
                "bin {b}: {got} against {e}"
            );
            if e == 0.0 {
                assert_eq!(got, 0.0, "bin {b} lies outside every window");
            }
        }
    }

    #[test]
    fn coverage_disjoint_in_time_adds_up_and_hides_the_background() {
        // Red covers the first half of the exposure, green (farther) the second half: each is
        // seen for half the time and the background never.
        let bins = TimeBins::<16>::over(&Shutter::default());
        let red = layer(0.5, [1.0, 0.0, 0.0], 1.0, [0.0, 0.5]);
        let green = layer(0.5, [0.0, 1.0, 0.0], 2.0, [0.5, 1.0]);
        let p = composite(&[red, green], &bins);
        assert_near(p, [0.5, 0.5, 0.0], "");
        // With one bin the same coverage is treated as stacked layers: the background leaks.
        let leaky = composite(&[red, green], &TimeBins::INSTANT);
        assert!((leaky[2] - 0.25).abs() < 1e-5, "{leaky:?}");
    }

    #[test]
    fn a_surface_behind_shows_the_colours_it_has_while_seen() {
        // Red (nearer) covers the pixel for a quarter or a half of the exposure. Behind it one
        // surface is yellow during the first half and green during the second: the pixel shows
        // each colour for the time it is seen, exactly, and the background never. Weighting the
        // far surface's colours by their whole weights mixed in the yellow hidden behind red.
        let bins = TimeBins::<16>::over(&Shutter::default());
        let yellow = layer(0.5, [1.0, 1.0, 0.0], 2.0, [0.0, 0.5]);
        let green = layer(0.5, [0.0, 1.0, 0.0], 2.0, [0.5, 1.0]);
        for red_until in [0.25f32, 0.5] {
            let red = layer(red_until, [1.0, 0.0, 0.0], 1.0, [0.0, f64::from(red_until)]);
            let p = composite(&[red, yellow, green], &bins);
            let yellow_seen = 0.5 - red_until;
            let expected = [red_until + yellow_seen, yellow_seen + 0.5, 0.0];
            assert_near(p, expected, &format!("red until {red_until}: "));
        }
    }

    #[test]
    fn a_faint_tail_from_behind_neither_splits_the_surface_in_front_nor_is_lost() {
        // Red (depth 1) covers the first half of the exposure in two footprints; green (depth 2)
        // covers all of it. The faint tail of a green splat arrives between the two reds, as
        // sorting by each footprint's own depth can order them. Red shows for half the exposure
        // and green for the other half. Had the tail closed red's group, the second red would
        // have joined green's and mixed with it where it hides it: red 0.375, green 0.625.
        let bins = TimeBins::<16>::over(&Shutter::default());
        let (red, _) = layer(0.25, [1.0, 0.0, 0.0], 1.0, [0.0, 0.5]);
        let (green, _) = layer(1.0, [0.0, 1.0, 0.0], 2.0, [0.0, 1.0]);
        let tail = 5e-4;
        let p = composite_marked(
            &[
                (red, 0.25, false),
                (green, tail, true),
                (red, 0.25, false),
                (green, 1.0, false),
            ],
            &bins,
        );
        assert_near(p, [0.5, 0.5, 0.0], "");
        // With nothing after it to join, a faint tail behind a surface still covers its share of
        // what that surface leaves: half of the exposure, so 0.02 × 0.5 of the pixel is green.
        let (half_red, _) = layer(0.5, [1.0, 0.0, 0.0], 1.0, [0.0, 1.0]);
        let p = composite_marked(&[(half_red, 0.5, false), (green, 0.02, true)], &bins);
        assert_near(p, [0.5, 0.01, 0.49], "");
    }

    #[test]
    fn a_faint_tail_hidden_all_its_time_has_no_say_in_the_surface_it_joins() {
        // Red (depth 1) covers the first half of the exposure in two footprints; the faint tail
        // of a blue splat (depth 2) over the same half arrives between them and is held aside;
        // green (depth 2) covers all of the exposure. Blue is hidden by red for all its time: the
        // pixel is half red, half green. Weighted by what it saw on arrival (all of its time),
        // the tail took 7.4 % of green's share: (0.5, 0.463, 0.037).
        let bins = TimeBins::<16>::over(&Shutter::default());
        let (red, _) = layer(0.25, [1.0, 0.0, 0.0], 1.0, [0.0, 0.5]);
        let (blue, _) = layer(0.04, [0.0, 0.0, 1.0], 2.0, [0.0, 0.5]);
        let (green, _) = layer(1.0, [0.0, 1.0, 0.0], 2.0, [0.0, 1.0]);
        let p = composite_marked(
            &[
                (red, 0.25, false),
                (blue, 0.04, true),
                (red, 0.25, false),
                (green, 1.0, false),
            ],
            &bins,
        );
        assert_near(p, [0.5, 0.5, 0.0], "");
    }

    #[test]
    fn a_splat_seen_edge_on_lends_the_chain_no_tolerance_in_time_bins() {
        // Red (depth 1) covers half the pixel all the exposure; a red splat seen nearly edge-on
        // (depth tolerance 5) moves its chain 0.005 deeper; green, 1 deeper, covers all of the
        // pixel all the exposure. Red must hide half of green. Had the chain taken the edge-on
        // splat's tolerance, green would have joined red's group and mixed with it: red 0.33.
        let bins = TimeBins::<16>::over(&Shutter::default());
        let red = layer(0.5, [1.0, 0.0, 0.0], 1.0, [0.0, 1.0]);
        let (mut edge_on, _) = layer(0.01, [1.0, 0.0, 0.0], 1.005, [0.0, 1.0]);
        edge_on.depth_tolerance = 5.0;
        let green = layer(1.0, [0.0, 1.0, 0.0], 2.0, [0.0, 1.0]);
        let p = composite(&[red, (edge_on, 0.01), green], &bins);
        assert_near(p, [0.51, 0.49, 0.0], "");
    }

    #[test]
    fn coverage_overlapping_in_time_occludes() {
        // Both cover the pixel during the whole exposure: the nearer one hides the farther.
        let bins = TimeBins::<16>::over(&Shutter::default());
        let red = layer(1.0, [1.0, 0.0, 0.0], 1.0, [0.0, 1.0]);
        let green = layer(1.0, [0.0, 1.0, 0.0], 2.0, [0.0, 1.0]);
        let p = composite(&[red, green], &bins);
        assert_near(p, [1.0, 0.0, 0.0], "");
    }

    #[test]
    fn additive_light_is_dimmed_only_by_what_lies_in_front() {
        let bins = TimeBins::INSTANT;
        let glow_at = |depth| {
            let (mut f, w) = layer(0.5, [1.0, 0.0, 0.0], depth, [0.0, 1.0]);
            f.additive = true;
            (f, w)
        };
        let wall = layer(1.0, [0.0, 1.0, 0.0], 2.0, [0.0, 1.0]);
        // Alone it adds to the background and hides nothing.
        assert_eq!(composite(&[glow_at(3.0)], &bins), [0.5, 0.0, 1.0]);
        // Behind an opaque wall it is hidden; in front of it, it adds to the wall.
        assert_eq!(composite(&[wall, glow_at(3.0)], &bins), [0.0, 1.0, 0.0]);
        assert_eq!(composite(&[glow_at(1.0), wall], &bins), [0.5, 1.0, 0.0]);
    }

    #[test]
    fn a_surface_whose_depth_drifts_is_one_surface() {
        // Three parts of one surface pass the pixel in turn, each 0.008 deeper than the one
        // before (within the 0.01 tolerance of its neighbour, not of the first): together they
        // cover the whole exposure and hide the background, as one surface would. (The middle
        // part shares a bin with each of the others: taken as two surfaces, the first two
        // would hide only a third of the second bin, and the third part 2/3 of what is left.)
        let bins = TimeBins::<2>::over(&Shutter::default());
        let parts: Vec<_> = (0..3)
            .map(|k| {
                let t = k as f64 / 3.0;
                layer(
                    1.0 / 3.0,
                    [1.0, 0.0, 0.0],
                    1.0 + 0.008 * k as f64,
                    [t, t + 1.0 / 3.0],
                )
            })
            .collect();
        let p = composite(&parts, &bins);
        assert!((p[0] - 1.0).abs() < 1e-5 && p[2].abs() < 1e-5, "{p:?}");
    }

    #[test]
    fn coverage_beyond_full_in_one_bin_fills_the_others() {
        // One surface deposits 0.7 of the exposure in its first half and 0.3 in its second:
        // its total covers the exposure, so nothing of the background shows.
        let bins = TimeBins::<2>::over(&Shutter::default());
        let early = layer(0.7, [1.0, 0.0, 0.0], 1.0, [0.0, 0.5]);
        let late = layer(0.3, [1.0, 0.0, 0.0], 1.0, [0.5, 1.0]);
        let p = composite(&[early, late], &bins);
        assert!((p[0] - 1.0).abs() < 1e-5 && p[2].abs() < 1e-5, "{p:?}");
        // Less than the exposure in all: what it covers is kept, spread over its time.
        let early = layer(0.6, [1.0, 0.0, 0.0], 1.0, [0.0, 0.5]);
        let late = layer(0.2, [1.0, 0.0, 0.0], 1.0, [0.5, 1.0]);
        let p = composite(&[early, late], &bins);
        assert!(
            (p[0] - 0.8).abs() < 1e-5 && (p[2] - 0.2).abs() < 1e-5,
            "{p:?}"
        );
    }

    #[test]
    fn opacity_keeps_faint_coverage_and_makes_near_full_coverage_opaque() {
        for c in [0.0, 0.1, 0.5, OPACITY_KNEE] {
            assert_eq!(opacity(c), c);
        }
        for c in [OPAQUE_COVERAGE, 0.97, 1.0, 2.0] {
            assert_eq!(opacity(c), 1.0);
        }
        // Continuous and increasing in between.
        let steps: Vec<f64> = (0..=100)
            .map(|i| {
                opacity(OPACITY_KNEE + (OPAQUE_COVERAGE - OPACITY_KNEE) * f64::from(i) / 100.0)
            })
            .collect();
        assert!(steps.windows(2).all(|w| w[1] > w[0] && w[1] - w[0] < 0.003));
    }

    #[test]
    fn partial_coverage_in_one_bin_matches_plain_alpha() {
        let red = layer(0.3, [1.0, 0.0, 0.0], 1.0, [0.0, 1.0]);
        let p = composite(&[red], &TimeBins::INSTANT);
        assert!(
            (p[0] - 0.3).abs() < 1e-6 && (p[2] - 0.7).abs() < 1e-6,
            "{p:?}"
        );
    }
}
