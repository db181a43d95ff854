//! What the benchmarks share: their command line and their scene.

use std::path::Path;
use streak::Scene;

/// The benchmark's own arguments (`cargo bench` passes `--bench`; everything else is ours), read
/// positionally: `arg(i, default)`.
pub fn args() -> impl Fn(usize, &str) -> String {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    move |i, default| args.get(i).cloned().unwrap_or_else(|| default.into())
}

/// The scene at `path`, `width` pixels wide with its aspect ratio (and vertical field of view)
/// kept; returns it and its height.
#[allow(dead_code)] // Not every benchmark loads a gallery scene.
pub fn scene_at_width(path: &str, width: u32) -> streak::Result<(Scene, u32)> {
    let mut scene = Scene::load(Path::new(path))?;
    let (w, h) = (scene.camera.width, scene.camera.height);
    let height = (u64::from(width) * u64::from(h) / u64::from(w)).max(1) as u32;
    scene.camera = scene.camera.resized(width, height)?;
    Ok((scene, height))
}

/// The median and the least of `times`, which are sorted in place.
pub fn median_and_min(times: &mut [f64]) -> (f64, f64) {
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], times[0])
}
