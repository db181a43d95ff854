//! Small linear algebra the stages share: symmetric 2×2 matrices (screen covariances and
//! conics) with their eigen-decomposition, and the smallest eigenvector of a symmetric 3×3 matrix
//! (a point neighbourhood's normal); the quadratic's roots; and a Morton (Z-order) curve, to lay
//! points out so that neighbours in space sit near each other in memory.

use glam::{DMat3, DVec2, DVec3};

/// A symmetric 2×2 matrix (a covariance or its inverse, the conic).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sym2 {
    /// Row 0, column 0.
    pub xx: f64,
    /// The off-diagonal entry.
    pub xy: f64,
    /// Row 1, column 1.
    pub yy: f64,
}

impl Sym2 {
    /// σ² I.
    #[must_use]
    pub fn isotropic(variance: f64) -> Self {
        Sym2 {
            xx: variance,
            xy: 0.0,
            yy: variance,
        }
    }

    /// v vᵀ.
    #[must_use]
    pub fn outer(v: DVec2) -> Self {
        Sym2 {
            xx: v.x * v.x,
            xy: v.x * v.y,
            yy: v.y * v.y,
        }
    }

    /// vᵀ S v.
    #[must_use]
    pub fn quadratic(&self, v: DVec2) -> f64 {
        self.xx * v.x * v.x + 2.0 * self.xy * v.x * v.y + self.yy * v.y * v.y
    }

    /// S v.
    #[must_use]
    pub fn apply(&self, v: DVec2) -> DVec2 {
        DVec2::new(self.xx * v.x + self.xy * v.y, self.xy * v.x + self.yy * v.y)
    }

    /// The determinant.
    #[must_use]
    pub fn det(&self) -> f64 {
        self.xx * self.yy - self.xy * self.xy
    }

    /// Every entry times `k`.
    #[must_use]
    pub fn scaled(&self, k: f64) -> Self {
        Sym2 {
            xx: self.xx * k,
            xy: self.xy * k,
            yy: self.yy * k,
        }
    }

    /// The inverse, or `None` when singular or not finite.
    #[must_use]
    pub fn inverse(&self) -> Option<Self> {
        let det = self.det();
        if !(det > 0.0 && det.is_finite()) {
            return None;
        }
        Some(Sym2 {
            xx: self.yy / det,
            xy: -self.xy / det,
            yy: self.xx / det,
        })
    }

    /// Eigenvalues (largest first) and unit eigenvectors. The eigenvector of the largest is the
    /// longer of (xy, λ₁ − xx) and (λ₁ − yy, xy), which both solve the eigen-equation and are
    /// never both near zero; with no spread, the axes.
    #[must_use]
    pub fn eigen(&self) -> ([f64; 2], [DVec2; 2]) {
        let mean = 0.5 * (self.xx + self.yy);
        let spread = (0.25 * (self.xx - self.yy).powi(2) + self.xy * self.xy).sqrt();
        let largest = mean + spread;
        let direction = if spread > 0.0 {
            let (p, q) = (
                DVec2::new(self.xy, largest - self.xx),
                DVec2::new(largest - self.yy, self.xy),
            );
            if p.length_squared() > q.length_squared() {
                p.normalize()
            } else {
                q.normalize()
            }
        } else {
            DVec2::X
        };
        ([largest, mean - spread], [direction, direction.perp()])
    }

    /// The principal axes of a covariance, each scaled to its standard deviation (a negative
    /// eigenvalue, from rounding, counts as zero).
    #[must_use]
    pub fn principal_axes(&self) -> (DVec2, DVec2) {
        let ([major, minor], [a, b]) = self.eigen();
        (a * major.sqrt(), b * minor.max(0.0).sqrt())
    }
}

impl std::ops::Add for Sym2 {
    type Output = Sym2;
    fn add(self, o: Sym2) -> Sym2 {
        Sym2 {
            xx: self.xx + o.xx,
            xy: self.xy + o.xy,
            yy: self.yy + o.yy,
        }
    }
}

