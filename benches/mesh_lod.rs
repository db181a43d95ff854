//! Motion-aware simplification measured (issue 12; Zhang et al. 2014 Fig. 6 and 7): the
//! armadillo translating horizontally and the bunny turning about its vertical axis, at Zhang's
//! four screen speeds (10, 30, 90, 270 px per shutter: the armadillo's at the depth of its centre,
//! the bunny's that of its fastest vertex; each line prints its fastest vertex's).
//!
//! 1. Direction-aware against isotropic QEM at equal face counts (Zhang's Table 1 shares of the
//!    input): ꟻLIP of the `analytic` render against the full-detail `analytic` render.
//! 2. The plan's level of detail for each detail rule σ₁ given: faces kept, ꟻLIP against full
//!    detail, and the speed-up of `analytic` and of `blur` (the surfel path) with the
//!    simplification excluded and included (Zhang's Fig. 7: (T_full − T_lod) / T_lod; here as
//!    the plain ratio T_full / T_lod).
//!
//! `cargo bench --bench mesh_lod -- [SIZE] [SIGMAS] [SPEEDS] [REPEATS] [SCENES]`, by default
//! `320 7.3,1,0.5 10,30,90,270 3`: each speed-up compares median times over `REPEATS` renders,
//! full detail and simplified taking turns. Given a folder `SCENES`, each scene is also written
//! there (`armadillo-90px-0.3.toml`, say), for `streak render --explain` or the `raster` bench.
//! Reads the meshes from `../shared/data/meshes/`.

mod common;

use std::path::Path;
use std::time::Instant;

use streak::lod::Lod;
use streak::metrics::compare;
use streak::scene::{Object, TriangleMesh};
use streak::simplify::speed::ScreenMotion;
use streak::simplify::{simplify, Options, Weighting};
use streak::surfels::Mesh;
use streak::{Framebuffer, Method, Plan, Scene};

/// Zhang's Table 1: the bunny's faces at each of their speeds, as shares of its 69,460 (a tenth
/// at other speeds).
fn share(speed: f64) -> f64 {
    [(10.0, 0.4), (30.0, 0.2), (90.0, 0.1), (270.0, 0.04)]
        .iter()
        .find(|(v, _)| *v == speed)
        .map_or(0.1, |&(_, s)| s)
}

struct Case {
    name: &'static str,
    mesh: &'static str,
    /// Scale making the mesh about 2 units tall.
    scale: f64,
    turning: bool,
}

const CASES: [Case; 2] = [
    Case {
        name: "armadillo translating",
        mesh: "../shared/data/meshes/armadillo_100k.obj",
        scale: 0.0135,
        turning: false,
    },
    Case {
        name: "bunny turning",
        mesh: "../shared/data/meshes/bunny_bun_zipper.ply",
        scale: 13.0,
        turning: true,
    },
];

/// The scene text for `case` moving `speed` px per shutter at the widest point, a turn scaled by
/// `turn` (see [`turn_for`]).
fn scene_text(case: &Case, speed: f64, width: u32, sigma: f64, turn: f64) -> String {
    let height = width * 3 / 4;
    let fov_y: f64 = 30.0;
    let depth = 6.0;
    let focal = 0.5 * f64::from(height) / (0.5 * fov_y.to_radians()).tan();
    let keyframes = if case.turning {
        // The bunny's widest point is about 1.1 units from its axis.
        let degrees = turn * (speed / (focal * 1.1 / depth)).to_degrees();
        // Keyframes at most 90° apart: a scene's rotations between keyframes must stay under
        // 180° (at 270 px per shutter the bunny turns 188°).
        let steps = (degrees / 90.0).ceil().max(1.0) as usize;
        (0..=steps)
            .map(|i| {
                let t = i as f64 / steps as f64;
                format!(
                    "[[object.keyframe]]\nt = {t}\nscale = {s}\nrotate = {{ axis = [0, 1, 0], degrees = {a} }}\n",
                    s = case.scale,
                    a = degrees * (t - 0.5),
                )
            })
            .collect::<String>()
    } else {
        let dx = speed * depth / focal;
        format!(
            "[[object.keyframe]]\nt = 0\nscale = {s}\ntranslate = [{a}, 0, 0]\n[[object.keyframe]]\nt = 1\nscale = {s}\ntranslate = [{b}, 0, 0]\n",
            s = case.scale,
            a = -dx / 2.0,
            b = dx / 2.0
        )
    };
    format!(
        "background = [0.05, 0.05, 0.06]\n[camera]\neye = [0, 0, -{depth}]\ntarget = [0, 0, 0]\nfov_y = {fov_y}\nwidth = {width}\nheight = {height}\n[lighting]\nambient = 0.15\nlight = [{{ direction = [-0.5, 0.7, -1], intensity = 0.9 }}]\n[mesh_detail]\nsigma_speed = {sigma}\nsigma_base = 0.36\n[[object]]\nname = \"model\"\nshape = {{ type = \"mesh\", path = \"{}\", samples = 100000, draw = \"triangles\" }}\ncolour = [0.8, 0.7, 0.55]\n{keyframes}",
        std::fs::canonicalize(case.mesh).expect("the mesh is in ../shared/data").display()
    )
}

