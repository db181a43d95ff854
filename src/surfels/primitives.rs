//! Procedural surfaces centred at the origin, sampled on grids over their parameter domains with
//! exact per-sample cell areas, so that the areas add up to the surface area (the tests check the
//! closed forms).

use glam::DVec3;

use super::{Budget, Surfel, DEFAULT_GREY, LENGTH_RANGE, SIGMA_PER_SPACING};
use crate::error::{Error, Result};

/// Most turns a torus knot may make each way (p and q): the parameter lines are measured with a
/// number of steps proportional to the turns.
pub const MAX_KNOT_TURNS: u32 = 1000;

/// The greatest common divisor of `a` and `b`.
fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// A procedural surface, centred at the origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    /// A sphere of `radius`.
    Sphere {
        /// Radius.
        radius: f64,
    },
    /// A rectangle in the xy plane facing +z, `size = [x, y]`.
    Quad {
        /// Side lengths along x and y.
        size: [f64; 2],
    },
    /// An axis-aligned box, `size = [x, y, z]`.
    Box {
        /// Side lengths along x, y and z.
        size: [f64; 3],
    },
    /// A capped cylinder along y (a rod), of `radius` and `length`.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Length along y.
        length: f64,
    },
    /// A torus in the xz plane around y: `major` radius of the ring, `minor` radius of the tube.
    Torus {
        /// Radius of the ring.
        major: f64,
        /// Radius of the tube.
        minor: f64,
    },
    /// A (p, q) torus knot of tube radius `tube`; `scale` sets its overall size (the core curve
    /// reaches about 3·scale from the centre).
    TorusKnot {
        /// Turns around the torus's axis.
        p: u32,
        /// Turns through the torus's hole.
        q: u32,
        /// Overall size.
        scale: f64,
        /// Tube radius.
        tube: f64,
    },
}

impl Primitive {
    /// Sample the surface into light grey surfels about `spacing` apart, within `budget` (counted
    /// on the sampling grid before anything is allocated). Errors name the field: `spacing`
    /// (outside [`LENGTH_RANGE`], or so small that the budget would be exceeded), a dimension
    /// (`radius`, `size[1]`, …) outside [`LENGTH_RANGE`], or the torus knot itself when p or q is
    /// 0 or more than [`MAX_KNOT_TURNS`], or when they have a common factor.
    pub fn surfels(&self, spacing: f64, budget: Budget) -> Result<Vec<Surfel>> {
        let (lo, hi) = LENGTH_RANGE;
        if !(spacing >= lo && spacing <= hi) {
            return Err(Error::invalid(
                "spacing",
                format!("{spacing}: must be a finite number between {lo:e} and {hi:e}"),
            ));
        }
        let dimensions: Vec<(&str, f64)> = match *self {
            Primitive::Sphere { radius } => vec![("radius", radius)],
            Primitive::Quad { size } => vec![("size[0]", size[0]), ("size[1]", size[1])],
            Primitive::Box { size } => vec![
                ("size[0]", size[0]),
                ("size[1]", size[1]),
                ("size[2]", size[2]),
            ],
            Primitive::Cylinder { radius, length } => vec![("radius", radius), ("length", length)],
            Primitive::Torus { major, minor } => vec![("major", major), ("minor", minor)],
            Primitive::TorusKnot { scale, tube, .. } => vec![("scale", scale), ("tube", tube)],
        };
        for (name, v) in dimensions {
            if !(v >= lo && v <= hi) {
                return Err(Error::invalid(
                    name,
                    format!("{v}: must be a finite number between {lo:e} and {hi:e}"),
                ));
            }
        }
        if let Primitive::TorusKnot { p, q, .. } = *self {
            if !(1..=MAX_KNOT_TURNS).contains(&p) || !(1..=MAX_KNOT_TURNS).contains(&q) {
                return Err(Error::invalid(
                    "",
                    format!(
                        "a torus knot needs p and q from 1 to {MAX_KNOT_TURNS}, not ({p}, {q})"
                    ),
                ));
            }
            let d = gcd(p, q);
            if d > 1 {
                return Err(Error::invalid(
                    "",
                    format!(
                        "({p}, {q}) have the common factor {d}: that curve is the ({}, {}) knot \
                         run {d} times over; give p and q without a common factor",
                        p / d,
                        q / d
                    ),
                ));
            }
        }
        sample(self, spacing, budget).ok_or_else(|| {
            budget.exceeded(
                "spacing",
                &format!("{spacing} would make"),
                "use a larger spacing",
            )
        })
    }
}

