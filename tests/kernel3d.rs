//! The 3D-kernel renderer against closed forms, the reference, and the paper's approximation:
//! one kernel of linear motion is the exact time integral; keyframe scales cancel; sub-frames
//! converge on an arc; the exact A-buffer sees what the GPU approximation misses (Heinzle §6,
//! Fig. 9).

mod common;

use common::*;
use glam::{DQuat, DVec3};
use streak::lod::Lod;
use streak::render::Visibility;
use streak::scene::{Shutter, ShutterShape};
use streak::{Framebuffer, Method, Plan, Pose, Scene, Subframes};

fn kernel3d(scene: &Scene, subframes: Option<usize>, visibility: Visibility) -> Framebuffer {
    let subframes = match subframes {
        Some(n) => Subframes::Equal(n),
        None => Subframes::Planned { tolerance_px: 1.0 },
    };
    draw(
        scene,
        &Method::Kernel3d {
            subframes,
            visibility,
        },
    )
}

#[test]
fn one_kernel_of_linear_motion_is_the_exact_time_integral() {
    // A facing splat sliding 48 px: the kernel integrates its Gaussian along each ray over the
    // whole exposure in closed form, so one sub-frame is the erf streak itself. What is left is
    // the 3σ truncation (renormalized), as for the reference (tests/blur.rs): ≈ 1.3 % in L1.
    let (scene, exact) = translating_scene();
    let image = red(&kernel3d(&scene, Some(1), Visibility::Exact));
    let error = relative_l1(&image, &exact);
    assert!(error < 0.02, "kernel3d vs exact: {error}");
}

#[test]
fn a_keyframe_scale_draws_what_the_scaled_geometry_draws() {
    // The same square built 3× larger, or built small and scaled 3× by its keyframes: every
    // method must draw the same picture (areas live in object space, the scale in the pose).
    let camera = camera(96, 64);
    let big = patch(DVec3::ZERO, [1.5, 1.5], 0.05, false);
    let small = patch(DVec3::ZERO, [0.5, 0.5], 0.05 / 3.0, false);
    let slide = |scale: f64| {
        let mut poses = [
            pose(DVec3::new(-1.0, 0.0, 0.0), 0.0),
            pose(DVec3::new(1.0, 0.0, 0.0), 0.0),
        ];
        for p in &mut poses {
            p.scale = scale;
        }
        motion(&[(0.0, poses[0]), (1.0, poses[1])])
    };
    let built = scene(camera.clone(), vec![object(big, slide(1.0))]);
    let scaled = scene(camera, vec![object(small, slide(3.0))]);
    for method in [
        Method::STATIC,
        Method::BLUR,
        Method::Reference { samples: 16 },
        Method::KERNEL3D,
    ] {
        let a = draw(&built, &method);
        let b = draw(&scaled, &method);
        // The two samplings of the square differ in where their surfels sit: within 1 % RMSE.
        assert!(rmse(&a, &b) < 0.01, "{method:?}: {}", rmse(&a, &b));
    }
}

#[test]
fn sub_frames_converge_on_an_arc() {
    // A rod spinning 60° about one end: one sub-frame stands for the arc by its chord; more
    // sub-frames follow the arc, and the error against the converged reference falls.
    let camera = camera(160, 160);
    let spinning = motion(&[
        (0.0, pose(DVec3::ZERO, 0.0)),
        (1.0, pose(DVec3::ZERO, 60.0)),
    ]);
    let rod = patch(DVec3::new(1.2, 0.0, 0.0), [2.4, 0.15], 0.03, false);
    let scene = scene(camera, vec![object(rod, spinning)]);
    let reference = draw(&scene, &Method::Reference { samples: 1024 });
    let errors: Vec<f64> = [1, 2, 4, 8]
        .iter()
        .map(|&n| rmse(&kernel3d(&scene, Some(n), Visibility::Exact), &reference))
        .collect();
    for pair in errors.windows(2) {
        assert!(pair[1] < pair[0], "{errors:?}");
    }
    // Eight chords of 7.5° each: the arc's sagitta is 0.2 % of the radius, well under a pixel
    // here; measured 4e-4.
    assert!(errors[3] < 2e-3, "{errors:?}");
}

