//! The scene model: a camera, a shutter, lighting, a background and objects, each a geometry
//! with a keyframed motion. Build one in code with the validating constructors here, or read a
//! scene file with [`Scene::load`] ([`crate::io::scene_file`]); either way every number is checked
//! once, where the scene is built, and the renderers can trust it.

pub mod camera;
pub mod motion;
pub mod shutter;
pub mod triangles;

pub use camera::{Camera, MAX_IMAGE_SIDE};
pub use motion::{Keyframe, Motion, Pose};
pub use shutter::{Shutter, ShutterShape};
pub use triangles::TriangleMesh;

use crate::error::{Error, Result};
use crate::simplify::speed::DetailRule;
use crate::surfels::Surfel;
use glam::DVec3;
use std::path::PathBuf;

/// Largest colour component or light intensity accepted: values above 1 are bright (HDR), but
/// past this they overflow the f32 colour buffers into infinities.
pub const MAX_RADIANCE: f64 = 1e4;

/// A directional light: `direction` points from the scene towards the light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Unit vector towards the light.
    pub direction: DVec3,
    /// Irradiance scale.
    pub intensity: f64,
    /// Whether triangle objects cast shadows from it onto triangle objects.
    pub shadows: bool,
}

impl Light {
    /// A light from `direction` (any length but zero; it is normalized) of `intensity` in
    /// [0, [`MAX_RADIANCE`]], casting no shadows. Errors name `direction` or `intensity`.
    pub fn new(direction: DVec3, intensity: f64) -> Result<Light> {
        let direction = crate::math::unit_direction(finite3("direction", direction)?)
            .ok_or_else(|| Error::invalid("direction", "must not be the zero vector"))?;
        Ok(Light {
            direction,
            intensity: radiance("intensity", intensity)?,
            shadows: false,
        })
    }

    /// The same light casting shadows (or not).
    #[must_use]
    pub fn with_shadows(mut self, shadows: bool) -> Light {
        self.shadows = shadows;
        self
    }
}

/// A spot light: a point at `position` shining along `direction` within a cone of half-angle
/// `angle`, its edge softened over the outer [`SPOT_EDGE`] of the angle. Irradiance does not
/// fall off with distance (an illustration light, like the directional one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spot {
    /// Where the light is, in world space.
    pub position: DVec3,
    /// Unit vector along the cone's axis, away from the light.
    pub direction: DVec3,
    /// Half-angle of the cone, radians, in (0, 80°].
    pub angle: f64,
    /// Cosines of the half-angle and of the edge's inner end: where the light fades.
    edge_cosines: [f64; 2],
    /// Irradiance scale on the axis.
    pub intensity: f64,
    /// Whether triangle objects cast shadows from it onto triangle objects.
    pub shadows: bool,
}

/// Share of a spot's half-angle over which its edge fades to dark.
pub const SPOT_EDGE: f64 = 0.15;

/// Widest spot half-angle, degrees: its shadow map is a perspective view of twice that.
pub const MAX_SPOT_ANGLE_DEGREES: f64 = 80.0;

/// Narrowest spot half-angle, degrees: half the narrowest field of view a camera takes, so that
/// its shadow map's view can be made (a spot of 10⁻⁵° was refused there, naming only `lighting`).
pub const MIN_SPOT_ANGLE_DEGREES: f64 = camera::MIN_FOV_Y_DEGREES / 2.0;

