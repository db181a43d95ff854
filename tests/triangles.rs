//! Triangles drawn as triangles: `analytic` (time-continuous triangles with interval lists) and
//! the z-buffer of `static` and `reference`, against closed forms, against the converged
//! reference, and on the hard cases of the edge quadratics.

mod common;

use common::rmse;
use glam::{DQuat, DVec3};
use streak::render::Receivers;
use streak::scene::{Camera, Keyframe, Light, Lighting, Motion, Object, Pose, TriangleMesh};
use streak::surfels::{from_mesh, Colouring, Mesh};
use streak::{Framebuffer, Method, Plan, Render, Scene};

/// A square of side `side` in the plane z = 0 centred on the origin, as two triangles.
fn square(side: f64) -> Mesh {
    let h = 0.5 * side;
    quad([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])
}

/// The quadrilateral through `corners` in turn, as two triangles.
fn quad(corners: [[f64; 3]; 4]) -> Mesh {
    Mesh {
        positions: corners.map(DVec3::from_array).to_vec(),
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// An object drawn as the triangles of `mesh` in `colour`, at the poses `keys` (time, pose).
fn object(name: &str, mesh: &Mesh, colour: [f32; 3], keys: &[(f64, Pose)]) -> Object {
    let triangles = TriangleMesh::new(mesh, DVec3::ZERO, Colouring::Rgb(colour)).unwrap();
    let mut surfels = from_mesh(mesh, 400, false).unwrap();
    Colouring::Rgb(colour).apply(&mut surfels);
    let motion = Motion::new(keys.iter().map(|&(t, pose)| Keyframe { t, pose }).collect()).unwrap();
    Object::triangles(name, triangles, surfels, motion)
}

fn at(x: f64, y: f64, z: f64) -> Pose {
    Pose {
        translation: DVec3::new(x, y, z),
        ..Pose::IDENTITY
    }
}

/// A `size` × `size` image looking down −z from z = 10 at the origin, 1 spatial sample per pixel
/// (at the pixel's centre), black background, unlit.
fn scene(size: u32, samples: u32) -> Scene {
    let camera = Camera::new(
        DVec3::new(0.0, 0.0, 10.0),
        DVec3::ZERO,
        DVec3::Y,
        20.0,
        size,
        size,
    )
    .unwrap()
    .with_spatial_samples(samples)
    .unwrap();
    Scene::new(camera).with_background([0.0; 3]).unwrap()
}

fn render(scene: &Scene, method: &Method) -> Render {
    Plan::new(scene, method).unwrap().render(None)
}

fn pixel(image: &Framebuffer, x: u32, y: u32) -> [f32; 3] {
    image.pixels[(y * image.width + x) as usize]
}

fn all_finite(image: &Framebuffer) -> bool {
    image.pixels.iter().flatten().all(|c| c.is_finite())
}

#[test]
fn a_translating_square_covers_the_centre_pixel_for_the_closed_form_time() {
    // Side 1 sliding from x = −2 to 2 in the plane facing the camera: the ray through the
    // image centre (odd size: a pixel centre lies on it) is inside while |x| ≤ 0.5, a quarter
    // of the exposure.
    let s = scene(33, 1).with_object(object(
        "square",
        &square(1.0),
        [1.0; 3],
        &[(0.0, at(-2.0, 0.0, 0.0)), (1.0, at(2.0, 0.0, 0.0))],
    ));
    let out = render(&s, &Method::ANALYTIC);
    let p = pixel(&out.image, 16, 16);
    assert!((p[0] - 0.25).abs() < 1e-6, "{p:?}");
    assert!(out.stats.triangles.intervals > 0);
}

#[test]
fn what_moves_wholly_behind_a_still_surface_is_left_out_where_it_covers_and_drawn_elsewhere() {
    // A still blue square at z = 0 and a green one sliding behind it at z = −1, wide enough to
    // show past the blue one's right edge at the end of its slide: where the blue square covers
    // a sample all along, the green one is left out unsolved and the image is blue's alone;
    // past its edge green shows for the closed-form share.
    let blue = object(
        "blue",
        &square(2.0),
        [0.0, 0.0, 1.0],
        &[(0.0, at(0.0, 0.0, 0.0))],
    );
    let green = object(
        "green",
        &square(1.0),
        [0.0, 1.0, 0.0],
        &[(0.0, at(-0.5, 0.0, -1.0)), (1.0, at(1.5, 0.0, -1.0))],
    );
    let alone = render(&scene(33, 1).with_object(blue.clone()), &Method::ANALYTIC);
    let both = render(
        &scene(33, 1).with_object(blue).with_object(green),
        &Method::ANALYTIC,
    );
    assert!(both.stats.triangles.hidden_behind_still > 0);
    // The camera sees z = 0 over ±tan(10°)·10 = ±1.763 across 33 px: blue covers |x| ≤ 1,
    // pixels 16 ± 9.
    for x in 7..=25 {
        assert_eq!(
            pixel(&both.image, x, 16),
            pixel(&alone.image, x, 16),
            "x = {x}"
        );
    }
    // Pixel 30's centre ray meets z = −1 at x = 14/16.5 · 1.763 · 1.1 = 1.645: the green square
    // (centre −0.5 + 2s, half side 0.5) covers it from s = (1.645 − 0.5 + 0.5)/2 = 0.822 on.
    let p = pixel(&both.image, 30, 16);
    let share = 1.0 - 1.645 / 2.0;
    assert!((f64::from(p[1]) - share).abs() < 2e-3, "{p:?}, {share}");
}

#[test]
fn a_surface_receding_behind_another_is_seen_until_it_crosses() {
    // Palmér Fig. 2.1 with a crossing: a still blue square at z = 0 and a red one moving from
    // z = 1 to z = −1 in front of and then behind it; red is nearer for exactly half the time.
    let s = scene(33, 1)
        .with_object(object(
            "blue",
            &square(2.0),
            [0.0, 0.0, 1.0],
            &[(0.0, at(0.0, 0.0, 0.0))],
        ))
        .with_object(object(
            "red",
            &square(2.0),
            [1.0, 0.0, 0.0],
            &[(0.0, at(0.0, 0.0, 1.0)), (1.0, at(0.0, 0.0, -1.0))],
        ));
    let p = pixel(&render(&s, &Method::ANALYTIC).image, 16, 16);
    assert!(
        (p[0] - 0.5).abs() < 1e-6 && (p[2] - 0.5).abs() < 1e-6,
        "{p:?}"
    );
}

#[test]
fn a_square_turning_about_the_view_axis_matches_the_converged_reference() {
    // Turning 90° about z: the edges sweep quadratically in time (the TCT case). The plan cuts
    // the arc into linear sub-segments within the tolerance of it, so the two agree up to the
    // chords' departure and the reference's 2,048 instants.
    let turn = |degrees: f64| Pose {
        rotation: DQuat::from_rotation_z(degrees.to_radians()),
        ..Pose::IDENTITY
    };
    let s = scene(48, 4).with_object(object(
        "square",
        &square(2.0),
        [1.0; 3],
        &[(0.0, turn(0.0)), (1.0, turn(90.0))],
    ));
    let reference = render(&s, &Method::Reference { samples: 2048 }).image;
    let error = |tolerance_px| {
        rmse(
            &render(
                &s,
                &Method::Analytic {
                    tolerance_px,
                    receivers: Receivers::Sampled,
                },
            )
            .image,
            &reference,
        )
    };
    // At the default 0.1 px measured 0.0036; the chords' error falls with the tolerance.
    let (default, fine) = (error(0.1), error(0.03));
    assert!(
        default < 0.006 && fine < 0.5 * default,
        "RMSE {default} at 0.1 px, {fine} at 0.03 px"
    );
}

#[test]
fn analytic_converges_where_the_reference_gets_there_with_many_frames() {
    let s = scene(40, 4).with_object(object(
        "square",
        &square(1.0),
        [1.0, 0.8, 0.2],
        &[(0.0, at(-1.5, -0.5, 0.0)), (1.0, at(1.5, 0.5, -2.0))],
    ));
    let converged = render(&s, &Method::Reference { samples: 4096 }).image;
    let analytic = rmse(&render(&s, &Method::ANALYTIC).image, &converged);
    let few = rmse(
        &render(&s, &Method::Reference { samples: 8 }).image,
        &converged,
    );
    let many = rmse(
        &render(&s, &Method::Reference { samples: 128 }).image,
        &converged,
    );
    assert!(
        few > many && many > analytic,
        "N=8 {few}, N=128 {many}, analytic {analytic}"
    );
    assert!(analytic < 1e-3, "{analytic}");
}

#[test]
fn without_motion_analytic_is_the_static_image() {
    let s = scene(40, 4)
        .with_object(object(
            "a",
            &square(1.5),
            [0.2, 0.9, 0.3],
            &[(0.0, at(0.3, 0.1, 0.0))],
        ))
        .with_object(object(
            "b",
            &square(1.0),
            [0.9, 0.2, 0.3],
            &[(0.0, at(-0.2, 0.0, 0.5))],
        ));
    let still = render(&s, &Method::STATIC).image;
    let analytic = render(&s, &Method::ANALYTIC).image;
    let largest = still
        .pixels
        .iter()
        .zip(&analytic.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0f32, f32::max);
    assert!(largest < 1e-6, "{largest}");
}

#[test]
fn edge_on_degenerate_and_near_plane_crossing_triangles_stay_finite_and_bounded() {
    // Edge-on to the camera all the time: covers nothing.
    let edge_on = Pose {
        rotation: DQuat::from_rotation_y(90f64.to_radians()),
        ..Pose::IDENTITY
    };
    let s = scene(24, 4).with_object(object("edge-on", &square(2.0), [1.0; 3], &[(0.0, edge_on)]));
    for method in [Method::STATIC, Method::ANALYTIC] {
        let image = render(&s, &method).image;
        let brightest = image.pixels.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
        assert!(brightest < 0.05, "{} {brightest}", method.name());
    }
    // Turning through edge-on during the shutter.
    let turning = |degrees: f64| Pose {
        rotation: DQuat::from_rotation_y(degrees.to_radians()),
        ..Pose::IDENTITY
    };
    let s = scene(24, 4).with_object(object(
        "turning",
        &square(2.0),
        [1.0; 3],
        &[(0.0, turning(45.0)), (1.0, turning(135.0))],
    ));
    let analytic = render(&s, &Method::ANALYTIC).image;
    let reference = render(&s, &Method::Reference { samples: 1024 }).image;
    assert!(all_finite(&analytic));
    assert!(
        rmse(&analytic, &reference) < 5e-3,
        "{}",
        rmse(&analytic, &reference)
    );
    // Flying through the camera: the near plane is crossed mid-shutter; the triangle is left
    // out while a corner is behind it, as each reference frame leaves it out.
    let s = scene(24, 4).with_object(object(
        "flying",
        &square(0.5),
        [1.0; 3],
        &[(0.0, at(0.0, 0.0, 0.0)), (1.0, at(0.0, 0.0, 20.0))],
    ));
    let out = render(&s, &Method::ANALYTIC);
    assert!(all_finite(&out.image));
    let reference = render(&s, &Method::Reference { samples: 1024 }).image;
    assert!(
        rmse(&out.image, &reference) < 0.02,
        "{}",
        rmse(&out.image, &reference)
    );
}

#[test]
fn the_image_does_not_depend_on_the_thread_count() {
    let s = scene(64, 4).with_object(object(
        "square",
        &square(1.0),
        [1.0, 0.5, 0.2],
        &[
            (0.0, at(-1.0, 0.0, 0.0)),
            (
                1.0,
                Pose {
                    translation: DVec3::new(1.0, 0.3, -1.0),
                    rotation: DQuat::from_rotation_z(1.0),
                    scale: 1.0,
                },
            ),
        ],
    ));
    let in_pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render(&s, &Method::ANALYTIC).image)
    };
    assert_eq!(in_pool(1).pixels, in_pool(3).pixels);
}