/// A sphere of `radius` sampled `spacing` apart, within the default budget (see
/// [`Primitive::surfels`]).
pub fn sphere(radius: f64, spacing: f64) -> Result<Vec<Surfel>> {
    Primitive::Sphere { radius }.surfels(spacing, Budget::default())
}

/// A rectangle of `size` in the xy plane facing +z, sampled `spacing` apart.
pub fn quad(size: [f64; 2], spacing: f64) -> Result<Vec<Surfel>> {
    Primitive::Quad { size }.surfels(spacing, Budget::default())
}

/// An axis-aligned box of `size`, sampled `spacing` apart.
pub fn cuboid(size: [f64; 3], spacing: f64) -> Result<Vec<Surfel>> {
    Primitive::Box { size }.surfels(spacing, Budget::default())
}

/// A capped cylinder along y, sampled `spacing` apart.
pub fn cylinder(radius: f64, length: f64, spacing: f64) -> Result<Vec<Surfel>> {
    Primitive::Cylinder { radius, length }.surfels(spacing, Budget::default())
}

/// A torus in the xz plane around y, sampled `spacing` apart.
pub fn torus(major: f64, minor: f64, spacing: f64) -> Result<Vec<Surfel>> {
    Primitive::Torus { major, minor }.surfels(spacing, Budget::default())
}

/// A (p, q) torus knot, sampled `spacing` apart.
pub fn torus_knot(p: u32, q: u32, scale: f64, tube: f64, spacing: f64) -> Result<Vec<Surfel>> {
    Primitive::TorusKnot { p, q, scale, tube }.surfels(spacing, Budget::default())
}

impl Surfel {
    /// A surfel for a parallelogram cell spanned by the tangent steps `step_u` and `step_v`.
    fn from_cell(position: DVec3, step_u: DVec3, step_v: DVec3, outward: DVec3) -> Option<Self> {
        let cross = step_u.cross(step_v);
        let area = cross.length();
        let mut normal = cross.try_normalize()?;
        if normal.dot(outward) < 0.0 {
            normal = -normal;
        }
        Some(Surfel {
            position,
            normal,
            axis_u: step_u * SIGMA_PER_SPACING,
            axis_v: step_v * SIGMA_PER_SPACING,
            area,
            colour: DEFAULT_GREY,
        })
    }
}

