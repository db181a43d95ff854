//! Point clouds end to end: a PLY file without normals or radii, read through a scene, must
//! render as a closed surface: coverage ≈ 1 everywhere inside its silhouette.

use glam::DVec3;
use streak::pointcloud::{write_ply, PointCloud};
use streak::{render, Method, Plan, Scene, Settings};

/// `count` points on the unit sphere along a Fibonacci spiral.
fn fibonacci_sphere(count: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / count as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), z, r * phi.sin())
        })
        .collect()
}

#[test]
fn an_estimated_point_cloud_covers_its_silhouette_without_holes() {
    let dir = std::env::temp_dir().join(format!("streak-cloud-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cloud = PointCloud {
        positions: fibonacci_sphere(30_000),
        ..PointCloud::default()
    };
    let mut file = std::fs::File::create(dir.join("sphere.ply")).unwrap();
    write_ply(&cloud, true, &mut file).unwrap();
    drop(file);
    let scene_text = r#"
        background = [0, 0, 0]
        [camera]
        eye = [0, 0, 4]
        target = [0, 0, 0]
        fov_y = 35
        width = 160
        height = 160
        [[object]]
        shape = { type = "ply", path = "sphere.ply" }
        colour = [1, 1, 1]
    "#;
    let scene = Scene::parse(scene_text, &dir.join("scene.toml")).unwrap();
    let settings = Settings {
        method: Method::Static,
        ..Settings::default()
    };
    let image = render(&scene, &Plan::new(&scene, 1.0), &settings, None).image;

    // The sphere's silhouette: radius r_px = f·tan(asin(1/4)) around the centre. Every pixel
    // centre more than 2 px inside it must be covered; white on black makes coverage the value.
    let f = scene.camera.focal_px;
    let radius_px = f * (1.0f64 / 4.0).asin().tan();
    let (mut inside, mut worst) = (0, 1.0f32);
    for y in 0..160u32 {
        for x in 0..160u32 {
            let d = ((x as f64 + 0.5 - 80.0).powi(2) + (y as f64 + 0.5 - 80.0).powi(2)).sqrt();
            if d < radius_px - 2.0 {
                inside += 1;
                worst = worst.min(image.pixels[(y * 160 + x) as usize][0]);
            } else if d > radius_px + 3.0 {
                assert!(
                    image.pixels[(y * 160 + x) as usize][0] < 0.01,
                    "coverage outside the silhouette at ({x}, {y})"
                );
            }
        }
    }
    assert!(inside > 10_000);
    // Splats are drawn at full opacity once their weights sum past 1; a hole would show as a dip.
    assert!(
        worst > 0.98,
        "least-covered pixel inside the silhouette: {worst}"
    );
}