/// Light from direction `direction` (casting shadows) over ambient `ambient`.
fn lit(scene: Scene, ambient: f64, direction: DVec3, intensity: f64) -> Scene {
    let light = Light::new(direction, intensity).unwrap().with_shadows(true);
    scene.with_lighting(Lighting::new(ambient, vec![light]).unwrap())
}

/// A `size` × `size` view (one sample per pixel) of a white 8 × 8 floor at z = 0, lit from
/// (1, 0, 1) with ambient 0.2 and 0.8 more where lit, under a black square of side `side` posed
/// at `keys`.
fn floor_under_square(size: u32, side: f64, keys: &[(f64, Pose)]) -> Scene {
    lit(scene(size, 1), 0.2, DVec3::new(1.0, 0.0, 1.0), 0.8)
        .with_object(object(
            "floor",
            &square(8.0),
            [1.0; 3],
            &[(0.0, at(0.0, 0.0, 0.0))],
        ))
        .with_object(object("occluder", &square(side), [0.0; 3], keys))
}

#[test]
fn a_directional_map_frames_what_the_camera_sees() {
    // The floor and its unit square, seen 3.5 units across, shadowed where x ∈ [−1.5, −0.5].
    let near = floor_under_square(33, 1.0, &[(0.0, at(0.0, 0.0, 1.0))]);
    let plan = Plan::new(&near, &Method::STATIC).unwrap();
    assert!(plan.departures().is_empty(), "{:?}", plan.departures());
    let speck = |x: f64, z: f64| object("speck", &square(0.01), [1.0; 3], &[(0.0, at(x, 0.0, z))]);
    // A speck 10⁴ units off screen, which can shadow nothing seen, leaves the image as it was,
    // and no note. A map framing the speck too had texels 10 units wide, lost the square's
    // shadow (a mean difference of 0.042 over the image) and noted all three objects.
    let off_screen = near.clone().with_object(speck(1e4, 0.0));
    let [with, without] = [&off_screen, &near].map(|s| render(s, &Method::STATIC).image);
    // Pixel (4, 16) is the floor at x ≈ −1.3, in the shadow: 0.2 (ambient).
    assert!((pixel(&without, 4, 16)[0] - 0.2).abs() < 1e-3);
    assert!(with.pixels == without.pixels);
    let plan = Plan::new(&off_screen, &Method::STATIC).unwrap();
    assert!(plan.departures().is_empty(), "{:?}", plan.departures());
    // `--explain` says what the map spans: the same with the speck as without.
    let span = |plan: &Plan| {
        let explain = plan.explain(None);
        let at = explain.find("shadow map spans ").expect(&explain);
        explain[at..].split(" units").next().unwrap().to_string()
    };
    let without_speck = span(&Plan::new(&near, &Method::STATIC).unwrap());
    assert_eq!(span(&plan), without_speck);
    // The square 1000 units up the light (behind the camera, out of view) casts the same
    // shadow: the map's near plane stands before every object that may shadow what is seen.
    let up = 1000.0 * std::f64::consts::FRAC_1_SQRT_2;
    let high = floor_under_square(33, 1.0, &[(0.0, at(up, 0.0, 1.0 + up))]);
    let shadow = pixel(&render(&high, &Method::STATIC).image, 4, 16);
    assert!((shadow[0] - 0.2).abs() < 1e-3, "{shadow:?}");
    // A speck seen 10⁴ units beneath the floor (behind it, but within the view) widens what the
    // map frames to about 10⁴ units, and the square's shadow falls within two texels: a note.
    let deep = near.with_object(speck(0.0, -1e4));
    let notes = Plan::new(&deep, &Method::STATIC).unwrap().departures();
    assert!(
        notes
            .iter()
            .any(|n| n.starts_with("\"occluder\" is 1.414 across, within two texels")),
        "{notes:?}"
    );
}

