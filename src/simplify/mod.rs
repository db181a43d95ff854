//! Triangle mesh simplification by quadric edge collapse (Garland & Heckbert 1997), with the
//! motion-aware edge weights of Zhang et al. 2014 (§4) and their level of detail from screen
//! speed (§5, [`speed`]).
//!
//! [`simplify`] repairs what it can, says what it repaired ([`Repairs`]), and collapses edges
//! cheapest first until the mesh has the faces asked for, or no edge may collapse without
//! breaking the surface or a detail limit ([`collapse`] lists the safeguards). A manifold input
//! stays manifold, closed stays closed, and no face folds over. A mesh of at least
//! 2 × [`BLOCK_VERTICES`] vertices is first collapsed in parallel blocks, up to a little short of
//! the target, and a single queue finishes it. The result depends on the input alone, whatever
//! the thread count.

mod blocks;
pub mod collapse;
mod heap;
pub mod quadric;
pub mod speed;

use glam::DVec3;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::math::MortonCurve;
use crate::surfels::Mesh;
pub use blocks::{BLOCK_VERTICES, MAX_BLOCKS};
use collapse::{first_normals, Collapser, FacesAround, Vertices};
pub use collapse::{Stats, MAX_DRIFT_DEGREES, MAX_TURN_DEGREES, MAX_VALENCE};

/// Zhang et al.'s exponent r in eq. 4, from their user study (Appendix A).
pub const DIRECTION_EXPONENT: i32 = 4;

/// Zhang et al.'s ε in eq. 4: edges along the motion still collapse, at a cost weighted by ε
/// against 1 + ε for edges across it.
pub const DIRECTION_EPSILON: f64 = 0.5;

/// Eq. 4 of Zhang et al. 2014 for an edge at angle α to the motion, given |cos α|:
/// f = 1 − (1 − cos α)^r + ε. Edges across the motion (cos α = 0) weigh ε and collapse first;
/// edges along it weigh 1 + ε.
#[must_use]
pub fn direction_weight(cos_alpha: f64) -> f64 {
    1.0 - (1.0 - cos_alpha.clamp(0.0, 1.0)).powi(DIRECTION_EXPONENT) + DIRECTION_EPSILON
}

/// How edge costs are weighted by motion.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Weighting {
    /// Plain quadric costs (f ≡ 1): isotropic QEM.
    #[default]
    Isotropic,
    /// One motion direction for the whole mesh (object space; any length but zero).
    Direction(DVec3),
    /// A motion per vertex (object space; zero where a vertex does not move), for rotations:
    /// an edge takes the sum of its ends' motions.
    PerVertex(Vec<DVec3>),
}

/// Detail limits: the longest perimeter, in object units, a face touching each vertex may grow
/// to (Zhang et al. §5.1 take a triangle's projected perimeter as its feature size).
#[derive(Clone, Debug, PartialEq)]
pub struct Limits {
    /// One limit per vertex of the input mesh.
    pub per_vertex: Vec<f64>,
}

/// What to simplify to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Options {
    /// Stop when this many faces are left (0: as far as the limits and safeguards allow).
    pub target_faces: usize,
    /// Edge weights by motion.
    pub weighting: Weighting,
    /// Per-vertex detail limits, if any.
    pub limits: Option<Limits>,
}

/// What was repaired in the input before simplifying.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Repairs {
    /// Vertices at exactly the position of an earlier vertex, welded to it (a mesh split along
    /// its normals or texture seams, as OBJ exporters write them).
    pub welded: usize,
    /// Faces with a corner repeated (after welding), dropped: they have no area and no edges
    /// of their own.
    pub repeated_corners: usize,
    /// Faces on the same three vertices as an earlier face, dropped.
    pub duplicate_faces: usize,
    /// Edges shared by more than two faces: their vertices are kept in place.
    pub non_manifold_edges: usize,
    /// Vertices no face uses, left out of the result.
    pub isolated: usize,
}