/// The unit vector along `v`, or `None` for a zero or non-finite `v`. Where its squared length
/// overflows ([10³⁰⁰, 10³⁰⁰, 0]) or vanishes ([10⁻³⁰⁰, 0, 0]), `v` is scaled by its largest
/// component first, so that it still has a direction.
#[must_use]
pub fn unit_direction(v: DVec3) -> Option<DVec3> {
    v.try_normalize()
        .or_else(|| (v / v.abs().max_element()).try_normalize())
}

/// v vᵀ.
#[must_use]
pub fn outer3(v: DVec3) -> DMat3 {
    DMat3::from_cols(v * v.x, v * v.y, v * v.z)
}

/// Unit eigenvector of the smallest eigenvalue of a symmetric 3×3 matrix, by cyclic Jacobi
/// rotations: slower than a closed form but accurate even when eigenvalues nearly coincide.
pub fn smallest_eigenvector(mut a: [[f64; 3]; 3]) -> DVec3 {
    let mut vectors = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..50 {
        let off_diagonal = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diagonal = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if off_diagonal <= 1e-30 * diagonal {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let r = 3 - p - q;
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + theta.hypot(1.0));
            let c = 1.0 / t.hypot(1.0);
            let s = t * c;
            a[p][p] -= t * a[p][q];
            a[q][q] += t * a[p][q];
            a[p][q] = 0.0;
            a[q][p] = 0.0;
            let (arp, arq) = (a[r][p], a[r][q]);
            a[r][p] = c * arp - s * arq;
            a[p][r] = a[r][p];
            a[r][q] = s * arp + c * arq;
            a[q][r] = a[r][q];
            for row in &mut vectors {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let smallest = (0..3)
        .min_by(|&i, &j| a[i][i].total_cmp(&a[j][j]))
        .unwrap_or(0);
    let column = DVec3::new(
        vectors[0][smallest],
        vectors[1][smallest],
        vectors[2][smallest],
    );
    column.try_normalize().unwrap_or(DVec3::Z)
}

/// ⌊x⌋ as an integer, saturating at the ends of i64 (NaN gives 0): a cast and a compare, where
/// `f64::floor` is a library call on the baseline x86-64 target.
#[must_use]
pub fn floor_to_i64(x: f64) -> i64 {
    let truncated = x as i64;
    truncated.saturating_sub(i64::from((truncated as f64) > x))
}

/// x rounded to the nearest integer, halves away from zero as `f64::round` (a library call on the
/// baseline x86-64 target), saturating at the ends of i64 (NaN gives 0).
#[must_use]
pub fn round_to_i64(x: f64) -> i64 {
    let truncated = x as i64;
    // Exact where the cast is: a whole number's distance from x within 2⁵² of zero.
    let rest = x - truncated as f64;
    if rest >= 0.5 {
        truncated.saturating_add(1)
    } else if rest <= -0.5 {
        truncated.saturating_sub(1)
    } else {
        truncated
    }
}

/// Real roots of a·x² + b·x + c = 0 in ascending order, as (roots, how many): none, one or two,
/// a double root once.
///
/// The stable form: q = −(b + sign(b)·√(b² − 4ac))/2, roots q/a and c/q, so neither root comes
/// from subtracting nearly equal numbers. A leading term that is negligible against the others
/// (|a| ≤ 1e-12·(|b| + |c|)) makes the equation linear: its second root lies beyond 10¹² of the
/// scale and is left out. Non-finite coefficients give no roots; finite ones of any size are
/// solved as well as those near 1.
#[must_use]
pub fn quadratic_roots(a: f64, b: f64, c: f64) -> ([f64; 2], usize) {
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return ([0.0; 2], 0);
    }
    // Far from 1, b² and 4ac overflow (∞ − ∞) or underflow (a double root at −b/2a). The roots
    // are those of the coefficients scaled by a power of two, which is exact.
    let largest = a.abs().max(b.abs()).max(c.abs());
    if largest > 0.0 && !(1e-100..=1e100).contains(&largest) {
        let exponent = libm::ilogb(largest);
        let [a, b, c] = [a, b, c].map(|v| libm::scalbn(v, -exponent));
        return quadratic_roots(a, b, c);
    }
    let scale = b.abs() + c.abs();
    if a.abs() <= 1e-12 * scale || a == 0.0 {
        return if b != 0.0 {
            ([-c / b, 0.0], 1)
        } else {
            ([0.0; 2], 0)
        };
    }
    let discriminant = b * b - 4.0 * a * c;
    if discriminant < 0.0 {
        return ([0.0; 2], 0);
    }
    if discriminant == 0.0 {
        return ([-0.5 * b / a, 0.0], 1);
    }
    let q = -0.5 * (b + b.signum() * discriminant.sqrt());
    // q = 0 only when b = 0 and ac ≥ 0 with a positive discriminant: impossible, but stay safe.
    let (x0, x1) = if q == 0.0 {
        let r = (-c / a).abs().sqrt();
        (-r, r)
    } else {
        (q / a, c / q)
    };
    ([x0.min(x1), x0.max(x1)], 2)
}

/// Whether as² + bs + c surely has no root in [s0, s1]: it is nonzero with one sign at both ends
/// and monotone between them (its slope 2as + b has one sign at both ends). Most quadratics of a
/// short span pass this test, and skip the square root and divisions of [`quadratic_roots`].
#[must_use]
#[inline]
pub fn keeps_sign(a: f64, b: f64, c: f64, [s0, s1]: [f64; 2]) -> bool {
    let value = |s: f64| (a * s + b) * s + c;
    let slope = |s: f64| 2.0 * a * s + b;
    value(s0) * value(s1) > 0.0 && slope(s0) * slope(s1) > 0.0
}

/// Where `g` changes sign in [a, b], given `ga = g(a)` and `gb = g(b)` of opposite signs (or one
/// zero): the secant's root, exact for a linear `g`, then refined by regula falsi (the Illinois
/// variant, which halves the weight of an end kept twice) until the bracket or the step vanishes,
/// a few steps for a `g` that bends gently.
#[must_use]
pub fn sign_change(g: impl Fn(f64) -> f64, [a, b]: [f64; 2], [ga, gb]: [f64; 2]) -> f64 {
    let ([mut lo, mut hi], [mut glo, mut ghi]) = ([a, b], [ga, gb]);
    let mut t = lo + (hi - lo) * glo / (glo - ghi);
    for _ in 0..32 {
        let gt = g(t);
        if gt == 0.0 || !(hi - lo > 1e-12 * (1.0 + b.abs())) {
            break;
        }
        if (gt < 0.0) == (glo < 0.0) {
            (lo, glo) = (t, gt);
            ghi *= 0.5;
        } else {
            (hi, ghi) = (t, gt);
            glo *= 0.5;
        }
        let next = lo + (hi - lo) * glo / (glo - ghi);
        if next == t {
            break;
        }
        t = next;
    }
    t
}

/// The least and greatest coordinates of `points` on each axis (∞ and −∞ for none).
#[must_use]
pub fn bounds(points: impl IntoIterator<Item = DVec3>) -> (DVec3, DVec3) {
    points
        .into_iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        })
}

