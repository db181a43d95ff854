//! Stiff and extreme cases (docs/conventions.md, "Stiff and extreme cases"): on each one every splat renderer draws a finite picture
//! with bounded work, and the picture is the right one. Expectations that differ between methods
//! are small functions of the method, so that a new renderer joins every case by one line in
//! [`METHODS`]. NaN and infinite numbers in input files are `tests/cli.rs`'s.

mod common;

use common::*;
use glam::{DQuat, DVec3};
use streak::lod::Lod;
use streak::plan::{ObjectMotion, SegmentCap, MAX_MOTION_FOOTPRINTS, MAX_SEGMENTS_PER_INTERVAL};
use streak::render::{
    MAX_FRAGMENTS_PER_PIXEL, MAX_SUBFRAMES, PREFILTER_VARIANCE_PX2, TILE_PX, TRUNCATION_GAIN,
};
use streak::scene::shutter::MIN_EXPOSURE;
use streak::scene::{Camera, Pose};
use streak::scene::{Shutter, ShutterShape};
use streak::surfels::Surfel;
use streak::{Framebuffer, Method, Plan, Render, Scene};

/// Every splat renderer; each case runs all of them.
const METHODS: &[Kind] = &[
    Kind::Static,
    Kind::Blur,
    Kind::Reference,
    Kind::Hint,
    Kind::Kernel3d,
    Kind::Kernel3dApproximate,
];

/// Frames of the reference in [`METHODS`]: few, as a user in a hurry would ask for. A power of
/// two, so that a box shutter's strata weigh exactly 1/32 and a background passes through the
/// weighted sum unchanged.
const SAMPLES: usize = 32;

/// Frames of the converged reference that the other methods are compared to.
const CONVERGED: usize = 512;

/// Least coverage of a pixel well inside a dense, still surface: opaque (`streak::render::opacity`
/// counts summed weights from 0.94 up as full; they dip to 0.99 here where pixel centres lie just
/// beyond the 3σ cut-off of some footprints).
const DENSE_COVERAGE: f64 = 0.999;

/// How many times the energy of a faint moving splat appears in `method`'s picture: `hint` draws
/// it sharp at the flash and again in the trail under it; the others once.
fn exposures(method: Kind) -> f64 {
    if method == Kind::Hint {
        2.0
    } else {
        1.0
    }
}

/// Largest RMSE and largest pixel error allowed against [`expected`] for a surface sliding within
/// its own plane. The reference's 32 frames of a ≤ 54 px path are ≤ 1.7 px apart, and each frame
/// is a soft-edged surface: measured 8e-5 and 1.5e-3. Blur's ellipses are Gaussians standing for
/// flat-topped streaks (τ = 1 px allows sub-segments of 32 px), which is Guan & Mueller's
/// approximation: measured 0.013 and 0.08, at the streak's ends; hint's trail is the same.
fn sliding_error(method: Kind) -> [f64; 2] {
    match method {
        Kind::Static => [0.0, 0.0],
        Kind::Reference => [1e-3, 5e-3],
        _ => [0.015, 0.1],
    }
}

/// Most footprints `method` may make for `plan` with `samples` reference frames: one per surfel
/// for an instant (static, each reference frame), one per surfel and sub-segment for a motion
/// renderer, and the hint's sharp object on top of its trail.
fn footprint_bound(method: Kind, plan: &Plan, samples: usize) -> usize {
    let surfels: usize = plan.objects.iter().map(|o| o.surfels).sum();
    let pieces: usize = plan
        .objects
        .iter()
        .map(|o| match &o.motion {
            ObjectMotion::Still | ObjectMotion::Instants { .. } => o.surfels,
            ObjectMotion::Moving { segments, .. } => o.surfels * segments.len(),
        })
        .sum();
    match method {
        Kind::Static => surfels,
        Kind::Reference => surfels * samples,
        Kind::Hint => surfels + pieces,
        _ => pieces,
    }
}

/// Render with `samples` reference frames, asserting what every case asks of every method: no
/// NaN or infinity in any pixel, and no more footprints than [`footprint_bound`].
fn run_with(scene: &Scene, method: Kind, samples: usize) -> Render {
    run_with_lod(scene, method, samples, Lod::Auto)
}

fn run_with_lod(scene: &Scene, method: Kind, samples: usize, lod: Lod) -> Render {
    let plan = Plan::with_lod(scene, &method.method(samples), lod).unwrap();
    let out = plan.render(None);
    let name = plan.method().name();
    assert!(
        out.image.pixels.iter().flatten().all(|c| c.is_finite()),
        "{name}: a pixel is not finite"
    );
    let bound = footprint_bound(method, &plan, samples);
    assert!(
        out.stats.footprints <= bound,
        "{name}: {} footprints, more than {bound}",
        out.stats.footprints
    );
    out
}

fn run(scene: &Scene, method: Kind) -> Render {
    run_with(scene, method, SAMPLES)
}

/// The shutter average that the methods which average time approach.
fn converged(scene: &Scene) -> Framebuffer {
    run_with(scene, Kind::Reference, CONVERGED).image
}

/// What `method` should draw of white surfels on black (where a pixel's value is its coverage),
/// given the converged shutter average `average`: `static` the frame at mid-exposure; `hint` its
/// sharp frame at the flash (the end of the exposure) over the default trail, which spans the
/// whole exposure and so is the average, but starts only from points seen at the flash (in
/// front of the camera and facing it; Guan & Mueller's hints are of the visible points); every
/// other method the average.
fn expected(method: Kind, scene: &Scene, average: &Framebuffer) -> Vec<f64> {
    match method {
        Kind::Static => red(&sharp(scene, scene.shutter.middle()).image),
        Kind::Hint => {
            let flash = sharp(scene, scene.shutter.close);
            let unseen = flash.stats.culled.behind_near + flash.stats.culled.back_facing;
            assert!(
                unseen == 0 || unseen == scene.surfel_count(),
                "the scenes here have all or no points seen at the flash"
            );
            let trail = if unseen == 0 {
                red(average)
            } else {
                vec![0.0; average.pixels.len()]
            };
            red(&flash.image)
                .iter()
                .zip(trail)
                .map(|(s, a)| s + (1.0 - s) * a)
                .collect()
        }
        _ => red(average),
    }
}

/// Largest |a − b| over pixels.
fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn rms_difference(a: &[f64], b: &[f64]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
}

/// Whether every pixel is exactly `background`.
fn is_background(image: &Framebuffer, background: [f32; 3]) -> bool {
    image.pixels.iter().all(|p| *p == background)
}

/// Tiles of a `width`×`height` image.
fn tiles(width: u32, height: u32) -> usize {
    (width.div_ceil(TILE_PX) * height.div_ceil(TILE_PX)) as usize
}

/// A white square `size` world units wide, surfels `spacing` apart, facing the camera from the
/// plane z = `z`.
fn square(size: f64, spacing: f64, z: f64) -> Vec<Surfel> {
    patch(DVec3::new(0.0, 0.0, z), [size, size], spacing, false)
}

