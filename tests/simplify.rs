//! Quadric edge-collapse simplification (`streak::simplify`): topology and geometry kept where
//! they must be, the direction weights ordering collapses as eq. 4 of Zhang et al. 2014 says,
//! degenerate input repaired or refused with a message, the same bytes on every run, and the
//! plan's level of detail for moving meshes.

mod common;

use std::collections::HashMap;

use glam::DVec3;
use streak::lod::Lod;
use streak::scene::{Camera, Keyframe, Motion, Object, Pose, TriangleMesh};
use streak::simplify::speed::DetailRule;
use streak::simplify::{
    direction_weight, simplify, Limits, Options, Simplified, Weighting, BLOCK_VERTICES,
};
use streak::surfels::{from_mesh, Colouring, Mesh};
use streak::{Method, Plan, Scene};

fn run(mesh: &Mesh, target_faces: usize, weighting: Weighting) -> Simplified {
    let options = Options {
        target_faces,
        weighting,
        limits: None,
    };
    simplify(mesh, &options, (&[], 0), &mut |_| {}).unwrap()
}

/// The shared icosphere (`common::icosphere`) as a mesh.
fn icosphere(levels: usize) -> Mesh {
    let (positions, triangles) = common::icosphere(levels);
    Mesh {
        positions,
        triangles: triangles.iter().map(|t| t.map(|v| v as u32)).collect(),
    }
}

/// An `n` × `n` grid of squares over the unit square in z = 0, two triangles each.
fn grid(n: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for j in 0..=n {
        for i in 0..=n {
            mesh.positions.push(DVec3::new(
                f64::from(i) / f64::from(n),
                f64::from(j) / f64::from(n),
                0.0,
            ));
        }
    }
    quads(&mut mesh, [n, n], |i, j| j * (n + 1) + i);
    mesh
}

/// Two triangles for each of `columns` × `rows` quads, whose corner (i, j) is vertex `at(i, j)`.
fn quads(mesh: &mut Mesh, [columns, rows]: [u32; 2], at: impl Fn(u32, u32) -> u32) {
    for j in 0..rows {
        for i in 0..columns {
            mesh.triangles
                .push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            mesh.triangles
                .push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
}

/// The cube [−1, 1]³, each side an `n` × `n` grid, wound outwards, vertices shared.
fn cube(n: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for axis in 0..3 {
        for side in [-1.0, 1.0] {
            let face = grid(n);
            let base = mesh.positions.len() as u32;
            for p in &face.positions {
                let (u, v) = (2.0 * p.x - 1.0, 2.0 * p.y - 1.0);
                let mut q = [0.0; 3];
                q[axis] = side;
                q[(axis + 1) % 3] = u;
                q[(axis + 2) % 3] = v;
                mesh.positions.push(DVec3::from_array(q));
            }
            for t in &face.triangles {
                let t = t.map(|v| v + base);
                mesh.triangles
                    .push(if side > 0.0 { t } else { [t[0], t[2], t[1]] });
            }
        }
    }
    weld(mesh)
}

/// Vertices at the same position merged (what `simplify` repairs; done here so that inputs are
/// clean).
fn weld(mesh: Mesh) -> Mesh {
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut out = Mesh::default();
    let map: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let key = p.to_array().map(|c| (c + 0.0).to_bits());
            *index.entry(key).or_insert_with(|| {
                out.positions.push(*p);
                out.positions.len() as u32 - 1
            })
        })
        .collect();
    out.triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| map[v as usize]))
        .collect();
    out
}

/// Whether every directed edge appears once and its reverse once: closed, manifold and
/// consistently wound.
fn closed_manifold(mesh: &Mesh) -> bool {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &mesh.triangles {
        for i in 0..3 {
            *directed.entry((t[i], t[(i + 1) % 3])).or_default() += 1;
        }
    }
    directed
        .iter()
        .all(|(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1))
}

