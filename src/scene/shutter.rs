//! The shutter: when it is open inside the normalized frame time [0, 1] and how it weights time.
//!
//! Every renderer asks the same three questions of a time interval: how much of the exposure falls
//! in it (its mass), and the mean and variance of time inside it under the shutter weight. The
//! reference weights its frames by the masses; the blur renderer places each motion ellipse at the
//! mean and stretches it by the variance (docs/math.md, "Shutter moments").

use serde::Deserialize;

use crate::error::{Error, Result};

/// How the shutter weights time while it is open.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShutterShape {
    /// Constant weight: an ideal mechanical shutter.
    #[default]
    Box,
    /// Weight rising linearly to the middle of the exposure and falling back to zero.
    Tent,
    /// A Gaussian centred on the middle of the exposure with σ = duration / 6, cut at ±3σ.
    Gaussian,
}

/// An open interval of the frame and its weighting.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shutter {
    /// Opening time in [0, 1].
    pub open: f64,
    /// Closing time in [0, 1], after `open`.
    pub close: f64,
    /// Weighting over the open interval.
    pub shape: ShutterShape,
}

/// Mass, mean time and time variance of a time interval under the shutter weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeMoments {
    /// Fraction of the whole exposure that falls in the interval (masses of a partition sum to 1).
    pub mass: f64,
    /// Weighted mean time in the interval.
    pub mean: f64,
    /// Weighted variance of time in the interval.
    pub variance: f64,
}

impl Default for Shutter {
    fn default() -> Self {
        Shutter {
            open: 0.0,
            close: 1.0,
            shape: ShutterShape::Box,
        }
    }
}

/// Gauss–Legendre nodes and weights on [-1, 1], 8 points: exact for polynomials of degree 15.
const GAUSS_LEGENDRE_8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

/// The shortest exposure a shutter may stay open, in normalized frame time. The methods' time
/// arithmetic holds there (the stiff suite draws the instant at it with every method and shape);
/// near 10⁻¹³ of the frame, a few hundred ulps of the open time, the reference's frame times and
/// the time bins round together and the image darkens, and below 10⁻¹⁵ it was black.
pub const MIN_EXPOSURE: f64 = 1e-9;

impl Shutter {
    /// A shutter open from `open` to `close` in normalized frame time, weighting time by
    /// `shape`; an error unless 0 ≤ open < close ≤ 1 and the shutter stays open at least
    /// [`MIN_EXPOSURE`].
    pub fn new(open: f64, close: f64, shape: ShutterShape) -> Result<Shutter> {
        let open = super::finite("open", open)?;
        let close = super::finite("close", close)?;
        let (open_text, close_text) = (crate::error::shown(open), crate::error::shown(close));
        if !(0.0..=1.0).contains(&open) || !(0.0..=1.0).contains(&close) || !(open < close) {
            return Err(Error::invalid(
                "",
                format!(
                    "open = {open_text}, close = {close_text}: need 0 ≤ open < close ≤ 1 (normalized frame time)"
                ),
            ));
        }
        // close − open rounds: a shutter written MIN_EXPOSURE long may come out a few ulps short.
        if !(close - open >= MIN_EXPOSURE * (1.0 - 1e-6)) {
            return Err(Error::invalid(
                "",
                format!(
                    "open = {open_text}, close = {close_text}: open for {:e} of the frame, less than {MIN_EXPOSURE:e}; for one instant, draw `-m static --time {open_text}`",
                    close - open
                ),
            ));
        }
        Ok(Shutter { open, close, shape })
    }

    /// Length of the exposure in normalized time.
    #[must_use]
    pub fn duration(&self) -> f64 {
        self.close - self.open
    }

    /// The middle of the exposure.
    #[must_use]
    pub fn middle(&self) -> f64 {
        0.5 * (self.open + self.close)
    }

