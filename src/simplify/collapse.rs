//! The edge-collapse loop (Garland & Heckbert 1997, §3–4): every edge gets the cost of moving its
//! two ends to the point its summed quadric likes best, the cheapest edge is collapsed, and the
//! edges around the merged vertex are costed again. The heap (`super::heap`) is lazy: an entry
//! carries the summed versions of its two vertices (which only grow) and is dropped when popped
//! stale.
//!
//! Safeguards, checked when an edge is popped, so that a manifold input stays manifold:
//! - the link condition (the vertices next to both ends are exactly the corners opposite the
//!   edge), and no interior edge between two boundary vertices (it would pinch the surface);
//! - no corner opposite the edge left with two faces (a closed tetrahedron would fold flat);
//! - no face turned by more than [`MAX_TURN_DEGREES`] in one collapse or [`MAX_DRIFT_DEGREES`]
//!   from its normal in the input, or shrunk to nothing (fold-overs);
//! - no vertex with more than [`MAX_VALENCE`] faces, which also bounds the work of each
//!   collapse: without it a fan of n faces costs n² (see `Stats::valence_refusals`);
//! - vertices on an edge shared by more than two faces never move (`locked`).

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::heap::{Entry, Heap};
use super::quadric::Quadric;
use crate::scene::triangles::faces_around;

/// Largest turn of a face's normal a collapse may cause, degrees: past a right angle a face has
/// folded over; a little short of it catches the near-folds that flip with the next collapse.
pub const MAX_TURN_DEGREES: f64 = 80.0;

/// Largest turn of a face's normal from its normal in the input, degrees. Each collapse may turn a
/// face by up to [`MAX_TURN_DEGREES`], and turns add up: at 90° from the input, needles standing
/// across the surface were left on the bunny (one face facing away from the input surface nearest
/// it); at 60° none, at the same mean distance to the input (docs/math.md, "Mesh simplification
/// and its level of detail").
pub const MAX_DRIFT_DEGREES: f64 = 60.0;

/// Most faces one vertex may gather (see the module notes).
pub const MAX_VALENCE: usize = 32;

/// Weight of the planes that hold a boundary edge in place, relative to the area weight of a
/// face whose side is that edge (Garland & Heckbert §6.1's penalty planes).
const BOUNDARY_PENALTY: f64 = 100.0;

/// How often, in collapses, the progress callback hears the face count.
const PROGRESS_EVERY: usize = 8192;

/// What the loop counted. Refusals count attempts, not edges: an edge is tried again whenever
/// the faces around it change, and the queue that finishes after the parallel blocks tries
/// every edge left once more, so one edge may be refused several times.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Edges collapsed.
    pub collapses: usize,
    /// Attempts refused because a face would fold over or vanish.
    pub fold_refusals: usize,
    /// Attempts refused by the link condition or a boundary pinch.
    pub topology_refusals: usize,
    /// Attempts refused because a vertex would gather more than [`MAX_VALENCE`] faces.
    pub valence_refusals: usize,
    /// Attempts refused because a face would grow past its detail limit.
    pub limit_refusals: usize,
}

impl std::ops::AddAssign for Stats {
    fn add_assign(&mut self, other: Stats) {
        self.collapses += other.collapses;
        self.fold_refusals += other.fold_refusals;
        self.topology_refusals += other.topology_refusals;
        self.valence_refusals += other.valence_refusals;
        self.limit_refusals += other.limit_refusals;
    }
}

/// Why the faces around a collapse refuse it.
enum Refusal {
    Fold,
    Limit,
}

/// What costing and checking a collapse read of a vertex, side by side in two cache lines, where
/// six arrays took up to seven (the loop waits on these loads: docs/history.md, "Issue 12, fifth
/// part").
#[derive(Clone, Copy, Debug, Default)]
#[repr(align(64))]
pub(super) struct Point {
    pub quadric: Quadric,
    pub position: DVec3,
    /// On an edge of one face.
    pub boundary: bool,
    /// On an edge of more than two faces: never moves.
    pub locked: bool,
    /// Faces around it that the collapser working on it does not hold (see `super::blocks`);
    /// a vertex with any may not be an end of a collapse. Zero outside a collapser.
    pub faces_elsewhere: u32,
    /// The collapser's last visit that marked it (see `Collapser::next_visit`): sets of
    /// neighbours without sorting or clearing. Zero outside a collapser.
    pub mark: u32,
}