#[test]
fn exact_visibility_shows_the_background_between_two_brief_passes() {
    // Heinzle §6, Fig. 9: two squares cross the centre pixel, one at the start of the exposure
    // and one at its end. In between the background shows; the GPU approximation blends the
    // background only outside [t_min, t_max] = the whole exposure, and so loses it.
    let camera = camera(96, 64);
    let pass = |start: f64| {
        motion(&[
            (0.0, pose(DVec3::new(start, 0.0, 0.0), 0.0)),
            (1.0, pose(DVec3::new(start + 3.0, 0.0, 0.0), 0.0)),
        ])
    };
    let square = || patch(DVec3::ZERO, [0.4, 0.4], 0.02, false);
    let mut scene = scene(
        camera,
        vec![object(square(), pass(0.0)), object(square(), pass(-3.0))],
    );
    scene.background = [0.0, 0.0, 1.0];
    let centre = |image: &Framebuffer| image.pixels[32 * 96 + 48];
    let reference = centre(&draw(&scene, &Method::Reference { samples: 1024 }));
    let exact = centre(&kernel3d(&scene, Some(1), Visibility::Exact));
    let approximate = centre(&kernel3d(&scene, Some(1), Visibility::Approximate));
    // Each white square covers the pixel while its half-width 0.2 passes, 0.2/3 of the exposure:
    // the red channel (white's share; the background is blue) is 2 × 0.2/3 ≈ 0.133.
    assert!((reference[0] - 0.133).abs() < 0.01, "{reference:?}");
    // The A-buffer agrees with the reference to the truncation's few ‰.
    assert!(
        (exact[0] - reference[0]).abs() < 0.005,
        "{exact:?} vs {reference:?}"
    );
    // The approximation lets the background show only outside [t_min, t_max], the whole
    // exposure: between the passes it sees the squares' mean coverage while any of their
    // fragments touches the pixel (measured 0.60), over four times the true share.
    assert!(approximate[0] > 4.0 * reference[0], "{approximate:?}");
    // With more sub-frames the approximation's [t_min, t_max] shrink and it recovers (§5.5).
    let finer = centre(&kernel3d(&scene, Some(8), Visibility::Approximate));
    assert!((finer[0] - reference[0]).abs() < 0.01, "{finer:?}");
}

