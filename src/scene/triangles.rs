//! Triangle meshes drawn as triangles (`static`, `reference` and `analytic`): positions shared by
//! the triangles, a shading normal per corner and a colour per vertex, all in object space.
//!
//! Corner normals are smoothed across edges and split at creases: a corner takes the
//! area-weighted mean of the face normals around its vertex that lie within [`CREASE_DEGREES`]
//! of its own face's, so a scanned surface shades smoothly and a cube keeps its flat sides.

use glam::DVec3;

use crate::error::{Error, Result};
use crate::surfels::{Colouring, Mesh, DEFAULT_GREY};

/// Faces meeting at more than this angle keep their own normals along the shared edge.
pub const CREASE_DEGREES: f64 = 60.0;

/// A triangle mesh ready to draw.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Triangles, three indices into `positions` each, none degenerate.
    pub triangles: Vec<[u32; 3]>,
    /// Unit shading normal of each triangle's three corners.
    pub normals: Vec<[DVec3; 3]>,
    /// Linear RGB of each vertex.
    pub colours: Vec<[f32; 3]>,
    /// Whether every edge is shared by exactly two triangles wound consistently: a closed
    /// surface, whose triangles facing away from the eye are hidden and need not be drawn.
    pub closed: bool,
    /// Whether any part of it can shadow another: not when all its triangles lie in one plane
    /// (within [`PLANAR_TOLERANCE`] of its extent), nor when it is closed and convex, wound
    /// outward, so that every point the eye sees on it lies on its outside (docs/math.md,
    /// "Shadows a mesh cannot cast on itself"). Shadow lookups then leave the whole mesh out for
    /// its own points.
    pub shadows_itself: bool,
}

/// How far in front of a triangle's plane, as a share of the mesh's bounding box diagonal, a
/// vertex of a mesh that cannot shadow itself may lie ([`TriangleMesh::shadows_itself`]):
/// rounding in the file's coordinates, not shape. A bump this small could only shadow light
/// grazing the plane within about this many radians, whose Lambert term is no larger.
pub const PLANAR_TOLERANCE: f64 = 1e-6;

/// Most triangles of a closed mesh tested for convexity (each against every vertex); a larger
/// one is taken to shadow itself.
pub const MAX_CONVEX_TEST_TRIANGLES: usize = 4096;

impl TriangleMesh {
    /// The triangles of `mesh` with a positive area, moved by `-offset`, coloured as
    /// `colouring` says (a mesh file has no colours of its own: [`Colouring::Own`] is light grey).
    /// An error names `faces` when no triangle is left.
    pub fn new(mesh: &Mesh, offset: DVec3, colouring: Colouring) -> Result<TriangleMesh> {
        let positions: Vec<DVec3> = mesh.positions.iter().map(|&p| p - offset).collect();
        let mut triangles = Vec::with_capacity(mesh.triangles.len());
        let mut face_normals = Vec::with_capacity(mesh.triangles.len());
        for &t in &mesh.triangles {
            let Some([a, b, c]) = mesh.corners(t) else {
                continue;
            };
            // Twice the area along the unit normal; zero or non-finite areas are left out.
            let cross = (b - a).cross(c - a);
            if cross.length() > 0.0 && cross.is_finite() {
                triangles.push(t);
                face_normals.push(cross);
            }
        }
        if triangles.is_empty() {
            return Err(mesh.no_faces_left());
        }
        let normals = corner_normals(positions.len(), &triangles, &face_normals);
        let mut vertex_normals = vec![DVec3::ZERO; positions.len()];
        for (t, corners) in triangles.iter().zip(&normals) {
            for (&v, n) in t.iter().zip(corners) {
                vertex_normals[v as usize] += *n;
            }
        }
        let colours = vertex_normals
            .iter()
            .map(|n| match colouring {
                Colouring::Own => DEFAULT_GREY,
                Colouring::Rgb(rgb) => rgb,
                Colouring::Normal => (n.normalize_or_zero() * 0.5 + 0.5).as_vec3().to_array(),
            })
            .collect();
        let closed = is_closed(&triangles);
        let shadows_itself = shadows_itself(&positions, &triangles, &face_normals, closed);
        Ok(TriangleMesh {
            positions,
            triangles,
            normals,
            colours,
            closed,
            shadows_itself,
        })
    }

