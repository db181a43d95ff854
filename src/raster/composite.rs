//! Per-pixel compositing of depth-sorted footprints, in bins of shutter time.
//!
//! The ternary depth test groups footprints into surfaces (a footprint within the larger of its
//! own and the open group's depth tolerance of the group's depth belongs to it); a group's colour
//! is the normalized Σwc/Σw, and the share of the pixel it covers is counted per time bin: it
//! hides what lies behind it only in the bins in which it covers the pixel, so that time-disjoint
//! coverage of a sliding surface adds up instead of stacking as transparent layers. With one bin
//! (an instant) this is plain front-to-back compositing with α = min(1, Σw). Why bins, with the
//! measurements: docs/math.md, "Time bins for coverage".

use super::Footprint;
use crate::scene::shutter::Shutter;

/// Once this share of the exposure is left unoccluded at a pixel, farther surfaces cannot change
/// its 8-bit value.
const OPAQUE_REMAINDER: f32 = 1e-4;

/// The visible surface of a pixel is the first that leaves less than this share unoccluded.
const VISIBLE_REMAINDER: f32 = 0.5;

/// The exposure cut into `B` equal bins of time, with the shutter's mass in each. Times are
/// exposure times ([`super::TimeExtent`]): 0 at shutter open, 1 at close.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeBins<const B: usize> {
    start: f32,
    bins_per_time: f32,
    mass: [f32; B],
}

impl TimeBins<1> {
    /// One bin holding the whole exposure: for instants, where every footprint covers all of it.
    pub const INSTANT: TimeBins<1> = TimeBins {
        start: 0.0,
        bins_per_time: 1.0,
        mass: [1.0],
    };
}

impl<const B: usize> TimeBins<B> {
    /// `B` bins over the open interval of `shutter`, weighted by its shape.
    #[must_use]
    pub fn over(shutter: &Shutter) -> Self {
        let step = shutter.duration() / B as f64;
        TimeBins {
            start: 0.0,
            bins_per_time: B as f32,
            mass: std::array::from_fn(|b| {
                let t0 = shutter.open + step * b as f64;
                shutter.moments(t0, t0 + step).mass as f32
            }),
        }
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
    group_colour: [f32; 3],
    /// Light added by additive footprints of the open group.
    group_emission: [f32; 3],
    group_weight: f32,
    group_depth: f32,
    group_tolerance: f32,
    group_coverage: [f32; B],
}

impl<const B: usize> PixelState<B> {
    pub(super) const EMPTY: Self = PixelState {
        colour: [0.0; 3],
        transmittance: [1.0; B],
        remaining: 1.0,
        front_depth: f32::INFINITY,
        group_colour: [0.0; 3],
        group_emission: [0.0; 3],
        group_weight: 0.0,
        group_depth: f32::NEG_INFINITY,
        group_tolerance: 0.0,
        group_coverage: [0.0; B],
    };

    /// Whether nothing behind can show any more.
    #[inline]
    pub(super) fn is_opaque(&self) -> bool {
        self.remaining < OPAQUE_REMAINDER
    }

    /// Add footprint `f` with weight `w` at this pixel, (x, y).
    #[inline]
    pub(super) fn add(&mut self, f: &Footprint, w: f32, [x, y]: [u32; 2], bins: &TimeBins<B>) {
        let depth = f.depth_at(x, y);
        let same_surface = depth - self.group_depth <= self.group_tolerance.max(f.depth_tolerance);
        if !same_surface {
            self.close_group(bins);
            self.group_depth = depth;
            self.group_tolerance = f.depth_tolerance;
        }
        if f.additive {
            for c in 0..3 {
                self.group_emission[c] += w * f.colour[c];
            }
            return;
        }
        for c in 0..3 {
            self.group_colour[c] += w * f.colour[c];
        }
        self.group_weight += w;
        if B == 1 {
            self.group_coverage[0] += w;
        } else {
            self.deposit(w, f.time_window_at(x, y), bins);
        }
    }

    /// Spread `w` over the bins that `window` overlaps, in proportion to the shutter mass there.
    fn deposit(&mut self, w: f32, [lo, hi]: [f32; 2], bins: &TimeBins<B>) {
        let end = B as f32;
        let u0 = ((lo - bins.start) * bins.bins_per_time).clamp(0.0, end);
        let u1 = ((hi - bins.start) * bins.bins_per_time).clamp(0.0, end);
        let first = (u0 as usize).min(B - 1);
        let last = (u1.ceil() as usize).clamp(first + 1, B);
        if last == first + 1 || u1 - u0 < 1e-4 {
            self.group_coverage[first] += w;
            return;
        }
        let overlap =
            |b: usize| (u1.min(b as f32 + 1.0) - u0.max(b as f32)).max(0.0) * bins.mass[b];
        let total: f32 = (first..last).map(overlap).sum();
        if total > 0.0 {
            for b in first..last {
                self.group_coverage[b] += w * overlap(b) / total;
            }
        }
    }