#[test]
fn a_still_floor_under_a_sliding_occluder_is_lit_for_the_closed_form_time() {
    // The floor z = 0 is seen straight down at its centre pixel, which is the point (0, 0).
    // Light comes from (1, 0, 1): the point is in the shadow of the black unit square at
    // height 1 while the square's x lies in [0.5, 1.5], a quarter of its slide from −2 to 2;
    // the square hides the point itself while its x is in [−0.5, 0.5], another quarter.
    // Lit: 0.2 + 0.8·cos 45°; shadowed: 0.2; hidden: black.
    let s = floor_under_square(
        33,
        1.0,
        &[(0.0, at(-2.0, 0.0, 1.0)), (1.0, at(2.0, 0.0, 1.0))],
    );
    let lit = 0.2 + 0.8 * std::f64::consts::FRAC_1_SQRT_2;
    let expected = 0.5 * lit + 0.25 * 0.2;
    let out = render(&s, &Method::ANALYTIC);
    let p = pixel(&out.image, 16, 16);
    // The shadow map's tiles that only the floor reaches hold no occluders (the floor cannot
    // shadow itself); the ones the occluder reaches do, or the shadow above would be missing.
    let stats = out.stats.triangles;
    assert!(
        0 < stats.shadow_tiles_left_empty && stats.shadow_tiles_left_empty < stats.shadow_tiles,
        "{stats:?}"
    );
    // The occluder's pieces are counted, far within the budget: the map as asked, nothing cut.
    let lists = stats.shadow_lists;
    assert!(
        lists.pieces > 0 && lists.coarsened.is_none() && lists.cap.is_none(),
        "{lists:?}"
    );
    // Percentage-closer filtering blurs each shadow edge over a texel: 0.01 units of a 4-unit
    // slide, 0.3 % of the time.
    assert!(
        (f64::from(p[0]) - expected).abs() < 2e-3,
        "{p:?} against {expected}"
    );
    // The reference converges to the same.
    let reference = pixel(
        &render(&s, &Method::Reference { samples: 512 }).image,
        16,
        16,
    );
    assert!(
        (f64::from(reference[0]) - expected).abs() < 5e-3,
        "{reference:?}"
    );
}

#[test]
fn at_an_instant_only_tiles_a_shadow_may_reach_look_up_their_shadow_map() {
    // A 48 × 48 image (tiles of 16 px) of a still floor at z = 0, and a still black square of
    // side 0.4 at height 1 over the origin, lit from (1, 0, 1): the square's shadow falls on
    // x, y in [−1.2, −0.8] × [−0.2, 0.2], in the middle row's first tile, while the square
    // itself is seen in its second. No other tile's samples can read a texel the square
    // reaches, and they look up nothing.
    let s = floor_under_square(48, 0.4, &[(0.0, at(0.0, 0.0, 1.0))]);
    let lit_value = 0.2 + 0.8 * std::f64::consts::FRAC_1_SQRT_2;
    // 3.53 units across 48 px: x = −1.0 at px 10.4, x = 1.2 at px 40.3.
    for method in [Method::STATIC, Method::Reference { samples: 4 }] {
        let out = render(&s, &method);
        let shadowed = pixel(&out.image, 10, 24);
        let lit = pixel(&out.image, 40, 24);
        assert!(
            (f64::from(shadowed[0]) - 0.2).abs() < 1e-6,
            "{method:?} {shadowed:?}"
        );
        assert!(
            (f64::from(lit[0]) - lit_value).abs() < 1e-6,
            "{method:?} {lit:?}"
        );
        // One lookup per sample, made only in those two tiles of 16 × 16 samples (the
        // square's own samples there may be left out too: it cannot shadow itself); each
        // frame alike.
        let frames = match method {
            Method::Reference { samples } => samples,
            _ => 1,
        };
        let stats = out.stats.triangles;
        assert_eq!(
            stats.shadow_lookups + stats.shadow_lookups_left_out,
            48 * 48 * frames
        );
        assert!(
            stats.shadow_lookups > 0 && stats.shadow_lookups <= 2 * 16 * 16 * frames,
            "{stats:?}"
        );
    }
}