/// What a collapse works on per vertex, and gives back: the rest of the collapser is
/// bookkeeping.
pub(super) struct Vertices {
    pub points: Vec<Point>,
    /// Channels carried along, `channels` numbers per vertex, interpolated along each edge.
    pub carried: Vec<f32>,
    /// Motion per vertex (for [`super::Weighting::PerVertex`], else empty), carried like a channel.
    pub motions: Vec<DVec3>,
    /// Longest perimeter, object units, of a face touching each vertex.
    pub limits: Option<Vec<f64>>,
    /// A power of two near the inverse fourth power of the mesh's size: costs (areas times
    /// squared distances) are queued times this, so that the queue's f32 bins see the same
    /// numbers at any scale (see [`cost_scale`]).
    pub cost_scale: f64,
}

/// The vertices a collapser works on, borrowed from [`Vertices`] (all of them, or a block's run
/// of them): the blocks collapse in place, so nothing is copied out and joined back.
pub(super) struct VerticesMut<'a> {
    pub points: &'a mut [Point],
    pub carried: &'a mut [f32],
    /// Empty when there are no motions per vertex.
    pub motions: &'a mut [DVec3],
    pub limits: Option<&'a mut [f64]>,
    pub cost_scale: f64,
}

impl<'a> VerticesMut<'a> {
    /// The first `mid` vertices and the rest (`channels` carried numbers each).
    pub fn split_at(self, mid: usize, channels: usize) -> (VerticesMut<'a>, VerticesMut<'a>) {
        let (points, points_rest) = self.points.split_at_mut(mid);
        let (carried, carried_rest) = self.carried.split_at_mut(mid * channels);
        let motions_mid = if self.motions.is_empty() { 0 } else { mid };
        let (motions, motions_rest) = self.motions.split_at_mut(motions_mid);
        let (limits, limits_rest) = match self.limits {
            Some(l) => {
                let (l, rest) = l.split_at_mut(mid);
                (Some(l), Some(rest))
            }
            None => (None, None),
        };
        (
            VerticesMut {
                points,
                carried,
                motions,
                limits,
                cost_scale: self.cost_scale,
            },
            VerticesMut {
                points: points_rest,
                carried: carried_rest,
                motions: motions_rest,
                limits: limits_rest,
                cost_scale: self.cost_scale,
            },
        )
    }
}