impl Spot {
    /// A spot at `position` aimed at `target` with half-angle `angle_degrees` in
    /// [[`MIN_SPOT_ANGLE_DEGREES`], [`MAX_SPOT_ANGLE_DEGREES`]] and `intensity` in
    /// [0, [`MAX_RADIANCE`]]. Errors name the field.
    pub fn new(
        position: DVec3,
        target: DVec3,
        angle_degrees: f64,
        intensity: f64,
        shadows: bool,
    ) -> Result<Spot> {
        let position = finite3("position", position)?;
        let direction = crate::math::unit_direction(finite3("target", target)? - position)
            .ok_or_else(|| Error::invalid("target", "must differ from the spot's position"))?;
        let angle = finite("angle", angle_degrees)?;
        if !(MIN_SPOT_ANGLE_DEGREES..=MAX_SPOT_ANGLE_DEGREES).contains(&angle) {
            return Err(Error::invalid(
                "angle",
                format!("{angle}: the cone's half-angle is in degrees, at least {MIN_SPOT_ANGLE_DEGREES} and at most {MAX_SPOT_ANGLE_DEGREES}"),
            ));
        }
        Ok(Spot {
            position,
            direction,
            angle: angle.to_radians(),
            edge_cosines: [
                angle.to_radians().cos(),
                ((1.0 - SPOT_EDGE) * angle.to_radians()).cos(),
            ],
            intensity: radiance("intensity", intensity)?,
            shadows,
        })
    }

    /// Irradiance scale along `from_light` (of length `distance`, above 0) before the cosine
    /// law: the intensity inside the cone, fading to 0 over its outer edge (smoothstep in the
    /// cosine of the angle off the axis, which needs no arc cosine per shaded point), 0 outside.
    /// The cone's edges are tested on the unnormalized cosine, so that only the ramp divides.
    #[must_use]
    pub fn reach(&self, from_light: DVec3, distance: f64) -> f64 {
        let [outer, inner] = self.edge_cosines;
        let along = from_light.dot(self.direction);
        if along >= inner * distance {
            return self.intensity;
        }
        if along <= outer * distance {
            return 0.0;
        }
        let x = ((along / distance - outer) / (inner - outer)).clamp(0.0, 1.0);
        self.intensity * x * x * (3.0 - 2.0 * x)
    }

    /// Where the straight path from world point `p0` to `p1` crosses the cone's outer and inner
    /// edges, as shares u ∈ (0, 1) of the way, each handed to `crossing`: between them the reach
    /// ramps, a change a few points of a quadrature rule over the whole path would miss. On an
    /// edge of cosine c, (p(u) − S)·a = c |p(u) − S|; squared, (a₀ + a₁u)² = c² |d₀ + u e|²,
    /// quadratic in u, and only its roots on the light's side (a₀ + a₁u > 0) are the cone's.
    pub fn cone_crossings(&self, [p0, p1]: [DVec3; 2], mut crossing: impl FnMut(f64)) {
        let (d0, e) = (p0 - self.position, p1 - p0);
        let (a0, a1) = (d0.dot(self.direction), e.dot(self.direction));
        let (d1, a_end) = (p1 - self.position, a0 + a1);
        for c in self.edge_cosines {
            let c2 = c * c;
            // A cone narrower than a half-space is convex: a path with both ends inside it lies
            // inside all along (most paths, under the inner edge).
            let inside =
                |along: f64, d: DVec3| along > 0.0 && along * along >= c2 * d.length_squared();
            if inside(a0, d0) && inside(a_end, d1) {
                continue;
            }
            let (roots, n) = crate::math::quadratic_roots(
                a1 * a1 - c2 * e.length_squared(),
                2.0 * (a0 * a1 - c2 * d0.dot(e)),
                a0 * a0 - c2 * d0.length_squared(),
            );
            for &u in &roots[..n] {
                if u > 0.0 && u < 1.0 && a0 + a1 * u > 0.0 {
                    crossing(u);
                }
            }
        }
    }
}

/// Texels per side of a shadow map unless the scene says otherwise.
pub const DEFAULT_SHADOW_MAP: u32 = 1024;

/// Largest shadow map side, texels.
pub const MAX_SHADOW_MAP: u32 = 4096;

/// Smallest shadow map side, texels: one tile.
pub const MIN_SHADOW_MAP: u32 = 16;

/// Lambertian lighting; with no lights the scene is drawn unlit (colours as given).
#[derive(Clone, Debug, PartialEq)]
pub struct Lighting {
    /// Irradiance added everywhere.
    pub ambient: f64,
    /// Directional lights.
    pub lights: Vec<Light>,
    /// Spot lights.
    pub spots: Vec<Spot>,
    /// Texels per side of each shadow map.
    pub shadow_map: u32,
}

