//! Scene files (TOML): what they may say, and their validation into a [`Scene`].
//!
//! Parsing is two steps: serde reads the file into plain `*Spec` structs that mirror the format
//! (unknown keys are errors), then the model's validating constructors build the scene, and their
//! errors are placed in the file: every message names the file and the field
//! (`object[1].keyframe[2].t`) and says what would be right. The format is documented in the
//! README.

use glam::{DQuat, DVec3};
use serde::Deserialize;
use std::path::{Path, PathBuf};

use super::ply::read_ply_checked;
use super::raw_volume::VoxelType;
use crate::error::{Error, Result};
use crate::scene::{
    Camera, Keyframe, Light, Lighting, Motion, Object, Pose, Scene, Shutter, ShutterShape, Spot,
    TriangleMesh,
};
use crate::simplify::speed::DetailRule;
use crate::style::Style;
use crate::surfels::cloud::{check_neighbours, DEFAULT_NEIGHBOURS};
use crate::surfels::volume::{checked_stride, voxel_count, IsoSurface, Volume, MAX_VOXELS};
use crate::surfels::{
    from_mesh, from_point_cloud, from_volume, Budget, Colouring, Mesh, Primitive, Surfel,
};

/// Largest scene file read, bytes: room for eight objects of 10,000 keyframes each (about 1 MB
/// apiece with a turn in each), while the TOML parsed from it stays under about half a GB (a
/// 16 MiB file of keyframes peaked at 915 MB before it was refused for their count).
pub const MAX_SCENE_BYTES: u64 = 8 << 20;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneSpec {
    #[serde(
        default = "default_background",
        deserialize_with = "super::exact::exact"
    )]
    background: [f64; 3],
    camera: CameraSpec,
    #[serde(default)]
    shutter: ShutterSpec,
    lighting: Option<LightingSpec>,
    style: Option<PathBuf>,
    mesh_detail: Option<MeshDetailSpec>,
    #[serde(default)]
    object: Vec<ObjectSpec>,
}

/// `[mesh_detail]`: Zhang et al.'s σ₁ and σ₂ for the level of detail of moving meshes, and the
/// cap on the perimeter they allow.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshDetailSpec {
    sigma_speed: f64,
    sigma_base: f64,
    #[serde(default = "default_max_perimeter")]
    max_perimeter: f64,
}

fn default_max_perimeter() -> f64 {
    crate::simplify::speed::DEFAULT_MAX_PERIMETER_PX
}

