//! The example in `examples/` builds a scene in code and renders it; here it runs as a user would
//! run it, and its pictures are checked: the hint's knot is sharp where the blur's is smeared.

#[path = "../examples/moving_knot.rs"]
#[allow(dead_code)] // its `main` is the example's entry point, not called here
mod moving_knot;

#[test]
fn the_example_renders_a_blur_and_a_hint() {
    let folder = std::env::temp_dir().join(format!("streak-example-{}", std::process::id()));
    let files = moving_knot::draw(&folder).unwrap();
    assert_eq!(files.len(), 2);
    let [blur, hint] = [&files[0], &files[1]].map(|file| image::open(file).unwrap().to_rgb8());
    std::fs::remove_dir_all(&folder).unwrap();
    assert_eq!(blur.dimensions(), (320, 200));
    // The orange knot is drawn on white, so its blue channel tells how solid it looks: sharp at
    // the flash it is opaque (blue near that of its shaded orange), smeared over the exposure
    // nowhere near.
    let least_blue = |image: &image::RgbImage| image.pixels().map(|p| p[2]).min().unwrap();
    assert!(least_blue(&hint) < 100, "hint {}", least_blue(&hint));
    assert!(
        least_blue(&blur) > least_blue(&hint) + 40,
        "blur {} vs hint {}",
        least_blue(&blur),
        least_blue(&hint)
    );
}
