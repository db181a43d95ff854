//! Scenes built in code for the tests: one camera, surfels placed exactly where a test needs them.

#![allow(dead_code)]

use glam::{DQuat, DVec3};
use std::collections::HashMap;
use streak::scene::Camera;
use streak::scene::{Keyframe, Motion, Pose};
use streak::scene::{Object, Scene};
use streak::surfels::Surfel;
use streak::{render, Framebuffer, Method, Render};

/// Camera distance; the surfels sit in the plane z = 0, parallel to the image plane, where the
/// projection is exactly a scale by `focal / DISTANCE`.
pub const DISTANCE: f64 = 10.0;

pub fn camera(width: u32, height: u32) -> Camera {
    Camera::new(
        DVec3::new(0.0, 0.0, DISTANCE),
        DVec3::ZERO,
        DVec3::Y,
        30.0,
        width,
        height,
    )
    .unwrap()
    .with_near(0.01)
    .unwrap()
}

/// World units → pixels in the plane z = 0.
pub fn px_per_unit(camera: &Camera) -> f64 {
    camera.focal_px / DISTANCE
}

/// A black scene of `objects`, unlit, with the default shutter.
pub fn scene(camera: Camera, objects: Vec<Object>) -> Scene {
    let mut scene = Scene::new(camera).with_background([0.0; 3]).unwrap();
    scene.objects = objects;
    scene
}

/// A white surfel at `position` facing the camera, whose Gaussian has standard deviation `sigma`.
pub fn facing_surfel(position: DVec3, sigma: f64) -> Surfel {
    let area = (sigma / streak::surfels::SIGMA_PER_SPACING).powi(2);
    Surfel::isotropic(position, DVec3::Z, area, None, [1.0; 3])
}

pub fn pose(translation: DVec3, rotation_z_degrees: f64) -> Pose {
    Pose {
        translation,
        rotation: DQuat::from_rotation_z(rotation_z_degrees.to_radians()),
        scale: 1.0,
    }
}

/// A pose at `translation` turned `degrees` about the vertical (y) axis.
pub fn pose_about_y(translation: DVec3, degrees: f64) -> Pose {
    Pose {
        translation,
        rotation: DQuat::from_rotation_y(degrees.to_radians()),
        scale: 1.0,
    }
}

/// A rectangle of white surfels `size` wide and high, parallel to the image plane, centred on
/// `centre`, about `spacing` apart: an opaque surface. It faces the camera (+z) unless
/// `facing_away`.
pub fn patch(centre: DVec3, size: [f64; 2], spacing: f64, facing_away: bool) -> Vec<Surfel> {
    let [nx, ny] = size.map(|s| (s / spacing).ceil().max(1.0) as usize);
    let [hx, hy] = [size[0] / nx as f64, size[1] / ny as f64];
    let normal = if facing_away { -DVec3::Z } else { DVec3::Z };
    (0..nx * ny)
        .map(|k| {
            let (i, j) = ((k % nx) as f64, (k / nx) as f64);
            let offset = DVec3::new(
                (i + 0.5) * hx - size[0] / 2.0,
                (j + 0.5) * hy - size[1] / 2.0,
                0.0,
            );
            Surfel::isotropic(centre + offset, normal, hx * hy, None, [1.0; 3])
        })
        .collect()
}

/// `surfels`, all of `colour`.
pub fn coloured(mut surfels: Vec<Surfel>, colour: [f32; 3]) -> Vec<Surfel> {
    for s in &mut surfels {
        s.colour = colour;
    }
    surfels
}

/// A motion through poses at the given times.
pub fn motion(keys: &[(f64, Pose)]) -> Motion {
    Motion::new(keys.iter().map(|&(t, pose)| Keyframe { t, pose }).collect())
        .expect("sorted keyframes")
}

/// No motion at all: the object stays where its surfels are.
pub fn still() -> Motion {
    motion(&[(0.0, pose(DVec3::ZERO, 0.0))])
}

/// A uniform translation from `from` at t = 0 to `to` at t = 1.
pub fn linear(from: DVec3, to: DVec3) -> Motion {
    motion(&[(0.0, pose(from, 0.0)), (1.0, pose(to, 0.0))])
}

pub fn object(surfels: Vec<Surfel>, motion: Motion) -> Object {
    Object::new("test", surfels, motion)
}

/// The scene drawn by `method`.
pub fn draw(scene: &Scene, method: &Method) -> Framebuffer {
    render(scene, method, None).unwrap().image
}