/// A simplified mesh and how it was made.
#[derive(Clone, Debug, PartialEq)]
pub struct Simplified {
    /// The result: the surviving vertices in input order, the surviving faces in input order.
    pub mesh: Mesh,
    /// The carried per-vertex channels of the result's vertices, as many per vertex as given.
    pub carried: Vec<f32>,
    /// What was repaired first.
    pub repairs: Repairs,
    /// What the collapse loop did and refused.
    pub stats: Stats,
    /// Whether the face target was reached (otherwise every remaining collapse was refused).
    pub reached_target: bool,
}

/// Simplify `mesh` as `options` say. `carried` holds per-vertex channels (`channels` numbers
/// per input vertex: colours, normals, texture coordinates) which are interpolated along each
/// collapsed edge at the merged vertex's place (normals come back unnormalized). `progress`
/// hears the face count now and then.
///
/// Errors: a position that is not finite, or a face corner past the vertices, named by index;
/// `carried` of the wrong length, or differing between vertices at one position (welded, one
/// would take the other's); limits not one per vertex, or not positive; a motion direction that
/// is not finite or is zero, or motions not one finite one per vertex.
pub fn simplify(
    mesh: &Mesh,
    options: &Options,
    carried: (&[f32], usize),
    progress: &mut dyn FnMut(usize),
) -> Result<Simplified> {
    let (values, channels) = carried;
    let n = mesh.positions.len();
    if values.len() != n * channels {
        return Err(Error::invalid(
            "carried",
            format!(
                "{} numbers for {n} vertices of {channels} channels",
                values.len()
            ),
        ));
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::invalid(
            format!("vertex {i}"),
            format!("{} is not a finite position", mesh.positions[i]),
        ));
    }
    if let Some(i) = mesh
        .triangles
        .iter()
        .position(|t| t.iter().any(|&v| v as usize >= n))
    {
        return Err(Error::invalid(
            format!("face {i}"),
            format!(
                "{:?} names a vertex past the {n} there are",
                mesh.triangles[i]
            ),
        ));
    }
    if let Some(limits) = &options.limits {
        if limits.per_vertex.len() != n || !limits.per_vertex.iter().all(|&l| l > 0.0) {
            return Err(Error::invalid(
                "limits",
                format!("need one positive limit per vertex ({n})"),
            ));
        }
    }
    if let Weighting::Direction(d) = options.weighting {
        if !(d.is_finite() && d != DVec3::ZERO) {
            return Err(Error::invalid(
                "weighting",
                format!("direction {d}: must be finite and not the zero vector"),
            ));
        }
    }
    if let Weighting::PerVertex(m) = &options.weighting {
        if m.len() != n || !m.iter().all(|v| v.is_finite()) {
            return Err(Error::invalid(
                "weighting",
                format!("need one finite motion per vertex ({n})"),
            ));
        }
    }
    let mut repairs = Repairs::default();
    let order = VertexOrder::new(mesh);
    if let Some((v, first)) = order.first_seam(values, channels) {
        return Err(Error::invalid(
            "carried",
            format!(
                "vertex {v} lies where vertex {first} does with other values (a seam, as where \
                 colours change): welding them would give it vertex {first}'s"
            ),
        ));
    }
    repairs.welded = n - order.original.len();
    let (faces, around) = repaired_faces(mesh, &order, &mut repairs);

    // The collapser works on the vertices in curve order; what it is given per input vertex is
    // taken from each position's first vertex.
    let (motions, direction) = match &options.weighting {
        Weighting::PerVertex(motions) => (order.gather(motions, 1), None),
        Weighting::Direction(d) => (Vec::new(), Some(*d)),
        Weighting::Isotropic => (Vec::new(), None),
    };
    let limits = options
        .limits
        .as_ref()
        .map(|l| order.gather(&l.per_vertex, 1));
    let carried_in = order.gather(values, channels);
    // Measured from a point near the mesh's middle, positions far from the origin keep their
    // digits in the planes' offsets and the quadrics' errors (see `origin`).
    let mut positions = order.gather(&mesh.positions, 1);
    let origin = origin(&positions);
    positions.par_iter_mut().for_each(|p| *p -= origin);
    let normals = first_normals(&positions, &faces);
    let (mut vertices, edges, non_manifold_edges) =
        Vertices::new(positions, &faces, &around, carried_in, motions, limits);
    repairs.non_manifold_edges = non_manifold_edges;
    let target = options.target_faces;
    let blocked = blocks::collapse_in_blocks(
        &mut vertices,
        faces,
        around,
        edges,
        &normals,
        target,
        channels,
        direction,
        progress,
    );
    let (faces, normals) = blocked
        .faces
        .into_iter()
        .map(|(face, place)| (face, normals[place as usize]))
        .unzip();
    let mut collapser = Collapser::new(
        vertices.as_mut(),
        faces,
        normals,
        Vec::new(),
        blocked.known,
        channels,
        direction,
    );
    // A face count one above the target is finished on a boundary edge if it can be, so that an
    // open mesh reaches any target exactly.
    let exact = target > 0;
    collapser.run(target + usize::from(exact), usize::MAX, progress);
    if !(exact && collapser.finish_on_boundary(target)) {
        collapser.run(target, usize::MAX, progress);
    }
    let reached_target = collapser.live_faces <= target;
    let mut stats = collapser.stats;
    stats += blocked.stats;
    let faces = collapser.into_faces();

    // Keep the vertices live faces use, in input order.
    let mut used = vec![false; order.original.len()];
    for (face, _) in &faces {
        for &v in face {
            used[v as usize] = true;
        }
    }
    let mut kept: Vec<(u32, u32)> = (0..order.original.len() as u32)
        .filter(|&v| used[v as usize])
        .map(|v| (order.original[v as usize], v))
        .collect();
    kept.sort_unstable();
    let mut index = vec![u32::MAX; order.original.len()];
    let mut out = Mesh::default();
    let mut carried_out = Vec::new();
    for &(_, v) in &kept {
        let v = v as usize;
        index[v] = out.positions.len() as u32;
        let p = vertices.points[v].position;
        // Where the origin is zero the position is as it was, −0 too.
        out.positions
            .push(DVec3::select(origin.cmpeq(DVec3::ZERO), p, p + origin));
        carried_out.extend_from_slice(&vertices.carried[v * channels..(v + 1) * channels]);
    }
    out.triangles = faces
        .into_iter()
        .map(|(face, _)| face.map(|v| index[v as usize]))
        .collect();
    Ok(Simplified {
        mesh: out,
        carried: carried_out,
        repairs,
        stats,
        reached_target,
    })
}

