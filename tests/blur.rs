//! The blur renderer against closed forms and the reference: one Gaussian splat moving along a
//! line or an arc, energy, and the zero-motion limit.

mod common;

use common::*;
use glam::DVec3;
use streak::scene::shutter::ShutterShape;
use streak::{Light, Lighting, Method, Shutter};

#[test]
fn the_test_splat_stays_below_full_coverage() {
    // The tests below read Σw straight off the image; that holds only while Σw < 1.
    let (scene, _) = translating_scene();
    let peak = red(&draw(&scene, &Method::STATIC))
        .into_iter()
        .fold(0.0, f64::max);
    assert!(peak > 0.1 && peak < 0.9, "{peak}");
}

#[test]
fn reference_converges_to_the_closed_form_time_integral() {
    let (scene, exact) = translating_scene();
    let reference = red(&draw(&scene, &Method::Reference { samples: 2048 }));
    // 2048 frames are 0.02 px apart: what is left is the 3σ truncation of each frame's Gaussian
    // across the streak (renormalized, so only its shape differs: ≈ 1.3 % in L1) and f32 rounding.
    let error = relative_l1(&reference, &exact);
    assert!(error < 0.02, "reference vs exact: {error}");
}

#[test]
fn blur_matches_the_closed_form_with_one_segment_or_many() {
    let (scene, exact) = translating_scene();
    // Under a box shutter each sub-segment is drawn as its exact streak (docs/math.md, "Exact
    // streaks"), so one segment for the whole 48 px path and twelve of 4 px (τ = 0.125 px) both
    // match the closed form. What is left is the cut at 3σ across (renormalized, so only its shape
    // differs) and pixel-centre sampling: 0.6 % in L1. Guan & Mueller's single ellipse, a
    // Gaussian with the streak's variance, was a third off here.
    for tolerance_px in [64.0, 0.125] {
        let blur = red(&draw(&scene, &Method::Blur { tolerance_px }));
        let error = relative_l1(&blur, &exact);
        assert!(error < 0.01, "blur τ={tolerance_px} vs exact: {error}");
    }
}

#[test]
fn one_segment_under_a_tent_shutter_is_the_summed_covariance_gaussian() {
    // Guan & Mueller §3.3 (docs/math.md, "Motion ellipse by summing covariances"): for shutters
    // other than the box, Σ + m mᵀ · Var(t)/Δ², centred at the mean time, same weight. A tent over
    // the whole interval has Var(t)/Δ² = 1/24 and its mean mid-path.
    let (mut scene, _) = translating_scene();
    scene.shutter = Shutter::new(0.0, 1.0, ShutterShape::Tent).unwrap();
    let scale = px_per_unit(&scene.camera);
    let surfel = &scene.objects[0].surfels()[0];
    let (weight, m) = (surfel.area * scale * scale, 4.0 * scale);
    let variance = SIGMA_PX * SIGMA_PX + streak::render::PREFILTER_VARIANCE_PX2;
    let (vx, vy) = (variance + m * m / 24.0, variance);
    let oracle: Vec<f64> = (0..64)
        .flat_map(|y| (0..128).map(move |x| (x as f64 + 0.5 - 64.0, y as f64 + 0.5 - 32.0)))
        .map(|(dx, dy)| {
            weight / (std::f64::consts::TAU * (vx * vy).sqrt())
                * (-0.5 * (dx * dx / vx + dy * dy / vy)).exp()
        })
        .collect();
    let single = red(&draw(&scene, &Method::Blur { tolerance_px: 64.0 }));
    // The render truncates at 3σ and renormalizes: ≈ 2 % in L1 for an isolated 2D Gaussian.
    let error = relative_l1(&single, &oracle);
    assert!(error < 0.03, "single ellipse vs Σ + mmᵀ/24: {error}");
}

#[test]
fn blur_matches_the_reference_when_segments_are_short() {
    let (scene, _) = translating_scene();
    let blur = red(&draw(
        &scene,
        &Method::Blur {
            tolerance_px: 0.125,
        },
    ));
    let reference = red(&draw(&scene, &Method::Reference { samples: 2048 }));
    let error = relative_l1(&blur, &reference);
    assert!(error < 0.02, "blur vs reference: {error}");
}