/// Sample `primitive` into surfels about `spacing` apart, or `None` past the budget.
fn sample(primitive: &Primitive, spacing: f64, budget: Budget) -> Option<Vec<Surfel>> {
    let mut out = Sampler {
        surfels: Vec::new(),
        budget,
        over_budget: false,
    };
    match *primitive {
        Primitive::Sphere { radius } => sample_sphere(radius, spacing, &mut out),
        Primitive::Quad { size } => sample_quad(
            DVec3::ZERO,
            DVec3::X * size[0],
            DVec3::Y * size[1],
            spacing,
            &mut out,
        ),
        Primitive::Box { size } => {
            let h = DVec3::from_array(size) * 0.5;
            for axis in 0..3 {
                let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                let (mut span_a, mut span_b) = (DVec3::ZERO, DVec3::ZERO);
                span_a[a] = size[a];
                span_b[b] = size[b];
                for sign in [-1.0, 1.0] {
                    let mut centre = DVec3::ZERO;
                    centre[axis] = sign * h[axis];
                    sample_quad(centre, span_a, span_b, spacing, &mut out);
                }
            }
            // The loop above orients each face by its cross product; make them all point out.
            for s in &mut out.surfels {
                let centre_dir = s.position;
                if s.normal.dot(centre_dir) < 0.0 {
                    s.normal = -s.normal;
                }
            }
        }
        Primitive::Cylinder { radius, length } => {
            let side = |u: f64, v: f64| {
                let phi = u * std::f64::consts::TAU;
                DVec3::new(radius * phi.cos(), (v - 0.5) * length, -radius * phi.sin())
            };
            sample_parametric(side, spacing, |p| DVec3::new(p.x, 0.0, p.z), &mut out);
            for sign in [-1.0, 1.0] {
                sample_disc(
                    DVec3::Y * (0.5 * sign * length),
                    DVec3::Y * sign,
                    radius,
                    spacing,
                    &mut out,
                );
            }
        }
        Primitive::Torus { major, minor } => {
            let ring = move |u: f64| {
                let phi = u * std::f64::consts::TAU;
                DVec3::new(major * phi.cos(), 0.0, -major * phi.sin())
            };
            let surface = move |u: f64, v: f64| {
                let core = ring(u);
                let theta = v * std::f64::consts::TAU;
                let radial = core.normalize();
                core + minor * (theta.cos() * radial + theta.sin() * DVec3::Y)
            };
            let outward = move |p: DVec3| p - DVec3::new(p.x, 0.0, p.z).normalize() * major;
            sample_parametric(surface, spacing, outward, &mut out);
        }
        Primitive::TorusKnot { p, q, scale, tube } => {
            let turns = p.max(q) as usize;
            let (p, q) = (f64::from(p), f64::from(q));
            let curve = move |u: f64| {
                let phi = u * std::f64::consts::TAU;
                let r = 2.0 + (q * phi).cos();
                scale * DVec3::new(r * (p * phi).cos(), -(q * phi).sin(), r * (p * phi).sin())
            };
            let frame = move |u: f64| {
                // At most a thousandth of a turn, and 10⁻⁴ for a knot of ten turns or fewer.
                let h = (1e-3 / turns as f64).min(1e-4);
                let (a, c, b) = (curve(u - h), curve(u), curve(u + h));
                let tangent = (b - a).normalize();
                let bend = b - 2.0 * c + a;
                let normal = (bend - tangent * bend.dot(tangent))
                    .try_normalize()
                    .unwrap_or_else(|| tangent.any_orthonormal_vector());
                (c, normal, tangent.cross(normal))
            };
            let surface = move |u: f64, v: f64| {
                let (c, n, b) = frame(u);
                let theta = v * std::f64::consts::TAU;
                c + tube * (theta.cos() * n + theta.sin() * b)
            };
            // Outward is away from the nearest point of the core curve; the tube is thin enough
            // that the curve point at the same parameter is that point.
            let outward_at = move |u: f64, v: f64| surface(u, v) - frame(u).0;
            sample_parametric_with(surface, spacing, outward_at, turns, &mut out);
        }
    }
    (!out.over_budget).then_some(out.surfels)
}

/// Surfels being sampled, within a budget.
struct Sampler {
    surfels: Vec<Surfel>,
    budget: Budget,
    over_budget: bool,
}

impl Sampler {
    /// Whether `count` more surfels fit; remembers when they do not, and from then on nothing
    /// fits: the object is refused, and the parts after the one that did not fit (a cylinder's
    /// caps after its side) must not spend the budget on surfels that are thrown away.
    fn reserve(&mut self, count: usize) -> bool {
        let fits = !self.over_budget && self.budget.fits(self.surfels.len().saturating_add(count));
        self.over_budget |= !fits;
        fits
    }
}

/// Fibonacci-spiral samples: near-uniform density with exactly equal areas.
fn sample_sphere(radius: f64, spacing: f64, out: &mut Sampler) {
    let total_area = 4.0 * std::f64::consts::PI * radius * radius;
    let count = cell_count(total_area / (spacing * spacing));
    if !out.reserve(count) {
        return;
    }
    let area = total_area / count as f64;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..count {
        let z = 1.0 - (2.0 * i as f64 + 1.0) / count as f64;
        let ring = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * i as f64;
        let normal = DVec3::new(ring * phi.cos(), z, ring * phi.sin());
        out.surfels.push(Surfel::isotropic(
            normal * radius,
            normal,
            area,
            None,
            DEFAULT_GREY,
        ));
    }
}

/// A parallelogram centred at `centre` spanned by `span_a`, `span_b`, normal along their cross product.
fn sample_quad(centre: DVec3, span_a: DVec3, span_b: DVec3, spacing: f64, out: &mut Sampler) {
    let (na, nb) = (
        cell_count(span_a.length() / spacing),
        cell_count(span_b.length() / spacing),
    );
    if !out.reserve(na.saturating_mul(nb)) {
        return;
    }
    let (step_a, step_b) = (span_a / na as f64, span_b / nb as f64);
    let outward = span_a.cross(span_b);
    let corner = centre - 0.5 * (span_a + span_b);
    for j in 0..nb {
        for i in 0..na {
            let p = corner + step_a * (i as f64 + 0.5) + step_b * (j as f64 + 0.5);
            out.surfels
                .extend(Surfel::from_cell(p, step_a, step_b, outward));
        }
    }
}

