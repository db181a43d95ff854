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
//! - no face turned by more than [`MAX_TURN_DEGREES`] or shrunk to nothing (fold-overs);
//! - no vertex with more than [`MAX_VALENCE`] faces, which also bounds the work of each
//!   collapse: without it a fan of n faces costs n² (see `Stats::valence_refusals`);
//! - vertices on an edge shared by more than two faces never move (`locked`).

use std::cmp::Ordering;

use glam::DVec3;
use rayon::prelude::*;

use super::heap::{Entry, Heap};
use super::quadric::Quadric;
use super::{Limits, Weighting};
use crate::scene::triangles::faces_around;

/// Largest turn of a face's normal a collapse may cause, degrees: past a right angle a face has
/// folded over; a little short of it catches the near-folds that flip with the next collapse.
pub const MAX_TURN_DEGREES: f64 = 80.0;

/// Most faces one vertex may gather (see the module notes).
pub const MAX_VALENCE: usize = 32;

/// Weight of the planes that hold a boundary edge in place, relative to the area weight of a
/// face whose side is that edge (Garland & Heckbert §6.1's penalty planes).
const BOUNDARY_PENALTY: f64 = 100.0;

/// How often, in collapses, the progress callback hears the face count.
const PROGRESS_EVERY: usize = 8192;

/// What the loop counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Edges collapsed.
    pub collapses: usize,
    /// Collapses refused because a face would fold over or vanish.
    pub fold_refusals: usize,
    /// Collapses refused by the link condition or a boundary pinch.
    pub topology_refusals: usize,
    /// Collapses refused because a vertex would gather more than [`MAX_VALENCE`] faces.
    pub valence_refusals: usize,
    /// Collapses refused because a face would grow past its detail limit.
    pub limit_refusals: usize,
}

/// Why the faces around a collapse refuse it.
enum Refusal {
    Fold,
    Limit,
}

/// The mesh being collapsed.
pub(super) struct Collapser<'w> {
    pub positions: Vec<DVec3>,
    pub faces: Vec<[u32; 3]>,
    pub face_alive: Vec<bool>,
    vertex_alive: Vec<bool>,
    /// Per-vertex channels carried along, `channels` numbers each, interpolated along the edge.
    pub carried: Vec<f32>,
    channels: usize,
    quadrics: Vec<Quadric>,
    /// Faces around each vertex: `refs[start[v]..start[v] + count[v]]`, stale faces included
    /// until the vertex is next rewritten; a merged vertex's list is appended at the end.
    refs: Vec<u32>,
    start: Vec<usize>,
    count: Vec<u32>,
    version: Vec<u32>,
    boundary: Vec<bool>,
    locked: Vec<bool>,
    weighting: &'w Weighting,
    /// Per-vertex motion (for [`Weighting::PerVertex`]), carried like an attribute.
    motions: Vec<DVec3>,
    /// Longest perimeter, object units, of a face touching each vertex.
    limits: Option<Vec<f64>>,
    pub live_faces: usize,
    pub stats: Stats,
    /// Edges shared by more than two faces, whose ends were locked.
    pub non_manifold_edges: usize,
    heap: Heap,
    scratch_a: Vec<u32>,
    scratch_b: Vec<u32>,
}

impl<'w> Collapser<'w> {
    /// Set up quadrics, adjacency and boundaries for `faces` over `positions` (all indices valid,
    /// no face with a repeated corner).
    pub fn new(
        positions: Vec<DVec3>,
        faces: Vec<[u32; 3]>,
        carried: Vec<f32>,
        channels: usize,
        weighting: &'w Weighting,
        limits: Option<&Limits>,
    ) -> Collapser<'w> {
        let n = positions.len();
        let (mut start, refs) = faces_around(n, &faces);
        let count: Vec<u32> = (0..n).map(|v| (start[v + 1] - start[v]) as u32).collect();
        start.pop();

