//! Scalar volumes turned into surfels: the iso-surface at a chosen value, one surfel per cell
//! whose corners straddle it (surface nets; Guan & Mueller 2004, §3.1–3.2 render an iso-surface
//! as oriented Gaussian disks). Each surfel takes the area, centroid and second moments of its
//! own piece of surface (the polygon of the cell's edge crossings in its tangent plane), which is
//! right cell by cell, not only in total: docs/math.md, "Volume iso-surface surfels", and
//! docs/history.md, "Volumes".

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::{Budget, Surfel, DEFAULT_GREY, LENGTH_RANGE, SIGMA_PER_SPACING};
use crate::error::{Error, Result};
use crate::math::Sym2;

/// Most voxels a volume may have, 2³¹ (e.g. 2048 × 1024 × 1024): a typo in the dimensions must
/// not ask for more memory than a workstation has (this is 2 GiB of uint8, 8 GiB of float32).
pub const MAX_VOXELS: u64 = 1 << 31;

/// Voxel values in their own type, so a uint8 volume takes one byte per voxel in memory; x
/// fastest, then y, then z.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    /// Unsigned 8-bit integers.
    Uint8(Vec<u8>),
    /// Unsigned 16-bit integers.
    Uint16(Vec<u16>),
    /// Signed 16-bit integers.
    Int16(Vec<i16>),
    /// Single-precision floats, every one finite.
    Float32(Vec<f32>),
}

impl Samples {
    fn len(&self) -> usize {
        match self {
            Samples::Uint8(v) => v.len(),
            Samples::Uint16(v) => v.len(),
            Samples::Int16(v) => v.len(),
            Samples::Float32(v) => v.len(),
        }
    }
}

/// The voxel count of a grid of `dimensions`, or an error naming `dimensions` when a side is 0
/// or there are more than [`MAX_VOXELS`].
pub fn voxel_count(dimensions: [usize; 3]) -> Result<u64> {
    let [x, y, z] = dimensions;
    if dimensions.contains(&0) {
        return Err(Error::invalid(
            "dimensions",
            format!("{x} × {y} × {z}: every dimension must be at least 1"),
        ));
    }
    dimensions
        .iter()
        .try_fold(1u64, |product, &n| product.checked_mul(n as u64))
        .filter(|&n| n <= MAX_VOXELS)
        .ok_or_else(|| {
            Error::invalid(
                "dimensions",
                format!("{x} × {y} × {z} is more than the limit of {MAX_VOXELS} voxels"),
            )
        })
}

/// A scalar volume: one finite value per voxel on a grid of `dimensions`, x fastest, then y,
/// then z.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    dimensions: [usize; 3],
    samples: Samples,
}

