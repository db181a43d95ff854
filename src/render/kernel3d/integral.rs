//! The closed-form line integral of a 3D kernel along a pixel ray (Heinzle et al. 2010, §4.2,
//! eqs. 18–20), with numerics that hold in the tails (docs/math.md, "Stable erf differences").
//!
//! Along a pixel ray, the point where the ray meets the splat plane at kernel time s ∈ [−1, 1]
//! has splat-local coordinates p + s·q (in standard deviations), so the kernel's value there is
//! exp(−½ |p + s q|²) = exp(−½ (a s² + 2 b s + c)) with a = |q|², b = p·q, c = |p|²: a Gaussian in
//! s, whose integral over any sub-interval is a Gaussian factor times an erf difference.

use std::f64::consts::PI;

/// The exponent a s² + 2 b s + c of a kernel along one ray (a, c ≥ 0, b² ≤ a c).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayQuadratic {
    /// |q|²: how fast the hit point moves through the splat with kernel time.
    pub a: f64,
    /// p·q.
    pub b: f64,
    /// |p|²: the squared radius at s = 0.
    pub c: f64,
}

/// Below this a·(s₁ − s₀)², the integrand is constant over the interval to within 1e-12
/// relative: the ray runs (almost) parallel to the time axis, and the erf form would divide by
/// √a → 0. The limit exp(−c/2)·(s₁ − s₀) is used instead.
const FLAT: f64 = 1e-12;

impl RayQuadratic {
    /// The exponent at s.
    #[must_use]
    pub fn at(&self, s: f64) -> f64 {
        (self.a * s + 2.0 * self.b) * s + self.c
    }

    /// The interval of s where a s² + 2 b s + c ≤ `radius_sq`, clipped to [`lo`, `hi`]: where the
    /// ray is inside the kernel's bounding cylinder (§4.3). `None` when empty.
    #[must_use]
    pub fn support(&self, radius_sq: f64, lo: f64, hi: f64) -> Option<[f64; 2]> {
        let (a, b, c) = (self.a, self.b, self.c - radius_sq);
        let [s0, s1] = if a * (hi - lo) * (hi - lo) < FLAT {
            // Constant in s (to the flat tolerance): inside for all s, or for none.
            if self.at(0.5 * (lo + hi)) <= radius_sq {
                [lo, hi]
            } else {
                return None;
            }
        } else {
            let discriminant = b * b - a * c;
            if !(discriminant >= 0.0) {
                return None;
            }
            // Roots without cancellation: q = −(b + sign(b)√D), roots q/a and c/q.
            let q = -(b + b.signum() * discriminant.sqrt());
            let (r0, r1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
            [r0.min(r1), r0.max(r1)]
        };
        let (s0, s1) = (s0.max(lo), s1.min(hi));
        (s0 < s1).then_some([s0, s1])
    }

    /// ∫ exp(−½ (a s² + 2 b s + c)) ds over [s0, s1] (eq. 19 with δ = ½), accurate to a few ulps
    /// of the result even when the interval lies deep in a tail. (The renderer takes differences
    /// of [`RayQuadratic::primitive`], which is the same computation.)
    #[cfg(test)]
    pub fn integral(&self, s0: f64, s1: f64) -> f64 {
        if !(s1 > s0) {
            return 0.0;
        }
        let primitive = self.primitive([s0, s1]);
        primitive.at(s1) - primitive.at(s0)
    }

    /// An antiderivative in s, for differences within `range`: one erf-family evaluation per
    /// point, so that an A-buffer cutting a fragment into many pieces pays once per cut.
    #[must_use]
    pub fn primitive(&self, [s0, s1]: [f64; 2]) -> Primitive {
        let a = self.a;
        if a * (s1 - s0) * (s1 - s0) < FLAT {
            let s = 0.5 * (s0 + s1);
            return Primitive::Flat {
                rate: (-0.5 * self.at(s)).exp(),
            };
        }
        // a s² + 2 b s + c = a (s − m)² + r with m = −b/a, r = c − b²/a ≥ 0.
        let centre = -self.b / a;
        let r = (self.c - self.b * self.b / a).max(0.0);
        let k = (0.5 * a).sqrt();
        let (x0, x1) = (k * (s0 - centre), k * (s1 - centre));
        // Where the whole range lies on one side of the peak, differences of erfc on that side
        // keep every digit that erf rounds away (erf(6) is 1 − 2·10⁻¹⁷ in f64, erfc(6) is exact
        // to the last bit): erf(x1) − erf(x0) = erfc(x0) − erfc(x1) = erfc(−x1) − erfc(−x0).
        let side = if x0 >= 0.0 {
            Side::Right
        } else if x1 <= 0.0 {
            Side::Left
        } else {
            Side::Both
        };
        Primitive::Gauss {
            scale: (-0.5 * r).exp() * 0.5 * PI.sqrt() / k,
            k,
            centre,
            side,
        }
    }
}

/// Which erf-family function an antiderivative uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Side {
    /// The range lies left of the peak: erfc(−x).
    Left,
    /// The range holds the peak: erf(x).
    Both,
    /// The range lies right of the peak: −erfc(x).
    Right,
}

