//! Motion hints: where trails go and what emits them, their colour ramps, the blur they reduce to,
//! speed lines under the object, and every preset in `styles/`.

mod common;

use common::*;
use glam::DVec3;
use std::path::Path;
use std::sync::Arc;
use streak::style::Style;
use streak::{render, Framebuffer, Method, Plan, Render, Scene};

fn style(text: &str) -> Arc<Style> {
    Arc::new(Style::parse(text, Path::new("test-style.toml")).unwrap())
}

fn hint(scene: &Scene, style: &Arc<Style>) -> Render {
    let method = Method::Hint {
        style: Arc::clone(style),
        tolerance_px: 1.0,
    };
    render(scene, &method, None).unwrap()
}

/// The brightness of pixel (x, y).
fn value(image: &Framebuffer, x: usize, y: usize) -> f32 {
    let p = image.pixels[y * image.width as usize + x];
    (p[0] + p[1] + p[2]) / 3.0
}

/// A 1×1 white square sliding `travel` world units along x (≈ 15 px per unit) in a 200×80 image.
fn sliding_square(travel: f64) -> Scene {
    let camera = camera(200, 80);
    let motion = motion(&[
        (0.0, pose(DVec3::new(-travel / 2.0, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::new(travel / 2.0, 0.0, 0.0), 0.0)),
    ]);
    let square = patch(DVec3::ZERO, [1.0, 1.0], 0.04, false);
    scene(camera, vec![object(square, motion)])
}

/// The x of the brightness-weighted centroid of an image.
fn centroid_x(image: &Framebuffer) -> f64 {
    let (mut sum, mut moment) = (0.0, 0.0);
    for y in 0..image.height as usize {
        for x in 0..image.width as usize {
            let v = f64::from(value(image, x, y));
            sum += v;
            moment += v * (x as f64 + 0.5);
        }
    }
    moment / sum
}

#[test]
fn trails_point_away_from_the_direction_of_motion() {
    let trail_only = style("[object]\ndraw = false");
    for travel in [6.0, -6.0] {
        let scene = sliding_square(travel);
        let scale = px_per_unit(&scene.camera);
        // The square ends (at the flash) this far right of the image centre, px.
        let end = 100.0 + travel / 2.0 * scale;
        let image = hint(&scene, &trail_only).image;
        // The trail spans the path behind the square: its centroid is the path's middle, the
        // image centre. Ahead of where the square is at the flash there is only the spill of the
        // last motion ellipse's Gaussian end (widened to half a chord against beading, blur.rs):
        // a small share of the trail's light, far fainter than the trail.
        let c = centroid_x(&image);
        assert!((c - 100.0).abs() < 1.0, "travel {travel}: centroid {c}");
        let leading_edge = end + travel.signum() * (0.5 * scale + 1.0);
        let (mut ahead, mut total, mut peak_ahead, mut peak) = (0.0, 0.0, 0.0f32, 0.0f32);
        for x in 0..200usize {
            let v = value(&image, x, 40);
            total += v;
            peak = peak.max(v);
            if (x as f64 + 0.5 - leading_edge) * travel.signum() > 0.0 {
                ahead += v;
                peak_ahead = peak_ahead.max(v);
            }
        }
        assert!(
            ahead < 0.05 * total,
            "travel {travel}: {ahead} of {total} ahead"
        );
        assert!(
            peak_ahead < 0.25 * peak,
            "travel {travel}: {peak_ahead} vs {peak}"
        );
        // With the object drawn, the trail shows behind it and the square sits at its end.
        let full = hint(&scene, &style("")).image;
        let behind = (end - travel.signum() * 2.0 * scale) as usize;
        assert!(value(&full, behind, 40) > 0.1);
        assert!((value(&full, end as usize, 40) - 1.0).abs() < 1e-3);
    }
}

#[test]
fn zero_motion_gives_no_trail_and_the_static_image() {
    let camera = camera(200, 80);
    let square = patch(DVec3::ZERO, [1.0, 1.0], 0.04, false);
    let still = scene(
        camera,
        vec![object(square, motion(&[(0.0, pose(DVec3::ZERO, 0.0))]))],
    );
    let sharp = sharp(&still, 1.0).image;
    for preset in ["", "[trail]\nblend = \"add\"\ncopies = 4\nduty = 0.5"] {
        let out = hint(&still, &style(preset));
        assert_eq!(out.stats.hint().unwrap().trail_splats, 0);
        // Only the object layer's opacity arithmetic (1 − (1 − T)) may differ, in the last bit.
        assert!(rmse(&out.image, &sharp) < 1e-6);
    }
}

#[test]
fn a_full_trail_alone_is_the_blur() {
    // A hint that draws no sharp object and a trail of the whole exposure, from every point, in
    // the object's colours with the Gaussian footprint, is the physically based blur.
    let trail_only = style("[object]\ndraw = false\n[trail]\nemitters = \"all\"");
    let camera = camera(200, 200);
    let spinning = motion(&[
        (0.0, pose(DVec3::ZERO, 0.0)),
        (1.0, pose(DVec3::ZERO, 60.0)),
    ]);
    let rod = patch(DVec3::new(1.2, 0.0, 0.0), [2.4, 0.15], 0.03, false);
    for scene in [
        sliding_square(6.0),
        scene(camera, vec![object(rod, spinning)]),
    ] {
        let blur = draw(&scene, &Method::BLUR);
        let trail = hint(&scene, &trail_only).image;
        assert!(rmse(&trail, &blur) < 1e-5, "{}", rmse(&trail, &blur));
    }
}

#[test]
fn the_colour_ramp_follows_screen_speed() {
    // A rod spinning about one end: points move in proportion to their radius, so along the swept
    // fan the ramp from white (still) to red (fastest) loses green as the radius grows.
    let camera = camera(240, 240);
    let scale = px_per_unit(&camera);
    let spinning = motion(&[
        (0.0, pose(DVec3::ZERO, 0.0)),
        (1.0, pose(DVec3::ZERO, 40.0)),
    ]);
    let rod = patch(DVec3::new(1.25, 0.0, 0.0), [2.5, 0.2], 0.03, false);
    let scene = scene(camera, vec![object(rod, spinning)]);
    let ramp = style(
        "[object]\ndraw = false\n[trail]\ncolour = \"ramp\"\nramp_by = \"speed\"\nramp = [[1, 1, 1], [1, 0, 0]]",
    );
    let image = hint(&scene, &ramp).image;
    let angle = 20f64.to_radians();
    let mut previous = f32::INFINITY;
    for radius in [0.4, 0.8, 1.2, 1.6, 2.0, 2.3] {
        let x = (120.0 + radius * angle.cos() * scale) as usize;
        let y = (120.0 - radius * angle.sin() * scale) as usize;
        let p = image.pixels[y * 240 + x];
        assert!(p[0] > 0.05, "no trail at radius {radius}: {p:?}");
        // Green over red is 1 − u for this ramp, whatever the coverage; u is the speed over the
        // fastest probed path (the far end, radius ≈ 2.5).
        let green = p[1] / p[0];
        let expected = 1.0 - radius / 2.5;
        assert!(
            green < previous,
            "radius {radius}: {green} after {previous}"
        );
        assert!(
            (f64::from(green) - expected).abs() < 0.08,
            "radius {radius}: {green} vs {expected}"
        );
        previous = green;
    }
}

#[test]
fn back_facing_points_emit_no_trail() {
    let camera = camera(200, 80);
    let sliding = motion(&[
        (0.0, pose(DVec3::new(-3.0, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::new(3.0, 0.0, 0.0), 0.0)),
    ]);
    let away = patch(DVec3::ZERO, [1.0, 1.0], 0.04, true);
    let count = away.len();
    let scene = scene(camera, vec![object(away, sliding)]);
    let out = hint(&scene, &style(""));
    assert_eq!(out.stats.hint().unwrap().back_facing, count);
    assert_eq!(out.stats.hint().unwrap().trail_splats, 0);
    assert!(out.image.pixels.iter().all(|p| *p == [0.0; 3]));
    // Asked for trails from every point, they are still left out while facing away.
    let all_style = style("[trail]\nemitters = \"all\"");
    let all = hint(&scene, &all_style);
    assert_eq!(all.stats.hint().unwrap().trail_splats, 0);
    let culled = all.stats.hint().unwrap().trail_culled.back_facing;
    // The trail is drawn from the plan's surfels (merged along the motion): each is culled on
    // every sub-segment.
    let method = Method::Hint {
        style: all_style,
        tolerance_px: 1.0,
    };
    let trail_surfels = Plan::new(&scene, &method).unwrap().surfels(0).len();
    assert!(trail_surfels < count, "{trail_surfels}");
    assert!(
        culled >= trail_surfels && culled.is_multiple_of(trail_surfels),
        "{culled}"
    );
}

#[test]
fn points_hidden_at_the_flash_emit_no_trail() {
    // A still wall in front; a square rises from below it to end hidden behind it.
    let camera = camera(120, 160);
    let scale = px_per_unit(&camera);
    let wall = patch(DVec3::new(0.0, 0.0, 1.0), [2.0, 2.0], 0.04, false);
    let rising = motion(&[
        (0.0, pose(DVec3::new(0.0, -3.5, 0.0), 0.0)),
        (1.0, pose(DVec3::ZERO, 0.0)),
    ]);
    let square = patch(DVec3::ZERO, [1.0, 1.0], 0.04, false);
    let count = square.len();
    let still = motion(&[(0.0, pose(DVec3::ZERO, 0.0))]);
    let scene = scene(camera, vec![object(wall, still), object(square, rising)]);
    // Below the wall, on the square's path (2.5 units down, under the wall's edge at ≈ 1.1).
    let below = (80.0 + 2.5 * scale) as usize;
    let visible = hint(&scene, &style(""));
    assert_eq!(visible.stats.hint().unwrap().hidden, count);
    assert_eq!(visible.stats.hint().unwrap().trail_splats, 0);
    assert!(value(&visible.image, 60, below) < 1e-6);
    let facing = hint(&scene, &style("[trail]\nemitters = \"front-facing\""));
    assert_eq!(facing.stats.hint().unwrap().hidden, 0);
    assert!(value(&facing.image, 60, below) > 0.2);
}

#[test]
fn speed_lines_trail_the_object_and_lie_under_it() {
    let mut scene = sliding_square(6.0);
    let streak::scene::Geometry::Surfels(surfels) = &mut scene.objects[0].geometry else {
        unreachable!("the sliding square is made of surfels")
    };
    streak::surfels::Colouring::Rgb([0.5; 3]).apply(surfels);
    let lines = style(
        "background = [1, 1, 1]\n[trail]\ndraw = false\n[speed_lines]\ndraw = true\nselect = \"sample\"\ncount = 5\nspacing = 3\ncolour = [0, 0, 0]\nwidth = 2\ntaper = 1\nfade = 1",
    );
    let out = hint(&scene, &lines);
    assert!((1..=5).contains(&out.stats.hint().unwrap().speed_lines));
    let scale = px_per_unit(&scene.camera);
    let end = 100.0 + 3.0 * scale;
    // Behind the square, along the path, some column is inked.
    let behind = (end - 2.0 * scale) as usize;
    let darkest = (0..80)
        .map(|y| value(&out.image, behind, y))
        .fold(1.0, f32::min);
    assert!(darkest < 0.5, "{darkest}");
    // Ahead of it, nothing; on it, only the object: the lines pass under it.
    let ahead = (end + 0.5 * scale + 4.0) as usize;
    assert!((0..80).all(|y| value(&out.image, ahead, y) == 1.0));
    for y in 36..44 {
        assert!((value(&out.image, end as usize, y) - 0.5).abs() < 1e-3);
    }
}

#[test]
fn every_preset_parses_and_renders_a_small_frame() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("styles");
    let mut presets: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    presets.sort();
    assert!(presets.len() >= 8, "{} presets", presets.len());
    // A lit sphere (so that it has a silhouette and shading) sliding across the frame.
    let scene = Scene::parse(
        r#"
        background = [0.3, 0.3, 0.3]
        [camera]
        eye = [0, 0, 10]
        target = [0, 0, 0]
        fov_y = 30
        width = 192
        height = 96
        [lighting]
        ambient = 0.2
        light = [{ direction = [0, 1, 1] }]
        [[object]]
        shape = { type = "sphere", radius = 0.6 }
        spacing = 0.05
        colour = [0.9, 0.4, 0.1]
        [[object.keyframe]]
        t = 0
        translate = [-2, 0, 0]
        [[object.keyframe]]
        t = 1
        translate = [2, 0, 0]
        "#,
        &dir.join("test-scene.toml"),
    )
    .unwrap();
    let drawn = |image: &Framebuffer, background: [f32; 3]| {
        image
            .pixels
            .iter()
            .filter(|p| (0..3).any(|c| (p[c] - background[c]).abs() > 0.02))
            .count()
    };
    let sphere = drawn(&sharp(&scene, 1.0).image, scene.background);
    for path in &presets {
        let style = Arc::new(Style::load(path).unwrap_or_else(|e| panic!("{e}")));
        assert!(
            !style.description.is_empty(),
            "{}: no description",
            path.display()
        );
        let image = hint(&scene, &style).image;
        let background = style.background.unwrap_or(scene.background);
        assert!(image.pixels.iter().flatten().all(|c| c.is_finite()));
        // A trail or speed lines draw at least half as much again as the sphere at the flash.
        let changed = drawn(&image, background);
        assert!(
            2 * changed > 3 * sphere,
            "{}: {changed} pixels drawn, the sphere covers {sphere}",
            path.display()
        );
    }
}

#[test]
fn twelve_thousand_pixels_of_motion_stay_finite_and_faint() {
    // The square arrives at the centre from 800 units (≈ 12,000 px) to the left: almost all of
    // its path is off screen, the plan caps its sub-segments, speed lines are clipped.
    let camera = camera(200, 80);
    let arriving = motion(&[
        (0.0, pose(DVec3::new(-800.0, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::ZERO, 0.0)),
    ]);
    let square = patch(DVec3::ZERO, [1.0, 1.0], 0.04, false);
    let scene = scene(camera, vec![object(square, arriving)]);
    let look = style(
        "[speed_lines]\ndraw = true\nselect = \"sample\"\ncount = 8\ncolour = [1, 0, 0]\nfade = 1\ntaper = 1",
    );
    let out = hint(&scene, &look);
    assert!(out.image.pixels.iter().flatten().all(|c| c.is_finite()));
    assert!(out.stats.hint().unwrap().speed_lines >= 1);
    // Sharp at the flash: the square's middle is white.
    assert!((value(&out.image, 100, 40) - 1.0).abs() < 1e-3);
    // Behind it, on its row but clear of the lines' red, the trail's green is the share of the
    // exposure the 1-unit square covers a pixel: 1/800 (a box shutter). The chained ellipses
    // of capped sub-segments smooth it but keep it within a factor of two.
    let expected = 1.0 / 800.0;
    let p = out.image.pixels[40 * 200 + 30];
    assert!(
        f64::from(p[1]) > 0.5 * expected && f64::from(p[1]) < 2.0 * expected,
        "{p:?} vs {expected}"
    );
}

#[test]
fn the_sparsest_trail_allowed_stays_finite_and_a_sparser_one_is_refused() {
    use streak::style::MIN_TRAIL_DENSITY;
    // Each kept point is 1/density heavier: at 10⁻³⁰⁰ that overflowed single precision and
    // left NaN pixels; the floor keeps it finite.
    let sparsest = style(&format!("[trail]\ndensity = {MIN_TRAIL_DENSITY}"));
    let image = hint(&sliding_square(6.0), &sparsest).image;
    assert!(image.pixels.iter().flatten().all(|c| c.is_finite()));
    let error = Style::parse("[trail]\ndensity = 1e-300", Path::new("sparse.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("trail.density: 1e-300: must be between 0.0001 and 1"),
        "{error}"
    );
}

#[test]
fn a_flash_a_few_subnormals_after_the_shutter_opens_draws_without_panicking() {
    // The trail's window is then a few subnormals long: a sixteenth of it, the longest piece of
    // a fading trail, rounds to zero, and the pieces it cut the window into were once counted as
    // infinitely many (a panic). Speed lines cut theirs the same way.
    let scene = sliding_square(6.0);
    for text in [
        "[object]\nflash = 5e-324\n[trail]\nfade = 0.5",
        "[object]\nflash = 5e-324\n[trail]\ndraw = false\n[speed_lines]\ndraw = true\nselect = \"sample\"",
    ] {
        let out = hint(&scene, &style(text));
        assert!(
            out.image.pixels.iter().flatten().all(|c| c.is_finite()),
            "{text}"
        );
    }
}

#[test]
fn ramp_keys_the_colour_rule_does_not_read_are_refused_by_name() {
    for (text, field) in [
        ("[trail]\nramp = [[1, 0, 0], [0, 1, 0]]", "trail.ramp"),
        ("[trail]\nramp_by = \"time\"", "trail.ramp_by"),
        ("[trail]\nspeed_range = [5, 1]", "trail.speed_range"),
        (
            "[trail]\ncolour = \"ramp\"\nramp = [[1, 0, 0], [0, 1, 0]]\nramp_by = \"time\"\nspeed_range = [0, 10]",
            "trail.speed_range",
        ),
    ] {
        let error = Style::parse(text, Path::new("mistaken.toml"))
            .err()
            .unwrap_or_else(|| panic!("{text}: accepted"))
            .to_string();
        assert!(
            error.contains("mistaken.toml") && error.contains(field),
            "{text}: {error}"
        );
    }
}

#[test]
fn speed_lines_start_only_on_visible_points_whatever_the_trail_takes() {
    // A square facing away draws nothing, and its points carry no speed lines, even where the
    // trail takes every point.
    let camera = camera(200, 80);
    let sliding = motion(&[
        (0.0, pose(DVec3::new(-3.0, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::new(3.0, 0.0, 0.0), 0.0)),
    ]);
    let away = scene(
        camera,
        vec![object(patch(DVec3::ZERO, [1.0, 1.0], 0.04, true), sliding)],
    );
    for select in ["silhouette", "sample"] {
        let lines = format!(
            "[trail]\ndraw = false\nemitters = \"all\"\n[speed_lines]\ndraw = true\nselect = \"{select}\""
        );
        let out = hint(&away, &style(&lines));
        assert_eq!(out.stats.hint().unwrap().speed_lines, 0, "{select}");
        assert!(out.image.pixels.iter().all(|p| *p == [0.0; 3]), "{select}");
    }
    // The trail's density thins the trail, not the speed lines; the points it leaves out are
    // counted apart from those that emit.
    let scene = sliding_square(6.0);
    let with_density = |density: f64| {
        let text = format!(
            "[trail]\ndensity = {density}\n[speed_lines]\ndraw = true\nselect = \"sample\"\ncount = 40\nspacing = 2"
        );
        *hint(&scene, &style(&text)).stats.hint().unwrap()
    };
    let (whole, sparse) = (with_density(1.0), with_density(0.01));
    assert_eq!(whole.speed_lines, sparse.speed_lines);
    assert_eq!(whole.sparse, 0);
    assert_eq!(sparse.emitting + sparse.sparse, whole.emitting);
    assert!(sparse.emitting < whole.emitting / 20, "{sparse:?}");
}

#[test]
fn the_object_look_is_the_moving_objects_and_leaves_still_ones_as_they_are() {
    // A still square beside a sliding one: a flat colour, a see-through or an undrawn moving
    // object leaves the still square's pixels as the default style draws them.
    let camera = camera(200, 80);
    let still = motion(&[(0.0, pose(DVec3::new(-4.0, 0.0, 0.0), 0.0))]);
    let sliding = motion(&[
        (0.0, pose(DVec3::ZERO, 0.0)),
        (1.0, pose(DVec3::new(3.0, 0.0, 0.0), 0.0)),
    ]);
    let square = || patch(DVec3::ZERO, [1.0, 1.0], 0.04, false);
    let scene = scene(
        camera,
        vec![object(square(), still), object(square(), sliding)],
    );
    let scale = px_per_unit(&scene.camera);
    let (still_x, moving_x) = (
        (100.0 - 4.0 * scale) as usize,
        (100.0 + 3.0 * scale) as usize,
    );
    let plain = hint(&scene, &style("")).image;
    for text in [
        "[object]\ncolour = [1, 0, 0]",
        "[object]\nopacity = 0.25",
        "[object]\nopacity = 0",
        "[object]\ndraw = false",
    ] {
        let image = hint(&scene, &style(text)).image;
        for y in 36..44 {
            let at = y * 200 + still_x;
            assert_eq!(image.pixels[at], plain.pixels[at], "{text}, row {y}");
        }
    }
    // On the moving square at the flash, the look applies: a quarter of its light at 0.25.
    let quarter = hint(
        &scene,
        &style("[trail]\ndraw = false\n[object]\nopacity = 0.25"),
    )
    .image;
    let full = hint(&scene, &style("[trail]\ndraw = false")).image;
    let (q, f) = (value(&quarter, moving_x, 40), value(&full, moving_x, 40));
    assert!(f > 0.5 && (q - 0.25 * f).abs() < 1e-4, "{q} of {f}");
}

#[test]
fn copies_too_short_for_f64_are_sharp_ghosts_not_nothing() {
    // Four copies each drawn over a duty of their slot: below about 10⁻¹⁶ the copy's start
    // rounds onto its end; it is then drawn over the shortest time f64 tells, as bright as a
    // short copy (each is a whole exposure of its own slot).
    let scene = sliding_square(6.0);
    let energy = |duty: &str| -> f64 {
        let text = format!("[object]\ndraw = false\n[trail]\ncopies = 4\nduty = {duty}");
        let image = hint(&scene, &style(&text)).image;
        image.pixels.iter().flatten().map(|&c| f64::from(c)).sum()
    };
    let short = energy("1e-9");
    assert!(short > 100.0, "{short}");
    for duty in ["1e-17", "1e-300"] {
        let tiny = energy(duty);
        assert!(
            (tiny / short - 1.0).abs() < 0.01,
            "{duty}: {tiny} against {short}"
        );
    }
}

#[test]
fn a_textured_trail_turns_with_the_motion() {
    // A texture bright on its left half (the oldest end): moving right, the trail's light lies
    // left of its middle; moving left, right of it, by as much.
    let mut half = image::GrayImage::new(64, 64);
    for (x, _, p) in half.enumerate_pixels_mut() {
        p.0 = [if x < 32 { 255 } else { 0 }];
    }
    let dir = std::env::temp_dir().join(format!("streak-texture-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    half.save(dir.join("half.png")).unwrap();
    let look = Arc::new(
        Style::parse(
            "[object]\ndraw = false\n[trail]\ntexture = { image = \"half.png\" }",
            &dir.join("style.toml"),
        )
        .unwrap(),
    );
    let offsets: Vec<f64> = [2.0, -2.0]
        .into_iter()
        .map(|travel| {
            let camera = camera(200, 80);
            let sliding = motion(&[
                (0.0, pose(DVec3::new(-travel / 2.0, 0.0, 0.0), 0.0)),
                (1.0, pose(DVec3::new(travel / 2.0, 0.0, 0.0), 0.0)),
            ]);
            let surfel = vec![facing_surfel(DVec3::ZERO, 0.05)];
            let scene = scene(camera, vec![object(surfel, sliding)]);
            // From the path's middle, toward the newest end.
            (centroid_x(&hint(&scene, &look).image) - 100.0) * travel.signum()
        })
        .collect();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(offsets[0] < -1.0, "{offsets:?}");
    assert!((offsets[0] - offsets[1]).abs() < 0.05, "{offsets:?}");
}