/// The scene drawn sharp at time `t`.
pub fn sharp(scene: &Scene, t: f64) -> Render {
    render(scene, &Method::Static { time: Some(t) }, None).unwrap()
}

/// The renderers by name, for the suites that run each case through every one of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Static,
    Blur,
    Reference,
    Hint,
    Kernel3d,
    /// `kernel3d --approximate`: the paper's GPU visibility.
    Kernel3dApproximate,
}

impl Kind {
    /// The method with its defaults, and `samples` frames for the reference.
    pub fn method(self, samples: usize) -> Method {
        match self {
            Kind::Static => Method::STATIC,
            Kind::Blur => Method::BLUR,
            Kind::Reference => Method::Reference { samples },
            Kind::Hint => Method::hint(streak::style::Style::default()),
            Kind::Kernel3d => Method::KERNEL3D,
            Kind::Kernel3dApproximate => Method::Kernel3d {
                subframes: streak::Subframes::Planned { tolerance_px: 1.0 },
                visibility: streak::render::Visibility::Approximate,
            },
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Kind::Kernel3dApproximate => "kernel3d --approximate",
            _ => self.method(1).name(),
        }
    }
}

/// Σ of the red channel: for white surfels on black, the area covered in px².
pub fn energy(image: &Framebuffer) -> f64 {
    image.pixels.iter().map(|p| f64::from(p[0])).sum()
}

/// Red channel of every pixel.
pub fn red(image: &Framebuffer) -> Vec<f64> {
    image.pixels.iter().map(|p| f64::from(p[0])).collect()
}

/// Σ|a − b| / Σ|b|.
pub fn relative_l1(a: &[f64], b: &[f64]) -> f64 {
    let diff: f64 = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum();
    diff / b.iter().map(|y| y.abs()).sum::<f64>()
}

pub fn rmse(a: &Framebuffer, b: &Framebuffer) -> f64 {
    let sum: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| f64::from(p[c] - q[c]).powi(2)))
        .sum();
    (sum / (3 * a.pixels.len()) as f64).sqrt()
}

/// Background and camera of the coverage tests: a unit sphere at the origin seen from distance 4
/// fills a 160×160 image's middle.
pub const UNIT_SPHERE_VIEW: &str = r#"
    background = [0, 0, 0]
    [camera]
    eye = [0, 0, 4]
    target = [0, 0, 0]
    fov_y = 35
    width = 160
    height = 160
"#;

/// Least coverage inside a dense closed surface: nothing of what lies behind visible in 8 bits.
pub const OPAQUE: f32 = 0.999;

/// The least red value of `image` over the pixels whose centres, as offsets (dx, dy) from the
/// image centre in px, satisfy `inside` (∞ when there are none).
pub fn least_red_where(image: &Framebuffer, inside: impl Fn(f64, f64) -> bool) -> f64 {
    let (cx, cy) = (f64::from(image.width) / 2.0, f64::from(image.height) / 2.0);
    let mut least = f64::INFINITY;
    for y in 0..image.height {
        for x in 0..image.width {
            if inside(f64::from(x) + 0.5 - cx, f64::from(y) + 0.5 - cy) {
                let value = image.pixels[(y * image.width + x) as usize][0];
                least = least.min(f64::from(value));
            }
        }
    }
    least
}

/// Render a white unit sphere seen through [`UNIT_SPHERE_VIEW`] with `method` and return the least
/// coverage of any pixel centre more than 2 px inside its silhouette (radius f·tan(asin(1/4))),
/// asserting that nothing shows more than 3 px outside it. White on black makes coverage the value.
pub fn least_coverage_inside_unit_sphere(scene: &Scene, method: &Method) -> f32 {
    let image = draw(scene, method);
    let f = scene.camera.focal_px;
    let radius_px = f * (1.0f64 / 4.0).asin().tan();
    let (mut inside, mut worst) = (0, 1.0f32);
    for y in 0..160u32 {
        for x in 0..160u32 {
            let d = ((x as f64 + 0.5 - 80.0).powi(2) + (y as f64 + 0.5 - 80.0).powi(2)).sqrt();
            let value = image.pixels[(y * 160 + x) as usize][0];
            if d < radius_px - 2.0 {
                inside += 1;
                worst = worst.min(value);
            } else if d > radius_px + 3.0 {
                assert!(
                    value < 0.01,
                    "coverage outside the silhouette at ({x}, {y})"
                );
            }
        }
    }
    assert!(inside > 10_000);
    worst
}