/// An antiderivative of exp(−½ (a s² + 2 b s + c)) in s, valid for differences within the range
/// it was made for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    /// The integrand is constant (to 1e-12 relative) over the range.
    Flat {
        /// Its value.
        rate: f64,
    },
    /// scale · erf(k (s − centre)), written with erfc on a one-sided range.
    Gauss {
        /// exp(−r/2) √π / (2k).
        scale: f64,
        /// √(a/2).
        k: f64,
        /// Where the Gaussian peaks, −b/a.
        centre: f64,
        /// The erf-family form used.
        side: Side,
    },
}

impl Primitive {
    /// The antiderivative at s.
    #[must_use]
    pub fn at(&self, s: f64) -> f64 {
        match *self {
            Primitive::Flat { rate } => rate * s,
            Primitive::Gauss {
                scale,
                k,
                centre,
                side,
            } => {
                let x = k * (s - centre);
                scale
                    * match side {
                        Side::Left => libm::erfc(-x),
                        Side::Both => libm::erf(x),
                        Side::Right => -libm::erfc(x),
                    }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The integral by composite Simpson's rule on a fine grid.
    fn simpson(q: &RayQuadratic, s0: f64, s1: f64) -> f64 {
        let n = 20_000;
        let h = (s1 - s0) / n as f64;
        let f = |s: f64| (-0.5 * q.at(s)).exp();
        let mut sum = f(s0) + f(s1);
        for i in 1..n {
            sum += f(s0 + h * i as f64) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        sum * h / 3.0
    }

    #[test]
    fn the_closed_form_matches_quadrature() {
        for (a, b, c) in [
            (1.0, 0.3, 0.5),
            (40.0, -7.0, 2.0),
            (0.01, 0.001, 0.3),
            (9.0, 9.0, 9.5),
        ] {
            let q = RayQuadratic { a, b, c };
            for (s0, s1) in [(-1.0, 1.0), (-0.3, 0.7), (0.5, 0.9)] {
                let (closed, numeric) = (q.integral(s0, s1), simpson(&q, s0, s1));
                assert!(
                    (closed - numeric).abs() <= 1e-9 * numeric.max(1e-300),
                    "{q:?} [{s0}, {s1}]: {closed} vs {numeric}"
                );
            }
        }
    }

    #[test]
    fn deep_tails_keep_their_digits() {
        // The interval lies 6–8 standard deviations out: erf(x1) − erf(x0) in plain f64 is 0 (or
        // noise), the erfc form is exact. The integrand is ≈ exp(−18 ... −32), tiny but not 0.
        let q = RayQuadratic {
            a: 1.0,
            b: 0.0,
            c: 0.0,
        };
        let tail = q.integral(6.0, 8.0);
        let expected = simpson(&q, 6.0, 8.0);
        assert!(
            tail > 0.0 && (tail / expected - 1.0).abs() < 1e-9,
            "{tail} vs {expected}"
        );
        // Mirrored, the same.
        assert_eq!(q.integral(-8.0, -6.0), tail);
        // Far beyond: exactly zero, never NaN.
        assert_eq!(q.integral(60.0, 80.0), 0.0);
        let huge = RayQuadratic {
            a: 1e30,
            b: 1e15,
            c: 1e300,
        };
        assert_eq!(huge.integral(-1.0, 1.0), 0.0);
    }

    #[test]
    fn a_ray_parallel_to_the_time_axis_takes_the_limit() {
        // a → 0: the hit point does not move through the splat (no motion, or motion along the
        // ray). The integral tends to exp(−c/2)·length, continuously.
        for a in [0.0, 1e-20, 1e-13] {
            let q = RayQuadratic { a, b: 0.0, c: 2.0 };
            let value = q.integral(-1.0, 1.0);
            assert!(
                (value - 2.0 * (-1.0f64).exp()).abs() < 1e-9,
                "a = {a}: {value}"
            );
        }
        let just_above = RayQuadratic {
            a: 1e-9,
            b: 0.0,
            c: 2.0,
        };
        assert!((just_above.integral(-1.0, 1.0) - 2.0 * (-1.0f64).exp()).abs() < 1e-9);
    }

    #[test]
    fn the_support_is_where_the_ray_is_inside_the_cylinder() {
        let q = RayQuadratic {
            a: 4.0,
            b: -2.0,
            c: 1.0,
        };
        // 4s² − 4s + 1 = (2s − 1)² ≤ 9  ⇔  s ∈ [−1, 2], clipped to [−1, 1].
        let [s0, s1] = q.support(9.0, -1.0, 1.0).unwrap();
        assert!((s0 + 1.0).abs() < 1e-12 && (s1 - 1.0).abs() < 1e-12);
        let [s0, s1] = q.support(1.0, -1.0, 1.0).unwrap();
        assert!(s0.abs() < 1e-12 && (s1 - 1.0).abs() < 1e-12);
        assert!(q.support(9.0, 3.0, 4.0).is_none());
        let still = RayQuadratic {
            a: 0.0,
            b: 0.0,
            c: 10.0,
        };
        assert!(still.support(9.0, -1.0, 1.0).is_none());
        assert_eq!(
            RayQuadratic { c: 4.0, ..still }.support(9.0, -1.0, 1.0),
            Some([-1.0, 1.0])
        );
        // Roots from the stable formula agree with the quadratic.
        let wide = RayQuadratic {
            a: 1e-6,
            b: 1e-3,
            c: 0.5,
        };
        if let Some([s0, s1]) = wide.support(9.0, -1e6, 1e6) {
            assert!((wide.at(s0) - 9.0).abs() < 1e-6 && (wide.at(s1) - 9.0).abs() < 1e-6);
        }
    }
}