impl Volume {
    /// A volume of `dimensions` voxels holding `samples`. Errors name the field: `dimensions`
    /// (a side of 0, more than [`MAX_VOXELS`]), `samples` (a count other than the voxels'), or
    /// `voxel (x, y, z)` (the first float that is NaN or infinite).
    pub fn new(dimensions: [usize; 3], samples: Samples) -> Result<Volume> {
        let voxels = voxel_count(dimensions)?;
        if samples.len() as u64 != voxels {
            let [x, y, z] = dimensions;
            return Err(Error::invalid(
                "samples",
                format!(
                    "{} values for {x} × {y} × {z} = {voxels} voxels: give one per voxel",
                    samples.len()
                ),
            ));
        }
        if let Samples::Float32(values) = &samples {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                let [nx, ny, _] = dimensions;
                let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
                return Err(Error::invalid(
                    format!("voxel ({x}, {y}, {z})"),
                    format!(
                        "{}: a float32 volume must hold finite numbers only",
                        values[i]
                    ),
                ));
            }
        }
        Ok(Volume {
            dimensions,
            samples,
        })
    }

    /// Voxels along x, y and z.
    #[must_use]
    pub fn dimensions(&self) -> [usize; 3] {
        self.dimensions
    }

    /// The smallest and the largest voxel value.
    #[must_use]
    pub fn value_range(&self) -> (f64, f64) {
        fn range<T: Copy + Into<f64>>(values: &[T]) -> (f64, f64) {
            values
                .iter()
                .map(|&v| v.into())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                })
        }
        match &self.samples {
            Samples::Uint8(v) => range(v),
            Samples::Uint16(v) => range(v),
            Samples::Int16(v) => range(v),
            Samples::Float32(v) => range(v),
        }
    }

    /// The surfels of the iso-surface (light grey), one per cell whose
    /// corners straddle `surface.iso`, in the order of their cells (z, then y, then x), the
    /// same whatever the thread count. `None` when there would be more than `max_surfels`.
    ///
    /// Object space is voxel index × spacing, shifted so that the volume's centre is the origin.
    /// Settings that make no sense (a non-finite iso-value, a spacing that is not finite and
    /// positive, stride 0) give no surfels.
    #[must_use]
    pub fn iso_surfels(&self, surface: &IsoSurface, max_surfels: usize) -> Option<Vec<Surfel>> {
        let sane_spacing = surface
            .spacing
            .to_array()
            .iter()
            .all(|&s| s.is_finite() && s > 0.0);
        if !(surface.iso.is_finite() && sane_spacing && surface.stride >= 1) {
            return Some(Vec::new());
        }
        match &self.samples {
            Samples::Uint8(v) => Grid::new(v, self.dimensions, surface).surfels(max_surfels),
            Samples::Uint16(v) => Grid::new(v, self.dimensions, surface).surfels(max_surfels),
            Samples::Int16(v) => Grid::new(v, self.dimensions, surface).surfels(max_surfels),
            Samples::Float32(v) => Grid::new(v, self.dimensions, surface).surfels(max_surfels),
        }
    }
}

/// `stride` as a whole number of voxels from 1 to the smallest of `dimensions` less one, or an
/// error naming `stride` and quoting the value given (a negative one too).
pub fn checked_stride<T>(stride: T, dimensions: [usize; 3]) -> Result<usize>
where
    T: TryInto<usize> + std::fmt::Display + Copy,
{
    let widest = dimensions.iter().min().map_or(1, |&n| n.saturating_sub(1));
    stride
        .try_into()
        .ok()
        .filter(|s| (1..=widest).contains(s))
        .ok_or_else(|| {
            Error::invalid(
                "stride",
                format!(
                    "{stride}: use a whole number from 1 (every voxel) to {widest} (the smallest \
                     dimension less one)"
                ),
            )
        })
}

/// The surfels of `volume`'s iso-surface (light grey; see [`Volume::iso_surfels`]), within
/// `budget`. Errors name the field: `spacing[i]` (outside [`LENGTH_RANGE`]), `iso` (not
/// finite, or crossing no cell), `stride` (0, more than the smallest dimension less one, or so
/// small that the surface has more surfels than the budget allows).
pub fn from_volume(volume: &Volume, surface: &IsoSurface, budget: Budget) -> Result<Vec<Surfel>> {
    for (axis, s) in surface.spacing.to_array().into_iter().enumerate() {
        let (lo, hi) = LENGTH_RANGE;
        if !(s >= lo && s <= hi) {
            return Err(Error::invalid(
                format!("spacing[{axis}]"),
                format!("{s}: the distance between voxels must be between {lo:e} and {hi:e}"),
            ));
        }
    }
    if !surface.iso.is_finite() {
        return Err(Error::invalid(
            "iso",
            format!("{} is not a finite number", surface.iso),
        ));
    }
    if volume.dimensions.contains(&1) {
        let [x, y, z] = volume.dimensions;
        return Err(Error::invalid(
            "dimensions",
            format!("{x} × {y} × {z}: an iso-surface needs at least 2 voxels along each axis"),
        ));
    }
    let stride = checked_stride(surface.stride, volume.dimensions)?;
    let surfels = volume.iso_surfels(surface, budget.left).ok_or_else(|| {
        budget.exceeded(
            "stride",
            &format!(
                "the surface at iso = {} has, at stride {stride},",
                surface.iso
            ),
            "use a larger stride",
        )
    })?;
    if surfels.is_empty() {
        let (lo, hi) = volume.value_range();
        let iso = surface.iso;
        if lo <= iso && iso < hi {
            let advice = if stride > 1 {
                "use a smaller stride"
            } else {
                "every cell it crosses has a zero gradient"
            };
            return Err(Error::invalid(
                "iso",
                format!(
                    "the surface at {iso} crosses no cell with a gradient at stride {stride}, \
                     though the volume's values run from {lo} to {hi}: {advice}"
                ),
            ));
        }
        return Err(Error::invalid(
            "iso",
            format!(
                "the surface at {iso} crosses no cell: the volume's values run from {lo} to \
                 {hi}, pick one in between"
            ),
        ));
    }
    Ok(surfels)
}