fn default_background() -> [f64; 3] {
    [1.0, 1.0, 1.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraSpec {
    #[serde(deserialize_with = "super::exact::exact")]
    eye: [f64; 3],
    #[serde(deserialize_with = "super::exact::exact")]
    target: [f64; 3],
    #[serde(default = "default_up", deserialize_with = "super::exact::exact")]
    up: [f64; 3],
    fov_y: f64,
    width: u32,
    height: u32,
    near: Option<f64>,
    spatial_samples: Option<u32>,
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
    #[serde(default)]
    spot: Vec<SpotSpec>,
    shadow_map: Option<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightSpec {
    #[serde(deserialize_with = "super::exact::exact")]
    direction: [f64; 3],
    #[serde(default = "one")]
    intensity: f64,
    #[serde(default)]
    shadows: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SpotSpec {
    #[serde(deserialize_with = "super::exact::exact")]
    position: [f64; 3],
    #[serde(deserialize_with = "super::exact::exact")]
    target: [f64; 3],
    angle: f64,
    #[serde(default = "one")]
    intensity: f64,
    #[serde(default)]
    shadows: bool,
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
    #[serde(deserialize_with = "super::exact::exact")]
    translate: [f64; 3],
    rotate: Option<RotationSpec>,
    #[serde(default = "one")]
    scale: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RotationSpec {
    #[serde(deserialize_with = "super::exact::exact")]
    axis: [f64; 3],
    degrees: f64,
}

/// An object's geometry, in its own object space: a procedural primitive (centred at the origin),
/// a point cloud file, the iso-surface of a volume file (centred likewise) or a triangle mesh file
/// sampled into surfels (centred likewise unless it says not to be).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Shape {
    /// A sphere of `radius`.
    Sphere {
        /// Radius.
        radius: f64,
    },
    /// A rectangle in the xy plane facing +z, `size = [x, y]`.
    Quad {
        /// Side lengths along x and y.
        #[serde(deserialize_with = "super::exact::exact")]
        size: [f64; 2],
    },
    /// An axis-aligned box, `size = [x, y, z]`.
    Box {
        /// Side lengths along x, y and z.
        #[serde(deserialize_with = "super::exact::exact")]
        size: [f64; 3],
    },
    /// A capped cylinder along y (a rod), of `radius` and `length`.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Length along y.
        length: f64,
    },
    /// A torus in the xz plane around y: `major` radius of the ring, `minor` radius of the tube.
    Torus {
        /// Radius of the ring.
        major: f64,
        /// Radius of the tube.
        minor: f64,
    },
    /// A (p, q) torus knot of tube radius `tube`; `scale` sets its overall size (the core curve
    /// reaches about 3·scale from the centre).
    TorusKnot {
        /// Turns around the torus's axis.
        p: u32,
        /// Turns through the torus's hole.
        q: u32,
        /// Overall size.
        scale: f64,
        /// Tube radius.
        tube: f64,
    },
    /// A PLY point cloud (ascii or binary, optionally gzipped); normals, radii and areas missing
    /// from the file are estimated from `neighbours` nearest neighbours.
    Ply {
        /// The file, relative to the scene file.
        path: PathBuf,
        /// Neighbours used for estimation (default [`DEFAULT_NEIGHBOURS`]).
        neighbours: Option<usize>,
    },
    /// The iso-surface of a raw scalar volume (optionally gzipped), one surfel per voxel cell it
    /// crosses (Guan & Mueller 2004, §3.1); see [`crate::surfels::volume`].
    Volume(VolumeShape),
    /// A triangle mesh (OBJ or PLY, optionally gzipped) sampled into a given number of surfels,
    /// area-weighted; see [`crate::surfels::mesh`].
    Mesh(MeshShape),
}

/// How an object is coloured.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(try_from = "toml::Value")]
pub enum ColourSpec {
    /// One linear RGB colour.
    Rgb([f64; 3]),
    /// 0.5 + 0.5·n of the object-space normal: colour sticks to the surface as it moves.
    Normal,
    /// The file's colours where it has them, else light grey.
    Default,
}

impl From<&ColourSpec> for Colouring {
    fn from(spec: &ColourSpec) -> Colouring {
        match spec {
            ColourSpec::Rgb(rgb) => Colouring::Rgb(rgb.map(|c| c as f32)),
            ColourSpec::Normal => Colouring::Normal,
            ColourSpec::Default => Colouring::Own,
        }
    }
}

impl TryFrom<toml::Value> for ColourSpec {
    type Error = String;
    fn try_from(value: toml::Value) -> std::result::Result<Self, String> {
        let wrong =
            || format!("colour must be [r, g, b] (linear, 0 to 1) or \"normal\", not {value}");
        match &value {
            toml::Value::String(s) if s == "normal" => Ok(ColourSpec::Normal),
            toml::Value::Array(items) if items.len() == 3 => {
                let mut rgb = [0.0; 3];
                for (c, item) in rgb.iter_mut().zip(items) {
                    *c = match item {
                        toml::Value::Float(f) => *f,
                        toml::Value::Integer(i) => *i as f64,
                        _ => return Err(wrong()),
                    };
                }
                Ok(ColourSpec::Rgb(rgb))
            }
            _ => Err(wrong()),
        }
    }
}

/// A mesh shape as a scene file gives it (`shape = { type = "mesh", … }`), before checking.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MeshShape {
    /// The OBJ or PLY file (optionally `.gz`), relative to the scene file.
    pub path: PathBuf,
    /// How many surfels to sample the surface into.
    pub samples: i64,
    /// Whether to move the mesh so that the centre of its bounding box is the object's origin
    /// (default true); false keeps the file's coordinates.
    pub centre: Option<bool>,
    /// `"surfels"` (the default) or `"triangles"`: drawn as its triangles by the methods that
    /// can (`static`, `reference`, `analytic`), as its sampled surfels by the others.
    pub draw: Option<String>,
}

impl MeshShape {
    /// Check every field, read the file and sample its surface into surfels (within `budget`).
    /// `file` names the scene in messages, `base` anchors the relative path, `field` is where the
    /// shape sits in the scene (e.g. `object[2].shape`).
    pub fn surfels(
        &self,
        file: &Path,
        base: &Path,
        field: &str,
        budget: Budget,
    ) -> Result<Vec<Surfel>> {
        Ok(self.read(file, base, field, budget)?.2)
    }

    /// Whether the mesh is drawn as triangles; an error names `draw` when it is neither
    /// `"surfels"` nor `"triangles"`.
    pub fn as_triangles(&self, file: &Path, field: &str) -> Result<bool> {
        match self.draw.as_deref() {
            None | Some("surfels") => Ok(false),
            Some("triangles") => Ok(true),
            Some(other) => Err(Error::input(
                file,
                format!("{field}.draw"),
                format!("{other:?}: draw a mesh as \"surfels\" or \"triangles\""),
            )),
        }
    }

    /// Check every field and read the file: the mesh, the offset its surfels were moved by
    /// (the centre of its bounds, or zero) and the surfels sampled from it.
    fn read(
        &self,
        file: &Path,
        base: &Path,
        field: &str,
        budget: Budget,
    ) -> Result<(Mesh, DVec3, Vec<Surfel>)> {
        let samples_field = format!("{field}.samples");
        let count = usize::try_from(self.samples)
            .ok()
            .filter(|&n| n >= 1)
            .ok_or_else(|| {
                Error::input(
                    file,
                    &samples_field,
                    format!("{}: the number of surfels must be at least 1", self.samples),
                )
            })?;
        budget
            .allow(
                count,
                &samples_field,
                &format!("{count} surfels are"),
                "sample fewer",
            )
            .map_err(|e| e.in_file(file, ""))?;
        let path = base.join(&self.path);
        let mesh = Mesh::read(&path).map_err(|e| e.named_by(file, &format!("{field}.path")))?;
        let centre = self.centre.unwrap_or(true);
        let surfels = from_mesh(&mesh, count, centre).map_err(|e| e.in_file(&path, ""))?;
        let offset = match (centre, mesh.bounds()) {
            (true, Some((lo, hi))) => 0.5 * (lo + hi),
            _ => DVec3::ZERO,
        };
        Ok((mesh, offset, surfels))
    }

    /// The mesh as triangles (coloured by `colouring`) with the surfels sampled from it.
    pub fn triangles(
        &self,
        file: &Path,
        base: &Path,
        field: &str,
        budget: Budget,
        colouring: Colouring,
    ) -> Result<(TriangleMesh, Vec<Surfel>)> {
        let (mesh, offset, surfels) = self.read(file, base, field, budget)?;
        let triangles = TriangleMesh::new(&mesh, offset, colouring)
            .map_err(|e| e.in_file(&base.join(&self.path), ""))?;
        Ok((triangles, surfels))
    }
}

/// A volume shape as a scene file gives it (`shape = { type = "volume", … }`), before checking.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VolumeShape {
    /// The raw file (`.gz` for gzip), relative to the scene file.
    pub path: PathBuf,
    /// Voxels along x, y and z.
    #[serde(deserialize_with = "super::exact::exact")]
    pub dimensions: [i64; 3],
    /// Voxel type: `uint8`, `uint16`, `int16` or `float32`.
    pub voxel: String,
    /// Distance between voxel centres along x, y and z in object units (default [1, 1, 1]).
    #[serde(default, deserialize_with = "super::exact::exact_option")]
    pub spacing: Option<[f64; 3]>,
    /// The iso-value; the surface encloses the values above it.
    pub iso: f64,
    /// Use every `stride`-th voxel along each axis (default 1).
    pub stride: Option<i64>,
}

impl VolumeShape {
    /// Check every field, read the file and extract the iso-surface into surfels (within
    /// `budget`). `file` names the scene in messages, `base` anchors the relative path, `field` is
    /// where the shape sits in the scene (e.g. `object[2].shape`).
    pub fn surfels(
        &self,
        file: &Path,
        base: &Path,
        field: &str,
        budget: Budget,
    ) -> Result<Vec<Surfel>> {
        let voxel = VoxelType::from_name(&self.voxel).ok_or_else(|| {
            let names: Vec<String> = VoxelType::ALL
                .iter()
                .map(|t| format!("\"{}\"", t.name()))
                .collect();
            Error::input(
                file,
                format!("{field}.voxel"),
                format!("\"{}\": use one of {}", self.voxel, names.join(", ")),
            )
        })?;
        let mut dimensions = [0usize; 3];
        for (axis, &n) in self.dimensions.iter().enumerate() {
            if !(2..=MAX_VOXELS as i64).contains(&n) {
                return Err(Error::input(
                    file,
                    format!("{field}.dimensions[{axis}]"),
                    format!("{n}: a volume needs at least 2 voxels along each axis"),
                ));
            }
            dimensions[axis] = n as usize;
        }
        voxel_count(dimensions).map_err(|e| e.in_file(file, field))?;
        let volume = Volume::read(&base.join(&self.path), dimensions, voxel)
            .map_err(|e| e.named_by(file, &format!("{field}.path")))?;
        let stride = checked_stride(self.stride.unwrap_or(1), dimensions)
            .map_err(|e| e.in_file(file, field))?;
        let surface = IsoSurface {
            iso: self.iso,
            spacing: DVec3::from_array(self.spacing.unwrap_or([1.0; 3])),
            stride,
        };
        from_volume(&volume, &surface, budget).map_err(|e| e.in_file(file, field))
    }
}

impl Scene {
    /// Read and validate a scene file, within the default surfel budget. Relative paths inside
    /// it (point clouds, meshes, volumes, the style) are resolved against the file's folder.
    pub fn load(path: &Path) -> Result<Scene> {
        Scene::load_within(path, Budget::default())
    }

    /// [`Scene::load`] with a surfel budget for the whole scene: every object's surfels are
    /// counted against it before they are made.
    pub fn load_within(path: &Path, budget: Budget) -> Result<Scene> {
        let text = super::read::read_text(path, MAX_SCENE_BYTES)?;
        Scene::parse_within(&text, path, budget)
    }

    /// Validate scene text, within the default surfel budget; `path` names the file in messages
    /// and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Scene> {
        Scene::parse_within(text, path, Budget::default())
    }

    /// [`Scene::parse`] within a surfel budget for the whole scene.
    pub fn parse_within(text: &str, path: &Path, budget: Budget) -> Result<Scene> {
        validate(parse_toml(text, path)?, path, budget)
    }

    /// The style the scene names (`style = "…"`), read; `None` when it names none. A file that
    /// cannot be read is an error naming the scene file and its `style` field; a mistake inside
    /// the style names the style file and its field.
    pub fn own_style(&self) -> Result<Option<Style>> {
        let Some(path) = &self.style else {
            return Ok(None);
        };
        Style::load(path).map(Some).map_err(|e| match &self.source {
            Some(scene) => e.named_by(scene, "style"),
            None => e,
        })
    }
}