impl Default for Lighting {
    fn default() -> Self {
        Lighting {
            ambient: 0.0,
            lights: Vec::new(),
            spots: Vec::new(),
            shadow_map: DEFAULT_SHADOW_MAP,
        }
    }
}

impl Lighting {
    /// Ambient irradiance `ambient` in [0, [`MAX_RADIANCE`]] plus `lights` (made by
    /// [`Light::new`]). An error names `ambient`.
    pub fn new(ambient: f64, lights: Vec<Light>) -> Result<Lighting> {
        Ok(Lighting {
            ambient: radiance("ambient", ambient)?,
            lights,
            ..Lighting::default()
        })
    }

    /// The same lighting with `spots` added.
    #[must_use]
    pub fn with_spots(mut self, spots: Vec<Spot>) -> Lighting {
        self.spots = spots;
        self
    }

    /// The same lighting with shadow maps of `texels` per side, [`MIN_SHADOW_MAP`] to
    /// [`MAX_SHADOW_MAP`]; an error names `shadow_map`.
    pub fn with_shadow_map(mut self, texels: u32) -> Result<Lighting> {
        if !(MIN_SHADOW_MAP..=MAX_SHADOW_MAP).contains(&texels) {
            return Err(Error::invalid(
                "shadow_map",
                format!(
                    "{texels}: texels per side of a shadow map, between {MIN_SHADOW_MAP} and {MAX_SHADOW_MAP}"
                ),
            ));
        }
        self.shadow_map = texels;
        Ok(self)
    }

    /// Whether any shading happens at all: a scene without a `[lighting]` table (no lights, no
    /// ambient term) is drawn with its colours as given.
    #[must_use]
    pub fn is_lit(&self) -> bool {
        !self.lights.is_empty() || !self.spots.is_empty() || self.ambient != 0.0
    }

    /// Whether any light casts shadows.
    #[must_use]
    pub fn any_shadows(&self) -> bool {
        self.lights.iter().any(|l| l.shadows) || self.spots.iter().any(|s| s.shadows)
    }

    /// The colour of a surface of `albedo` with world-space unit normal `normal` at world point
    /// `position`, unshadowed.
    #[must_use]
    pub fn shade(&self, albedo: [f32; 3], normal: DVec3, position: DVec3) -> [f32; 3] {
        if !self.is_lit() {
            return albedo;
        }
        let irradiance = self.ambient + self.direct(normal, position);
        albedo.map(|c| c * irradiance as f32)
    }

    /// Irradiance from the lights alone on a surface with world-space unit normal `normal` at
    /// `position`: Σ intensity · max(0, N·L), each spot within its cone.
    #[must_use]
    pub fn direct(&self, normal: DVec3, position: DVec3) -> f64 {
        self.sources()
            .map(|source| source.irradiance(normal, position))
            .sum()
    }

    /// Every light: the directional ones, then the spots.
    pub fn sources(&self) -> impl Iterator<Item = LightSource<'_>> + '_ {
        (self.lights.iter().map(LightSource::Directional))
            .chain(self.spots.iter().map(LightSource::Spot))
    }
}