fn volume(mesh: &Mesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

fn face_normal(mesh: &Mesh, t: [u32; 3]) -> DVec3 {
    let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
    (b - a).cross(c - a)
}

#[test]
fn a_closed_sphere_stays_closed_and_manifold_at_every_target_with_no_face_flipped() {
    let sphere = icosphere(3);
    let full = volume(&sphere);
    assert!(closed_manifold(&sphere));
    for (target, volume_tolerance) in [(640, 0.02), (200, 0.06), (50, 0.25), (12, 1.0), (4, 1.0)] {
        let out = run(&sphere, target, Weighting::Isotropic);
        assert!(out.reached_target, "{target}: {:?}", out.stats);
        assert_eq!(out.mesh.triangles.len(), target);
        assert!(
            closed_manifold(&out.mesh),
            "{target} faces: not closed and manifold"
        );
        // A convex surface: every face's normal points away from the centre.
        for &t in &out.mesh.triangles {
            let [a, b, c] = t.map(|v| out.mesh.positions[v as usize]);
            assert!(
                face_normal(&out.mesh, t).dot(a + b + c) > 0.0,
                "{target} faces: a face flipped"
            );
        }
        // Volume: the optimal placements sit near the sphere, so the polyhedron loses little
        // until few faces are left (a regular 200-face polyhedron inscribed loses about 4 %).
        let change = (volume(&out.mesh) - full).abs() / full;
        assert!(
            change <= volume_tolerance,
            "{target} faces: volume changed by {change}"
        );
    }
}

#[test]
fn a_flat_grid_collapses_to_two_triangles_on_its_corners() {
    let out = run(&grid(8), 2, Weighting::Isotropic);
    assert_eq!(out.mesh.triangles.len(), 2);
    let mut corners: Vec<[i64; 3]> = out
        .mesh
        .positions
        .iter()
        .map(|p| (*p * 1e9).round().as_i64vec3().to_array())
        .collect();
    corners.sort_unstable();
    assert_eq!(
        corners,
        [
            [0, 0, 0],
            [0, 1_000_000_000, 0],
            [1_000_000_000, 0, 0],
            [1_000_000_000, 1_000_000_000, 0]
        ]
    );
}

#[test]
fn an_open_mesh_reaches_an_odd_target_exactly_and_a_closed_one_stops_one_below() {
    // A collapse inside a surface takes two faces, one on a boundary takes one.
    for target in [127, 77, 33, 9, 3] {
        let out = run(&grid(8), target, Weighting::Isotropic);
        assert_eq!(out.mesh.triangles.len(), target, "grid to {target}");
        assert!(out.reached_target);
        for &t in &out.mesh.triangles {
            assert!(
                face_normal(&out.mesh, t).z > 0.0,
                "grid to {target}: a face flipped"
            );
        }
    }
    // A closed surface's face count is even (3F = 2E).
    let out = run(&icosphere(2), 101, Weighting::Isotropic);
    assert_eq!(out.mesh.triangles.len(), 100);
    assert!(closed_manifold(&out.mesh));
}

#[test]
fn a_cube_keeps_its_corners() {
    let out = run(&cube(4), 12, Weighting::Isotropic);
    assert_eq!(out.mesh.triangles.len(), 12);
    assert!(closed_manifold(&out.mesh));
    assert_eq!(out.mesh.positions.len(), 8);
    for p in &out.mesh.positions {
        assert!(
            (p.abs() - DVec3::ONE).abs().max_element() < 1e-9,
            "{p} is not a corner of the cube"
        );
    }
}

#[test]
fn direction_weights_follow_eq_4_and_order_the_collapses() {
    // f(α) = 1 − (1 − cos α)^4 + 0.5: across the motion ε, along it 1 + ε, falling in between.
    assert_eq!(direction_weight(0.0), 0.5);
    assert_eq!(direction_weight(1.0), 1.5);
    let mut previous = direction_weight(1.0);
    for i in 1..=90 {
        let f = direction_weight(f64::from(i).to_radians().cos());
        assert!(f < previous, "not falling at {i}°");
        previous = f;
    }
    // The weights order the collapses: on a sphere moving along x, edges across the motion
    // weigh ε and collapse first. Each such collapse thins the vertices across the motion, so
    // the triangles left stretch across it and their edges lean away from the motion.
    let sphere = icosphere(3);
    let lean = |mesh: &Mesh| {
        let mut along = 0.0;
        let mut all = 0.0;
        for t in &mesh.triangles {
            for i in 0..3 {
                let e = mesh.positions[t[(i + 1) % 3] as usize] - mesh.positions[t[i] as usize];
                along += e.normalize().x.abs();
                all += 1.0;
            }
        }
        along / all
    };
    let isotropic = lean(&run(&sphere, 300, Weighting::Isotropic).mesh);
    let aware = lean(&run(&sphere, 300, Weighting::Direction(DVec3::X)).mesh);
    assert!(
        aware < isotropic - 0.03,
        "mean |cos α| of the edges left: direction-aware {aware}, isotropic {isotropic}"
    );
}

/// An open tube of radius 1 about z: `around` generators, `rings` + 1 rings spaced as far apart
/// as the generators are around it.
fn tube(around: u32, rings: u32) -> Mesh {
    let mut mesh = Mesh::default();
    let step = std::f64::consts::TAU / f64::from(around);
    for j in 0..=rings {
        for i in 0..around {
            let angle = step * f64::from(i);
            mesh.positions
                .push(DVec3::new(angle.cos(), angle.sin(), step * f64::from(j)));
        }
    }
    quads(&mut mesh, [around, rings], |i, j| j * around + i % around);
    mesh
}

#[test]
fn a_cylinder_loses_its_axial_edges_first_whatever_its_motion() {
    // Collapsing an edge along a generator leaves every vertex on the surface: its quadric error
    // is 0, and a direction weight multiplies the cost (Zhang §4), so it stays 0 and such edges
    // go first, moving along the axis (weight 1 + ε) or across it (ε) alike. Any other collapse
    // would take a vertex off its generator. A weight added to the cost instead would let the
    // ring edges go first when moving along the axis.
    let around = 24;
    let cylinder = tube(around, 12);
    let step = std::f64::consts::TAU / f64::from(around);
    for weighting in [
        Weighting::Isotropic,
        Weighting::Direction(DVec3::Z),
        Weighting::Direction(DVec3::X),
    ] {
        let simplified = run(&cylinder, 460, weighting.clone()).mesh;
        assert_eq!(simplified.triangles.len(), 460);
        for t in &simplified.triangles {
            for &v in t {
                let p = simplified.positions[v as usize];
                let generator = p.y.atan2(p.x) / step;
                assert!(
                    (p.truncate().length() - 1.0).abs() < 1e-9
                        && (generator - generator.round()).abs() < 1e-9,
                    "{weighting:?}: vertex {p} off the generators"
                );
            }
        }
    }
}

#[test]
fn degenerate_input_is_repaired_and_counted_or_refused_by_name() {
    // A cube written with its sides apart (24 vertices, as exporters split normals), plus a
    // face with a repeated corner, a repeated face, an isolated vertex, and a fin making one
    // edge non-manifold.
    let mut mesh = Mesh::default();
    let sides = cube(1);
    for t in &sides.triangles {
        let base = mesh.positions.len() as u32;
        mesh.positions
            .extend(t.map(|v| sides.positions[v as usize]));
        mesh.triangles.push([base, base + 1, base + 2]);
    }
    mesh.triangles.push([0, 0, 1]);
    mesh.triangles.push(mesh.triangles[3]);
    mesh.positions.push(DVec3::splat(7.0));
    let fin = mesh.positions.len() as u32;
    mesh.positions.push(DVec3::new(3.0, 3.0, 3.0));
    let [a, b, _] = mesh.triangles[0];
    mesh.triangles.push([a, b, fin]);
    let out = run(&mesh, 1, Weighting::Isotropic);
    let r = out.repairs;
    assert_eq!(r.welded, 36 - 8, "{r:?}");
    assert_eq!(
        (r.repeated_corners, r.duplicate_faces, r.isolated),
        (1, 1, 1),
        "{r:?}"
    );
    assert_eq!(r.non_manifold_edges, 1, "{r:?}");
    assert!(out.mesh.positions.iter().all(|p| p.is_finite()));
    assert!(out.mesh.triangles.len() >= 2);

    let mut bad = icosphere(0);
    bad.positions[3].y = f64::NAN;
    let e = simplify(&bad, &Options::default(), (&[], 0), &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("vertex 3"), "{e}");
    let mut bad = icosphere(0);
    bad.triangles[5][1] = 99;
    let e = simplify(&bad, &Options::default(), (&[], 0), &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("face 5"), "{e}");
    // Zero-area faces (three corners on a line) are kept until their edges collapse, first.
    let mut sliver = grid(2);
    sliver.positions.push(DVec3::new(0.5, 0.0, 0.0));
    sliver.triangles.push([0, 1, 2]);
    let out = run(&sliver, 2, Weighting::Isotropic);
    assert!(out.mesh.positions.iter().all(|p| p.is_finite()));
}

#[test]
fn the_same_mesh_and_settings_give_the_same_bytes_whatever_the_thread_count() {
    let sphere = icosphere(4);
    let simplified = |threads: usize| {
        run_on(
            threads,
            &sphere,
            700,
            Weighting::Direction(DVec3::new(1.0, 0.3, 0.0)),
        )
    };
    let one = bytes(&simplified(1));
    assert_eq!(one, bytes(&simplified(2)));
    assert_eq!(one, bytes(&simplified(3)));
}

/// The positions and faces of a simplified mesh as bytes, to compare runs.
fn bytes(s: &Simplified) -> Vec<u8> {
    let mut out = Vec::new();
    for p in &s.mesh.positions {
        for c in p.to_array() {
            out.extend(c.to_le_bytes());
        }
    }
    for t in &s.mesh.triangles {
        for v in t {
            out.extend(v.to_le_bytes());
        }
    }
    out
}

/// `run` on a pool of `threads` threads.
fn run_on(threads: usize, mesh: &Mesh, target_faces: usize, weighting: Weighting) -> Simplified {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| run(mesh, target_faces, weighting))
}