/// A unit icosphere: the icosahedron with each triangle cut into four `subdivisions` times, new
/// vertices pushed out to the sphere; triangles wound counter-clockwise seen from outside.
pub fn icosphere(subdivisions: usize) -> (Vec<DVec3>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| DVec3::from_array(p).normalize())
    .collect();
    let mut triangles = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints = HashMap::new();
        let mut midpoint = |a: usize, b: usize, positions: &mut Vec<DVec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push((positions[a] + positions[b]).normalize());
                positions.len() - 1
            })
        };
        triangles = triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let ab = midpoint(a, b, &mut positions);
                let bc = midpoint(b, c, &mut positions);
                let ca = midpoint(c, a, &mut positions);
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    (positions, triangles)
}

/// `count` points on the unit sphere along a Fibonacci spiral.
pub fn fibonacci_sphere(count: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / count as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), z, r * phi.sin())
        })
        .collect()
}

/// Voxels along each axis, and the sphere's radius in voxels.
pub const BALL_SIDE: usize = 48;
pub const BALL_RADIUS: f64 = 18.0;

/// A uint8 volume of a ball: 8 grey levels per voxel of distance from the sphere, 100 on it.
pub fn ball_volume() -> Vec<u8> {
    let centre = (BALL_SIDE - 1) as f64 / 2.0;
    let mut bytes = Vec::with_capacity(BALL_SIDE * BALL_SIDE * BALL_SIDE);
    for z in 0..BALL_SIDE {
        for y in 0..BALL_SIDE {
            for x in 0..BALL_SIDE {
                let d = [x, y, z]
                    .map(|i| (i as f64 - centre).powi(2))
                    .iter()
                    .sum::<f64>()
                    .sqrt();
                bytes.push((100.0 + 8.0 * (BALL_RADIUS - d)).round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    bytes
}

/// Screen standard deviation of the test splat, px.
pub const SIGMA_PX: f64 = 2.0;

/// The exact box-shutter time average of a Gaussian of weight `weight` and covariance σ²I moving
/// from `c0` by `m` (px), at pixel centres: ∫₀¹ N(x; c0 + t m, σ²I) dt. Written out: with
/// a = mᵀm/σ², b = mᵀd/σ², c = dᵀd/σ² for d = x − c0, the exponent is −(a t² − 2 b t + c)/2, whose
/// integral over [0, 1] is exp(−(c − b²/a)/2) √(π/2a) [erf(√(a/2)(1 − b/a)) − erf(−√(a/2) b/a)].
pub fn exact_streak(
    width: u32,
    height: u32,
    c0: [f64; 2],
    m: [f64; 2],
    variance: f64,
    weight: f64,
) -> Vec<f64> {
    let norm = weight / (std::f64::consts::TAU * variance);
    let a = (m[0] * m[0] + m[1] * m[1]) / variance;
    let mut out = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        for x in 0..width {
            let d = [x as f64 + 0.5 - c0[0], y as f64 + 0.5 - c0[1]];
            let b = (m[0] * d[0] + m[1] * d[1]) / variance;
            let c = (d[0] * d[0] + d[1] * d[1]) / variance;
            let k = (a / 2.0).sqrt();
            let integral = (-(c - b * b / a) / 2.0).exp()
                * (std::f64::consts::PI / (2.0 * a)).sqrt()
                * (libm::erf(k * (1.0 - b / a)) - libm::erf(-k * b / a));
            out.push(norm * integral);
        }
    }
    out
}

/// A splat translating 4 world units (≈ 48 px) to the right across a 128×64 image.
pub fn translating_scene() -> (Scene, Vec<f64>) {
    let camera = camera(128, 64);
    let scale = px_per_unit(&camera);
    let surfel = facing_surfel(DVec3::ZERO, SIGMA_PX / scale);
    let travel = 4.0;
    let motion = motion(&[
        (0.0, pose(DVec3::new(-travel / 2.0, 0.0, 0.0), 0.0)),
        (1.0, pose(DVec3::new(travel / 2.0, 0.0, 0.0), 0.0)),
    ]);
    let weight = surfel.area * scale * scale;
    let exact = exact_streak(
        128,
        64,
        [64.0 - travel / 2.0 * scale, 32.0],
        [travel * scale, 0.0],
        SIGMA_PX * SIGMA_PX + streak::render::PREFILTER_VARIANCE_PX2,
        weight,
    );
    (scene(camera, vec![object(vec![surfel], motion)]), exact)
}