impl Vertices {
    /// All of them, to collapse.
    pub fn as_mut(&mut self) -> VerticesMut<'_> {
        VerticesMut {
            points: &mut self.points,
            carried: &mut self.carried,
            motions: &mut self.motions,
            limits: self.limits.as_deref_mut(),
            cost_scale: self.cost_scale,
        }
    }

    /// The vertices of `faces` over `positions` (all indices valid, no face with a repeated
    /// corner; `around` them) before any collapse: each one's quadric, boundary and lock from the
    /// faces around it; the edges (see [`Edges`]); and how many edges have more than two faces.
    pub fn new(
        positions: Vec<DVec3>,
        faces: &[[u32; 3]],
        around: &FacesAround,
        carried: Vec<f32>,
        motions: Vec<DVec3>,
        limits: Option<Vec<f64>>,
    ) -> (Vertices, Edges, usize) {
        let n = positions.len();
        let cost_scale = cost_scale(&positions);
        let face_plane = |f: usize| {
            let [a, b, c] = faces[f].map(|i| positions[i as usize]);
            ((b - a).cross(c - a), a)
        };
        // Per vertex: its area-weighted face planes.
        let mut points: Vec<Point> = (0..n)
            .into_par_iter()
            .map(|v| {
                let mut quadric = Quadric::default();
                for &f in around.of(v) {
                    let (cross, point) = face_plane(f as usize);
                    let area2 = cross.length();
                    if area2 > 0.0 {
                        quadric += Quadric::plane(cross / area2, point, 0.5 * area2);
                    }
                }
                Point {
                    quadric,
                    position: positions[v],
                    ..Point::default()
                }
            })
            .collect();
        let mut non_manifold_edges = 0;
        let edges = around.edges(faces);
        for &[v, w, shared] in &edges {
            let (v, w) = (v as usize, w as usize);
            if shared > 2 {
                non_manifold_edges += 1;
                points[v].locked = true;
                points[w].locked = true;
            } else if shared == 1 {
                points[v].boundary = true;
                points[w].boundary = true;
                let f = around
                    .of(v)
                    .iter()
                    .copied()
                    .find(|&f| faces[f as usize].contains(&(w as u32)))
                    .expect("a boundary edge has its face");
                let (cross, _) = face_plane(f as usize);
                let edge = positions[w] - positions[v];
                if let Some(normal) = edge.cross(cross).try_normalize() {
                    let penalty = Quadric::plane(
                        normal,
                        positions[v],
                        BOUNDARY_PENALTY * edge.length_squared(),
                    );
                    points[v].quadric += penalty;
                    points[w].quadric += penalty;
                }
            }
        }
        let vertices = Vertices {
            points,
            carried,
            motions,
            limits,
            cost_scale,
        };
        (vertices, Edges::from_counted(edges), non_manifold_edges)
    }
}

/// Each edge of a mesh once, as its two ends, the lower-numbered first, ordered by that end.
pub(super) struct Edges(pub Vec<[u32; 2]>);

impl Edges {
    /// The edges of [`FacesAround::edges`], without their face counts.
    fn from_counted(counted: Vec<[u32; 3]>) -> Edges {
        Edges(counted.into_iter().map(|[v, w, _]| [v, w]).collect())
    }

    /// The edges with both ends in `range`, renumbered from its start.
    pub fn within(&self, range: std::ops::Range<usize>) -> Edges {
        let below = |end: usize| self.0.partition_point(|e| (e[0] as usize) < end);
        let start = range.start as u32;
        let inside = self.0[below(range.start)..below(range.end)]
            .iter()
            .filter(|e| (e[1] as usize) < range.end)
            .map(|e| e.map(|v| v - start))
            .collect();
        Edges(inside)
    }
}

/// What is already known of a collapser's faces, so that it need not find it again.
#[derive(Default)]
pub(super) struct Known {
    /// The faces around each vertex.
    pub around: Option<FacesAround>,
    /// The edges, or more (edges whose faces are all elsewhere are never candidates).
    pub edges: Option<Edges>,
}

/// The faces around each vertex, as one list: `refs[start[v]..start[v] + count[v]]`.
pub(super) struct FacesAround {
    refs: Vec<u32>,
    start: Vec<usize>,
    count: Vec<u32>,
}

impl FacesAround {
    /// The faces around each of `vertices` (all of `faces`' corners among them).
    pub fn new(vertices: usize, faces: &[[u32; 3]]) -> FacesAround {
        let (mut start, refs) = faces_around(vertices, faces);
        let count = start.windows(2).map(|w| (w[1] - w[0]) as u32).collect();
        start.pop();
        FacesAround { refs, start, count }
    }

    /// The faces around `v`.
    pub fn of(&self, v: usize) -> &[u32] {
        &self.refs[self.range(v)]
    }

    /// Where the faces around `v` lie in `refs`.
    fn range(&self, v: usize) -> std::ops::Range<usize> {
        self.start[v]..self.start[v] + self.count[v] as usize
    }

