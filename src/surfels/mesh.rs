//! Triangle meshes sampled into surfels: the surface is cut into pieces of about equal area, one
//! surfel each, whose Gaussian has the piece's area, centroid and second moments plus a
//! smoothing shared by all, so that the Gaussians add up to ≈ 1 as the pieces add up to the
//! surface. Pieces are allotted by systematic sampling along the faces in Morton order, each
//! face cut into equal-area parts along its longest edge, and faces too small for a piece join
//! their nearest piece facing the same way: none of it random, the same for any thread count.
//! Why not random points, and the measured coverage: docs/math.md, "Mesh sampling with moments",
//! and docs/history.md, "Meshes".

use std::num::NonZeroUsize;

use glam::{DMat3, DVec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use super::{Surfel, DEFAULT_GREY, MAX_SURFEL_BUDGET};
use crate::error::{Error, Result};
use crate::math::{outer3, MortonCurve, Sym2};

/// Most vertices a mesh file may define (33.5 M, a scan of Lucy's size fits): 24 bytes each as
/// read, and text of 8 bytes a vertex could otherwise name 268 M within the file size bound.
pub const MAX_MESH_VERTICES: usize = 1 << 25;

/// Most triangles a mesh may have once its polygons are cut into fans (33.5 M): drawn as
/// triangles, each holds its corners' normals in f64 (84 bytes with its indices), so the bound
/// keeps a mesh near 3 GB, where a polygon's corner costs 2 bytes of text and a 2 GiB file could
/// name a billion triangles.
pub const MAX_MESH_TRIANGLES: usize = 1 << 25;

/// What a mesh file's size is bounded in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MeshPart {
    /// At most [`MAX_MESH_VERTICES`].
    Vertices,
    /// At most [`MAX_MESH_TRIANGLES`], polygons counted as the triangles of their fans.
    Triangles,
}

impl MeshPart {
    /// An error naming the file at `path` and its `field` (made only then) when a mesh would hold
    /// `count` of this part, more than its bound.
    pub(crate) fn check(
        self,
        count: usize,
        path: &std::path::Path,
        field: impl FnOnce() -> String,
    ) -> Result<()> {
        let (most, what) = match self {
            MeshPart::Vertices => (MAX_MESH_VERTICES, "vertices"),
            MeshPart::Triangles => (
                MAX_MESH_TRIANGLES,
                "triangles (polygons counted as the triangles of their fans)",
            ),
        };
        if count <= most {
            return Ok(());
        }
        Err(Error::input(
            path,
            field(),
            format!(
                "more than {most} {what}: streak reads meshes up to that size; decimate it in a \
                 mesh tool first"
            ),
        ))
    }
}

/// A triangle mesh: vertex positions and triangles as indices into them, each wound
/// counter-clockwise seen from the side its normal points to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Triangles, three indices into `positions` each.
    pub triangles: Vec<[u32; 3]>,
}

/// Surfels sampled from a mesh, with what was left out.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSamples {
    /// The surfels (light grey), one per piece.
    pub surfels: Vec<Surfel>,
    /// Area of the surface the surfels stand for, which their areas add up to: that of the
    /// triangles less the degenerate and the isolated ones.
    pub area: f64,
    /// Triangles left out: zero area (repeated or collinear corners), an area too large to
    /// measure in f64, or an index past the positions.
    pub degenerate: usize,
    /// Triangles too small for a piece of their own, joined to a nearby piece.
    pub joined: usize,
    /// Triangles too small for a piece of their own and with no piece near enough to join (a part
    /// of the mesh smaller than one piece, apart from the rest), left out.
    pub isolated: usize,
}

impl Mesh {
    /// An axis-aligned box centred on the origin, two outward-wound triangles per side.
    pub fn cuboid(size: DVec3) -> Mesh {
        let corner = |k: u32| {
            DVec3::new(
                if k & 1 == 0 { -0.5 } else { 0.5 },
                if k & 2 == 0 { -0.5 } else { 0.5 },
                if k & 4 == 0 { -0.5 } else { 0.5 },
            ) * size
        };
        // Each side's corners in counter-clockwise order seen from outside.
        let sides = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        Mesh {
            positions: (0..8).map(corner).collect(),
            triangles: sides
                .iter()
                .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
                .collect(),
        }
    }