/// Read TOML `text` from `path` into `T`, naming the line of any syntax error or unknown key.
pub(crate) fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, path: &Path) -> Result<T> {
    let refusal = |e: &toml::de::Error, field: String| {
        let line = e
            .span()
            .map(|s| text[..s.start].matches('\n').count() + 1)
            .unwrap_or(0);
        let place = if field.is_empty() || field == "." {
            format!("line {line}")
        } else {
            format!("line {line}, {field}")
        };
        Error::input(path, place, numbers_shortened(e.message().trim_end()))
    };
    let document = toml::Deserializer::parse(text).map_err(|e| refusal(&e, String::new()))?;
    // The field's path ("speed_lines.count", "object[0].keyframe[1].t") beside its line: a type
    // error names the value and the type, not the field.
    serde_path_to_error::deserialize(document).map_err(|e| refusal(e.inner(), e.path().to_string()))
}

/// `message` with each number quoted in backticks that runs past 24 characters (the TOML
/// reader prints a float given for an integer with all its digits: 10³⁰⁰ as 301 of them) shown
/// as [`crate::error::shown`] shows numbers.
fn numbers_shortened(message: &str) -> String {
    let mut parts = message.split('`');
    let mut out = parts.next().unwrap_or_default().to_string();
    for (k, part) in parts.enumerate() {
        out.push('`');
        // Odd parts lie between backticks.
        match part.parse::<f64>() {
            Ok(value) if k % 2 == 0 && part.len() > 24 => out += &crate::error::shown(value),
            _ => out += part,
        }
    }
    out
}

