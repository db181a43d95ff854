//! Scene files (TOML): what they may say, and their validation into a [`Scene`].
//!
//! Parsing is two steps: serde reads the file into plain `*Spec` structs that mirror the format
//! (unknown keys are errors), then `validate` checks every number and relation and builds the
//! scene. Every error names the file and the field (`object[1].keyframe[2].t`) and says what
//! would be right. The format is documented in the README.

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::geometry::{build_surfels, ColourSpec, Shape, Surfel};
use crate::motion::{Keyframe, Motion, Pose};
use crate::shutter::{Shutter, ShutterShape};
use glam::{DQuat, DVec3};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Largest image side accepted.
pub const MAX_IMAGE_SIDE: u32 = 8192;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneSpec {
    #[serde(default = "default_background")]
    background: [f64; 3],
    camera: CameraSpec,
    #[serde(default)]
    shutter: ShutterSpec,
    lighting: Option<LightingSpec>,
    style: Option<PathBuf>,
    #[serde(default)]
    object: Vec<ObjectSpec>,
}

fn default_background() -> [f64; 3] {
    [1.0, 1.0, 1.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraSpec {
    eye: [f64; 3],
    target: [f64; 3],
    #[serde(default = "default_up")]
    up: [f64; 3],
    fov_y: f64,
    width: u32,
    height: u32,
    near: Option<f64>,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct ShutterSpec {
    open: f64,
    close: f64,
    shape: ShutterShape,
}

/// Missing shutter fields take [`Shutter::default`]'s values.
impl Default for ShutterSpec {
    fn default() -> Self {
        let Shutter { open, close, shape } = Shutter::default();
        ShutterSpec { open, close, shape }
    }
}

fn one() -> f64 {
    1.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightingSpec {
    #[serde(default)]
    ambient: f64,
    #[serde(default)]
    light: Vec<LightSpec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightSpec {
    direction: [f64; 3],
    #[serde(default = "one")]
    intensity: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectSpec {
    name: Option<String>,
    shape: Shape,
    spacing: Option<f64>,
    colour: Option<ColourSpec>,
    #[serde(default)]
    keyframe: Vec<KeyframeSpec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeSpec {
    t: f64,
    #[serde(default)]
    translate: [f64; 3],
    rotate: Option<RotationSpec>,
    #[serde(default = "one")]
    scale: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RotationSpec {
    axis: [f64; 3],
    degrees: f64,
}

/// A directional light: `direction` points from the scene towards the light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Unit vector towards the light.
    pub direction: DVec3,
    /// Irradiance scale.
    pub intensity: f64,
}

/// Lambertian lighting; with no lights the scene is drawn unlit (colours as given).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Lighting {
    /// Irradiance added everywhere.
    pub ambient: f64,
    /// Directional lights.
    pub lights: Vec<Light>,
}

impl Lighting {
    /// Whether any shading happens at all: a scene without a `[lighting]` table (no lights, no
    /// ambient term) is drawn with its colours as given.
    #[must_use]
    pub fn is_lit(&self) -> bool {
        !self.lights.is_empty() || self.ambient != 0.0
    }

    /// The colour of a surface of `albedo` with world-space unit normal `normal`.
    #[must_use]
    pub fn shade(&self, albedo: [f32; 3], normal: DVec3) -> [f32; 3] {
        if !self.is_lit() {
            return albedo;
        }
        let irradiance = self.ambient + self.direct(normal);
        albedo.map(|c| c * irradiance as f32)
    }

    /// Irradiance from the lights alone on a surface with world-space unit normal `normal`:
    /// Σ intensity · max(0, N·L).
    #[must_use]
    pub fn direct(&self, normal: DVec3) -> f64 {
        self.lights
            .iter()
            .map(|l| l.intensity * normal.dot(l.direction).max(0.0))
            .sum()
    }
}

/// One object: its surfels in object space and its motion.
#[derive(Clone, Debug)]
pub struct Object {
    /// Name from the scene (or `object N`).
    pub name: String,
    /// Surfels in object space.
    pub surfels: Vec<Surfel>,
    /// Keyframed pose over the frame.
    pub motion: Motion,
}

/// A validated scene, ready to plan and render.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file it came from (for messages).
    pub source: PathBuf,
    /// The camera and image size.
    pub camera: Camera,
    /// Linear RGB.
    pub background: [f32; 3],
    /// When the shutter is open and how it weights time.
    pub shutter: Shutter,
    /// Lights (none: unlit).
    pub lighting: Lighting,
    /// The objects, in file order.
    pub objects: Vec<Object>,
    /// The style file `hint` uses unless told otherwise, resolved against the scene's folder.
    pub style: Option<PathBuf>,
}

impl Scene {
    /// Read and validate a scene file. Relative paths inside it (PLY files) are resolved against
    /// the file's folder.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Scene::parse(&text, path)
    }

    /// Validate scene text; `path` names the file in messages and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Scene> {
        validate(parse_toml(text, path)?, path)
    }

    /// Total number of surfels.
    #[must_use]
    pub fn surfel_count(&self) -> usize {
        self.objects.iter().map(|o| o.surfels.len()).sum()
    }
}

/// Read TOML `text` from `path` into `T`, naming the line of any syntax error or unknown key.
pub(crate) fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, path: &Path) -> Result<T> {
    toml::from_str(text).map_err(|e| {
        let line = e
            .span()
            .map(|s| text[..s.start].matches('\n').count() + 1)
            .unwrap_or(0);
        Error::input(path, format!("line {line}"), e.message().trim_end())
    })
}

/// Checks a number is finite, naming the field when it is not.
pub(crate) fn finite(path: &Path, field: &str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::input(
            path,
            field,
            format!("{v} is not a finite number"),
        ))
    }
}

