//! The level of detail (`streak::lod`): merged surfels keep the energy, keep edges across the
//! motion, blur away only detail the shutter erases, and leave alone what they cannot help.

mod common;

use common::*;
use glam::DVec3;
use streak::lod::{Lod, LodOutcome, ALONG_FRACTION_KERNELS};
use streak::render::{Subframes, Visibility};
use streak::surfels::Surfel;
use streak::{Framebuffer, Method, Plan, Scene};

/// `kernel3d` keeps full detail by default; these tests ask it to merge at its own share.
fn merging(method: &Method) -> Lod {
    match method {
        Method::Kernel3d { .. } => Lod::Along(ALONG_FRACTION_KERNELS),
        _ => Lod::Auto,
    }
}

fn draw_with(scene: &Scene, method: &Method, lod: Lod) -> (Framebuffer, LodOutcome) {
    let plan = Plan::with_lod(scene, method, lod).unwrap();
    let outcome = plan.objects[0].lod.outcome.clone();
    (plan.render(None).image, outcome)
}

fn merged_by(outcome: &LodOutcome) -> f64 {
    match outcome {
        LodOutcome::Merged {
            surfels_in,
            surfels_out,
            ..
        } => *surfels_in as f64 / *surfels_out as f64,
        other => panic!("expected a merge, got {other:?}"),
    }
}

/// A patch `size` units wide, its surfels `spacing` apart, in squares of `square` × `square`
/// units, red and blue.
fn checkerboard(size: [f64; 2], spacing: f64, square: f64) -> Vec<Surfel> {
    let mut surfels = patch(DVec3::ZERO, size, spacing, false);
    for s in &mut surfels {
        let cell = (s.position.x / square).floor() + (s.position.y / square).floor();
        s.colour = if cell.rem_euclid(2.0) < 1.0 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 0.0, 1.0]
        };
    }
    surfels
}

const KERNEL3D: Method = Method::Kernel3d {
    subframes: Subframes::Equal(4),
    visibility: Visibility::Exact,
};

#[test]
fn merging_keeps_a_blurred_objects_energy() {
    // Sub-pixel surfels (0.45 px apart) sliding 90 px: both rules merge them.
    let surfels = patch(DVec3::ZERO, [2.0, 1.0], 0.02, false);
    let scene = scene(
        camera(200, 120),
        vec![object(
            surfels,
            linear(DVec3::new(-2.0, 0.0, 0.0), DVec3::new(2.0, 0.0, 0.0)),
        )],
    );
    for method in [Method::BLUR, KERNEL3D] {
        let (full, _) = draw_with(&scene, &method, Lod::Off);
        let (merged, outcome) = draw_with(&scene, &method, merging(&method));
        assert!(merged_by(&outcome) > 4.0, "{}: {outcome:?}", method.name());
        let (e_full, e_merged) = (energy(&full), energy(&merged));
        assert!(
            (e_merged / e_full - 1.0).abs() < 0.01,
            "{}: {e_merged} vs {e_full}",
            method.name()
        );
    }
}

#[test]
fn edges_along_the_motion_stay_sharp_and_detail_along_it_blurs_as_it_would() {
    let camera = camera(200, 120);
    let slide = |surfels, distance: f64| {
        scene(
            camera.clone(),
            vec![object(
                surfels,
                linear(
                    DVec3::new(-distance / 2.0, 0.0, 0.0),
                    DVec3::new(distance / 2.0, 0.0, 0.0),
                ),
            )],
        )
    };
    // Squares of 1 unit (22 px) sliding half a unit (11 px): longer than the streak. Their edges
    // along the motion (rows where red meets blue) are where a merge across the motion would show.
    let coarse = slide(checkerboard([3.0, 2.0], 0.02, 1.0), 0.5);
    let edge_row = (0.5 * f64::from(camera.height)) as usize;
    for method in [Method::BLUR, KERNEL3D] {
        let (full, _) = draw_with(&coarse, &method, Lod::Off);
        let (merged, outcome) = draw_with(&coarse, &method, merging(&method));
        assert!(merged_by(&outcome) > 2.0, "{outcome:?}");
        let worst = (edge_row - 3..edge_row + 3)
            .flat_map(|y| (60..140).map(move |x| y * 200 + x))
            .flat_map(|i| (0..3).map(move |c| (i, c)))
            .map(|(i, c)| (full.pixels[i][c] - merged.pixels[i][c]).abs())
            .fold(0.0f32, f32::max);
        // A cell 1 px across moves an edge's samples by at most a third of a pixel's ramp; a
        // merge reaching a few pixels across would smear it by tenths.
        assert!(worst < 0.05, "{}: {worst}", method.name());
    }
    // Squares of 0.1 unit (2.2 px) sliding 4 units (90 px): along the motion they are averaged
    // away, and merging along it must not change what is left.
    let fine = slide(checkerboard([2.0, 1.0], 0.02, 0.1), 4.0);
    for method in [Method::BLUR, KERNEL3D] {
        let (full, _) = draw_with(&fine, &method, Lod::Off);
        let (merged, outcome) = draw_with(&fine, &method, merging(&method));
        assert!(merged_by(&outcome) > 4.0, "{outcome:?}");
        let error = rmse(&merged, &full);
        assert!(error < 0.01, "{}: RMSE {error}", method.name());
    }
}