    fn close_group(&mut self, bins: &TimeBins<B>) {
        // Light emitted at this depth is dimmed by what lies in front, not by its own surface.
        for c in 0..3 {
            self.colour[c] += self.remaining * self.group_emission[c];
        }
        if self.group_weight > 0.0 {
            let (mut visible, mut remaining) = (0.0, 0.0);
            for b in 0..B {
                let mass = bins.mass[b];
                if mass > 0.0 {
                    let alpha = (self.group_coverage[b] / mass).min(1.0);
                    visible += self.transmittance[b] * alpha * mass;
                    self.transmittance[b] *= 1.0 - alpha;
                    remaining += self.transmittance[b] * mass;
                }
            }
            let k = visible / self.group_weight;
            for c in 0..3 {
                self.colour[c] += k * self.group_colour[c];
            }
            if self.remaining >= VISIBLE_REMAINDER && remaining < VISIBLE_REMAINDER {
                self.front_depth = self.group_depth;
            }
            self.remaining = remaining;
        }
        self.group_colour = [0.0; 3];
        self.group_emission = [0.0; 3];
        self.group_weight = 0.0;
        self.group_coverage = [0.0; B];
    }

    /// The pixel's premultiplied colour, the share of the exposure that shows what lies behind,
    /// and the depth of its visible surface.
    pub(super) fn finish(mut self, bins: &TimeBins<B>) -> ([f32; 3], f32, f32) {
        self.close_group(bins);
        (self.colour, self.remaining, self.front_depth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Sym2;
    use crate::raster::{ScreenSplat, TimeExtent};
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
            time: TimeExtent {
                center: 0.5 * (span[0] + span[1]),
                gradient: DVec2::ZERO,
                half_width: 0.5 * (span[1] - span[0]),
                span,
            },
            profile: crate::raster::Profile::Gaussian,
            additive: false,
        };
        (splat.footprint(1, 1).unwrap(), value)
    }

    fn composite<const B: usize>(layers: &[(Footprint, f32)], bins: &TimeBins<B>) -> [f32; 3] {
        let mut pixel = PixelState::<B>::EMPTY;
        for (f, w) in layers {
            pixel.add(f, *w, [0, 0], bins);
        }
        let (colour, remaining, _) = pixel.finish(bins);
        [0, 1, 2].map(|c| colour[c] + remaining * [0.0, 0.0, 1.0][c])
    }

    #[test]
    fn coverage_disjoint_in_time_adds_up_and_hides_the_background() {
        // Red covers the first half of the exposure, green (farther) the second half: each is
        // seen for half the time and the background never.
        let bins = TimeBins::<16>::over(&Shutter::default());
        let red = layer(0.5, [1.0, 0.0, 0.0], 1.0, [0.0, 0.5]);
        let green = layer(0.5, [0.0, 1.0, 0.0], 2.0, [0.5, 1.0]);
        let p = composite(&[red, green], &bins);
        assert!(
            (p[0] - 0.5).abs() < 1e-5 && (p[1] - 0.5).abs() < 1e-5 && p[2].abs() < 1e-5,
            "{p:?}"
        );
        // With one bin the same coverage is treated as stacked layers: the background leaks.
        let leaky = composite(&[red, green], &TimeBins::INSTANT);
        assert!((leaky[2] - 0.25).abs() < 1e-5, "{leaky:?}");
    }

    #[test]
    fn coverage_overlapping_in_time_occludes() {
        // Both cover the pixel during the whole exposure: the nearer one hides the farther.
        let bins = TimeBins::<16>::over(&Shutter::default());
        let red = layer(1.0, [1.0, 0.0, 0.0], 1.0, [0.0, 1.0]);
        let green = layer(1.0, [0.0, 1.0, 0.0], 2.0, [0.0, 1.0]);
        let p = composite(&[red, green], &bins);
        assert!(
            (p[0] - 1.0).abs() < 1e-5 && p[1].abs() < 1e-5 && p[2].abs() < 1e-5,
            "{p:?}"
        );
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
    fn partial_coverage_in_one_bin_matches_plain_alpha() {
        let red = layer(0.3, [1.0, 0.0, 0.0], 1.0, [0.0, 1.0]);
        let p = composite(&[red], &TimeBins::INSTANT);
        assert!(
            (p[0] - 0.3).abs() < 1e-6 && (p[2] - 0.7).abs() < 1e-6,
            "{p:?}"
        );
    }
}