    /// Each edge once, from its lower-numbered end, with how many faces share it (1 boundary,
    /// 2 manifold, more non-manifold): gathered in parallel chunks, joined in vertex order.
    fn edges(&self, faces: &[[u32; 3]]) -> Vec<[u32; 3]> {
        (0..self.start.len())
            .into_par_iter()
            .fold(Vec::new, |mut edges: Vec<[u32; 3]>, v| {
                let first = edges.len();
                for &f in self.of(v) {
                    for &w in &faces[f as usize] {
                        if w as usize > v {
                            match edges[first..].iter_mut().find(|e| e[1] == w) {
                                Some(e) => e[2] += 1,
                                None => edges.push([v as u32, w, 1]),
                            }
                        }
                    }
                }
                edges
            })
            .flatten_iter()
            .collect()
    }
}

/// A face as the collapser keeps it: what a collapse reads of it, side by side.
#[derive(Clone, Copy)]
struct Face {
    corners: [u32; 3],
    /// Its normal in the input mesh (unit, or zero for a face without area).
    first_normal: Vec3,
}

/// The mesh being collapsed.
pub(super) struct Collapser<'a> {
    vertices: VerticesMut<'a>,
    faces: Vec<Face>,
    face_alive: Vec<bool>,
    channels: usize,
    /// One motion direction for every edge (for [`super::Weighting::Direction`]).
    direction: Option<DVec3>,
    /// Whether some vertices have faces elsewhere ([`Point::faces_elsewhere`]): then the
    /// vertices are shared, and their marks and counts go back to zero when done.
    shared: bool,
    /// The live faces around each vertex. A merged vertex's list is appended at the end; a face
    /// that dies leaves its third corner's list.
    around: FacesAround,
    /// Bumped whenever a vertex moves or dies, so that every queued edge on it goes stale.
    version: Vec<u32>,
    pub live_faces: usize,
    pub stats: Stats,
    heap: Heap,
    /// The last mark given (see [`Point::mark`]).
    visit: u32,
    /// The neighbours of a merged vertex, gathered before they are costed.
    neighbours: Vec<u32>,
}