    /// A mesh of `triangles` over `positions` with a colour per vertex (a simplified mesh, say):
    /// corner normals made as [`TriangleMesh::new`] makes them, triangles without area left out.
    /// An error names `faces` when none is left, `colours` when they are not one per vertex.
    pub fn from_parts(
        positions: Vec<DVec3>,
        triangles: Vec<[u32; 3]>,
        colours: Vec<[f32; 3]>,
    ) -> Result<TriangleMesh> {
        if colours.len() != positions.len() {
            return Err(Error::invalid(
                "colours",
                format!("{} colours for {} vertices", colours.len(), positions.len()),
            ));
        }
        let mut mesh = TriangleMesh::new(
            &Mesh {
                positions,
                triangles,
            },
            DVec3::ZERO,
            Colouring::Own,
        )?;
        mesh.colours = colours;
        Ok(mesh)
    }
}

/// Whether each directed edge appears once and its reverse once: a closed, consistently wound
/// surface.
fn is_closed(triangles: &[[u32; 3]]) -> bool {
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .collect();
    edges.sort_unstable();
    let unique = edges.windows(2).all(|w| w[0] != w[1]);
    unique
        && edges
            .iter()
            .all(|&(a, b)| edges.binary_search(&(b, a)).is_ok())
}

/// [`TriangleMesh::shadows_itself`] for `triangles` over `positions` (`face_normals` twice
/// their areas along their winding's normals), `closed` as [`is_closed`] says: not when every
/// vertex they use lies within [`PLANAR_TOLERANCE`] of the largest triangle's plane, nor, for a
/// closed mesh of at most [`MAX_CONVEX_TEST_TRIANGLES`], when none lies more than that in front
/// of any triangle's plane (convex and wound outward).
fn shadows_itself(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    face_normals: &[DVec3],
    closed: bool,
) -> bool {
    let mut used: Vec<u32> = triangles.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    let corners: Vec<DVec3> = used.iter().map(|&v| positions[v as usize]).collect();
    let (lo, hi) = crate::math::bounds(corners.iter().copied());
    let tolerance = PLANAR_TOLERANCE * (hi - lo).length();
    // How far each corner lies in front of the plane of triangle t.
    let heights = |t: &[u32; 3], n: &DVec3| {
        let (normal, origin) = (n.normalize(), positions[t[0] as usize]);
        corners.iter().map(move |&p| (p - origin).dot(normal))
    };
    let largest = triangles
        .iter()
        .zip(face_normals)
        .max_by(|a, b| a.1.length_squared().total_cmp(&b.1.length_squared()));
    let planar = largest.is_some_and(|(t, n)| heights(t, n).all(|h| h.abs() <= tolerance));
    let convex = || {
        closed
            && triangles.len() <= MAX_CONVEX_TEST_TRIANGLES
            && triangles
                .iter()
                .zip(face_normals)
                .all(|(t, n)| heights(t, n).all(|h| h <= tolerance))
    };
    !(planar || convex())
}

/// The faces around each of `vertices` vertices, as a compressed list: vertex v's are
/// `faces[starts[v]..starts[v + 1]]`, in face order.
pub(crate) fn faces_around(vertices: usize, triangles: &[[u32; 3]]) -> (Vec<usize>, Vec<u32>) {
    let mut starts = vec![0usize; vertices + 1];
    for t in triangles {
        for &v in t {
            starts[v as usize + 1] += 1;
        }
    }
    for i in 1..starts.len() {
        starts[i] += starts[i - 1];
    }
    let mut fill = starts.clone();
    let mut faces = vec![0u32; starts[vertices]];
    for (f, t) in triangles.iter().enumerate() {
        for &v in t {
            faces[fill[v as usize]] = f as u32;
            fill[v as usize] += 1;
        }
    }
    (starts, faces)
}

