//! Surfels from bare points: unit normals, covering radii and the surface area each point
//! stands for, estimated from its neighbours (docs/math.md, "Point-cloud normals and areas").

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::num::NonZeroUsize;

use glam::{DQuat, DVec2, DVec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use spade::{DelaunayTriangulation, Point2, Triangulation};

use super::{Surfel, DEFAULT_GREY};
use crate::error::{Error, Result};
use crate::math::smallest_eigenvector;

/// Neighbours used to estimate normals, radii and areas of a point cloud, unless told otherwise.
pub const DEFAULT_NEIGHBOURS: usize = 12;

/// The range of neighbour counts an estimate may use.
pub const NEIGHBOUR_RANGE: std::ops::RangeInclusive<usize> = 3..=64;

/// A point cloud as read from a file, before surfels are built. Colours are linear RGB in 0..=1
/// (8-bit PLY colours are sRGB-decoded; float colours are taken as linear).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    /// Point positions.
    pub positions: Vec<DVec3>,
    /// Unit normals, one per point, when the file has them.
    pub normals: Option<Vec<DVec3>>,
    /// Linear RGB colours in 0..=1, one per point, when the file has them.
    pub colors: Option<Vec<[f32; 3]>>,
    /// Surfel radii (positive), one per point, when the file has them.
    pub radii: Option<Vec<f64>>,
}

/// `neighbours` if it is within [`NEIGHBOUR_RANGE`], else an error naming `neighbours`.
pub fn check_neighbours(neighbours: usize) -> Result<usize> {
    if NEIGHBOUR_RANGE.contains(&neighbours) {
        Ok(neighbours)
    } else {
        Err(Error::invalid(
            "neighbours",
            format!(
                "{neighbours}: use between {} and {}",
                NEIGHBOUR_RANGE.start(),
                NEIGHBOUR_RANGE.end()
            ),
        ))
    }
}

/// Surfels from a point cloud: one isotropic surfel per distinct position, with the cloud's
/// normals and colours where it has them (else [`DEFAULT_GREY`]) and the area each point stands
/// for estimated from its `neighbours` nearest neighbours (its coverage). A radius r in the cloud
/// is the splat's own: the Gaussian's standard deviation is r/2, so that its 2σ disc reaches r;
/// without one, the splat is as wide as its area asks (σ = [`super::SIGMA_PER_SPACING`]·√area) and at
/// least covers the gaps to its neighbours (σ ≥ covering radius / 2).
///
/// Points at exactly the same position are one point (the first of them): a stack of them would
/// only draw one disc several times over, and would make the neighbour search quadratic. Errors
/// name `neighbours` when it is outside [`NEIGHBOUR_RANGE`], and `points` when the cloud cannot
/// give surfels: no points, one distinct position (nothing to measure an area by), or, with
/// normals to estimate, all on one line (no plane to fit).
pub fn from_point_cloud(cloud: &PointCloud, neighbours: usize) -> Result<Vec<Surfel>> {
    let k = check_neighbours(neighbours)?;
    let kept = distinct_positions(&cloud.positions);
    let positions: Vec<DVec3> = kept.iter().map(|&i| cloud.positions[i]).collect();
    let merged = cloud.positions.len() - positions.len();
    let counted = || {
        let n = cloud.positions.len();
        let mut counted = format!("{n} point{}", if n == 1 { "" } else { "s" });
        if merged > 0 {
            counted += &format!(" ({} at one position with another, merged)", merged);
        }
        counted
    };
    if positions.len() < 2 {
        return Err(Error::invalid(
            "points",
            format!(
                "{}: a surfel's area is measured by its neighbours, so a cloud needs at least two \
                 distinct positions (three not on one line without normals)",
                counted()
            ),
        ));
    }
    let normals = match &cloud.normals {
        Some(n) => kept.iter().map(|&i| n[i]).collect(),
        None if collinear(&positions) => {
            return Err(Error::invalid(
                "points",
                format!(
                    "{}, all on one line: normals are estimated from the plane of a point's \
                     neighbours, and a line has none; give normals (nx ny nz) or points off \
                     the line",
                    counted()
                ),
            ))
        }
        None => estimate_normals(&positions, k),
    };
    let (cover_radii, areas) = estimate_radii_and_areas(&positions, &normals, k);
    Ok(kept
        .iter()
        .enumerate()
        .map(|(j, &i)| {
            let colour = cloud.colors.as_ref().map_or(DEFAULT_GREY, |c| c[i]);
            match &cloud.radii {
                // A radius given is the splat's: its Gaussian reaches it at 2σ.
                Some(radii) => {
                    Surfel::disc(positions[j], normals[j], areas[j], 0.5 * radii[i], colour)
                }
                None => Surfel::isotropic(
                    positions[j],
                    normals[j],
                    areas[j],
                    Some(cover_radii[j]),
                    colour,
                ),
            }
        })
        .collect())
}

/// The index of the first point at each distinct position, in order (−0 and +0 are one).
fn distinct_positions(positions: &[DVec3]) -> Vec<usize> {
    let key = |p: DVec3| (p + DVec3::ZERO).to_array().map(f64::to_bits);
    let mut seen = std::collections::HashSet::with_capacity(positions.len());
    (0..positions.len())
        .filter(|&i| seen.insert(key(positions[i])))
        .collect()
}