/// A disc of `radius` at `centre` facing `normal`, in concentric rings of near-square cells.
fn sample_disc(centre: DVec3, normal: DVec3, radius: f64, spacing: f64, out: &mut Sampler) {
    // The rings hold at least π (radius / spacing)² cells, each ring's count being rounded up:
    // refused at once when those do not fit, rather than ring by ring until the budget is spent.
    if !out.reserve(cell_count(
        std::f64::consts::PI * (radius / spacing).powi(2),
    )) {
        return;
    }
    let (e1, e2) = normal.any_orthonormal_pair();
    let rings = cell_count(radius / spacing);
    let dr = radius / rings as f64;
    for k in 0..rings {
        let r = (k as f64 + 0.5) * dr;
        let n = cell_count(std::f64::consts::TAU * r / spacing);
        if !out.reserve(n) {
            return;
        }
        let dphi = std::f64::consts::TAU / n as f64;
        for i in 0..n {
            let phi = (i as f64 + 0.5) * dphi;
            let radial = e1 * phi.cos() + e2 * phi.sin();
            let around = normal.cross(radial);
            // Cell area is exactly the annular sector r·dr·dφ.
            out.surfels.extend(Surfel::from_cell(
                centre + radial * r,
                radial * dr,
                around * (r * dphi),
                normal,
            ));
        }
    }
}

/// Sample a surface f(u, v) over [0,1]² with outward given by a function of the point.
fn sample_parametric(
    surface: impl Fn(f64, f64) -> DVec3,
    spacing: f64,
    outward: impl Fn(DVec3) -> DVec3,
    out: &mut Sampler,
) {
    sample_parametric_with(&surface, spacing, |u, v| outward(surface(u, v)), 1, out);
}

/// Sample a surface f(u, v) over [0,1]² on a grid whose counts follow the mean lengths of the
/// parameter lines; each cell's tangent steps come from central differences. A u-line may wind
/// `turns` times round; its length is measured with at least 32 steps per turn (256 steps
/// measured a (255, 1) knot's so short that its cells came out 200 times too long).
fn sample_parametric_with(
    surface: impl Fn(f64, f64) -> DVec3,
    spacing: f64,
    outward: impl Fn(f64, f64) -> DVec3,
    turns: usize,
    out: &mut Sampler,
) {
    let mean_length = |along_u: bool| {
        let (lines, steps) = (8, if along_u { (32 * turns).max(256) } else { 256 });
        let mut total = 0.0;
        for l in 0..lines {
            let fixed = (l as f64 + 0.5) / lines as f64;
            let at = |s: f64| {
                if along_u {
                    surface(s, fixed)
                } else {
                    surface(fixed, s)
                }
            };
            total += (0..steps)
                .map(|i| at(i as f64 / steps as f64).distance(at((i + 1) as f64 / steps as f64)))
                .sum::<f64>();
        }
        total / lines as f64
    };
    let nu = cell_count(mean_length(true) / spacing);
    let nv = cell_count(mean_length(false) / spacing);
    if !out.reserve(nu.saturating_mul(nv)) {
        return;
    }
    let (du, dv) = (1.0 / nu as f64, 1.0 / nv as f64);
    for j in 0..nv {
        for i in 0..nu {
            let (u, v) = ((i as f64 + 0.5) * du, (j as f64 + 0.5) * dv);
            let h = 1e-3;
            let step_u = (surface(u + h * du, v) - surface(u - h * du, v)) / (2.0 * h);
            let step_v = (surface(u, v + h * dv) - surface(u, v - h * dv)) / (2.0 * h);
            out.surfels.extend(Surfel::from_cell(
                surface(u, v),
                step_u,
                step_v,
                outward(u, v),
            ));
        }
    }
}

