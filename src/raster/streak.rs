//! Exact streaks. A Gaussian splat whose centre slides at constant speed along a chord while the
//! shutter is open leaves the splat convolved with that segment: Gaussian across the motion and
//! an erf difference along it, flat-topped where the chord is long. Measured in the splat's own
//! standard deviations (the metric of its conic Q), with v the position along the chord from its
//! middle, p the distance across it and k the chord's length:
//!
//! ```text
//! f(p, v) = exp(−p²/2) · (Φ(k/2 − v) − Φ(−k/2 − v)) / (k √(2π) √det Σ)
//! ```
//!
//! which integrates to one. It is cut where |p| > 3 or |v| > k/2 + 3 (a parallelogram on screen)
//! and the amplitude is raised by the mass the cut leaves out, found in closed form. A splat whose
//! light grows or fades along the chord (its screen area changing, or its speed) leaves the same
//! streak with a linear density along it, also in closed form. Derivation: docs/math.md, "Exact
//! streaks" and "A streak whose light changes along it".

use super::profile::{exp_half, gaussian_table, GaussianTable};
use super::{columns_within, nearest_step, Shape, CUTOFF_Q, CUTOFF_SIGMAS};
use crate::math::Sym2;
use glam::DVec2;
use std::sync::LazyLock;

/// Chords shorter than this many of the splat's standard deviations along them are drawn as the
/// moment-matched ellipse instead: the streak is then nearly Gaussian, and the erf difference
/// divided by a short chord would lose its digits.
pub const MIN_STREAK_SIGMAS: f64 = 1.0;

/// Φ is tabulated over [−PHI_RANGE, PHI_RANGE]; beyond, it is 0 or 1 to within 10⁻⁹.
const PHI_RANGE: f32 = 6.0;

/// Steps of the Φ table. The tangent at the nearest entry, at most half a step h = 12/2048 away,
/// errs by at most (h/2)²/2 · max|φ'| = (12/2048)²/8 · 0.242 ≈ 1.0·10⁻⁶ in Φ, and h²/8 ·
/// max|φ''| ≈ 1.7·10⁻⁶ in φ (as linear interpolation between entries would).
const PHI_STEPS: usize = 2048;

/// Φ(t) and φ(t), the standard normal distribution and density, at t = −PHI_RANGE + i · 2
/// PHI_RANGE / PHI_STEPS for i = 0 ..= PHI_STEPS; side by side, so that a lookup of both reads
/// one place.
static PHI_TABLE: LazyLock<PhiTable> = LazyLock::new(|| {
    std::array::from_fn(|i| {
        let t = -f64::from(PHI_RANGE) + i as f64 * 2.0 * f64::from(PHI_RANGE) / PHI_STEPS as f64;
        [normal_cdf(t) as f32, normal_density(t) as f32]
    })
});

/// φ(t) in f64.
fn normal_density(t: f64) -> f64 {
    (-0.5 * t * t).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// Φ(t) in f64, from erfc so that the lower tail keeps its digits.
fn normal_cdf(t: f64) -> f64 {
    0.5 * libm::erfc(-t / std::f64::consts::SQRT_2)
}

/// ψ(x) = ∫ₓ^∞ Φ(−t) dt = φ(x) − x Φ(−x): the mass an erf ramp holds beyond x.
fn ramp_tail(x: f64) -> f64 {
    normal_density(x) - x * normal_cdf(-x)
}

/// The table of Φ and φ.
type PhiTable = [[f32; 2]; PHI_STEPS + 1];

/// Φ(t) from `table` (the [`PHI_TABLE`]).
#[inline]
fn phi(table: &PhiTable, t: f32) -> f32 {
    phi_and_density(table, t)[0]
}

/// Φ(t) and φ(t) from `table`, each from its tangent at the nearest entry: Φ' = φ and φ' = −tφ.
#[inline]
fn phi_and_density(table: &PhiTable, t: f32) -> [f32; 2] {
    const STEP: f32 = 2.0 * PHI_RANGE / PHI_STEPS as f32;
    // Past the last step, its end.
    let u = ((t + PHI_RANGE) * (1.0 / STEP)).min(PHI_STEPS as f32);
    if !(u > 0.0) {
        return [0.0, 0.0];
    }
    let (i, entry) = nearest_step(u);
    let [phi, density] = table[i.min(PHI_STEPS)];
    let offset = (u - entry) * STEP;
    let at = entry * STEP - PHI_RANGE;
    [phi + density * offset, density * (1.0 - at * offset)]
}

/// A footprint's streak: the linear maps from a pixel offset to its place across and along the
/// chord, in the splat's standard deviations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Streak {
    /// p = across · d.
    pub across: [f32; 2],
    /// v = along · d, 0 at the chord's middle.
    pub along: [f32; 2],
    /// Half the chord, k/2.
    pub half_length: f32,
    /// The slide's density is 1 + slope · s at s standard deviations from the chord's middle
    /// (|slope| ≤ 1/(k/2), so it is nowhere negative).
    pub slope: f32,
    /// The colour is the footprint's × (1 + colour_slope · s) at s standard deviations from the
    /// chord's middle.
    pub colour_slope: f32,
}