#[test]
fn a_jump_between_nearly_coincident_keyframes_draws_two_objects_and_no_smear() {
    // A square at x = −1 until mid-exposure and at x = +1 from the very next representable
    // instant: a teleport. The reference draws each half as bright; so must the kernels, with
    // nothing between them (a kernel across the jump once smeared it over the gap).
    let camera = camera(96, 48);
    let half = 0.5f64;
    let teleport = motion(&[
        (0.0, pose(DVec3::new(-1.0, 0.0, 0.0), 0.0)),
        (half, pose(DVec3::new(-1.0, 0.0, 0.0), 0.0)),
        (half.next_up(), pose(DVec3::new(1.0, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::new(1.0, 0.0, 0.0), 0.0)),
    ]);
    let square = patch(DVec3::ZERO, [0.8, 0.8], 0.04, false);
    let scene = scene(camera.clone(), vec![object(square, teleport)]);
    let reference = draw(&scene, &Method::Reference { samples: 64 });
    let kernels = kernel3d(&scene, None, Visibility::Exact);
    let error = rmse(&kernels, &reference);
    assert!(error < 0.01, "RMSE {error} against the reference");
    // The middle column, half way between the squares (about 40 px apart), stays dark.
    let middle = (0..48)
        .map(|y| f64::from(kernels.pixels[y * 96 + 48][0]))
        .fold(0.0, f64::max);
    assert!(middle < 1e-3, "the gap holds {middle}");
}

#[test]
fn a_square_turning_through_edge_on_draws_the_sliver_it_shows() {
    // A square turning about the vertical axis from 60° to 120° away from the camera, exactly
    // edge-on at mid-exposure: it shows a shrinking sliver for the first half. Its kernels once
    // took their splat axes at the middle of the sub-frame, edge-on, and drew nothing (half the
    // energy); spanning the facing part only, they carry the reference's energy, up to the
    // facing cosine taken as linear in time over each sub-frame: at full detail 6.3 % short at
    // the planned 4 sub-frames, 1.9 % at 8, 0.05 % at 32.
    let camera = camera(96, 64);
    let turn = |degrees: f64| Pose {
        rotation: DQuat::from_rotation_y(degrees.to_radians()),
        ..Pose::IDENTITY
    };
    let turning = motion(&[(0.0, turn(60.0)), (1.0, turn(120.0))]);
    let square = patch(DVec3::ZERO, [2.0, 2.0], 0.04, false);
    let scene = scene(camera, vec![object(square, turning)]);
    let reference = energy(&draw(&scene, &Method::Reference { samples: 512 }));
    for (subframes, tolerance) in [
        (Subframes::Planned { tolerance_px: 1.0 }, 0.08),
        (Subframes::Equal(32), 0.005),
    ] {
        let method = Method::Kernel3d {
            subframes,
            visibility: Visibility::Exact,
        };
        let image = Plan::with_lod(&scene, &method, Lod::Off)
            .unwrap()
            .render(None)
            .image;
        let ratio = energy(&image) / reference;
        assert!(
            (ratio - 1.0).abs() < tolerance,
            "{subframes:?}: kernel3d carries {ratio} of the reference's energy"
        );
    }
}

#[test]
fn hidden_tubes_do_not_show_through_a_knot_seen_from_afar() {
    // A still torus knot coloured by its normals, 160×120 px: a pixel is as wide as the tube's
    // radius. Splats along a hidden tube's silhouette are seen nearly edge-on; their planes'
    // depths, extrapolated over the pre-filter's reach, once landed metres in front of and
    // behind the knot, between the surfaces, and a surface's chain of fragments took on their
    // large tolerances and stepped through to the tubes behind: light lines along each hidden
    // silhouette, RMSE 0.0161 against `static` (linear). Depths kept within each disc's own
    // range and the chain keeping its smaller tolerance: 0.0059 (either alone: 0.0151, 0.0142).
    // What is left lies where silhouettes cross.
    let camera = streak::scene::Camera::new(
        DVec3::new(0.0, 0.0, 4.2),
        DVec3::ZERO,
        DVec3::Y,
        34.0,
        160,
        120,
    )
    .unwrap();
    let mut surfels = streak::surfels::torus_knot(2, 3, 0.3, 0.11, 0.0048).unwrap();
    for s in &mut surfels {
        s.colour = (s.normal * 0.5 + 0.5).as_vec3().to_array();
    }
    let scene = scene(camera, vec![object(surfels, still())]);
    let full_detail = |method: &Method| {
        streak::Plan::with_lod(&scene, method, streak::lod::Lod::Off)
            .unwrap()
            .render(None)
            .image
    };
    let error = rmse(
        &full_detail(&Method::KERNEL3D),
        &full_detail(&Method::STATIC),
    );
    assert!(error < 0.008, "kernel3d against static: {error}");
}

#[test]
fn a_still_object_is_drawn_once_however_many_passes_the_sub_frames_take() {
    // A still square, and a dense moving one out of view: 62,500 surfels × 34 sub-frames are
    // more kernels than one pass holds, so the sub-frames are drawn in passes, each over its part
    // of the exposure. The still square's one kernel spans the whole exposure and is in every
    // pass; it was once resolved over all of it in each, and drawn brighter (here by 4.8 %).
    let camera = camera(64, 48);
    let still_square = patch(DVec3::new(-1.2, 0.0, 0.0), [0.6, 0.6], 0.03, false);
    let dense = patch(DVec3::new(30.0, 0.0, 0.0), [0.5, 0.5], 0.002, false);
    let scene = scene(
        camera,
        vec![
            object(still_square, still()),
            object(dense, linear(DVec3::ZERO, DVec3::new(0.0, 0.5, 0.0))),
        ],
    );
    let method = Method::Kernel3d {
        subframes: Subframes::Equal(34),
        visibility: Visibility::Exact,
    };
    let out = Plan::with_lod(&scene, &method, Lod::Off)
        .unwrap()
        .render(None);
    let passes = out.stats.kernel3d().unwrap().passes;
    assert!(passes >= 2, "{passes} pass(es)");
    // As the static frame draws it.
    let ratio = energy(&out.image) / energy(&draw(&scene, &Method::STATIC));
    // The kernel and the static footprint weigh the same splats: measured 1.000.
    assert!((ratio - 1.0).abs() < 0.01, "{ratio}");
}

#[test]
fn planned_sub_frames_follow_a_shutter_whose_weight_varies() {
    // One splat sliding about 60 px: a sub-frame draws the shutter's weight as uniform, so under
    // a tent or Gaussian shutter the plan adds equal sub-frames until the path in each is short.
    // In one sub-frame the streak came out as the box shutter's, relative L1 0.48 (tent) and 0.70
    // (Gaussian) against the reference.
    let (box_scene, _) = translating_scene();
    for shape in [ShutterShape::Tent, ShutterShape::Gaussian] {
        let shutter = Shutter::new(0.0, 1.0, shape).unwrap();
        let scene = box_scene.clone().with_shutter(shutter);
        let reference = red(&draw(&scene, &Method::Reference { samples: 512 }));
        let planned = red(&kernel3d(&scene, None, Visibility::Exact));
        let error = relative_l1(&planned, &reference);
        assert!(error < 0.05, "{shape:?}: relative L1 {error}");
    }
}
