//! The same scene and options give the same image bits whatever the thread count.

use std::path::Path;
use streak::{render, Method, Plan, Scene, Settings};

fn render_with_threads(scene: &Scene, method: Method, threads: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let plan = Plan::new(scene, 1.0);
        let settings = Settings {
            method,
            time: None,
            samples: 4,
        };
        let image = render(scene, &plan, &settings, None).image;
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
    for method in [Method::Static, Method::Blur, Method::Reference] {
        let one = render_with_threads(&scene, method, 1);
        assert!(one.iter().any(|&b| b != 0));
        for threads in [2, 5] {
            assert!(
                one == render_with_threads(&scene, method, threads),
                "{method:?} differs with {threads} threads"
            );
        }
    }
}