fn finite3(path: &Path, field: &str, v: [f64; 3]) -> Result<DVec3> {
    for (i, c) in v.iter().enumerate() {
        finite(path, &format!("{field}[{i}]"), *c)?;
    }
    Ok(DVec3::from_array(v))
}

fn positive(path: &Path, field: &str, v: f64) -> Result<f64> {
    if finite(path, field, v)? > 0.0 {
        Ok(v)
    } else {
        Err(Error::input(
            path,
            field,
            format!("must be greater than zero, not {v}"),
        ))
    }
}

/// Largest colour component or light intensity accepted: values above 1 are bright (HDR), but
/// past this they overflow the f32 colour buffers into infinities.
pub const MAX_RADIANCE: f64 = 1e4;

/// A value in [0, MAX_RADIANCE].
fn radiance(path: &Path, field: &str, v: f64) -> Result<f64> {
    if (0.0..=MAX_RADIANCE).contains(&finite(path, field, v)?) {
        Ok(v)
    } else {
        Err(Error::input(
            path,
            field,
            format!("{v}: must be between 0 and {MAX_RADIANCE} (linear)"),
        ))
    }
}

/// A linear RGB colour, each component in [0, [`MAX_RADIANCE`]].
pub(crate) fn colour(path: &Path, field: &str, v: [f64; 3]) -> Result<[f32; 3]> {
    let mut rgb = [0.0f32; 3];
    for (i, c) in v.iter().enumerate() {
        rgb[i] = radiance(path, &format!("{field}[{i}]"), *c)? as f32;
    }
    Ok(rgb)
}

/// Check an image size: each side from 1 to [`MAX_IMAGE_SIDE`].
pub fn check_image_size(width: u32, height: u32) -> std::result::Result<(), String> {
    if (1..=MAX_IMAGE_SIDE).contains(&width) && (1..=MAX_IMAGE_SIDE).contains(&height) {
        Ok(())
    } else {
        Err(format!(
            "{width}×{height}: each side must be between 1 and {MAX_IMAGE_SIDE} pixels"
        ))
    }
}

fn validate(spec: SceneSpec, path: &Path) -> Result<Scene> {
    let camera = validate_camera(&spec.camera, path)?;
    let shutter = validate_shutter(&spec.shutter, path)?;
    let lighting = match &spec.lighting {
        None => Lighting::default(),
        Some(l) => Lighting {
            ambient: radiance(path, "lighting.ambient", l.ambient)?,
            lights: l
                .light
                .iter()
                .enumerate()
                .map(|(i, light)| {
                    let field = format!("lighting.light[{i}]");
                    let direction = finite3(path, &format!("{field}.direction"), light.direction)?
                        .try_normalize()
                        .ok_or_else(|| {
                            Error::input(
                                path,
                                format!("{field}.direction"),
                                "must not be the zero vector",
                            )
                        })?;
                    Ok(Light {
                        direction,
                        intensity: radiance(path, &format!("{field}.intensity"), light.intensity)?,
                    })
                })
                .collect::<Result<_>>()?,
        },
    };
    let base = path.parent().unwrap_or(Path::new("."));
    let objects = spec
        .object
        .iter()
        .enumerate()
        .map(|(i, o)| validate_object(o, i, path, base))
        .collect::<Result<_>>()?;
    Ok(Scene {
        source: path.to_path_buf(),
        camera,
        background: colour(path, "background", spec.background)?,
        shutter,
        lighting,
        objects,
        style: spec.style.map(|s| base.join(s)),
    })
}