/// A streak with what its footprint needs besides.
pub(super) struct StreakGeometry {
    pub(super) streak: Streak,
    /// ∫ of the cut profile over the plane, in the splat's unit coordinates (where its covariance
    /// is the identity): the amplitude is weight / (this · √det Σ).
    pub(super) integral: f64,
    /// Half the streak's bounding box, px.
    pub(super) extent: DVec2,
}

impl StreakGeometry {
    /// The streak of a splat of `covariance` (px², pre-filter included) sliding along `chord`
    /// (px), its light along the chord changing by `change` of its mean from end to end (see
    /// [`super::ScreenSplat::sweep_change`]; clamped to ±2, where one end has none) and its
    /// colour by `colour_change`; `None` when the chord is shorter than [`MIN_STREAK_SIGMAS`] or
    /// the covariance is singular.
    pub(super) fn of(
        covariance: &Sym2,
        chord: DVec2,
        change: f64,
        colour_change: f64,
    ) -> Option<StreakGeometry> {
        let conic = covariance.inverse()?;
        let length = conic.quadratic(chord).sqrt();
        let normal = chord.perp();
        let spread = covariance.quadratic(normal).sqrt();
        if !(length >= MIN_STREAK_SIGMAS && spread > 0.0 && length.is_finite()) {
            return None;
        }
        // v(chord) = k and p(chord) = 0; the screen vector Σn/√(nᵀΣn) has v = 0 and p = 1.
        let along = conic.apply(chord) / length;
        let across = normal / spread;
        let (unit_along, unit_across) = (chord / length, covariance.apply(normal) / spread);
        let reach = 0.5 * length + CUTOFF_SIGMAS;
        let extent = unit_along.abs() * reach + unit_across.abs() * CUTOFF_SIGMAS;
        // Mass kept inside the cut: across, a 1D Gaussian within ±3; along, the erf difference's
        // integral k less ψ(3) − ψ(k + 3) beyond each end.
        let kept_across = 1.0 - 2.0 * normal_cdf(-CUTOFF_SIGMAS);
        let kept_along =
            length - 2.0 * (ramp_tail(CUTOFF_SIGMAS) - ramp_tail(reach + 0.5 * length));
        Some(StreakGeometry {
            streak: Streak {
                across: across.as_vec2().to_array(),
                along: along.as_vec2().to_array(),
                half_length: (0.5 * length) as f32,
                slope: (change.clamp(-2.0, 2.0) / length) as f32,
                colour_slope: (colour_change / length) as f32,
            },
            integral: (2.0 * std::f64::consts::PI).sqrt() * kept_across * kept_along,
            extent,
        })
    }
}

/// A streak's cut parallelogram row by row (the columns where both |p| ≤ 3 and |v| ≤ k/2 + 3),
/// and its value.
pub(super) struct StreakRows {
    streak: Streak,
    /// Centre column less ½ (pixel x covers the streak where x + ½ lies inside).
    centre: f32,
    centre_y: f32,
    /// The bounds' first and last column.
    first: f32,
    last: f32,
    /// The tables, fetched once per footprint rather than through their lazy cells per pixel.
    gaussian: &'static GaussianTable,
    phi: &'static PhiTable,
}

impl StreakRows {
    #[inline]
    pub(super) fn new(streak: Streak, center: [f32; 2], [x0, _, x1, _]: [u32; 4]) -> StreakRows {
        StreakRows {
            streak,
            centre: center[0] - 0.5,
            centre_y: center[1],
            first: x0 as f32,
            last: x1 as f32 - 1.0,
            gaussian: gaussian_table(),
            phi: &PHI_TABLE,
        }
    }
}

impl Shape for StreakRows {
    /// p and v at the row's column 0 offset: their parts that the row's dy gives.
    type Row = [f32; 2];