/// Whether all `positions` lie on one line (or at one point): each within 10⁻⁹ of its distance
/// from the first point (or 10⁻¹³ of its coordinates' size, their rounding) off the line through
/// the first and the farthest point. Measured point by point rather than against the whole extent,
/// which one far outlier would make so large that a plane near the first point passed for a line.
fn collinear(positions: &[DVec3]) -> bool {
    let origin = positions[0];
    let Some(far) = positions.iter().copied().max_by(|a, b| {
        a.distance_squared(origin)
            .total_cmp(&b.distance_squared(origin))
    }) else {
        return true;
    };
    let Some(direction) = crate::math::unit_direction(far - origin) else {
        return true;
    };
    positions.iter().all(|&p| {
        let offset = p - origin;
        let rounding = 1e-13 * p.abs().max(origin.abs()).max_element();
        offset.reject_from_normalized(direction).length() <= 1e-9 * offset.length() + rounding
    })
}

// ---------------------------------------------------------------------------------------------
// Neighbourhoods
// ---------------------------------------------------------------------------------------------

/// Nearest-neighbour queries over a fixed set of points. Exact ties in distance are broken the
/// same way on every run, so everything built on this is deterministic.
struct NeighbourSearch {
    points: Vec<[f64; 3]>,
    /// `None` when there are no points to search.
    tree: Option<ImmutableKdTree<f64, 3>>,
}

/// A fixed turn of the points before they enter the k-d tree, which splits on x, y and z in turn
/// and prunes nothing along an axis where the points do not spread: the queries for 40,000 points
/// on the z axis (a cloud's lines and planes often run along its axes) took 2.1 s, on a slanted
/// line 19 ms. Distances do not change, so neither do the neighbours beyond ties.
/// The quaternion (1, 2, 3, 4)/√30 turns no axis or diagonal close to an axis.
const SEARCH_TURN: DQuat = DQuat::from_xyzw(
    0.18257418583505536,
    0.3651483716701107,
    0.5477225575051661,
    0.7302967433402214,
);

impl NeighbourSearch {
    fn new(positions: &[DVec3]) -> Self {
        let points: Vec<[f64; 3]> = positions
            .iter()
            .map(|&p| (SEARCH_TURN * p).to_array())
            .collect();
        let tree = (!points.is_empty()).then(|| {
            ImmutableKdTree::new_from_slice(&points)
                .expect("a point cloud has fewer than 2^32 points")
        });
        NeighbourSearch { points, tree }
    }

    /// Replaces `out` with the `count` nearest other points of point `index`, nearest first
    /// (fewer when the cloud is smaller).
    fn nearest(&self, index: usize, count: usize, out: &mut Vec<u32>) {
        out.clear();
        let (Some(tree), Some(query_count)) = (&self.tree, NonZeroUsize::new(count)) else {
            return;
        };
        let found = tree
            .query(&self.points[index])
            .nearest_n::<SquaredEuclidean<f64>>(query_count.saturating_add(1))
            .execute();
        // The point itself is among the results unless more than `count` duplicates of it crowd
        // it out; either way keep the first `count` others.
        out.extend(
            found
                .iter()
                .map(|neighbour| neighbour.item)
                .filter(|&item| item as usize != index)
                .take(count),
        );
    }
}

/// The min(k, n - 1) nearest other points of every point, nearest first.
struct Neighbours {
    per_point: usize,
    indices: Vec<u32>,
}

impl Neighbours {
    fn find(positions: &[DVec3], k: usize) -> Self {
        let per_point = k.min(positions.len().saturating_sub(1));
        let mut indices = vec![0u32; positions.len() * per_point];
        if per_point > 0 {
            let search = NeighbourSearch::new(positions);
            indices.par_chunks_mut(per_point).enumerate().for_each_init(
                Vec::new,
                |found, (index, out)| {
                    search.nearest(index, per_point, found);
                    out.copy_from_slice(found);
                },
            );
        }
        Neighbours { per_point, indices }
    }

    fn of(&self, index: usize) -> &[u32] {
        &self.indices[index * self.per_point..(index + 1) * self.per_point]
    }
}

// ---------------------------------------------------------------------------------------------
// Normal estimation
// ---------------------------------------------------------------------------------------------

/// Unit normals by PCA of the k nearest neighbours (the smallest-eigenvalue eigenvector of their
/// covariance), oriented consistently: orientation is propagated over the k-NN graph along a
/// minimum spanning tree with edge cost 1 - |n_i·n_j| (Hoppe et al. 1992), then each connected
/// part of the graph is flipped as a whole so that most of its normals point away from its
/// centroid. Deterministic (same input → same output, whatever the thread count). Duplicate
/// points, collinear neighbourhoods (any unit normal perpendicular to the line) and fewer than `k`
/// points are handled; a point with `k` or more duplicates has only them for neighbours and gets
/// an arbitrary unit normal ([`from_point_cloud`] merges duplicates first). `k` below 3 is raised
/// to 3, the fewest points that span a plane.
/// Positions must be finite, as [`crate::io::ply::read_ply`] guarantees.
pub fn estimate_normals(positions: &[DVec3], k: usize) -> Vec<DVec3> {
    let neighbours = Neighbours::find(positions, k.max(3));
    let mut normals: Vec<DVec3> = (0..positions.len())
        .into_par_iter()
        .map(|index| pca_normal(positions, index, neighbours.of(index)))
        .collect();
    orient_normals(positions, &neighbours, &mut normals);
    normals
}

/// Normal of the plane that best fits a point and its neighbours.
fn pca_normal(positions: &[DVec3], index: usize, neighbours: &[u32]) -> DVec3 {
    let points = || {
        std::iter::once(positions[index]).chain(neighbours.iter().map(|&j| positions[j as usize]))
    };
    let count = (neighbours.len() + 1) as f64;
    let mean = points().sum::<DVec3>() / count;
    let mut covariance = [[0.0; 3]; 3];
    for point in points() {
        let d = (point - mean).to_array();
        for row in 0..3 {
            for column in 0..3 {
                covariance[row][column] += d[row] * d[column];
            }
        }
    }
    smallest_eigenvector(covariance)
}

