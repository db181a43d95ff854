//! The simplifier's speed and quality (issue 12's targets): a mesh, optionally Loop-subdivided
//! first, simplified to a face count; the median time, and the result's non-manifold and
//! boundary edges, flipped faces and mean symmetric surface distance to the input. Given another
//! simplification of the same input (MeshLab's, say), the same quality figures for it, so the
//! two compare in one run.
//!
//! `cargo bench --bench simplify -- MESH FACES [SUBDIVISIONS] [REPEATS] [OTHER] [WRITE_INPUT]`,
//! by default `../shared/data/meshes/bunny_bun_zipper.ply 27789 0 5`. `SUBDIVISIONS` Loop steps
//! make the 1.6 M-face armadillo from the 100 k one (generated here, not stored); `WRITE_INPUT`
//! writes the subdivided input for the other tool. `-` skips an optional argument. MeshLab's
//! simplification of the same input comes from `python3 benches/meshlab.py INPUT FACES OUT.ply`
//! (needs `pip install pymeshlab`); pass `OUT.ply` as `OTHER`.

mod common;

use std::collections::HashMap;
use std::f64::consts::TAU;
use std::num::NonZeroUsize;
use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use streak::io::obj::write_mesh;
use streak::simplify::{simplify, Options};
use streak::surfels::Mesh;

fn main() -> streak::Result<()> {
    let arg = common::args();
    let path = arg(0, "../shared/data/meshes/bunny_bun_zipper.ply");
    let faces: usize = arg(1, "27789").parse().expect("FACES is a count");
    let subdivisions: usize = arg(2, "0").parse().expect("SUBDIVISIONS is a count");
    let repeats: usize = arg(3, "5").parse().expect("REPEATS is a count");
    let other = arg(4, "-");
    let write_input = arg(5, "-");

    let mut mesh = Mesh::read(Path::new(&path))?;
    for _ in 0..subdivisions {
        mesh = loop_subdivide(&mesh);
    }
    if write_input != "-" {
        write_mesh(&mesh, Path::new(&write_input))?;
    }
    let options = Options {
        target_faces: faces,
        ..Options::default()
    };
    let mut times = Vec::new();
    let mut result = None;
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        let simplified = simplify(&mesh, &options, (&[], 0), &mut |_| {})?;
        times.push(start.elapsed().as_secs_f64());
        result = Some(simplified);
    }
    let (median, min) = common::median_and_min(&mut times);
    let result = result.expect("at least one run");
    println!(
        "{path} ({} faces, {subdivisions} Loop steps) → {} faces: median {:.4} s of {} on {} thread(s) (min {:.4} s); {:?}",
        mesh.triangles.len(),
        result.mesh.triangles.len(),
        median,
        times.len(),
        rayon::current_num_threads(),
        min,
        result.stats,
    );
    let reference = Surface::new(&mesh);
    report("streak", &result.mesh, &mesh, &reference);
    if other != "-" {
        let other_mesh = Mesh::read(Path::new(&other))?;
        report(&other, &other_mesh, &mesh, &reference);
    }
    Ok(())
}

/// Quality of `simplified` against `input`: non-manifold edges, faces flipped against the input
/// surface nearest their centre, and the mean symmetric distance, relative to the input's
/// bounding-box diagonal.
fn report(name: &str, simplified: &Mesh, input: &Mesh, input_surface: &Surface) {
    let (lo, hi) = input.bounds().expect("the input has faces");
    let diagonal = (hi - lo).length();
    let surface = Surface::new(simplified);
    let forward = mean_distance(input, &surface, 200_000);
    let backward = mean_distance(simplified, input_surface, 200_000);
    let (non_manifold, boundary) = odd_edges(simplified);
    let flipped = simplified
        .triangles
        .iter()
        .filter(|t| {
            let [a, b, c] = t.map(|v| simplified.positions[v as usize]);
            let normal = (b - a).cross(c - a);
            let (_, face) = input_surface.nearest((a + b + c) / 3.0);
            normal.dot(input_surface.normals[face]) < 0.0
        })
        .count();
    println!(
        "  {name}: {} faces, {non_manifold} non-manifold edges, {boundary} boundary edges, {flipped} flipped faces, mean distance {:.3e} of the diagonal (input→result {:.3e}, result→input {:.3e})",
        simplified.triangles.len(),
        0.5 * (forward + backward) / diagonal,
        forward / diagonal,
        backward / diagonal,
    );
}

/// Edges with more than two faces, and edges with one (the boundary: the bunny has holes, so its
/// result keeps some; a closed input's result should have none).
fn odd_edges(mesh: &Mesh) -> (usize, usize) {
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &mesh.triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let more = count.values().filter(|&&c| c > 2).count();
    let one = count.values().filter(|&&c| c == 1).count();
    (more, one)
}

/// A triangle mesh with a k-d tree over points spread on its faces, for nearest-face queries.
struct Surface<'m> {
    mesh: &'m Mesh,
    normals: Vec<DVec3>,
    tree: ImmutableKdTree<f64, 3>,
    point_face: Vec<usize>,
}