    #[inline]
    fn span(&self, y: u32) -> (u32, u32) {
        let dy = y as f32 + 0.5 - self.centre_y;
        let s = &self.streak;
        let mut range = [self.first - self.centre, self.last - self.centre];
        for ([ax, ay], reach) in [
            (s.across, CUTOFF_SIGMAS as f32),
            (s.along, s.half_length + CUTOFF_SIGMAS as f32),
        ] {
            // |ax·dx + ay·dy| ≤ reach as a range of dx.
            let offset = ay * dy;
            if ax == 0.0 {
                if offset.abs() > reach {
                    return (0, 0);
                }
                continue;
            }
            let (a, b) = ((-reach - offset) / ax, (reach - offset) / ax);
            range = [range[0].max(a.min(b)), range[1].min(a.max(b))];
        }
        if !(range[0] <= range[1]) {
            return (0, 0);
        }
        columns_within(
            self.centre + range[0],
            self.centre + range[1],
            self.first,
            self.last,
        )
    }

    #[inline]
    fn row(&self, dy: f32) -> [f32; 2] {
        [self.streak.across[1] * dy, self.streak.along[1] * dy]
    }

    #[inline]
    fn value(&self, [p_row, v_row]: [f32; 2], dx: f32) -> (f32, f32) {
        let s = &self.streak;
        let (p, v) = (s.across[0] * dx + p_row, s.along[0] * dx + v_row);
        let (q, h) = (p * p, s.half_length);
        if q > CUTOFF_Q || v.abs() > h + CUTOFF_SIGMAS as f32 {
            return (0.0, 0.0);
        }
        if v.abs() <= h - PHI_RANGE {
            // Both ends lie beyond the table, where Φ is 0 or 1 and φ is 0 to within 10⁻⁹: the
            // moments below are M₀ = 1, M₁ = v and M₂ = v² + 1 (about half of a long streak).
            let across = exp_half(self.gaussian, q);
            return (
                across * (1.0 + s.slope * v),
                across * (v + s.slope * (v * v + 1.0)),
            );
        }
        let even_colour = s.colour_slope == 0.0;
        if s.slope == 0.0 && even_colour {
            let value = phi(self.phi, h - v) - phi(self.phi, -h - v);
            return (exp_half(self.gaussian, q) * value, 0.0);
        }
        // The moments Mₙ = ∫ sⁿ φ(v − s) ds over |s| ≤ h, n = 0, 1, 2 (docs/math.md, "A streak
        // whose colour changes along it"), with φ(v − h) = φ(h − v) and φ(v + h) = φ(−h − v)
        // from the same lookups. The light is ∫ (1 + slope·s) φ(v − s) ds = M₀ + slope·M₁, its
        // first moment M₁ + slope·M₂.
        let ([upper, density_upper], [lower, density_lower]) = (
            phi_and_density(self.phi, h - v),
            phi_and_density(self.phi, -h - v),
        );
        let m0 = upper - lower;
        let ends = density_lower - density_upper;
        let m1 = m0 * v + ends;
        let across = exp_half(self.gaussian, q);
        let value = across * (m0 + s.slope * m1);
        if even_colour {
            return (value, 0.0);
        }
        // ∫ (u + v)² φ(u) du over [−h − v, h − v].
        let m2 = m0 * (v * v + 1.0) + 2.0 * v * ends
            - ((h - v) * density_upper + (h + v) * density_lower);
        (value, across * (m1 + s.slope * m2))
    }

    #[inline]
    fn colour_slope(&self) -> Option<f32> {
        let slope = self.streak.colour_slope;
        (slope != 0.0).then_some(slope)
    }