/// A translation from `from` to `to` over the exposure, turned by `rotation` throughout.
fn sliding(rotation: DQuat, from: DVec3, to: DVec3) -> streak::scene::Motion {
    let at = |translation| Pose {
        translation,
        rotation,
        scale: 1.0,
    };
    motion(&[(0.0, at(from)), (1.0, at(to))])
}

/// Value of pixel (x, y) in the red channel `values` of a `width`-wide image.
fn at(values: &[f64], width: u32, x: u32, y: u32) -> f64 {
    values[(y * width + x) as usize]
}

/// The brightness-weighted centroid of the red channel.
fn centroid(image: &Framebuffer) -> [f64; 2] {
    let (mut sum, mut mx, mut my) = (0.0, 0.0, 0.0);
    for y in 0..image.height {
        for x in 0..image.width {
            let v = f64::from(image.pixels[(y * image.width + x) as usize][0]);
            sum += v;
            mx += v * (f64::from(x) + 0.5);
            my += v * (f64::from(y) + 0.5);
        }
    }
    [mx / sum, my / sum]
}

/// The cases, in a module of their own so that `cargo test --release stiff` runs them all.
mod stiff {
    use super::*;

    #[test]
    fn zero_motion_draws_the_static_image() {
        let camera = camera(64, 64);
        let mut surfels = square(2.0, 0.05, 0.0);
        surfels.extend(
            (0..20).map(|i| facing_surfel(DVec3::new(-2.0 + 0.2 * f64::from(i), 1.8, 0.3), 0.06)),
        );
        let still_scene = scene(camera.clone(), vec![object(surfels.clone(), still())]);
        let sharp = red(&sharp(&still_scene, 0.5).image);
        // Keyframes 1e-9 units apart: the plan sees motion, so every motion path runs.
        let barely = linear(DVec3::ZERO, DVec3::new(1e-9, 0.0, 0.0));
        let barely_scene = scene(camera, vec![object(surfels, barely)]);
        assert!(Plan::new(&barely_scene, &Method::BLUR)
            .unwrap()
            .any_moving());
        for &method in METHODS {
            let name = method.name();
            // 1e-5: far below one 8-bit step. Only f32 rounding may differ: the reference's weighted
            // sum of equal frames, the hint's layer opacity (1 − (1 − T)), blur's time bins
            // (measured 5e-7).
            let image = red(&run(&still_scene, method).image);
            let error = max_difference(&image, &sharp);
            assert!(error < 1e-5, "{name}: still, {error}");
            // Barely moving, the limit of every motion path is the static image too; the hint's
            // trail is that image again, under its sharp object: s + (1 − s)·s.
            let image = red(&run(&barely_scene, method).image);
            let expected: Vec<f64> = sharp
                .iter()
                .map(|&s| s + (exposures(method) - 1.0) * (1.0 - s) * s)
                .collect();
            let error = max_difference(&image, &expected);
            assert!(error < 1e-5, "{name}: barely moving, {error}");
        }
    }