fn validate_camera(c: &CameraSpec, path: &Path) -> Result<Camera> {
    let eye = finite3(path, "camera.eye", c.eye)?;
    let target = finite3(path, "camera.target", c.target)?;
    let up = finite3(path, "camera.up", c.up)?;
    let forward = target - eye;
    if !(forward.length() > 0.0) {
        return Err(Error::input(
            path,
            "camera.target",
            "must differ from camera.eye",
        ));
    }
    if !(forward.normalize().cross(up).length() > 1e-9) {
        return Err(Error::input(
            path,
            "camera.up",
            "must not be zero or parallel to the viewing direction",
        ));
    }
    let fov = finite(path, "camera.fov_y", c.fov_y)?;
    if !(fov > 0.0 && fov < 180.0) {
        return Err(Error::input(
            path,
            "camera.fov_y",
            format!("{fov}: the vertical field of view is in degrees, between 0 and 180"),
        ));
    }
    check_image_size(c.width, c.height)
        .map_err(|message| Error::input(path, "camera.width/height", message))?;
    let near = positive(
        path,
        "camera.near",
        c.near.unwrap_or(1e-3 * forward.length()),
    )?;
    Ok(Camera::look_at(
        eye, target, up, fov, c.width, c.height, near,
    ))
}

fn validate_shutter(s: &ShutterSpec, path: &Path) -> Result<Shutter> {
    let open = finite(path, "shutter.open", s.open)?;
    let close = finite(path, "shutter.close", s.close)?;
    if !(0.0..=1.0).contains(&open) || !(0.0..=1.0).contains(&close) || !(open < close) {
        return Err(Error::input(
            path,
            "shutter",
            format!(
                "open = {open}, close = {close}: need 0 ≤ open < close ≤ 1 (normalized frame time)"
            ),
        ));
    }
    Ok(Shutter {
        open,
        close,
        shape: s.shape,
    })
}