/// The factor on a turning case's angle that makes its fastest vertex move `speed` px per
/// shutter on screen: the widest point the angle is first reckoned from moves partly in depth
/// (the bunny's, at "90 px", moved 65 px on screen). One correction, the screen speed being
/// nearly proportional to the angle at these turns.
fn turn_for(case: &Case, speed: f64, width: u32) -> streak::Result<f64> {
    if !case.turning {
        return Ok(1.0);
    }
    let probe = Scene::parse(
        &scene_text(case, speed, width, 0.0, 1.0),
        Path::new("bench.toml"),
    )?;
    let object = &probe.objects[0];
    let mesh = object.mesh().expect("a triangle object");
    let shutter = [probe.shutter.open, probe.shutter.close];
    let fastest = fastest_px(&ScreenMotion::of(
        &probe.camera,
        object,
        &mesh.positions,
        shutter,
    ));
    Ok(if fastest > 0.0 { speed / fastest } else { 1.0 })
}

/// The screen speed of the fastest vertex, px per shutter.
fn fastest_px(screen: &ScreenMotion) -> f64 {
    screen.speed_px.iter().copied().fold(0.0, f64::max)
}

/// Renders timed: the last image, the first plan's time (with any simplification), the median
/// plan's time over the repeats (with the simplification cached after the first), the median
/// render's time, and the faces the first object was drawn with. Medians, because one render
/// alone also times first touches of memory and whatever else this machine does at that moment.
struct Timed {
    image: Framebuffer,
    first_plan: f64,
    plan: f64,
    render: f64,
    faces: usize,
}

/// Each scene's render timed `repeats` times, the scenes taking turns, so that a change in what
/// else the machine does weighs on all of them alike (timed one after the other, full detail
/// and its level of detail were seen to drift apart by 20 % on this VM).
fn timed_in_turn(renders: &[(&Scene, &Method, Lod)], repeats: usize) -> streak::Result<Vec<Timed>> {
    let mut times = vec![(Vec::new(), Vec::new()); renders.len()];
    let mut last = Vec::new();
    for _ in 0..repeats.max(1) {
        last.clear();
        for (&(scene, method, lod), (plans, renders)) in renders.iter().zip(&mut times) {
            let start = Instant::now();
            let plan = Plan::with_lod(scene, method, lod)?;
            let planned = start.elapsed().as_secs_f64();
            let image = plan.render(None).image;
            plans.push(planned);
            renders.push(start.elapsed().as_secs_f64() - planned);
            last.push((image, plan.mesh_of(0).map_or(0, |m| m.triangles.len())));
        }
    }
    Ok(last
        .into_iter()
        .zip(times)
        .map(|((image, faces), (mut plans, mut renders))| Timed {
            image,
            first_plan: plans[0],
            plan: common::median_and_min(&mut plans).0,
            render: common::median_and_min(&mut renders).0,
            faces,
        })
        .collect())
}

/// One render timed alone.
fn timed_render(scene: &Scene, method: &Method, lod: Lod) -> streak::Result<Timed> {
    let mut timed = timed_in_turn(&[(scene, method, lod)], 1)?;
    Ok(timed.remove(0))
}

fn flip(test: &Framebuffer, reference: &Framebuffer) -> f64 {
    compare(test, reference).expect("same size").flip
}

