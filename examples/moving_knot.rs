//! A torus knot built in code, sliding and turning while the shutter is open, drawn twice: as a
//! camera would record it (`blur`) and as an illustrator would show it (a `hint`, the knot sharp
//! over a trail). No scene file is involved.
//!
//! Run it with `cargo run --release --example moving_knot [OUTPUT_FOLDER]`; it writes
//! `blur.png` and `hint.png` there (default: `moving-knot`).

use std::path::{Path, PathBuf};

use streak::glam::{DQuat, DVec3};
use streak::io::image::write_png;
use streak::style::Style;
use streak::surfels::{torus_knot, Colouring};
use streak::{render, Camera, Keyframe, Light, Lighting, Method, Motion, Object, Pose, Scene};

fn main() -> streak::Result<()> {
    let folder = std::env::args_os()
        .nth(1)
        .map_or_else(|| PathBuf::from("moving-knot"), PathBuf::from);
    for file in draw(&folder)? {
        println!("wrote {}", file.display());
    }
    Ok(())
}

/// Build the scene, render it both ways into `folder`, and return the files written.
pub fn draw(folder: &Path) -> streak::Result<Vec<PathBuf>> {
    let camera = Camera::new(
        DVec3::new(0.0, 0.5, 7.0),
        DVec3::ZERO,
        DVec3::Y,
        35.0,
        320,
        200,
    )?;

    // A (2, 3) knot of orange surfels 0.02 apart.
    let mut surfels = torus_knot(2, 3, 0.35, 0.1, 0.02)?;
    Colouring::Rgb([0.8, 0.3, 0.1]).apply(&mut surfels);

    // It slides 0.8 units to the right and turns 45° about the view axis during the exposure.
    let motion = Motion::new(vec![
        Keyframe {
            t: 0.0,
            pose: Pose {
                translation: DVec3::new(-0.4, 0.0, 0.0),
                ..Pose::IDENTITY
            },
        },
        Keyframe {
            t: 1.0,
            pose: Pose {
                translation: DVec3::new(0.4, 0.0, 0.0),
                rotation: DQuat::from_rotation_z(45f64.to_radians()),
                scale: 1.0,
            },
        },
    ])?;

    let lighting = Lighting::new(0.35, vec![Light::new(DVec3::new(1.0, 1.0, 2.0), 0.75)?])?;
    let scene = Scene::new(camera)
        .with_background([1.0, 1.0, 1.0])?
        .with_lighting(lighting)
        .with_object(Object::new("knot", surfels, motion));

    std::fs::create_dir_all(folder).map_err(|e| streak::Error::io(folder, e))?;
    let mut written = Vec::new();
    for (name, method) in [
        ("blur", Method::BLUR),
        ("hint", Method::hint(Style::default())),
    ] {
        let image = render(&scene, &method, None)?.image;
        let file = folder.join(format!("{name}.png"));
        write_png(&image, &file)?;
        written.push(file);
    }
    Ok(written)
}