/// Flips normals so that neighbours agree (Hoppe's minimum-spanning-tree propagation), then
/// flips each connected part so that most of its normals point away from its centroid.
fn orient_normals(positions: &[DVec3], neighbours: &Neighbours, normals: &mut [DVec3]) {
    let graph = SymmetricGraph::from_neighbours(neighbours, positions.len());
    let mut visited = vec![false; positions.len()];
    // Per node, the least (cost bits, parent) pushed for it.
    let mut best = vec![(u64::MAX, u32::MAX); positions.len()];
    let mut heap = BinaryHeap::new();
    let mut part = Vec::new();
    for seed in 0..positions.len() {
        if visited[seed] {
            continue;
        }
        // Prim's algorithm; costs are non-negative floats, whose bit patterns order like the
        // values, and ties fall to the lower index, so the tree does not depend on timing.
        // A node's entry is pushed only when it beats the best one pushed for it so far: the
        // entries it does not beat would be popped after that one, when the node is visited
        // already, so the tree is the same, and the heap holds a few entries per node rather than
        // one per edge (88 % of the time and most of the memory at 64 neighbours).
        part.clear();
        heap.push(Reverse((0u64, seed as u32, seed as u32)));
        while let Some(Reverse((_, node, parent))) = heap.pop() {
            let node = node as usize;
            if visited[node] {
                continue;
            }
            visited[node] = true;
            part.push(node);
            if normals[node].dot(normals[parent as usize]) < 0.0 {
                normals[node] = -normals[node];
            }
            for &next in graph.adjacent(node) {
                if !visited[next as usize] {
                    let cost = (1.0 - normals[node].dot(normals[next as usize]).abs()).max(0.0);
                    let entry = (cost.to_bits(), node as u32);
                    if entry < best[next as usize] {
                        best[next as usize] = entry;
                        heap.push(Reverse((entry.0, next, entry.1)));
                    }
                }
            }
        }

        let centroid = part.iter().map(|&i| positions[i]).sum::<DVec3>() / part.len() as f64;
        let outward_votes: i64 = part
            .iter()
            .map(|&i| {
                let alignment = (positions[i] - centroid).dot(normals[i]);
                i64::from(alignment > 0.0) - i64::from(alignment < 0.0)
            })
            .sum();
        if outward_votes < 0 {
            for &i in &part {
                normals[i] = -normals[i];
            }
        }
    }
}

/// The k-NN graph made undirected, as adjacency lists in one array (compressed sparse rows).
struct SymmetricGraph {
    starts: Vec<usize>,
    adjacent: Vec<u32>,
}

impl SymmetricGraph {
    /// Each point's neighbours and the points that have it as a neighbour, in ascending order,
    /// once each. Built in place: a list of (from, to) pairs sorted whole took twice the memory
    /// of the lists (1 KB a point at 64 neighbours).
    fn from_neighbours(neighbours: &Neighbours, count: usize) -> Self {
        let mut starts = vec![0usize; count + 1];
        for i in 0..count {
            starts[i + 1] += neighbours.of(i).len();
            for &j in neighbours.of(i) {
                starts[j as usize + 1] += 1;
            }
        }
        for i in 0..count {
            starts[i + 1] += starts[i];
        }
        let mut filled = starts[..count].to_vec();
        let mut adjacent = vec![0u32; starts[count]];
        for i in 0..count {
            for &j in neighbours.of(i) {
                adjacent[filled[i]] = j;
                filled[i] += 1;
                adjacent[filled[j as usize]] = i as u32;
                filled[j as usize] += 1;
            }
        }
        drop(filled);
        // Sort each list, then close the gaps its duplicates leave (an edge both points chose).
        let mut rows: Vec<&mut [u32]> = Vec::with_capacity(count);
        let mut rest = adjacent.as_mut_slice();
        for i in 0..count {
            let (row, tail) = rest.split_at_mut(starts[i + 1] - starts[i]);
            rows.push(row);
            rest = tail;
        }
        rows.par_iter_mut().for_each(|row| row.sort_unstable());
        drop(rows);
        let mut kept = 0;
        for i in 0..count {
            let (start, end) = (starts[i], starts[i + 1]);
            starts[i] = kept;
            let mut previous = None;
            for k in start..end {
                // `kept` ≤ k: what is read here has not been written over yet.
                let j = adjacent[k];
                if previous != Some(j) {
                    adjacent[kept] = j;
                    kept += 1;
                    previous = Some(j);
                }
            }
        }
        starts[count] = kept;
        adjacent.truncate(kept);
        adjacent.shrink_to_fit();
        SymmetricGraph { starts, adjacent }
    }

    fn adjacent(&self, node: usize) -> &[u32] {
        &self.adjacent[self.starts[node]..self.starts[node + 1]]
    }
}

// ---------------------------------------------------------------------------------------------
// Radii and areas
// ---------------------------------------------------------------------------------------------

/// Triangles whose circumradius exceeds this many times the distance to the k-th neighbour are
/// slivers (typically spanning a boundary) and are left out.
const SLIVER_CIRCUMRADIUS_LIMIT: f64 = 3.0;

/// A point whose triangles are not yet known to be complete looks at up to this many times k
/// neighbours before it is taken for a point on the boundary of the surface.
const NEIGHBOURHOOD_GROWTH_LIMIT: usize = 4;