/// One light of either kind, as shading and shadows ask of it.
#[derive(Clone, Copy, Debug)]
pub enum LightSource<'a> {
    /// A directional light.
    Directional(&'a Light),
    /// A spot light.
    Spot(&'a Spot),
}

impl LightSource<'_> {
    /// Whether it casts shadows.
    #[must_use]
    pub fn shadows(&self) -> bool {
        match self {
            LightSource::Directional(l) => l.shadows,
            LightSource::Spot(s) => s.shadows,
        }
    }

    /// N·(L − p) towards a spot at L, N·L towards a directional light: the sign of the cosine
    /// at world point `p` on a surface with `normal` (of any length), without normalizing. Linear
    /// in `p` and in the normal, so exactly quadratic in time where both move linearly (Palmér
    /// eq. 2.5).
    #[must_use]
    pub fn facing(&self, normal: DVec3, p: DVec3) -> f64 {
        match self {
            LightSource::Directional(l) => normal.dot(l.direction),
            LightSource::Spot(s) => normal.dot(s.position - p),
        }
    }

    /// Irradiance at world point `p` on a surface with unit `normal`, unshadowed: the light's
    /// reach there (a spot's within its cone) times max(0, N·L).
    #[must_use]
    pub fn irradiance(&self, normal: DVec3, p: DVec3) -> f64 {
        match self {
            LightSource::Directional(l) => l.intensity * normal.dot(l.direction).max(0.0),
            LightSource::Spot(s) => {
                // N·L unnormalized first: a surface facing away (or a point at the light
                // itself) takes no light and no square root.
                let to_light = s.position - p;
                let facing = normal.dot(to_light);
                if !(facing > 0.0) {
                    return 0.0;
                }
                let distance = to_light.length();
                s.reach(-to_light, distance) * facing / distance
            }
        }
    }
}

/// What an object is made of. Each primitive is drawn natively by the methods that can and
/// sampled into surfels for the others (docs/architecture.md, "Module tree").
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    /// Oriented Gaussian disks in object space.
    Surfels(Vec<Surfel>),
    /// A triangle mesh: drawn as triangles by `static`, `reference` and `analytic`, and as the
    /// surfels sampled from it by `blur`, `hint` and `kernel3d`.
    Triangles {
        /// The triangles.
        mesh: TriangleMesh,
        /// Surfels sampled from the same surface.
        surfels: Vec<Surfel>,
    },
}

/// One object: its geometry in object space and its motion.
#[derive(Clone, Debug)]
pub struct Object {
    /// Name (for messages and `--explain`).
    pub name: String,
    /// What it is made of, in object space.
    pub geometry: Geometry,
    /// Keyframed pose over the frame.
    pub motion: Motion,
}

impl Object {
    /// An object called `name` made of `surfels` (from a [`crate::surfels`] source), moving as
    /// `motion` says.
    #[must_use]
    pub fn new(name: impl Into<String>, surfels: Vec<Surfel>, motion: Motion) -> Object {
        Object {
            name: name.into(),
            geometry: Geometry::Surfels(surfels),
            motion,
        }
    }

    /// An object called `name` drawn as the triangles of `mesh` where the method can, and as
    /// `surfels` (sampled from the same surface) where it cannot, moving as `motion` says.
    #[must_use]
    pub fn triangles(
        name: impl Into<String>,
        mesh: TriangleMesh,
        surfels: Vec<Surfel>,
        motion: Motion,
    ) -> Object {
        Object {
            name: name.into(),
            geometry: Geometry::Triangles { mesh, surfels },
            motion,
        }
    }

    /// The surfels the splat renderers draw.
    #[must_use]
    pub fn surfels(&self) -> &[Surfel] {
        match &self.geometry {
            Geometry::Surfels(surfels) | Geometry::Triangles { surfels, .. } => surfels,
        }
    }

    /// The triangles, for an object made of them.
    #[must_use]
    pub fn mesh(&self) -> Option<&TriangleMesh> {
        match &self.geometry {
            Geometry::Surfels(_) => None,
            Geometry::Triangles { mesh, .. } => Some(mesh),
        }
    }
}

/// A validated scene, ready to plan and render.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file it came from, if any (for messages and the study's cache).
    pub source: Option<PathBuf>,
    /// The camera and image size.
    pub camera: Camera,
    /// Linear RGB.
    pub background: [f32; 3],
    /// When the shutter is open and how it weights time.
    pub shutter: Shutter,
    /// Lights (none: unlit).
    pub lighting: Lighting,
    /// The objects, in order.
    pub objects: Vec<Object>,
    /// The style file `hint` uses unless told otherwise, resolved against the scene's folder.
    pub style: Option<PathBuf>,
    /// How much detail a moving triangle mesh keeps for its screen speed
    /// ([`crate::simplify::speed`]).
    pub mesh_detail: DetailRule,
}

