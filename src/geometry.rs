//! Surfels and the procedural primitives sampled into them.
//!
//! A surfel is a small oriented Gaussian disk: a centre, a unit normal, two tangent axes scaled to
//! the Gaussian's standard deviation, and the surface area it stands for. The area is what makes
//! coverage meaningful: a surfel's footprint integrates to its (projected) area, so the footprints
//! of a densely sampled surface sum to ≈ 1 over its image and fall to ½ at its silhouette.
//!
//! Primitives are sampled on grids over their parameter domains with exact per-sample cell
//! areas, so the sum of areas is the surface area (tests check it against the closed forms).

use crate::error::{Error, Result};
use crate::mesh::MeshShape;
use crate::pointcloud;
use crate::volume::VolumeShape;
use glam::DVec3;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Standard deviation of a surfel's Gaussian as a fraction of its cell's side. At 0.6 the sum of
/// Gaussians on a regular grid ripples by ~0.2 % (Poisson summation: 2·exp(−2π²·0.6²)); below
/// ~0.5 the ripple grows fast and holes show.
pub const SIGMA_PER_SPACING: f64 = 0.6;

/// The colour of freshly sampled surfels, before the object's colour is applied.
const UNCOLOURED: [f32; 3] = [1.0; 3];

/// A surface element in object space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surfel {
    /// Centre in object space.
    pub position: DVec3,
    /// Unit outward normal.
    pub normal: DVec3,
    /// First tangent axis, scaled to the Gaussian's standard deviation along it.
    pub axis_u: DVec3,
    /// Second tangent axis, scaled likewise.
    pub axis_v: DVec3,
    /// Surface area the surfel stands for.
    pub area: f64,
    /// Linear RGB.
    pub colour: [f32; 3],
}

impl Surfel {
    /// An isotropic surfel for a cell of `area`; `cover_radius`, when known, widens the Gaussian so
    /// that its 2σ disc reaches the farthest point the surfel must cover.
    #[must_use]
    pub fn isotropic(
        position: DVec3,
        normal: DVec3,
        area: f64,
        cover_radius: Option<f64>,
        colour: [f32; 3],
    ) -> Self {
        let sigma = (SIGMA_PER_SPACING * area.sqrt()).max(0.5 * cover_radius.unwrap_or(0.0));
        let (u, v) = normal.any_orthonormal_pair();
        Surfel {
            position,
            normal,
            axis_u: u * sigma,
            axis_v: v * sigma,
            area,
            colour,
        }
    }

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
            colour: UNCOLOURED,
        })
    }
}

/// Most surfels one object may be sampled into: a spacing typo must not eat the machine.
pub const MAX_SURFELS_PER_OBJECT: f64 = 20e6;

/// Neighbours used to estimate normals, radii and areas of a point cloud, unless the scene says.
pub const DEFAULT_NEIGHBOURS: usize = 12;

/// An object's geometry, in its own object space: a procedural primitive (centred at the origin),
/// a point cloud file, the iso-surface of a volume file (centred likewise) or a triangle mesh file
/// sampled into surfels (centred likewise unless it says not to be).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Shape {
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
    /// A PLY point cloud (ascii or binary, optionally gzipped); normals, radii and areas missing
    /// from the file are estimated from `neighbours` nearest neighbours.
    Ply {
        /// The file, relative to the scene file.
        path: PathBuf,
        /// Neighbours used for estimation (default [`DEFAULT_NEIGHBOURS`]).
        neighbours: Option<usize>,
    },
    /// The iso-surface of a raw scalar volume (optionally gzipped), one surfel per voxel cell it
    /// crosses (Guan & Mueller 2004, §3.1); see [`crate::volume`].
    Volume(VolumeShape),
    /// A triangle mesh (OBJ or PLY, optionally gzipped) sampled into a given number of surfels,
    /// area-weighted; see [`crate::mesh`].
    Mesh(MeshShape),
}