    /// Against a long streak's peak, 1, whatever this one's: a streak k standard deviations long
    /// peaks at 2Φ(k/2) − 1 (0.38 at k = 1, 0.87 at k = 3), so on a short one the threshold is a
    /// larger share of its own peak (docs/math.md, "Faint footprints").
    fn faint_below(&self) -> f32 {
        super::composite::FAINT_VALUE
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::{Footprint, Profile, ScreenSplat, TimeExtent};

    /// A Gaussian splat of `covariance` sliding along `sweep`, centred at (40.3, 31.6) in a
    /// 96 × 64 image.
    fn streak(covariance: Sym2, sweep: DVec2, weight: f64) -> Footprint {
        sloped_streak(covariance, sweep, 0.0, weight)
    }

    /// [`streak`] with its light changing by `change` of its mean along the chord.
    fn sloped_streak(covariance: Sym2, sweep: DVec2, change: f64, weight: f64) -> Footprint {
        coloured_streak(covariance, sweep, change, 0.0, weight)
    }

    /// [`sloped_streak`] coloured (1, ½, ¼) at its middle, its colour changing by
    /// `colour_change` of itself from start to end.
    fn coloured_streak(
        covariance: Sym2,
        sweep: DVec2,
        change: f64,
        colour_change: f64,
        weight: f64,
    ) -> Footprint {
        ScreenSplat {
            center: DVec2::new(40.3, 31.6),
            covariance,
            weight,
            colour: COLOUR,
            depth: 1.0,
            depth_gradient: DVec2::ZERO,
            depth_tolerance: 0.01,
            depth_rate: 0.0,
            time: TimeExtent::WHOLE_FRAME,
            profile: Profile::Gaussian,
            sweep,
            sweep_change: change,
            colour_change,
            additive: false,
        }
        .footprint(96, 64)
        .unwrap()
    }

    const COLOUR: [f32; 3] = [1.0, 0.5, 0.25];

    fn pixels() -> impl Iterator<Item = (u32, u32)> {
        (0..64).flat_map(|y| (0..96).map(move |x| (x, y)))
    }

    const TILTED: Sym2 = Sym2 {
        xx: 2.3,
        xy: 0.9,
        yy: 1.1,
    };

    #[test]
    fn a_streak_is_the_splat_integrated_along_its_chord() {
        // The closed form against the midpoint rule over 4,000 positions of the sliding splat, at
        // pixels inside the cut, with its light even along the chord, growing from a third of
        // its mean to 5/3 of it, and fading to nothing: the tables' error (10⁻⁶ of the peak), the
        // density's cut at 3σ and f32 rounding remain.
        let (covariance, sweep) = (TILTED, DVec2::new(31.0, -12.0));
        let conic = covariance.inverse().unwrap();
        let norm = 5.0 / (std::f64::consts::TAU * covariance.det().sqrt());
        for change in [0.0, 1.333, -2.0] {
            let f = sloped_streak(covariance, sweep, change, 5.0);
            assert!(f.streak.is_some());
            let mut checked = 0;
            for (x, y) in pixels() {
                let d = DVec2::new(f64::from(x) + 0.5 - 40.3, f64::from(y) + 0.5 - 31.6);
                let steps = 4000;
                let exact: f64 = (0..steps)
                    .map(|i| {
                        let u = (f64::from(i) + 0.5) / f64::from(steps) - 0.5;
                        (1.0 + change * u) * (-0.5 * conic.quadratic(d - u * sweep)).exp()
                    })
                    .sum::<f64>()
                    * norm
                    / f64::from(steps);
                let drawn = f64::from(f.weight_at(x, y, None));
                if drawn > 0.0 {
                    // The amplitude also carries the cut's gain, 0.27 %.
                    assert!(
                        (drawn - exact).abs() < 0.004 * exact + 2e-5 * norm,
                        "change {change}, ({x}, {y}): {drawn} vs {exact}"
                    );
                    checked += 1;
                } else {
                    assert!(exact < 0.012 * norm, "({x}, {y}) left out at {exact}");
                }
            }
            assert!(checked > 200, "{checked}");
        }
    }

    #[test]
    fn a_streak_whose_colour_changes_is_the_coloured_splat_integrated_along_its_chord() {
        // As above, the light weighted by a colour scaled linearly along the chord (its shading
        // changing), with the light even, growing and fading: the moments' closed forms against
        // the midpoint rule, channel by channel.
        let (covariance, sweep) = (TILTED, DVec2::new(31.0, -12.0));
        let conic = covariance.inverse().unwrap();
        let norm = 5.0 / (std::f64::consts::TAU * covariance.det().sqrt());
        let colour_change = 0.8;
        for change in [0.0, 1.333, -2.0] {
            let f = coloured_streak(covariance, sweep, change, colour_change, 5.0);
            let mut checked = 0;
            for (x, y) in pixels() {
                let d = DVec2::new(f64::from(x) + 0.5 - 40.3, f64::from(y) + 0.5 - 31.6);
                let steps = 4000;
                let mut exact = [0.0f64; 3];
                for i in 0..steps {
                    let u = (f64::from(i) + 0.5) / f64::from(steps) - 0.5;
                    let light = (1.0 + change * u) * (-0.5 * conic.quadratic(d - u * sweep)).exp();
                    for c in 0..3 {
                        exact[c] += light * f64::from(COLOUR[c]) * (1.0 + colour_change * u);
                    }
                }
                let exact = exact.map(|e| e * norm / f64::from(steps));
                let drawn = f.light_at(x, y);
                if f.weight_at(x, y, None) > 0.0 {
                    for c in 0..3 {
                        let drawn = f64::from(drawn[c]);
                        assert!(
                            (drawn - exact[c]).abs() < 0.004 * exact[c].abs() + 3e-5 * norm,
                            "change {change}, ({x}, {y}), channel {c}: {drawn} vs {}",
                            exact[c]
                        );
                    }
                    checked += 1;
                }
            }
            assert!(checked > 200, "{checked}");
        }
    }

    #[test]
    fn pixel_samples_of_a_streak_sum_to_its_weight() {
        // Long and short, level and steep, round and tilted splats: the cut's gain restores what
        // the cut leaves out; what remains is pixel-centre sampling (within 0.5 %, as for
        // ellipses at least the pre-filter wide).
        for (covariance, sweep) in [
            (Sym2::isotropic(0.3), DVec2::new(40.0, 0.0)),
            (Sym2::isotropic(0.3), DVec2::new(0.0, 0.6)),
            (TILTED, DVec2::new(31.0, -12.0)),
            (TILTED, DVec2::new(-1.5, 1.8)),
            (Sym2::isotropic(4.0), DVec2::new(5.0, 5.0)),
        ] {
            // A light changing along the chord moves light within the streak, not its sum.
            for change in [0.0, 0.8, -2.0] {
                let f = sloped_streak(covariance, sweep, change, 2.0);
                assert!(f.streak.is_some(), "{sweep}");
                let sum: f32 = pixels().map(|(x, y)| f.weight_at(x, y, None)).sum();
                assert!((sum - 2.0).abs() < 2.0 * 0.005, "{sweep}, {change}: {sum}");
            }
        }
    }

    #[test]
    fn row_spans_cover_exactly_the_pixels_inside_the_cut() {
        for sweep in [
            DVec2::new(31.0, -12.0),
            DVec2::new(0.0, 20.0),
            DVec2::new(25.0, 0.0),
        ] {
            let f = streak(TILTED, sweep, 1.0);
            let s = f.streak.unwrap();
            let rows = StreakRows::new(s, f.center, f.bounds);
            for (x, y) in pixels() {
                let (dx, dy) = (x as f32 + 0.5 - f.center[0], y as f32 + 0.5 - f.center[1]);
                let p = s.across[0] * dx + s.across[1] * dy;
                let v = s.along[0] * dx + s.along[1] * dy;
                let inside = p.abs() <= 3.0 && v.abs() <= s.half_length + 3.0;
                let on_edge =
                    (p.abs() - 3.0).abs() < 1e-3 || (v.abs() - s.half_length - 3.0).abs() < 1e-3;
                let (x0, x1) = rows.span(y);
                if !on_edge {
                    assert_eq!(inside, (x0..x1).contains(&x), "{sweep}: ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn a_slide_shorter_than_a_standard_deviation_is_the_moment_matched_ellipse() {
        // Below MIN_STREAK_SIGMAS the footprint is Σ + m mᵀ/12; just above, the streak. Both have
        // the same moments, and at the threshold they differ by little.
        let sweep = |k: f64| DVec2::new(k * 0.3f64.sqrt(), 0.0);
        let below = streak(Sym2::isotropic(0.3), sweep(0.99), 1.0);
        let above = streak(Sym2::isotropic(0.3), sweep(1.01), 1.0);
        assert!(below.streak.is_none() && above.streak.is_some());
        let l1: f32 = pixels()
            .map(|(x, y)| (below.weight_at(x, y, None) - above.weight_at(x, y, None)).abs())
            .sum();
        assert!(l1 < 0.03, "{l1}");
    }

    #[test]
    fn the_phi_table_matches_erfc_and_the_density_to_their_stated_error() {
        for i in 0..=4000 {
            let t = -7.0 + 14.0 * f64::from(i) / 4000.0;
            let [cdf, density] = phi_and_density(&PHI_TABLE, t as f32).map(f64::from);
            let err = (cdf - normal_cdf(t)).abs();
            assert!(err < 1.5e-6, "Φ({t}) off by {err}");
            let err = (density - normal_density(t)).abs();
            assert!(err < 2.5e-6, "φ({t}) off by {err}");
        }
    }

    #[test]
    fn the_ramp_tail_is_the_integral_of_the_lower_tail() {
        // ψ(x) = ∫ₓ^∞ Φ(−t) dt by the midpoint rule.
        for x in [-2.0, 0.0, 1.5, 3.0] {
            let h = 1e-3;
            let numeric: f64 = (0..20_000)
                .map(|i| normal_cdf(-(x + (f64::from(i) + 0.5) * h)) * h)
                .sum();
            assert!((numeric - ramp_tail(x)).abs() < 1e-7, "ψ({x})");
        }
    }
}