fn validate(spec: SceneSpec, path: &Path, mut budget: Budget) -> Result<Scene> {
    let within = |field: &'static str| move |e: Error| e.in_file(path, field);
    let c = &spec.camera;
    let mut camera = Camera::new(
        DVec3::from_array(c.eye),
        DVec3::from_array(c.target),
        DVec3::from_array(c.up),
        c.fov_y,
        c.width,
        c.height,
    )
    .map_err(within("camera"))?;
    if let Some(near) = c.near {
        camera = camera.with_near(near).map_err(within("camera"))?;
    }
    if let Some(samples) = c.spatial_samples {
        camera = camera
            .with_spatial_samples(samples)
            .map_err(within("camera"))?;
    }
    let shutter = Shutter::new(spec.shutter.open, spec.shutter.close, spec.shutter.shape)
        .map_err(within("shutter"))?;
    let lighting = match &spec.lighting {
        None => Lighting::default(),
        Some(l) => {
            let lights = l
                .light
                .iter()
                .enumerate()
                .map(|(i, light)| {
                    Light::new(DVec3::from_array(light.direction), light.intensity)
                        .map(|l| l.with_shadows(light.shadows))
                        .map_err(|e| e.in_file(path, &format!("lighting.light[{i}]")))
                })
                .collect::<Result<_>>()?;
            let spots = l
                .spot
                .iter()
                .enumerate()
                .map(|(i, spot)| {
                    Spot::new(
                        DVec3::from_array(spot.position),
                        DVec3::from_array(spot.target),
                        spot.angle,
                        spot.intensity,
                        spot.shadows,
                    )
                    .map_err(|e| e.in_file(path, &format!("lighting.spot[{i}]")))
                })
                .collect::<Result<_>>()?;
            let mut lighting = Lighting::new(l.ambient, lights)
                .map_err(within("lighting"))?
                .with_spots(spots);
            if let Some(texels) = l.shadow_map {
                lighting = lighting
                    .with_shadow_map(texels)
                    .map_err(within("lighting"))?;
            }
            lighting
        }
    };
    let base = path.parent().unwrap_or(Path::new("."));
    let mut scene = Scene::new(camera)
        .with_background(spec.background)
        .map_err(within(""))?
        .with_shutter(shutter)
        .with_lighting(lighting);
    if let Some(d) = &spec.mesh_detail {
        scene = scene
            .with_mesh_detail(DetailRule {
                sigma_speed: d.sigma_speed,
                sigma_base: d.sigma_base,
                max_perimeter_px: d.max_perimeter,
            })
            .map_err(within("mesh_detail"))?;
    }
    for (i, o) in spec.object.iter().enumerate() {
        let object = validate_object(o, i, path, base, budget)?;
        budget.take(object.surfels().len());
        scene = scene.with_object(object);
    }
    scene.source = Some(path.to_path_buf());
    scene.style = spec.style.map(|s| base.join(s));
    Ok(scene)
}

