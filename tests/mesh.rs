//! Meshes end to end: an icosphere written as OBJ or PLY, gzipped or not, read through a scene
//! and sampled into surfels, must render as a closed surface: coverage ≈ 1 everywhere inside its
//! silhouette, nothing outside it. The three cases cover the regimes of the sampler: many pieces
//! per triangle, about one and a half, and far fewer pieces than triangles (most join a piece).

use std::io::Write;
mod common;

use common::{icosphere, least_coverage_inside_unit_sphere, OPAQUE, UNIT_SPHERE_VIEW};
use streak::{Method, Scene};

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
    least_coverage_inside_unit_sphere(&scene, &Method::STATIC)
}

// Piece Gaussians add up to 1 within a few per cent (least sums 0.968–0.992 on icospheres of
// 5,120 to 81,920 triangles with 3,000 to 100,000 samples), and sums from 0.94 up are opaque
// (`streak::render::opacity`); a hole would fail by far: points with A/N each and Gaussians
// twice as wide left dips to 0.60.

#[test]
fn many_pieces_per_triangle_cover_the_sphere() {
    // 1,280 triangles, about 78 pieces each.
    let worst = least_coverage("sphere.ply", &ply_bytes(3, false), 100_000);
    assert!(
        worst >= OPAQUE,
        "least-covered pixel inside the silhouette: {worst}"
    );
}

#[test]
fn about_one_piece_per_triangle_covers_the_sphere() {
    // 20,480 triangles, 1.5 pieces each, from a gzipped OBJ with vertex normals.
    let worst = least_coverage("sphere.obj.gz", &gzip(&obj_text(5)), 30_000);
    assert!(
        worst >= OPAQUE,
        "least-covered pixel inside the silhouette: {worst}"
    );
}

#[test]
fn triangles_joined_into_pieces_cover_the_sphere() {
    // 81,920 triangles and 10,000 pieces: most triangles join a piece.
    let worst = least_coverage("sphere.ply.gz", &gzip(&ply_bytes(6, true)), 10_000);
    assert!(
        worst >= OPAQUE,
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

#[test]
fn a_gz_suffix_in_capitals_is_gunzipped_too() {
    // Formats are named ignoring case, and so is `.gz`: `SPHERE.OBJ.GZ` reads as its lower-case
    // twin (its bytes were once parsed as OBJ text without being gunzipped: no faces).
    let worst = least_coverage("SPHERE.OBJ.GZ", &gzip(&obj_text(5)), 30_000);
    assert!(
        worst >= OPAQUE,
        "least-covered pixel inside the silhouette: {worst}"
    );
}
