//! The rasterizer's throughput: a gallery scene rendered repeatedly by one method at a chosen
//! size, reporting the median wall time and surfels per second (the figure issue 10 targets:
//! `static` on the torus knot at 1024² on 2 threads).
//!
//! `cargo bench --bench raster -- [SCENE] [METHOD] [SIZE] [REPEATS] [LOD]`, by default
//! `gallery/torus_knot.toml static 1024 9 auto` (`LOD` is `auto` or `off`). Threads: `RAYON_NUM_THREADS`. Methods: `static`,
//! `blur`, `kernel3d`, `analytic` (its default tolerance, or `analytic:PX`), `reference:N`.
//! Profile it with
//! `perf record -g target/release/deps/raster-* gallery/torus_knot.toml static 1024 40`.

mod common;

use std::time::Instant;

use streak::lod::Lod;
use streak::{Method, Plan};

fn main() -> streak::Result<()> {
    let arg = common::args();
    let scene_path = arg(0, "gallery/torus_knot.toml");
    let method = match arg(1, "static").as_str() {
        "static" => Method::STATIC,
        "blur" => Method::BLUR,
        "kernel3d" => Method::KERNEL3D,
        "analytic" => Method::ANALYTIC,
        other => match (
            other.strip_prefix("reference:").map(str::parse),
            other.strip_prefix("analytic:").map(str::parse),
        ) {
            (Some(Ok(samples)), _) => Method::Reference { samples },
            (_, Some(Ok(tolerance_px))) => Method::Analytic {
                tolerance_px,
                receivers: streak::render::Receivers::Sampled,
            },
            _ => panic!(
                "unknown method {other}: static, blur, kernel3d, analytic, analytic:TOLERANCE_PX or reference:N"
            ),
        },
    };
    let size: u32 = arg(2, "1024").parse().expect("SIZE is a number of pixels");
    let repeats: usize = arg(3, "9").parse().expect("REPEATS is a count");
    let lod = match arg(4, "auto").as_str() {
        "auto" => Lod::Auto,
        "off" => Lod::Off,
        other => panic!("unknown LOD {other}: auto or off"),
    };

    let (scene, height) = common::scene_at_width(&scene_path, size)?;
    let surfels = scene.surfel_count();

    let mut times = Vec::with_capacity(repeats);
    let mut footprints = 0;
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        let render = Plan::with_lod(&scene, &method, lod)?.render(None);
        times.push(start.elapsed().as_secs_f64());
        footprints = render.stats.footprints;
    }
    let (median, min) = common::median_and_min(&mut times);
    println!(
        "{} {} (LOD {lod:?}) at {size}×{height}, {} thread(s): median {:.4} s of {} (min {:.4} s), {surfels} surfels → {footprints} footprints, {:.2} M surfels/s",
        scene_path,
        method.name(),
        rayon::current_num_threads(),
        median,
        times.len(),
        min,
        surfels as f64 / median / 1e6
    );
    Ok(())
}