#[test]
fn a_streak_is_as_long_as_a_straight_path_unless_its_shape_may_change_along_it() {
    // 48 px in a straight line: the tolerance (1 px) holds for one chord of any length, and an
    // exact streak of it is the closed form.
    let (scene, exact) = translating_scene();
    let planned = |scene: &streak::Scene| {
        let plan = streak::Plan::new(scene, &Method::BLUR).unwrap();
        let streak::plan::ObjectMotion::Moving {
            segments,
            uncapped_streaks,
            ..
        } = &plan.objects[0].motion
        else {
            panic!("blur plans the splat's sub-segments");
        };
        (segments.len(), *uncapped_streaks)
    };
    let segments = |scene: &streak::Scene| planned(scene).0;
    assert_eq!(segments(&scene), 1);
    // The render truncates at 3σ and renormalizes: 2 % in L1, as for one ellipse.
    let error = relative_l1(&red(&draw(&scene, &Method::BLUR)), &exact);
    assert!(error < 0.03, "one streak vs the closed form: {error}");
    // A streak holds its colour and orientation at the middle: turning in place (about the view
    // axis, so the path stays straight) or lit by a spot, the splat may not change them over
    // more than 32 px (plan::SEGMENT_LENGTH_PER_TOLERANCE).
    let mut turning = scene.clone();
    turning.objects[0].motion = motion(&[
        (0.0, pose(DVec3::new(-2.0, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::new(2.0, 0.0, 0.0), 30.0)),
    ]);
    assert_eq!(segments(&turning), 2);
    let mut spot_lit = scene.clone();
    spot_lit.lighting.spots =
        vec![
            streak::scene::Spot::new(DVec3::new(0.0, 0.0, 10.0), DVec3::ZERO, 40.0, 1.0, false)
                .unwrap(),
        ];
    assert_eq!(segments(&spot_lit), 2);
    // Moving 0.6 units in depth (more than the splat's own depth tolerance, 0.5) its size on
    // screen changes by 0.12 px, under the tolerance: still one streak, its depth along it
    // following the splat, and as close to the reference as across the view.
    let mut in_depth = scene.clone();
    in_depth.objects[0].motion = motion(&[
        (0.0, pose(DVec3::new(-2.0, 0.0, -0.3), 0.0)),
        (1.0, pose(DVec3::new(2.0, 0.0, 0.3), 0.0)),
    ]);
    assert_eq!(planned(&in_depth), (1, true));
    let reference = red(&draw(&in_depth, &Method::Reference { samples: 2048 }));
    let error = relative_l1(&red(&draw(&in_depth, &Method::BLUR)), &reference);
    assert!(
        error < 0.03,
        "one streak in depth vs the reference: {error}"
    );
    // Flying to half its distance, the splat doubles in size (2 → 4 px): cut into pieces over
    // which its size changes by at most the tolerance, at least two.
    let mut nearing = scene.clone();
    nearing.objects[0].motion = motion(&[
        (0.0, pose(DVec3::new(-2.0, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::new(2.0, 0.0, DISTANCE / 2.0), 0.0)),
    ]);
    assert!(segments(&nearing) >= 2);
}

#[test]
fn a_splat_growing_by_its_pose_scale_is_cut_as_one_growing_by_nearing() {
    // A splat whose screen area grows 9× over the shutter: by its pose's scale (1 → 3) or by
    // coming three times nearer. Its weight, linear over each sub-segment as `blur` draws it,
    // must stay within the plan's 1 % either way; with the scale left out of the plan's weight
    // it was one streak carrying 15 % more light than the reference.
    let camera = camera(128, 64);
    let surfel = facing_surfel(DVec3::ZERO, SIGMA_PX / px_per_unit(&camera));
    let scaled = streak::scene::Motion::new(
        [1.0, 3.0]
            .iter()
            .enumerate()
            .map(|(i, &scale)| streak::scene::Keyframe {
                t: i as f64,
                pose: streak::Pose {
                    scale,
                    ..streak::Pose::IDENTITY
                },
            })
            .collect(),
    )
    .unwrap();
    let nearing = linear(DVec3::ZERO, DVec3::new(0.0, 0.0, DISTANCE - DISTANCE / 3.0));
    for motion in [scaled, nearing] {
        let s = scene(camera.clone(), vec![object(vec![surfel], motion)]);
        let blurred = energy(&draw(&s, &Method::BLUR));
        let reference = energy(&draw(&s, &Method::Reference { samples: 512 }));
        assert!(
            (blurred / reference - 1.0).abs() < 0.01,
            "{blurred} against {reference}"
        );
    }
}

#[test]
fn a_blurred_splat_carries_the_energy_of_the_static_one() {
    let (scene, _) = translating_scene();
    let total = |image: Vec<f64>| image.iter().sum::<f64>();
    let still = total(red(&draw(&scene, &Method::STATIC)));
    for tolerance in [64.0, 4.0, 1.0, 0.25] {
        let blurred = total(red(&draw(
            &scene,
            &Method::Blur {
                tolerance_px: tolerance,
            },
        )));
        // Pixel-centre sampling of Gaussians at least 0.55 px wide: within 0.5 %.
        assert!(
            (blurred / still - 1.0).abs() < 0.005,
            "τ={tolerance}: {blurred} vs {still}"
        );
    }
}

/// A splat on a 2-unit arm (≈ 36 px) swinging 120° about the view axis.
fn swinging_scene() -> streak::Scene {
    let camera = camera(96, 96);
    let surfel = facing_surfel(DVec3::new(2.0, 0.0, 0.0), 1.5 / px_per_unit(&camera));
    let motion = motion(&[
        (0.0, pose(DVec3::ZERO, 0.0)),
        (0.5, pose(DVec3::ZERO, 60.0)),
        (1.0, pose(DVec3::ZERO, 120.0)),
    ]);
    scene(camera, vec![object(vec![surfel], motion)])
}

#[test]
fn curved_path_error_falls_as_sub_segments_increase() {
    let scene = swinging_scene();
    let reference = draw(&scene, &Method::Reference { samples: 2048 });
    let errors: Vec<f64> = [8.0, 2.0, 0.5, 0.125]
        .iter()
        .map(|&tolerance| {
            rmse(
                &draw(
                    &scene,
                    &Method::Blur {
                        tolerance_px: tolerance,
                    },
                ),
                &reference,
            )
        })
        .collect();
    for pair in errors.windows(2) {
        assert!(
            pair[1] < pair[0],
            "errors must fall with the tolerance: {errors:?}"
        );
    }
    assert!(errors[3] < 0.25 * errors[0], "{errors:?}");
}

#[test]
fn a_streak_of_a_bent_path_is_centred_on_the_paths_mean() {
    // At τ = 8 px each 60° of the swing (r ≈ 36 px) is one straight sub-segment, whose chord
    // cuts 4.8 px inside the arc at its middle. Drawn on the chords, the blurred splat's centroid
    // lay at r cos²30° = 0.75 r from the pivot (26.9 px); the mean of the arc is
    // r sin 60° / (π/3) = 0.827 r (29.6 px). Moved by ⅔ of the sagitta (docs/math.md, "A bent
    // path's mean"), each piece's centre is within 0.05 % of its arc's mean, and the image's
    // centroid was 0.011 px from the whole swing's; 0.1 px allows for pixel sampling.
    let scene = swinging_scene();
    let r = 2.0 * px_per_unit(&scene.camera);
    let expected = r * 60f64.to_radians().sin() / 60f64.to_radians();
    let image = draw(&scene, &Method::Blur { tolerance_px: 8.0 });
    let plan = streak::Plan::new(&scene, &Method::Blur { tolerance_px: 8.0 }).unwrap();
    assert!(
        plan.explain(None).contains("2 linear sub-segments"),
        "{}",
        plan.explain(None)
    );
    let (mut sum, mut moment) = (0.0, glam::DVec2::ZERO);
    for (i, p) in image.pixels.iter().enumerate() {
        let at = glam::DVec2::new((i % 96) as f64 + 0.5, (i / 96) as f64 + 0.5);
        sum += f64::from(p[0]);
        moment += at * f64::from(p[0]);
    }
    let distance = (moment / sum).distance(glam::DVec2::splat(48.0));
    assert!(
        (distance - expected).abs() < 0.1,
        "centroid {distance} px from the pivot, the path's mean {expected}"
    );
}

#[test]
fn zero_motion_blur_equals_static_equals_reference() {
    let camera = camera(64, 64);
    let surfels: Vec<_> = (0..40)
        .map(|i| {
            facing_surfel(
                DVec3::new(-1.5 + 0.075 * i as f64, 0.3 * (i as f64).sin(), 0.0),
                0.08,
            )
        })
        .collect();
    let still = scene(
        camera.clone(),
        vec![object(
            surfels.clone(),
            motion(&[(0.0, pose(DVec3::ZERO, 0.0))]),
        )],
    );
    let static_image = draw(&still, &Method::STATIC);
    assert!(
        static_image.pixels.iter().any(|p| p[0] > 0.5),
        "the object must be visible"
    );
    assert_eq!(draw(&still, &Method::BLUR), static_image);
    assert!(
        rmse(
            &draw(&still, &Method::Reference { samples: 16 }),
            &static_image
        ) < 1e-6
    );

    // Keyframes that move by 1e-9 units: the plan sees motion, so the motion-ellipse path runs,
    // and its limit must be the static image.
    let barely = motion(&[
        (0.0, pose(DVec3::ZERO, 0.0)),
        (1.0, pose(DVec3::new(1e-9, 0.0, 0.0), 0.0)),
    ]);
    let moving = scene(camera, vec![object(surfels, barely)]);
    assert!(streak::Plan::new(&moving, &Method::BLUR)
        .unwrap()
        .any_moving());
    let blurred = draw(&moving, &Method::BLUR);
    let worst = blurred
        .pixels
        .iter()
        .zip(&static_image.pixels)
        .map(|(a, b)| (a[0] - b[0]).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "{worst}");
}

#[test]
fn ten_thousand_pixels_of_motion_keep_the_share_of_energy_inside_the_image() {
    // A splat crossing 12,000 px at uniform speed spends width/12,000 of the shutter over the
    // image, so the image must hold that share of the static splat's energy, with no NaN.
    let camera = camera(256, 64);
    let scale = px_per_unit(&camera);
    let surfel = facing_surfel(DVec3::ZERO, SIGMA_PX / scale);
    let travel_px = 12_000.0;
    let half = travel_px / 2.0 / scale;
    let fast = motion(&[
        (0.0, pose(DVec3::new(-half, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::new(half, 0.0, 0.0), 0.0)),
    ]);
    let still = scene(
        camera.clone(),
        vec![object(
            vec![surfel],
            motion(&[(0.0, pose(DVec3::ZERO, 0.0))]),
        )],
    );
    let moving = scene(camera, vec![object(vec![surfel], fast)]);
    let energy =
        |image: &streak::Framebuffer| image.pixels.iter().map(|p| f64::from(p[0])).sum::<f64>();
    let expected = energy(&draw(&still, &Method::STATIC)) * 256.0 / travel_px;
    let blurred = draw(&moving, &Method::BLUR);
    assert!(blurred.pixels.iter().flatten().all(|c| c.is_finite()));
    let share = energy(&blurred);
    // The sub-segment count is capped (256 per keyframe interval), so ellipses are ~47 px long
    // and the ones straddling the image edges put a little energy outside it: 3 %.
    assert!(
        (share / expected - 1.0).abs() < 0.03,
        "{share} vs {expected}"
    );
}

#[test]
fn splats_turning_edge_on_carry_the_energy_they_show() {
    // Five separate splats turning about the vertical axis from 60° to 120° away from the
    // camera: each shows its face for the first half of the exposure, shrinking to a sliver at
    // the turn. Blur once weighted the whole sub-segment by the share of time facing, counting
    // the far end's area as if it faced the camera: twice the reference's energy (measured
    // 2.0). Clipped to the facing part it is within 5 % (its facing cosine is taken as linear
    // in time, 2.3 % short of the cosine's mean over 60°–90°). A surface made of such splats
    // also loses what its uneven fill of the time bins loses (tests/stiff.rs).
    let camera = camera(96, 64);
    let turning = motion(&[
        (0.0, pose_about_y(DVec3::ZERO, 60.0)),
        (1.0, pose_about_y(DVec3::ZERO, 120.0)),
    ]);
    let splats = (0..5)
        .map(|i| facing_surfel(DVec3::new(0.0, f64::from(i) - 2.0, 0.0), 0.15))
        .collect();
    let scene = scene(camera, vec![object(splats, turning)]);
    let reference = energy(&draw(&scene, &Method::Reference { samples: 512 }));
    let blurred = energy(&draw(&scene, &Method::BLUR));
    let ratio = blurred / reference;
    assert!(
        (ratio - 1.0).abs() < 0.05,
        "blur {blurred} against the reference's {reference}"
    );
}

/// Relative L1 of `blur` (τ = 64 px, so only the plan's other rules cut the path) against the
/// reference of 2048 frames, for a 1 px splat moving through the keyframes `keys` in a 128 × 64
/// image under `lighting`.
fn one_splat_against_the_reference(keys: &[(f64, streak::Pose)], lighting: Lighting) -> f64 {
    let camera = camera(128, 64);
    let surfel = facing_surfel(DVec3::ZERO, 1.0 / px_per_unit(&camera));
    let mut scene = scene(camera, vec![object(vec![surfel], motion(keys))]);
    scene.lighting = lighting;
    let reference = red(&draw(&scene, &Method::Reference { samples: 2048 }));
    let blur = red(&draw(&scene, &Method::Blur { tolerance_px: 64.0 }));
    relative_l1(&blur, &reference)
}

#[test]
fn a_splat_turning_as_it_slides_leaves_a_streak_that_fades_along_it() {
    // Sliding 4 units while turning from facing the camera to 60° from it, its screen area
    // falls to half at an even speed; each sub-segment's streak carries the change of light
    // along it (docs/math.md, "A streak whose light changes along it").
    let error = one_splat_against_the_reference(
        &[
            (0.0, pose_about_y(DVec3::new(-2.0, 0.0, 0.0), 0.0)),
            (1.0, pose_about_y(DVec3::new(2.0, 0.0, 0.0), 60.0)),
        ],
        Lighting::default(),
    );
    // Five sub-segments (the weight's 1 % rule): 1.6 % in L1, the splat's foreshortening along
    // the chord and the cut; with even light along each streak it was 3.3 %.
    assert!(error < 0.02, "blur vs reference: {error}");
}

#[test]
fn a_splat_nearing_the_camera_leaves_a_streak_of_even_light() {
    // From 12 to 8 units away while crossing 4: its screen area grows as 1/z², and so does its
    // screen speed (f (ẋz − xż)/z², the numerator constant for linear motion), so the light it
    // leaves per pixel of its path is even; the two changes cancel in each streak.
    let error = one_splat_against_the_reference(
        &[
            (0.0, pose(DVec3::new(-2.0, 0.0, -2.0), 0.0)),
            (1.0, pose(DVec3::new(2.0, 0.0, 2.0), 0.0)),
        ],
        Lighting::default(),
    );
    // 1.6 % in L1 (the splat's growth along each streak and the cut); with the speed's change
    // counted the wrong way round, 6.7 %.
    assert!(error < 0.02, "blur vs reference: {error}");
}

#[test]
fn a_splat_turning_towards_a_light_leaves_a_streak_that_brightens_along_it() {
    // Sliding 4 units while turning from −30° to 30° about the vertical, under a light 45° to
    // the side: its shading n·l goes from cos 75° to cos 15°, 3.7 times brighter, while its
    // screen area changes by at most 13 %. Each streak's colour changes linearly along it
    // (docs/math.md, "A streak whose colour changes along it").
    let light = Light::new(DVec3::new(1.0, 0.0, 1.0), 1.0).unwrap();
    let error = one_splat_against_the_reference(
        &[
            (0.0, pose_about_y(DVec3::new(-2.0, 0.0, 0.0), -30.0)),
            (1.0, pose_about_y(DVec3::new(2.0, 0.0, 0.0), 30.0)),
        ],
        Lighting::new(0.0, vec![light]).unwrap(),
    );
    // 1.7 % in L1; with each streak's colour even (its ends' mean), 4.1 %.
    assert!(error < 0.025, "blur vs reference: {error}");
}

#[test]
fn a_shaped_shutter_s_sub_segments_are_short_enough_for_its_weight() {
    // One splat sliding about 60 px under a tent or Gaussian shutter: `blur` draws motion
    // ellipses, each standing for its sub-segment's shutter-weighted path by its mean and
    // variance, so the plan keeps them at most 8 τ long: relative L1 0.033 (tent) and 0.044
    // (Gaussian) against 512 frames. In 32 τ sub-segments the streak's ends spread past the path
    // and its weight's slope flattened (tent 0.31).
    let (box_scene, _) = translating_scene();
    for shape in [ShutterShape::Tent, ShutterShape::Gaussian] {
        let scene = box_scene
            .clone()
            .with_shutter(Shutter::new(0.0, 1.0, shape).unwrap());
        let reference = red(&draw(&scene, &Method::Reference { samples: 512 }));
        let blurred = red(&draw(&scene, &Method::BLUR));
        let error = relative_l1(&blurred, &reference);
        assert!(error < 0.05, "{shape:?}: relative L1 {error}");
    }
}