    /// The corners of triangle `t`, or `None` when an index is past the positions.
    pub(crate) fn corners(&self, t: [u32; 3]) -> Option<[DVec3; 3]> {
        let corner = |i: u32| self.positions.get(i as usize).copied();
        Some([corner(t[0])?, corner(t[1])?, corner(t[2])?])
    }

    /// The error for a mesh none of whose triangles can be drawn or sampled, naming `faces` and
    /// why: zero areas, areas too large for a double (coordinates near 10⁷⁷ and beyond, where the
    /// squared length of an edge cross product overflows: the model is to be scaled down), or
    /// indices past the vertices.
    #[must_use]
    pub fn no_faces_left(&self) -> Error {
        let (mut overflowing, mut outside) = (0, 0);
        let mut largest = 0.0f64;
        for &t in &self.triangles {
            match self.corners(t) {
                Some([a, b, c]) => {
                    if !(b - a).cross(c - a).length().is_finite() {
                        overflowing += 1;
                        largest = [a, b, c]
                            .iter()
                            .fold(largest, |m, p| m.max(p.abs().max_element()));
                    }
                }
                None => outside += 1,
            }
        }
        let total = self.triangles.len();
        let mut why = Vec::new();
        if total > overflowing + outside {
            why.push(format!("{} of zero area", total - overflowing - outside));
        }
        if outside > 0 {
            why.push(format!(
                "{outside} indexing past the {} vertices",
                self.positions.len()
            ));
        }
        if overflowing > 0 {
            why.push(format!(
                "{overflowing} too large for their area to be a double (coordinates up to {}: \
                 scale the model down)",
                crate::error::shown(largest)
            ));
        }
        Error::invalid(
            "faces",
            format!(
                "none of the {total} triangles has a surface to draw or sample: {}",
                why.join(", ")
            ),
        )
    }

    /// The smallest box around the vertices the triangles use, as (lowest, highest) corner;
    /// `None` when no triangle has valid indices.
    #[must_use]
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        self.triangles
            .iter()
            .filter_map(|&t| self.corners(t))
            .flatten()
            .fold(None, |bounds, p| match bounds {
                None => Some((p, p)),
                Some((lo, hi)) => Some((lo.min(p), hi.max(p))),
            })
    }

    /// Cut the surface into `count` pieces and make a surfel of each (see the module notes). No
    /// surfels when `count` is 0 or every triangle is degenerate.
    #[must_use]
    pub fn sample(&self, count: usize) -> MeshSamples {
        let mut faces: Vec<Face> = Vec::with_capacity(self.triangles.len());
        let mut area = 0.0;
        for &t in &self.triangles {
            let Some([a, b, c]) = self.corners(t) else {
                continue;
            };
            let cross = (b - a).cross(c - a);
            let face_area = 0.5 * cross.length();
            let Some(normal) = cross.try_normalize() else {
                continue;
            };
            if !(area + face_area).is_finite() {
                continue;
            }
            area += face_area;
            faces.push(Face {
                corners: [a, b, c],
                normal,
                area: face_area,
                pieces: 0,
            });
        }
        let mut samples = MeshSamples {
            surfels: Vec::new(),
            area,
            degenerate: self.triangles.len() - faces.len(),
            joined: 0,
            isolated: 0,
        };
        if count == 0 || faces.is_empty() {
            return samples;
        }

        // Systematic sampling along the faces in Morton order of their centroids: piece i stands
        // at cumulative area (i + ½)·A/N, and a face gets the pieces that stand in it. Neighbours
        // in that order are neighbours in space, so where faces are smaller than A/N the faces
        // that get a piece are spread evenly over the surface.
        sort_by_morton_order(&mut faces);
        let step = area / count as f64;
        let standing_before =
            |cumulative: f64| ((cumulative / step - 0.5).ceil().max(0.0) as usize).min(count);
        let mut cumulative = 0.0;
        for face in &mut faces {
            let first = standing_before(cumulative);
            cumulative += face.area;
            face.pieces = standing_before(cumulative) - first;
        }
        let mut pieces: Vec<Moments> = faces
            .par_iter()
            .flat_map_iter(|face| {
                let mut pieces = Vec::with_capacity(face.pieces);
                split(
                    face.corners,
                    face.normal,
                    face.area,
                    face.pieces,
                    &mut pieces,
                );
                pieces
            })
            .collect();
        let left_out = join_small_faces(&faces, &mut pieces, JOIN_REACH * step.sqrt());
        samples.joined = faces.iter().filter(|f| f.pieces == 0).count() - left_out.len();
        samples.isolated = left_out.len();
        samples.area -= left_out.iter().map(|&f| faces[f].area).sum::<f64>();

        let smoothing = Sym2::isotropic(SMOOTHING * step);
        samples.surfels = pieces
            .par_iter()
            .map(|piece| piece.surfel(smoothing))
            .collect();
        samples
    }
}