/// The point the simplifier measures `positions` from: their bounding box's centre, each
/// coordinate rounded towards zero to a multiple of the power of two s at least the box's
/// largest side. Measured from the origin, a mesh far from it loses digits: the planes' offsets d
/// grow with the distance, and the quadrics' errors, small differences of large terms, cancel (a
/// 24 × 24 rippled grid moved by 10⁶ on each axis gave 1,377 fold refusals rather than 2).
/// Every position less this point is exact: on an axis where the point, a multiple of s, is not
/// zero, a coordinate lies within s / 2 of the centre, so at least s / 2 from zero; below s it is
/// a multiple of 2⁻⁵³ s within s / 2 of the point, past s a multiple of 2⁻⁵² s within 1.5 s of
/// it, and either difference fits in 53 bits. The point is zero, and the simplification the same
/// bit for bit, for a mesh whose centre lies within s of the origin on every axis, as a centred
/// mesh's does.
fn origin(positions: &[DVec3]) -> DVec3 {
    let (lo, hi) = crate::math::bounds(positions.iter().copied());
    let side = (hi - lo).max_element();
    if !(side.is_finite() && side > 0.0) {
        return DVec3::ZERO;
    }
    let mut step = side.log2().ceil().exp2();
    if step < side {
        step *= 2.0;
    }
    // Adding zero turns −0 into +0, which leaves a −0 coordinate alone when subtracted.
    let origin = ((lo + 0.5 * (hi - lo)) / step).trunc() * step + DVec3::ZERO;
    if origin.is_finite() {
        origin
    } else {
        DVec3::ZERO
    }
}