/// Per point: a covering radius (discs of these radii in the tangent planes leave no holes in the
/// surface) and the surface area the point stands for.
///
/// The k nearest neighbours are projected to the point's tangent plane (normals must be unit
/// length) and triangulated together with the point (2D Delaunay, spade). Every triangle is
/// shared out among its three corners: each gets the part nearer to it than to the other two.
/// A point's area is the sum of its parts of the triangles around it, and its radius the
/// farthest reach of those parts, so the discs cover every triangle. For a triangle without an
/// obtuse angle the reach is its circumradius (the circumcentre is the spot farthest from all
/// corners); an obtuse triangle's circumcentre lies outside it, and the reach is shorter.
///
/// The shares add up to the surface only where the points' separate triangulations agree. A
/// point's triangles are certainly those of the triangulation of the whole cloud when they close
/// around it and each circumcircle lies within the distance of the farthest neighbour used (no
/// other point can fall inside it). Where that fails — irregular sampling, or a point on the hull
/// of its own neighbourhood — 2k and then 4k neighbours are tried; a point still on the hull is on
/// the boundary of an open surface and keeps the triangles on its inner side.
///
/// Unlike a third of the incident triangles' area, the shares do not depend on which diagonal the
/// triangulation picks where four points lie on a circle (any regular grid): on a square grid
/// every inner point gets exactly the area of one cell. Triangles whose circumradius exceeds 3×
/// the distance to the k-th neighbour are slivers spanning gaps or a concave boundary and are
/// left out. Neighbours that coincide with the point after projection (duplicates) are ignored.
/// When no triangle is left, the radius is the distance `d` to the nearest distinct neighbour and
/// the area that of a disc of radius `d/2`; a point with no distinct neighbour among its k nearest
/// (alone, or with `k` or more duplicates, which [`from_point_cloud`] merges first) gets 0 for
/// both. `k` below 3 is raised to 3. Parallel but deterministic.
///
/// # Panics
/// If `normals` and `positions` differ in length.
pub fn estimate_radii_and_areas(
    positions: &[DVec3],
    normals: &[DVec3],
    k: usize,
) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(
        positions.len(),
        normals.len(),
        "estimate_radii_and_areas needs one normal per position"
    );
    let search = NeighbourSearch::new(positions);
    (0..positions.len())
        .into_par_iter()
        .map_init(
            || (DelaunayTriangulation::new(), Vec::new()),
            |(triangulation, neighbours), index| {
                let mut patch = TangentPatch {
                    triangulation,
                    neighbours,
                    positions,
                    index,
                    normal: normals[index],
                };
                patch.radius_and_area(&search, k.max(3))
            },
        )
        .unzip()
}

/// One point's neighbourhood projected to its tangent plane; the buffers are reused between
/// points.
struct TangentPatch<'a> {
    triangulation: &'a mut DelaunayTriangulation<Point2<f64>>,
    neighbours: &'a mut Vec<u32>,
    positions: &'a [DVec3],
    index: usize,
    normal: DVec3,
}

/// The point's shares of the triangles around it, in units of the farthest neighbour's distance.
struct Fan {
    reach: f64,
    area: f64,
    /// The triangles close around the point and are those of the whole cloud's triangulation.
    complete: bool,
}

impl TangentPatch<'_> {
    fn radius_and_area(&mut self, search: &NeighbourSearch, k: usize) -> (f64, f64) {
        let centre = self.positions[self.index];
        let distance = |j: u32| self.positions[j as usize].distance(centre);
        search.nearest(self.index, k, self.neighbours);
        let Some(nearest_distinct) = self
            .neighbours
            .iter()
            .map(|&j| distance(j))
            .find(|&d| d > 0.0)
        else {
            return (0.0, 0.0);
        };
        let sliver_limit =
            SLIVER_CIRCUMRADIUS_LIMIT * self.neighbours.last().map_or(0.0, |&j| distance(j));

        let mut count = k;
        loop {
            let scale = self.neighbours.last().map_or(0.0, |&j| distance(j));
            let fan = self.fan(scale, sliver_limit / scale);
            let grown = count * 2;
            if fan.complete
                || grown > k * NEIGHBOURHOOD_GROWTH_LIMIT
                || self.neighbours.len() < count
            {
                return if fan.area > 0.0 {
                    (fan.reach * scale, fan.area * scale * scale)
                } else {
                    let disc_area = std::f64::consts::PI * (nearest_distinct / 2.0).powi(2);
                    (nearest_distinct, disc_area)
                };
            }
            count = grown;
            search.nearest(self.index, count, self.neighbours);
        }
    }

    /// Triangulates the point with its neighbours, in units of `scale`, and sums up its shares of
    /// the triangles around it whose circumradius is at most `sliver_limit`.
    fn fan(&mut self, scale: f64, sliver_limit: f64) -> Fan {
        let mut fan = Fan {
            reach: 0.0,
            area: 0.0,
            complete: false,
        };
        let (u, v) = self
            .normal
            .try_normalize()
            .unwrap_or(DVec3::Z)
            .any_orthonormal_pair();
        // Coordinates are of order 1; flushing the tiniest to zero keeps them inside the range
        // spade accepts.
        let planar = |x: f64| if x.abs() < 1e-12 { 0.0 } else { x };

        // A cleared triangulation resets spade's search hint too, so reuse does not change
        // results.
        self.triangulation.clear();
        let Ok(centre_vertex) = self.triangulation.insert(Point2::new(0.0, 0.0)) else {
            return fan;
        };
        let centre = self.positions[self.index];
        for &j in self.neighbours.iter() {
            let offset = (self.positions[j as usize] - centre) / scale;
            let point = Point2::new(planar(offset.dot(u)), planar(offset.dot(v)));
            // Duplicates of the point (or points straight above it) would land on it.
            if point.x == 0.0 && point.y == 0.0 {
                continue;
            }
            // Spade rejects only coordinates it cannot represent; such a neighbour is left out.
            let _ = self.triangulation.insert(point);
        }

        let mut closed = true;
        let mut certain = true;
        for edge in self.triangulation.vertex(centre_vertex).out_edges() {
            if edge.face().is_outer() {
                closed = false;
                continue;
            }
            // The face lies to the left of the edge: its other corners are the ends of this edge
            // and the next.
            let [a, b] = [edge.to(), edge.next().to()].map(|vertex| {
                let position = vertex.position();
                DVec2::new(position.x, position.y)
            });
            // The circumcircle passes through the origin: its radius is the centre's distance,
            // and it lies within the unit disc of the neighbourhood if that is at most 1/2.
            let circumradius = circumcentre(a, b).length();
            certain &= circumradius <= 0.5;
            if circumradius <= sliver_limit {
                let share = nearest_share(a, b);
                fan.reach = fan.reach.max(share.reach());
                fan.area += share.area();
            }
        }
        fan.complete = closed && certain;
        fan
    }
}