fn validate_object(o: &ObjectSpec, index: usize, path: &Path, base: &Path) -> Result<Object> {
    let field = format!("object[{index}]");
    let name = o.name.clone().unwrap_or_else(|| format!("object {index}"));
    let colour_spec = match &o.colour {
        Some(ColourSpec::Rgb(rgb)) => {
            ColourSpec::Rgb(colour(path, &format!("{field}.colour"), *rgb)?.map(f64::from))
        }
        Some(other) => other.clone(),
        None => ColourSpec::Default,
    };
    let spacing = o
        .spacing
        .map(|s| positive(path, &format!("{field}.spacing"), s))
        .transpose()?;
    let surfels = build_surfels(
        &o.shape,
        spacing,
        &colour_spec,
        path,
        base,
        &format!("{field}.shape"),
    )?;
    let mut keyframes: Vec<Keyframe> = Vec::with_capacity(o.keyframe.len());
    for (k, key) in o.keyframe.iter().enumerate() {
        let kf = format!("{field}.keyframe[{k}]");
        let t = finite(path, &format!("{kf}.t"), key.t)?;
        if !(0.0..=1.0).contains(&t) {
            return Err(Error::input(
                path,
                format!("{kf}.t"),
                format!("{t} is outside the frame: keyframe times are in [0, 1]"),
            ));
        }
        if let Some(previous) = keyframes.last() {
            if !(t > previous.t) {
                return Err(Error::input(
                    path,
                    format!("{kf}.t"),
                    format!(
                        "keyframe times must increase: {t} comes after {}",
                        previous.t
                    ),
                ));
            }
        }
        let rotation = match &key.rotate {
            None => DQuat::IDENTITY,
            Some(r) => {
                let axis = finite3(path, &format!("{kf}.rotate.axis"), r.axis)?
                    .try_normalize()
                    .ok_or_else(|| {
                        Error::input(
                            path,
                            format!("{kf}.rotate.axis"),
                            "must not be the zero vector",
                        )
                    })?;
                DQuat::from_axis_angle(
                    axis,
                    finite(path, &format!("{kf}.rotate.degrees"), r.degrees)?.to_radians(),
                )
            }
        };
        if let Some(previous) = keyframes.last() {
            // Quaternions from the given angles with a negative dot product mean the user asked
            // for the long way round, which slerp cannot take.
            if previous.pose.rotation.dot(rotation) <= 1e-9 {
                return Err(Error::input(
                    path,
                    format!("{kf}.rotate"),
                    "turns 180° or more from the previous keyframe; rotation is interpolated by slerp, which takes \
                     the shorter way, so keyframes must be less than 180° apart: add keyframes in between",
                ));
            }
        }
        keyframes.push(Keyframe {
            t,
            pose: Pose {
                translation: finite3(path, &format!("{kf}.translate"), key.translate)?,
                rotation,
                scale: positive(path, &format!("{kf}.scale"), key.scale)?,
            },
        });
    }
    // Times were checked to increase above, so only an empty list is left for `still`.
    let motion = Motion::new(keyframes).unwrap_or_else(|| Motion::still(Pose::IDENTITY));
    Ok(Object {
        name,
        surfels,
        motion,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
        [camera]
        eye = [0, 0, 5]
        target = [0, 0, 0]
        fov_y = 40
        width = 64
        height = 48

        [[object]]
        shape = { type = "sphere", radius = 1.0 }
        spacing = 0.1
    "#;

    fn parse(text: &str) -> Result<Scene> {
        Scene::parse(text, Path::new("test.toml"))
    }

    fn error_of(text: &str) -> String {
        parse(text).expect_err("should be rejected").to_string()
    }

    #[test]
    fn a_minimal_scene_has_the_documented_defaults() {
        let scene = parse(MINIMAL).unwrap();
        assert_eq!(scene.background, [1.0; 3]);
        assert_eq!(scene.shutter, Shutter::default());
        assert!(!scene.lighting.is_lit());
        assert_eq!(scene.objects.len(), 1);
        assert!(!scene.objects[0].motion.moves_within(0.0, 1.0));
    }

    #[test]
    fn unknown_keys_are_named_with_their_line() {
        let message = error_of(&MINIMAL.replace("fov_y = 40", "fov_y = 40\nfocal = 3"));
        assert!(
            message.contains("test.toml")
                && message.contains("focal")
                && message.contains("line 6"),
            "{message}"
        );
    }

    #[test]
    fn non_finite_numbers_are_rejected_by_field() {
        let message = error_of(&MINIMAL.replace("radius = 1.0", "radius = nan"));
        assert!(message.contains("object[0].shape.radius"), "{message}");
        let message = error_of(&MINIMAL.replace("eye = [0, 0, 5]", "eye = [0, inf, 5]"));
        assert!(message.contains("camera.eye[1]"), "{message}");
    }

    #[test]
    fn keyframes_out_of_order_or_outside_the_frame_are_rejected() {
        let keys = "\n[[object.keyframe]]\nt = 0.6\n[[object.keyframe]]\nt = 0.4\n";
        assert!(error_of(&format!("{MINIMAL}{keys}")).contains("object[0].keyframe[1].t"));
        let keys = "\n[[object.keyframe]]\nt = 1.5\n";
        assert!(error_of(&format!("{MINIMAL}{keys}")).contains("outside the frame"));
    }

    #[test]
    fn a_half_turn_between_keyframes_asks_for_more_keyframes() {
        let keys = "\n[[object.keyframe]]\nt = 0\n[[object.keyframe]]\nt = 1\nrotate = { axis = [0, 1, 0], degrees = 200 }\n";
        assert!(error_of(&format!("{MINIMAL}{keys}")).contains("add keyframes in between"));
    }

    #[test]
    fn lighting_shades_by_the_cosine_law() {
        let lighting = Lighting {
            ambient: 0.1,
            lights: vec![Light {
                direction: DVec3::Z,
                intensity: 0.8,
            }],
        };
        let lit = lighting.shade([1.0, 0.5, 0.0], DVec3::new(0.0, 0.6, 0.8));
        assert!((lit[0] - (0.1 + 0.8 * 0.8)).abs() < 1e-6 && (lit[1] - 0.5 * 0.74).abs() < 1e-6);
        assert_eq!(
            lighting.shade([1.0; 3], -DVec3::Z),
            [0.1; 3].map(|c: f64| c as f32)
        );
    }
}