impl Scene {
    /// A scene seen by `camera`: white background, the default shutter (box, open the whole
    /// frame), unlit, no objects yet.
    #[must_use]
    pub fn new(camera: Camera) -> Scene {
        Scene {
            source: None,
            camera,
            background: [1.0; 3],
            shutter: Shutter::default(),
            lighting: Lighting::default(),
            objects: Vec::new(),
            style: None,
            mesh_detail: DetailRule::default(),
        }
    }

    /// The same scene with moving meshes simplified by `rule`; an error names `sigma_speed` or
    /// `sigma_base` when it is negative or not finite, `max_perimeter` when it is not positive.
    pub fn with_mesh_detail(mut self, rule: DetailRule) -> Result<Scene> {
        for (field, v) in [
            ("sigma_speed", rule.sigma_speed),
            ("sigma_base", rule.sigma_base),
        ] {
            if !(finite(field, v)? >= 0.0) {
                return Err(Error::invalid(field, format!("{v}: must not be negative")));
            }
        }
        positive("max_perimeter", rule.max_perimeter_px)?;
        self.mesh_detail = rule;
        Ok(self)
    }

    /// The same scene on a background of linear RGB `colour` (each component in
    /// [0, [`MAX_RADIANCE`]]); an error names `background[i]`.
    pub fn with_background(mut self, colour: [f64; 3]) -> Result<Scene> {
        self.background = rgb("background", colour)?;
        Ok(self)
    }

    /// The same scene with `shutter` (made by [`Shutter::new`]).
    #[must_use]
    pub fn with_shutter(mut self, shutter: Shutter) -> Scene {
        self.shutter = shutter;
        self
    }

    /// The same scene lit by `lighting` (made by [`Lighting::new`]).
    #[must_use]
    pub fn with_lighting(mut self, lighting: Lighting) -> Scene {
        self.lighting = lighting;
        self
    }

    /// The same scene with `object` added.
    #[must_use]
    pub fn with_object(mut self, object: Object) -> Scene {
        self.objects.push(object);
        self
    }

    /// Total number of surfels.
    #[must_use]
    pub fn surfel_count(&self) -> usize {
        self.objects.iter().map(|o| o.surfels().len()).sum()
    }
}

/// A finite number, or an error naming `field`.
pub(crate) fn finite(field: &str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::invalid(field, format!("{v} is not a finite number")))
    }
}

/// A finite vector, or an error naming the component `field[i]`.
pub(crate) fn finite3(field: &str, v: DVec3) -> Result<DVec3> {
    for (i, c) in v.to_array().iter().enumerate() {
        finite(&format!("{field}[{i}]"), *c)?;
    }
    Ok(v)
}

/// A finite number greater than zero, or an error naming `field`.
pub(crate) fn positive(field: &str, v: f64) -> Result<f64> {
    if finite(field, v)? > 0.0 {
        Ok(v)
    } else {
        Err(Error::invalid(
            field,
            format!("must be greater than zero, not {v}"),
        ))
    }
}

/// A value in [0, [`MAX_RADIANCE`]] (as f64), or an error naming `field` that shows `v` as
/// given.
fn radiance<T: Copy + Into<f64> + std::fmt::Display>(field: &str, v: T) -> Result<f64> {
    let x: f64 = v.into();
    if !x.is_finite() {
        Err(Error::invalid(field, format!("{v} is not a finite number")))
    } else if (0.0..=MAX_RADIANCE).contains(&x) {
        Ok(x)
    } else {
        Err(Error::invalid(
            field,
            format!("{v}: must be between 0 and {MAX_RADIANCE} (linear)"),
        ))
    }
}