    /// Unnormalized weight at time `t` (zero outside the open interval).
    #[must_use]
    pub fn weight(&self, t: f64) -> f64 {
        if !(t >= self.open && t <= self.close) {
            return 0.0;
        }
        let half = 0.5 * self.duration();
        match self.shape {
            ShutterShape::Box => 1.0,
            ShutterShape::Tent => 1.0 - ((t - self.middle()) / half).abs(),
            ShutterShape::Gaussian => {
                let x = (t - self.middle()) / (self.duration() / 6.0);
                (-0.5 * x * x).exp()
            }
        }
    }

    /// Moments ∫a, ∫a·s, ∫a·s² over [t0, t1] (clipped to the open interval), unnormalized, with
    /// s = t − c measured from the clipped interval's centre c, which is returned too. Taking them
    /// about the centre keeps the variance of a short interval free of cancellation.
    fn central_moments(&self, t0: f64, t1: f64) -> ([f64; 3], f64) {
        let (t0, t1) = (t0.max(self.open), t1.min(self.close));
        let c = 0.5 * (t0 + t1);
        if !(t1 > t0) {
            return ([0.0; 3], c);
        }
        if self.shape == ShutterShape::Box {
            let length = t1 - t0;
            return ([length, 0.0, length.powi(3) / 12.0], c);
        }
        // The tent has a kink at the middle: integrate each side separately, where the weight is smooth.
        let mid = self.middle();
        let pieces: &[(f64, f64)] = if t0 < mid && mid < t1 {
            &[(t0, mid), (mid, t1)]
        } else {
            &[(t0, t1)]
        };
        // Four Gauss–Legendre panels per smooth piece: exact for the tent, ~1e-15 for the Gaussian.
        const PANELS: usize = 4;
        let mut sums = [0.0; 3];
        for &(a, b) in pieces {
            for panel in 0..PANELS {
                let (pa, pb) = (
                    a + (b - a) * panel as f64 / PANELS as f64,
                    a + (b - a) * (panel + 1) as f64 / PANELS as f64,
                );
                let (centre, half) = (0.5 * (pa + pb), 0.5 * (pb - pa));
                for (node, w) in GAUSS_LEGENDRE_8 {
                    let s = centre - c + half * node;
                    let aw = w * half * self.weight(c + s);
                    sums[0] += aw;
                    sums[1] += aw * s;
                    sums[2] += aw * s * s;
                }
            }
        }
        (sums, c)
    }

    /// Mass, mean and variance of time over [t0, t1] (clipped to the open interval).
    ///
    /// ```
    /// use streak::Shutter;
    /// // A box shutter: the whole exposure is uniform on [0, 1], variance 1/12.
    /// let m = Shutter::default().moments(0.0, 1.0);
    /// assert!((m.mass - 1.0).abs() < 1e-12 && (m.variance - 1.0 / 12.0).abs() < 1e-12);
    /// ```
    #[must_use]
    pub fn moments(&self, t0: f64, t1: f64) -> TimeMoments {
        let total = self.central_moments(self.open, self.close).0[0];
        let ([m0, m1, m2], c) = self.central_moments(t0, t1);
        if !(m0 > 0.0) {
            return TimeMoments {
                mass: 0.0,
                mean: 0.5 * (t0 + t1),
                variance: 0.0,
            };
        }
        let offset = m1 / m0;
        TimeMoments {
            mass: m0 / total,
            mean: c + offset,
            variance: (m2 / m0 - offset * offset).max(0.0),
        }
    }

    /// The share of the shutter's weight over [t0, t1] (clipped to the open interval): the mass
    /// of [`Shutter::moments`], without the other moments for a box.
    #[must_use]
    pub fn mass(&self, t0: f64, t1: f64) -> f64 {
        if self.shape == ShutterShape::Box {
            (t1.min(self.close) - t0.max(self.open)).max(0.0) / self.duration()
        } else {
            self.moments(t0, t1).mass
        }
    }