/// Circumcentre of the triangle (origin, a, b); not finite when the triangle is degenerate.
fn circumcentre(a: DVec2, b: DVec2) -> DVec2 {
    let twice_area = 2.0 * a.perp_dot(b);
    DVec2::new(
        a.length_squared() * b.y - b.length_squared() * a.y,
        b.length_squared() * a.x - a.length_squared() * b.x,
    ) / twice_area
}

/// The part of triangle (origin, a, b) nearer to the origin than to `a` and to `b`: the triangle
/// cut by the two perpendicular bisectors.
fn nearest_share(a: DVec2, b: DVec2) -> ConvexPolygon {
    let triangle = ConvexPolygon::from_corners(&[DVec2::ZERO, a, b]);
    // Nearer to the origin than to `p` means x·p ≤ |p|²/2.
    triangle
        .clip(a, a.length_squared() / 2.0)
        .clip(b, b.length_squared() / 2.0)
}

/// A convex polygon of up to six corners, enough for a triangle clipped twice (rounding can make
/// a clipped polygon very slightly non-convex, and then one cut may add two corners).
#[derive(Clone, Copy, Default)]
struct ConvexPolygon {
    corners: [DVec2; 6],
    len: usize,
}

impl ConvexPolygon {
    fn from_corners(corners: &[DVec2]) -> Self {
        let mut polygon = ConvexPolygon::default();
        for &corner in corners {
            polygon.push(corner);
        }
        polygon
    }

    fn push(&mut self, corner: DVec2) {
        if let Some(slot) = self.corners.get_mut(self.len) {
            *slot = corner;
            self.len += 1;
        }
    }

    fn corners(&self) -> &[DVec2] {
        &self.corners[..self.len]
    }

    /// The part where x·direction ≤ limit (Sutherland–Hodgman).
    fn clip(&self, direction: DVec2, limit: f64) -> Self {
        let mut clipped = ConvexPolygon::default();
        let corners = self.corners();
        for (i, &p) in corners.iter().enumerate() {
            let q = corners[(i + 1) % corners.len()];
            let (p_excess, q_excess) = (p.dot(direction) - limit, q.dot(direction) - limit);
            if p_excess <= 0.0 {
                clipped.push(p);
            }
            if (p_excess < 0.0 && q_excess > 0.0) || (p_excess > 0.0 && q_excess < 0.0) {
                clipped.push(p + (q - p) * (p_excess / (p_excess - q_excess)));
            }
        }
        clipped
    }

    /// Shoelace formula.
    fn area(&self) -> f64 {
        let corners = self.corners();
        let twice: f64 = (0..corners.len())
            .map(|i| corners[i].perp_dot(corners[(i + 1) % corners.len()]))
            .sum();
        twice.abs() / 2.0
    }

    /// The largest distance from the origin to the polygon.
    fn reach(&self) -> f64 {
        self.corners()
            .iter()
            .map(|corner| corner.length())
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points spread evenly over the unit sphere (golden-angle spiral).
    fn fibonacci_sphere(count: usize) -> Vec<DVec3> {
        let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..count)
            .map(|i| {
                let z = 1.0 - (2 * i + 1) as f64 / count as f64;
                let ring = (1.0 - z * z).sqrt();
                let angle = golden_angle * i as f64;
                DVec3::new(ring * angle.cos(), ring * angle.sin(), z)
            })
            .collect()
    }

    /// A small deterministic random number generator (SplitMix64).
    struct Random(u64);

    impl Random {
        fn unit(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }

        fn on_sphere(&mut self) -> DVec3 {
            let z = 2.0 * self.unit() - 1.0;
            let angle = std::f64::consts::TAU * self.unit();
            let ring = (1.0 - z * z).sqrt();
            DVec3::new(ring * angle.cos(), ring * angle.sin(), z)
        }
    }

    /// A `side` × `side` grid of spacing 1 in the z = 0 plane, each point moved by up to
    /// `jitter` in x and y and `z_noise` in z.
    fn jittered_grid(side: usize, jitter: f64, z_noise: f64, random: &mut Random) -> Vec<DVec3> {
        let mut points = Vec::new();
        for row in 0..side {
            for column in 0..side {
                let mut wobble = || 2.0 * random.unit() - 1.0;
                points.push(DVec3::new(
                    column as f64 + jitter * wobble(),
                    row as f64 + jitter * wobble(),
                    z_noise * wobble(),
                ));
            }
        }
        points
    }

