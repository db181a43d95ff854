//! Surfels, and the sources that make them from data: procedural [`primitives`], point clouds
//! ([`cloud`]), triangle meshes ([`mesh`]) and volume iso-surfaces ([`volume`]). Every source
//! takes data already in memory and returns surfels in object space, or an error naming the
//! setting at fault; reading files is [`crate::io`]'s.
//!
//! A surfel is a small oriented Gaussian disk: a centre, a unit normal, two tangent axes scaled to
//! the Gaussian's standard deviation, and the surface area it stands for. The area is what makes
//! coverage meaningful: a surfel's footprint integrates to its (projected) area, so the footprints
//! of a densely sampled surface sum to ≈ 1 over its image and fall to ½ at its silhouette
//! (docs/conventions.md, "Area and coverage").

pub mod cloud;
pub mod mesh;
pub mod primitives;
pub mod volume;

pub use cloud::{from_point_cloud, PointCloud};
pub use mesh::{from_mesh, Mesh};
pub use primitives::{cuboid, cylinder, quad, sphere, torus, torus_knot, Primitive};
pub use volume::{from_volume, IsoSurface, Volume};

use crate::error::{Error, Result};
use glam::DVec3;

/// Smallest and largest length accepted for a generated surface (a primitive's size and
/// spacing, a volume's voxel spacing): wide enough for any unit, narrow enough that areas, cell
/// counts and squared extents stay finite (4πr² overflows from r ≈ 10¹⁵⁴).
pub const LENGTH_RANGE: (f64, f64) = (1e-9, 1e9);

/// Standard deviation of a surfel's Gaussian as a fraction of its cell's side: the sum of
/// Gaussians on a regular grid then ripples by ~0.2 % (docs/math.md, "Poisson summation and
/// SIGMA_PER_SPACING").
pub const SIGMA_PER_SPACING: f64 = 0.6;

/// The colour a source gives surfels that its data does not colour.
pub const DEFAULT_GREY: [f32; 3] = [0.7, 0.7, 0.7];

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
        Surfel::disc(position, normal, area, sigma, colour)
    }

    /// A round surfel whose Gaussian has standard deviation `sigma`, standing for `area`.
    #[must_use]
    pub fn disc(position: DVec3, normal: DVec3, area: f64, sigma: f64, colour: [f32; 3]) -> Self {
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
}

/// Surfels a scene may have unless told otherwise: a spacing typo must not eat the machine.
/// A surfel costs 300–360 bytes at the peak of a render (20 million took 6.1 GB; a one-triangle
/// mesh of 8 million peaked at 2.88 GB with `blur` and `kernel3d`), so this is about 3 GB.
pub const DEFAULT_SURFEL_BUDGET: usize = 8_000_000;

/// The largest surfel budget that may be asked for.
pub const MAX_SURFEL_BUDGET: usize = 200_000_000;

/// How many surfels a source may still make: what the scene's budget leaves after the objects
/// before it. Every source checks it before it allocates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    /// Surfels left.
    pub left: usize,
    /// The scene's whole budget.
    pub total: usize,
}

impl Default for Budget {
    fn default() -> Self {
        Budget {
            left: DEFAULT_SURFEL_BUDGET,
            total: DEFAULT_SURFEL_BUDGET,
        }
    }
}

impl Budget {
    /// A budget of `total` surfels, 1 to [`MAX_SURFEL_BUDGET`]; an error names `max_surfels`.
    pub fn new(total: usize) -> Result<Budget> {
        if (1..=MAX_SURFEL_BUDGET).contains(&total) {
            Ok(Budget { left: total, total })
        } else {
            Err(Error::invalid(
                "max_surfels",
                format!("{total}: allow between 1 and {MAX_SURFEL_BUDGET} surfels"),
            ))
        }
    }

    /// The budget after `count` surfels were made.
    pub fn take(&mut self, count: usize) {
        self.left = self.left.saturating_sub(count);
    }

    /// Whether `count` more surfels fit.
    #[must_use]
    pub fn fits(&self, count: usize) -> bool {
        count <= self.left
    }

    /// `Ok` when `count` more surfels fit, else [`Budget::exceeded`].
    pub(crate) fn allow(&self, count: usize, field: &str, asked: &str, advice: &str) -> Result<()> {
        if self.fits(count) {
            Ok(())
        } else {
            Err(self.exceeded(field, asked, advice))
        }
    }

    /// The error for a `field` that asks for more surfels than fit, with `advice` on making
    /// fewer.
    pub(crate) fn exceeded(&self, field: &str, asked: &str, advice: &str) -> Error {
        let left = if self.left < self.total {
            format!(
                "the {} surfels left of the scene's budget of {}",
                self.left, self.total
            )
        } else {
            format!("the scene's budget of {} surfels", self.total)
        };
        Error::invalid(
            field,
            format!("{asked} more than {left}: {advice}, or raise the budget (--max-surfels)"),
        )
    }
}

/// How an object's surfels are coloured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Colouring {
    /// The source's own colours: a file's where it has them, else [`DEFAULT_GREY`].
    #[default]
    Own,
    /// One linear RGB colour.
    Rgb([f32; 3]),
    /// 0.5 + 0.5·n of the object-space normal: colour sticks to the surface as it moves.
    Normal,
}

impl Colouring {
    /// Colour `surfels` as this says.
    pub fn apply(self, surfels: &mut [Surfel]) {
        for s in surfels {
            match self {
                Colouring::Own => {}
                Colouring::Rgb(rgb) => s.colour = rgb,
                Colouring::Normal => s.colour = (s.normal * 0.5 + 0.5).as_vec3().to_array(),
            }
        }
    }
}