/// How an object is coloured.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(try_from = "toml::Value")]
pub enum ColourSpec {
    /// One linear RGB colour.
    Rgb([f64; 3]),
    /// 0.5 + 0.5·n of the object-space normal: colour sticks to the surface as it moves.
    Normal,
    /// The file's colours where it has them, else light grey.
    Default,
}

impl TryFrom<toml::Value> for ColourSpec {
    type Error = String;
    fn try_from(value: toml::Value) -> std::result::Result<Self, String> {
        let wrong =
            || format!("colour must be [r, g, b] (linear, 0 to 1) or \"normal\", not {value}");
        match &value {
            toml::Value::String(s) if s == "normal" => Ok(ColourSpec::Normal),
            toml::Value::Array(items) if items.len() == 3 => {
                let mut rgb = [0.0; 3];
                for (c, item) in rgb.iter_mut().zip(items) {
                    *c = match item {
                        toml::Value::Float(f) => *f,
                        toml::Value::Integer(i) => *i as f64,
                        _ => return Err(wrong()),
                    };
                }
                Ok(ColourSpec::Rgb(rgb))
            }
            _ => Err(wrong()),
        }
    }
}

const DEFAULT_GREY: [f32; 3] = [0.7, 0.7, 0.7];

/// The colour a surfel gets under `spec`, given the file's colour if any.
fn colour_for(spec: &ColourSpec, normal: DVec3, from_file: Option<[f32; 3]>) -> [f32; 3] {
    match spec {
        ColourSpec::Rgb(rgb) => rgb.map(|c| c as f32),
        ColourSpec::Normal => (normal * 0.5 + 0.5).as_vec3().to_array(),
        ColourSpec::Default => from_file.unwrap_or(DEFAULT_GREY),
    }
}

/// Build an object's surfels. `file` names the scene in messages, `base` anchors relative paths,
/// `field` is where the shape sits in the scene (e.g. `object[2].shape`).
pub fn build_surfels(
    shape: &Shape,
    spacing: Option<f64>,
    colour: &ColourSpec,
    file: &Path,
    base: &Path,
    field: &str,
) -> Result<Vec<Surfel>> {
    if let Shape::Ply { path, neighbours } = shape {
        let k = neighbours.unwrap_or(DEFAULT_NEIGHBOURS);
        if !(3..=64).contains(&k) {
            return Err(Error::input(
                file,
                format!("{field}.neighbours"),
                format!("{k}: use between 3 and 64"),
            ));
        }
        return surfels_from_cloud(&pointcloud::read_ply(&base.join(path))?, k, colour);
    }
    if let Shape::Volume(volume) = shape {
        if spacing.is_some() {
            return Err(Error::input(
                file,
                field.replace(".shape", ".spacing"),
                "a volume makes one surfel per voxel cell its surface crosses: remove this \
                 `spacing` (the distance between voxels is `shape.spacing = [x, y, z]`)",
            ));
        }
        let mut surfels = volume.surfels(file, base, field, MAX_SURFELS_PER_OBJECT as usize)?;
        for s in &mut surfels {
            s.colour = colour_for(colour, s.normal, None);
        }
        return Ok(surfels);
    }
    if let Shape::Mesh(mesh) = shape {
        if spacing.is_some() {
            return Err(Error::input(
                file,
                field.replace(".shape", ".spacing"),
                "a mesh is sampled into `shape.samples` surfels: remove this `spacing`",
            ));
        }
        let mut surfels = mesh.surfels(file, base, field, MAX_SURFELS_PER_OBJECT as usize)?;
        for s in &mut surfels {
            s.colour = colour_for(colour, s.normal, None);
        }
        return Ok(surfels);
    }
    let dimensions: Vec<(&str, f64)> = match *shape {
        Shape::Sphere { radius } => vec![("radius", radius)],
        Shape::Quad { size } => vec![("size[0]", size[0]), ("size[1]", size[1])],
        Shape::Box { size } => vec![
            ("size[0]", size[0]),
            ("size[1]", size[1]),
            ("size[2]", size[2]),
        ],
        Shape::Cylinder { radius, length } => vec![("radius", radius), ("length", length)],
        Shape::Torus { major, minor } => vec![("major", major), ("minor", minor)],
        Shape::TorusKnot { scale, tube, .. } => vec![("scale", scale), ("tube", tube)],
        Shape::Ply { .. } | Shape::Volume(_) | Shape::Mesh(_) => Vec::new(),
    };
    for (name, v) in &dimensions {
        if !(v.is_finite() && *v > 0.0) {
            return Err(Error::input(
                file,
                format!("{field}.{name}"),
                format!("{v}: must be a finite number greater than zero"),
            ));
        }
    }
    if let Shape::TorusKnot { p, q, .. } = *shape {
        if p == 0 || q == 0 {
            return Err(Error::input(
                file,
                field,
                "a torus knot needs p ≥ 1 and q ≥ 1",
            ));
        }
    }
    let spacing = spacing.ok_or_else(|| {
        Error::input(
            file,
            field.replace(".shape", ".spacing"),
            "a procedural shape needs `spacing`, the distance between surfels",
        )
    })?;
    let mut surfels = sample_primitive(shape, spacing).ok_or_else(|| {
        Error::input(
            file,
            field.replace(".shape", ".spacing"),
            format!("{spacing} would make more than {MAX_SURFELS_PER_OBJECT:.0} surfels: use a larger spacing"),
        )
    })?;
    for s in &mut surfels {
        s.colour = colour_for(colour, s.normal, None);
    }
    Ok(surfels)
}