/// Which iso-surface to extract and how the voxel grid sits in object space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsoSurface {
    /// The iso-value. The surface encloses the values above it, so normals point towards lower
    /// values.
    pub iso: f64,
    /// Distance between neighbouring voxel centres along x, y and z, in object units.
    pub spacing: DVec3,
    /// Use every `stride`-th voxel along each axis (1: all); cells become `stride` voxels wide.
    pub stride: usize,
}

/// Variance of the smoothing added to each piece's own, per unit of the cell's shadow area: a
/// square cell of side h then gets σ² = h²/12 + SMOOTHING·h² = (SIGMA_PER_SPACING·h)², the width
/// the procedural shapes' regular grids use. On a sphere of radius 18 voxels the surfels' summed
/// Gaussians stay within 2.5 % of 1 everywhere; smoothing by the mean area per surfel instead of
/// the shadow let them dip 12 %, and isotropic Gaussians of the piece's area 23 %.
const SMOOTHING: f64 = SIGMA_PER_SPACING * SIGMA_PER_SPACING - 1.0 / 12.0;

/// The twelve edges of a cell, as pairs of corners; corner `k` sits at offset
/// (k & 1, k >> 1 & 1, k >> 2 & 1).
const EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Offset of corner `k` within its cell, in cells.
fn corner_offset(k: usize) -> DVec3 {
    DVec3::new((k & 1) as f64, (k >> 1 & 1) as f64, (k >> 2 & 1) as f64)
}

/// The piece of surface in one cell, in its tangent plane: the convex hull of the crossings.
struct Piece {
    area: f64,
    centroid: DVec2,
    /// Second moments about the centroid, per unit area.
    covariance: Sym2,
}

impl Piece {
    /// The convex hull of `points` (which get reordered), by Andrew's monotone chain. The
    /// crossings of a planar cut through a box are in convex position already; the hull also gives
    /// a sensible piece where two sheets of surface pass through one cell.
    fn hull(points: &mut [DVec2]) -> Piece {
        points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        let n = points.len();
        let mut hull: Vec<DVec2> = Vec::with_capacity(2 * n);
        // The lower chain left to right, then the upper one back; each drops its last point,
        // which starts the other.
        for backwards in [false, true] {
            let start = hull.len();
            for i in 0..n {
                let p = points[if backwards { n - 1 - i } else { i }];
                while hull.len() >= start + 2
                    && (hull[hull.len() - 1] - hull[hull.len() - 2])
                        .perp_dot(p - hull[hull.len() - 2])
                        <= 0.0
                {
                    hull.pop();
                }
                hull.push(p);
            }
            hull.pop();
        }
        let edges = || (0..hull.len()).map(|i| (hull[i], hull[(i + 1) % hull.len()]));
        // Shoelace: area and first moment from the triangles (0, a, b), counter-clockwise.
        let area = 0.5 * edges().map(|(a, b)| a.perp_dot(b)).sum::<f64>();
        if !(area > 0.0) {
            return Piece {
                area: 0.0,
                centroid: DVec2::ZERO,
                covariance: Sym2::default(),
            };
        }
        let centroid = edges().map(|(a, b)| (a + b) * a.perp_dot(b)).sum::<DVec2>() / (6.0 * area);
        // A triangle with a corner at the origin and corners a, b has second moment
        // (area/12)·(aaᵀ + bbᵀ + (a+b)(a+b)ᵀ).
        let covariance = edges()
            .map(|(a, b)| {
                let (a, b) = (a - centroid, b - centroid);
                (Sym2::outer(a) + Sym2::outer(b) + Sym2::outer(a + b)).scaled(a.perp_dot(b) / 24.0)
            })
            .fold(Sym2::default(), |sum, m| sum + m)
            .scaled(1.0 / area);
        Piece {
            area,
            centroid,
            covariance,
        }
    }
}