impl<'a> Collapser<'a> {
    /// Queue every edge of `faces` over `vertices` (all indices valid, no face with a repeated
    /// corner; `first_normals` one per face, see [`first_normals`]) whose ends have no
    /// `faces_elsewhere` (empty: none has). What is not `known` of the faces is found here.
    pub fn new(
        vertices: VerticesMut<'a>,
        faces: Vec<[u32; 3]>,
        first_normals: Vec<Vec3>,
        faces_elsewhere: Vec<u32>,
        known: Known,
        channels: usize,
        direction: Option<DVec3>,
    ) -> Collapser<'a> {
        let n = vertices.points.len();
        let Known { around, edges } = known;
        let mut around = around.unwrap_or_else(|| FacesAround::new(n, &faces));
        // Merged vertices' lists are appended: room for about as many again as there are.
        around.refs.reserve(around.refs.len());
        let Edges(edges) = edges.unwrap_or_else(|| Edges::from_counted(around.edges(&faces)));
        let mut collapser = Collapser {
            live_faces: faces.len(),
            face_alive: vec![true; faces.len()],
            vertices,
            faces: faces
                .into_iter()
                .zip(first_normals)
                .map(|(corners, first_normal)| Face {
                    corners,
                    first_normal,
                })
                .collect(),
            channels,
            direction,
            shared: !faces_elsewhere.is_empty(),
            around,
            version: vec![0; n],
            stats: Stats::default(),
            heap: Heap::default(),
            visit: 0,
            neighbours: Vec::new(),
        };
        for (point, &elsewhere) in collapser.vertices.points.iter_mut().zip(&faces_elsewhere) {
            point.faces_elsewhere = elsewhere;
        }
        let this = &collapser;
        let entries: Vec<(f64, Entry)> = edges
            .par_iter()
            .filter_map(|&[v, w]| this.candidate(v, w))
            .collect();
        collapser.heap.extend(entries);
        collapser
    }

    /// The live faces, each with its place among those given (the vertices were collapsed in
    /// place, and are left with no marks or faces elsewhere for the next collapser).
    pub fn into_faces(self) -> Vec<([u32; 3], u32)> {
        if self.shared {
            for point in self.vertices.points.iter_mut() {
                point.faces_elsewhere = 0;
                point.mark = 0;
            }
        }
        self.faces
            .into_iter()
            .map(|face| face.corners)
            .zip(self.face_alive)
            .enumerate()
            .filter(|(_, (_, alive))| *alive)
            .map(|(f, (face, _))| (face, f as u32))
            .collect()
    }

    /// The queue's cheapest bin, if any edge waits.
    pub fn cheapest_bin(&self) -> Option<usize> {
        self.heap.cheapest_bin()
    }

    /// Collapse the cheapest edges until at most `target_faces` faces are left, or no edge
    /// waits in a bin before `below_bin`, or none may collapse; `progress` hears the face count
    /// now and then.
    pub fn run(&mut self, target_faces: usize, below_bin: usize, progress: &mut dyn FnMut(usize)) {
        while self.live_faces > target_faces {
            let Some(entry) = self.heap.pop(below_bin) else {
                break;
            };
            let (a, b) = (entry.a as usize, entry.b as usize);
            if self.version[a] + self.version[b] != entry.stamp {
                continue;
            }
            if self.try_collapse(a, b) {
                self.stats.collapses += 1;
                if self.stats.collapses.is_multiple_of(PROGRESS_EVERY) {
                    progress(self.live_faces);
                }
            }
        }
        progress(self.live_faces);
    }

    /// One face above `target_faces`, a collapse inside the surface would take two and end one
    /// below: collapse instead the cheapest edge on a boundary that may collapse, which takes
    /// one. Returns whether there was one (a closed mesh has none: its face count is even).
    pub fn finish_on_boundary(&mut self, target_faces: usize) -> bool {
        if self.live_faces != target_faces + 1 || !self.vertices.points.iter().any(|p| p.boundary) {
            return false;
        }
        let on_boundary: Vec<Entry> = self
            .heap
            .in_order()
            .filter(|e| {
                let (a, b) = (e.a as usize, e.b as usize);
                self.version[a] + self.version[b] == e.stamp
                    && self.vertices.points[a].boundary
                    && self.vertices.points[b].boundary
                    && self
                        .faces_of(a)
                        .filter(|&f| self.faces[f].corners.contains(&e.b))
                        .count()
                        == 1
            })
            .collect();
        for e in on_boundary {
            if self.try_collapse(e.a as usize, e.b as usize) {
                self.stats.collapses += 1;
                return true;
            }
        }
        false
    }

    /// The heap entry for edge (a, b), or `None` when it may not collapse (see `placement`).
    fn candidate(&self, a: u32, b: u32) -> Option<(f64, Entry)> {
        let (cost, _) = self.placement(a as usize, b as usize)?;
        let cost = cost * self.vertices.cost_scale;
        let stamp = self.version[a as usize] + self.version[b as usize];
        Some((cost, Entry { a, b, stamp }))
    }

    /// Where the merged vertex of edge (a, b) goes and what that costs: the quadric's minimum,
    /// or when the quadric is singular the cheapest of the two ends and the middle (§4); a
    /// locked end stays put. `None` when both ends are locked or either has faces elsewhere.
    fn placement(&self, a: usize, b: usize) -> Option<(f64, DVec3)> {
        let (point_a, point_b) = (&self.vertices.points[a], &self.vertices.points[b]);
        if point_a.faces_elsewhere > 0 || point_b.faces_elsewhere > 0 {
            return None;
        }
        let q = point_a.quadric + point_b.quadric;
        let (pa, pb) = (point_a.position, point_b.position);
        let p = match (point_a.locked, point_b.locked) {
            (true, true) => return None,
            (true, false) => pa,
            (false, true) => pb,
            (false, false) => q.minimum().unwrap_or_else(|| {
                let mid = 0.5 * (pa + pb);
                [pa, pb, mid]
                    .into_iter()
                    .min_by(|x, y| q.error(*x).total_cmp(&q.error(*y)))
                    .expect("three choices")
            }),
        };
        Some((q.error(p) * self.direction_weight(a, b), p))
    }

    /// Zhang et al. 2014, eq. 4: f(α) = 1 − (1 − cos α)^r + ε, α the angle between the edge and
    /// the motion; 1 without motion.
    fn direction_weight(&self, a: usize, b: usize) -> f64 {
        let motions = &self.vertices.motions;
        let motion = match self.direction {
            _ if !motions.is_empty() => motions[a] + motions[b],
            Some(d) => d,
            None => return 1.0,
        };
        let edge = self.vertices.points[b].position - self.vertices.points[a].position;
        let norms = edge.length() * motion.length();
        if !(norms > 0.0) {
            return 1.0;
        }
        super::direction_weight((edge.dot(motion) / norms).abs())
    }

    /// The live faces around `v`.
    fn faces_of(&self, v: usize) -> impl Iterator<Item = usize> + '_ {
        self.around.of(v).iter().map(|&f| f as usize)
    }

    /// The corners other than `v` of the live faces around `v`: each neighbour twice on a closed
    /// fan (once on a boundary).
    fn corners_around(&self, v: usize) -> impl Iterator<Item = usize> + '_ {
        self.faces_of(v)
            .flat_map(move |f| self.faces[f].corners)
            .map(|w| w as usize)
            .filter(move |&w| w != v)
    }

    /// A fresh mark: no vertex carries it yet.
    fn next_visit(&mut self) -> u32 {
        if self.visit == u32::MAX {
            self.vertices.points.iter_mut().for_each(|p| p.mark = 0);
            self.visit = 0;
        }
        self.visit += 1;
        self.visit
    }

    /// Check the safeguards for merging `b` into `a` and, when they hold, do it.
    fn try_collapse(&mut self, a: usize, b: usize) -> bool {
        let Some((_, p)) = self.placement(a, b) else {
            return false;
        };
        // Faces on the edge, and the corners opposite it.
        let mut shared = 0usize;
        let mut opposite = [0u32; 2];
        let mut faces_a = 0usize;
        for f in self.faces_of(a) {
            faces_a += 1;
            let face = self.faces[f].corners;
            if face.contains(&(b as u32)) {
                if shared < 2 {
                    opposite[shared] = *face
                        .iter()
                        .find(|&&w| w as usize != a && w as usize != b)
                        .expect("a face has three corners");
                }
                shared += 1;
            }
        }
        let faces_b = self.around.count[b] as usize;
        // The merged vertex would keep no face: the collapse takes away the last faces of a
        // piece (a lone triangle, or two faces that are all either end has), which no fold or
        // detail limit check sees, as no face is left to reshape.
        if shared == 0 || shared > 2 || faces_a + faces_b == 2 * shared {
            self.stats.topology_refusals += 1;
            return false;
        }
        if faces_a + faces_b - 2 * shared > MAX_VALENCE {
            self.stats.valence_refusals += 1;
            return false;
        }
        if !self.topology_holds(a, b, shared, &opposite[..shared]) {
            self.stats.topology_refusals += 1;
            return false;
        }
        let limit = self.vertices.limits.as_ref().map(|l| l[a].min(l[b]));
        match self.reshaped_faces(a, b, p, limit) {
            Some(Refusal::Fold) => {
                self.stats.fold_refusals += 1;
                return false;
            }
            Some(Refusal::Limit) => {
                self.stats.limit_refusals += 1;
                return false;
            }
            None => {}
        }
        self.merge(a, b, p, limit);
        true
    }

    /// Why the faces that move with a collapse of (a, b) to `p` refuse it, if they do: one folds
    /// over, or grows past its detail limit (`limit` is the merged vertex's).
    fn reshaped_faces(&self, a: usize, b: usize, p: DVec3, limit: Option<f64>) -> Option<Refusal> {
        for (moved, other) in [(a, b), (b, a)] {
            for f in self.faces_of(moved) {
                let Face {
                    corners: face,
                    first_normal,
                } = self.faces[f];
                if face.contains(&(other as u32)) {
                    continue;
                }
                let old = face.map(|w| self.vertices.points[w as usize].position);
                let new = face.map(|w| {
                    if w as usize == moved {
                        p
                    } else {
                        self.vertices.points[w as usize].position
                    }
                });
                if folds(old, new, first_normal) {
                    return Some(Refusal::Fold);
                }
                if let (Some(limit), Some(limits)) = (limit, &self.vertices.limits) {
                    let face_limit = face
                        .iter()
                        .map(|&w| {
                            if w as usize == moved {
                                limit
                            } else {
                                limits[w as usize]
                            }
                        })
                        .fold(f64::INFINITY, f64::min);
                    let perimeter = (new[1] - new[0]).length()
                        + (new[2] - new[1]).length()
                        + (new[0] - new[2]).length();
                    if perimeter > face_limit {
                        return Some(Refusal::Limit);
                    }
                }
            }
        }
        None
    }

    /// The link condition and the boundary rules for edge (a, b) with `shared` faces whose
    /// corners off the edge are `opposite`.
    fn topology_holds(&mut self, a: usize, b: usize, shared: usize, opposite: &[u32]) -> bool {
        if shared == 2 && self.vertices.points[a].boundary && self.vertices.points[b].boundary {
            return false;
        }
        // A corner opposite the edge with three faces would keep two, back to back.
        if opposite.iter().any(|&o| {
            !self.vertices.points[o as usize].boundary && self.faces_around_count(o as usize) <= 3
        }) {
            return false;
        }
        // Neighbours of a carry `of_a`; each neighbour of b found with it is counted once and
        // re-marked `counted`.
        let of_a = self.next_visit();
        let counted = self.next_visit();
        // The corners come from the face lists, the marks from the points: borrowed apart.
        let points = std::mem::take(&mut self.vertices.points);
        for w in self.corners_around(a) {
            points[w].mark = of_a;
        }
        let mut common = 0;
        for w in self.corners_around(b) {
            if points[w].mark == of_a {
                points[w].mark = counted;
                common += 1;
            }
        }
        self.vertices.points = points;
        common == shared
    }

    /// How many faces are around `v`, held here or not.
    fn faces_around_count(&self, v: usize) -> u32 {
        self.around.count[v] + self.vertices.points[v].faces_elsewhere
    }

    /// Take face `f` out of the list of faces around `v` (the order of the rest may change).
    fn forget_face(&mut self, v: usize, f: u32) {
        let around = &mut self.around;
        let range = around.range(v);
        let list = &mut around.refs[range];
        if let Some(i) = list.iter().position(|&g| g == f) {
            let last = list.len() - 1;
            list.swap(i, last);
            around.count[v] -= 1;
        }
    }

    /// Merge `b` into `a` at `p`: faces on the edge die, `b`'s other faces take `a`, and the
    /// edges around `a` are costed again.
    fn merge(&mut self, a: usize, b: usize, p: DVec3, limit: Option<f64>) {
        let (pa, pb) = (
            self.vertices.points[a].position,
            self.vertices.points[b].position,
        );
        let along = (pb - pa).length_squared();
        let t = if along > 0.0 {
            ((p - pa).dot(pb - pa) / along).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let k = self.channels;
        for c in 0..k {
            let (x, y) = (
                self.vertices.carried[a * k + c],
                self.vertices.carried[b * k + c],
            );
            self.vertices.carried[a * k + c] = x + (y - x) * t as f32;
        }
        if !self.vertices.motions.is_empty() {
            self.vertices.motions[a] = self.vertices.motions[a].lerp(self.vertices.motions[b], t);
        }
        if let (Some(limit), Some(limits)) = (limit, self.vertices.limits.as_mut()) {
            limits[a] = limit;
        }
        self.vertices.points[a].position = p;
        let qb = self.vertices.points[b].quadric;
        self.vertices.points[a].quadric += qb;
        self.vertices.points[a].boundary |= self.vertices.points[b].boundary;
        self.vertices.points[a].locked |= self.vertices.points[b].locked;
        self.version[b] += 1;

        let new_start = self.around.refs.len();
        for i in self.around.range(a) {
            let f = self.around.refs[i] as usize;
            let face = self.faces[f].corners;
            if face.contains(&(b as u32)) {
                self.face_alive[f] = false;
                self.live_faces -= 1;
                let opposite = face
                    .into_iter()
                    .find(|&w| w as usize != a && w as usize != b)
                    .expect("a face has three corners") as usize;
                self.forget_face(opposite, f as u32);
            } else {
                self.around.refs.push(f as u32);
            }
        }
        for i in self.around.range(b) {
            let f = self.around.refs[i] as usize;
            // The faces on the edge, dead now, are the ones with `a`.
            if !self.faces[f].corners.contains(&(a as u32)) {
                for w in &mut self.faces[f].corners {
                    if *w as usize == b {
                        *w = a as u32;
                    }
                }
                self.around.refs.push(f as u32);
            }
        }
        self.around.start[a] = new_start;
        self.around.count[a] = (self.around.refs.len() - new_start) as u32;
        self.around.count[b] = 0;
        self.version[a] += 1;

        let seen = self.next_visit();
        let mut neighbours = std::mem::take(&mut self.neighbours);
        let points = std::mem::take(&mut self.vertices.points);
        for w in self.corners_around(a) {
            if points[w].mark != seen {
                points[w].mark = seen;
                neighbours.push(w as u32);
            }
        }
        self.vertices.points = points;
        for w in neighbours.drain(..) {
            if let Some((cost, entry)) = self.candidate(a as u32, w) {
                self.heap.push(cost, entry);
            }
        }
        self.neighbours = neighbours;
    }
}