#[test]
fn surfels_wider_than_a_pixel_merge_across_the_motion_only_within_their_own_blur() {
    // Surfels 0.1 units apart (2.2 px, σ about 2 px) in squares of 1 unit (22 px) sliding 4 units
    // (90 px): cells one pixel wide would gather too few of them to pay, so cells across the
    // motion are two of the surfels' own σ wide (`ACROSS_SIGMAS`).
    let camera = camera(200, 120);
    let board = scene(
        camera.clone(),
        vec![object(
            checkerboard([3.0, 2.0], 0.1, 1.0),
            linear(DVec3::new(-2.0, 0.0, 0.0), DVec3::new(2.0, 0.0, 0.0)),
        )],
    );
    let (full, _) = draw_with(&board, &Method::BLUR, Lod::Off);
    let (merged, outcome) = draw_with(&board, &Method::BLUR, Lod::Auto);
    assert!(merged_by(&outcome) > 2.0, "{outcome:?}");
    let LodOutcome::Merged { widest_cell_px, .. } = outcome else {
        unreachable!()
    };
    assert!((2.0..8.0).contains(&widest_cell_px), "{widest_cell_px}");
    // Where red meets blue along the motion, the surfels' own Gaussians already spread the edge
    // over several pixels; members within 2σ across add at most a third to that variance (cells
    // 2.7 px wide here: 0.024 at worst). Cells of 8σ (10.7 px) move the edge by 0.094.
    let edge_row = (0.5 * f64::from(camera.height)) as usize;
    let worst = (edge_row - 3..edge_row + 3)
        .flat_map(|y| (60..140).map(move |x| y * 200 + x))
        .flat_map(|i| (0..3).map(move |c| (i, c)))
        .map(|(i, c)| (full.pixels[i][c] - merged.pixels[i][c]).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 0.05, "{worst}");
    let error = rmse(&merged, &full);
    assert!(error < 0.01, "RMSE {error}");
}

#[test]
fn objects_whose_surfels_cover_a_pixel_are_drawn_at_full_detail() {
    // 0.1 units apart: 2.2 px.
    let still_patch = scene(
        camera(160, 120),
        vec![object(patch(DVec3::ZERO, [2.0, 1.0], 0.1, false), still())],
    );
    for method in [
        Method::STATIC,
        Method::Reference { samples: 4 },
        Method::BLUR,
        KERNEL3D,
    ] {
        let (full, _) = draw_with(&still_patch, &method, Lod::Off);
        let (auto, outcome) = draw_with(&still_patch, &method, merging(&method));
        assert!(
            matches!(outcome, LodOutcome::Kept { surfel_px } if surfel_px > 2.0),
            "{outcome:?}"
        );
        assert_eq!(full.pixels, auto.pixels, "{}", method.name());
    }
}

#[test]
fn sub_pixel_surfels_of_an_instant_merge_within_a_pixel() {
    // 0.005 units apart: 0.11 px, about eighty surfels per pixel.
    let far = scene(
        camera(160, 120),
        vec![object(checkerboard([2.0, 1.0], 0.005, 0.25), still())],
    );
    let (full, _) = draw_with(&far, &Method::STATIC, Lod::Off);
    let (merged, outcome) = draw_with(&far, &Method::STATIC, Lod::Auto);
    assert!(merged_by(&outcome) > 20.0, "{outcome:?}");
    let error = rmse(&merged, &full);
    assert!(error < 0.01, "RMSE {error}");
}

