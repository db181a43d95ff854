//! Point clouds end to end: a PLY file without normals or radii, read through a scene, must
//! render as a closed surface: coverage ≈ 1 everywhere inside its silhouette.

use glam::DVec3;
use streak::io::ply::write_ply;
use streak::surfels::PointCloud;
mod common;

use common::{least_coverage_inside_unit_sphere, UNIT_SPHERE_VIEW};
use streak::Scene;

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
    let scene_text = format!(
        r#"{UNIT_SPHERE_VIEW}
        [[object]]
        shape = {{ type = "ply", path = "sphere.ply" }}
        colour = [1, 1, 1]
    "#
    );
    let scene = Scene::parse(&scene_text, &dir.join("scene.toml")).unwrap();
    let worst = least_coverage_inside_unit_sphere(&scene);
    // Splats are drawn at full opacity once their weights sum past 1; a hole would show as a dip.
    assert!(
        worst > 0.98,
        "least-covered pixel inside the silhouette: {worst}"
    );
}