#[test]
fn a_mesh_collapsed_in_parallel_blocks_is_closed_even_and_the_same_whatever_the_thread_count() {
    let sphere = icosphere(6);
    assert!(
        sphere.positions.len() >= 4 * BLOCK_VERTICES,
        "too small for blocks"
    );
    let target = 6000;
    let one = run_on(1, &sphere, target, Weighting::Isotropic);
    let two = run_on(2, &sphere, target, Weighting::Isotropic);
    assert_eq!(bytes(&one), bytes(&two));
    assert!(one.reached_target, "{:?}", one.stats);
    assert_eq!(one.mesh.triangles.len(), target);
    assert!(closed_manifold(&one.mesh));
    let areas: Vec<f64> = one
        .mesh
        .triangles
        .iter()
        .map(|&t| {
            let [a, b, c] = t.map(|v| one.mesh.positions[v as usize]);
            assert!(
                face_normal(&one.mesh, t).dot(a + b + c) > 0.0,
                "a face flipped"
            );
            0.5 * face_normal(&one.mesh, t).length()
        })
        .collect();
    for p in &one.mesh.positions {
        assert!((p.length() - 1.0).abs() < 0.002, "{p} is off the sphere");
    }
    // On a sphere every part is alike, so faces end up alike in size. Seams between blocks left
    // denser than the rest show as faces far smaller than the mean: 1,446 of the 6,000 were
    // below a quarter of it when the blocks left the single queue only the seam faces' own share
    // of the reduction; 2 when they leave twice that (the faces just inside the blocks, around
    // the seams' corners, are about as many again).
    let mean = areas.iter().sum::<f64>() / areas.len() as f64;
    let small = areas.iter().filter(|&&a| a < 0.25 * mean).count();
    assert!(
        small <= target / 100,
        "{small} faces below a quarter of the mean"
    );
}