fn main() -> streak::Result<()> {
    let arg = common::args();
    let width: u32 = arg(0, "320").parse().expect("SIZE is a number of pixels");
    let sigmas: Vec<f64> = arg(1, "7.3,1,0.5")
        .split(',')
        .map(|s| s.parse().expect("SIGMAS are numbers"))
        .collect();
    let speeds: Vec<f64> = arg(2, "10,30,90,270")
        .split(',')
        .map(|s| s.parse().expect("SPEEDS are px per shutter"))
        .collect();
    let repeats: usize = arg(3, "3").parse().expect("REPEATS is a count");
    let scenes = arg(4, "");
    println!(
        "{} thread(s), {width} px wide",
        rayon::current_num_threads()
    );
    for case in &CASES {
        for &speed in &speeds {
            let share = share(speed);
            let turn = turn_for(case, speed, width)?;
            let scene = Scene::parse(
                &scene_text(case, speed, width, sigmas[0], turn),
                Path::new("bench.toml"),
            )?;
            let full = timed_render(&scene, &Method::ANALYTIC, Lod::Off)?;
            let object = &scene.objects[0];
            let mesh = object.mesh().expect("a triangle object");
            let input = Mesh {
                positions: mesh.positions.clone(),
                triangles: mesh.triangles.clone(),
            };
            let target = (share * mesh.triangles.len() as f64) as usize;
            let shutter = [scene.shutter.open, scene.shutter.close];
            let screen = ScreenMotion::of(&scene.camera, object, &mesh.positions, shutter);
            let fastest = fastest_px(&screen);
            let motion = screen.motion;
            let mut line = format!(
                "{} at {speed} px/shutter (fastest vertex {fastest:.0} px): full {} faces, analytic {:.2} s; at {target} faces ꟻLIP vs full:",
                case.name,
                mesh.triangles.len(),
                full.render
            );
            for (label, weighting) in [
                ("isotropic", Weighting::Isotropic),
                ("direction-aware", Weighting::PerVertex(motion)),
            ] {
                let options = Options {
                    target_faces: target,
                    weighting,
                    limits: None,
                };
                let simplified = simplify(&input, &options, (&[], 0), &mut |_| {})?;
                let colours = vec![mesh.colours[0]; simplified.mesh.positions.len()];
                let triangles = TriangleMesh::from_parts(
                    simplified.mesh.positions,
                    simplified.mesh.triangles,
                    colours,
                )?;
                let mut variant = scene.clone();
                variant.objects[0] = Object::triangles(
                    "model",
                    triangles,
                    object.surfels().to_vec(),
                    object.motion.clone(),
                );
                let simplified = timed_render(&variant, &Method::ANALYTIC, Lod::Off)?;
                line += &format!(" {label} {:.4}", flip(&simplified.image, &full.image));
            }
            println!("{line}");
            for &sigma in &sigmas {
                let text = scene_text(case, speed, width, sigma, turn);
                if !scenes.is_empty() {
                    let kind = case.name.split(' ').next().unwrap_or("mesh");
                    let path = Path::new(&scenes).join(format!("{kind}-{speed}px-{sigma}.toml"));
                    std::fs::write(&path, &text).expect("SCENES is a writable folder");
                }
                let lod_scene = Scene::parse(&text, Path::new("bench.toml"))?;
                let [full, lod, blur_full, blur] = <[Timed; 4]>::try_from(timed_in_turn(
                    &[
                        (&scene, &Method::ANALYTIC, Lod::Off),
                        (&lod_scene, &Method::ANALYTIC, Lod::Auto),
                        (&scene, &Method::BLUR, Lod::Off),
                        (&lod_scene, &Method::BLUR, Lod::Auto),
                    ],
                    repeats,
                )?)
                .ok()
                .expect("four renders timed");
                println!(
                    "  σ₁ = {sigma}: {} faces, simplify+plan {:.3} s; analytic ꟻLIP {:.4}, speed-up {:.2}× without, {:.2}× with the simplification; blur ꟻLIP {:.4}, speed-up {:.2}× (blur {:.3} s, LOD {:.3} s + plan, cached, {:.3} s)",
                    lod.faces,
                    lod.first_plan,
                    flip(&lod.image, &full.image),
                    full.render / lod.render,
                    full.render / (lod.render + lod.first_plan),
                    flip(&blur.image, &blur_full.image),
                    blur_full.render / (blur.render + blur.plan),
                    blur_full.render,
                    blur.render,
                    blur.plan,
                );
            }
        }
    }
    Ok(())
}