/// Surfels sampled from `mesh`'s surface (see the module notes), light grey, `samples` of them:
/// moved so that the centre of the mesh's bounding box is the origin when `centre` is true. An
/// error names `samples` (0 or more than [`MAX_SURFEL_BUDGET`]) or `faces` (every triangle
/// degenerate, or too large: [`Mesh::no_faces_left`]).
pub fn from_mesh(mesh: &Mesh, samples: usize, centre: bool) -> Result<Vec<Surfel>> {
    if !(1..=MAX_SURFEL_BUDGET).contains(&samples) {
        return Err(Error::invalid(
            "samples",
            format!("{samples}: the number of surfels must be between 1 and {MAX_SURFEL_BUDGET}"),
        ));
    }
    let mut sampled = mesh.sample(samples);
    if sampled.surfels.is_empty() {
        return Err(mesh.no_faces_left());
    }
    let offset = match (centre, mesh.bounds()) {
        (true, Some((lo, hi))) => 0.5 * (lo + hi),
        _ => DVec3::ZERO,
    };
    for s in &mut sampled.surfels {
        s.position -= offset;
    }
    Ok(sampled.surfels)
}

/// Sorts faces along a Morton (Z-order) curve through their centroids; ties keep their order, so
/// the result is the same on every run.
fn sort_by_morton_order(faces: &mut [Face]) {
    let centroid = |f: &Face| f.corners.iter().sum::<DVec3>() / 3.0;
    let curve = MortonCurve::around(faces.iter().map(centroid));
    faces.par_sort_by_cached_key(|f| curve.key(centroid(f)));
}

/// Adds each face that got no piece to the nearest piece within `reach` that faces the same way
/// (the other side of a thin part faces away), or else to the nearest within `reach`, so that the
/// pieces still cover the surface. Faces are added in order, so the sums do not depend on the
/// thread count. Returns the faces left out, with no piece within `reach`: joining them would
/// stretch a Gaussian across the gap, and leaving out a part smaller than one piece costs less.
fn join_small_faces(faces: &[Face], pieces: &mut [Moments], reach: f64) -> Vec<usize> {
    let small: Vec<usize> = (0..faces.len()).filter(|&f| faces[f].pieces == 0).collect();
    let centroids: Vec<[f64; 3]> = pieces.iter().map(|c| c.centroid.to_array()).collect();
    // Building the tree fails only past 2³² pieces, far more than memory holds.
    let (Ok(tree), Some(candidates)) = (
        ImmutableKdTree::<f64, 3>::new_from_slice(&centroids),
        NonZeroUsize::new(JOIN_CANDIDATES.min(pieces.len())),
    ) else {
        return small;
    };
    let targets: Vec<Option<usize>> = small
        .par_iter()
        .map(|&index| {
            let face = &faces[index];
            let centroid = face.corners.iter().sum::<DVec3>() / 3.0;
            let nearest: Vec<usize> = tree
                .query(&centroid.to_array())
                .nearest_n::<SquaredEuclidean<f64>>(candidates)
                .execute()
                .iter()
                .filter(|n| n.distance <= reach * reach)
                .map(|n| n.item as usize)
                .collect();
            nearest
                .iter()
                .find(|&&c| pieces[c].normal.dot(face.normal) > 0.0)
                .or(nearest.first())
                .copied()
        })
        .collect();
    let mut left_out = Vec::new();
    for (&index, target) in small.iter().zip(targets) {
        let face = &faces[index];
        match target {
            Some(piece) => {
                pieces[piece].add(&Moments::triangle(face.corners, face.normal, face.area));
            }
            None => left_out.push(index),
        }
    }
    left_out
}

/// How far a face too small for a piece may be from the piece it joins, in units of √(A/N).
const JOIN_REACH: f64 = 4.0;

/// Nearest pieces looked at for one that faces the same way as a triangle too small for a piece.
const JOIN_CANDIDATES: usize = 16;