#[test]
fn blocks_spend_the_faces_where_the_detail_is_whatever_block_it_lies_in() {
    // A 200 × 200 grid, flat where x < 1/2 and rippled beyond: cut into blocks along a Morton
    // curve, some blocks hold only flat squares and some only ripples. The blocks advance in
    // rounds of cost, so the flat half (whose collapses cost nothing) goes first, as one queue
    // would take it: 67 of the 8,000 faces are left on it. Blocks reducing each by the same share
    // (the rounds made 256 octaves wide) left 2,888.
    let mut mesh = grid(200);
    for p in &mut mesh.positions {
        if p.x > 0.5 {
            p.z = 0.02 * (40.0 * p.x).sin() * (30.0 * p.y).sin();
        }
    }
    assert!(
        mesh.positions.len() >= 4 * BLOCK_VERTICES,
        "too small for blocks"
    );
    let target = mesh.triangles.len() / 10;
    let simplified = run(&mesh, target, Weighting::Isotropic);
    let flat = simplified
        .mesh
        .triangles
        .iter()
        .filter(|t| {
            let centre: DVec3 = t
                .iter()
                .map(|&v| simplified.mesh.positions[v as usize])
                .sum();
            centre.x / 3.0 < 0.5
        })
        .count();
    assert!(
        flat * 10 < simplified.mesh.triangles.len(),
        "{flat} of {} faces on the flat half",
        simplified.mesh.triangles.len()
    );
}

