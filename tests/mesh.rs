//! Meshes end to end: an icosphere written as OBJ or PLY, gzipped or not, read through a scene
//! and sampled into surfels, must render as a closed surface: coverage ≈ 1 everywhere inside its
//! silhouette, nothing outside it. The three cases cover the regimes of the sampler: many pieces
//! per triangle, about one and a half, and far fewer pieces than triangles (most join a piece).

use std::collections::HashMap;
use std::io::Write;
mod common;

use common::{least_coverage_inside_unit_sphere, UNIT_SPHERE_VIEW};
use glam::DVec3;
use streak::Scene;

/// A unit icosphere: the icosahedron with each triangle cut into four `subdivisions` times, new
/// vertices pushed out to the sphere; triangles wound counter-clockwise seen from outside.
fn icosphere(subdivisions: usize) -> (Vec<DVec3>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| DVec3::from_array(p).normalize())
    .collect();
    let mut triangles = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints = HashMap::new();
        let mut midpoint = |a: usize, b: usize, positions: &mut Vec<DVec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push((positions[a] + positions[b]).normalize());
                positions.len() - 1
            })
        };
        triangles = triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let ab = midpoint(a, b, &mut positions);
                let bc = midpoint(b, c, &mut positions);
                let ca = midpoint(c, a, &mut positions);
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    (positions, triangles)
}

fn obj_text(subdivisions: usize) -> Vec<u8> {
    let (positions, triangles) = icosphere(subdivisions);
    let mut text = String::from("# icosphere\n");
    for p in positions {
        text += &format!("v {} {} {}\nvn {} {} {}\n", p.x, p.y, p.z, p.x, p.y, p.z);
    }
    for [a, b, c] in triangles {
        text += &format!("f {0}//{0} {1}//{1} {2}//{2}\n", a + 1, b + 1, c + 1);
    }
    text.into_bytes()
}

fn ply_bytes(subdivisions: usize, binary: bool) -> Vec<u8> {
    let (positions, triangles) = icosphere(subdivisions);
    let format = if binary {
        "binary_little_endian"
    } else {
        "ascii"
    };
    let mut bytes = format!(
        "ply\nformat {format} 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        positions.len(),
        triangles.len()
    )
    .into_bytes();
    for p in positions {
        let xyz = p.as_vec3().to_array();
        if binary {
            bytes.extend(xyz.iter().flat_map(|v| v.to_le_bytes()));
        } else {
            bytes.extend(format!("{} {} {}\n", xyz[0], xyz[1], xyz[2]).into_bytes());
        }
    }
    for t in triangles {
        if binary {
            bytes.push(3);
            bytes.extend(t.iter().flat_map(|&i| (i as i32).to_le_bytes()));
        } else {
            bytes.extend(format!("3 {} {} {}\n", t[0], t[1], t[2]).into_bytes());
        }
    }
    bytes
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

/// The least coverage inside the silhouette of the mesh file `name` holding `bytes`, sampled
/// into `samples` surfels.
fn least_coverage(name: &str, bytes: &[u8], samples: usize) -> f32 {
    let dir = std::env::temp_dir().join(format!("streak-mesh-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join(name), bytes).unwrap();
    let scene_text = format!(
        r#"{UNIT_SPHERE_VIEW}
        [[object]]
        shape = {{ type = "mesh", path = "{name}", samples = {samples} }}
        colour = [1, 1, 1]
    "#
    );
    let scene = Scene::parse(&scene_text, &dir.join("scene.toml")).unwrap();
    assert_eq!(scene.surfel_count(), samples);
    least_coverage_inside_unit_sphere(&scene)
}

// Piece Gaussians add up to 1 within a few per cent (least coverage 0.968–0.992 on icospheres of
// 5,120 to 81,920 triangles with 3,000 to 100,000 samples); a hole would fail by far: points
// with A/N each and Gaussians twice as wide left dips to 0.60.

#[test]
fn many_pieces_per_triangle_cover_the_sphere() {
    // 1,280 triangles, about 78 pieces each.
    let worst = least_coverage("sphere.ply", &ply_bytes(3, false), 100_000);
    assert!(
        worst > 0.95,
        "least-covered pixel inside the silhouette: {worst}"
    );
}

#[test]
fn about_one_piece_per_triangle_covers_the_sphere() {
    // 20,480 triangles, 1.5 pieces each, from a gzipped OBJ with vertex normals.
    let worst = least_coverage("sphere.obj.gz", &gzip(&obj_text(5)), 30_000);
    assert!(
        worst > 0.95,
        "least-covered pixel inside the silhouette: {worst}"
    );
}

#[test]
fn triangles_joined_into_pieces_cover_the_sphere() {
    // 81,920 triangles and 10,000 pieces: most triangles join a piece.
    let worst = least_coverage("sphere.ply.gz", &gzip(&ply_bytes(6, true)), 10_000);
    assert!(
        worst > 0.95,
        "least-covered pixel inside the silhouette: {worst}"
    );
}

#[test]
fn mesh_mistakes_are_errors_naming_file_and_field() {
    let dir = std::env::temp_dir().join(format!("streak-mesh-errors-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("good.obj"), obj_text(0)).unwrap();
    std::fs::write(
        dir.join("nan.obj"),
        b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("index.obj"),
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
    )
    .unwrap();
    std::fs::write(dir.join("points.ply"), b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n").unwrap();
    let scene = |shape: &str, extra: &str| {
        format!("{UNIT_SPHERE_VIEW}\n[[object]]\nshape = {shape}\n{extra}\n")
    };
    let cases = [
        (
            scene(r#"{ type = "mesh", path = "good.obj", samples = 0 }"#, ""),
            "scene.toml: object[0].shape.samples",
        ),
        (
            scene(
                r#"{ type = "mesh", path = "good.obj", samples = 30000000 }"#,
                "",
            ),
            "scene.toml: object[0].shape.samples",
        ),
        (
            scene(
                r#"{ type = "mesh", path = "good.obj", samples = 100 }"#,
                "spacing = 0.1",
            ),
            "scene.toml: object[0].spacing",
        ),
        (
            scene(r#"{ type = "mesh", path = "good.obj" }"#, ""),
            "scene.toml: line",
        ),
        (
            scene(
                r#"{ type = "mesh", path = "good.obj", samples = 10, center = true }"#,
                "",
            ),
            "scene.toml: line",
        ),
        (
            scene(r#"{ type = "mesh", path = "nan.obj", samples = 100 }"#, ""),
            "nan.obj: line 2",
        ),
        (
            scene(
                r#"{ type = "mesh", path = "index.obj", samples = 100 }"#,
                "",
            ),
            "index.obj: line 4",
        ),
        (
            scene(
                r#"{ type = "mesh", path = "points.ply", samples = 100 }"#,
                "",
            ),
            "points.ply: element face",
        ),
        (
            scene(
                r#"{ type = "mesh", path = "missing.obj", samples = 100 }"#,
                "",
            ),
            "missing.obj",
        ),
    ];
    for (text, needle) in cases {
        let message = match Scene::parse(&text, &dir.join("scene.toml")) {
            Ok(_) => panic!("expected an error naming {needle}"),
            Err(error) => error.to_string(),
        };
        assert!(
            message.contains(needle),
            "`{message}` should contain `{needle}`"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