/// Variance of the smoothing every surfel's Gaussian adds to its piece's own second moments, per
/// unit of A/N, the area one surfel stands for on average. The pieces are triangles, whose
/// Gaussians leave a ripple at the pieces' spacing. On a flat square cut into 512 to 3,000 pieces
/// the Gaussians summed to 0.91–1.06 at the regular grids' width (0.6² − 1/12 ≈ 0.28, which makes
/// a square piece's σ 0.6 of its side), 0.96–1.02 at 0.5, 0.974–1.014 at 0.65 and 0.98–1.01 at
/// 0.8; on the coverage test's icospheres of 5,120 to 81,920 triangles the least coverage rose
/// from 0.955 at 0.5 to 0.968 at 0.65 and 0.971 at 0.8. Every step widens the splats, so 0.65:
/// an equilateral piece gets σ ≈ 0.86 √(A/N).
pub const SMOOTHING: f64 = 0.65;

/// A triangle of the mesh with an area and a normal.
struct Face {
    corners: [DVec3; 3],
    normal: DVec3,
    area: f64,
    /// How many pieces it is cut into.
    pieces: usize,
}

/// Area, centroid, spread and mean normal of a piece of surface.
#[derive(Clone, Copy, Debug, Default)]
struct Moments {
    area: f64,
    centroid: DVec3,
    /// Second moments about the centroid, per unit area.
    covariance: DMat3,
    /// Σ area · unit normal over the parts.
    normal: DVec3,
}

impl Moments {
    /// A triangle of `area` (passed in, so that the pieces of a triangle add up to exactly its
    /// area), uniformly covered.
    fn triangle(corners: [DVec3; 3], normal: DVec3, area: f64) -> Moments {
        let centroid = corners.iter().sum::<DVec3>() / 3.0;
        // The second moments of a triangle about its centroid are Σ dᵢdᵢᵀ / 12 over the corners'
        // offsets dᵢ from it.
        let covariance = corners
            .iter()
            .map(|&p| outer3(p - centroid))
            .fold(DMat3::ZERO, |sum, m| sum + m)
            * (1.0 / 12.0);
        Moments {
            area,
            centroid,
            covariance,
            normal: normal * area,
        }
    }

    /// Adds `other` (the parallel-axis theorem moves both covariances to the joint centroid).
    fn add(&mut self, other: &Moments) {
        let total = self.area + other.area;
        if !(total > 0.0) {
            return;
        }
        let (w, v) = (self.area / total, other.area / total);
        let centroid = self.centroid * w + other.centroid * v;
        let (d, e) = (self.centroid - centroid, other.centroid - centroid);
        self.covariance = (self.covariance + outer3(d)) * w + (other.covariance + outer3(e)) * v;
        self.centroid = centroid;
        self.area = total;
        self.normal += other.normal;
    }

    /// The surfel of this piece: at its centroid, facing its mean normal (+z in the unlikely case
    /// that its parts' normals cancel), with a Gaussian of its second moments in that plane plus
    /// `smoothing`.
    fn surfel(&self, smoothing: Sym2) -> Surfel {
        let normal = self.normal.try_normalize().unwrap_or(DVec3::Z);
        let (u, v) = normal.any_orthonormal_pair();
        let c = self.covariance;
        let spread = Sym2 {
            xx: u.dot(c * u),
            xy: u.dot(c * v),
            yy: v.dot(c * v),
        };
        let (a, b) = (spread + smoothing).principal_axes();
        Surfel {
            position: self.centroid,
            normal,
            axis_u: u * a.x + v * a.y,
            axis_v: u * b.x + v * b.y,
            area: self.area,
            colour: DEFAULT_GREY,
        }
    }
}