    #[test]
    fn sphere_normals_point_outward_within_two_degrees() {
        let points = fibonacci_sphere(2000);
        let normals = estimate_normals(&points, 12);
        let worst = points
            .iter()
            .zip(&normals)
            .map(|(p, n)| p.normalize().angle_between(*n).to_degrees())
            .fold(0.0, f64::max);
        assert!(worst < 2.0, "worst deviation {worst}°");
    }

    #[test]
    fn separate_parts_are_each_oriented_outward() {
        let sphere = fibonacci_sphere(500);
        let centres = [DVec3::new(-10.0, 0.0, 0.0), DVec3::new(10.0, 0.0, 0.0)];
        let points: Vec<DVec3> = centres
            .iter()
            .flat_map(|&c| sphere.iter().map(move |&p| c + 2.0 * p))
            .collect();
        let normals = estimate_normals(&points, 10);
        for (i, normal) in normals.iter().enumerate() {
            let outward = sphere[i % 500];
            assert!(
                outward.angle_between(*normal).to_degrees() < 5.0,
                "point {i}"
            );
        }
    }

    #[test]
    fn plane_normals_are_all_the_same_z() {
        // Turned about the x axis too, where the eigenvectors' signs vary from point to point and
        // only the orientation step makes them agree.
        let grid = jittered_grid(30, 0.3, 1e-3, &mut Random(7));
        for turn in [0.0, 1.0f64] {
            let rotation = glam::DQuat::from_rotation_x(turn);
            let points: Vec<DVec3> = grid.iter().map(|&p| rotation * p).collect();
            let plane_normal = rotation * DVec3::Z;
            let normals = estimate_normals(&points, 12);
            let sign = normals[0].dot(plane_normal).signum();
            for normal in &normals {
                assert!((normal.length() - 1.0).abs() < 1e-12);
                assert!(
                    normal.dot(plane_normal) * sign > 0.0,
                    "orientation differs: {normal}"
                );
                assert!((sign * *normal).angle_between(plane_normal).to_degrees() < 1.0);
            }
        }
    }