    /// `count` equal strata of the exposure with their moments: the reference's sample times
    /// (stratum midpoints) and weights (stratum masses).
    pub fn strata(&self, count: usize) -> impl Iterator<Item = (f64, f64)> + '_ {
        let step = self.duration() / count as f64;
        (0..count).map(move |i| {
            let t0 = self.open + step * i as f64;
            let t1 = t0 + step;
            (0.5 * (t0 + t1), self.mass(t0, t1))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shutter(shape: ShutterShape) -> Shutter {
        Shutter {
            open: 0.1,
            close: 0.9,
            shape,
        }
    }

    #[test]
    fn a_shutter_shorter_than_the_least_exposure_is_refused_with_the_instant_to_draw() {
        // 10⁻¹⁶ past one half is one ulp of it: the methods' time arithmetic drew black there.
        for close in [0.5 + 1e-10, 0.5 + 1e-16] {
            let error = Shutter::new(0.5, close, ShutterShape::Box)
                .unwrap_err()
                .to_string();
            assert!(error.contains("-m static --time 0.5"), "{error}");
        }
        assert!(Shutter::new(0.5, 0.5 + MIN_EXPOSURE, ShutterShape::Gaussian).is_ok());
    }

    #[test]
    fn box_moments_are_those_of_a_uniform_interval() {
        let m = shutter(ShutterShape::Box).moments(0.1, 0.9);
        assert!((m.mass - 1.0).abs() < 1e-12);
        assert!((m.mean - 0.5).abs() < 1e-12);
        // Uniform on an interval of length 0.8: variance 0.8²/12.
        assert!((m.variance - 0.64 / 12.0).abs() < 1e-12);
    }

    #[test]
    fn tent_variance_is_analytic() {
        // Symmetric triangular distribution of width L has variance L²/24.
        let m = shutter(ShutterShape::Tent).moments(0.0, 1.0);
        assert!((m.mass - 1.0).abs() < 1e-12);
        assert!((m.mean - 0.5).abs() < 1e-12);
        assert!((m.variance - 0.64 / 24.0).abs() < 1e-9, "{}", m.variance);
    }

    #[test]
    fn masses_of_a_partition_sum_to_one_for_every_shape() {
        for shape in [
            ShutterShape::Box,
            ShutterShape::Tent,
            ShutterShape::Gaussian,
        ] {
            let s = shutter(shape);
            let sum: f64 = s.strata(7).map(|(_, mass)| mass).sum();
            assert!((sum - 1.0).abs() < 1e-9, "{shape:?}: {sum}");
            for (t0, t1) in [(0.1, 0.35), (-0.5, 0.2), (0.9, 1.4), (0.6, 0.6), (0.7, 0.3)] {
                assert_eq!(
                    s.mass(t0, t1),
                    s.moments(t0, t1).mass,
                    "{shape:?} {t0} {t1}"
                );
            }
        }
    }

    #[test]
    fn gaussian_moments_match_a_dense_riemann_sum() {
        let s = shutter(ShutterShape::Gaussian);
        let (a, b) = (0.3, 0.62);
        let n = 200_000;
        let (mut m0, mut m1, mut m2) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let t = a + (b - a) * (i as f64 + 0.5) / n as f64;
            let w = s.weight(t);
            m0 += w;
            m1 += w * t;
            m2 += w * t * t;
        }
        let m = s.moments(a, b);
        let mean = m1 / m0;
        assert!((m.mean - mean).abs() < 1e-9);
        assert!((m.variance - (m2 / m0 - mean * mean)).abs() < 1e-9);
    }

    #[test]
    fn tiny_intervals_keep_their_variance() {
        // 1e-7 of the frame at t ≈ 0.7: about the centre, Δ²/12 survives; about 0 it would cancel.
        for shape in [
            ShutterShape::Box,
            ShutterShape::Tent,
            ShutterShape::Gaussian,
        ] {
            let (a, b) = (0.7, 0.7 + 1e-7);
            let m = shutter(shape).moments(a, b);
            let expected = (b - a) * (b - a) / 12.0;
            assert!(
                (m.variance / expected - 1.0).abs() < 1e-3,
                "{shape:?}: {} vs {expected}",
                m.variance
            );
        }
    }

    #[test]
    fn intervals_outside_the_exposure_have_no_mass() {
        let m = shutter(ShutterShape::Box).moments(0.95, 1.0);
        assert_eq!(m.mass, 0.0);
        assert!(m.mean.is_finite() && m.variance == 0.0);
    }
}