/// Cuts a triangle into `pieces` triangles of equal area (none for 0): in two, from the corner
/// opposite the longest edge to the point that divides that edge (and so the area) as
/// ⌊pieces/2⌋ : ⌈pieces/2⌉, and each part again. Cutting the longest edge keeps the parts from
/// becoming slivers.
fn split(corners: [DVec3; 3], normal: DVec3, area: f64, pieces: usize, out: &mut Vec<Moments>) {
    if pieces <= 1 {
        if pieces == 1 {
            out.push(Moments::triangle(corners, normal, area));
        }
        return;
    }
    let length = |k: usize| corners[(k + 1) % 3].distance_squared(corners[(k + 2) % 3]);
    let k = (0..3).fold(0, |best, k| if length(k) > length(best) { k } else { best });
    let [a, b, c] = [corners[k], corners[(k + 1) % 3], corners[(k + 2) % 3]];
    let first = pieces / 2;
    let share = first as f64 / pieces as f64;
    let m = b + (c - b) * share;
    split([a, b, m], normal, area * share, first, out);
    split([a, m, c], normal, area * (1.0 - share), pieces - first, out);
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A unit square in the xy plane (facing +z) cut into two triangles, `size` on a side.
    pub(crate) fn square(size: f64) -> Mesh {
        let positions = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
            .map(|[x, y]| DVec3::new(x, y, 0.0) * size)
            .to_vec();
        Mesh {
            positions,
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    /// A `side` × `side` grid of the unit square with its inner vertices moved by up to a third
    /// of a cell, so that its triangles differ in size, facing +z.
    fn jittered_sheet(side: u32, z: f64) -> Mesh {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut jitter = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut positions = Vec::new();
        for j in 0..=side {
            for i in 0..=side {
                let inner = i > 0 && j > 0 && i < side && j < side;
                let (dx, dy) = if inner {
                    (jitter() / 1.5, jitter() / 1.5)
                } else {
                    (0.0, 0.0)
                };
                let cell = 1.0 / f64::from(side);
                positions.push(DVec3::new(
                    (f64::from(i) + dx) * cell,
                    (f64::from(j) + dy) * cell,
                    z,
                ));
            }
        }
        let at = |i: u32, j: u32| j * (side + 1) + i;
        let mut triangles = Vec::new();
        for j in 0..side {
            for i in 0..side {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                triangles.extend([[a, b, c], [a, c, d]]);
            }
        }
        Mesh {
            positions,
            triangles,
        }
    }

    fn surfel_area(samples: &MeshSamples) -> f64 {
        samples.surfels.iter().map(|s| s.area).sum()
    }

    #[test]
    fn areas_add_up_to_the_surface_area() {
        let cases = [
            (Mesh::cuboid(DVec3::new(1.0, 2.0, 3.0)), 22.0, 1000),
            (square(2.0), 4.0, 1),
            (square(2.0), 4.0, 7),
            (jittered_sheet(40, 0.0), 1.0, 1000),
            (jittered_sheet(40, 0.0), 1.0, 10_000),
        ];
        for (mesh, area, count) in cases {
            let samples = mesh.sample(count);
            assert_eq!(samples.surfels.len(), count);
            assert!((samples.area - area).abs() < 1e-12 * area);
            let sum = surfel_area(&samples);
            assert!((sum - area).abs() < 1e-9 * area, "{count}: {sum} vs {area}");
        }
    }

    #[test]
    fn each_triangle_gets_its_share_of_the_pieces() {
        let size = DVec3::new(1.0, 2.0, 3.0);
        let mesh = Mesh::cuboid(size);
        let count = 1000;
        let samples = mesh.sample(count);
        for axis in 0..3 {
            let side_area = size.element_product() / size[axis];
            let on_side = samples
                .surfels
                .iter()
                .filter(|s| s.normal[axis].abs() == 1.0)
                .count() as f64;
            // Each of the side's two triangles rounds its share up or down.
            let share = count as f64 * 2.0 * side_area / 22.0;
            assert!(
                (on_side - share).abs() <= 4.0,
                "axis {axis}: {on_side} vs {share}"
            );
        }
        // Pieces of one triangle have equal areas.
        let one = Mesh {
            positions: vec![
                DVec3::ZERO,
                DVec3::new(3.0, 0.0, 0.0),
                DVec3::new(0.5, 1.0, 0.0),
            ],
            triangles: vec![[0, 1, 2]],
        };
        for s in one.sample(7).surfels {
            assert!((s.area - 1.5 / 7.0).abs() < 1e-12);
            let p = s.position;
            assert!(
                p.y > 0.0 && p.y < 1.0 && p.y < p.x * 2.0 && p.z == 0.0,
                "{p}"
            );
        }
    }

    #[test]
    fn normals_are_the_faces_normals_and_surfels_lie_on_them() {
        let size = DVec3::new(1.0, 2.0, 3.0);
        for s in Mesh::cuboid(size).sample(2000).surfels {
            let axis = (0..3).find(|&k| s.normal[k].abs() == 1.0).unwrap();
            let outward = s.normal[axis];
            assert_eq!(s.normal.length(), 1.0);
            assert!((s.position[axis] - outward * size[axis] / 2.0).abs() < 1e-12);
            // The Gaussian lies in the face's plane.
            assert!(s.axis_u[axis].abs() < 1e-12 && s.axis_v[axis].abs() < 1e-12);
        }
        // Winding decides: the same square wound the other way faces −z.
        let mut flipped = square(1.0);
        for t in &mut flipped.triangles {
            t.swap(1, 2);
        }
        assert!(flipped
            .sample(50)
            .surfels
            .iter()
            .all(|s| s.normal == -DVec3::Z));
    }

    #[test]
    fn small_triangles_join_pieces_facing_the_same_way() {
        // Two sheets a hair apart, facing away from each other: far finer triangles than
        // pieces, so most join a piece, and none may join the other sheet's.
        let mut mesh = jittered_sheet(30, 0.0);
        let mut back = jittered_sheet(30, 1e-4);
        for t in &mut back.triangles {
            t.swap(1, 2);
        }
        let offset = mesh.positions.len() as u32;
        mesh.positions.extend(back.positions);
        mesh.triangles
            .extend(back.triangles.iter().map(|t| t.map(|i| i + offset)));
        let samples = mesh.sample(500);
        assert_eq!(samples.surfels.len(), 500);
        assert!(samples.joined > 3000, "joined {}", samples.joined);
        assert!((surfel_area(&samples) - 2.0).abs() < 1e-9);
        let up_area: f64 = samples
            .surfels
            .iter()
            .filter(|s| s.normal.z > 0.0)
            .map(|s| s.area)
            .sum();
        assert!((up_area - 1.0).abs() < 1e-9, "area facing up {up_area}");
        assert!(samples.surfels.iter().all(|s| s.normal.x == 0.0
            && s.normal.y == 0.0
            && (s.normal.z.abs() - 1.0).abs() < 1e-12));
    }

    #[test]
    fn a_speck_far_from_the_rest_is_left_out() {
        // Joining it would stretch a piece across the gap.
        let mut mesh = square(1.0);
        let speck = DVec3::new(10.0, 10.0, 0.0);
        mesh.positions
            .extend([speck, speck + DVec3::X * 1e-3, speck + DVec3::Y * 1e-3]);
        mesh.triangles.push([4, 5, 6]);
        let samples = mesh.sample(100);
        assert_eq!((samples.isolated, samples.joined), (1, 0));
        assert!((samples.area - 1.0).abs() < 1e-12);
        assert!((surfel_area(&samples) - 1.0).abs() < 1e-12);
        assert!(samples.surfels.iter().all(|s| s.position.x < 1.0));
    }

    #[test]
    fn sampling_is_the_same_whatever_the_thread_count() {
        let mesh = jittered_sheet(60, 0.0);
        let bits = |samples: MeshSamples| -> Vec<[u64; 13]> {
            samples
                .surfels
                .iter()
                .map(|s| {
                    let mut out = [0; 13];
                    let values = [s.position, s.normal, s.axis_u, s.axis_v]
                        .into_iter()
                        .flat_map(|v| v.to_array())
                        .chain([s.area]);
                    for (o, v) in out.iter_mut().zip(values) {
                        *o = v.to_bits();
                    }
                    out
                })
                .collect()
        };
        for count in [1_000, 20_000] {
            let default = bits(mesh.sample(count));
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                assert_eq!(default, pool.install(|| bits(mesh.sample(count))));
            }
        }
    }

    #[test]
    fn degenerate_triangles_are_left_out_and_counted() {
        let mut mesh = square(1.0);
        mesh.positions.push(DVec3::new(2.0, 2.0, 0.0));
        mesh.triangles.extend([
            [0, 0, 1],  // repeated corner
            [0, 2, 4],  // collinear corners
            [0, 1, 99], // no such vertex
            [1, 1, 1],
        ]);
        let samples = mesh.sample(100);
        assert_eq!(samples.degenerate, 4);
        assert_eq!(samples.surfels.len(), 100);
        assert!((surfel_area(&samples) - 1.0).abs() < 1e-12);
        assert!(samples.surfels.iter().all(|s| s.normal == DVec3::Z));

        let flat = Mesh {
            positions: vec![DVec3::ZERO; 3],
            triangles: vec![[0, 1, 2]],
        };
        let nothing = flat.sample(10);
        assert_eq!((nothing.surfels.len(), nothing.degenerate), (0, 1));
        assert!(square(1.0).sample(0).surfels.is_empty());
        assert!(flat.bounds().is_some() && Mesh::default().bounds().is_none());
    }
}
