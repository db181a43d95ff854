//! The sweep the level of detail's rule comes from (docs/math.md, "Level of detail"): `blur` and
//! `kernel3d` at 8 sub-frames, with full detail and with cells of several shares of the screen
//! path, each timed (median of 3, as a ratio to `static` in the same run) and measured against a
//! converged reference (RMSE, ꟻLIP) and against its own full-detail image (ꟻLIP).
//!
//! `cargo bench --bench lod_sweep -- [SCENE] [SIZE] [REFERENCE_SAMPLES]`, by default
//! `gallery/torus_knot.toml 512 256`. The reference is cached in `target/lod-sweep/`.

mod common;

use std::path::Path;
use std::time::Instant;

use streak::lod::Lod;
use streak::metrics::compare;
use streak::render::{Subframes, Visibility};
use streak::study::converged_reference;
use streak::{Framebuffer, Method, Plan, Scene};

const SHARES: [f64; 5] = [0.05, 0.1, 0.2, 0.3, 0.5];

fn timed(scene: &Scene, method: &Method, lod: Lod) -> streak::Result<(Framebuffer, f64, usize)> {
    let mut times = Vec::new();
    let mut image = None;
    let mut footprints = 0;
    for _ in 0..3 {
        let start = Instant::now();
        let render = Plan::with_lod(scene, method, lod)?.render(None);
        times.push(start.elapsed().as_secs_f64());
        footprints = render.stats.footprints;
        image = Some(render.image);
    }
    let (median, _) = common::median_and_min(&mut times);
    Ok((image.expect("three renders"), median, footprints))
}

fn main() -> streak::Result<()> {
    let arg = common::args();
    let scene_path = arg(0, "gallery/torus_knot.toml");
    let size: u32 = arg(1, "512").parse().expect("SIZE is a number of pixels");
    let samples: usize = arg(2, "256").parse().expect("REFERENCE_SAMPLES is a count");

    let (scene, height) = common::scene_at_width(&scene_path, size)?;
    let reference = converged_reference(&scene, samples, Path::new("target/lod-sweep"), None)?;
    let (_, base, _) = timed(&scene, &Method::STATIC, Lod::Off)?;
    println!(
        "{scene_path} at {size}×{height}; static (full detail) {base:.4} s; reference N={samples}"
    );
    println!(
        "| method | level of detail | × static | footprints | RMSE | ꟻLIP | ꟻLIP vs full detail |"
    );
    println!("|---|---|---|---|---|---|---|");
    let kernel3d = Method::Kernel3d {
        subframes: Subframes::Equal(8),
        visibility: Visibility::Exact,
    };
    for method in [Method::BLUR, kernel3d] {
        let (full, seconds, footprints) = timed(&scene, &method, Lod::Off)?;
        let error = compare(&full, &reference)?;
        println!(
            "| {} | off | {:.1} | {footprints} | {:.5} | {:.4} | 0 |",
            method.name(),
            seconds / base,
            error.rmse,
            error.flip
        );
        for share in SHARES {
            let (image, seconds, footprints) = timed(&scene, &method, Lod::Along(share))?;
            let error = compare(&image, &reference)?;
            let departure = compare(&image, &full)?;
            println!(
                "| {} | {share} of the path | {:.1} | {footprints} | {:.5} | {:.4} | {:.4} |",
                method.name(),
                seconds / base,
                error.rmse,
                error.flip,
                departure.flip
            );
        }
    }
    Ok(())
}