        // Per vertex: its area-weighted face planes; and the edges to higher-numbered
        // neighbours with how many faces share each (1 boundary, 2 manifold, more non-manifold),
        // gathered in parallel chunks and joined in vertex order.
        let face_plane = |f: usize| {
            let [a, b, c] = faces[f].map(|i| positions[i as usize]);
            ((b - a).cross(c - a), a)
        };
        let faces_around = |v: usize| &refs[start[v]..start[v] + count[v] as usize];
        let mut quadrics: Vec<Quadric> = (0..n)
            .into_par_iter()
            .map(|v| {
                let mut q = Quadric::default();
                for &f in faces_around(v) {
                    let (cross, point) = face_plane(f as usize);
                    let area2 = cross.length();
                    if area2 > 0.0 {
                        q += Quadric::plane(cross / area2, point, 0.5 * area2);
                    }
                }
                q
            })
            .collect();
        let edges: Vec<[u32; 3]> = (0..n)
            .into_par_iter()
            .fold(Vec::new, |mut edges: Vec<[u32; 3]>, v| {
                let first = edges.len();
                for &f in faces_around(v) {
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
            .collect();
        let mut boundary = vec![false; n];
        let mut locked = vec![false; n];
        let mut non_manifold_edges = 0;
        for &[v, w, shared] in &edges {
            let (v, w) = (v as usize, w as usize);
            if shared > 2 {
                non_manifold_edges += 1;
                locked[v] = true;
                locked[w] = true;
            } else if shared == 1 {
                boundary[v] = true;
                boundary[w] = true;
                let f = faces_around(v)
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
                    quadrics[v] += penalty;
                    quadrics[w] += penalty;
                }
            }
        }
        let motions = match weighting {
            Weighting::PerVertex(m) => m.clone(),
            _ => Vec::new(),
        };
        let live_faces = faces.len();
        let mut collapser = Collapser {
            face_alive: vec![true; faces.len()],
            vertex_alive: vec![true; n],
            positions,
            faces,
            carried,
            channels,
            quadrics,
            refs,
            start,
            count,
            version: vec![0; n],
            boundary,
            locked,
            weighting,
            motions,
            limits: limits.map(|l| l.per_vertex.clone()),
            live_faces,
            stats: Stats::default(),
            non_manifold_edges,
            heap: Heap::default(),
            scratch_a: Vec::new(),
            scratch_b: Vec::new(),
        };
        collapser.initial_heap(&edges);
        collapser
    }

    fn initial_heap(&mut self, edges: &[[u32; 3]]) {
        let this = &*self;
        let entries: Vec<(f64, Entry)> = edges
            .par_iter()
            .filter_map(|&[v, w, _]| this.candidate(v, w))
            .collect();
        for (cost, entry) in entries {
            self.heap.push(cost, entry);
        }
    }

    /// Collapse the cheapest edges until at most `target_faces` faces are left or no edge may
    /// collapse; `progress` hears the face count now and then.
    pub fn run(&mut self, target_faces: usize, progress: &mut dyn FnMut(usize)) {
        while self.live_faces > target_faces {
            let Some(entry) = self.heap.pop() else { break };
            let (a, b) = (entry.a as usize, entry.b as usize);
            if !(self.vertex_alive[a] && self.vertex_alive[b])
                || self.version[a] + self.version[b] != entry.stamp
            {
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

    /// The heap entry for edge (a, b), or `None` when neither end may move.
    fn candidate(&self, a: u32, b: u32) -> Option<(f64, Entry)> {
        let (cost, _) = self.placement(a as usize, b as usize)?;
        let stamp = self.version[a as usize] + self.version[b as usize];
        Some((cost, Entry { a, b, stamp }))
    }

    /// Where the merged vertex of edge (a, b) goes and what that costs: the quadric's minimum,
    /// or when the quadric is singular the cheapest of the two ends and the middle (§4); a
    /// locked end stays put.
    fn placement(&self, a: usize, b: usize) -> Option<(f64, DVec3)> {
        let q = self.quadrics[a] + self.quadrics[b];
        let (pa, pb) = (self.positions[a], self.positions[b]);
        let p = match (self.locked[a], self.locked[b]) {
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
        let motion = match self.weighting {
            Weighting::Isotropic => return 1.0,
            Weighting::Direction(d) => *d,
            Weighting::PerVertex(_) => self.motions[a] + self.motions[b],
        };
        let edge = self.positions[b] - self.positions[a];
        let norms = edge.length() * motion.length();
        if !(norms > 0.0) {
            return 1.0;
        }
        super::direction_weight((edge.dot(motion) / norms).abs())
    }

    /// The live faces around `v`.
    fn faces_of(&self, v: usize) -> impl Iterator<Item = usize> + '_ {
        self.refs[self.start[v]..self.start[v] + self.count[v] as usize]
            .iter()
            .map(|&f| f as usize)
            .filter(|&f| self.face_alive[f])
    }

    /// The vertices sharing a live face with `v` (not `v`), sorted, into `out`.
    fn neighbours(&self, v: usize, out: &mut Vec<u32>) {
        out.clear();
        for f in self.faces_of(v) {
            out.extend(self.faces[f].iter().filter(|&&w| w as usize != v));
        }
        out.sort_unstable();
        out.dedup();
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
            let face = self.faces[f];
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
        let faces_b = self.faces_of(b).count();
        if shared == 0 || shared > 2 {
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
        let limit = self.limits.as_ref().map(|l| l[a].min(l[b]));
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
                let face = self.faces[f];
                if face.contains(&(other as u32)) {
                    continue;
                }
                let old = face.map(|w| self.positions[w as usize]);
                let new = face.map(|w| {
                    if w as usize == moved {
                        p
                    } else {
                        self.positions[w as usize]
                    }
                });
                if folds(old, new) {
                    return Some(Refusal::Fold);
                }
                if let (Some(limit), Some(limits)) = (limit, &self.limits) {
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
        if shared == 2 && self.boundary[a] && self.boundary[b] {
            return false;
        }
        // A corner opposite the edge with three faces would keep two, back to back.
        if opposite
            .iter()
            .any(|&o| !self.boundary[o as usize] && self.faces_of(o as usize).count() <= 3)
        {
            return false;
        }
        let mut na = std::mem::take(&mut self.scratch_a);
        let mut nb = std::mem::take(&mut self.scratch_b);
        self.neighbours(a, &mut na);
        self.neighbours(b, &mut nb);
        let (mut i, mut j, mut common) = (0, 0, 0);
        while i < na.len() && j < nb.len() {
            match na[i].cmp(&nb[j]) {
                Ordering::Less => i += 1,
                Ordering::Greater => j += 1,
                Ordering::Equal => {
                    common += 1;
                    i += 1;
                    j += 1;
                }
            }
        }
        self.scratch_a = na;
        self.scratch_b = nb;
        common == shared
    }

    /// Merge `b` into `a` at `p`: faces on the edge die, `b`'s other faces take `a`, and the
    /// edges around `a` are costed again.
    fn merge(&mut self, a: usize, b: usize, p: DVec3, limit: Option<f64>) {
        let (pa, pb) = (self.positions[a], self.positions[b]);
        let along = (pb - pa).length_squared();
        let t = if along > 0.0 {
            ((p - pa).dot(pb - pa) / along).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let k = self.channels;
        for c in 0..k {
            let (x, y) = (self.carried[a * k + c], self.carried[b * k + c]);
            self.carried[a * k + c] = x + (y - x) * t as f32;
        }
        if !self.motions.is_empty() {
            self.motions[a] = self.motions[a].lerp(self.motions[b], t);
        }
        if let (Some(limit), Some(limits)) = (limit, self.limits.as_mut()) {
            limits[a] = limit;
        }
        self.positions[a] = p;
        let qb = self.quadrics[b];
        self.quadrics[a] += qb;
        self.boundary[a] |= self.boundary[b];
        self.locked[a] |= self.locked[b];
        self.vertex_alive[b] = false;

        let new_start = self.refs.len();
        for i in self.start[a]..self.start[a] + self.count[a] as usize {
            let f = self.refs[i] as usize;
            if !self.face_alive[f] {
                continue;
            }
            if self.faces[f].contains(&(b as u32)) {
                self.face_alive[f] = false;
                self.live_faces -= 1;
            } else {
                self.refs.push(f as u32);
            }
        }
        for i in self.start[b]..self.start[b] + self.count[b] as usize {
            let f = self.refs[i] as usize;
            if self.face_alive[f] {
                for w in &mut self.faces[f] {
                    if *w as usize == b {
                        *w = a as u32;
                    }
                }
                self.refs.push(f as u32);
            }
        }
        self.start[a] = new_start;
        self.count[a] = (self.refs.len() - new_start) as u32;
        self.count[b] = 0;
        self.version[a] += 1;

        let mut around = std::mem::take(&mut self.scratch_a);
        self.neighbours(a, &mut around);
        for &n in &around {
            if let Some((cost, entry)) = self.candidate(a as u32, n) {
                self.heap.push(cost, entry);
            }
        }
        self.scratch_a = around;
    }
}

/// Whether a face moving from corners `old` to `new` folds over, turns by more than
/// [`MAX_TURN_DEGREES`], or shrinks to no area. A face that had no area may take any shape.
fn folds(old: [DVec3; 3], new: [DVec3; 3]) -> bool {
    let n_old = (old[1] - old[0]).cross(old[2] - old[0]);
    let n_new = (new[1] - new[0]).cross(new[2] - new[0]);
    let (l_old, l_new) = (n_old.length(), n_new.length());
    if !(l_old > 0.0) {
        return false;
    }
    !(l_new > 0.0) || n_old.dot(n_new) < MAX_TURN_DEGREES.to_radians().cos() * l_old * l_new
}