/// Whether a face moving from corners `old` to `new` folds over: turns by more than
/// [`MAX_TURN_DEGREES`] in this collapse or [`MAX_DRIFT_DEGREES`] from its unit normal in the
/// input (`first`), or shrinks to no area. A face that had no area may take any shape.
fn folds(old: [DVec3; 3], new: [DVec3; 3], first: Vec3) -> bool {
    let n_old = (old[1] - old[0]).cross(old[2] - old[0]);
    let n_new = (new[1] - new[0]).cross(new[2] - new[0]);
    let (l_old, l_new) = (n_old.length(), n_new.length());
    if !(l_old > 0.0) {
        return false;
    }
    !(l_new > 0.0)
        || n_old.dot(n_new) < MAX_TURN_DEGREES.to_radians().cos() * l_old * l_new
        || (first != Vec3::ZERO
            && n_new.dot(first.as_dvec3()) < MAX_DRIFT_DEGREES.to_radians().cos() * l_new)
}

/// The power of two nearest 1 / d⁴, d the diagonal of `positions`' bounding box (1 for a mesh
/// without extent). Costs are areas times squared distances, so a cost times this is the same
/// number for the mesh at any scale, and it stays far from the f32 limits of the queue's bins
/// (below 10⁻³⁸ costs all fell in one bin, above 10³⁸ in another). Being a power of two, it
/// changes no collapse of a mesh whose costs were in range.
fn cost_scale(positions: &[DVec3]) -> f64 {
    let (lo, hi) = crate::math::bounds(positions.iter().copied());
    let diagonal2 = (hi - lo).length_squared();
    let scale = (-(2.0 * diagonal2.log2()).round().clamp(-1000.0, 1000.0)).exp2();
    if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    }
}

/// The unit normal of each face (zero where it has no area), kept in single precision: it only
/// tells which way a face once faced.
pub(super) fn first_normals(positions: &[DVec3], faces: &[[u32; 3]]) -> Vec<Vec3> {
    faces
        .par_iter()
        .map(|face| {
            let [a, b, c] = face.map(|v| positions[v as usize]);
            (b - a).cross(c - a).normalize_or_zero().as_vec3()
        })
        .collect()
}
