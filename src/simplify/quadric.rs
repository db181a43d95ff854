//! Quadric error metrics (Garland & Heckbert 1997, §5): the squared distances of a point to a
//! set of planes, summed, as one symmetric 4 × 4 matrix per vertex.

use glam::DVec3;

/// Σ w (n·p + d)² over planes (n, d) with weights w, kept as the ten distinct entries of the
/// symmetric matrix w [n d]ᵀ[n d]: `[aa, ab, ac, ad, bb, bc, bd, cc, cd, dd]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Quadric([f64; 10]);

/// Below this, relative to the cube of the matrix's largest entry, a 3 × 3 determinant is singular
/// for placement: the planes do not pin a point (a flat patch, a straight crease), and the
/// minimum is a line or a plane of points rather than one.
const SINGULAR: f64 = 1e-10;

impl Quadric {
    /// The plane through `point` with unit normal `normal`, weighted by `weight`.
    #[must_use]
    pub fn plane(normal: DVec3, point: DVec3, weight: f64) -> Quadric {
        let [a, b, c] = normal.to_array();
        let d = -normal.dot(point);
        let w = weight;
        Quadric([
            w * a * a,
            w * a * b,
            w * a * c,
            w * a * d,
            w * b * b,
            w * b * c,
            w * b * d,
            w * c * c,
            w * c * d,
            w * d * d,
        ])
    }

    /// The weighted squared distance of `p` to the planes: pᵀ Q p with p = (x, y, z, 1).
    #[must_use]
    pub fn error(&self, p: DVec3) -> f64 {
        let [aa, ab, ac, ad, bb, bc, bd, cc, cd, dd] = self.0;
        let [x, y, z] = p.to_array();
        let e = x * (aa * x + 2.0 * (ab * y + ac * z + ad))
            + y * (bb * y + 2.0 * (bc * z + bd))
            + z * (cc * z + 2.0 * cd)
            + dd;
        // Rounding may take a sum of squares a hair below zero.
        e.max(0.0)
    }

    /// The point that minimizes the error, when the planes pin one down (§4: solve the 3 × 3
    /// system A p = −b by Cramer's rule); `None` when A is near singular.
    #[must_use]
    pub fn minimum(&self) -> Option<DVec3> {
        let [aa, ab, ac, ad, bb, bc, bd, cc, cd, _] = self.0;
        let c0 = bb * cc - bc * bc;
        let c1 = ac * bc - ab * cc;
        let c2 = ab * bc - ac * bb;
        let det = aa * c0 + ab * c1 + ac * c2;
        let scale = aa.abs().max(bb.abs()).max(cc.abs());
        if !(det.abs() > SINGULAR * scale * scale * scale) {
            return None;
        }
        // The inverse of the symmetric A, applied to −b = −(ad, bd, cd).
        let i01 = c1;
        let i02 = c2;
        let i11 = aa * cc - ac * ac;
        let i12 = ab * ac - aa * bc;
        let i22 = aa * bb - ab * ab;
        let p = DVec3::new(
            -(c0 * ad + i01 * bd + i02 * cd),
            -(i01 * ad + i11 * bd + i12 * cd),
            -(i02 * ad + i12 * bd + i22 * cd),
        ) / det;
        p.is_finite().then_some(p)
    }
}

impl std::ops::Add for Quadric {
    type Output = Quadric;
    fn add(self, other: Quadric) -> Quadric {
        let mut sum = self;
        sum += other;
        sum
    }
}

impl std::ops::AddAssign for Quadric {
    fn add_assign(&mut self, other: Quadric) {
        for (a, b) in self.0.iter_mut().zip(other.0) {
            *a += b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_is_the_weighted_squared_distance() {
        let q = Quadric::plane(DVec3::Z, DVec3::new(0.0, 0.0, 1.0), 2.0);
        assert!((q.error(DVec3::new(5.0, -3.0, 4.0)) - 2.0 * 9.0).abs() < 1e-12);
        assert_eq!(q.error(DVec3::new(7.0, 1.0, 1.0)), 0.0);
    }

    #[test]
    fn three_planes_meet_at_their_corner_and_two_do_not_pin_a_point() {
        let corner = DVec3::new(1.0, -2.0, 3.0);
        let two = Quadric::plane(DVec3::X, corner, 1.0) + Quadric::plane(DVec3::Y, corner, 1.0);
        assert_eq!(two.minimum(), None);
        let three = two + Quadric::plane(DVec3::Z, corner, 0.5);
        let p = three.minimum().unwrap();
        assert!((p - corner).length() < 1e-12, "{p}");
        assert!(three.error(p) < 1e-20);
    }
}