impl<'m> Surface<'m> {
    fn new(mesh: &'m Mesh) -> Surface<'m> {
        let normals = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
                (b - a).cross(c - a)
            })
            .collect();
        // The centre and the three corner-ward points of each face: a query's nearest point
        // then lies on or next to its nearest face, even among faces of different sizes.
        let mut points = Vec::new();
        let mut point_face = Vec::new();
        for (f, t) in mesh.triangles.iter().enumerate() {
            let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
            let centre = (a + b + c) / 3.0;
            for p in [
                centre,
                (centre + a) / 2.0,
                (centre + b) / 2.0,
                (centre + c) / 2.0,
            ] {
                points.push(p.to_array());
                point_face.push(f);
            }
        }
        let tree = ImmutableKdTree::new_from_slice(&points).expect("fewer than 2^32 points");
        Surface {
            mesh,
            normals,
            tree,
            point_face,
        }
    }

    /// Distance from `p` to the nearest of the faces next to its 16 nearest spread points, and
    /// that face.
    fn nearest(&self, p: DVec3) -> (f64, usize) {
        self.tree
            .query(&p.to_array())
            .nearest_n::<SquaredEuclidean<f64>>(NonZeroUsize::new(16).unwrap())
            .execute()
            .iter()
            .map(|n| {
                let f = self.point_face[n.item as usize];
                let [a, b, c] = self.mesh.triangles[f].map(|v| self.mesh.positions[v as usize]);
                (point_triangle_distance(p, a, b, c), f)
            })
            .min_by(|x, y| x.0.total_cmp(&y.0))
            .expect("the tree has points")
    }
}

/// Mean distance from `samples` points spread uniformly by area over `from` to `to`.
fn mean_distance(from: &Mesh, to: &Surface, samples: usize) -> f64 {
    let areas: Vec<f64> = from
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| from.positions[v as usize]);
            0.5 * (b - a).cross(c - a).length()
        })
        .collect();
    let total: f64 = areas.iter().sum();
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut uniform = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut sum = 0.0;
    let mut count = 0usize;
    for (t, area) in from.triangles.iter().zip(&areas) {
        let expected = samples as f64 * area / total;
        let mut n = expected.floor() as usize;
        if uniform() < expected - n as f64 {
            n += 1;
        }
        let [a, b, c] = t.map(|v| from.positions[v as usize]);
        for _ in 0..n {
            let (mut u, mut v) = (uniform(), uniform());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            sum += to.nearest(a + u * (b - a) + v * (c - a)).0;
            count += 1;
        }
    }
    sum / count.max(1) as f64
}

/// Distance from `p` to triangle (a, b, c) (Ericson, Real-Time Collision Detection §5.1.5).
fn point_triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).length()
}

/// One step of Loop subdivision (Loop 1987): a new vertex on each edge at 3/8 of its ends and
/// 1/8 of the opposite corners (the middle on a boundary), and each old vertex moved to
/// (1 − nβ) of itself and β of each of its n neighbours, β = (5/8 − (3/8 + cos(2π/n)/4)²)/n
/// (boundary vertices stay).
fn loop_subdivide(mesh: &Mesh) -> Mesh {
    let n = mesh.positions.len();
    let mut edge_vertex: HashMap<(u32, u32), u32> = HashMap::new();
    let mut edge_corners: Vec<(u32, u32, Vec<u32>)> = Vec::new();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut triangles = Vec::with_capacity(mesh.triangles.len() * 4);
    for t in &mesh.triangles {
        let mut mids = [0u32; 3];
        for i in 0..3 {
            let (a, b, c) = (t[i], t[(i + 1) % 3], t[(i + 2) % 3]);
            let key = (a.min(b), a.max(b));
            let next = (n + edge_corners.len()) as u32;
            let index = *edge_vertex.entry(key).or_insert_with(|| {
                edge_corners.push((key.0, key.1, Vec::new()));
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
                next
            });
            edge_corners[index as usize - n].2.push(c);
            mids[i] = index;
        }
        triangles.push([t[0], mids[0], mids[2]]);
        triangles.push([t[1], mids[1], mids[0]]);
        triangles.push([t[2], mids[2], mids[1]]);
        triangles.push(mids);
    }
    let mut on_boundary = vec![false; n];
    let p = &mesh.positions;
    let mut positions: Vec<DVec3> = Vec::with_capacity(n + edge_corners.len());
    let odd: Vec<DVec3> = edge_corners
        .iter()
        .map(|(a, b, corners)| {
            let ends = p[*a as usize] + p[*b as usize];
            if corners.len() == 2 {
                0.375 * ends + 0.125 * (p[corners[0] as usize] + p[corners[1] as usize])
            } else {
                on_boundary[*a as usize] = true;
                on_boundary[*b as usize] = true;
                0.5 * ends
            }
        })
        .collect();
    for v in 0..n {
        let around = &neighbours[v];
        let k = around.len() as f64;
        if on_boundary[v] || around.is_empty() {
            positions.push(p[v]);
            continue;
        }
        let beta = (0.625 - (0.375 + 0.25 * (TAU / k).cos()).powi(2)) / k;
        let sum: DVec3 = around.iter().map(|&w| p[w as usize]).sum();
        positions.push((1.0 - k * beta) * p[v] + beta * sum);
    }
    positions.extend(odd);
    Mesh {
        positions,
        triangles,
    }
}