/// Around a vertex with more faces than this, the crease test is made once per distinct face
/// normal rather than once per pair of faces: the pairs grow as the square of the faces, and one
/// polygon of 900,000 corners in a 2.7 KB `.obj.gz` put 300,000 faces around each of its three
/// vertices.
const GROUPED_ABOVE_VALENCE: usize = 64;

/// At most this many groups of normals around one vertex: with more distinct normals, the faces
/// are grouped by cells of a cube map of 16 × 16 cells a side (up to 6° across), and the crease
/// test is made between the cells' mean directions.
const MAX_NORMAL_GROUPS: usize = 6 * 16 * 16;

/// Each corner's normal: the sum of the (area-weighted) normals of the faces around its vertex
/// within [`CREASE_DEGREES`] of its own face's, normalized.
fn corner_normals(
    vertices: usize,
    triangles: &[[u32; 3]],
    face_normals: &[DVec3],
) -> Vec<[DVec3; 3]> {
    let (starts, faces) = faces_around(vertices, triangles);
    let cos_crease = CREASE_DEGREES.to_radians().cos();
    let units: Vec<DVec3> = face_normals.iter().map(|n| n.normalize()).collect();
    let around = |v: u32| &faces[starts[v as usize]..starts[v as usize + 1]];
    // Per vertex with many faces around it, each face's corner normal there, in face order.
    let grouped: std::collections::HashMap<u32, Vec<DVec3>> = (0..vertices as u32)
        .filter(|&v| around(v).len() > GROUPED_ABOVE_VALENCE)
        .map(|v| {
            (
                v,
                grouped_normals(around(v), &units, face_normals, cos_crease),
            )
        })
        .collect();
    triangles
        .iter()
        .enumerate()
        .map(|(f, t)| {
            t.map(|v| {
                let around = around(v);
                if around.len() > GROUPED_ABOVE_VALENCE {
                    // `around` is in face order and holds f (once per corner f has at v).
                    let at = around.partition_point(|&g| (g as usize) < f);
                    return grouped[&v][at];
                }
                let sum: DVec3 = around
                    .iter()
                    .filter(|&&g| units[g as usize].dot(units[f]) >= cos_crease)
                    .map(|&g| face_normals[g as usize])
                    .sum();
                sum.try_normalize().unwrap_or(units[f])
            })
        })
        .collect()
}

/// [`corner_normals`] at one vertex whose faces are `around`: the faces are grouped by their
/// unit normal (bit for bit, so the result is the pairwise one up to the order of the sums) or,
/// past [`MAX_NORMAL_GROUPS`] distinct normals, by cube-map cell; the crease test is made between
/// groups. The work is the faces plus the groups squared.
fn grouped_normals(
    around: &[u32],
    units: &[DVec3],
    face_normals: &[DVec3],
    cos_crease: f64,
) -> Vec<DVec3> {
    let group_by = |key: &dyn Fn(DVec3) -> [u64; 3]| {
        let mut index = std::collections::HashMap::new();
        // Per group: the sum of its unit normals (its direction) and of its faces' normals.
        let mut groups: Vec<[DVec3; 2]> = Vec::new();
        let of_face: Vec<usize> = around
            .iter()
            .map(|&g| {
                let unit = units[g as usize];
                let at = *index.entry(key(unit)).or_insert_with(|| {
                    groups.push([DVec3::ZERO; 2]);
                    groups.len() - 1
                });
                groups[at][0] += unit;
                groups[at][1] += face_normals[g as usize];
                at
            })
            .collect();
        (groups, of_face)
    };
    let (mut groups, mut of_face) = group_by(&|unit| unit.to_array().map(f64::to_bits));
    if groups.len() > MAX_NORMAL_GROUPS {
        (groups, of_face) = group_by(&cube_map_cell);
    }
    let directions: Vec<DVec3> = groups.iter().map(|[u, _]| u.normalize()).collect();
    let sums: Vec<DVec3> = directions
        .iter()
        .map(|d| {
            (directions.iter().zip(&groups))
                .filter(|(e, _)| e.dot(*d) >= cos_crease)
                .map(|(_, [_, sum])| *sum)
                .sum()
        })
        .collect();
    around
        .iter()
        .zip(of_face)
        .map(|(&g, at)| sums[at].try_normalize().unwrap_or(units[g as usize]))
        .collect()
}