#[test]
fn still_triangles_reaching_behind_the_near_plane_keep_their_part_in_front() {
    // A slope rising from z = 0 past the eye (z = 10) to z = 12: both its triangles have corners
    // behind the eye. The centre ray meets it at z = 6, in front: it was left out whole.
    let slope = quad([
        [-5.0, -5.0, 0.0],
        [5.0, -5.0, 0.0],
        [5.0, 5.0, 12.0],
        [-5.0, 5.0, 12.0],
    ]);
    let s = scene(33, 1).with_object(object(
        "slope",
        &slope,
        [1.0; 3],
        &[(0.0, at(0.0, 0.0, 0.0))],
    ));
    for method in [
        Method::STATIC,
        Method::Reference { samples: 2 },
        Method::ANALYTIC,
    ] {
        let out = render(&s, &method);
        assert!(all_finite(&out.image), "{method:?}");
        assert_eq!(pixel(&out.image, 16, 16), [1.0; 3], "{method:?}");
        assert_eq!(out.stats.triangles.behind_near, 0, "{method:?}");
    }
    // A spot at (0, 0, 3) shining down on a floor, beside a wall at x = 0.5 rising from z = 0.5
    // past the spot's own plane to z = 5: the wall reaches behind the spot's near plane, and
    // still shadows the floor beyond x = 0.6 (seen at x = 1.3, pixel 28), where before the
    // shadow map left it out and the floor was lit. The floor at x = −1 (pixel 7) stays lit.
    let wall = quad([
        [0.5, -1.0, 0.5],
        [0.5, 1.0, 0.5],
        [0.5, 1.0, 5.0],
        [0.5, -1.0, 5.0],
    ]);
    let spot =
        |position: DVec3| streak::scene::Spot::new(position, DVec3::ZERO, 60.0, 1.0, true).unwrap();
    let lit_by = |position: DVec3| {
        scene(33, 1)
            .with_lighting(
                Lighting::new(0.2, Vec::new())
                    .unwrap()
                    .with_spots(vec![spot(position)]),
            )
            .with_object(object(
                "floor",
                &square(8.0),
                [1.0; 3],
                &[(0.0, at(0.0, 0.0, 0.0))],
            ))
    };
    let walled = lit_by(DVec3::new(0.0, 0.0, 3.0)).with_object(object(
        "wall",
        &wall,
        [1.0; 3],
        &[(0.0, at(0.0, 0.0, 0.0))],
    ));
    // A spot inside a closed unit cube standing over the floor: from inside, every face of the
    // cube faces away from the light, and culling back faces left none to cast a shadow.
    let boxed = lit_by(DVec3::new(0.0, 0.0, 0.5)).with_object(object(
        "box",
        &Mesh::cuboid(DVec3::ONE),
        [1.0; 3],
        &[(0.0, at(0.0, 0.0, 0.6))],
    ));
    for (s, name) in [(walled, "wall"), (boxed, "box")] {
        for method in [Method::STATIC, Method::ANALYTIC] {
            let image = render(&s, &method).image;
            let shadowed = pixel(&image, 28, 16)[0];
            assert!(
                (shadowed - 0.2).abs() < 1e-6,
                "{name} {method:?}: {shadowed}"
            );
            if name == "wall" {
                let lit = pixel(&image, 7, 16)[0];
                assert!(lit > 0.3, "{method:?}: {lit}");
            }
        }
    }
}

#[test]
fn a_face_turning_away_from_the_light_is_lit_while_it_faces_it() {
    // A square turning about y from −80° to 80° (normal (sin θ, 0, cos θ)) under light from −x:
    // N·L = −sin θ, positive for the first half (Palmér eq. 2.5). At its centre, on the axis,
    // the irradiance over the exposure is ∫₀^½ sin(θ₀(1 − 2t)) dt = (1 − cos θ₀)/(2θ₀).
    let turn = |degrees: f64| Pose {
        rotation: DQuat::from_rotation_y(degrees.to_radians()),
        ..Pose::IDENTITY
    };
    let s = lit(scene(33, 1), 0.0, DVec3::new(-1.0, 0.0, 0.0), 1.0).with_object(object(
        "turning",
        &square(2.0),
        [1.0; 3],
        &[(0.0, turn(-80.0)), (0.5, turn(0.0)), (1.0, turn(80.0))],
    ));
    let theta = 80f64.to_radians();
    let expected = (1.0 - theta.cos()) / (2.0 * theta);
    let p = pixel(&render(&s, &Method::ANALYTIC).image, 16, 16);
    assert!(
        (f64::from(p[0]) - expected).abs() < 2e-3,
        "{p:?} against {expected}"
    );
}

#[test]
fn a_triangle_scaled_far_past_the_image_covers_the_same_half_of_it() {
    // Its hypotenuse runs through the view's centre while its corners lie ~10¹⁸ px out at scale
    // 10¹⁷: rounding its screen hull's edges by ulps of that moved them by pixels at 10¹⁶ and
    // left every row empty at 10¹⁷, with the edge functions exact throughout.
    let mesh = Mesh {
        positions: vec![
            DVec3::new(-0.5, -0.5, 0.0),
            DVec3::new(0.5, -0.5, 0.0),
            DVec3::new(-0.5, 0.5, 0.0),
        ],
        triangles: vec![[0, 1, 2]],
    };
    let image = |scale: f64, method: &Method| {
        let pose = Pose {
            scale,
            ..Pose::IDENTITY
        };
        let s = scene(24, 4).with_object(object("t", &mesh, [0.6; 3], &[(0.0, pose)]));
        render(&s, method)
    };
    for method in [Method::STATIC, Method::ANALYTIC] {
        let drawn = image(1e3, &method);
        assert_eq!(drawn.stats.departures(), Vec::<String>::new());
        let expected = drawn.image;
        let covered = expected.pixels.iter().filter(|p| p[0] > 0.0).count();
        assert!((250..=330).contains(&covered), "about half: {covered}");
        for scale in [1e15, 1e16, 1e17, 1e20, 1e100] {
            assert!(
                image(scale, &method).image.pixels == expected.pixels,
                "{} at {scale}",
                method.name()
            );
        }
        // Past 10¹⁰⁰ the depth's products of three corner coordinates would overflow (at 10¹⁶⁰
        // the edge functions' products of two did, and nothing was drawn or said): refused and
        // counted.
        let refused = image(1e160, &method);
        assert_eq!(refused.stats.triangles.too_far, 1, "{}", method.name());
        let said = refused.stats.departures();
        assert!(
            said[0].starts_with("1 triangle item(s) left out"),
            "{said:?}"
        );
        assert!(refused.image.pixels.iter().all(|p| *p == [0.0; 3]));
    }
}

#[test]
fn extreme_triangles_stay_finite_and_their_lists_bounded() {
    let cases = [
        // Across the image a million times its width in one exposure.
        ("fast", square(1.0), at(-1e6, 0.0, 0.0), at(1e6, 0.0, 0.0)),
        // A nanometre square.
        ("tiny", square(1e-9), at(0.0, 0.0, 0.0), at(1e-9, 0.0, 0.0)),
        // Far from the origin in depth, crossing the view.
        ("far", square(1e5), at(-1e5, 0.0, -1e6), at(1e5, 0.0, -1e6)),
    ];
    for (name, mesh, from, to) in cases {
        let s = lit(scene(32, 4), 0.2, DVec3::new(0.3, 0.5, 1.0), 0.8)
            .with_object(object(
                "floor",
                &square(4.0),
                [0.8; 3],
                &[(0.0, at(0.0, 0.0, -1.0))],
            ))
            .with_object(object(
                name,
                &mesh,
                [0.9, 0.1, 0.1],
                &[(0.0, from), (1.0, to)],
            ));
        for method in [
            Method::STATIC,
            Method::ANALYTIC,
            Method::Reference { samples: 8 },
        ] {
            let out = render(&s, &method);
            assert!(all_finite(&out.image), "{name} {}", method.name());
            assert!(
                out.stats.triangles.peak_per_sample
                    <= streak::render::triangles::MAX_INTERVALS_PER_SAMPLE,
                "{name}"
            );
        }
    }
}