#[test]
fn carried_colours_are_interpolated_within_their_range() {
    let sphere = icosphere(3);
    let colours: Vec<f32> = sphere
        .positions
        .iter()
        .flat_map(|p| [(0.5 + 0.5 * p.x) as f32, 0.25, (0.5 + 0.5 * p.z) as f32])
        .collect();
    let options = Options {
        target_faces: 100,
        ..Options::default()
    };
    let out = simplify(&sphere, &options, (&colours, 3), &mut |_| {}).unwrap();
    assert_eq!(out.carried.len(), out.mesh.positions.len() * 3);
    for (p, c) in out.mesh.positions.iter().zip(out.carried.chunks_exact(3)) {
        assert!((0.0..=1.0).contains(&c[0]) && c[1] == 0.25);
        // The colour still follows the position it was made from, to within a coarse facet.
        assert!(
            (f64::from(c[0]) - (0.5 + 0.5 * p.normalize().x)).abs() < 0.15,
            "{p} {c:?}"
        );
    }
}

/// A 160 × 120 camera at z = 6 looking at the origin.
fn camera_from_z6() -> Camera {
    Camera::new(
        DVec3::new(0.0, 0.0, 6.0),
        DVec3::ZERO,
        DVec3::Y,
        30.0,
        160,
        120,
    )
    .unwrap()
}

/// A scene looking at the icosphere from z = 6, the sphere moving `dx` along x over the shutter.
fn moving_sphere(dx: f64) -> Scene {
    let mesh = icosphere(4);
    let camera = camera_from_z6();
    let triangles = TriangleMesh::new(&mesh, DVec3::ZERO, Colouring::Rgb([0.8, 0.6, 0.4])).unwrap();
    let mut surfels = from_mesh(&mesh, 4000, false).unwrap();
    Colouring::Rgb([0.8, 0.6, 0.4]).apply(&mut surfels);
    let at = |x: f64| Pose {
        translation: DVec3::new(x, 0.0, 0.0),
        ..Pose::IDENTITY
    };
    let motion = Motion::new(vec![
        Keyframe {
            t: 0.0,
            pose: at(-dx / 2.0),
        },
        Keyframe {
            t: 1.0,
            pose: at(dx / 2.0),
        },
    ])
    .unwrap();
    Scene::new(camera).with_object(Object::triangles("sphere", triangles, surfels, motion))
}