/// Surfels from a point cloud, estimating what the file does not give.
fn surfels_from_cloud(
    cloud: &pointcloud::PointCloud,
    k: usize,
    colour: &ColourSpec,
) -> Result<Vec<Surfel>> {
    let normals = match &cloud.normals {
        Some(n) => n.clone(),
        None => pointcloud::estimate_normals(&cloud.positions, k),
    };
    let (cover_radii, areas) = pointcloud::estimate_radii_and_areas(&cloud.positions, &normals, k);
    Ok((0..cloud.positions.len())
        .map(|i| {
            let radius = cloud.radii.as_ref().map_or(cover_radii[i], |r| r[i]);
            let from_file = cloud.colors.as_ref().map(|c| c[i]);
            let colour = colour_for(colour, normals[i], from_file);
            Surfel::isotropic(
                cloud.positions[i],
                normals[i],
                areas[i],
                Some(radius),
                colour,
            )
        })
        .collect())
}

/// Sample a procedural `shape` into surfels about `spacing` apart (white; the caller colours them).
fn sample_primitive(shape: &Shape, spacing: f64) -> Option<Vec<Surfel>> {
    let mut out = Sampler::default();
    match *shape {
        Shape::Ply { .. } | Shape::Volume(_) | Shape::Mesh(_) => {}
        Shape::Sphere { radius } => sample_sphere(radius, spacing, &mut out),
        Shape::Quad { size } => sample_quad(
            DVec3::ZERO,
            DVec3::X * size[0],
            DVec3::Y * size[1],
            spacing,
            &mut out,
        ),
        Shape::Box { size } => {
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
        Shape::Cylinder { radius, length } => {
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
        Shape::Torus { major, minor } => {
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
        Shape::TorusKnot { p, q, scale, tube } => {
            let (p, q) = (f64::from(p), f64::from(q));
            let curve = move |u: f64| {
                let phi = u * std::f64::consts::TAU;
                let r = 2.0 + (q * phi).cos();
                scale * DVec3::new(r * (p * phi).cos(), -(q * phi).sin(), r * (p * phi).sin())
            };
            let frame = move |u: f64| {
                let h = 1e-4;
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
            sample_parametric_with(surface, spacing, outward_at, &mut out);
        }
    }
    (!out.over_budget).then_some(out.surfels)
}

/// Surfels being sampled, within [`MAX_SURFELS_PER_OBJECT`].
#[derive(Default)]
struct Sampler {
    surfels: Vec<Surfel>,
    over_budget: bool,
}

impl Sampler {
    /// Whether `count` more surfels fit; remembers when they do not.
    fn reserve(&mut self, count: usize) -> bool {
        let fits = self.surfels.len().saturating_add(count) as f64 <= MAX_SURFELS_PER_OBJECT;
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
            UNCOLOURED,
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
    sample_parametric_with(&surface, spacing, |u, v| outward(surface(u, v)), out);
}

/// Sample a surface f(u, v) over [0,1]² on a grid whose counts follow the mean lengths of the
/// parameter lines; each cell's tangent steps come from central differences.
fn sample_parametric_with(
    surface: impl Fn(f64, f64) -> DVec3,
    spacing: f64,
    outward: impl Fn(f64, f64) -> DVec3,
    out: &mut Sampler,
) {
    let mean_length = |along_u: bool| {
        let (lines, steps) = (8, 256);
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
    fn sampled_areas_sum_to_the_closed_form_surface_areas() {
        let cases = [
            (Shape::Sphere { radius: 1.5 }, 4.0 * PI * 2.25),
            (Shape::Quad { size: [2.0, 0.5] }, 1.0),
            (
                Shape::Box {
                    size: [1.0, 2.0, 3.0],
                },
                22.0,
            ),
            (
                Shape::Cylinder {
                    radius: 0.2,
                    length: 3.0,
                },
                2.0 * PI * 0.2 * 3.0 + 2.0 * PI * 0.04,
            ),
            (
                Shape::Torus {
                    major: 1.0,
                    minor: 0.3,
                },
                4.0 * PI * PI * 0.3,
            ),
        ];
        for (primitive, expected) in cases {
            let surfels = sample_primitive(&primitive, 0.02).unwrap();
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
        let surfels = sample_primitive(
            &Shape::TorusKnot {
                p: 2,
                q: 3,
                scale,
                tube,
            },
            0.01,
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
            Shape::Sphere { radius: 1.0 },
            Shape::Box {
                size: [1.0, 1.0, 1.0],
            },
            Shape::Cylinder {
                radius: 0.5,
                length: 2.0,
            },
            Shape::Torus {
                major: 1.0,
                minor: 0.25,
            },
            Shape::TorusKnot {
                p: 2,
                q: 3,
                scale: 0.3,
                tube: 0.08,
            },
        ];
        for primitive in cases {
            for s in sample_primitive(&primitive, 0.05).unwrap() {
                assert!((s.normal.length() - 1.0).abs() < 1e-9);
                let outward = match primitive {
                    Shape::Torus { major, .. } => {
                        s.position - DVec3::new(s.position.x, 0.0, s.position.z).normalize() * major
                    }
                    Shape::TorusKnot { .. } => continue,
                    Shape::Cylinder { .. } if s.normal.y.abs() < 0.5 => {
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
        let surfels = sample_primitive(
            &Shape::TorusKnot {
                p: 2,
                q: 3,
                scale: 0.3,
                tube,
            },
            0.02,
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
        let sliver = Shape::Quad {
            size: [1000.0, 1e-9],
        };
        assert!(sample_primitive(&sliver, 1e-6).is_none());
        let thin_torus = Shape::Torus {
            major: 1e3,
            minor: 1e-9,
        };
        assert!(sample_primitive(&thin_torus, 1e-5).is_none());
    }

    #[test]
    fn sampling_density_follows_spacing() {
        let coarse = sample_primitive(&Shape::Sphere { radius: 1.0 }, 0.1)
            .unwrap()
            .len();
        let fine = sample_primitive(&Shape::Sphere { radius: 1.0 }, 0.05)
            .unwrap()
            .len();
        assert!((fine as f64 / coarse as f64 - 4.0).abs() < 0.05);
    }
}