fn validate_object(
    o: &ObjectSpec,
    index: usize,
    path: &Path,
    base: &Path,
    budget: Budget,
) -> Result<Object> {
    let field = format!("object[{index}]");
    let name = o.name.clone().unwrap_or_else(|| format!("object {index}"));
    let colouring = match &o.colour {
        Some(ColourSpec::Rgb(rgb)) => {
            Colouring::Rgb(crate::scene::rgb("colour", *rgb).map_err(|e| e.in_file(path, &field))?)
        }
        Some(other) => Colouring::from(other),
        None => Colouring::Own,
    };
    let mesh = match &o.shape {
        Shape::Mesh(shape) if shape.as_triangles(path, &format!("{field}.shape"))? => {
            if o.spacing.is_some() {
                return Err(Error::input(
                    path,
                    format!("{field}.spacing"),
                    "a mesh is sampled into `shape.samples` surfels: remove this `spacing`",
                ));
            }
            Some(shape.triangles(path, base, &format!("{field}.shape"), budget, colouring)?)
        }
        _ => None,
    };
    let (triangles, mut surfels) = match mesh {
        Some((triangles, surfels)) => (Some(triangles), surfels),
        None => (None, object_surfels(o, path, base, &field, budget)?),
    };
    colouring.apply(&mut surfels);
    let mut keyframes = Vec::with_capacity(o.keyframe.len());
    // The previous keyframe's rotation as written: its unit axis (none for no rotation) and angle.
    let mut previous: Option<(Option<DVec3>, f64)> = None;
    for (k, key) in o.keyframe.iter().enumerate() {
        let rotate_field = format!("{field}.keyframe[{k}].rotate");
        let (axis, degrees) = match &key.rotate {
            None => (None, 0.0),
            Some(r) => {
                let axis = crate::scene::finite3("axis", DVec3::from_array(r.axis))
                    .map_err(|e| e.in_file(path, &rotate_field))?;
                let axis = crate::math::unit_direction(axis).ok_or_else(|| {
                    Error::input(
                        path,
                        format!("{rotate_field}.axis"),
                        "must not be the zero vector",
                    )
                })?;
                let degrees = crate::scene::finite("degrees", r.degrees)
                    .map_err(|e| e.in_file(path, &rotate_field))?;
                // No turn about one axis is no rotation: the step from it is the next angle
                // as written, about whatever axis.
                ((degrees != 0.0).then_some(axis), degrees)
            }
        };
        if let Some(turn) = turn_past_half(previous, (axis, degrees)) {
            return Err(Error::input(path, &rotate_field, turn));
        }
        previous = Some((axis, degrees));
        let mut rotation = axis.map_or(DQuat::IDENTITY, |axis| {
            DQuat::from_axis_angle(axis, degrees.to_radians())
        });
        // q and −q are one orientation: after a whole turn (q = −1) a tilt about another axis
        // is taken the short way, as between two axes only the orientations count. Steps about
        // one axis are under half a turn (above), so their quaternions never disagree in sign.
        if keyframes
            .last()
            .is_some_and(|last: &Keyframe| last.pose.rotation.dot(rotation) < 0.0)
        {
            rotation = -rotation;
        }
        keyframes.push(Keyframe {
            t: key.t,
            pose: Pose {
                translation: DVec3::from_array(key.translate),
                rotation,
                scale: key.scale,
            },
        });
    }
    let motion = Motion::new(keyframes).map_err(|e| e.in_file(path, &field))?;
    Ok(match triangles {
        Some(mesh) => Object::triangles(name, mesh, surfels, motion),
        None => Object::new(name, surfels, motion),
    })
}

/// Why a keyframe's rotation, written as `axis` and `degrees`, cannot follow the `previous`
/// one's, if it cannot. Rotations between keyframes are interpolated by slerp, the shorter way
/// between two orientations, so a step must turn less than 180°. The quaternions cannot tell
/// whole turns (720° is the identity, and 0° → 720° would be drawn as no rotation at all), so
/// the angles as written are compared: about one axis (or from no rotation) the step between
/// them; about two different axes the orientations, which [`Motion::new`] checks. A spin of many
/// turns is written as keyframes less than 180° apart: 0, 90, 180, 270, 360, 450, …
fn turn_past_half(
    previous: Option<(Option<DVec3>, f64)>,
    (axis, degrees): (Option<DVec3>, f64),
) -> Option<String> {
    let (previous_axis, previous_degrees) = previous?;
    // Angles about one axis (or from no rotation) compare directly; the opposite axis turns the
    // other way.
    let step = match (previous_axis, axis) {
        (None, _) | (_, None) => Some(degrees - previous_degrees),
        (Some(a), Some(b)) if a.dot(b) > 1.0 - 1e-12 => Some(degrees - previous_degrees),
        (Some(a), Some(b)) if a.dot(b) < -1.0 + 1e-12 => Some(-degrees - previous_degrees),
        // About a new axis only the orientations count, and a whole turn about it is none.
        _ if degrees.abs() >= 360.0 => {
            return Some(format!(
                "turns {}° about another axis than the previous keyframe's; between two axes only \
                 the orientations count, and whole turns cannot be seen in them: write the turn \
                 about one axis, in keyframes less than 180° apart",
                degrees.abs()
            ))
        }
        _ => None,
    }?;
    (step.abs() >= 180.0).then(|| {
        format!(
            "turns {}° from the previous keyframe; rotation is interpolated by slerp, which takes \
             the shorter way, so keyframes must be less than 180° apart: add keyframes in between",
            step.abs()
        )
    })
}