/// The cell of a cube map, 16 × 16 cells a side, that unit vector `n` points into (one key for
/// every vector that is not finite).
fn cube_map_cell(n: DVec3) -> [u64; 3] {
    if !n.is_finite() {
        return [u64::MAX; 3];
    }
    let a = n.abs().to_array();
    let major = if a[0] >= a[1] && a[0] >= a[2] {
        0
    } else if a[1] >= a[2] {
        1
    } else {
        2
    };
    let n = n.to_array();
    let cell = |i: usize| {
        let along = n[(major + i) % 3] / a[major];
        ((along + 1.0) * 8.0).floor().clamp(0.0, 15.0) as u64
    };
    [
        2 * major as u64 + u64::from(n[major] < 0.0),
        cell(1),
        cell(2),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> Mesh {
        Mesh::cuboid(DVec3::ONE)
    }

    /// The largest angle, in degrees, between `corner_normals` and the pairwise crease test at
    /// the apex of a cone of `segments` faces whose normals fan round it (each face's crease
    /// neighbours are those within 60° of azimuth or so).
    fn apex_error_degrees(segments: usize) -> f64 {
        let ring = (0..segments).map(|i| {
            let a = std::f64::consts::TAU * i as f64 / segments as f64;
            DVec3::new(a.cos(), a.sin(), 0.0)
        });
        let positions: Vec<DVec3> = std::iter::once(DVec3::new(0.0, 0.0, 0.6))
            .chain(ring)
            .collect();
        let triangles: Vec<[u32; 3]> = (0..segments as u32)
            .map(|i| [0, 1 + i, 1 + (i + 1) % segments as u32])
            .collect();
        let face_normals: Vec<DVec3> = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| positions[v as usize]);
                (b - a).cross(c - a)
            })
            .collect();
        let cos_crease = CREASE_DEGREES.to_radians().cos();
        let normals = corner_normals(positions.len(), &triangles, &face_normals);
        (0..segments)
            .map(|f| {
                let unit = face_normals[f].normalize();
                let pairwise: DVec3 = (face_normals.iter())
                    .filter(|n| n.normalize().dot(unit) >= cos_crease)
                    .sum();
                let angle = normals[f][0]
                    .dot(pairwise.normalize())
                    .clamp(-1.0, 1.0)
                    .acos();
                angle.to_degrees()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_vertex_with_many_faces_gets_the_pairwise_normals_or_close_to_them() {
        // 200 faces: grouped by exact normal, the same sums in another order.
        assert!(apex_error_degrees(200) < 1e-9);
        // 3,000 distinct normals: grouped in cube-map cells (up to 6° across); a cell straddling
        // the crease brings in or leaves out the faces at its edge, a few of the ~1,000 summed
        // (1.7° at worst, measured).
        let coarse = apex_error_degrees(3000);
        assert!(coarse < 2.5, "{coarse}°");
    }
    #[test]
    fn a_tilted_grid_and_a_cube_cannot_shadow_themselves_a_bent_grid_or_an_inverted_cube_can() {
        // A 4 × 4 grid of squares in a tilted plane, its coordinates in f32 as a file has them.
        let (u, v) = (DVec3::new(1.0, 0.3, -0.2), DVec3::new(0.1, 0.7, 0.9));
        let mut grid = Mesh {
            positions: (0..25)
                .map(|i| {
                    (u * f64::from(i % 5) + v * f64::from(i / 5))
                        .as_vec3()
                        .as_dvec3()
                })
                .collect(),
            triangles: (0..16u32)
                .flat_map(|q| {
                    let c = q % 4 + 5 * (q / 4);
                    [[c, c + 1, c + 6], [c, c + 6, c + 5]]
                })
                .collect(),
        };
        let shadows_itself = |mesh: &Mesh| {
            TriangleMesh::new(mesh, DVec3::ZERO, Colouring::Own)
                .unwrap()
                .shadows_itself
        };
        assert!(!shadows_itself(&grid));
        assert!(!shadows_itself(&cube()));
        // Wound inward, the same cube shows its inside, where one wall shadows another.
        let mut inverted = cube();
        inverted.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        assert!(shadows_itself(&inverted));
        // Not closed, a convex surface may be seen and lit from its inside.
        let mut open = cube();
        open.triangles.pop();
        assert!(shadows_itself(&open));
        // One corner lifted by a thousandth of the grid's size off its plane.
        grid.positions[12] += u.cross(v).normalize() * 0.005;
        assert!(shadows_itself(&grid));
    }

    #[test]
    fn a_cube_keeps_flat_faces_and_degenerate_triangles_are_dropped() {
        let mut mesh = cube();
        mesh.triangles.push([0, 0, 1]);
        mesh.triangles.push([0, 1, 99]);
        let drawn = TriangleMesh::new(&mesh, DVec3::ZERO, Colouring::Own).unwrap();
        assert_eq!(drawn.triangles.len(), 12);
        assert!(drawn.closed);
        let mut open = cube();
        open.triangles.pop();
        assert!(
            !TriangleMesh::new(&open, DVec3::ZERO, Colouring::Own)
                .unwrap()
                .closed
        );
        for (t, corners) in drawn.triangles.iter().zip(&drawn.normals) {
            let [a, b, c] = t.map(|v| drawn.positions[v as usize]);
            let face = (b - a).cross(c - a).normalize();
            // Outward: the face normal points away from the centred cube's middle.
            assert!(face.dot((a + b + c) / 3.0) > 0.0);
            for n in corners {
                assert!((n.dot(face) - 1.0).abs() < 1e-12, "{n} against {face}");
            }
        }
    }

    #[test]
    fn a_mesh_of_only_degenerate_triangles_is_an_error_naming_faces() {
        let mesh = Mesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0],
            triangles: vec![[0, 1, 2]],
        };
        let message = TriangleMesh::new(&mesh, DVec3::ZERO, Colouring::Own)
            .unwrap_err()
            .to_string();
        assert!(message.starts_with("faces: "), "{message}");
        assert!(message.ends_with("1 of zero area"), "{message}");
    }

    #[test]
    fn a_mesh_too_large_for_its_areas_is_told_to_be_scaled_down() {
        // Its area, 5·10⁵⁹⁹, overflows a double: not "zero area", as it was once called.
        let mesh = Mesh {
            positions: vec![DVec3::ZERO, DVec3::X * 1e300, DVec3::Y * 1e300, DVec3::X],
            triangles: vec![[0, 1, 2], [0, 1, 7]],
        };
        let expected = "faces: none of the 2 triangles has a surface to draw or sample: 1 \
                        indexing past the 4 vertices, 1 too large for their area to be a double \
                        (coordinates up to 1e300: scale the model down)";
        let drawn = TriangleMesh::new(&mesh, DVec3::ZERO, Colouring::Own).unwrap_err();
        assert_eq!(drawn.to_string(), expected);
        let sampled = crate::surfels::from_mesh(&mesh, 100, false).unwrap_err();
        assert_eq!(sampled.to_string(), expected);
    }
}