/// The input's distinct positions laid out along a Morton curve, so that a run of consecutive
/// vertices is a compact patch of the surface: the blocks collapsed in parallel (`blocks`) are
/// such runs, and their seams stay short.
struct VertexOrder {
    /// For each vertex in curve order, the first input vertex at its position.
    original: Vec<u32>,
    /// For each input vertex, its place in curve order (vertices at one position share it).
    place: Vec<u32>,
}

impl VertexOrder {
    /// Sorted in parallel by (key, position, index), so vertices at exactly one position (signed
    /// zeros alike) fall next to each other and the first of them comes first.
    fn new(mesh: &Mesh) -> VertexOrder {
        let curve = MortonCurve::around(mesh.positions.iter().copied());
        // Adding zero turns −0 into +0, so the two weld.
        let bits = |p: DVec3| (p + DVec3::ZERO).to_array().map(f64::to_bits);
        let mut sorted: Vec<(u64, [u64; 3], u32)> = mesh
            .positions
            .par_iter()
            .enumerate()
            .map(|(v, &p)| (curve.key(p), bits(p), v as u32))
            .collect();
        sorted.par_sort_unstable();
        let mut original = Vec::with_capacity(sorted.len());
        let mut place = vec![0u32; sorted.len()];
        for (i, &(key, position, v)) in sorted.iter().enumerate() {
            if i == 0 || (key, position) != (sorted[i - 1].0, sorted[i - 1].1) {
                original.push(v);
            }
            place[v as usize] = original.len() as u32 - 1;
        }
        VertexOrder { original, place }
    }

    /// The first input vertex whose `per` values differ from those of the first vertex at its
    /// position, and that vertex: welded, it would take them.
    fn first_seam(&self, values: &[f32], per: usize) -> Option<(usize, usize)> {
        if per == 0 {
            return None;
        }
        (0..self.place.len()).find_map(|v| {
            let first = self.original[self.place[v] as usize] as usize;
            let own = &values[v * per..(v + 1) * per];
            let welded = &values[first * per..(first + 1) * per];
            (own != welded).then_some((v, first))
        })
    }

    /// Per-vertex values given in input order (`per` of them per vertex), in curve order: each
    /// position's first vertex's.
    fn gather<T: Copy + Send + Sync>(&self, values: &[T], per: usize) -> Vec<T> {
        (0..self.original.len() * per)
            .into_par_iter()
            .map(|i| values[self.original[i / per] as usize * per + i % per])
            .collect()
    }
}

/// The faces in curve-order vertices, less those with a repeated corner or repeating an earlier
/// face, and the faces around each vertex. An earlier face on the same three vertices is among
/// the faces around the lowest of them: on a 1.6 M-face mesh, looking there cost less than
/// sorting the faces by their corners, which cost less than hashing them.
fn repaired_faces(
    mesh: &Mesh,
    order: &VertexOrder,
    repairs: &mut Repairs,
) -> (Vec<[u32; 3]>, FacesAround) {
    let n = order.original.len();
    let mut faces: Vec<[u32; 3]> = mesh
        .triangles
        .par_iter()
        .map(|t| t.map(|v| order.place[v as usize]))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0])
        .collect();
    repairs.repeated_corners = mesh.triangles.len() - faces.len();
    let mut around = FacesAround::new(n, &faces);
    // No face repeats a corner, so a face with all three of `t`'s is a face on the same three.
    let repeats: Vec<bool> = faces
        .par_iter()
        .enumerate()
        .map(|(f, &t)| {
            let [v, w, x] = t;
            let lowest = v.min(w).min(x);
            around
                .of(lowest as usize)
                .iter()
                .any(|&g| (g as usize) < f && t.iter().all(|c| faces[g as usize].contains(c)))
        })
        .collect();
    repairs.duplicate_faces = repeats.iter().filter(|&&r| r).count();
    if repairs.duplicate_faces > 0 {
        let mut repeats = repeats.iter();
        faces.retain(|_| !*repeats.next().expect("one flag per face"));
        around = FacesAround::new(n, &faces);
    }
    repairs.isolated = (0..n).filter(|&v| around.of(v).is_empty()).count();
    (faces, around)
}