/// The surfels of an object's shape, in their sources' own colours, within `budget`.
fn object_surfels(
    o: &ObjectSpec,
    path: &Path,
    base: &Path,
    field: &str,
    budget: Budget,
) -> Result<Vec<Surfel>> {
    let shape_field = format!("{field}.shape");
    let spacing_field = format!("{field}.spacing");
    let no_spacing = |why: &str| match o.spacing {
        Some(_) => Err(Error::input(path, &spacing_field, why)),
        None => Ok(()),
    };
    let primitive = match o.shape {
        Shape::Ply {
            path: ref file,
            neighbours,
        } => {
            no_spacing("a point cloud makes one surfel per point: remove this `spacing`")?;
            let neighbours = check_neighbours(neighbours.unwrap_or(DEFAULT_NEIGHBOURS))
                .map_err(|e| e.in_file(path, &shape_field))?;
            let file = base.join(file);
            // Checked against the count the header declares, before the points are read.
            let cloud = read_ply_checked(&file, |points| {
                budget
                    .allow(
                        points,
                        "element vertex",
                        &format!("its {points} points are"),
                        "thin the cloud",
                    )
                    .map_err(|e| e.in_file(&file, ""))
            })
            .map_err(|e| e.named_by(path, &format!("{shape_field}.path")))?;
            return from_point_cloud(&cloud, neighbours).map_err(|e| e.in_file(&file, ""));
        }
        Shape::Volume(ref volume) => {
            no_spacing(
                "a volume makes one surfel per voxel cell its surface crosses: remove this \
                 `spacing` (the distance between voxels is `shape.spacing = [x, y, z]`)",
            )?;
            return volume.surfels(path, base, &shape_field, budget);
        }
        Shape::Mesh(ref mesh) => {
            no_spacing("a mesh is sampled into `shape.samples` surfels: remove this `spacing`")?;
            return mesh.surfels(path, base, &shape_field, budget);
        }
        Shape::Sphere { radius } => Primitive::Sphere { radius },
        Shape::Quad { size } => Primitive::Quad { size },
        Shape::Box { size } => Primitive::Box { size },
        Shape::Cylinder { radius, length } => Primitive::Cylinder { radius, length },
        Shape::Torus { major, minor } => Primitive::Torus { major, minor },
        Shape::TorusKnot { p, q, scale, tube } => Primitive::TorusKnot { p, q, scale, tube },
    };
    let spacing = o.spacing.ok_or_else(|| {
        Error::input(
            path,
            &spacing_field,
            "a procedural shape needs `spacing`, the distance between surfels",
        )
    })?;
    primitive.surfels(spacing, budget).map_err(|e| match &e {
        Error::Invalid { field: f, .. } if f == "spacing" => e.in_file(path, field),
        _ => e.in_file(path, &shape_field),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surfels::volume::tests::{voxel_positions, workdir};

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
    fn a_huge_float_for_an_integer_is_shown_short() {
        let message = error_of(&MINIMAL.replace("width = 64", "width = 1e300"));
        assert!(
            message.contains(
                "line 6, camera.width: invalid type: floating point `1e300`, expected u32"
            ),
            "{message}"
        );
        // Short numbers and other quoted words are left as the reader wrote them.
        let message = error_of(&MINIMAL.replace("width = 64", "width = 64.5"));
        assert!(message.contains("`64.5`"), "{message}");
    }

    #[test]
    fn arrays_of_another_length_and_files_past_their_size_are_refused() {
        // A fourth coordinate, colour channel or size was dropped without a word.
        for (from, to) in [
            ("eye = [0, 0, 5]", "eye = [0, 0, 5, 9]"),
            ("eye = [0, 0, 5]", "eye = [0, 0]"),
            ("[camera]", "background = [0, 0, 0, 1]\n[camera]"),
            (
                "shape = { type = \"sphere\", radius = 1.0 }",
                "shape = { type = \"box\", size = [1, 1, 1, 1] }",
            ),
        ] {
            let message = error_of(&MINIMAL.replace(from, to));
            assert!(message.contains("invalid length"), "{to}: {message}");
        }
        let message = crate::io::read::tests::refusal_past_size(MINIMAL, MAX_SCENE_BYTES, |path| {
            Scene::load(path).map(|_| ())
        });
        assert!(
            message.contains("large.toml: file: larger than 8388608 bytes"),
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

    /// The mesh detail rule is read with its cap defaulted, and a cap that is not a positive
    /// number of px (which would keep no face or every face) is refused by name.
    #[test]
    fn mesh_detail_takes_its_cap_or_the_default_and_refuses_a_cap_that_is_not_positive() {
        let with = |lines: &str| {
            format!("[mesh_detail]\nsigma_speed = 0.4\nsigma_base = 0.3\n{lines}{MINIMAL}")
        };
        let rule = parse(&with("")).unwrap().mesh_detail;
        assert_eq!(
            rule.max_perimeter_px,
            crate::simplify::speed::DEFAULT_MAX_PERIMETER_PX
        );
        assert_eq!(rule.perimeter_px(10.0), 4.3);
        assert_eq!(rule.perimeter_px(1000.0), rule.max_perimeter_px);
        let rule = parse(&with("max_perimeter = 20\n")).unwrap().mesh_detail;
        assert_eq!(rule.perimeter_px(10.0), 4.3);
        assert_eq!(rule.perimeter_px(100.0), 20.0);
        for cap in ["0", "-3", "nan", "inf"] {
            let message = error_of(&with(&format!("max_perimeter = {cap}\n")));
            assert!(
                message.contains("mesh_detail.max_perimeter"),
                "{cap}: {message}"
            );
        }
    }

    #[test]
    fn keyframes_out_of_order_or_outside_the_frame_are_rejected() {
        let keys = "\n[[object.keyframe]]\nt = 0.6\n[[object.keyframe]]\nt = 0.4\n";
        assert!(error_of(&format!("{MINIMAL}{keys}")).contains("object[0].keyframe[1].t"));
        let keys = "\n[[object.keyframe]]\nt = 1.5\n";
        assert!(error_of(&format!("{MINIMAL}{keys}")).contains("outside the frame"));
    }

    #[test]
    fn more_keyframes_than_the_cap_are_refused_by_count() {
        use crate::scene::motion::MAX_KEYFRAMES;
        let keys = |n: usize| {
            let list: Vec<String> = (0..n)
                .map(|i| format!("{{ t = {} }}", i as f64 / n as f64))
                .collect();
            format!("{MINIMAL}keyframe = [{}]\n", list.join(", "))
        };
        let at_cap = Scene::parse(&keys(MAX_KEYFRAMES), Path::new("s.toml"));
        assert!(at_cap.is_ok(), "{:?}", at_cap.err());
        let message = error_of(&keys(MAX_KEYFRAMES + 1));
        assert!(
            message.contains("object[0].keyframe") && message.contains("at most 10000"),
            "{message}"
        );
    }

    #[test]
    fn a_half_turn_between_keyframes_asks_for_more_keyframes() {
        let keys = "\n[[object.keyframe]]\nt = 0\n[[object.keyframe]]\nt = 1\nrotate = { axis = [0, 1, 0], degrees = 200 }\n";
        assert!(error_of(&format!("{MINIMAL}{keys}")).contains("add keyframes in between"));
        // Under 180° as written, but the quaternions' rounding may take either way: the
        // orientations' check refuses it, and says why.
        let near = keys.replace("200", "179.99999999999997");
        let message = error_of(&format!("{MINIMAL}{near}"));
        assert!(message.contains("so near it"), "{message}");
        let fine = keys.replace("200", "179.9999");
        assert!(Scene::parse(&format!("{MINIMAL}{fine}"), Path::new("s.toml")).is_ok());
    }

    #[test]
    fn a_tilt_after_a_whole_turn_is_the_turn_between_the_orientations() {
        // A whole turn about y in three steps (its quaternion −1), then 10° about x: the two
        // orientations are 10° apart, and the tilt is taken that way rather than refused.
        let mut keys = String::new();
        for (t, axis, degrees) in [
            (0.0, "0, 1, 0", 0),
            (0.25, "0, 1, 0", 120),
            (0.5, "0, 1, 0", 240),
            (0.75, "0, 1, 0", 360),
            (1.0, "1, 0, 0", 10),
        ] {
            keys.push_str(&format!(
                "\n[[object.keyframe]]\nt = {t}\nrotate = {{ axis = [{axis}], degrees = {degrees} }}\n"
            ));
        }
        let scene = Scene::parse(&format!("{MINIMAL}{keys}"), Path::new("s.toml")).unwrap();
        let motion = &scene.objects[0].motion;
        let (end, tilt) = (motion.pose_at(0.75).rotation, motion.pose_at(1.0).rotation);
        assert!((end.angle_between(tilt).to_degrees() - 10.0).abs() < 1e-9);
        // Halfway through the tilt, 5° from the upright orientation.
        let halfway = motion.pose_at(0.875).rotation;
        assert!((halfway.angle_between(DQuat::IDENTITY).to_degrees() - 5.0).abs() < 1e-6);
    }

    fn mesh_shape(path: &str, samples: i64, centre: Option<bool>) -> MeshShape {
        MeshShape {
            path: path.into(),
            samples,
            centre,
            draw: None,
        }
    }

    #[test]
    fn mesh_shapes_check_their_fields_and_centre_the_mesh() {
        let dir = std::env::temp_dir().join(format!("streak-mesh-shape-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join("box.obj"),
            "v 1 1 1\nv 3 1 1\nv 3 5 1\nv 1 5 1\nf 1 2 3 4\n",
        )
        .unwrap();
        std::fs::write(dir.join("flat.obj"), "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n").unwrap();
        let scene = Path::new("scene.toml");
        let surfels =
            |s: &MeshShape| s.surfels(scene, &dir, "object[0].shape", Budget::new(1000).unwrap());
        let error = |s: &MeshShape| surfels(s).unwrap_err().to_string();

        let centred = surfels(&mesh_shape("box.obj", 200, None)).unwrap();
        assert_eq!(centred.len(), 200);
        let mean = centred.iter().map(|s| s.position).sum::<DVec3>() / 200.0;
        assert!(mean.length() < 1e-12, "centroid {mean}");
        let kept = surfels(&mesh_shape("box.obj", 200, Some(false))).unwrap();
        assert!(
            (kept[0].position - centred[0].position - DVec3::new(2.0, 3.0, 1.0)).length() < 1e-12
        );

        for bad in [0, -3, 1001] {
            let message = error(&mesh_shape("box.obj", bad, None));
            assert!(
                message.starts_with("scene.toml: object[0].shape.samples: "),
                "{message}"
            );
        }
        let message = error(&mesh_shape("flat.obj", 10, None));
        assert!(
            message.contains("flat.obj: faces: none of the 1 triangles has a surface to draw or sample: 1 of zero area"),
            "{message}"
        );
        let message = error(&mesh_shape("box.stl", 10, None));
        assert!(message.contains("box.stl: file name: "), "{message}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A scene's volume shape over a small uint8 sphere file.
    fn volume_shape() -> (VolumeShape, PathBuf) {
        let dir = workdir("shape");
        let bytes: Vec<u8> = voxel_positions([16; 3], DVec3::ONE)
            .map(|p| (100.0 + 8.0 * (6.0 - p.length())).clamp(0.0, 255.0) as u8)
            .collect();
        std::fs::write(dir.join("ball.raw"), bytes).unwrap();
        let shape = VolumeShape {
            path: "ball.raw".into(),
            dimensions: [16; 3],
            voxel: "uint8".into(),
            spacing: None,
            iso: 100.0,
            stride: None,
        };
        (shape, dir)
    }

    #[test]
    fn shape_fields_are_checked_by_name() {
        let (good, dir) = volume_shape();
        let scene = Path::new("scene.toml");
        let surfels = good
            .surfels(
                scene,
                &dir,
                "object[0].shape",
                Budget::new(1_000_000).unwrap(),
            )
            .unwrap();
        assert!(surfels.len() > 100);
        type Edit = fn(&mut VolumeShape);
        let cases: [(Edit, &str, &str); 11] = [
            (
                |s| s.voxel = "int32".into(),
                "object[0].shape.voxel",
                "use one of \"uint8\"",
            ),
            (
                |s| s.dimensions[2] = 0,
                "object[0].shape.dimensions[2]",
                "at least 2",
            ),
            (
                |s| s.dimensions[0] = -16,
                "object[0].shape.dimensions[0]",
                "at least 2",
            ),
            (
                |s| s.dimensions = [1 << 20; 3],
                "object[0].shape.dimensions",
                "limit of 2147483648",
            ),
            (
                |s| s.spacing = Some([1.0, -1.0, 1.0]),
                "object[0].shape.spacing[1]",
                "between",
            ),
            (
                |s| s.spacing = Some([1.0, 1.0, f64::NAN]),
                "object[0].shape.spacing[2]",
                "between",
            ),
            (
                |s| s.iso = f64::INFINITY,
                "object[0].shape.iso",
                "not a finite number",
            ),
            (
                |s| s.iso = 300.0,
                "object[0].shape.iso",
                "values run from 44 to 141",
            ),
            (
                |s| s.stride = Some(0),
                "object[0].shape.stride",
                "from 1 (every voxel) to 15",
            ),
            (
                |s| s.stride = Some(16),
                "object[0].shape.stride",
                "from 1 (every voxel) to 15",
            ),
            (
                |s| s.stride = Some(-3),
                "object[0].shape.stride",
                "-3: use a whole number from 1",
            ),
        ];
        for (change, field, hint) in cases {
            let mut bad = good.clone();
            change(&mut bad);
            let message = bad
                .surfels(
                    scene,
                    &dir,
                    "object[0].shape",
                    Budget::new(1_000_000).unwrap(),
                )
                .unwrap_err()
                .to_string();
            assert!(
                message.starts_with(&format!("scene.toml: {field}: ")) && message.contains(hint),
                "{message}"
            );
        }
        let message = good
            .surfels(scene, &dir, "object[0].shape", Budget::new(100).unwrap())
            .unwrap_err()
            .to_string();
        assert!(message.contains("object[0].shape.stride") && message.contains("larger stride"));
    }
}