/// The samples used for one extraction (every `stride`-th voxel) and where they sit.
struct Grid<'a, T> {
    values: &'a [T],
    dimensions: [usize; 3],
    stride: usize,
    /// Samples along each axis.
    points: [usize; 3],
    iso: f64,
    /// A cell's extent along each axis, in object units.
    cell: DVec3,
    /// Object-space position of sample (0, 0, 0).
    origin: DVec3,
}

impl<'a, T: Copy + Into<f64> + Sync> Grid<'a, T> {
    fn new(values: &'a [T], dimensions: [usize; 3], surface: &IsoSurface) -> Self {
        let extent = DVec3::from_array(dimensions.map(|n| (n - 1) as f64)) * surface.spacing;
        Grid {
            values,
            dimensions,
            stride: surface.stride,
            points: dimensions.map(|n| (n - 1) / surface.stride + 1),
            iso: surface.iso,
            cell: surface.spacing * surface.stride as f64,
            origin: -0.5 * extent,
        }
    }

    /// The value at sample `p`.
    fn value(&self, p: [usize; 3]) -> f64 {
        let [x, y, z] = p.map(|c| c * self.stride);
        self.values[x + self.dimensions[0] * (y + self.dimensions[1] * z)].into()
    }

    /// The field's gradient at sample `p` by central differences (one-sided at the border), in
    /// value per object unit.
    fn gradient(&self, p: [usize; 3]) -> DVec3 {
        let mut gradient = DVec3::ZERO;
        for axis in 0..3 {
            let (mut lo, mut hi) = (p, p);
            lo[axis] = p[axis].saturating_sub(1);
            hi[axis] = (p[axis] + 1).min(self.points[axis] - 1);
            let run = (hi[axis] - lo[axis]) as f64 * self.cell[axis];
            gradient[axis] = (self.value(hi) - self.value(lo)) / run;
        }
        gradient
    }

    /// All surfels, one z-layer of cells per parallel task; `None` past `max_surfels`.
    fn surfels(&self, max_surfels: usize) -> Option<Vec<Surfel>> {
        let cells = self.points.map(|n| n - 1);
        // Surfels in finished layers: a layer gives up once it and they pass the budget, which
        // happens exactly when the whole surface would, so the outcome does not depend on timing.
        let made = AtomicUsize::new(0);
        let layers: Vec<Option<Vec<Surfel>>> = (0..cells[2])
            .into_par_iter()
            .map(|z| {
                let mut layer = Vec::new();
                for y in 0..cells[1] {
                    if made.load(Ordering::Relaxed) + layer.len() > max_surfels {
                        return None;
                    }
                    layer.extend((0..cells[0]).filter_map(|x| self.surfel([x, y, z])));
                }
                let total = made.fetch_add(layer.len(), Ordering::Relaxed) + layer.len();
                (total <= max_surfels).then_some(layer)
            })
            .collect();
        let layers: Vec<Vec<Surfel>> = layers.into_iter().collect::<Option<_>>()?;
        Some(layers.concat())
    }