    #[test]
    fn very_short_shutters_of_every_shape_draw_the_instant() {
        // A square sliding 2 units over the frame, seen through a shutter open for the least
        // exposure a scene may ask, 10⁻⁹ of it: it moves 10⁻⁹ units while the shutter is open, so
        // every method draws the instant (the hint its sharp frame over a trail of that frame).
        // Blur once stored absolute times in f32, where the whole exposure fell into one of its
        // 32 time bins and the square came out at a 32nd of its opacity; shorter shutters, near
        // 10⁻¹³, darkened the reference, and are refused.
        let camera = camera(64, 64);
        let path = linear(DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0));
        let mut moving = scene(camera, vec![object(square(1.5, 0.05, 0.0), path)]);
        for shape in [
            ShutterShape::Box,
            ShutterShape::Tent,
            ShutterShape::Gaussian,
        ] {
            moving.shutter = Shutter::new(0.5, 0.5 + MIN_EXPOSURE, shape).unwrap();
            let instant = red(&sharp(&moving, 0.5).image);
            for &method in METHODS {
                let name = method.name();
                let image = red(&run(&moving, method).image);
                let expected: Vec<f64> = instant
                    .iter()
                    .map(|&s| s + (exposures(method) - 1.0) * (1.0 - s) * s)
                    .collect();
                let error = max_difference(&image, &expected);
                assert!(error < 1e-4, "{name}, {shape:?} shutter: {error}");
            }
        }
    }

    #[test]
    fn a_hundred_turn_spin_keeps_kernel3d_within_its_caps_and_draws_the_average() {
        // A bar spinning about the view axis through 100 turns, keyframes 90° apart: its path
        // asks for 1,200 sub-frames, more than kernel3d may cut the exposure into (it once took
        // them all, 4.6 GB for such a scene), so the plan cuts it into as many equal ones as
        // kernel3d draws (they hold the tolerance here: deviation 0.83 px). Every method draws
        // the time average: a disc.
        let camera = camera(64, 64);
        let keys: Vec<(f64, Pose)> = (0..=400)
            .map(|i| {
                let rotation = DQuat::from_rotation_z(f64::from(i) * 90f64.to_radians());
                let pose = Pose {
                    rotation,
                    ..Pose::IDENTITY
                };
                (f64::from(i) / 400.0, pose)
            })
            .collect();
        let bar = patch(DVec3::ZERO, [3.0, 0.3], 0.05, false);
        let spinning = scene(camera, vec![object(bar, motion(&keys))]);
        let average = red(&converged(&spinning));
        for &method in METHODS {
            let name = method.name();
            let out = run(&spinning, method);
            if let Some(k) = out.stats.kernel3d() {
                assert_eq!(k.subframes, MAX_SUBFRAMES, "{name}");
                let plan = Plan::new(&spinning, &Method::KERNEL3D).unwrap();
                assert!(
                    matches!(
                        &plan.objects[0].motion,
                        ObjectMotion::Moving { segments, .. } if segments.len() == MAX_SUBFRAMES
                    ),
                    "{}",
                    plan.explain(None)
                );
                assert!(
                    k.peak_kernels <= streak::render::MAX_KERNELS_PER_PASS,
                    "{k:?}"
                );
            }
            // The static and hint frames are a bar, not the average; the reference's 32 frames
            // fall 3⅛ turns apart, 8 bars 45° apart (RMSE 0.044).
            if matches!(method, Kind::Blur | Kind::Kernel3d) {
                // Measured 0.0016 (blur) and 0.0045 (kernel3d).
                let error = rms_difference(&red(&out.image), &average);
                assert!(
                    error < 0.01,
                    "{name}: RMSE {error} against the time average"
                );
            }
        }
    }

    /// What the plan for `method` makes of a square of 2,500 surfels at x = `x(i)` at each of
    /// 10,000 keyframes (the most an object may have): the object's share of the motion
    /// footprints, its sub-segments and cap, and what `--explain` and the notes say.
    fn square_through_ten_thousand_keyframes(
        method: &Method,
        x: impl Fn(u32) -> f64,
    ) -> (usize, usize, Option<SegmentCap>, String, Vec<String>) {
        let keys: Vec<(f64, Pose)> = (0..10_000)
            .map(|i| {
                (
                    f64::from(i) / 9_999.0,
                    pose(DVec3::new(x(i), 0.0, 0.0), 0.0),
                )
            })
            .collect();
        let square = patch(DVec3::ZERO, [2.0, 2.0], 0.04, false);
        let share = MAX_MOTION_FOOTPRINTS / square.len();
        let scene = scene(camera(64, 64), vec![object(square, motion(&keys))]);
        let plan = Plan::new(&scene, method).unwrap();
        let (segments, capped) = match &plan.objects[0].motion {
            ObjectMotion::Moving {
                segments, capped, ..
            } => (segments.len(), *capped),
            ObjectMotion::Instants { .. } => (0, None),
            ObjectMotion::Still => panic!("the square moves"),
        };
        (
            share,
            segments,
            capped,
            plan.explain(None),
            plan.departures(),
        )
    }

    #[test]
    fn ten_thousand_keyframes_keep_the_motion_footprints_within_their_budget() {
        // The square zigzagging: one sub-segment per keyframe interval would already be 2.5·10⁷
        // motion ellipses. The plan cuts the exposure into the object's share of the budget
        // instead, and says so.
        let (share, segments, capped, explain, departures) =
            square_through_ten_thousand_keyframes(&Method::BLUR, |i| {
                if i % 2 == 0 {
                    -0.5
                } else {
                    0.5
                }
            });
        assert_eq!(capped, Some(SegmentCap::Footprints(share)));
        assert_eq!(segments, share);
        assert!(explain.contains("motion footprints"));
        assert!(departures[0].contains("its share of the scene's"));
        // Each keyframe interval is straight, but the equal pieces of the cap are not the
        // streaks as long as the path allows that it would otherwise be.
        assert!(!explain.contains("as long as the path allows"));
    }

    #[test]
    fn equal_sub_segments_that_hold_the_tolerance_are_not_called_capped() {
        // The square sliding straight and uniformly: one sub-segment per interval passes its
        // share of the footprints, but equal sub-segments over the exposure follow a straight
        // uniform path exactly, so nothing is given up and nothing is said.
        let (share, segments, capped, _, departures) =
            square_through_ten_thousand_keyframes(&Method::BLUR, |i| f64::from(i) / 9_999.0 - 0.5);
        assert_eq!((segments, capped), (share, None));
        assert!(departures.is_empty(), "{departures:?}");
        // The same slide 10⁵ times as long: its equal pieces are longer than the 32 tolerances
        // a streak that changes along it may be, but nothing changes along these, as in each
        // keyframe interval: still not capped.
        let (share, segments, capped, explain, departures) =
            square_through_ten_thousand_keyframes(&Method::BLUR, |i| {
                (f64::from(i) / 9_999.0 - 0.5) * 1e5
            });
        assert_eq!((segments, capped), (share, None), "{explain}");
        assert!(departures.is_empty(), "{departures:?}");
        let longest: f64 = explain
            .split("longest ")
            .nth(1)
            .and_then(|rest| rest.split(" px").next())
            .and_then(|number| number.parse().ok())
            .unwrap();
        assert!(longest > 32.0, "{explain}");
        // Out and back, drawn as motion ellipses (a hint's disc-shaped trail), whose error is the
        // distance from the chord: the turn at keyframe 5,241 falls 1/16 into an equal piece of
        // about 24 px, every one of the piece's equal-share samples lies on its chord (measured
        // without the corners: deviation 0.00 px, not capped), and the turn lies about 1.5 px
        // past its end. Measured at its corners too, the equal pieces do not hold the tolerance.
        let out_and_back = |i: u32| {
            let apex = 5_241.0;
            let i = f64::from(i);
            7e3 * if i <= apex {
                i / apex
            } else {
                (9_999.0 - i) / (9_999.0 - apex)
            }
        };
        let mut disc_trail = streak::style::Style::default();
        disc_trail.trail.profile = streak::style::Profile::Disc;
        let hint = Method::Hint {
            style: std::sync::Arc::new(disc_trail),
            tolerance_px: 1.0,
        };
        let (share, segments, capped, explain, _) =
            square_through_ten_thousand_keyframes(&hint, out_and_back);
        assert_eq!(
            (segments, capped),
            (share, Some(SegmentCap::Footprints(share))),
            "{explain}"
        );
        // `kernel3d` draws at most MAX_SUBFRAMES sub-frames, and plans no more sub-segments than
        // that, and says so; its path is still measured through every keyframe.
        let (share, segments, capped, explain, departures) =
            square_through_ten_thousand_keyframes(&Method::KERNEL3D, out_and_back);
        assert!(MAX_SUBFRAMES < share);
        assert_eq!(
            (segments, capped),
            (MAX_SUBFRAMES, Some(SegmentCap::SubFrames)),
            "{explain}"
        );
        assert!(departures[0].contains("the most sub-frames kernel3d draws"));
        let path = |method: &Method| {
            let explain = square_through_ten_thousand_keyframes(method, out_and_back).3;
            let rest = explain
                .split("screen path up to ")
                .nth(1)
                .unwrap_or_default();
            rest.split(" px").next().unwrap_or_default().to_string()
        };
        assert_eq!(path(&Method::KERNEL3D), path(&Method::STATIC));
    }

    #[test]
    fn far_offsets_and_extreme_scales_draw_the_same_picture() {
        // A moving, turning square seen from 10 units, then the whole world (camera, square and
        // path) moved 10⁶ units away, or scaled by 10⁻⁶ and 10⁶: the pictures must agree. The
        // moved world loses what f64 positions 10⁶ from the origin cannot hold (about 10⁻¹⁰ of
        // a unit, 10⁻⁹ px here); the scaled ones only rounding.
        let world = |offset: DVec3, scale: f64| {
            let camera = Camera::new(
                (DVec3::new(0.0, 0.0, DISTANCE) + offset) * scale,
                offset * scale,
                DVec3::Y,
                30.0,
                64,
                64,
            )
            .unwrap()
            .with_near(0.01 * scale)
            .unwrap();
            let path = motion(&[
                (
                    0.0,
                    Pose {
                        translation: (DVec3::new(-1.0, 0.0, 0.0) + offset) * scale,
                        rotation: DQuat::IDENTITY,
                        scale,
                    },
                ),
                (
                    1.0,
                    Pose {
                        translation: (DVec3::new(1.0, 0.5, 0.0) + offset) * scale,
                        rotation: DQuat::from_rotation_z(0.5),
                        scale,
                    },
                ),
            ]);
            scene(camera, vec![object(square(2.0, 0.05, 0.0), path)])
        };
        let home = world(DVec3::ZERO, 1.0);
        // Measured: the same bits in every case and method; the square covers ~500 px.
        assert!(red(&sharp(&home, 0.5).image).iter().sum::<f64>() > 400.0);
        for (offset, scale) in [
            (DVec3::new(1e6, -1e6, 1e6), 1.0),
            (DVec3::ZERO, 1e-6),
            (DVec3::ZERO, 1e6),
        ] {
            let far = world(offset, scale);
            for &method in METHODS {
                let name = method.name();
                let error = max_difference(
                    &red(&run(&far, method).image),
                    &red(&run(&home, method).image),
                );
                assert!(
                    error < 1e-3,
                    "{name}, offset {offset}, scale {scale}: {error}"
                );
            }
        }
    }

    #[test]
    fn motion_along_the_view_ray_grows_the_image_about_a_fixed_centre() {
        // A 1×1 square on the view axis flies from distance 10 to 5: its image doubles in width.
        let camera = camera(96, 96);
        let approaching = linear(DVec3::ZERO, DVec3::new(0.0, 0.0, 5.0));
        let scene = scene(camera, vec![object(square(1.0, 0.04, 0.0), approaching)]);
        let start = energy(&sharp(&scene, 0.0).image);
        let end = energy(&sharp(&scene, 1.0).image);
        // 0.75 %: the opacity rule (`streak::render::opacity`) counts the inner part of a
        // silhouette's soft edge as more than its summed weights, which adds to the area in
        // proportion to the perimeter and the edge's width: measured +0.2 % at the start, whose
        // surfels are 0.7 px apart, and +0.6 % at the end, 1.4 px apart.
        assert!((end / start - 4.0).abs() < 0.03, "{start} {end}");
        // Area ∝ 1/d(t)² with d = 10 − 5t: over a box shutter its mean is twice the start area
        // (100 ∫₀¹ dt/(10 − 5t)² = 2), and at mid-exposure (d = 7.5) it is (10/7.5)² times it.
        let average = converged(&scene);
        let mean = energy(&average) / start;
        // 0.5 %: 512 frames sum to the integral to 1e-5; what is left is the pixel sampling of each.
        assert!((mean - 2.0).abs() < 0.01, "{mean}");
        let expected_area = |method: Kind| match method {
            Kind::Static => (10.0f64 / 7.5).powi(2),
            // The sharp square at the flash covers its whole trail, but for a soft edge.
            Kind::Hint => 4.0,
            _ => 2.0,
        };
        let half_start_px = 0.5 * px_per_unit(&scene.camera);
        for &method in METHODS {
            let name = method.name();
            let image = run(&scene, method).image;
            let area = energy(&image) / start;
            assert!(
                area > 1.0 && area < 4.0 * 1.01,
                "{name}: {area} start areas, not between the start and end sizes"
            );
            // 1 %: the plan cuts the flight where a footprint's area (∝ 1/d²) departs from linear
            // by more than 1 % (plan::MAX_WEIGHT_DEVIATION; blur measured +0.48 %);
            // the opacity rule widens soft edges a little (reference +0.25 %, kernel3d +0.35 %,
            // --approximate +0.27 %);
            // hint's trail shows under the sharp square's soft edge (+0.6 %).
            let want = expected_area(method);
            assert!((area / want - 1.0).abs() < 0.01, "{name}: {area} vs {want}");
            // The scene is symmetric about the view axis. 0.05 px: blur groups ellipses into depth
            // surfaces in footprint order, which shifts it 0.03 px; the others are within 1e-4 px.
            let [cx, cy] = centroid(&image);
            assert!(
                (cx - 48.0).abs() < 0.05 && (cy - 48.0).abs() < 0.05,
                "{name}: centroid ({cx}, {cy})"
            );
            // Inside the start square (2 px clear of its soft edge) the square covers every pixel at
            // every instant: opaque in every method. (Blur's ellipses pass the pixel at ever other
            // depths; its depth groups chain along them, where they once leaked 16 %.)
            let half = half_start_px - 2.0;
            let least = least_red_where(&image, |dx, dy| dx.abs().max(dy.abs()) <= half);
            assert!(
                least > DENSE_COVERAGE,
                "{name}: a hole of coverage {least} at the centre"
            );
        }
    }

    /// A splat of σ = 2 px crossing a `width`×32 image along its middle row, `travel_px` from end to
    /// end, at the image centre at mid-exposure.
    fn crossing_splat(width: u32, travel_px: f64) -> Scene {
        let camera = camera(width, 32);
        let scale = px_per_unit(&camera);
        let surfel = facing_surfel(DVec3::ZERO, 2.0 / scale);
        let half = DVec3::new(travel_px / 2.0 / scale, 0.0, 0.0);
        scene(camera, vec![object(vec![surfel], linear(-half, half))])
    }

    #[test]
    fn ten_thousand_pixels_of_motion_and_more_keep_the_share_of_energy_inside_the_image() {
        let width = 400;
        let whole = energy(&sharp(&crossing_splat(width, 0.0), 0.5).image);
        let sigma_px = (4.0 + PREFILTER_VARIANCE_PX2).sqrt();
        for travel_px in [1.2e4, 1.2e6] {
            let scene = crossing_splat(width, travel_px);
            let planned = |scene: &Scene| {
                let plan = Plan::new(scene, &Method::BLUR).unwrap();
                let ObjectMotion::Moving {
                    segments,
                    capped,
                    uncapped_streaks,
                    ..
                } = &plan.objects[0].motion
                else {
                    panic!("the splat moves");
                };
                (segments.len(), *capped, *uncapped_streaks)
            };
            // An exact streak holds nothing that changes along a straight path: one, however long.
            assert_eq!(planned(&scene), (1, None, true));
            // Motion ellipses (under a tent shutter) are at most 32 px long: the plan's cap on
            // their count bounds the work however fast the motion.
            let mut tent = scene.clone();
            tent.shutter = Shutter::new(0.0, 1.0, ShutterShape::Tent).unwrap();
            assert_eq!(
                planned(&tent),
                (
                    MAX_SEGMENTS_PER_INTERVAL,
                    Some(SegmentCap::PerInterval),
                    false
                )
            );
            // At uniform speed the splat spends width/travel of the exposure over the image.
            let path_share = f64::from(width) / travel_px;
            // The reference is SAMPLES sharp copies at the strata's midpoints: the image holds the
            // share of the exposure whose copies land in it (none straddles an edge).
            let copies_share: f64 = scene
                .shutter
                .strata(SAMPLES)
                .map(|(t, mass)| {
                    let from_edge = f64::from(width) / 2.0 - ((t - 0.5) * travel_px).abs();
                    assert!(from_edge.abs() > 3.0 * sigma_px, "a copy on the edge");
                    if from_edge > 0.0 {
                        mass
                    } else {
                        0.0
                    }
                })
                .sum();
            for &method in METHODS {
                let name = method.name();
                let expected_share = match method {
                    // At mid-exposure the splat is at the image centre.
                    Kind::Static => 1.0,
                    Kind::Reference => copies_share,
                    // The sharp splat at the flash is off screen; its trail is the blur.
                    _ => path_share,
                };
                let out = run(&scene, method);
                let share = energy(&out.image) / whole;
                // 1 %: measured within 0.06 % (one streak for blur and the hint, 256 sub-frames
                // for kernel3d); blur's capped ellipses once lost 2.1 % at 1.2e6 px where they
                // straddled the image's edges.
                assert!(
                    (share - expected_share).abs() <= 0.01 * expected_share,
                    "{name}, {travel_px} px: share {share} vs {expected_share}"
                );
                // Only what reaches the image is binned: a few ellipses per tile (measured ≤ 3.4),
                // whatever the length of the path.
                let bound = 4 * tiles(width, 32);
                assert!(
                    out.stats.tile_entries <= bound,
                    "{name}, {travel_px} px: {} tile entries",
                    out.stats.tile_entries
                );
            }
        }
    }

    /// A 1×1 square of white surfels in the plane x = 0, which holds the eye, turned by `tilt`
    /// radians about the y axis so that it faces the camera by sin(tilt): exactly edge-on at 0.
    fn edge_on_square(tilt: f64) -> Vec<Surfel> {
        let normal = DVec3::new(tilt.cos(), 0.0, tilt.sin());
        let across = DVec3::new(-tilt.sin(), 0.0, tilt.cos());
        let n = 25;
        let step = 1.0 / f64::from(n);
        (0..n * n)
            .map(|k| {
                let (i, j) = (f64::from(k % n) + 0.5, f64::from(k / n) + 0.5);
                let position = across * (i * step - 0.5) + DVec3::Y * (j * step - 0.5);
                Surfel::isotropic(position, normal, step * step, None, [1.0; 3])
            })
            .collect()
    }

    #[test]
    fn a_surface_turning_through_edge_on_draws_only_while_it_faces_the_camera() {
        // A 2×2 square turns about y between 150° (its back to the camera) and facing it, one
        // way and the other: it turns edge-on at t = 0.4 or 0.6, inside a sub-segment, and
        // covers cos θ of its area while it faces the camera, 1/(150° in rad) = 0.382 of it on
        // average over the exposure.
        let camera = camera(64, 64);
        let turned = Pose {
            translation: DVec3::ZERO,
            rotation: DQuat::from_rotation_y(150f64.to_radians()),
            scale: 1.0,
        };
        let facing = pose(DVec3::ZERO, 0.0);
        for (start, end) in [(turned, facing), (facing, turned)] {
            let turn = motion(&[(0.0, start), (1.0, end)]);
            let scene = scene(camera.clone(), vec![object(square(2.0, 0.05, 0.0), turn)]);
            let average = converged(&scene);
            let full = energy(&sharp(&scene, 1.0).image).max(energy(&sharp(&scene, 0.0).image));
            let mean_share = energy(&average) / full;
            // 1 %: perspective (the turning square's near half grows, its far half shrinks).
            assert!(
                (mean_share - 1.0 / 150f64.to_radians()).abs() < 0.01,
                "{mean_share}"
            );
            // Its screen paths are straight lines; the plan cuts the turn where footprint weights
            // depart from linear (plan::MAX_WEIGHT_DEVIATION).
            let plan = Plan::new(&scene, &Method::BLUR).unwrap();
            let ObjectMotion::Moving { segments, .. } = &plan.objects[0].motion else {
                panic!("the square turns");
            };
            assert!(segments.len() >= 10, "{} sub-segments", segments.len());
            for &method in METHODS {
                let name = method.name();
                let image = red(&run(&scene, method).image);
                let want = expected(method, &scene, &average);
                let (got, wanted) = (image.iter().sum::<f64>(), want.iter().sum::<f64>());
                if wanted == 0.0 {
                    assert_eq!(got, 0.0, "{name}");
                    continue;
                }
                // Measured: energy within 0.7 % (kernel3d --approximate; blur 0.4 %), RMSE ≤
                // 0.0025, worst pixel ≤ 0.019. In one sub-segment, blur drew 64 % of the light and
                // kernel3d 90 %: each took the weight as linear over the whole 150°. A hint whose
                // square has its back to the camera at the flash draws nothing: no point is seen
                // there to start a trail from.
                let (rmse, worst) = (rms_difference(&image, &want), max_difference(&image, &want));
                assert!(
                    (got / wanted - 1.0).abs() < 0.01,
                    "{name}: energy {}",
                    got / wanted
                );
                assert!(
                    rmse < 0.005 && worst < 0.05,
                    "{name}: RMSE {rmse}, worst {worst}"
                );
            }
        }
    }

    #[test]
    fn edge_on_splats_draw_nothing_and_a_hair_off_edge_on_almost_nothing() {
        let camera = camera(64, 64);
        // Sliding along y keeps the square in its plane through the eye.
        let slide = || linear(DVec3::new(0.0, -0.5, 0.0), DVec3::new(0.0, 0.5, 0.0));
        let mut edge_on = scene(camera.clone(), vec![object(edge_on_square(0.0), slide())]);
        edge_on.background = [0.2, 0.3, 0.4];
        let tilt = 1e-6f64;
        let grazing = scene(camera.clone(), vec![object(edge_on_square(tilt), slide())]);
        let facing = scene(camera, vec![object(square(1.0, 0.04, 0.0), slide())]);
        let facing_area = energy(&sharp(&facing, 0.5).image);
        for &method in METHODS {
            let name = method.name();
            let out = run(&edge_on, method);
            assert!(
                is_background(&out.image, edge_on.background),
                "{name}: an edge-on splat drew something"
            );
            assert_eq!(out.stats.footprints, 0, "{name}");
            // A hair off edge-on, the square covers its projected area, sin(tilt) of the facing
            // square's, once per exposure of the method. 1 %: perspective across the square's depth
            // and pixel sampling (measured 0.2 %).
            let out = run(&grazing, method);
            let area = energy(&out.image) / (facing_area * tilt.sin() * exposures(method));
            assert!((area - 1.0).abs() < 0.01, "{name}: {area}");
            let brightest = red(&out.image).into_iter().fold(0.0, f64::max);
            assert!(brightest < 1e-4, "{name}: {brightest}");
        }
    }

    #[test]
    fn sub_pixel_splats_keep_their_area_and_larger_than_image_splats_their_closed_form() {
        let camera = camera(64, 64);
        let scale = px_per_unit(&camera);
        // σ = 0.01 px: the footprint is the pre-filter alone, sampled at pixel centres. Held still
        // on a pixel centre (the worst case, +1.8 %, see PREFILTER_VARIANCE_PX2) and moving 10 px
        // over every sub-pixel position, its pixels sum to its screen area, once per exposure.
        let tiny = facing_surfel(DVec3::ZERO, 0.01 / scale);
        let weight = tiny.area * scale * scale;
        let on_centre = DVec3::new(0.5, 0.5, 0.0) / scale;
        let held = scene(
            camera.clone(),
            vec![object(vec![tiny], linear(on_centre, on_centre))],
        );
        let moving = scene(
            camera.clone(),
            vec![object(
                vec![tiny],
                linear(DVec3::new(-0.4, 0.1, 0.0), DVec3::new(0.43, 0.0, 0.0)),
            )],
        );
        for &method in METHODS {
            let name = method.name();
            for (scene, copies) in [(&held, 1.0), (&moving, exposures(method))] {
                let area = energy(&run(scene, method).image) / (weight * copies);
                // 2 %: the pre-filter's stated accuracy for the narrowest footprint.
                assert!((area - 1.0).abs() < 0.02, "{name}: {area} of its area");
            }
        }
        // σ 10 and 10⁴ times the image, spinning about its own centre: the plan sees motion, the
        // footprint does not change. Every pixel is the Gaussian's closed form (the 3σ cut-off is far
        // outside the image, the truncation gain raises it); the hint draws it twice.
        for times in [10.0, 1e4] {
            let sigma_px = 64.0 * times;
            let big = facing_surfel(DVec3::ZERO, sigma_px / scale);
            let spin = motion(&[
                (0.0, pose(DVec3::ZERO, 0.0)),
                (1.0, pose(DVec3::ZERO, 90.0)),
            ]);
            let scene = scene(camera.clone(), vec![object(vec![big], spin)]);
            let variance = sigma_px * sigma_px + PREFILTER_VARIANCE_PX2;
            let peak =
                TRUNCATION_GAIN * big.area * scale * scale / (std::f64::consts::TAU * variance);
            for &method in METHODS {
                let name = method.name();
                let out = run(&scene, method);
                let image = red(&out.image);
                for y in 0..64 {
                    for x in 0..64 {
                        let (dx, dy) = (f64::from(x) + 0.5 - 32.0, f64::from(y) + 0.5 - 32.0);
                        let a = peak * (-(dx * dx + dy * dy) / (2.0 * variance)).exp();
                        let want = a + (exposures(method) - 1.0) * (1.0 - a) * a;
                        let value = at(&image, 64, x, y);
                        // 1e-5 relative: f32 rounding (measured 6e-7).
                        assert!(
                            (value / want - 1.0).abs() < 1e-5,
                            "{name}, σ {sigma_px} px: ({x}, {y}) {value} vs {want}"
                        );
                    }
                }
                // One footprint per frame and layer, binned once into each tile.
                assert!(out.stats.tile_entries <= tiles(64, 64), "{name}");
            }
        }
    }

    #[test]
    fn motion_within_the_splat_plane_matches_the_reference() {
        // A 2×2 square turned 80° away from the camera about x slides 3 units within its own plane,
        // sideways (x, at constant depth) or along its slope (mostly in depth), and 1e-3 rad out of
        // it: the motion axis lies in or almost in every splat's plane.
        let camera = camera(96, 96);
        let rotation = DQuat::from_rotation_x(-80f64.to_radians());
        let normal = rotation * DVec3::Z;
        for in_plane in [rotation * DVec3::X, rotation * DVec3::Y] {
            for off_plane in [0.0f64, 1e-3] {
                let axis = in_plane * off_plane.cos() + normal * off_plane.sin();
                let path = sliding(rotation, -1.5 * axis, 1.5 * axis);
                let scene = scene(camera.clone(), vec![object(square(2.0, 0.05, 0.0), path)]);
                let average = converged(&scene);
                for &method in METHODS {
                    let name = method.name();
                    let image = red(&run(&scene, method).image);
                    let want = expected(method, &scene, &average);
                    let [rmse_bound, max_bound] = sliding_error(method);
                    let (rmse, worst) =
                        (rms_difference(&image, &want), max_difference(&image, &want));
                    assert!(
                        rmse <= rmse_bound && worst <= max_bound,
                        "{name}, axis {axis}: RMSE {rmse}, worst {worst}"
                    );
                }
            }
        }
    }

    #[test]
    fn splats_far_off_screen_add_exactly_nothing_and_at_the_edge_almost_nothing() {
        let camera = camera(64, 64);
        let scale = px_per_unit(&camera);
        let background = [0.2, 0.3, 0.4];
        // Footprint centres 1e6 px beyond each edge, sliding 20 px along it.
        for direction in [DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y] {
            let far = direction * 1e6 / scale;
            let along = direction.cross(DVec3::Z) * 10.0 / scale;
            let mut scene = scene(
                camera.clone(),
                vec![object(
                    vec![facing_surfel(DVec3::ZERO, 2.0 / scale)],
                    linear(far - along, far + along),
                )],
            );
            scene.background = background;
            for &method in METHODS {
                let name = method.name();
                let out = run(&scene, method);
                assert!(is_background(&out.image, background), "{name}");
                assert_eq!(out.stats.footprints, 0, "{name}: nothing to rasterize");
            }
        }
        // A splat whose 3σ circle touches the left edge (its centre 3σ outside), sliding 20 px along
        // it: the image holds at most what its Gaussian has there, exp(−9/2) = 1.1 % of its peak
        // (4.9e-3 here). The 2D renderers cut footprints off at 3σ, and the nearest pixel centres
        // lie 0.5 px beyond: they draw exactly nothing.
        let sigma = 2.0;
        let sigma_px = (sigma * sigma + PREFILTER_VARIANCE_PX2).sqrt();
        let surfel = facing_surfel(DVec3::ZERO, sigma / scale);
        let peak = TRUNCATION_GAIN * surfel.area * scale * scale
            / (std::f64::consts::TAU * sigma_px.powi(2));
        let x = (-3.0 * sigma_px - 32.0) / scale;
        let scene = scene(
            camera,
            vec![object(
                vec![surfel],
                linear(
                    DVec3::new(x, -10.0 / scale, 0.0),
                    DVec3::new(x, 10.0 / scale, 0.0),
                ),
            )],
        );
        for &method in METHODS {
            let brightest = red(&run(&scene, method).image)
                .into_iter()
                .fold(0.0, f64::max);
            assert!(
                brightest <= peak * (-4.5f64).exp() * exposures(method),
                "{}: {brightest}",
                method.name()
            );
        }
    }

    #[test]
    fn surfels_crossing_the_near_plane_draw_the_part_in_front() {
        // A 1×1 square on the view axis flies through the camera (at z = 10; near plane 0.01 in
        // front of it): away from the scene towards and past the eye, or from behind the eye into the
        // scene. Each is in front of the near plane for a known share of the exposure. Every renderer
        // leaves out a surfel whose centre is behind the near plane: `static` draws its instant (the
        // frame at mid-exposure: the square in front in the first case, nothing in the second), the
        // reference each of its frames so; blur drops each sub-segment with an end behind the near
        // plane; hint draws the square only if it is in front at the flash, and trails only from
        // points in front then, so the first case, which ends behind the camera, leaves no trail.
        let camera = camera(64, 64);
        let square = square(1.0, 0.1, 0.0);
        let cases = [
            // z = 15t passes z = 9.99 at t = 0.666.
            (0.0, 15.0, 9.99 / 15.0),
            // z = 25 − 25t passes z = 9.99 at t = 0.6004.
            (25.0, 0.0, 1.0 - 15.01 / 25.0),
        ];
        for (from, to, share) in cases {
            let path = linear(DVec3::new(0.0, 0.0, from), DVec3::new(0.0, 0.0, to));
            let scene = scene(camera.clone(), vec![object(square.clone(), path)]);
            // A path through the near plane never holds the tolerance: the plan cuts it to the cap,
            // so that the motion renderers, which drop a piece with an end behind the near plane,
            // drop only the 1/256 of the exposure around the crossing.
            let plan = Plan::new(&scene, &Method::BLUR).unwrap();
            let ObjectMotion::Moving {
                segments, capped, ..
            } = &plan.objects[0].motion
            else {
                panic!("the square moves");
            };
            assert!(
                *capped == Some(SegmentCap::PerInterval)
                    && segments.len() == MAX_SEGMENTS_PER_INTERVAL
            );
            // The image centre is covered whenever the square is in front. 2/512: the stratum
            // holding the crossing, and the pixel's soft coverage at the square's huge splats.
            let average = converged(&scene);
            let centre = |image: &[f64]| at(image, 64, 32, 32);
            let covered = centre(&red(&average));
            assert!(
                (covered - share).abs() < 2.0 / CONVERGED as f64,
                "{covered}"
            );
            for &method in METHODS {
                let name = method.name();
                let out = run(&scene, method);
                let (image, want) = (red(&out.image), expected(method, &scene, &average));
                // One reference frame more or less of a square that covers the whole image moves
                // every pixel by 1/SAMPLES; other methods answer to the same average, 2 % for pixel
                // sampling.
                let slack = if method == Kind::Reference {
                    1.0 / SAMPLES as f64
                } else {
                    0.02
                };
                let (got, wanted) = (centre(&image), centre(&want));
                assert!(
                    (got - wanted).abs() <= slack,
                    "{name}, {from} → {to}: centre {got} vs {wanted}"
                );
                let pixels = image.len() as f64;
                let (got, wanted) = (image.iter().sum::<f64>(), want.iter().sum::<f64>());
                assert!(
                    (got - wanted).abs() <= slack * pixels,
                    "{name}, {from} → {to}: energy {got} vs {wanted}"
                );
            }
        }
    }

    #[test]
    fn a_point_in_front_only_between_two_keyframes_behind_the_near_plane_is_drawn() {
        // A small patch orbits the eye at radius 1, 170° about the vertical axis: behind the near
        // plane (0.1) at both keyframes, straight in front of the camera at mid-exposure. The plan
        // once saw no crossing (both ends behind), kept one piece, and every motion renderer
        // dropped it: the patch was gone.
        let camera = Camera::new(DVec3::ZERO, -DVec3::Z, DVec3::Y, 60.0, 64, 64)
            .unwrap()
            .with_near(0.1)
            .unwrap();
        let key = |degrees: f64| Pose {
            rotation: DQuat::from_rotation_y(degrees.to_radians()),
            ..Pose::IDENTITY
        };
        let surfel = Surfel::isotropic(DVec3::new(0.0, 0.0, -1.0), DVec3::Z, 1e-4, None, [1.0; 3]);
        let orbit = motion(&[(0.0, key(-85.0)), (1.0, key(85.0))]);
        let scene = scene(camera, vec![object(vec![surfel], orbit)]);
        let plan = Plan::new(&scene, &Method::BLUR).unwrap();
        let ObjectMotion::Moving { segments, .. } = &plan.objects[0].motion else {
            panic!("the patch moves");
        };
        assert!(segments.len() > 1, "{segments:?}");
        let reference = energy(&draw(&scene, &Method::Reference { samples: 256 }));
        let blur = energy(&draw(&scene, &Method::BLUR));
        assert!(reference > 0.0);
        assert!(
            (blur - reference).abs() < 0.1 * reference,
            "blur {blur} against the reference's {reference}"
        );
    }

    /// Whether a pixel shows a red surface in front of a blue one, opaque.
    fn hides(p: [f32; 3]) -> bool {
        let (front, behind) = (f64::from(p[0]), f64::from(p[2]));
        front > DENSE_COVERAGE && behind < 1.0 - DENSE_COVERAGE
    }

    #[test]
    fn coincident_surfaces_blend_and_one_clearly_in_front_hides_the_other() {
        // Two 2×2 squares, red and blue, sliding 0.2 units together; the red one `gap` in front.
        let camera = camera(64, 64);
        let path = || linear(DVec3::new(-0.1, 0.0, 0.0), DVec3::new(0.1, 0.0, 0.0));
        let pair = |gap: f64, red_first: bool| {
            let red = object(coloured(square(2.0, 0.05, gap), [1.0, 0.0, 0.0]), path());
            let blue = object(coloured(square(2.0, 0.05, 0.0), [0.0, 0.0, 1.0]), path());
            let objects = if red_first {
                vec![red, blue]
            } else {
                vec![blue, red]
            };
            scene(camera.clone(), objects)
        };
        // Pixels covered by both squares all the time: 3 px clear of their soft edges.
        let interior = |image: &Framebuffer| -> Vec<[f32; 3]> {
            (26..38)
                .flat_map(|y| (26..38).map(move |x| (x, y)))
                .map(|(x, y)| image.pixels[y * 64 + x])
                .collect()
        };
        for &method in METHODS {
            let name = method.name();
            // The ternary depth test makes them one surface whose colour is the normalized mix: half
            // red, half blue in every pixel whatever the order they come in, not one or the other.
            // Coincident, their weights are equal: 1e-6 for f32 sums in another order (measured 0).
            // 1e-6 apart is far inside the depth tolerance (3σ = 0.09 units), but their footprints
            // are then 1e-6 px apart on screen, enough for a pixel centre to fall inside one's 3σ
            // cut-off and outside the other's, a step of exp(−9/2) of a footprint's peak: 2e-3
            // (measured 7e-4 in one reference frame, 9e-5 averaged over 32).
            for (gap, tolerance) in [(0.0, 1e-6), (1e-6, 2e-3)] {
                for red_first in [true, false] {
                    let image = run(&pair(gap, red_first), method).image;
                    for p in &image.pixels {
                        let difference = f64::from((p[0] - p[2]).abs());
                        assert!(difference < tolerance, "{name}, gap {gap}: {p:?}");
                    }
                    for p in interior(&image) {
                        let (r, b) = (f64::from(p[0]), f64::from(p[2]));
                        assert!(
                            (r - 0.5).abs() < tolerance && (b - 0.5).abs() < tolerance,
                            "{name}, gap {gap}: {p:?}"
                        );
                    }
                }
            }
            // Half a unit in front (five depth tolerances) the red square hides the blue one.
            let image = run(&pair(0.5, false), method).image;
            for p in interior(&image) {
                assert!(hides(p), "{name}: {p:?}");
            }
        }
    }

    /// `layers` parallel squares, each 10×10 surfels of `colour` (the nearest `front`) `area_share`
    /// of their spacing² in area, 0.5 units apart in depth from z = 0 back, sliding 0.2 units.
    fn stack(layers: usize, front: [f32; 3], colour: [f32; 3], area_share: f64) -> Scene {
        let camera = camera(64, 64);
        let spacing = 0.2;
        let surfels = (0..layers)
            .flat_map(|k| {
                let z = -0.5 * k as f64;
                let c = if k == 0 { front } else { colour };
                square(2.0, spacing, z).into_iter().map(move |s| {
                    // Same σ (0.6 spacing) whatever the area: a sparse layer is a thinner cover.
                    Surfel::isotropic(
                        s.position,
                        s.normal,
                        s.area * area_share,
                        Some(1.2 * spacing),
                        c,
                    )
                })
            })
            .collect();
        let path = linear(DVec3::new(-0.1, 0.0, 0.0), DVec3::new(0.1, 0.0, 0.0));
        scene(camera, vec![object(surfels, path)])
    }

    #[test]
    fn hundreds_of_surfaces_over_one_pixel() {
        const LAYERS: usize = 300;
        let opaque = stack(LAYERS, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 1.0);
        let sparse = stack(LAYERS, [1.0; 3], [1.0; 3], 0.5);
        let surfels = opaque.surfel_count();
        let plan = Plan::new(&opaque, &Method::BLUR).unwrap();
        let ObjectMotion::Moving { segments, .. } = &plan.objects[0].motion else {
            panic!("the stack moves");
        };
        assert_eq!(segments.len(), 1);
        // One half-covering layer alone covers half of the image centre (±5 %: its surfels' sum
        // ripples between grid points, and the pixel samples it).
        let one = red(&sharp(&stack(1, [1.0; 3], [1.0; 3], 0.5), 0.5).image);
        assert!((at(&one, 64, 32, 32) - 0.5).abs() < 0.05);
        for &method in METHODS {
            let name = method.name();
            // The nearest opaque square wins the centre.
            let out = run(&opaque, method);
            let p = out.image.pixels[32 * 64 + 32];
            assert!(hides(p), "{name}: {p:?}");
            // Memory stays proportional to the surfels: a frame (or layer) rasterizes one footprint
            // per surfel of its single sub-segment, each narrower than a tile (σ ≤ 2.2 px, motion ≤
            // 2.4 px) and so binned into at most 2×2 tiles (4 bytes each), and a tile lists each at
            // most once: the centre tiles list almost all of them (measured 28,667 of 30,000).
            assert!(out.stats.tile_entries <= 4 * surfels, "{name}");
            assert!(out.stats.max_per_tile <= surfels, "{name}");
            // Three hundred half-covering layers cover the centre fully and never more than fully:
            // coverage is 1 − Π(1 − αₖ) ≤ 1 (1e-6: f32 rounding).
            let image = red(&run(&sparse, method).image);
            let most = image.iter().copied().fold(0.0, f64::max);
            assert!(most <= 1.0 + 1e-6, "{name}: coverage {most}");
            let centre = at(&image, 64, 32, 32);
            if method == Kind::Kernel3dApproximate {
                // The GPU approximation keeps only fragments at or in front of the visible surface
                // at the sub-frame's ends, the first that leaves less than half of what lies
                // behind showing: here the front layer (0.5006 at the centre), so the stack
                // shows that layer alone (Heinzle §5 assumes opaque surfaces).
                assert!(
                    (centre - at(&one, 64, 32, 32)).abs() < 0.01,
                    "{name}: {centre}"
                );
            } else {
                assert!(centre > 0.999, "{name}: {centre}");
            }
        }
    }

    #[test]
    fn a_million_surfels_in_one_pixel_draw_their_sphere_and_keep_the_work_bounded() {
        // A sphere of radius 0.001 at distance 5 is 0.018 px across on screen: 1,002,775 surfels
        // 3.5e-6 apart pile into one pixel, moving 0.18 px. Each footprint is at least the
        // pre-filter wide, so a dozen pixels each hold half a million of them (the front half).
        let camera = Camera::new(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
            40.0,
            64,
            64,
        )
        .unwrap();
        let surfels = coloured(
            streak::surfels::sphere(0.001, 0.000_003_54).unwrap(),
            [1.0; 3],
        );
        assert!(surfels.len() > 1_000_000);
        let path = linear(DVec3::ZERO, DVec3::new(0.01, 0.0, 0.0));
        let scene = scene(camera, vec![object(surfels, path)]);
        // White on black, the image sums to the sphere's screen area: π (r f / d)².
        let radius_px = 0.001 * scene.camera.focal_px / 5.0;
        let area = std::f64::consts::PI * radius_px * radius_px;
        for &method in METHODS {
            let mut full_detail_fragments = 0;
            for lod in [Lod::Off, Lod::Auto] {
                let name = format!("{}, {lod:?}", method.name());
                let out = run_with_lod(&scene, method, 4, lod);
                assert!(
                    out.image.pixels.iter().flatten().all(|v| v.is_finite()),
                    "{name}"
                );
                // 3 %: the surfels' areas add up to the sphere's (4πr²), whose front half
                // projects to πr²; pixel sampling of footprints 0.55 px wide (measured
                // 0.989–0.994). The hint draws it twice, sharp and in its trail.
                let drawn = energy(&out.image) / (area * exposures(method));
                assert!(
                    (drawn - 1.0).abs() < 0.03,
                    "{name}: {drawn} of the sphere's area"
                );
                let Some(kernels) = out.stats.kernel3d() else {
                    continue;
                };
                // No pixel holds more than the cap: the half-million fragments of a pixel are
                // merged, one per surface and sub-frame, as they come (--explain says how many
                // pixels).
                assert!(
                    kernels.peak_fragments_per_pixel <= MAX_FRAGMENTS_PER_PIXEL,
                    "{name}: {}",
                    kernels.peak_fragments_per_pixel
                );
                if lod == Lod::Off {
                    assert!(kernels.fragments > 1_000_000, "{name}");
                    assert!(kernels.merged_pixels > 0, "{name}");
                    full_detail_fragments = kernels.fragments;
                } else {
                    // Merged in pixel cells, the sub-pixel surfels leave one per normal bucket
                    // and depth layer: at least 20× fewer fragments are made (measured 47×; a
                    // pixel-wide cell's plane depths of a sphere 0.02 px across spread over many
                    // layers).
                    assert!(
                        kernels.fragments * 20 < full_detail_fragments,
                        "{name}: {} of {full_detail_fragments}",
                        kernels.fragments
                    );
                }
            }
        }
    }

    #[test]
    fn empty_scenes_draw_exactly_the_background() {
        let camera = camera(64, 64);
        // Behind the camera (z > 10): still, and moving without coming in front.
        let behind = || square(1.0, 0.1, 20.0);
        let scenes = [
            Vec::new(),
            vec![object(behind(), still())],
            vec![object(
                behind(),
                linear(DVec3::ZERO, DVec3::new(3.0, 0.0, 5.0)),
            )],
        ];
        for objects in scenes {
            let mut scene = scene(camera.clone(), objects);
            scene.background = [0.2, 0.4, 0.6];
            // A path wholly behind the camera costs no sub-segments.
            let plan = Plan::new(&scene, &Method::BLUR).unwrap();
            for o in &plan.objects {
                if let ObjectMotion::Moving { segments, .. } = &o.motion {
                    assert_eq!(segments.len(), 1);
                }
            }
            for &method in METHODS {
                let name = method.name();
                let out = run(&scene, method);
                assert!(is_background(&out.image, scene.background), "{name}");
                assert_eq!(out.stats.footprints, 0, "{name}");
            }
        }
    }
}