/// The eight corners of the box from `lo` to `hi`.
#[must_use]
pub fn box_corners(lo: DVec3, hi: DVec3) -> [DVec3; 8] {
    std::array::from_fn(|k| {
        DVec3::select(glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0), hi, lo)
    })
}

/// A Morton (Z-order) curve through a bounding cube, 21 bits per axis: points near each other
/// in space mostly get keys near each other, so data sorted by key is read with fewer cache
/// misses when a computation walks the surface.
#[derive(Clone, Copy, Debug)]
pub struct MortonCurve {
    lo: DVec3,
    scale: f64,
}

/// Cells per axis of the curve, less one.
const MORTON_CELLS: f64 = ((1u32 << 21) - 1) as f64;

impl MortonCurve {
    /// The curve through the bounding cube of `points`.
    pub fn around(points: impl Iterator<Item = DVec3>) -> MortonCurve {
        let (lo, hi) = bounds(points);
        let extent = (hi - lo).max_element();
        MortonCurve {
            lo: if lo.is_finite() { lo } else { DVec3::ZERO },
            scale: if extent.is_finite() && extent > 0.0 {
                MORTON_CELLS / extent
            } else {
                0.0
            },
        }
    }

    /// The key of `p`: its cell's three coordinates, bits interleaved (points outside the cube
    /// go to its faces).
    pub fn key(&self, p: DVec3) -> u64 {
        let q = ((p - self.lo) * self.scale).clamp(DVec3::ZERO, DVec3::splat(MORTON_CELLS));
        // Spreads the 21 low bits of `x` to every third bit.
        let spread = |x: u64| {
            let mut x = x & 0x1f_ffff;
            x = (x | x << 32) & 0x1f_0000_0000_ffff;
            x = (x | x << 16) & 0x1f_0000_ff00_00ff;
            x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
            x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
            (x | x << 2) & 0x1249_2492_4924_9249
        };
        spread(q.x as u64) | spread(q.y as u64) << 1 | spread(q.z as u64) << 2
    }
}

