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
    // The orange knot is drawn on white, so its blue channel tells how solid it looks. Of the
    // pixels it touches (blue below 250), the share where it is solid (below 100, near the blue
    // of its shaded orange): sharp at the flash, the hint's knot is solid over much of its
    // footprint (measured 39 %); smeared over the exposure, the blur's only where the tube
    // covers a pixel most of the time (7 %).
    let solid_share = |image: &image::RgbImage| {
        let touched = image.pixels().filter(|p| p[2] < 250).count();
        let solid = image.pixels().filter(|p| p[2] < 100).count();
        solid as f64 / touched.max(1) as f64
    };
    let (blurred, sharp) = (solid_share(&blur), solid_share(&hint));
    assert!(sharp > 0.25, "hint {sharp}");
    assert!(sharp > 3.0 * blurred, "blur {blurred} vs hint {sharp}");
}