#[test]
fn surfels_facing_away_wherever_they_are_drawn_are_left_out_and_the_rest_keep_their_energy() {
    // A unit ball of 20,000 sub-pixel surfels (0.28 px apart).
    let count = 20_000;
    let area = 4.0 * std::f64::consts::PI / count as f64;
    let ball: Vec<Surfel> = fibonacci_sphere(count)
        .into_iter()
        .map(|p| Surfel::isotropic(p, p, area, None, [1.0; 3]))
        .collect();
    let back = |outcome: &LodOutcome| match outcome {
        LodOutcome::Merged { back_facing, .. } => *back_facing as f64 / count as f64,
        other => panic!("expected a merge, got {other:?}"),
    };
    let still_ball = scene(camera(100, 60), vec![object(ball.clone(), still())]);
    // Turning a quarter turn about the vertical: a surfel on the far side at the middle of the
    // exposure faces the camera at one of its ends, and `blur` draws it there.
    let turning = motion(&[
        (0.0, pose_about_y(DVec3::ZERO, -45.0)),
        (1.0, pose_about_y(DVec3::ZERO, 45.0)),
    ]);
    let turning_ball = scene(camera(100, 60), vec![object(ball, turning)]);
    // From 10 radii away a camera sees a cap of (1 − 1/10)/2 of a ball: 55 % faces away.
    // Turning, the ball shows more of itself over the exposure, and less of it is left out.
    for (scene, method, left_out) in [
        (&still_ball, Method::STATIC, 0.54..0.56),
        (&turning_ball, Method::BLUR, 0.2..0.5),
    ] {
        let (full, _) = draw_with(scene, &method, Lod::Off);
        let (merged, outcome) = draw_with(scene, &method, Lod::Auto);
        let share = back(&outcome);
        assert!(
            left_out.contains(&share),
            "{}: {share} of the surfels left out",
            method.name()
        );
        // Leaving out a surfel the render draws at some instant would take its light.
        let (e_full, e_merged) = (energy(&full), energy(&merged));
        assert!(
            (e_merged / e_full - 1.0).abs() < 0.01,
            "{}: {e_merged} vs {e_full}",
            method.name()
        );
    }
}

#[test]
fn longer_cells_on_a_curved_surface_gather_more_surfels_each() {
    // A ball of 1 px surfels falling 110 px. A cell along the motion is cut by normal and depth
    // into runs of one surface; a longer cell may hold more runs, but each longer run holds more
    // surfels, so the merge must not fall as the cells grow: 3.7× at cells of a twentieth of the
    // path, 5.0× at a fifth. When a surfel's depth layer was its tangent plane's depth at the
    // cell's centre, a long cell on a ball put the surfels near both of its ends (whose tangent
    // planes pass alike in front of the centre) in one layer, and each merged surfel spanned a
    // gap: 4.5× and 4.3×.
    let radius = 1.5;
    let count = 40_000;
    let area = 4.0 * std::f64::consts::PI * radius * radius / count as f64;
    let surfels: Vec<Surfel> = fibonacci_sphere(count)
        .into_iter()
        .map(|n| Surfel::isotropic(n * radius, n, area, None, [1.0; 3]))
        .collect();
    let falling = linear(DVec3::new(0.0, 1.5, 0.0), DVec3::new(0.0, -1.5, 0.0));
    let scene = scene(camera(200, 200), vec![object(surfels, falling)]);
    let merged = |share: f64| {
        let plan = Plan::with_lod(&scene, &Method::BLUR, Lod::Along(share)).unwrap();
        merged_by(&plan.objects[0].lod.outcome)
    };
    let (short, long) = (merged(0.05), merged(0.2));
    assert!(
        long >= short,
        "cells of 0.2 of the path: {long}×; of 0.05: {short}×"
    );
}

#[test]
fn a_blurred_object_merges_in_cells_that_gather_fewer_surfels_than_an_instant_needs() {
    // Surfels 0.06 units apart (1.3 px) sliding 0.7 units (15 px): a cell along the motion, a
    // fifth of the path long and 2σ wide, gathers about three of them (the median surfel is 0.59
    // of the cell's √(length × width)), so `blur` merges them (`MERGE_SHARE_ALONG`; the square
    // cells' share, 0.5, would not), while a square cell of the instant, 1 px, gathers less than
    // one.
    let sliding = scene(
        camera(200, 120),
        vec![object(
            patch(DVec3::ZERO, [2.0, 1.0], 0.06, false),
            linear(DVec3::new(-0.35, 0.0, 0.0), DVec3::new(0.35, 0.0, 0.0)),
        )],
    );
    let (full, _) = draw_with(&sliding, &Method::BLUR, Lod::Off);
    let (merged, outcome) = draw_with(&sliding, &Method::BLUR, Lod::Auto);
    assert!(merged_by(&outcome) > 1.3, "{outcome:?}");
    let error = rmse(&merged, &full);
    assert!(error < 0.01, "RMSE {error}");
    let (_, instant) = draw_with(&sliding, &Method::STATIC, Lod::Auto);
    assert!(
        matches!(instant, LodOutcome::Kept { surfel_px } if surfel_px > 1.0),
        "{instant:?}"
    );
}