#[test]
fn a_sample_behind_hundreds_of_layers_keeps_what_is_in_front() {
    // 1,100 squares stacked behind a red one sliding past, one triangle of each over the centre:
    // more intervals than a list holds (1,024), so it is compressed to its visible pieces; the
    // centre pixel is red for the quarter of the exposure the slider covers it and the nearest
    // layer (blue) otherwise. The layers drift a hair, so that none is left out unsolved behind
    // a still one before the list fills.
    let mut s = scene(33, 1).with_object(object(
        "slider",
        &square(1.0),
        [1.0, 0.0, 0.0],
        &[(0.0, at(-2.0, 0.0, 1.0)), (1.0, at(2.0, 0.0, 1.0))],
    ));
    for k in 0..1100 {
        let colour = if k == 0 {
            [0.0, 0.0, 1.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        s = s.with_object(object(
            "layer",
            &square(2.0),
            colour,
            &[
                (0.0, at(0.0, 0.0, -0.01 * f64::from(k))),
                (1.0, at(0.0, 1e-4, -0.01 * f64::from(k))),
            ],
        ));
    }
    let out = render(&s, &Method::ANALYTIC);
    assert!(
        out.stats.triangles.compressed > 0,
        "{:?}",
        out.stats.triangles
    );
    assert_eq!(out.stats.triangles.dropped, 0);
    let p = pixel(&out.image, 16, 16);
    assert!(
        (p[0] - 0.25).abs() < 1e-4 && p[1].abs() < 1e-4 && (p[2] - 0.75).abs() < 1e-4,
        "{p:?}"
    );
}

/// A floor rising from z = −1 to 1.9 towards the camera under a still black unit square at
/// height 2 centred at x = 1, lit from (1, 0, 1).
fn rising_floor() -> Scene {
    lit(scene(33, 1), 0.2, DVec3::new(1.0, 0.0, 1.0), 0.8)
        .with_object(object(
            "floor",
            &square(8.0),
            [1.0; 3],
            &[(0.0, at(0.0, 0.0, -1.0)), (1.0, at(0.0, 0.0, 1.9))],
        ))
        .with_object(object(
            "occluder",
            &square(1.0),
            [0.0; 3],
            &[(0.0, at(1.0, 0.0, 2.0))],
        ))
}

#[test]
fn a_floor_moving_in_depth_under_a_still_occluder_is_shadowed_for_the_closed_form_time() {
    // The centre pixel sees the point (0, 0, z) of a floor rising from z = −1 to 1.9 towards
    // the camera. Light from (1, 0, 1): the unit square at height 2, centred at x = 1, shadows
    // the point while 2 − z lies in [0.5, 1.5], z in [0.5, 1.5]: 1/2.9 of the exposure, during
    // which the point sweeps shadow-map texels (a dynamic receiver).
    let s = rising_floor();
    let lit = 0.2 + 0.8 * std::f64::consts::FRAC_1_SQRT_2;
    let expected = lit - (1.0 / 2.9) * (lit - 0.2);
    for receivers in [Receivers::Sampled, Receivers::Traced] {
        let method = Method::Analytic {
            tolerance_px: 0.1,
            receivers,
        };
        let p = pixel(&render(&s, &method).image, 16, 16);
        assert!(
            (f64::from(p[0]) - expected).abs() < 3e-3,
            "{receivers:?}: {p:?} against {expected}"
        );
    }
}

#[test]
fn a_floor_turning_under_a_still_occluder_stays_in_its_shadow_over_every_sub_segment() {
    // The floor of the sliding-occluder test turns 30° about the vertical through (1.5, 0): the
    // point (0, 0) under the centre pixel stays where it is and on one triangle, which crosses
    // it over many sub-segments (a run of pieces). The still unit square centred at (1, 0, 1)
    // shadows it throughout under light from (1, 0, 1): ambient only. Without the square, lit.
    let turned = |degrees: f64| Pose {
        rotation: DQuat::from_rotation_z(degrees.to_radians()),
        ..at(1.5, 0.0, 0.0)
    };
    let floor = object(
        "floor",
        &square(8.0),
        [1.0; 3],
        &[(0.0, turned(0.0)), (1.0, turned(30.0))],
    );
    let open = lit(scene(33, 1), 0.2, DVec3::new(1.0, 0.0, 1.0), 0.8).with_object(floor);
    let shaded = open.clone().with_object(object(
        "occluder",
        &square(1.0),
        [0.0; 3],
        &[(0.0, at(1.0, 0.0, 1.0))],
    ));
    let out = render(&shaded, &Method::ANALYTIC);
    let p = pixel(&out.image, 16, 16);
    assert!((f64::from(p[0]) - 0.2).abs() < 1e-3, "{p:?}");
    let lit_value = 0.2 + 0.8 * std::f64::consts::FRAC_1_SQRT_2;
    let p = pixel(&render(&open, &Method::ANALYTIC).image, 16, 16);
    assert!((f64::from(p[0]) - lit_value).abs() < 1e-3, "{p:?}");
}

#[test]
fn more_shadowed_lights_than_the_cap_are_refused_by_name() {
    use streak::render::MAX_SHADOWED_LIGHTS;
    let lights = |count: usize| {
        (0..count)
            .map(|k| {
                Light::new(DVec3::new(k as f64, 1.0, 1.0), 0.1)
                    .unwrap()
                    .with_shadows(true)
            })
            .collect::<Vec<_>>()
    };
    let with = |count| {
        scene(9, 1)
            .with_lighting(Lighting::new(0.1, lights(count)).unwrap())
            .with_object(object(
                "floor",
                &square(2.0),
                [1.0; 3],
                &[(0.0, at(0.0, 0.0, 0.0))],
            ))
    };
    assert!(Plan::new(&with(MAX_SHADOWED_LIGHTS), &Method::ANALYTIC).is_ok());
    let Err(error) = Plan::new(&with(MAX_SHADOWED_LIGHTS + 1), &Method::ANALYTIC) else {
        panic!("{} shadowed lights accepted", MAX_SHADOWED_LIGHTS + 1);
    };
    let error = error.to_string();
    assert!(
        error.contains("lighting") && error.contains("cast shadows"),
        "{error}"
    );
}

#[test]
fn a_light_whose_shadow_map_cannot_be_made_is_refused_by_name() {
    use streak::scene::Spot;
    // A non-square image: a shadow map that fell back to the scene's camera was read as square
    // and indexed past its tiles.
    let camera = Camera::new(
        DVec3::new(0.0, 0.0, 10.0),
        DVec3::ZERO,
        DVec3::Y,
        20.0,
        12,
        9,
    )
    .unwrap();
    let floor = |p: DVec3| object("floor", &square(2.0), [1.0; 3], &[(0.0, at(p.x, p.y, p.z))]);
    let spot =
        |distance: f64| Spot::new(DVec3::splat(distance), DVec3::ZERO, 30.0, 1.0, true).unwrap();
    let sun = Light::new(DVec3::new(0.3, 1.0, 0.2), 0.5)
        .unwrap()
        .with_shadows(true);
    // A second floor at `p`.
    let with = |lighting: Lighting, p: DVec3| {
        Scene::new(camera.clone())
            .with_lighting(lighting)
            .with_object(floor(DVec3::ZERO))
            .with_object(floor(p))
    };
    let spot_at = |distance| {
        Lighting::new(0.1, Vec::new())
            .unwrap()
            .with_spots(vec![spot(distance)])
    };
    let sun_over = |p| with(Lighting::new(0.1, vec![sun]).unwrap(), p);
    let right = DVec3::new(3.0, 0.0, 0.0);
    // A spot 10¹⁸ away cannot step along its direction in double precision; a floor 10³⁰⁷ up
    // the light from what is seen, which may shadow it, puts a directional light's view at
    // infinity. (A floor 10³⁰⁰ off to the side shadows nothing seen, and is not framed.)
    for (scene, light) in [
        (with(spot_at(1e18), right), "spot"),
        (sun_over(sun.direction * 1e307), "directional"),
    ] {
        let Err(error) = Plan::new(&scene, &Method::ANALYTIC) else {
            panic!("the {light} light's shadow map was made");
        };
        let error = error.to_string();
        assert!(
            error.contains("lighting") && error.contains(light) && error.contains("shadow map"),
            "{error}"
        );
    }
    let aside = DVec3::new(1e300, 0.0, 0.0);
    for scene in [with(spot_at(10.0), right), sun_over(right), sun_over(aside)] {
        assert!(all_finite(&render(&scene, &Method::ANALYTIC).image));
    }
}

#[test]
fn only_receivers_that_sweep_texels_and_may_be_shadowed_are_point_sampled() {
    // A square sliding under a light with nothing above it: lit for sure all along, so none of
    // its pieces is point-sampled, though it sweeps many shadow-map texels. A floor rising under
    // a still occluder (the closed-form test above) is point-sampled.
    let count = |s: &Scene| {
        let stats = render(s, &Method::ANALYTIC).stats.triangles;
        assert!(stats.pieces > 0);
        stats.point_sampled
    };
    let alone = lit(scene(33, 1), 0.2, DVec3::new(1.0, 0.0, 1.0), 0.8).with_object(object(
        "slider",
        &square(1.0),
        [1.0; 3],
        &[(0.0, at(-2.0, 0.0, 0.0)), (1.0, at(2.0, 0.0, 0.0))],
    ));
    assert_eq!(count(&alone), 0);
    let rising = rising_floor();
    assert!(count(&rising) > 0);
}

#[test]
fn a_mesh_that_can_shadow_itself_does_and_a_convex_one_is_lit_throughout() {
    // Light from (1, 0, 1), seen straight down. A 2 × 2 floor at z = 0 with a wall of height 1
    // standing at x = 0.5, as one mesh: the floor's centre point (0, 0) is shadowed by its own
    // wall (the ray to the light meets x = 0.5 at z = 0.5), so the centre pixel is ambient only.
    let lit_value = 0.2 + 0.8 * std::f64::consts::FRAC_1_SQRT_2;
    let mut folded = square(2.0);
    folded.positions.extend([
        DVec3::new(0.5, -1.0, 0.0),
        DVec3::new(0.5, 1.0, 0.0),
        DVec3::new(0.5, 1.0, 1.0),
        DVec3::new(0.5, -1.0, 1.0),
    ]);
    folded.triangles.extend([[4, 5, 6], [4, 6, 7]]);
    let with = |mesh: &Mesh, keys: &[(f64, Pose)]| {
        lit(scene(33, 1), 0.2, DVec3::new(1.0, 0.0, 1.0), 0.8)
            .with_object(object("mesh", mesh, [1.0; 3], keys))
    };
    let still = [(0.0, at(0.0, 0.0, 0.0))];
    let out = render(&with(&folded, &still), &Method::ANALYTIC);
    let p = pixel(&out.image, 16, 16);
    assert!((f64::from(p[0]) - 0.2).abs() < 1e-3, "{p:?}");
    // No shadow-map tile is left empty for a mesh that can shadow itself.
    assert_eq!(out.stats.triangles.shadow_tiles_left_empty, 0);
    // Without its wall the floor is planar, and lit.
    let p = pixel(
        &render(&with(&square(2.0), &still), &Method::ANALYTIC).image,
        16,
        16,
    );
    assert!((f64::from(p[0]) - lit_value).abs() < 1e-3, "{p:?}");
    // A cube sliding and turning about the view axis: the middle of its top face, which faces
    // the camera all along, is lit all along, and none of its pieces needs point sampling.
    let turned = |x: f64, degrees: f64| Pose {
        rotation: DQuat::from_rotation_z(degrees.to_radians()),
        ..at(x, 0.0, 0.0)
    };
    let drawn = TriangleMesh::new(&Mesh::cuboid(DVec3::ONE), DVec3::ZERO, Colouring::Own).unwrap();
    assert!(drawn.closed && !drawn.shadows_itself);
    let out = render(
        &with(
            &Mesh::cuboid(DVec3::ONE),
            &[(0.0, turned(-0.1, 0.0)), (1.0, turned(0.1, 40.0))],
        ),
        &Method::ANALYTIC,
    );
    let p = pixel(&out.image, 16, 16);
    assert!((f64::from(p[0]) - lit_value).abs() < 1e-3, "{p:?}");
    assert_eq!(out.stats.triangles.point_sampled, 0);
}

/// A unit sphere as `rings` × `segments` quads between its poles, wound outward.
fn uv_sphere(rings: u32, segments: u32) -> Mesh {
    let mut positions = vec![DVec3::Y];
    for i in 1..rings {
        let theta = std::f64::consts::PI * f64::from(i) / f64::from(rings);
        for j in 0..segments {
            let phi = std::f64::consts::TAU * f64::from(j) / f64::from(segments);
            positions.push(DVec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            ));
        }
    }
    positions.push(-DVec3::Y);
    let bottom = positions.len() as u32 - 1;
    let at = |i: u32, j: u32| 1 + (i - 1) * segments + j % segments;
    let mut triangles = Vec::new();
    for j in 0..segments {
        triangles.push([0, at(1, j), at(1, j + 1)]);
        triangles.push([bottom, at(rings - 1, j + 1), at(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            let [a, b, c, d] = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    Mesh {
        positions,
        triangles,
    }
}

#[test]
fn a_smooth_mesh_lit_from_above_is_ambient_only_below_its_equator_up_to_its_silhouette() {
    // Light straight down on a smooth sphere seen from the side: every point below the equator
    // band faces away from the light, so no pixel there may be brighter than ambient × albedo,
    // its silhouette included, where smooth normals face away from the eye on triangles that
    // face it (turned to the eye's side, they would be lit from inside).
    let sphere = uv_sphere(24, 48);
    let drawn = TriangleMesh::new(&sphere, DVec3::ZERO, Colouring::Own).unwrap();
    assert!(drawn.closed);
    for shadows in [false, true] {
        let light = Light::new(DVec3::Y, 0.8).unwrap().with_shadows(shadows);
        let s = scene(201, 4)
            .with_lighting(Lighting::new(0.2, vec![light]).unwrap())
            .with_object(object(
                "sphere",
                &sphere,
                [1.0; 3],
                &[(0.0, at(0.0, 0.0, 0.0))],
            ));
        for method in [Method::STATIC, Method::ANALYTIC] {
            let image = render(&s, &method).image;
            // Rows 125–200 lie below y = −0.43 on the sphere (57 px per unit).
            let brightest = (125..201)
                .flat_map(|y| (0..201).map(move |x| (x, y)))
                .map(|(x, y)| pixel(&image, x, y)[0])
                .fold(0.0f32, f32::max);
            assert!(
                brightest <= 0.2 + 1e-5,
                "{} shadows {shadows}: {brightest}",
                method.name()
            );
        }
    }
}

#[test]
fn a_floor_rising_through_a_spots_soft_edge_is_lit_as_the_reference_sees_it() {
    // A spot straight down from (2, 0, 5), half-angle 25°: the point (0, 0, z) the centre pixel
    // sees leaves the cone through its soft edge while the floor rises from z = −1 to 1.9, in a
    // small part of the exposure. Three quadrature points over the piece miss that ramp (9 % too
    // dark at any tolerance); cut where the point crosses the cone's edges, each part is smooth.
    // The tent shutter's kink is cut as well. Against the reference at 2,048 frames, whose
    // midpoint rule errs far below the tolerance on a light this smooth in time.
    let spot = streak::scene::Spot::new(
        DVec3::new(2.0, 0.0, 5.0),
        DVec3::new(2.0, 0.0, 0.0),
        25.0,
        1.0,
        false,
    )
    .unwrap();
    for shape in [
        streak::scene::ShutterShape::Box,
        streak::scene::ShutterShape::Tent,
    ] {
        let s = scene(33, 1)
            .with_lighting(
                Lighting::new(0.1, Vec::new())
                    .unwrap()
                    .with_spots(vec![spot]),
            )
            .with_shutter(streak::scene::Shutter::new(0.0, 1.0, shape).unwrap())
            .with_object(object(
                "floor",
                &square(8.0),
                [1.0; 3],
                &[(0.0, at(0.0, 0.0, -1.0)), (1.0, at(0.0, 0.0, 1.9))],
            ));
        let reference = pixel(
            &render(&s, &Method::Reference { samples: 2048 }).image,
            16,
            16,
        );
        for tolerance_px in [0.1, 0.01] {
            let method = Method::Analytic {
                tolerance_px,
                receivers: Receivers::Sampled,
            };
            let p = pixel(&render(&s, &method).image, 16, 16);
            assert!(
                (p[0] - reference[0]).abs() < 1e-3,
                "{shape:?}, τ = {tolerance_px}: {p:?} against {reference:?}"
            );
        }
    }
}

#[test]
fn a_point_sampled_receiver_takes_its_colour_at_each_sample() {
    // A floor coloured red at x = −4 and green at x = 4 (corners' colours) slides from x = −3 to
    // 3 while it rises through a still occluder's shadow, far enough to sweep texels: it is point
    // sampled. The centre pixel sees red's share go from 1/8 to 7/8 while the light changes, so
    // its colour is not the middle's times the mean light (±0.009 in red and green).
    let red = [1.0, 0.0, 0.0];
    let green = [0.0, 1.0, 0.0];
    let mut floor = object(
        "floor",
        &square(8.0),
        [1.0; 3],
        &[(0.0, at(-3.0, 0.0, -1.0)), (1.0, at(3.0, 0.0, 1.9))],
    );
    if let streak::scene::Geometry::Triangles { mesh, .. } = &mut floor.geometry {
        mesh.colours = vec![red, green, green, red];
    }
    let light = Light::new(DVec3::new(1.0, 0.0, 1.0), 0.8)
        .unwrap()
        .with_shadows(true);
    let s = scene(33, 1)
        .with_lighting(Lighting::new(0.2, vec![light]).unwrap())
        .with_object(floor)
        .with_object(object(
            "occluder",
            &square(1.0),
            [1.0; 3],
            &[(0.0, at(1.0, 0.0, 2.0))],
        ));
    let reference = pixel(
        &render(&s, &Method::Reference { samples: 2048 }).image,
        16,
        16,
    );
    let sampled = render(
        &s,
        &Method::Analytic {
            tolerance_px: 0.1,
            receivers: Receivers::Sampled,
        },
    );
    assert!(sampled.stats.triangles.point_sampled > 0);
    let p = pixel(&sampled.image, 16, 16);
    for c in 0..2 {
        assert!(
            (p[c] - reference[c]).abs() < 1e-3,
            "channel {c}: {p:?} against {reference:?}"
        );
    }
}

#[test]
fn a_face_turning_under_a_gaussian_shutter_is_lit_for_the_weighted_mean() {
    // A square turning about y from −40° to 40° under light from +z (towards the camera):
    // N·L = cos θ > 0 all along, so the centre's run is one piece with no cut, and its mean
    // irradiance is cos(θ₀(2t − 1)) weighted by the shutter (a fine midpoint rule here). Three
    // Gauss–Legendre points over the whole exposure weighted by a Gaussian of σ = 1/6 put 0.89
    // of the weight on the middle node: 1.5·10⁻² too bright.
    let turn = |degrees: f64| Pose {
        rotation: DQuat::from_rotation_y(degrees.to_radians()),
        ..Pose::IDENTITY
    };
    let theta = 40f64.to_radians();
    for shape in [
        streak::scene::ShutterShape::Box,
        streak::scene::ShutterShape::Tent,
        streak::scene::ShutterShape::Gaussian,
    ] {
        let shutter = streak::scene::Shutter::new(0.0, 1.0, shape).unwrap();
        let s = lit(scene(33, 1), 0.0, DVec3::new(0.0, 0.0, 1.0), 1.0)
            .with_shutter(shutter)
            .with_object(object(
                "turning",
                &square(2.0),
                [1.0; 3],
                &[(0.0, turn(-40.0)), (0.5, turn(0.0)), (1.0, turn(40.0))],
            ));
        let n = 200_000;
        let (mut sum, mut weight) = (0.0, 0.0);
        for i in 0..n {
            let t = (f64::from(i) + 0.5) / f64::from(n);
            let w = shutter.weight(t);
            sum += w * (theta * (2.0 * t - 1.0)).cos();
            weight += w;
        }
        let expected = sum / weight;
        let p = pixel(&render(&s, &Method::ANALYTIC).image, 16, 16);
        assert!(
            (f64::from(p[0]) - expected).abs() < 1e-3,
            "{shape:?}: {p:?} against {expected}"
        );
    }
}

#[test]
fn a_receiver_turning_to_face_the_light_takes_its_depth_bias_at_each_time() {
    // A 2 × 2 square turning about y between θ = −25° and 60° under light from 60° (its normal
    // from 85° off the light to facing it, or back), a small still square hovering 0.04 above
    // the centre point, facing the light, in a 256² shadow map. The depth bias grows with the
    // angle to the light (2(1 + tan α) texels), so the point is shadowed only while it nearly
    // faces the light.
    // One piece of the receiver turns ~14°: taking the bias of its start for all of it (as
    // before) lit the centre 0.03 too long one way and too short the other. The reference
    // places each of its instants with that instant's normal. A still square below, larger
    // than the receiver, frames the shadow map alike at every instant and over the exposure, so
    // the texels, and so the biases, are the same for both methods.
    let phi = 60f64.to_radians();
    let l = DVec3::new(phi.sin(), 0.0, phi.cos());
    let turn = |degrees: f64| Pose {
        rotation: DQuat::from_rotation_y(degrees.to_radians()),
        ..Pose::IDENTITY
    };
    let c = l * 0.04;
    let hovering = Pose {
        rotation: DQuat::from_rotation_y(phi),
        ..at(c.x, c.y, c.z)
    };
    for (from, to) in [(-25.0, 60.0), (60.0, -25.0)] {
        let light = Light::new(l, 1.0).unwrap().with_shadows(true);
        let lighting = Lighting::new(0.0, vec![light]).unwrap();
        let s = scene(33, 1)
            .with_lighting(lighting.with_shadow_map(256).unwrap())
            .with_object(object(
                "receiver",
                &square(2.0),
                [1.0; 3],
                &[(0.0, turn(from)), (1.0, turn(to))],
            ))
            .with_object(object(
                "hovering",
                &square(0.02),
                [0.0; 3],
                &[(0.0, hovering)],
            ))
            .with_object(object(
                "frame",
                &square(2.2),
                [1.0; 3],
                &[(0.0, at(0.0, 0.0, -1.2))],
            ));
        let analytic = pixel(&render(&s, &Method::ANALYTIC).image, 16, 16)[0];
        let reference = pixel(
            &render(&s, &Method::Reference { samples: 1024 }).image,
            16,
            16,
        )[0];
        assert!(
            (analytic - reference).abs() < 3e-3,
            "{from}° to {to}°: analytic {analytic}, reference {reference}"
        );
    }
}

#[test]
fn every_method_and_tolerance_sees_the_same_shadow_map() {
    // A bar from 0.5 to 3 units off the z axis turns about it from 20° to 150° under a shadowed
    // light from above: its extent in y peaks at 90°, between the keyframes, where sub-segment
    // ends fall differently for each tolerance. The light's camera bounds the scene, not a
    // method's plan of it, so `static`, each `reference` frame and `analytic` at any tolerance
    // look the shadow map up on one texel grid.
    let bar = Mesh {
        positions: vec![
            DVec3::new(0.5, -0.1, 0.0),
            DVec3::new(3.0, -0.1, 0.0),
            DVec3::new(3.0, 0.1, 0.0),
            DVec3::new(0.5, 0.1, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    let turned = |degrees: f64| Pose {
        rotation: DQuat::from_rotation_z(degrees.to_radians()),
        ..Pose::IDENTITY
    };
    let object = object(
        "bar",
        &bar,
        [0.8; 3],
        &[(0.0, turned(20.0)), (1.0, turned(150.0))],
    );
    let scene = lit(
        scene(32, 1).with_object(object),
        0.2,
        DVec3::new(0.2, 0.3, 1.0),
        0.8,
    );
    let cameras = |method: Method| Plan::new(&scene, &method).unwrap().shadow_cameras;
    let analytic = |tolerance_px| Method::Analytic {
        tolerance_px,
        receivers: Receivers::Sampled,
    };
    let seen = cameras(analytic(0.05));
    assert_eq!(seen.len(), 1);
    for method in [
        Method::STATIC,
        Method::Reference { samples: 16 },
        analytic(1.0),
        analytic(4.0),
    ] {
        assert!(cameras(method.clone()) == seen, "{method:?}");
    }
}

#[test]
fn a_tile_holding_more_items_than_it_copies_draws_them_from_their_corners() {
    // A flat grey grid of 105,800 triangles, 4 units wide, filling a 16 × 16 view (one tile) that
    // sees about 81,000 of them, more than the tile keeps copies of; under a light at cos 0.8
    // with ambient 0.2, each pixel is 0.5 × (0.2 + 0.8 × 0.8) = 0.42, still and sliding.
    let cells = 230;
    let step = 4.0 / f64::from(cells);
    let vertex =
        |i: u32, j: u32| DVec3::new(-2.0 + step * f64::from(i), -2.0 + step * f64::from(j), 0.0);
    let positions = (0..=cells)
        .flat_map(|j| (0..=cells).map(move |i| vertex(i, j)))
        .collect();
    let corner = |i: u32, j: u32| j * (cells + 1) + i;
    let triangles = (0..cells)
        .flat_map(|j| (0..cells).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            let [a, b, c, d] = [
                corner(i, j),
                corner(i + 1, j),
                corner(i + 1, j + 1),
                corner(i, j + 1),
            ];
            [[a, b, c], [a, c, d]]
        })
        .collect();
    let grid = Mesh {
        positions,
        triangles,
    };
    let light = Light::new(DVec3::new(0.0, 0.6, 0.8), 0.8).unwrap();
    let lit = scene(16, 4).with_lighting(Lighting::new(0.2, vec![light]).unwrap());
    for (keys, method) in [
        (vec![(0.0, at(0.0, 0.0, 0.0))], Method::STATIC),
        (
            vec![(0.0, at(-0.1, 0.0, 0.0)), (1.0, at(0.1, 0.0, 0.0))],
            Method::ANALYTIC,
        ),
    ] {
        let s = lit
            .clone()
            .with_object(object("grid", &grid, [0.5; 3], &keys));
        let out = Plan::with_lod(&s, &method, streak::lod::Lod::Off)
            .unwrap()
            .render(None);
        let stats = out.stats.triangles;
        assert!(stats.unshared_tile_items > 10_000, "{stats:?}");
        for p in &out.image.pixels {
            assert!((f64::from(p[0]) - 0.42).abs() < 1e-5, "{method:?}: {p:?}");
        }
    }
}