    #[test]
    fn degenerate_normal_inputs_give_unit_normals() {
        assert!(estimate_normals(&[], 12).is_empty());
        let single = estimate_normals(&[DVec3::ONE], 12);
        assert!((single[0].length() - 1.0).abs() < 1e-12);

        let direction = DVec3::new(1.0, 2.0, 2.0) / 3.0;
        let line: Vec<DVec3> = (0..20).map(|i| direction * i as f64).collect();
        for points in [&line[..2], &line[..]] {
            for normal in estimate_normals(points, 12) {
                assert!((normal.length() - 1.0).abs() < 1e-12);
                assert!(normal.dot(direction).abs() < 1e-9, "{normal} not ⟂ line");
            }
        }

        let mut crowded = jittered_grid(10, 0.2, 0.0, &mut Random(3));
        crowded.extend(std::iter::repeat_n(DVec3::new(4.5, 4.5, 0.0), 40));
        crowded.extend(crowded[..50].to_vec());
        for normal in estimate_normals(&crowded, 8) {
            assert!((normal.length() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn sphere_radii_cover_the_surface_and_areas_sum_to_its_area() {
        let points = fibonacci_sphere(20_000);
        let normals = points.clone();
        let (radii, areas) = estimate_radii_and_areas(&points, &normals, 12);

        let total_area: f64 = areas.iter().sum();
        let sphere_area = 4.0 * std::f64::consts::PI;
        assert!(
            (total_area / sphere_area - 1.0).abs() < 0.03,
            "area {total_area} vs {sphere_area}"
        );
        // A loose upper bound, so that covering cannot come from absurdly large discs.
        let spacing = (sphere_area / points.len() as f64).sqrt();
        let largest = radii.iter().copied().fold(0.0, f64::max);
        assert!(
            largest < spacing,
            "largest radius {largest}, spacing {spacing}"
        );

        let samples: Vec<[f64; 3]> = points.iter().map(|p| p.to_array()).collect();
        let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(&samples).unwrap();
        let mut random = Random(11);
        let uncovered = (0..10_000)
            .filter(|_| {
                let spot = random.on_sphere();
                let nearby = tree
                    .query(&spot.to_array())
                    .nearest_n::<SquaredEuclidean<f64>>(NonZeroUsize::new(16).unwrap())
                    .execute();
                !nearby.iter().any(|sample| {
                    let j = sample.item as usize;
                    let offset = spot - points[j];
                    let in_plane = offset - offset.dot(normals[j]) * normals[j];
                    in_plane.length() <= radii[j]
                })
            })
            .count();
        assert_eq!(uncovered, 0, "random spots not covered by any disc");
    }

    #[test]
    fn plane_radii_and_areas_match_the_sampling() {
        let points = jittered_grid(40, 0.2, 0.0, &mut Random(5));
        let normals = vec![DVec3::Z; points.len()];
        let (radii, areas) = estimate_radii_and_areas(&points, &normals, 12);
        assert!(
            radii.iter().all(|&r| r > 0.3 && r < 1.5),
            "radii out of range"
        );
        let total_area: f64 = areas.iter().sum();
        assert!(
            (total_area / (39.0 * 39.0) - 1.0).abs() < 0.03,
            "area {total_area}"
        );
    }

    #[test]
    fn triangles_are_shared_out_by_nearest_corner() {
        let close = |x: f64, y: f64| (x - y).abs() < 1e-12;
        // Equilateral: a third each, reaching to the circumcentre.
        let (a, b) = (DVec2::new(1.0, 0.0), DVec2::new(0.5, 0.75f64.sqrt()));
        let share = nearest_share(a, b);
        assert!(close(share.area(), 0.75f64.sqrt() / 6.0));
        assert!(close(share.reach(), 1.0 / 3f64.sqrt()));
        assert!(close(circumcentre(a, b).length(), 1.0 / 3f64.sqrt()));
        // Right angle at the origin: a unit square, reaching the hypotenuse's midpoint.
        let share = nearest_share(DVec2::new(2.0, 0.0), DVec2::new(0.0, 2.0));
        assert!(close(share.area(), 1.0) && close(share.reach(), 2f64.sqrt()));
        // Flat triangle with the obtuse angle at (1, 0.1): the circumradius is over 5, yet no
        // spot is farther than 0.505 from its nearest corner.
        let (a, b) = (DVec2::new(2.0, 0.0), DVec2::new(1.0, 0.1));
        assert!(circumcentre(a, b).length() > 5.0);
        assert!(close(nearest_share(a, b).reach(), 0.505));
        let shares = [
            nearest_share(a, b),
            nearest_share(-a, b - a),
            nearest_share(-b, a - b),
        ];
        assert!(shares.iter().all(|share| share.reach() <= 0.505 + 1e-12));
        let total: f64 = shares.iter().map(ConvexPolygon::area).sum();
        assert!(
            close(total, 0.1),
            "the shares partition the triangle: {total}"
        );
    }

    #[test]
    fn square_grid_areas_do_not_depend_on_diagonals() {
        let grid: Vec<DVec3> = (0..400)
            .map(|i| DVec3::new((i % 20) as f64, (i / 20) as f64, 0.0))
            .collect();
        let (radii, areas) = estimate_radii_and_areas(&grid, &vec![DVec3::Z; 400], 12);
        for (i, (radius, area)) in radii.iter().zip(&areas).enumerate() {
            let inner = (1..19).contains(&(i % 20)) && (1..19).contains(&(i / 20));
            if inner {
                assert!((area - 1.0).abs() < 1e-9, "point {i}: area {area}");
                assert!(
                    (radius - 0.5f64.sqrt()).abs() < 1e-9,
                    "point {i}: radius {radius}"
                );
            }
        }
        let total: f64 = areas.iter().sum();
        assert!((total - 19.0 * 19.0).abs() < 1e-6, "total {total}");
    }

    #[test]
    fn irregular_sampling_is_covered_and_areas_add_up() {
        // Uniform random points: with only their 12 nearest neighbours many points would miss
        // some of their triangles (about a tenth of the area, and holes).
        let mut random = Random(17);
        let points: Vec<DVec3> = (0..5000)
            .map(|_| DVec3::new(random.unit(), random.unit(), 0.0))
            .collect();
        let normals = vec![DVec3::Z; points.len()];
        let (radii, areas) = estimate_radii_and_areas(&points, &normals, 12);
        let total: f64 = areas.iter().sum();
        assert!((total - 1.0).abs() < 0.03, "area {total}");
        let uncovered = (0..5000)
            .filter(|_| {
                let spot = DVec3::new(0.05 + 0.9 * random.unit(), 0.05 + 0.9 * random.unit(), 0.0);
                !points
                    .iter()
                    .zip(&radii)
                    .any(|(point, radius)| point.distance(spot) <= *radius)
            })
            .count();
        assert_eq!(uncovered, 0, "random spots not covered by any disc");
    }

    #[test]
    fn duplicate_and_isolated_points_get_fallback_radii() {
        let (radii, areas) = estimate_radii_and_areas(&[DVec3::ONE; 5], &[DVec3::Z; 5], 12);
        assert_eq!((radii, areas), (vec![0.0; 5], vec![0.0; 5]));

        // Collinear points have no triangles: the nearest distinct neighbour gives the radius.
        let line: Vec<DVec3> = (0..6).map(|i| DVec3::X * (2 * i) as f64).collect();
        let (radii, _) = estimate_radii_and_areas(&line, &[DVec3::Z; 6], 4);
        assert_eq!(radii, vec![2.0; 6]);

        let mut doubled = jittered_grid(12, 0.2, 0.0, &mut Random(9));
        doubled.extend(doubled.clone());
        let (radii, areas) = estimate_radii_and_areas(&doubled, &vec![DVec3::Z; doubled.len()], 12);
        assert!(radii
            .iter()
            .chain(&areas)
            .all(|&v| v.is_finite() && v > 0.0));
    }

    #[test]
    fn estimates_are_deterministic_across_runs_and_thread_counts() {
        let mut random = Random(13);
        let points: Vec<DVec3> = fibonacci_sphere(3000)
            .into_iter()
            .map(|p| p * (1.0 + 0.01 * random.unit()))
            .collect();
        let estimate = || {
            let normals = estimate_normals(&points, 12);
            let (radii, areas) = estimate_radii_and_areas(&points, &normals, 12);
            let bits = |values: &[f64]| values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            let normal_bits: Vec<[u64; 3]> = normals
                .iter()
                .map(|n| n.to_array().map(f64::to_bits))
                .collect();
            (normal_bits, bits(&radii), bits(&areas))
        };
        let first = estimate();
        assert_eq!(first, estimate());
        let single_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert_eq!(first, single_thread.install(estimate));
    }

    /// A cloud of `positions` and nothing else.
    fn bare(positions: Vec<DVec3>) -> PointCloud {
        PointCloud {
            positions,
            ..PointCloud::default()
        }
    }

    #[test]
    fn clouds_that_cannot_give_surfels_are_errors_naming_why() {
        let error = |cloud: PointCloud| from_point_cloud(&cloud, 12).unwrap_err().to_string();
        let message = error(bare(Vec::new()));
        assert!(message.starts_with("points: 0 points: "), "{message}");
        let message = error(bare(vec![DVec3::ONE]));
        assert!(message.starts_with("points: 1 point: "), "{message}");
        // A thousand points at one position are one point.
        let message = error(bare(vec![DVec3::new(0.2, 0.1, 0.0); 1000]));
        assert!(
            message.contains("1000 points (999 at one position with another, merged)"),
            "{message}"
        );
        // Two points, or a hundred on a line, fit no plane for the normals.
        for line in [2, 100] {
            let points = (0..line)
                .map(|i| DVec3::X * (0.01 * f64::from(i)))
                .collect();
            let message = error(bare(points));
            assert!(message.contains("all on one line"), "{message}");
        }
        // With their normals given, two points are enough: each stands for a disc half way to
        // the other.
        let mut two = bare(vec![DVec3::ZERO, DVec3::X * 0.1]);
        two.normals = Some(vec![DVec3::Z; 2]);
        let surfels = from_point_cloud(&two, 12).unwrap();
        assert_eq!(surfels.len(), 2);
        assert!(surfels.iter().all(|s| s.area > 0.0 && s.normal == DVec3::Z));
    }

    #[test]
    fn repeated_points_are_merged_before_the_neighbour_search() {
        // A 30 × 30 grid, every point given three times (and one of them as −0 where it is 0):
        // the surfels are those of the grid given once.
        let grid: Vec<DVec3> = (0..900)
            .map(|i| DVec3::new(f64::from(i % 30) * 0.1, f64::from(i / 30) * 0.1, 0.0))
            .collect();
        let mut repeated = Vec::new();
        for p in &grid {
            repeated.extend([*p, *p, DVec3::new(p.x, p.y, -0.0)]);
        }
        let once = from_point_cloud(&bare(grid), 12).unwrap();
        assert_eq!(from_point_cloud(&bare(repeated), 12).unwrap(), once);
        // 10⁵ points at one position end at once with an error, not in a quadratic search.
        let message = from_point_cloud(&bare(vec![DVec3::ONE; 100_000]), 12)
            .unwrap_err()
            .to_string();
        assert!(message.contains("99999 at one position"), "{message}");
    }

    #[test]
    fn a_radius_in_the_cloud_is_the_splat_s() {
        // A 10 × 10 grid 0.01 apart: without radii the splats are as wide as their cells ask
        // (σ = 0.6 × 0.01); with radii r they have σ = r/2, and the areas stay the cells'.
        let grid: Vec<DVec3> = (0..100)
            .map(|i| DVec3::new(f64::from(i % 10), f64::from(i / 10), 0.0) * 0.01)
            .collect();
        let mut cloud = bare(grid);
        cloud.normals = Some(vec![DVec3::Z; 100]);
        let estimated = from_point_cloud(&cloud, 12).unwrap();
        for radius in [0.001, 0.0055, 0.03] {
            cloud.radii = Some(vec![radius; 100]);
            let given = from_point_cloud(&cloud, 12).unwrap();
            for (g, e) in given.iter().zip(&estimated) {
                assert!((g.axis_u.length() - radius / 2.0).abs() < 1e-15);
                assert!((g.axis_v.length() - radius / 2.0).abs() < 1e-15);
                assert_eq!(g.area, e.area);
            }
        }
        let inner = &estimated[55];
        assert!((inner.axis_u.length() - 0.006).abs() < 1e-9, "{inner:?}");
    }

    #[test]
    fn one_far_outlier_does_not_make_a_plane_a_line() {
        // A 20 × 20 grid of spacing 1 and one stray point 10¹² away: the grid spans a plane, and
        // only a tolerance relative to the whole extent (10⁻⁹ of it is 1000) took it for a line.
        let mut points: Vec<DVec3> = (0..400)
            .map(|i| DVec3::new(f64::from(i % 20), f64::from(i / 20), 0.0))
            .collect();
        points.push(DVec3::new(1e12, 0.0, 0.0));
        let surfels = from_point_cloud(&bare(points), 12).unwrap();
        let total: f64 = surfels[..400].iter().map(|s| s.area).sum();
        assert!((total - 19.0 * 19.0).abs() < 1e-6, "grid area {total}");
        // A line far from the origin is still a line, whatever its coordinates' rounding.
        let direction = DVec3::new(1.0, 2.0, 2.0) / 3.0;
        let far_line = (0..100)
            .map(|i| DVec3::new(3e6, -1e6, 2e6) + direction * (1e-3 * f64::from(i)))
            .collect();
        let message = from_point_cloud(&bare(far_line), 12)
            .unwrap_err()
            .to_string();
        assert!(message.contains("all on one line"), "{message}");
        // Nor does a stray point so far that its squared distance overflows, which left the line
        // through it without a direction; three points on the x axis with it are still a line.
        let mut huge = bare(vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::ONE]);
        huge.positions.push(DVec3::X * 1e200);
        assert!(!collinear(&huge.positions));
        huge.positions.truncate(2);
        huge.positions.push(DVec3::X * 1e200);
        assert!(collinear(&huge.positions));
    }
}
