//! The real binary: user mistakes get a message naming the file and field, and a non-zero exit;
//! good input renders.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const SCENE: &str = r#"
background = [0, 0, 0]

[camera]
eye = [0, 0, 5]
target = [0, 0, 0]
fov_y = 40
width = 48
height = 32

[[object]]
name = "ball"
shape = { type = "sphere", radius = 1.0 }
spacing = 0.1

[[object.keyframe]]
t = 0.0
[[object.keyframe]]
t = 1.0
translate = [0.5, 0, 0]
"#;

/// The arguments of a study of `scene.toml` into `out` with the fewest frames and one repeat.
fn quick_study(out: &str) -> [&str; 10] {
    [
        "study",
        "scene.toml",
        "-o",
        out,
        "--reference-samples",
        "4",
        "--max-samples",
        "2",
        "--repeats",
        "1",
    ]
}

/// A fresh folder for one test.
fn workdir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("streak-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn streak(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_streak"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// Write `scene` into `dir`, render it, and return (exit success, stderr).
fn render_scene(name: &str, scene: &str, files: &[(&str, &[u8])]) -> (bool, String) {
    let dir = workdir(name);
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    for (file, bytes) in files {
        std::fs::write(dir.join(file), bytes).unwrap();
    }
    let out = streak(&["render", "scene.toml", "-o", "out.png"], &dir);
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The scene must be rejected with a message containing every one of `needles`.
fn rejected(name: &str, scene: &str, files: &[(&str, &[u8])], needles: &[&str]) {
    let (ok, stderr) = render_scene(name, scene, files);
    assert!(!ok, "{name}: should fail");
    assert!(!stderr.contains("panicked"), "{name}: panicked: {stderr}");
    for needle in needles {
        assert!(
            stderr.contains(needle),
            "{name}: {needle:?} missing from: {stderr}"
        );
    }
}

#[test]
fn a_good_scene_renders_and_explains_itself() {
    let dir = workdir("good");
    std::fs::write(dir.join("scene.toml"), SCENE).unwrap();
    let out = streak(
        &[
            "render",
            "scene.toml",
            "-m",
            "blur",
            "-o",
            "out.png",
            "--exr",
            "out.exr",
            "--explain",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("\"ball\"") && stdout.contains("moving") && stdout.contains("back-facing"),
        "{stdout}"
    );
    let png = image::open(dir.join("out.png")).unwrap();
    assert_eq!((png.width(), png.height()), (48, 32));
    assert!(dir.join("out.exr").exists());
    assert!(
        !String::from_utf8_lossy(&out.stderr).contains("note:"),
        "nothing departs from this scene"
    );
}

#[test]
fn a_render_that_departs_from_its_scene_says_so_without_being_asked() {
    // A triangle growing to 10³⁰⁰ times its size over the exposure: its path cannot be followed
    // within the tolerance, and its corners pass where double precision overflows. Both are
    // said on standard error, without --explain.
    let scene = format!(
        "{SCENE}
[[object]]
name = \"growing\"
shape = {{ type = \"mesh\", path = \"triangle.obj\", samples = 200, draw = \"triangles\" }}

[[object.keyframe]]
t = 0.0
[[object.keyframe]]
t = 1.0
scale = 1e300
"
    );
    let triangle: &[u8] = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let dir = workdir("departs");
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    std::fs::write(dir.join("triangle.obj"), triangle).unwrap();
    let out = streak(
        &["render", "scene.toml", "-m", "analytic", "-o", "out.png"],
        &dir,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    for needle in [
        "note: \"growing\": its path is drawn in 256 sub-segments per keyframe interval",
        "fewer than the tolerance of",
        "triangle item(s) left out",
        "; --explain says more",
    ] {
        assert!(stderr.contains(needle), "{needle:?} missing from: {stderr}");
    }
    assert!(!stderr.contains("\"ball\""), "{stderr}");

    // A study and a gallery say it too, for each render that departs, by method and setting;
    // the gallery's page under the image.
    let study = quick_study("study");
    std::fs::create_dir_all(dir.join("looks")).unwrap();
    std::fs::write(dir.join("looks/plain.toml"), "").unwrap();
    let gallery = [
        "gallery",
        "--scenes",
        ".",
        "--styles",
        "looks",
        "-o",
        "gallery",
        "--samples",
        "2",
    ];
    for (args, needle) in [
        (
            &study[..],
            "note: analytic τ=0.3px: 256 triangle item(s) left out",
        ),
        (
            &gallery[..],
            "note: scene analytic τ=0.1px: 256 triangle item(s) left out",
        ),
        (
            &study[..],
            "note: blur τ=1px: \"growing\": its path is drawn in 256",
        ),
    ] {
        let out = streak(args, &dir);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(stderr.contains(needle), "{needle:?} missing from: {stderr}");
        // `static` and the reference draw instants, and `kernel3d F=n` its equal sub-frames, not
        // the path's sub-segments: none of their paths is capped.
        assert!(
            !stderr
                .lines()
                .any(|line| ["note: static", "note: reference", "note: kernel3d"]
                    .iter()
                    .any(|method| line.starts_with(method))
                    && line.contains("its path is drawn")),
            "{stderr}"
        );
    }
    let page = std::fs::read_to_string(dir.join("gallery/index.html")).unwrap();
    assert!(
        page.contains("<br>note: 256 triangle item(s) left out"),
        "{page}"
    );
}

#[test]
fn unknown_keys_are_rejected() {
    rejected(
        "unknown",
        &SCENE.replace("fov_y = 40", "fov_y = 40\nzoom = 2"),
        &[],
        &["scene.toml", "zoom", "line"],
    );
}

#[test]
fn missing_fields_are_rejected() {
    rejected(
        "missing",
        &SCENE.replace("fov_y = 40\n", ""),
        &[],
        &["scene.toml", "fov_y"],
    );
    rejected(
        "no-spacing",
        &SCENE.replace("spacing = 0.1\n", ""),
        &[],
        &["object[0].spacing"],
    );
}

#[test]
fn non_finite_numbers_are_rejected() {
    rejected(
        "nan",
        &SCENE.replace("radius = 1.0", "radius = nan"),
        &[],
        &["object[0].shape.radius"],
    );
    rejected(
        "inf",
        &SCENE.replace("translate = [0.5, 0, 0]", "translate = [inf, 0, 0]"),
        &[],
        &["object[0].keyframe[1].translate[0]"],
    );
}

#[test]
fn keyframes_out_of_order_or_outside_the_frame_are_rejected() {
    rejected(
        "order",
        &SCENE.replace("t = 1.0", "t = 0.0"),
        &[],
        &["object[0].keyframe[1].t", "increase"],
    );
    rejected(
        "range",
        &SCENE.replace("t = 1.0", "t = 1.5"),
        &[],
        &["object[0].keyframe[1].t", "[0, 1]"],
    );
}

#[test]
fn half_turns_lights_colours_and_budgets_are_rejected() {
    let half_turn = SCENE.replace(
        "translate = [0.5, 0, 0]",
        "rotate = { axis = [0, 1, 0], degrees = 190 }",
    );
    rejected(
        "half-turn",
        &half_turn,
        &[],
        &["object[0].keyframe[1].rotate", "add keyframes"],
    );
    // Whole turns are orientations slerp cannot tell from none (720° is the identity), and a
    // step past a half turn about one axis would be drawn the short way round. No turn about one
    // axis is no rotation, whatever the next axis; whole turns about a new axis are refused.
    const Y: &str = "[0, 1, 0]";
    const Z: &str = "[0, 0, 1]";
    for (name, (from_axis, from), (to_axis, to), needle) in [
        (
            "two-turns",
            (Y, 0),
            (Y, 720),
            "turns 720° from the previous keyframe",
        ),
        (
            "one-turn",
            (Y, 0),
            (Y, 360),
            "turns 360° from the previous keyframe",
        ),
        (
            "long-way",
            (Y, 170),
            (Y, -170),
            "turns 340° from the previous keyframe",
        ),
        (
            "no-rotation-first",
            (Y, 0),
            (Y, 200),
            "turns 200° from the previous keyframe",
        ),
        (
            "no-turn-about-another-axis-first",
            (Y, 0),
            (Z, 450),
            "turns 450° from the previous keyframe",
        ),
        (
            "whole-turns-about-a-new-axis",
            (Y, 30),
            (Z, 720),
            "turns 720° about another axis",
        ),
    ] {
        let turn = SCENE
            .replace(
                "t = 0.0",
                &format!("t = 0.0\nrotate = {{ axis = {from_axis}, degrees = {from} }}"),
            )
            .replace(
                "translate = [0.5, 0, 0]",
                &format!("rotate = {{ axis = {to_axis}, degrees = {to} }}"),
            );
        rejected(name, &turn, &[], &["object[0].keyframe[", needle]);
    }
    let opposite_axes = SCENE
        .replace(
            "t = 0.0",
            "t = 0.0\nrotate = { axis = [0, 1, 0], degrees = 100 }",
        )
        .replace(
            "translate = [0.5, 0, 0]",
            "rotate = { axis = [0, -1, 0], degrees = 100 }",
        );
    rejected(
        "opposite-axes",
        &opposite_axes,
        &[],
        &["object[0].keyframe[1].rotate", "turns 200°"],
    );
    let dark = format!("{SCENE}\n[lighting]\nlight = [{{ direction = [0, 0, 0] }}]\n");
    rejected("light", &dark, &[], &["lighting.light[0].direction"]);
    rejected(
        "colour",
        &SCENE.replace("spacing = 0.1", "spacing = 0.1\ncolour = [1e30, 0, 0]"),
        &[],
        &["object[0].colour[0]"],
    );
    rejected(
        "budget",
        &SCENE.replace("spacing = 0.1", "spacing = 1e-5"),
        &[],
        &[
            "object[0].spacing",
            "more than the scene's budget of 8000000 surfels: use a larger spacing",
            "--max-surfels",
        ],
    );
    // Twenty million mesh samples are refused before the mesh is read (it took 6.1 GB).
    rejected(
        "mesh-budget",
        &SCENE.replace(
            "shape = { type = \"sphere\", radius = 1.0 }\nspacing = 0.1",
            "shape = { type = \"mesh\", path = \"no-such.obj\", samples = 20000000 }",
        ),
        &[],
        &[
            "object[0].shape.samples",
            "20000000 surfels are more than",
            "--max-surfels",
        ],
    );
    rejected(
        "up",
        &SCENE.replace("fov_y = 40", "fov_y = 40\nup = [0, 0, 1]"),
        &[],
        &["camera.up"],
    );
    let many_neighbours = PLY_SCENE.replace(
        "path = \"cloud.ply\"",
        "path = \"cloud.ply\", neighbours = 500",
    );
    rejected(
        "neighbours",
        &many_neighbours,
        &[],
        &["object[0].shape.neighbours"],
    );
}

#[test]
fn bad_shutters_and_cameras_are_rejected() {
    rejected(
        "shutter",
        &format!("{SCENE}\n[shutter]\nopen = 0.8\nclose = 0.2\n"),
        &[],
        &["shutter", "open < close"],
    );
    rejected(
        "fov",
        &SCENE.replace("fov_y = 40", "fov_y = 190"),
        &[],
        &["camera.fov_y"],
    );
    rejected(
        "eye",
        &SCENE.replace("eye = [0, 0, 5]", "eye = [0, 0, 0]"),
        &[],
        &["camera.target"],
    );
}

const PLY_SCENE: &str = r#"
[camera]
eye = [0, 0, 5]
target = [0, 0, 0]
fov_y = 40
width = 32
height = 32

[[object]]
shape = { type = "ply", path = "cloud.ply" }
"#;

#[test]
fn unreadable_and_malformed_ply_files_are_rejected() {
    // A file the scene names but that is not there: the scene and the field that named it.
    rejected(
        "ply-missing",
        PLY_SCENE,
        &[],
        &["scene.toml: object[0].shape.path: cannot read", "cloud.ply"],
    );
    rejected(
        "ply-garbage",
        PLY_SCENE,
        &[("cloud.ply", b"this is not a ply file\n")],
        &["cloud.ply"],
    );
    let truncated = b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nproperty float y\nproperty float z\nend_header\n\x00\x00";
    rejected(
        "ply-truncated",
        PLY_SCENE,
        &[("cloud.ply", truncated)],
        &["cloud.ply"],
    );
}

#[test]
fn zero_normals_in_a_ply_are_rejected() {
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
               property float nx\nproperty float ny\nproperty float nz\nend_header\n\
               0 0 0 0 0 1\n1 0 0 0 0 0\n0 1 0 0 0 1\n";
    rejected(
        "ply-normal",
        PLY_SCENE,
        &[("cloud.ply", ply.as_bytes())],
        &["cloud.ply", "vertex 1", "normal"],
    );
}

const VOLUME_SCENE: &str = r#"
[camera]
eye = [0, 0, 5]
target = [0, 0, 0]
fov_y = 40
width = 32
height = 32

[[object]]
shape = { type = "volume", path = "blob.raw", dimensions = [4, 4, 4], voxel = "uint8", iso = 50 }
colour = "normal"
[[object.keyframe]]
t = 0
scale = 0.5
"#;

/// A 4³ uint8 volume: a 2³ block of 200 in the middle of zeros.
fn blob() -> Vec<u8> {
    (0..64)
        .map(|i| {
            let inner = |c: usize| (1..=2).contains(&c);
            if inner(i % 4) && inner(i / 4 % 4) && inner(i / 16) {
                200
            } else {
                0
            }
        })
        .collect()
}

#[test]
fn a_volume_renders_and_its_mistakes_name_the_field() {
    let blob = blob();
    let (ok, stderr) = render_scene("volume", VOLUME_SCENE, &[("blob.raw", &blob)]);
    assert!(ok, "{stderr}");
    rejected(
        "volume-missing",
        VOLUME_SCENE,
        &[],
        &["scene.toml: object[0].shape.path: cannot read", "blob.raw"],
    );
    rejected(
        "volume-size",
        VOLUME_SCENE,
        &[("blob.raw", &blob[..63])],
        &["blob.raw", "expected 64 bytes", "found 63"],
    );
    rejected(
        "volume-voxel",
        &VOLUME_SCENE.replace("\"uint8\"", "\"int32\""),
        &[("blob.raw", &blob)],
        &["object[0].shape.voxel", "\"float32\""],
    );
    rejected(
        "volume-dimension",
        &VOLUME_SCENE.replace("[4, 4, 4]", "[4, 0, 16]"),
        &[("blob.raw", &blob)],
        &["object[0].shape.dimensions[1]", "at least 2"],
    );
    rejected(
        "volume-iso",
        &VOLUME_SCENE.replace("iso = 50", "iso = 250"),
        &[("blob.raw", &blob)],
        &["object[0].shape.iso", "from 0 to 200"],
    );
    rejected(
        "volume-spacing",
        &VOLUME_SCENE.replace("colour = \"normal\"", "spacing = 0.1"),
        &[("blob.raw", &blob)],
        &["object[0].spacing", "shape.spacing"],
    );
    rejected(
        "volume-unknown",
        &VOLUME_SCENE.replace("iso = 50", "iso = 50, threshold = 3"),
        &[("blob.raw", &blob)],
        &["threshold"],
    );
}

#[test]
fn command_line_mistakes_are_explained() {
    let dir = workdir("args");
    std::fs::write(dir.join("scene.toml"), SCENE).unwrap();
    for (args, needle) in [
        (vec!["render", "scene.toml", "--time", "2"], "--time"),
        (vec!["render", "scene.toml", "-o", "out.jpg"], ".png"),
        (vec!["render", "nope.toml"], "nope.toml"),
        (vec!["render", "scene.toml", "--threads", "0"], "--threads"),
        (
            vec!["render", "scene.toml", "--threads", "4000"],
            "--threads 4000: use 1 to",
        ),
        (
            vec!["render", "scene.toml", "--exr", "x.tiff"],
            "--exr x.tiff: the linear float image is OpenEXR",
        ),
        (vec!["render", "scene.toml", "-m", "sharp"], "sharp"),
        // Options a method does not read are errors, not ignored.
        (
            vec!["render", "scene.toml", "-m", "blur", "--time", "0.5"],
            "--time applies to -m static only",
        ),
        (
            vec!["render", "scene.toml", "-m", "blur", "--samples", "8"],
            "--samples applies to -m reference only",
        ),
        (
            vec!["render", "scene.toml", "-m", "static", "--tolerance", "2"],
            "--tolerance applies to -m blur and -m hint and -m kernel3d and -m analytic only",
        ),
        (
            vec!["render", "scene.toml", "--tolerance", "1000"],
            "--tolerance 1000: must be between",
        ),
        // A negative value is a value, not an option.
        (
            vec!["render", "scene.toml", "--tolerance", "-1"],
            "--tolerance -1: must be between",
        ),
        (
            vec![
                "render",
                "scene.toml",
                "-m",
                "blur",
                "--spatial-samples",
                "4",
            ],
            "--spatial-samples applies to -m static and -m reference and -m analytic only",
        ),
    ] {
        let out = streak(&args, &dir);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(
            stderr.contains(needle),
            "{args:?}: {needle:?} missing from {stderr}"
        );
    }
}

/// Render `SCENE` (with `scene_extra` prepended) as a hint with `args`, style files written beside it.
fn hint_run(name: &str, scene_extra: &str, styles: &[(&str, &str)], args: &[&str]) -> Output {
    let dir = workdir(name);
    std::fs::write(dir.join("scene.toml"), format!("{scene_extra}\n{SCENE}")).unwrap();
    for (file, text) in styles {
        std::fs::write(dir.join(file), text).unwrap();
    }
    let mut all = vec!["render", "scene.toml", "-m", "hint", "-o", "out.png"];
    all.extend_from_slice(args);
    streak(&all, &dir)
}

fn assert_fails_with(out: &Output, needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "should fail: {stderr}");
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{needle:?} missing from: {stderr}");
    }
}

#[test]
fn style_mistakes_name_the_file_and_field() {
    let cases: [(&str, &[&str]); 6] = [
        (
            "[trail]\nlength = 2",
            &["bad.toml", "trail.length", "between 0 and 1"],
        ),
        ("[trail]\nlenght = 0.5", &["bad.toml", "lenght", "line 2"]),
        (
            "[trail]\nfade = nan",
            &["bad.toml", "trail.fade", "not a finite number"],
        ),
        ("[trail]\ncolour = \"ramp\"", &["bad.toml", "trail.ramp"]),
        ("[trail]\ntexture = \"stripes\"", &["bad.toml", "line 2"]),
        (
            "[speed_lines]\ncount = 0",
            &["bad.toml", "speed_lines.count"],
        ),
    ];
    for (i, (text, needles)) in cases.iter().enumerate() {
        let out = hint_run(
            &format!("style-{i}"),
            "",
            &[("bad.toml", text)],
            &["--style", "bad.toml"],
        );
        assert_fails_with(&out, needles);
    }
    // A texture image that is not there, named from the style.
    let out = hint_run(
        "style-texture",
        "",
        &[("bad.toml", "[trail]\ntexture = { image = \"gone.png\" }")],
        &["--style", "bad.toml"],
    );
    assert_fails_with(&out, &["bad.toml", "trail.texture.image", "gone.png"]);
    // A style named by the scene is read from beside the scene.
    let out = hint_run(
        "style-scene",
        "style = \"look.toml\"",
        &[("look.toml", "[object]\nflash = 2")],
        &[],
    );
    assert_fails_with(&out, &["look.toml", "object.flash"]);
    // --style belongs to hints.
    let dir = workdir("style-method");
    std::fs::write(dir.join("scene.toml"), SCENE).unwrap();
    std::fs::write(dir.join("look.toml"), "").unwrap();
    let out = streak(
        &["render", "scene.toml", "-m", "blur", "--style", "look.toml"],
        &dir,
    );
    assert_fails_with(&out, &["--style applies to -m hint only"]);
}

#[test]
fn a_scene_may_name_its_style() {
    let out = hint_run(
        "style-good",
        "style = \"look.toml\"",
        &[(
            "look.toml",
            "[trail]\ncolour = \"ramp\"\nramp = [[1, 1, 1], [1, 0, 0]]",
        )],
        &["--explain"],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("surfels emit trails"), "{stdout}");
}

#[test]
fn kernel_options_belong_to_kernel3d() {
    let dir = workdir("kernel-options");
    std::fs::write(dir.join("scene.toml"), SCENE).unwrap();
    let out = streak(
        &["render", "scene.toml", "-m", "blur", "--subframes", "2"],
        &dir,
    );
    assert_fails_with(&out, &["--subframes applies to -m kernel3d only"]);
    let out = streak(
        &["render", "scene.toml", "-m", "kernel3d", "--subframes", "0"],
        &dir,
    );
    assert!(!out.status.success());
    let out = streak(
        &[
            "render",
            "scene.toml",
            "-m",
            "kernel3d",
            "--approximate",
            "--explain",
            "-o",
            "k.png",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("kernel3d: "));
}

#[test]
fn a_reader_that_goes_away_ends_the_output_quietly() {
    // `streak render … --explain | head -1`: standard output closes before the explanation is
    // written.
    let dir = workdir("pipe");
    std::fs::write(dir.join("scene.toml"), SCENE).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_streak"))
        .args(["render", "scene.toml", "--explain"])
        .current_dir(&dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn a_missing_scene_style_names_the_scene_and_its_field() {
    let dir = workdir("missing-style");
    std::fs::write(
        dir.join("scene.toml"),
        format!("style = \"nope.toml\"\n{SCENE}"),
    )
    .unwrap();
    let out = streak(&["render", "scene.toml", "-m", "hint"], &dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("scene.toml: style: cannot read") && stderr.contains("nope.toml"),
        "{stderr}"
    );
}

#[test]
fn the_surfel_budget_is_the_whole_scene_s_and_can_be_raised() {
    // Two spheres of 1,257 surfels each.
    let dir = workdir("scene-budget");
    let second = SCENE[SCENE.find("[[object]]").unwrap()..].replace("\"ball\"", "\"other\"");
    std::fs::write(dir.join("scene.toml"), format!("{SCENE}\n{second}")).unwrap();
    let run = |budget: &str| streak(&["render", "scene.toml", "--max-surfels", budget], &dir);
    let out = run("2000");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("object[1].spacing")
            && stderr.contains("more than the 743 surfels left of the scene's budget of 2000"),
        "{stderr}"
    );
    assert!(run("3000").status.success());
    let stderr = String::from_utf8_lossy(&run("0").stderr).into_owned();
    assert!(
        stderr.contains("--max-surfels 0: allow between 1 and"),
        "{stderr}"
    );
}

#[test]
fn compare_reports_the_error_and_where_it_is_largest() {
    use streak::io::image::write_exr;
    use streak::Framebuffer;
    let dir = workdir("compare");
    let reference = Framebuffer::filled(8, 4, [0.5; 3]);
    let mut test = reference.clone();
    // Pixel (3, 2), green channel: RMSE = √(0.25² / (3 · 32)) = 0.025516.
    test.pixels[2 * 8 + 3][1] += 0.25;
    write_exr(&reference, &dir.join("reference.exr")).unwrap();
    write_exr(&test, &dir.join("test.exr")).unwrap();

    let out = streak(
        &[
            "compare",
            "test.exr",
            "reference.exr",
            "--diff",
            "diff.exr",
            "--gain",
            "2",
        ],
        &dir,
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}{:?}", out.stderr);
    assert!(stdout.contains("RMSE 2.5516e-2"), "{stdout}");
    assert!(
        stdout.contains("largest difference 2.5000e-1 at pixel (3, 2); 1 of 32 pixels differ"),
        "{stdout}"
    );
    let diff = streak::io::image::read_exr(&dir.join("diff.exr")).unwrap();
    assert_eq!(diff.pixels[2 * 8 + 3], [0.0, 0.5, 0.0]);
    assert_eq!(diff.pixels.iter().filter(|p| **p != [0.0; 3]).count(), 1);

    let same = streak(&["compare", "test.exr", "test.exr"], &dir);
    assert!(String::from_utf8_lossy(&same.stdout).contains("identical"));

    write_exr(&Framebuffer::filled(4, 4, [0.5; 3]), &dir.join("small.exr")).unwrap();
    let mismatch = streak(&["compare", "small.exr", "reference.exr"], &dir);
    assert_fails_with(
        &mismatch,
        &["small.exr is 4×4 but reference.exr is 8×4", "same --width"],
    );

    // A 65-byte PNG whose header claims 100,000 × 100,000 pixels (30 GB as RGB floats) is refused
    // from its header.
    std::fs::write(dir.join("huge.png"), HUGE_PNG).unwrap();
    let huge = streak(&["compare", "huge.png", "reference.exr"], &dir);
    assert_fails_with(&huge, &["huge.png", "at most 8192 pixels a side"]);
}

#[test]
fn simplify_takes_a_direction_as_x_y_z() {
    // A flat 4 × 4 grid of squares, 32 triangles, facing +z.
    let dir = workdir("simplify");
    let mut obj = String::new();
    for j in 0..5 {
        for i in 0..5 {
            obj += &format!("v {i} {j} 0\n");
        }
    }
    for j in 0..4 {
        for i in 0..4 {
            let a = j * 5 + i + 1;
            obj += &format!("f {a} {} {}\nf {a} {} {}\n", a + 1, a + 6, a + 6, a + 5);
        }
    }
    std::fs::write(dir.join("grid.obj"), obj).unwrap();
    let run = |direction: &str| {
        streak(
            &[
                "simplify",
                "grid.obj",
                "-o",
                "out.obj",
                "--faces",
                "2",
                "--direction",
                direction,
            ],
            &dir,
        )
    };
    let out = run("1,0,0");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let written = std::fs::read_to_string(dir.join("out.obj")).unwrap();
    assert_eq!(written.lines().filter(|l| l.starts_with("f ")).count(), 2);
    assert_fails_with(&run("1,0"), &["X,Y,Z"]);
}

/// A PNG signature, an IHDR chunk for 100,000 × 100,000 8-bit RGB, an empty IDAT and IEND.
const HUGE_PNG: [u8; 65] = [
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
    0x00, 0x01, 0x86, 0xa0, 0x00, 0x01, 0x86, 0xa0, 0x08, 0x02, 0x00, 0x00, 0x00, 0x27, 0x30, 0x9c,
    0x9f, 0x00, 0x00, 0x00, 0x08, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00,
    0x01, 0x48, 0x06, 0x89, 0xd2, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60,
    0x82,
];

#[test]
fn gallery_and_simplify_mistakes_are_explained() {
    let dir = workdir("gallery-args");
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    std::fs::create_dir_all(dir.join("styles")).unwrap();
    std::fs::write(dir.join("scenes/ball.toml"), SCENE).unwrap();
    let gallery = |extra: &[&str]| {
        let mut args = vec![
            "gallery",
            "--scenes",
            "scenes",
            "--styles",
            "styles",
            "--samples",
            "2",
            "-o",
            "out",
        ];
        args.extend_from_slice(extra);
        streak(&args, &dir)
    };
    // The gallery reads --spatial-samples as render does: a grid's count, or an error.
    assert_fails_with(
        &gallery(&["--spatial-samples", "5"]),
        &["--spatial-samples 5: samples per pixel form an n × n grid"],
    );
    let out = gallery(&["--spatial-samples", "1"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A scene the plan refuses is named.
    let lights = (0..9)
        .map(|i| format!("{{ direction = [{i}, 1, 1], intensity = 0.1, shadows = true }}"))
        .collect::<Vec<_>>()
        .join(", ");
    std::fs::write(
        dir.join("scenes/lights.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("scenes/lights.toml"),
        format!(
            "{SCENE}\n[lighting]\nlight = [{lights}]\n[[object]]\nshape = {{ type = \"mesh\", path = \"lights.obj\", samples = 10, draw = \"triangles\" }}\n"
        ),
    )
    .unwrap();
    assert_fails_with(&gallery(&[]), &["lights.toml", "lights cast shadows"]);
    // Simplifying to no face at all would write a mesh nothing reads.
    std::fs::write(dir.join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert_fails_with(
        &streak(
            &["simplify", "tri.obj", "--faces", "0", "-o", "x.obj"],
            &dir,
        ),
        &["--faces 0"],
    );
    let out = streak(
        &["simplify", "tri.obj", "--ratio", "0.1", "-o", "x.obj"],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::read_to_string(dir.join("x.obj"))
        .unwrap()
        .contains("\nf "));
    // Nor would a mesh whose every face repairing drops (three corners at one point).
    std::fs::write(
        dir.join("point.obj"),
        "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n",
    )
    .unwrap();
    assert_fails_with(
        &streak(
            &["simplify", "point.obj", "--faces", "1", "-o", "empty.obj"],
            &dir,
        ),
        &["point.obj", "no face is left", "empty.obj not written"],
    );
    assert!(!dir.join("empty.obj").exists());
}

/// A still scene: the references at every N match the converged one exactly, and zero error
/// cannot go on log axes. The plot leaves those points out and the study says so.
#[test]
fn a_study_says_which_points_its_plot_leaves_out() {
    let dir = workdir("still-study");
    let still = SCENE.replace("translate = [0.5, 0, 0]", "translate = [0, 0, 0]");
    std::fs::write(dir.join("scene.toml"), still).unwrap();
    let out = streak(&quick_study("out"), &dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("points are not plotted"), "{stderr}");
    assert!(dir.join("out/study.svg").exists());

    // An output folder named where a file is: said so, not "File exists".
    std::fs::write(dir.join("taken"), "").unwrap();
    assert_fails_with(
        &streak(&["study", "scene.toml", "-o", "taken"], &dir),
        &["-o taken: a file of that name is there; name a folder"],
    );
}