#[test]
fn the_plan_simplifies_moving_meshes_by_their_speed_and_leaves_still_ones_alone() {
    let faces = |scene: &Scene, method: &Method, lod: Lod| {
        let plan = Plan::with_lod(scene, method, lod).unwrap();
        (plan.mesh_of(0).unwrap().triangles.len(), plan.explain(None))
    };
    let full = 20 * 4usize.pow(4);
    let (still, explain) = faces(&moving_sphere(0.0), &Method::ANALYTIC, Lod::Auto);
    assert_eq!(still, full);
    assert!(explain.contains("faces kept: still"), "{explain}");
    let fast = moving_sphere(3.0);
    assert_eq!(faces(&fast, &Method::ANALYTIC, Lod::Off).0, full);
    assert_eq!(faces(&fast, &Method::STATIC, Lod::Auto).0, full);
    let (simplified, explain) = faces(&fast, &Method::ANALYTIC, Lod::Auto);
    assert!(simplified < full / 4, "{explain}");
    assert!(
        explain.contains(&format!("{full} faces → {simplified}")),
        "{explain}"
    );
    // The cap on the perimeter binds at any speed: at 20 px the fast sphere keeps more faces.
    let capped = fast
        .clone()
        .with_mesh_detail(DetailRule {
            max_perimeter_px: 20.0,
            ..DetailRule::default()
        })
        .unwrap();
    let (finer, explain) = faces(&capped, &Method::ANALYTIC, Lod::Auto);
    assert!(simplified < finer && finer < full, "{simplified} {explain}");
    assert!(explain.contains("0.36, 20) px"), "{explain}");
    let simplifies = |scene: &Scene, lod: Lod| {
        Plan::with_lod(scene, &Method::ANALYTIC, lod)
            .unwrap()
            .simplifies_a_mesh()
    };
    assert!(simplifies(&fast, Lod::Auto));
    assert!(!simplifies(&fast, Lod::Off));
    assert!(!simplifies(&moving_sphere(0.0), Lod::Auto));
    // Moving too slowly for any collapse: simplified to every face it had, so nothing differs.
    let crawling = moving_sphere(0.01);
    assert_eq!(faces(&crawling, &Method::ANALYTIC, Lod::Auto).0, full);
    assert!(!simplifies(&crawling, Lod::Auto));
    // Slower, less simplified.
    let (slower, _) = faces(&moving_sphere(1.2), &Method::ANALYTIC, Lod::Auto);
    assert!(
        simplified < slower && slower < full,
        "{simplified} {slower}"
    );
    // The render with the simplified mesh is finite and close to full detail's.
    let lod = Plan::with_lod(&fast, &Method::ANALYTIC, Lod::Auto)
        .unwrap()
        .render(None)
        .image;
    let off = Plan::with_lod(&fast, &Method::ANALYTIC, Lod::Off)
        .unwrap()
        .render(None)
        .image;
    let flip_free_rmse = lod
        .pixels
        .iter()
        .zip(&off.pixels)
        .map(|(a, b)| (0..3).map(|c| f64::from(a[c] - b[c]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / (3 * lod.pixels.len()) as f64;
    assert!(lod.pixels.iter().flatten().all(|v| v.is_finite()));
    assert!(
        flip_free_rmse.sqrt() < 0.03,
        "RMSE {}",
        flip_free_rmse.sqrt()
    );
}

/// A collapse that takes away every face its two ends have would leave nothing of a piece: an
/// open mesh reaches target 0 with faces left, and a small open quad beside a large grid, moving
/// too slowly for its faces to grow past their limits, keeps a face.
#[test]
fn no_piece_of_an_open_mesh_is_collapsed_to_nothing() {
    let one = Mesh {
        positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
        triangles: vec![[0, 1, 2]],
    };
    assert_eq!(run(&one, 0, Weighting::Isotropic).mesh.triangles.len(), 1);
    assert!(!run(&grid(4), 0, Weighting::Isotropic)
        .mesh
        .triangles
        .is_empty());
    let mut mesh = grid(4);
    let base = mesh.positions.len() as u32;
    let quad = grid(1);
    mesh.positions.extend(
        quad.positions
            .iter()
            .map(|&p| DVec3::new(5.0, 0.0, 0.0) + 0.01 * p),
    );
    mesh.triangles
        .extend(quad.triangles.iter().map(|t| t.map(|v| v + base)));
    let options = Options {
        target_faces: 0,
        weighting: Weighting::Isotropic,
        limits: Some(Limits {
            per_vertex: vec![0.1; mesh.positions.len()],
        }),
    };
    let out = simplify(&mesh, &options, (&[], 0), &mut |_| {}).unwrap();
    let on_quad = out
        .mesh
        .triangles
        .iter()
        .filter(|t| out.mesh.positions[t[0] as usize].x > 4.0)
        .count();
    assert!(on_quad >= 1, "the small quad is gone: {:?}", out.stats);
}

/// Scaling a mesh by a power of two scales every cost by its fourth power exactly, so no
/// collapse may change, down to sizes whose costs fall below f32's range (2⁻³⁰: costs near
/// 10⁻³⁸ and less) and up to sizes whose costs pass it.
#[test]
fn a_mesh_scaled_by_a_power_of_two_collapses_the_same_way() {
    let rippled = rippled_grid();
    let corners = |out: &Simplified, scale: f64| {
        let mut v: Vec<[i64; 3]> = out
            .mesh
            .positions
            .iter()
            .map(|&p| (p / scale * 1e6).round().as_i64vec3().to_array())
            .collect();
        v.sort_unstable();
        v
    };
    let unscaled = corners(&run(&rippled, 150, Weighting::Isotropic), 1.0);
    for exponent in [-30, -25, -20, 20, 25, 30, 35] {
        let scale = 2f64.powi(exponent);
        let mut scaled = rippled.clone();
        for p in &mut scaled.positions {
            *p *= scale;
        }
        let out = run(&scaled, 150, Weighting::Isotropic);
        assert!(corners(&out, scale) == unscaled, "scaled by 2^{exponent}");
    }
}

/// A 24 × 24 grid over the unit square, rippled in z.
fn rippled_grid() -> Mesh {
    let mut rippled = grid(24);
    for p in &mut rippled.positions {
        p.z = 0.05 * (9.0 * p.x).sin() * (7.0 * p.y).sin() + 0.02 * (23.0 * p.x * p.y).cos();
    }
    rippled
}

/// The quadrics are built about the mesh's centre, so a mesh far from the origin collapses as it
/// does at the origin: the same faces, the same stats, every vertex in place to 10⁻⁶ of the
/// mesh's size (translating the input rounds its positions to the ulp of the offset, 10⁻¹⁰ at
/// 10⁶). Built about the origin, the plane offsets d cancelled: at 10³ ten of 89 vertices moved
/// by more than that (up to 0.06), at 10⁶ the fold refusals went from 2 to 1,377.
#[test]
fn a_mesh_far_from_the_origin_collapses_as_it_does_at_the_origin() {
    let rippled = rippled_grid();
    let sorted = |out: &Simplified, offset: DVec3| {
        let mut v: Vec<[f64; 3]> = out
            .mesh
            .positions
            .iter()
            .map(|&p| (p - offset).to_array())
            .collect();
        v.sort_unstable_by(|a, b| {
            a.iter()
                .zip(b)
                .map(|(x, y)| x.total_cmp(y))
                .find(|o| o.is_ne())
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        v
    };
    let home = run(&rippled, 150, Weighting::Isotropic);
    let expected = sorted(&home, DVec3::ZERO);
    for offset in [1e3, 1e6] {
        let offset = DVec3::splat(offset);
        let mut moved = rippled.clone();
        for p in &mut moved.positions {
            *p += offset;
        }
        let out = run(&moved, 150, Weighting::Isotropic);
        let got = sorted(&out, offset);
        let far = got
            .iter()
            .zip(&expected)
            .filter(|(a, b)| (DVec3::from_array(**a) - DVec3::from_array(**b)).length() > 1e-6)
            .count();
        assert!(
            got.len() == expected.len() && far == 0,
            "at {offset}: {} vertices against {}, {far} off by more than 1e-6; stats {:?} against {:?}",
            got.len(),
            expected.len(),
            out.stats,
            home.stats
        );
        assert_eq!(out.mesh.triangles.len(), home.mesh.triangles.len());
        assert_eq!(out.stats, home.stats, "at {offset}");
    }
}

/// Coordinates near f64's limit stay finite through the quadrics and placements.
#[test]
fn huge_coordinates_stay_finite() {
    let mut mesh = grid(4);
    for p in &mut mesh.positions {
        *p *= 1e200;
    }
    let out = run(&mesh, 4, Weighting::Isotropic);
    assert!(out.mesh.positions.iter().all(|p| p.is_finite()));
}

/// eq. 4's motion direction is named by the error, not turned into NaN costs (infinite) or
/// isotropic weights (zero).
#[test]
fn a_motion_direction_that_is_not_finite_or_is_zero_is_refused() {
    for direction in [DVec3::new(f64::INFINITY, 0.0, 0.0), DVec3::ZERO] {
        let options = Options {
            target_faces: 8,
            weighting: Weighting::Direction(direction),
            limits: None,
        };
        let error = simplify(&grid(4), &options, (&[], 0), &mut |_| {}).unwrap_err();
        assert!(error.to_string().contains("direction"), "{error}");
    }
}

/// A cube written with each triangle's corners apart, each side its own colour (as exporters
/// split vertices at colour seams), moving too slowly for any collapse: welding for the
/// simplifier must not give one side's colour to the corners of the side next to it.
#[test]
fn a_slow_mesh_with_colour_seams_keeps_each_corner_colour() {
    let cube = Mesh::cuboid(DVec3::ONE);
    let mut split = Mesh::default();
    let mut colours = Vec::new();
    for t in &cube.triangles {
        let [a, b, c] = t.map(|v| cube.positions[v as usize]);
        let colour = ((b - a).cross(c - a).normalize() * 0.4 + 0.5)
            .as_vec3()
            .to_array();
        let base = split.positions.len() as u32;
        split.positions.extend([a, b, c]);
        split.triangles.push([base, base + 1, base + 2]);
        colours.extend([colour; 3]);
    }
    let triangles =
        TriangleMesh::from_parts(split.positions.clone(), split.triangles.clone(), colours)
            .unwrap();
    let surfels = from_mesh(&split, 600, false).unwrap();
    let camera = camera_from_z6();
    let at = |x: f64| Keyframe {
        t: (x + 0.005) / 0.01,
        pose: Pose {
            translation: DVec3::new(x, 0.0, 0.0),
            ..Pose::IDENTITY
        },
    };
    let motion = Motion::new(vec![at(-0.005), at(0.005)]).unwrap();
    let scene = Scene::new(camera).with_object(Object::triangles(
        "cube",
        triangles.clone(),
        surfels,
        motion,
    ));
    let plan = Plan::with_lod(&scene, &Method::ANALYTIC, Lod::Auto).unwrap();
    let drawn = plan.mesh_of(0).unwrap();
    let corner_colours = |m: &TriangleMesh| -> Vec<[f32; 3]> {
        m.triangles
            .iter()
            .flat_map(|t| t.map(|v| m.colours[v as usize]))
            .collect()
    };
    assert_eq!(drawn.triangles.len(), triangles.triangles.len());
    assert!(
        corner_colours(drawn) == corner_colours(&triangles),
        "{}",
        plan.explain(None)
    );
}