/// At least one cell; never a count that would not fit in memory for a sane spacing.
fn cell_count(ratio: f64) -> usize {
    if ratio.is_finite() {
        ratio.ceil().clamp(1.0, 1e9) as usize
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn total_area(s: &[Surfel]) -> f64 {
        s.iter().map(|s| s.area).sum()
    }

    #[test]
    fn nothing_is_sampled_once_the_budget_has_refused_a_part() {
        let mut out = Sampler {
            surfels: Vec::new(),
            budget: Budget::new(1000).unwrap(),
            over_budget: false,
        };
        // A disc of about 31,400 cells: refused before its first ring (it was sampled ring by
        // ring until a ring no longer fitted, 1,000 surfels made for nothing).
        sample_disc(DVec3::ZERO, DVec3::Z, 100.0, 1.0, &mut out);
        assert!(
            out.over_budget && out.surfels.is_empty(),
            "{}",
            out.surfels.len()
        );
        // What would fit on its own after a refusal is refused too (a cylinder's caps after its
        // side).
        assert!(!out.reserve(1));
        sample_disc(DVec3::ZERO, DVec3::Z, 1.0, 1.0, &mut out);
        assert!(out.surfels.is_empty());
    }

    #[test]
    fn sampled_areas_sum_to_the_closed_form_surface_areas() {
        let cases = [
            (Primitive::Sphere { radius: 1.5 }, 4.0 * PI * 2.25),
            (Primitive::Quad { size: [2.0, 0.5] }, 1.0),
            (
                Primitive::Box {
                    size: [1.0, 2.0, 3.0],
                },
                22.0,
            ),
            (
                Primitive::Cylinder {
                    radius: 0.2,
                    length: 3.0,
                },
                2.0 * PI * 0.2 * 3.0 + 2.0 * PI * 0.04,
            ),
            (
                Primitive::Torus {
                    major: 1.0,
                    minor: 0.3,
                },
                4.0 * PI * PI * 0.3,
            ),
        ];
        for (primitive, expected) in cases {
            let surfels = primitive.surfels(0.02, Budget::default()).unwrap();
            let area = total_area(&surfels);
            assert!(
                (area - expected).abs() < 2e-3 * expected,
                "{primitive:?}: {area} vs {expected}"
            );
        }
    }

    #[test]
    fn torus_knot_area_is_tube_circumference_times_curve_length() {
        let (scale, tube) = (0.3, 0.08);
        let surfels = sample(
            &Primitive::TorusKnot {
                p: 2,
                q: 3,
                scale,
                tube,
            },
            0.01,
            Budget::default(),
        )
        .unwrap();
        // Pappus: a tube of radius r around a curve of length L (curvature radius ≫ r) has area 2πrL.
        let n = 100_000;
        let curve = |u: f64| {
            let phi = u * 2.0 * PI;
            let r = 2.0 + (3.0 * phi).cos();
            scale
                * DVec3::new(
                    r * (2.0 * phi).cos(),
                    -(3.0 * phi).sin(),
                    r * (2.0 * phi).sin(),
                )
        };
        let length: f64 = (0..n)
            .map(|i| curve(i as f64 / n as f64).distance(curve((i + 1) as f64 / n as f64)))
            .sum();
        let expected = 2.0 * PI * tube * length;
        let area = total_area(&surfels);
        assert!(
            (area - expected).abs() < 0.01 * expected,
            "{area} vs {expected}"
        );
    }

    #[test]
    fn normals_are_unit_and_outward() {
        let cases = [
            Primitive::Sphere { radius: 1.0 },
            Primitive::Box {
                size: [1.0, 1.0, 1.0],
            },
            Primitive::Cylinder {
                radius: 0.5,
                length: 2.0,
            },
            Primitive::Torus {
                major: 1.0,
                minor: 0.25,
            },
            Primitive::TorusKnot {
                p: 2,
                q: 3,
                scale: 0.3,
                tube: 0.08,
            },
        ];
        for primitive in cases {
            for s in primitive.surfels(0.05, Budget::default()).unwrap() {
                assert!((s.normal.length() - 1.0).abs() < 1e-9);
                let outward = match primitive {
                    Primitive::Torus { major, .. } => {
                        s.position - DVec3::new(s.position.x, 0.0, s.position.z).normalize() * major
                    }
                    Primitive::TorusKnot { .. } => continue,
                    Primitive::Cylinder { .. } if s.normal.y.abs() < 0.5 => {
                        DVec3::new(s.position.x, 0.0, s.position.z)
                    }
                    _ => s.position,
                };
                assert!(
                    s.normal.dot(outward) > 0.0,
                    "{primitive:?} at {}",
                    s.position
                );
            }
        }
    }

    #[test]
    fn torus_knot_normals_point_away_from_the_core_curve() {
        let tube = 0.08;
        let surfels = sample(
            &Primitive::TorusKnot {
                p: 2,
                q: 3,
                scale: 0.3,
                tube,
            },
            0.02,
            Budget::default(),
        )
        .unwrap();
        // Stepping outward along the normal by a bit of the tube radius must leave the tube:
        // no sample may lie within the tube around the stepped point's nearest sample.
        for s in surfels.iter().step_by(37) {
            let inner = s.position - s.normal * tube;
            let outer = s.position + s.normal * tube;
            let nearest = |p: DVec3| {
                surfels
                    .iter()
                    .map(|o| o.position.distance(p))
                    .fold(f64::MAX, f64::min)
            };
            assert!(
                nearest(outer) > 0.5 * tube,
                "normal points in at {}",
                s.position
            );
            assert!(
                nearest(inner) > 0.5 * tube,
                "tube centre should be empty at {}",
                s.position
            );
        }
    }

    #[test]
    fn thin_shapes_cannot_slip_past_the_surfel_budget() {
        // Area/spacing² would be 1e6, but the grid is ⌈1000/1e-6⌉ × 1 = 1e9 cells.
        let sliver = Primitive::Quad {
            size: [1000.0, 1e-9],
        };
        assert!(sample(&sliver, 1e-6, Budget::default()).is_none());
        let thin_torus = Primitive::Torus {
            major: 1e3,
            minor: 1e-9,
        };
        assert!(sample(&thin_torus, 1e-5, Budget::default()).is_none());
    }

    #[test]
    fn sampling_density_follows_spacing() {
        let coarse = sample(&Primitive::Sphere { radius: 1.0 }, 0.1, Budget::default())
            .unwrap()
            .len();
        let fine = sample(&Primitive::Sphere { radius: 1.0 }, 0.05, Budget::default())
            .unwrap()
            .len();
        assert!((fine as f64 / coarse as f64 - 4.0).abs() < 0.05);
    }

    #[test]
    fn shapes_too_large_for_their_areas_are_refused() {
        // 4πr² overflows to infinity: one surfel of infinite area came back.
        let sphere = Primitive::Sphere { radius: 1e160 }.surfels(1.0, Budget::default());
        assert!(
            sphere.is_err(),
            "{:?}",
            sphere.map(|s| (s.len(), s[0].area))
        );
        // Each cell's area overflows: every surfel was dropped and the quad came back empty.
        let quad = Primitive::Quad {
            size: [1e300, 1e300],
        }
        .surfels(1e299, Budget::default());
        assert!(quad.is_err(), "{:?}", quad.map(|s| s.len()));
        // A subnormal spacing: 1/spacing is infinite, counted as one cell, past the budget.
        let fine = Primitive::Quad { size: [1.0, 1.0] }.surfels(1e-310, Budget::default());
        assert!(fine.is_err(), "{:?}", fine.map(|s| s.len()));
    }

    #[test]
    fn torus_knots_with_many_turns_are_sampled_spacing_apart() {
        for (p, q) in [(255, 1), (7, 200)] {
            let surfels = Primitive::TorusKnot {
                p,
                q,
                scale: 0.2,
                tube: 0.05,
            }
            .surfels(0.02, Budget::default())
            .unwrap();
            // axis_u is SIGMA_PER_SPACING times the cell's step along the knot.
            let mean = surfels.iter().map(|s| s.axis_u.length()).sum::<f64>()
                / (SIGMA_PER_SPACING * surfels.len() as f64);
            assert!(
                mean < 0.025,
                "({p}, {q}): cells {mean} long along the knot at spacing 0.02"
            );
        }
    }

    #[test]
    fn a_torus_knot_is_not_traced_twice_when_p_and_q_share_a_factor() {
        let knot = |p, q| {
            Primitive::TorusKnot {
                p,
                q,
                scale: 0.3,
                tube: 0.05,
            }
            .surfels(0.01, Budget::default())
        };
        let once = total_area(&knot(1, 2).unwrap());
        // (2, 4) runs the (1, 2) curve twice over: twice the surfels, twice the area.
        match knot(2, 4) {
            Ok(twice) => panic!("(2, 4): area {} vs {once} for (1, 2)", total_area(&twice)),
            Err(e) => assert!(e.to_string().contains("common factor"), "{e}"),
        }
    }
}
