//! The same scene and options give the same image bits whatever the thread count.

use std::path::Path;
use std::sync::Arc;
use streak::render::Visibility;
use streak::style::Style;
use streak::{render, Method, Plan, Scene, Settings};

fn render_with_threads(scene: &Scene, settings: &Settings, threads: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let plan = Plan::new(scene, 1.0);
        let image = render(scene, &plan, settings, None).image;
        image
            .pixels
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect()
    })
}

#[test]
fn images_are_bit_identical_for_one_two_and_five_threads() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("gallery/torus_knot.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.camera = scene.camera.resized(160, 120);
    let styles = Path::new(env!("CARGO_MANIFEST_DIR")).join("styles");
    // Hints with a texture image, speed lines, and stroboscopic copies merged by depth.
    let hint = |name: &str| Settings {
        method: Method::Hint,
        style: Some(Arc::new(Style::load(&styles.join(name)).unwrap())),
        ..Settings::default()
    };
    let settings = [
        Settings {
            method: Method::Static,
            ..Settings::default()
        },
        Settings {
            method: Method::Blur,
            ..Settings::default()
        },
        Settings {
            method: Method::Reference,
            samples: 4,
            ..Settings::default()
        },
        hint("brush.toml"),
        hint("ink-lines.toml"),
        hint("stroboscopic.toml"),
        Settings {
            method: Method::Kernel3d,
            subframes: Some(1),
            ..Settings::default()
        },
        Settings {
            method: Method::Kernel3d,
            subframes: Some(1),
            visibility: Visibility::Approximate,
            ..Settings::default()
        },
    ];
    for settings in &settings {
        let one = render_with_threads(&scene, settings, 1);
        assert!(one.iter().any(|&b| b != 0));
        for threads in [2, 5] {
            assert!(
                one == render_with_threads(&scene, settings, threads),
                "{:?} {:?} differs with {threads} threads",
                settings.method,
                settings.style.as_ref().map(|s| s.name())
            );
        }
    }
}