/// A linear RGB colour, each component in [0, [`MAX_RADIANCE`]], or an error naming the
/// component `field[i]`.
pub(crate) fn rgb<T: Copy + Into<f64> + std::fmt::Display>(
    field: &str,
    v: [T; 3],
) -> Result<[f32; 3]> {
    let mut colour = [0.0f32; 3];
    for (i, c) in v.iter().enumerate() {
        colour[i] = radiance(&format!("{field}[{i}]"), *c)? as f32;
    }
    Ok(colour)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spot_reaches_fully_within_its_inner_cone_and_fades_to_nothing_over_its_edge() {
        let spot = Spot::new(DVec3::ZERO, -DVec3::Z, 30.0, 0.8, false).unwrap();
        // A point 2.5 from the spot, `degrees` off the axis.
        let off_axis = |degrees: f64| {
            let a = degrees.to_radians();
            DVec3::new(a.sin(), 0.0, -a.cos()) * 2.5
        };
        let inner = (1.0 - SPOT_EDGE) * 30.0;
        for degrees in [0.0, 10.0, inner - 1e-9] {
            assert_eq!(spot.reach(off_axis(degrees), 2.5), 0.8, "{degrees}°");
        }
        for degrees in [30.0 + 1e-9, 45.0, 120.0] {
            assert_eq!(spot.reach(off_axis(degrees), 2.5), 0.0, "{degrees}°");
        }
        // Across the edge, the smoothstep of the cosine: strictly falling, 0.4 half-way in
        // cosine.
        let ramp: Vec<f64> = (1..10)
            .map(|k| spot.reach(off_axis(inner + (30.0 - inner) * f64::from(k) / 10.0), 2.5))
            .collect();
        assert!(
            ramp.windows(2)
                .all(|p| p[0] > p[1] && p[1] > 0.0 && p[0] < 0.8),
            "{ramp:?}"
        );
        let [outer_cos, inner_cos] = spot.edge_cosines;
        let middle = (0.5 * (outer_cos + inner_cos)).acos();
        let half = spot.reach(DVec3::new(middle.sin(), 0.0, -middle.cos()), 1.0);
        assert!((half - 0.4).abs() < 1e-12, "{half}");
    }

    #[test]
    fn lighting_shades_by_the_cosine_law() {
        let lighting = Lighting::new(0.1, vec![Light::new(DVec3::Z, 0.8).unwrap()]).unwrap();
        let lit = lighting.shade([1.0, 0.5, 0.0], DVec3::new(0.0, 0.6, 0.8), DVec3::ZERO);
        assert!((lit[0] - (0.1 + 0.8 * 0.8)).abs() < 1e-6 && (lit[1] - 0.5 * 0.74).abs() < 1e-6);
        assert_eq!(
            lighting.shade([1.0; 3], -DVec3::Z, DVec3::ZERO),
            [0.1; 3].map(|c: f64| c as f32)
        );
    }

    #[test]
    fn constructors_name_what_is_wrong() {
        let error = |r: Result<Lighting>| r.unwrap_err().to_string();
        assert_eq!(
            error(Lighting::new(-1.0, Vec::new())),
            "ambient: -1: must be between 0 and 10000 (linear)"
        );
        let message = Light::new(DVec3::ZERO, 1.0).unwrap_err().to_string();
        assert!(message.starts_with("direction: "), "{message}");
        // A spot narrower than its shadow map's camera can see is refused by its angle.
        let spot = |angle| Spot::new(DVec3::Y * 3.0, DVec3::ZERO, angle, 1.0, true);
        let message = spot(1e-5).unwrap_err().to_string();
        assert!(
            message.starts_with("angle: ") && message.contains("at least 0.0005"),
            "{message}"
        );
        assert!(spot(MIN_SPOT_ANGLE_DEGREES).is_ok());
        let message = Light::new(DVec3::new(f64::NAN, 0.0, 1.0), 1.0)
            .unwrap_err()
            .to_string();
        assert!(message.starts_with("direction[0]: "), "{message}");
        let camera = Camera::new(DVec3::Z, DVec3::ZERO, DVec3::Y, 40.0, 8, 8).unwrap();
        let message = Scene::new(camera)
            .with_background([0.0, 2e4, 0.0])
            .unwrap_err()
            .to_string();
        assert!(message.starts_with("background[1]: "), "{message}");
    }
}
