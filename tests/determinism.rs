//! The same scene and options give the same image bits whatever the thread count.

use std::path::Path;
use std::sync::Arc;
use streak::render::Visibility;
use streak::style::Style;
use streak::{render, Method, Scene, Subframes};

fn render_with_threads(scene: &Scene, method: &Method, threads: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let image = render(scene, method, None).unwrap().image;
        image
            .pixels
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect()
    })
}

/// Render with `method` on 1, 2 and 5 threads and check the bits agree.
fn assert_thread_count_independent(scene: &Scene, method: &Method) {
    let one = render_with_threads(scene, method, 1);
    assert!(one.iter().any(|&b| b != 0));
    for threads in [2, 5] {
        assert!(
            one == render_with_threads(scene, method, threads),
            "{method:?} differs with {threads} threads",
        );
    }
}

fn gallery_scene(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("gallery")
        .join(name);
    let mut scene = Scene::load(&path).unwrap();
    scene.camera = scene.camera.resized(160, 120).unwrap();
    scene
}

#[test]
fn images_are_bit_identical_for_one_two_and_five_threads() {
    let scene = gallery_scene("torus_knot.toml");
    let styles = Path::new(env!("CARGO_MANIFEST_DIR")).join("styles");
    // Hints with a texture image, speed lines, and stroboscopic copies merged by depth.
    let hint = |name: &str| Method::Hint {
        style: Arc::new(Style::load(&styles.join(name)).unwrap()),
        tolerance_px: 1.0,
    };
    let methods = [
        Method::STATIC,
        Method::BLUR,
        Method::Reference { samples: 4 },
        hint("brush.toml"),
        hint("ink-lines.toml"),
        hint("stroboscopic.toml"),
    ];
    for method in &methods {
        assert_thread_count_independent(&scene, method);
    }
    // The kernels: on the knot, whose sub-pixel surfels at 160×120 fill some pixels' lists to
    // the cap (715 pixels merged, `--explain`), and both ways of resolving on a lighter scene.
    let kernels = |visibility| Method::Kernel3d {
        subframes: Subframes::Planned { tolerance_px: 1.0 },
        visibility,
    };
    assert_thread_count_independent(&scene, &kernels(Visibility::Exact));
    let scene = gallery_scene("rod_rotating.toml");
    for visibility in [Visibility::Exact, Visibility::Approximate] {
        assert_thread_count_independent(&scene, &kernels(visibility));
    }
}