    /// The surfel of cell `c` (its lowest corner is sample `c`), if the surface crosses it and
    /// the field's gradient there is not zero.
    fn surfel(&self, c: [usize; 3]) -> Option<Surfel> {
        let corner = |k: usize| [c[0] + (k & 1), c[1] + (k >> 1 & 1), c[2] + (k >> 2 & 1)];
        let values: [f64; 8] = std::array::from_fn(|k| self.value(corner(k)));
        let above = values.map(|v| v > self.iso);
        if above.iter().all(|&a| a == above[0]) {
            return None;
        }
        // Where each crossed edge meets the iso-value under linear interpolation, in cell units.
        let mut crossings = [DVec3::ZERO; 12];
        let mut count = 0;
        for (a, b) in EDGES {
            if above[a] != above[b] {
                let t = (self.iso - values[a]) / (values[b] - values[a]);
                crossings[count] = corner_offset(a).lerp(corner_offset(b), t);
                count += 1;
            }
        }
        let crossings = &crossings[..count];
        let local = crossings.iter().sum::<DVec3>() / count as f64;

        // The gradient of the trilinearly interpolated field, from the corners' gradients.
        let gradient: DVec3 = (0..8)
            .map(|k| {
                let offset = corner_offset(k);
                let weight = (offset * local + (1.0 - offset) * (1.0 - local)).element_product();
                weight * self.gradient(corner(k))
            })
            .sum();
        let normal = (-gradient).try_normalize()?;

        // The piece of surface inside the cell is, where it is planar, the convex polygon whose
        // corners are the crossings. The surfel takes its area and centroid, so that the surfels'
        // weights are the surface's area locally, not only in total.
        let (u, v) = normal.any_orthonormal_pair();
        let mut corners = [DVec2::ZERO; 12];
        for (corner, &p) in corners.iter_mut().zip(crossings) {
            let d = (p - local) * self.cell;
            *corner = DVec2::new(d.dot(u), d.dot(v));
        }
        let piece = Piece::hull(&mut corners[..count]);
        if !(piece.area > 0.0) {
            return None;
        }
        // The Gaussian has the piece's second moments plus a smoothing shared by neighbours, so
        // that the pieces' Gaussians add up to a smooth ≈ 1 as the pieces add up to the surface.
        // The smoothing scales with the cell's shadow on the tangent plane, s_y s_z |n_x| +
        // s_x s_z |n_y| + s_x s_y |n_z|: on a tilted surface the pieces fall in terraces one
        // shadow apart.
        let shadow = normal.abs().dot(DVec3::new(
            self.cell.y * self.cell.z,
            self.cell.x * self.cell.z,
            self.cell.x * self.cell.y,
        ));
        let (a, b) = (piece.covariance + Sym2::isotropic(SMOOTHING * shadow)).principal_axes();
        let at_local = self.origin + (DVec3::from_array(c.map(|i| i as f64)) + local) * self.cell;
        Some(Surfel {
            position: at_local + u * piece.centroid.x + v * piece.centroid.y,
            normal,
            axis_u: u * a.x + v * a.y,
            axis_v: u * b.x + v * b.y,
            area: piece.area,
            colour: DEFAULT_GREY,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::io::raw_volume::VoxelType;
    use std::f64::consts::PI;
    use std::io::Write;
    use std::path::{Path, PathBuf};

    /// Radius of the test spheres, in voxels: large against a cell, so that curvature biases
    /// positions and areas by well under a percent, and small enough to test quickly.
    const R: f64 = 18.0;

    /// The object-space positions of a volume's voxels, x fastest.
    pub(crate) fn voxel_positions(
        dimensions: [usize; 3],
        spacing: DVec3,
    ) -> impl Iterator<Item = DVec3> {
        let centre = DVec3::from_array(dimensions.map(|n| (n - 1) as f64)) * spacing * 0.5;
        (0..dimensions[2]).flat_map(move |z| {
            (0..dimensions[1]).flat_map(move |y| {
                (0..dimensions[0])
                    .map(move |x| DVec3::new(x as f64, y as f64, z as f64) * spacing - centre)
            })
        })
    }

    /// The bytes of a float32 volume of `field` sampled at its voxels.
    pub(crate) fn float_bytes(
        dimensions: [usize; 3],
        spacing: DVec3,
        field: impl Fn(DVec3) -> f64,
    ) -> Vec<u8> {
        voxel_positions(dimensions, spacing)
            .flat_map(|p| (field(p) as f32).to_le_bytes())
            .collect()
    }

    fn float_volume(
        dimensions: [usize; 3],
        spacing: DVec3,
        field: impl Fn(DVec3) -> f64,
    ) -> Volume {
        let bytes = float_bytes(dimensions, spacing, field);
        Volume::parse(
            &bytes,
            dimensions,
            VoxelType::Float32,
            Path::new("test.raw"),
        )
        .unwrap()
    }

    /// Signed distance inside a sphere of radius `R`: positive inside, so the surface at 0
    /// encloses the high values.
    fn ball(p: DVec3) -> f64 {
        R - p.length()
    }

    fn extract(volume: &Volume, iso: f64, spacing: DVec3, stride: usize) -> Vec<Surfel> {
        let surface = IsoSurface {
            iso,
            spacing,
            stride,
        };
        volume.iso_surfels(&surface, usize::MAX).unwrap()
    }

    fn total_area(surfels: &[Surfel]) -> f64 {
        surfels.iter().map(|s| s.area).sum()
    }

    /// A fresh folder for one test's files.
    pub(crate) fn workdir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("streak-volume-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    pub(crate) fn gzip(bytes: &[u8]) -> Vec<u8> {
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        encoder.write_all(bytes).unwrap();
        encoder.finish().unwrap()
    }

    /// Checks a sphere of radius `r` around the origin: the summed area is 4πr² within 2 % (the
    /// crossed-cell count fluctuates with how the sphere meets the grid, and curvature at
    /// r = 18 cells biases it by a few tenths of a percent), at least 99 % of the normals are
    /// within 8° of radial (dot > 0.99) and all point outward, and every centre lies within
    /// `tolerance` of the sphere.
    fn assert_sphere(surfels: &[Surfel], r: f64, tolerance: f64) {
        let expected = 4.0 * PI * r * r;
        let area = total_area(surfels);
        assert!(
            (area / expected - 1.0).abs() < 0.02,
            "area {area} vs 4πr² = {expected}"
        );
        let radial = |s: &Surfel| s.normal.dot(s.position.normalize());
        assert!(
            surfels.iter().all(|s| radial(s) > 0.0),
            "a normal points in"
        );
        let aligned = surfels.iter().filter(|s| radial(s) > 0.99).count();
        assert!(
            aligned as f64 >= 0.99 * surfels.len() as f64,
            "{aligned} of {} normals radial",
            surfels.len()
        );
        let worst = surfels
            .iter()
            .map(|s| (s.position.length() - r).abs())
            .fold(0.0, f64::max);
        assert!(worst < tolerance, "a centre is {worst} off the sphere");
    }

    #[test]
    fn a_float_sphere_has_the_right_area_normals_and_positions() {
        let volume = float_volume([48; 3], DVec3::ONE, ball);
        let surfels = extract(&volume, 0.0, DVec3::ONE, 1);
        // Chords of a curved surface cut inside it by about (cell diagonal)²/8r ≈ 0.02 voxel.
        assert_sphere(&surfels, R, 0.05);
        for s in &surfels {
            assert!((s.normal.length() - 1.0).abs() < 1e-12);
            assert_eq!(s.colour, DEFAULT_GREY);
        }
    }

    #[test]
    fn a_gzipped_uint8_sphere_reads_like_the_raw_file_and_keeps_its_shape() {
        // 8 grey levels per voxel of distance: quantization moves the surface by up to 1/16 voxel.
        let bytes: Vec<u8> = voxel_positions([48; 3], DVec3::ONE)
            .map(|p| (100.0 + 8.0 * ball(p)).round().clamp(0.0, 255.0) as u8)
            .collect();
        let dir = workdir("uint8");
        std::fs::write(dir.join("ball.raw"), &bytes).unwrap();
        std::fs::write(dir.join("ball.raw.gz"), gzip(&bytes)).unwrap();
        let raw = Volume::read(&dir.join("ball.raw"), [48; 3], VoxelType::Uint8).unwrap();
        let gz = Volume::read(&dir.join("ball.raw.gz"), [48; 3], VoxelType::Uint8).unwrap();
        assert_eq!(raw, gz);
        assert_eq!(raw.value_range(), (0.0, 237.0));
        assert_sphere(&extract(&raw, 100.0, DVec3::ONE, 1), R, 0.1);
    }

    #[test]
    fn anisotropic_spacing_scales_positions_and_areas() {
        let isotropic = extract(&float_volume([48; 3], DVec3::ONE, ball), 0.0, DVec3::ONE, 1);
        // The same samples twice as far apart along x: a prolate spheroid with semi-axes 2R, R, R.
        let stretch = DVec3::new(2.0, 1.0, 1.0);
        let stretched = extract(&float_volume([48; 3], DVec3::ONE, ball), 0.0, stretch, 1);
        assert_eq!(isotropic.len(), stretched.len());
        // Undoing the stretch puts every centre back near the sphere.
        for s in &stretched {
            assert!(((s.position / stretch).length() - R).abs() < 0.05);
        }
        let (a, b) = (2.0 * R, R);
        let e = (1.0 - b * b / (a * a)).sqrt();
        let spheroid = 2.0 * PI * b * b * (1.0 + a / (b * e) * e.asin());
        let area = total_area(&stretched);
        assert!(
            (area / spheroid - 1.0).abs() < 0.02,
            "area {area} vs {spheroid}"
        );
        // A sphere sampled with half as many voxels along x, each twice as long.
        let coarse_x = extract(&float_volume([24, 48, 48], stretch, ball), 0.0, stretch, 1);
        assert_sphere(&coarse_x, R, 0.1);
    }

    #[test]
    fn a_stride_samples_every_kth_voxel() {
        let volume = float_volume([48; 3], DVec3::ONE, ball);
        let fine = extract(&volume, 0.0, DVec3::ONE, 1);
        let coarse = extract(&volume, 0.0, DVec3::ONE, 2);
        let ratio = coarse.len() as f64 / fine.len() as f64;
        assert!((ratio - 0.25).abs() < 0.02, "{ratio}");
        // Cells two voxels wide: twice the chord error.
        assert_sphere(&coarse, R, 0.1);
        // Every third voxel of a 48-voxel side is 16 samples, the last at voxel 45: positions
        // stay centred on the full volume, not on the samples.
        let third = extract(&volume, 0.0, DVec3::ONE, 3);
        assert_sphere(&third, R, 0.2);
    }

    #[test]
    fn pieces_have_the_area_centroid_and_moments_of_their_polygon() {
        // A 2 × 1 rectangle given out of order, with a point inside that the hull drops.
        let mut corners = [(2.0, 1.0), (0.0, 0.0), (1.0, 0.5), (0.0, 1.0), (2.0, 0.0)]
            .map(|(x, y)| DVec2::new(x, y) + DVec2::new(5.0, -3.0));
        let piece = Piece::hull(&mut corners);
        assert!((piece.area - 2.0).abs() < 1e-12);
        assert!((piece.centroid - DVec2::new(6.0, -2.5)).length() < 1e-12);
        let c = piece.covariance;
        assert!((c.xx - 4.0 / 12.0).abs() < 1e-12 && c.xy.abs() < 1e-12);
        assert!((c.yy - 1.0 / 12.0).abs() < 1e-12);
        // A right triangle: centroid at a third, covariance from the closed form.
        let piece = Piece::hull(&mut [DVec2::ZERO, DVec2::X * 3.0, DVec2::Y * 3.0]);
        assert!((piece.area - 4.5).abs() < 1e-12);
        assert!((piece.centroid - DVec2::ONE).length() < 1e-12);
        assert!((piece.covariance.xx - 0.5).abs() < 1e-12);
        assert!((piece.covariance.xy + 0.25).abs() < 1e-12);
        // Collinear or coincident crossings make no piece.
        let line = Piece::hull(&mut [DVec2::ZERO, DVec2::ONE, DVec2::ONE * 2.0]);
        assert_eq!(line.area, 0.0);
    }

    #[test]
    fn a_constant_volume_has_no_surface() {
        let volume = float_volume([8, 9, 10], DVec3::ONE, |_| 3.0);
        for iso in [2.0, 3.0, 4.0] {
            assert!(extract(&volume, iso, DVec3::ONE, 1).is_empty());
        }
        assert_eq!(volume.value_range(), (3.0, 3.0));
    }

    #[test]
    fn cells_without_a_gradient_are_skipped() {
        // Values alternate along x, so central differences vanish everywhere but at the borders.
        let volume = float_volume([9, 4, 4], DVec3::ONE, |p| (p.x + 4.0) % 2.0);
        let surfels = extract(&volume, 0.5, DVec3::ONE, 1);
        assert!(surfels.len() < 8 * 3 * 3);
        for s in &surfels {
            assert!((s.normal.length() - 1.0).abs() < 1e-12 && s.area.is_finite());
        }
    }

    #[test]
    fn surfels_are_the_same_whatever_the_thread_count() {
        let volume = float_volume([40, 44, 48], DVec3::new(1.0, 1.5, 0.5), |p| {
            15.0 - (p * DVec3::new(1.0, 0.8, 1.3)).length() + (p.x * 0.3).sin()
        });
        let spacing = DVec3::new(1.0, 1.5, 0.5);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| extract(&volume, 0.0, spacing, 1))
        };
        let one = run(1);
        assert!(one.len() > 1000);
        assert!(one == run(2) && one == run(3));
    }

    #[test]
    fn the_surfel_budget_is_all_or_nothing() {
        let volume = float_volume([48; 3], DVec3::ONE, ball);
        let surface = IsoSurface {
            iso: 0.0,
            spacing: DVec3::ONE,
            stride: 1,
        };
        let count = extract(&volume, 0.0, DVec3::ONE, 1).len();
        assert_eq!(
            volume.iso_surfels(&surface, count).map(|s| s.len()),
            Some(count)
        );
        assert_eq!(volume.iso_surfels(&surface, count - 1), None);
        assert_eq!(volume.iso_surfels(&surface, 10), None);
    }

    #[test]
    fn nonsense_settings_give_no_surfels() {
        let volume = float_volume([8; 3], DVec3::ONE, |p| 3.0 - p.length());
        for (iso, spacing, stride) in [
            (f64::NAN, DVec3::ONE, 1),
            (0.0, DVec3::new(1.0, 0.0, 1.0), 1),
            (0.0, DVec3::splat(f64::INFINITY), 1),
            (0.0, DVec3::ONE, 0),
            (0.0, DVec3::ONE, usize::MAX),
        ] {
            assert!(extract(&volume, iso, spacing, stride).is_empty());
        }
    }

    #[test]
    fn a_volume_one_voxel_thick_is_refused_by_its_dimensions() {
        let volume = float_volume([1, 8, 8], DVec3::ONE, |p| 3.0 - p.length());
        let surface = IsoSurface {
            iso: 0.0,
            spacing: DVec3::ONE,
            stride: 1,
        };
        let message = from_volume(&volume, &surface, Budget::default())
            .unwrap_err()
            .to_string();
        assert!(
            message.starts_with("dimensions: ") && message.contains("at least 2"),
            "{message}"
        );
    }

    #[test]
    fn an_iso_value_within_the_range_that_no_sampled_cell_crosses_blames_the_stride() {
        // One bright voxel between the samples of stride 2: the iso-value lies within the
        // values' range, but no sampled cell straddles it.
        let volume = float_volume([5; 3], DVec3::ONE, |p| {
            if p == DVec3::splat(-1.0) {
                10.0
            } else {
                0.0
            }
        });
        let surface = IsoSurface {
            iso: 5.0,
            spacing: DVec3::ONE,
            stride: 2,
        };
        let message = from_volume(&volume, &surface, Budget::default())
            .unwrap_err()
            .to_string();
        assert!(message.contains("smaller stride"), "{message}");
    }
}