/// A fixed sequence of numbers in [0, 1) from `seed` (a 64-bit linear congruential generator),
/// for tests that need many varied but repeatable inputs.
#[cfg(test)]
pub(crate) fn test_sequence(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1_u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_too_long_or_too_short_for_their_squared_length_still_have_one() {
        let diagonal = DVec3::new(1.0, 1.0, 0.0).normalize();
        for v in [
            DVec3::new(1e300, 1e300, 0.0),
            DVec3::new(1e-300, 1e-300, 0.0),
            DVec3::new(3.0, 3.0, 0.0),
        ] {
            let unit = unit_direction(v).unwrap();
            assert!((unit - diagonal).length() < 1e-15, "{v} → {unit}");
        }
        // An ordinary vector keeps the bits `normalize` gives it.
        let v = DVec3::new(0.5, 0.7, 0.6);
        assert_eq!(unit_direction(v), Some(v.normalize()));
        for v in [DVec3::ZERO, DVec3::new(f64::INFINITY, 0.0, 0.0), DVec3::NAN] {
            assert_eq!(unit_direction(v), None, "{v}");
        }
    }

    #[test]
    fn floor_to_i64_matches_floor_and_saturates() {
        for x in [
            -2.5, -2.0, -0.5, -0.0, 0.0, 0.3, 1.0, 7.999_999, 1e10, -1e10,
        ] {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "{x}");
        }
        assert_eq!(floor_to_i64(f64::INFINITY), i64::MAX);
        assert_eq!(floor_to_i64(f64::NEG_INFINITY), i64::MIN);
        assert_eq!(floor_to_i64(f64::NAN), 0);
    }

    /// Halves, their float neighbours and whole numbers, as `f64::round` has them.
    #[test]
    fn round_to_i64_matches_round_and_saturates() {
        let mut cases = vec![
            0.0,
            -0.0,
            1e10 + 0.5,
            -1e10 - 0.5,
            4.5e15 + 0.5,
            2f64.powi(53),
        ];
        for k in -20..=20 {
            let half = f64::from(k) + 0.5;
            cases.extend([half, half.next_up(), half.next_down(), f64::from(k)]);
        }
        for x in cases {
            assert_eq!(round_to_i64(x), x.round() as i64, "{x}");
        }
        assert_eq!(round_to_i64(0.5f64.next_down()), 0);
        assert_eq!(round_to_i64(f64::INFINITY), i64::MAX);
        assert_eq!(round_to_i64(f64::NEG_INFINITY), i64::MIN);
        assert_eq!(round_to_i64(f64::NAN), 0);
    }

    #[test]
    fn principal_axes_rebuild_the_covariance() {
        for c in [
            Sym2 {
                xx: 2.0,
                xy: 0.7,
                yy: 0.5,
            },
            Sym2 {
                xx: 0.5,
                xy: -0.7,
                yy: 2.0,
            },
            Sym2::isotropic(0.3),
            Sym2 {
                xx: 1.0,
                xy: 0.0,
                yy: 0.0,
            },
        ] {
            let (a, b) = c.principal_axes();
            let rebuilt = Sym2::outer(a) + Sym2::outer(b);
            assert!(
                (rebuilt.xx - c.xx).abs() < 1e-12
                    && (rebuilt.xy - c.xy).abs() < 1e-12
                    && (rebuilt.yy - c.yy).abs() < 1e-12,
                "{c:?}"
            );
            assert!(a.dot(b).abs() < 1e-12 && a.length() >= b.length());
        }
    }

    #[test]
    fn a_quadratic_that_keeps_its_sign_has_no_root_in_the_span() {
        // (s − r)(s − q) over [0, 1] for roots on a grid inside, at and beyond its ends.
        let grid = [-1.5, -0.25, 0.0, 0.1, 0.5, 0.9, 1.0, 1.25, 2.0];
        for &r in &grid {
            for &q in &grid {
                let (a, b, c) = (1.0, -(r + q), r * q);
                let root_within = [r, q].iter().any(|x| (0.0..=1.0).contains(x));
                if root_within {
                    assert!(!keeps_sign(a, b, c, [0.0, 1.0]), "roots {r}, {q}");
                }
                // Scaled by −2 the roots stay.
                assert_eq!(
                    keeps_sign(a, b, c, [0.0, 1.0]),
                    keeps_sign(-2.0 * a, -2.0 * b, -2.0 * c, [0.0, 1.0])
                );
            }
        }
        // Both roots beyond the same end, monotone over the span: passes.
        assert!(keeps_sign(1.0, -(2.0 + 3.0), 6.0, [0.0, 1.0]));
        // A dip between the ends that stays above zero is not monotone: it is left to the roots.
        assert!(!keeps_sign(1.0, -1.0, 1.0, [0.0, 1.0]));
        // A line (a = 0) with its root outside passes; one with its root inside does not.
        assert!(keeps_sign(0.0, 1.0, 0.5, [0.0, 1.0]));
        assert!(!keeps_sign(0.0, 1.0, -0.5, [0.0, 1.0]));
    }

    #[test]
    fn quadratic_roots_are_accurate_in_the_hard_cases() {
        let close = |(roots, n): ([f64; 2], usize), want: &[f64]| {
            let got = &roots[..n];
            got.len() == want.len()
                && got
                    .iter()
                    .zip(want)
                    .all(|(g, w)| (g - w).abs() <= 1e-12 * w.abs().max(1.0))
        };
        // (x − 0.25)(x − 0.75).
        assert!(close(quadratic_roots(1.0, -1.0, 0.1875), &[0.25, 0.75]));
        // A double root.
        assert!(close(quadratic_roots(1.0, -1.0, 0.25), &[0.5]));
        // Roots 10⁻⁸ and 10⁸: the naive formula loses the small one entirely.
        let got = quadratic_roots(1.0, -(1e8 + 1e-8), 1.0);
        assert!(close(got, &[1e-8, 1e8]), "{got:?}");
        // A vanishing leading term: the linear root.
        assert!(close(quadratic_roots(1e-20, 2.0, -1.0), &[0.5]));
        assert!(close(quadratic_roots(0.0, 2.0, -1.0), &[0.5]));
        assert_eq!(quadratic_roots(0.0, 0.0, 1.0).1, 0);
        assert_eq!(quadratic_roots(1.0, 0.0, 1.0).1, 0);
        assert_eq!(quadratic_roots(f64::NAN, 1.0, 1.0).1, 0);
        // b = 0: symmetric roots.
        assert!(close(quadratic_roots(4.0, 0.0, -1.0), &[-0.5, 0.5]));
    }

    #[test]
    fn quadratic_roots_do_not_depend_on_the_coefficients_scale() {
        // 10x² − 10x + 1: roots ½ ∓ √15/10. Scaled by 10¹⁹⁹, b² and 4ac overflowed (∞ − ∞, two
        // NaN roots); by 10⁻²⁰⁰ they underflowed to 0, a double root at ½.
        let (small, large) = (0.5 - 15f64.sqrt() / 10.0, 0.5 + 15f64.sqrt() / 10.0);
        for scale in [1.0, 1e199, 1e-200, 1e-300] {
            let (roots, n) = quadratic_roots(10.0 * scale, -10.0 * scale, scale);
            assert_eq!(n, 2, "scale {scale}: {roots:?}");
            assert!(
                (roots[0] - small).abs() < 1e-14 && (roots[1] - large).abs() < 1e-14,
                "scale {scale}: {roots:?}"
            );
        }
    }
}
