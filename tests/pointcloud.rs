//! Point clouds end to end: a PLY file without normals or radii, read through a scene, must
//! render as a closed surface: coverage ≈ 1 everywhere inside its silhouette.

use streak::io::ply::write_ply;
use streak::surfels::PointCloud;
mod common;

use common::{fibonacci_sphere, least_coverage_inside_unit_sphere, OPAQUE, UNIT_SPHERE_VIEW};
use streak::{Method, Scene};

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
    let worst = least_coverage_inside_unit_sphere(&scene, &Method::STATIC);
    // The splats' weights sum to 0.986–1.0 here, opaque from 0.94 up (`streak::render::opacity`);
    // a hole would show as a dip.
    assert!(
        worst >= OPAQUE,
        "least-covered pixel inside the silhouette: {worst}"
    );
}

#[test]
fn a_cloud_declaring_more_points_than_the_budget_is_refused_before_its_points_are_read() {
    // The header says 20 million points and the body holds three: the budget is checked against
    // what the header declares, before memory is spent on the points (once the whole body was
    // parsed first, 540 MB for such a file of 60 MB).
    let dir = std::env::temp_dir().join(format!("streak-cloud-budget-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let header = "ply\nformat ascii 1.0\nelement vertex 20000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    std::fs::write(
        dir.join("huge.ply"),
        format!("{header}0 0 0\n1 0 0\n0 1 0\n"),
    )
    .unwrap();
    let scene_text = format!(
        r#"{UNIT_SPHERE_VIEW}
        [[object]]
        shape = {{ type = "ply", path = "huge.ply" }}
    "#
    );
    let budget = streak::surfels::Budget::new(1000).unwrap();
    let error = Scene::parse_within(&scene_text, &dir.join("scene.toml"), budget)
        .expect_err("a cloud over the budget")
        .to_string();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        error.contains("huge.ply")
            && error.contains("element vertex")
            && error.contains("20000000 points")
            && error.contains("budget of 1000"),
        "{error}"
    );
}
