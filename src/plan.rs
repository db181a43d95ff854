//! The plan: what a scene needs before anything is rendered for one method, and what was left
//! out. Still objects take the static path (projected once, no motion ellipses); a moving
//! object's shutter interval is cut at its keyframes and then into as few linear sub-segments as
//! keep every probed point's screen path within the method's tolerance of its chord (of uniform
//! motion along it, for exact streaks and triangles) and every surfel sub-segment shorter than
//! [`SEGMENT_LENGTH_PER_TOLERANCE`] tolerances, but exact streaks whose splat keeps its shape
//! along them; a scene with no light runs no shading. A path crossing the near plane is cut into [`MAX_SEGMENTS_PER_INTERVAL`]
//! pieces, so that the renderers drop only the piece around the crossing. Derivation:
//! docs/math.md, "Sub-segment planning".

use crate::cache::Recent;
use crate::error::Error;
use crate::error::Result;
use crate::lod::{self, Cells, Lod, LodOutcome, ObjectLod, MAX_PATH_SAMPLES};
use crate::project::Culled;
use crate::render::triangles::shadow::{shadow_cameras, MAX_SHADOWED_LIGHTS};
use crate::render::{
    render_planned, trail_window, Method, Progress, Render, Subframes, MAX_SUBFRAMES,
    MAX_TRIANGLE_ITEMS,
};
use crate::scene::camera::Camera;
use crate::scene::motion::Motion;
use crate::scene::shutter::{Shutter, ShutterShape};
use crate::scene::{Lighting, Object, Scene, TriangleMesh};
use crate::simplify::speed::{self, DetailRule, ScreenMotion};
use crate::surfels::{Colouring, Mesh, Surfel};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::sync::Arc;

/// A surfel's sub-segment may be at most this many tolerances long on screen. One motion ellipse
/// stands for a whole segment with a single Gaussian; a long one differs from the true streak (a
/// box along the motion convolved with the splat) at its ends, so shorter segments converge to
/// it. An exact streak has no such error, but it carries the splat's shape at the chord's middle
/// over all of it, and its light and colour only linear along it. Where the shape holds (the
/// object does not turn, no spot light shades it by where it is, and no probe's size on screen
/// changes by more than the tolerance) the cap is lifted for streaks: there it cost time without
/// making them more accurate. Docs/math.md, "Sub-segment planning", has the measurements.
pub const SEGMENT_LENGTH_PER_TOLERANCE: f64 = 32.0;

/// [`SEGMENT_LENGTH_PER_TOLERANCE`] under a tent or Gaussian shutter. A motion ellipse there
/// stands for its sub-segment's shutter-weighted path by its mean and variance alone, and a long
/// one spreads the light past the path's ends and flattens its weight's slope (a ball sliding
/// 63 px under a tent shutter, in two 32 px sub-segments, had RMSE 2.5·10⁻² against the
/// reference; docs/history.md, "Shaped shutters in `blur`").
pub const SHAPED_SEGMENT_LENGTH_PER_TOLERANCE: f64 = 8.0;

/// Largest departure of a probe's screen weight from the straight line between a sub-segment's
/// ends, in units of the weight it would have facing the eye there. A footprint's weight (its
/// screen area, A·f²·n·(e − p)/z³ for a surfel at p, z deep, seen from the eye e) is interpolated
/// linearly between the ends, and a surfel turning edge-on is clipped where that line crosses
/// zero. Two motions bend it where the screen path stays straight: turning about an axis across
/// the view (a square turning 150° got one sub-segment, and `blur` drew 64 % of its light; a turn
/// by Δ departs by up to Δ²/8, so 1 % holds turns of about 16°), and moving in depth (area ∝ 1/z²:
/// a square flying to half its distance in one sub-segment drew 12 % too much light; 1 % holds
/// a depth ratio of about 1.13).
pub const MAX_WEIGHT_DEVIATION: f64 = 0.01;

/// Range of the sub-segment tolerance, px. Below it sub-segments only cost time; above it a
/// single motion ellipse may span the image many times over, and its tile lists with it.
pub const TOLERANCE_RANGE_PX: std::ops::RangeInclusive<f64> = 1e-3..=64.0;

/// Most sub-segments per keyframe interval: bounds the work for absurdly fast motion.
pub const MAX_SEGMENTS_PER_INTERVAL: usize = 256;

/// Most surfel sub-segments of the whole scene (one motion ellipse each in `blur` and in a
/// hint's trail, about 120 bytes): a moving object gets at most this share, divided by the
/// scene's moving surfels, of sub-segments in all, whatever its keyframes ask for (a scene of
/// 20,000 keyframes asks for at least as many).
pub const MAX_MOTION_FOOTPRINTS: usize = 1 << 24;

/// Surfels probed per object to measure its screen paths.
const PROBES: usize = 64;

/// Interior time samples per sub-segment when measuring chord deviation.
const DEVIATION_SAMPLES: usize = 8;

/// How one object will be drawn.
#[derive(Clone, Debug, PartialEq)]
pub enum ObjectMotion {
    /// Does not move while the shutter is open: the static path.
    Still,
    /// Moves, but the method draws it only at instants (`static`, each `reference` frame), which
    /// need no sub-segments: none are planned, and its path is measured for `--explain` only.
    Instants {
        /// Longest screen path of a probed point, px.
        path_px: f64,
    },
    /// Moves: linear sub-segments [t0, t1] covering the shutter interval.
    Moving {
        /// Sub-segments [t0, t1] in time order.
        segments: Vec<[f64; 2]>,
        /// Longest screen path of a probed point, px.
        path_px: f64,
        /// Largest distance of a probed path from its sub-segment chord, px.
        deviation_px: f64,
        /// Longest sub-segment chord, px.
        longest_segment_px: f64,
        /// What stopped the subdivision before the tolerance held, if anything.
        capped: Option<SegmentCap>,
        /// Whether its sub-segments are exact streaks free of [`SEGMENT_LENGTH_PER_TOLERANCE`]
        /// in every keyframe interval, since nothing they hold changes along them.
        uncapped_streaks: bool,
    },
}

/// Why an object's sub-segments stopped short of its tolerance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SegmentCap {
    /// A keyframe interval reached [`MAX_SEGMENTS_PER_INTERVAL`].
    PerInterval,
    /// The object reached its share of [`MAX_MOTION_FOOTPRINTS`]: this many equal sub-segments
    /// over the exposure, whatever its keyframes.
    Footprints(usize),
    /// `kernel3d` reached the [`MAX_SUBFRAMES`] sub-frames it draws, fewer than the object's
    /// share of the footprints: that many equal sub-segments over the exposure.
    SubFrames,
}

/// The plan for one object.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectPlan {
    /// The object's name.
    pub name: String,
    /// Its surfel count.
    pub surfels: usize,
    /// Its face count, if it is a triangle mesh.
    pub faces: usize,
    /// How it will be drawn.
    pub motion: ObjectMotion,
    /// The surfels the method draws where detail cannot show (see [`crate::lod`]).
    pub lod: ObjectLod,
    /// A moving mesh's level of detail from its screen speed (see [`crate::simplify::speed`]).
    pub mesh_lod: MeshLod,
}

/// What the plan did to an object's triangle mesh.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshLod {
    /// Not a triangle mesh.
    NoMesh,
    /// Drawn at full detail, for the reason given.
    Full(String),
    /// Simplified as far as its screen speed allows (Zhang et al. 2014, eq. 8).
    Simplified {
        /// The simplified triangles and how they were made.
        mesh: speed::Shared,
        /// Slowest and fastest vertex on screen, px per shutter.
        speed_px: [f64; 2],
        /// How many surfels were resampled from the simplified mesh for the splat methods, if
        /// they were (the object's plan draws them).
        resampled: Option<usize>,
    },
}

impl MeshLod {
    /// One line for `--explain`, or `None` for an object without a mesh.
    fn explain(&self, faces_in: usize, rule: &DetailRule) -> Option<String> {
        Some(match self {
            MeshLod::NoMesh => return None,
            MeshLod::Full(why) => format!("mesh: {faces_in} faces kept: {why}"),
            MeshLod::Simplified {
                mesh,
                speed_px,
                resampled,
            } => {
                let (triangles, stats) = &**mesh;
                format!(
                    "mesh: {faces_in} faces → {} (screen speed {:.0}–{:.0} px per shutter; projected perimeters up to min({} v + {}, {}) px; refused attempts to collapse: {} at the detail limit, {} folding, {} topology, {} valence){}",
                    triangles.triangles.len(),
                    speed_px[0],
                    speed_px[1],
                    rule.sigma_speed,
                    rule.sigma_base,
                    rule.max_perimeter_px,
                    stats.limit_refusals,
                    stats.fold_refusals,
                    stats.topology_refusals,
                    stats.valence_refusals,
                    match resampled {
                        Some(count) => format!("; {count} surfels resampled from it"),
                        None => String::new(),
                    }
                )
            }
        })
    }
}

/// The plan for rendering one scene with one method. It borrows the scene, so it cannot be paired
/// with another scene's objects.
#[derive(Clone, Debug)]
pub struct Plan<'a> {
    scene: &'a Scene,
    method: Method,
    /// One entry per scene object, in scene order.
    pub objects: Vec<ObjectPlan>,
    /// Chord-deviation tolerance of the sub-segments, px.
    pub tolerance_px: f64,
    /// Whether any light shades the surfels.
    pub lit: bool,
    /// The camera of each shadow-casting light's shadow map, in
    /// [`crate::scene::Lighting::sources`] order: made once here, for every frame the method
    /// draws (empty unless triangles are drawn as triangles).
    pub shadow_cameras: Vec<Camera>,
    /// Triangle objects whose shadows a directional light's map is too coarse to show
    /// ([`shadow_cameras`]), one note each.
    shadow_notes: Vec<String>,
    /// What each shadowed directional light's map spans, for `--explain` ([`shadow_cameras`]).
    shadow_framing: Vec<String>,
}

impl<'a> Plan<'a> {
    /// Decide what `scene` needs to be drawn by `method`: curved paths are cut to the method's
    /// tolerance ([`Method::tolerance_px`]).
    ///
    /// # Errors
    /// A setting of `method` out of its range ([`Method::check`]).
    pub fn new(scene: &'a Scene, method: &Method) -> Result<Plan<'a>> {
        Plan::with_lod(scene, method, Lod::Auto)
    }

    /// [`Plan::new`] with the level of detail `lod`.
    ///
    /// # Errors
    /// A setting of `method` out of its range ([`Method::check`]).
    pub fn with_lod(scene: &'a Scene, method: &Method, lod: Lod) -> Result<Plan<'a>> {
        method.check()?;
        let tolerance_px = method.tolerance_px();
        let (open, close) = (scene.shutter.open, scene.shutter.close);
        let moving: Vec<bool> = scene
            .objects
            .iter()
            .map(|o| o.motion.moves_within(open, close))
            .collect();
        let moving_surfels: usize = scene
            .objects
            .iter()
            .zip(&moving)
            .filter(|(_, &moves)| moves)
            .map(|(o, _)| o.surfels().len())
            .sum();
        let length_per_tolerance = match scene.shutter.shape {
            ShutterShape::Box => SEGMENT_LENGTH_PER_TOLERANCE,
            ShutterShape::Tent | ShutterShape::Gaussian => SHAPED_SEGMENT_LENGTH_PER_TOLERANCE,
        };
        let share = MAX_MOTION_FOOTPRINTS
            .checked_div(moving_surfels)
            .unwrap_or(MAX_MOTION_FOOTPRINTS)
            .max(1);
        // `kernel3d` draws at most MAX_SUBFRAMES sub-frames, equal ones past that: more
        // sub-segments would only be measured (671,088 of a zig-zag took 20 s).
        let most_segments = match method {
            Method::Kernel3d { .. } if MAX_SUBFRAMES < share => {
                (MAX_SUBFRAMES, SegmentCap::SubFrames)
            }
            _ => (share, SegmentCap::Footprints(share)),
        };
        let objects = scene
            .objects
            .iter()
            .zip(&moving)
            .map(|(object, &moves)| {
                let motion = match (moves, draws_instants(method)) {
                    (false, _) => ObjectMotion::Still,
                    (true, true) => ObjectMotion::Instants {
                        path_px: path_through_keyframes_px(
                            &scene.camera,
                            object,
                            &probes_of(object),
                            &object.motion.keyframe_ends(open, close),
                        ),
                    },
                    (true, false) => {
                        let mut motion = plan_motion(
                            &scene.camera,
                            object,
                            [open, close],
                            (tolerance_px, length_per_tolerance),
                            most_segments,
                            Drawn::by(method, &scene.shutter, &scene.lighting, object),
                        );
                        // Equal sub-frames are drawn, not the sub-segments, which only sample
                        // the path for the level of detail: no tolerance was asked of them.
                        if let (Some(_), ObjectMotion::Moving { capped, .. }) =
                            (equal_subframes(method), &mut motion)
                        {
                            *capped = None;
                        }
                        motion
                    }
                };
                let (mesh_lod, resampled) = mesh_lod(scene, object, moves, method, lod)?;
                let surfels = resampled.as_deref().map_or(object.surfels(), Vec::as_slice);
                let kernels = matches!(method, Method::Kernel3d { .. });
                let mut lod = match lod.blurred_cells(kernels) {
                    _ if draws_triangles(method, object) => ObjectLod::OFF,
                    None => ObjectLod::OFF,
                    Some(cells) => object_lod(scene, object, surfels, &motion, method, cells),
                };
                if lod.merged.is_none() {
                    lod.merged = resampled;
                }
                Ok(ObjectPlan {
                    name: object.name.clone(),
                    surfels: object.surfels().len(),
                    faces: object.mesh().map_or(0, |m| m.triangles.len()),
                    motion,
                    lod,
                    mesh_lod,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let mut plan = Plan {
            scene,
            method: method.clone(),
            objects,
            tolerance_px,
            lit: scene.lighting.is_lit(),
            shadow_cameras: Vec::new(),
            shadow_notes: Vec::new(),
            shadow_framing: Vec::new(),
        };
        let items = plan.triangle_items();
        if items > MAX_TRIANGLE_ITEMS {
            return Err(Error::invalid(
                "triangles",
                format!(
                    "{items} triangle items (triangles × sub-segments) are more than the {MAX_TRIANGLE_ITEMS} one render may hold: simplify the mesh, or raise --tolerance for fewer sub-segments"
                ),
            ));
        }
        if plan.any_triangles() {
            let shadowed = scene.lighting.sources().filter(|s| s.shadows()).count();
            if shadowed > MAX_SHADOWED_LIGHTS {
                return Err(Error::invalid(
                    "lighting",
                    format!(
                        "{shadowed} lights cast shadows, more than the {MAX_SHADOWED_LIGHTS} a scene may have: set shadows = false on the others"
                    ),
                ));
            }
            (plan.shadow_cameras, plan.shadow_notes, plan.shadow_framing) =
                shadow_cameras(scene, &plan)?;
        }
        Ok(plan)
    }

    /// Whether object `index` is drawn as its triangles (a triangle object, and a method that
    /// draws triangles: `static`, `reference`, `analytic`), not as its surfels.
    #[must_use]
    pub fn draws_triangles(&self, index: usize) -> bool {
        draws_triangles(&self.method, &self.scene.objects[index])
    }

    /// Whether any object is drawn as triangles.
    #[must_use]
    pub fn any_triangles(&self) -> bool {
        (0..self.objects.len()).any(|i| self.draws_triangles(i))
    }

    /// What `--explain` says of object `index`'s mesh: its level of detail, and where it is
    /// drawn as triangles in a scene with shadows and cannot shadow itself
    /// ([`TriangleMesh::shadows_itself`]), what its shadow lookups leave out.
    fn mesh_lines(&self, index: usize) -> impl Iterator<Item = String> {
        let o = &self.objects[index];
        let shadows = self.mesh_of(index).is_some_and(|mesh| {
            self.draws_triangles(index) && self.scene.lighting.any_shadows() && !mesh.shadows_itself
        });
        o.mesh_lod
            .explain(o.faces, &self.scene.mesh_detail)
            .into_iter()
            .chain(shadows.then(|| {
                "shadows: planar, or closed and convex, so it cannot shadow itself: its own triangles are left out of its shadow lookups".to_string()
            }))
    }

    /// Whether the level of detail simplifies any object's mesh, so that full detail
    /// ([`Lod::Off`]) would draw something else.
    #[must_use]
    pub fn simplifies_a_mesh(&self) -> bool {
        self.scene
            .objects
            .iter()
            .enumerate()
            .any(
                |(index, object)| match (self.mesh_of(index), object.mesh()) {
                    (Some(drawn), Some(own)) => drawn.triangles.len() < own.triangles.len(),
                    _ => false,
                },
            )
    }

    /// Triangle items one image draws: each triangle once per sub-segment (`analytic`) or once
    /// (an instant).
    fn triangle_items(&self) -> usize {
        self.scene
            .objects
            .iter()
            .zip(&self.objects)
            .enumerate()
            .filter(|(i, _)| self.draws_triangles(*i))
            .map(|(_, (object, plan))| {
                let triangles = self.mesh(object, plan).map_or(0, |m| m.triangles.len());
                match (&self.method, &plan.motion) {
                    (Method::Analytic { .. }, ObjectMotion::Moving { segments, .. }) => {
                        triangles * segments.len()
                    }
                    _ => triangles,
                }
            })
            .sum()
    }

    /// The scene this plan was made for.
    #[must_use]
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    /// The method this plan was made for.
    #[must_use]
    pub fn method(&self) -> &Method {
        &self.method
    }

    /// Render the scene with the method. `progress`, when given, is called once per frame.
    #[must_use]
    pub fn render(&self, progress: Option<Progress>) -> Render {
        render_planned(self, progress)
    }

    /// The surfels of object `index` as the method draws them where detail cannot show: merged
    /// by the level of detail, or the object's own.
    #[must_use]
    pub fn surfels(&self, index: usize) -> &[Surfel] {
        match &self.objects[index].lod.merged {
            Some(merged) => merged,
            None => self.scene.objects[index].surfels(),
        }
    }

    /// The triangles of object `index` as the method draws them: simplified by the mesh level of
    /// detail, or the object's own (`None` for an object without a mesh).
    #[must_use]
    pub fn mesh_of(&self, index: usize) -> Option<&TriangleMesh> {
        self.mesh(&self.scene.objects[index], &self.objects[index])
    }

    fn mesh<'p>(&'p self, object: &'a Object, plan: &'p ObjectPlan) -> Option<&'p TriangleMesh> {
        match &plan.mesh_lod {
            MeshLod::Simplified { mesh, .. } => Some(&mesh.0),
            _ => object.mesh(),
        }
    }

    /// Every object the method draws as surfels, in scene order, with its plan and its surfels
    /// ([`Plan::surfels`]); objects drawn as triangles ([`Plan::draws_triangles`]) are not among
    /// them.
    pub fn drawn(&self) -> impl Iterator<Item = (&'a Object, &ObjectPlan, &[Surfel])> + '_ {
        let scene: &'a Scene = self.scene;
        scene
            .objects
            .iter()
            .zip(&self.objects)
            .enumerate()
            .filter(|(index, _)| !self.draws_triangles(*index))
            .map(|(index, (object, plan))| (object, plan, self.surfels(index)))
    }

    /// Whether anything moves.
    #[must_use]
    pub fn any_moving(&self) -> bool {
        self.objects.iter().any(|o| o.motion != ObjectMotion::Still)
    }

    /// The longest screen path of a moving object's probed points, px (0 when nothing moves).
    #[must_use]
    pub fn longest_path_px(&self) -> f64 {
        self.objects
            .iter()
            .filter_map(|o| match o.motion {
                ObjectMotion::Moving { path_px, .. } | ObjectMotion::Instants { path_px } => {
                    Some(path_px)
                }
                ObjectMotion::Still => None,
            })
            .fold(0.0, f64::max)
    }

    /// Where the plan departs from what the scene asked, one short line each: objects whose
    /// sub-segments were capped, so their paths are followed less closely than the tolerance
    /// asks (in chord deviation, length or weight along them).
    /// [`Plan::explain`] says more.
    #[must_use]
    pub fn departures(&self) -> Vec<String> {
        self.objects
            .iter()
            .filter_map(|o| match &o.motion {
                ObjectMotion::Moving {
                    capped: Some(cap), ..
                } => {
                    let cap = match cap {
                        SegmentCap::PerInterval => format!(
                            "{MAX_SEGMENTS_PER_INTERVAL} sub-segments per keyframe interval, the most drawn"
                        ),
                        SegmentCap::Footprints(n) => format!(
                            "{n} equal sub-segments, its share of the scene's {MAX_MOTION_FOOTPRINTS} motion footprints"
                        ),
                        SegmentCap::SubFrames => format!(
                            "{MAX_SUBFRAMES} equal sub-segments, the most sub-frames kernel3d draws"
                        ),
                    };
                    Some(format!(
                        "{:?}: its path is drawn in {cap}, fewer than the tolerance of {} px asks for",
                        o.name, self.tolerance_px
                    ))
                }
                _ => None,
            })
            .chain(self.shadow_notes.iter().cloned())
            .collect()
    }

    /// Where `render`, drawn from this plan, departs from what the scene asked: the plan's
    /// departures, then the render's ([`crate::render::Stats::departures`]).
    #[must_use]
    pub fn departures_of(&self, render: &Render) -> Vec<String> {
        let mut out = self.departures();
        out.extend(render.stats.departures());
        out
    }

    /// Human-readable account of the plan and, when given, of what rendering culled.
    #[must_use]
    pub fn explain(&self, culled: Option<&Culled>) -> String {
        let mut out = String::new();
        let mut line = |s: String| {
            out.push_str(&s);
            out.push('\n');
        };
        line(format!("plan (tolerance {} px):", self.tolerance_px));
        for (index, o) in self.objects.iter().enumerate() {
            let header = match &o.motion {
                ObjectMotion::Still => "still while the shutter is open: static path, no motion ellipses, projected once for all reference frames".to_string(),
                ObjectMotion::Instants { path_px } => format!(
                    "moving: screen path up to {path_px:.1} px, {}: no sub-segments planned (only methods that draw the whole exposure need them)",
                    match self.method {
                        Method::Static { .. } => "drawn at one instant",
                        _ => "drawn at each of the reference's frames",
                    }
                ),
                ObjectMotion::Moving {
                    segments,
                    path_px,
                    deviation_px,
                    longest_segment_px,
                    ..
                } => format!(
                    "moving: screen path up to {path_px:.1} px, {} linear sub-segment{} (chord deviation ≤ {deviation_px:.2} px, longest {longest_segment_px:.1} px)",
                    segments.len(),
                    if segments.len() == 1 { "" } else { "s" },
                ),
            };
            line(format!("  {:?}: {} surfels, {header}", o.name, o.surfels));
            line(format!("    {}", o.lod.outcome.explain()));
            for mesh in self.mesh_lines(index) {
                line(format!("    {mesh}"));
            }
            let ObjectMotion::Moving {
                capped,
                uncapped_streaks,
                ..
            } = &o.motion
            else {
                continue;
            };
            if let Some(n) = equal_subframes(&self.method) {
                line(format!(
                    "    {n} equal sub-frames drawn; the sub-segments only sample the path for the level of detail"
                ));
            }
            if *uncapped_streaks {
                line(format!(
                    "    streaks as long as the path allows (otherwise at most {SEGMENT_LENGTH_PER_TOLERANCE} tolerances): it does not turn, no spot light shades it, and its surfels' size on screen changes by less than the tolerance"
                ));
            }
            match capped {
                Some(SegmentCap::PerInterval) => line(format!(
                    "    capped at {MAX_SEGMENTS_PER_INTERVAL} sub-segments per keyframe interval: the tolerance does not hold"
                )),
                Some(SegmentCap::Footprints(n)) => line(format!(
                    "    capped at {n} equal sub-segments over the exposure, the object's share of {MAX_MOTION_FOOTPRINTS} motion footprints for the scene: the tolerance does not hold"
                )),
                Some(SegmentCap::SubFrames) => line(format!(
                    "    capped at {MAX_SUBFRAMES} equal sub-segments over the exposure, the most sub-frames kernel3d draws: the tolerance does not hold"
                )),
                None => {}
            }
        }
        line(if self.lit {
            "  lighting: ambient plus Lambertian shading of every surfel at every instant it is seen".to_string()
        } else {
            "  lighting: none, so no shading pass (colours drawn as given)".to_string()
        });
        for note in self.shadow_framing.iter().chain(&self.shadow_notes) {
            line(format!("  shadows: {note}"));
        }
        if let Some(c) = culled {
            line("left out while rendering (per surfel and instant or sub-segment):".to_string());
            line(format!("  back-facing: {}", c.back_facing));
            line(format!("  off-screen: {}", c.off_screen));
            line(format!("  behind the near plane: {}", c.behind_near));
            line(format!(
                "  no weight or beyond f32 (edge-on, no shutter time, or numbers too large to \
                 draw): {}",
                c.degenerate
            ));
        }
        out
    }
}

/// How a moving object's sub-segments are drawn, which decides what they must hold to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Drawn {
    /// As triangles: each corner moves uniformly along its camera-space chord.
    Triangles,
    /// As exact streaks of surfels ([`crate::render::draws_exact_streaks`]): each splat slides
    /// uniformly along its screen chord; `spot_lit` when a spot light shades it, by where it is.
    Streaks { spot_lit: bool },
    /// As motion ellipses (or sub-frames): one Gaussian per sub-segment about the path's chord.
    Ellipses,
}

impl Drawn {
    fn by(method: &Method, shutter: &Shutter, lighting: &Lighting, object: &Object) -> Drawn {
        if draws_triangles(method, object) {
            Drawn::Triangles
        } else if crate::render::draws_exact_streaks(method, shutter) {
            Drawn::Streaks {
                spot_lit: !lighting.spots.is_empty(),
            }
        } else {
            Drawn::Ellipses
        }
    }

    /// The sub-segments' error in px under this drawing (see [`Fit`]).
    fn error(self, fit: &Fit) -> f64 {
        match self {
            Drawn::Triangles => fit.timed,
            Drawn::Streaks { .. } => fit.uniform,
            Drawn::Ellipses => fit.deviation,
        }
    }
}

/// The count of `kernel3d`'s equal sub-frames, when it draws those rather than the plan's.
fn equal_subframes(method: &Method) -> Option<usize> {
    match method {
        Method::Kernel3d {
            subframes: Subframes::Equal(n),
            ..
        } => Some(*n),
        _ => None,
    }
}

/// Whether `method` draws only instants (`static`, and each `reference` frame), so that a moving
/// object needs no sub-segments.
fn draws_instants(method: &Method) -> bool {
    matches!(method, Method::Static { .. } | Method::Reference { .. })
}

/// Whether `method` draws `object` as triangles.
fn draws_triangles(method: &Method, object: &Object) -> bool {
    object.mesh().is_some()
        && matches!(
            method,
            Method::Static { .. } | Method::Reference { .. } | Method::Analytic { .. }
        )
}

/// The level of detail of one object for `method`: merged in square cells at each instant the
/// method draws (`static`, the reference's frames, and still objects), along the motion for
/// what is drawn blurred (`blur`, `kernel3d`, a hint's trail) in `blurred` cells; a hint's object
/// layer, drawn sharp, keeps full detail.
fn object_lod(
    scene: &Scene,
    object: &Object,
    surfels: &[Surfel],
    motion: &ObjectMotion,
    method: &Method,
    blurred: Cells,
) -> ObjectLod {
    let (open, close) = (scene.shutter.open, scene.shutter.close);
    let middle = scene.shutter.middle();
    let camera = &scene.camera;
    let culled_at = culling_times(method, motion, middle);
    match (method, motion) {
        (Method::Static { time }, _) => lod::merge(
            camera,
            object,
            surfels,
            &[time.unwrap_or(middle)],
            Cells::Square,
            &culled_at,
        ),
        (Method::Hint { .. }, ObjectMotion::Still) => ObjectLod {
            merged: None,
            outcome: LodOutcome::Sharp,
        },
        (Method::Hint { style, .. }, ObjectMotion::Moving { .. }) if style.trail.density < 1.0 => {
            ObjectLod {
                merged: None,
                outcome: LodOutcome::Strokes,
            }
        }
        (Method::Hint { style, .. }, ObjectMotion::Moving { segments, .. }) => {
            // The trail runs over its window in copies, each over its duty share of a slot: the
            // streak whose detail blurs away is one copy's.
            let trail = &style.trail;
            let [start, end] = trail_window(&scene.shutter, style);
            let copy = trail.duty / f64::from(trail.copies.max(1));
            let times = path_times(segments, [start, end]);
            let cells = match blurred {
                Cells::AlongMotion(share) => Cells::AlongMotion(share * copy),
                Cells::Square => Cells::Square,
            };
            lod::merge(camera, object, surfels, &times, cells, &culled_at)
        }
        (_, ObjectMotion::Still) => lod::merge(
            camera,
            object,
            surfels,
            &[middle],
            Cells::Square,
            &culled_at,
        ),
        (Method::Reference { .. }, ObjectMotion::Moving { .. })
        | (_, ObjectMotion::Instants { .. }) => lod::merge(
            camera,
            object,
            surfels,
            &[open, middle, close],
            Cells::Square,
            &culled_at,
        ),
        (_, ObjectMotion::Moving { segments, .. }) => lod::merge(
            camera,
            object,
            surfels,
            &path_times(segments, [open, close]),
            blurred,
            &culled_at,
        ),
    }
}

/// The instants at which `method` decides whether a surfel of an object moving by `motion` faces
/// the camera, when those alone decide it and they are at most [`MAX_PATH_SAMPLES`]: `static` at
/// its instant; `blur` (and `analytic`'s surfel objects) at the middle for a still object, else at
/// its sub-segments' ends, between which a surfel's facing is taken as linear. Empty otherwise
/// (a reference frame, a sub-frame or a trail copy may fall anywhere in the shutter).
fn culling_times(method: &Method, motion: &ObjectMotion, middle: f64) -> Vec<f64> {
    match (method, motion) {
        (Method::Static { time }, _) => vec![time.unwrap_or(middle)],
        (Method::Blur { .. } | Method::Analytic { .. }, ObjectMotion::Still) => vec![middle],
        (Method::Blur { .. } | Method::Analytic { .. }, ObjectMotion::Moving { segments, .. })
            if segments.len() < MAX_PATH_SAMPLES =>
        {
            segment_ends(segments)
        }
        _ => Vec::new(),
    }
}

/// The ends of consecutive `segments`: each one's start, and the last one's end.
pub(crate) fn segment_ends(segments: &[[f64; 2]]) -> Vec<f64> {
    let mut ends: Vec<f64> = segments.iter().map(|s| s[0]).collect();
    ends.extend(segments.last().map(|s| s[1]));
    ends
}

/// Instants at which a screen path through `segments` is measured over `window`: the window's
/// ends and the sub-segment ends within it, thinned to at most [`MAX_PATH_SAMPLES`] (the path is
/// then a little shorter than drawn, which only makes cells shorter).
fn path_times(segments: &[[f64; 2]], [start, end]: [f64; 2]) -> Vec<f64> {
    let mut ends = vec![start];
    ends.extend(
        segments
            .iter()
            .map(|s| s[1])
            .filter(|&t| t > start && t < end),
    );
    ends.push(end);
    let step = ends.len().div_ceil(MAX_PATH_SAMPLES).max(1);
    let mut times: Vec<f64> = ends.iter().step_by(step).copied().collect();
    if times.last() != ends.last() {
        times.extend(ends.last());
    }
    times
}

/// What the plan measures of a probe at one instant.
#[derive(Clone, Copy)]
struct ProbeView {
    /// Screen position, px.
    screen: DVec2,
    /// Screen weight per unit of area and focal length², n·(e − p)/z³ (view space, where the eye
    /// e is the origin).
    weight: f64,
    /// The same facing the eye, |e − p|/z³.
    facing_weight: f64,
    /// Camera-space position.
    view: DVec3,
    /// The surfel's largest standard deviation on screen, px.
    screen_sigma: f64,
}

/// Every probe at time t, each `None` when not in front of the camera. The pose is evaluated
/// once for all of them.
fn probes_at(camera: &Camera, object: &Object, probes: &[usize], t: f64) -> Vec<Option<ProbeView>> {
    let pose = object.motion.pose_at(t);
    // A surfel's area grows with the square of a keyframed scale, as its screen weight does.
    let area_scale = pose.scale * pose.scale;
    let pose = pose.to_affine();
    probes
        .iter()
        .map(|&probe| {
            let surfel = &object.surfels()[probe];
            let p_view = camera
                .view
                .transform_point3(pose.transform_point3(surfel.position));
            let (screen, depth) = camera.project(p_view)?;
            let n_view = camera
                .view
                .transform_vector3(pose.transform_vector3(surfel.normal))
                .normalize_or_zero();
            let depth_cubed = depth.powi(3);
            let sigma = pose
                .transform_vector3(surfel.axis_u)
                .length()
                .max(pose.transform_vector3(surfel.axis_v).length());
            Some(ProbeView {
                view: p_view,
                screen_sigma: sigma * camera.focal_px / depth,
                screen,
                weight: area_scale * n_view.dot(-p_view) / depth_cubed,
                facing_weight: area_scale * p_view.length() / depth_cubed,
            })
        })
        .collect()
}

/// [t0, t1] cut into `k` equal pieces.
fn pieces(t0: f64, t1: f64, k: usize) -> impl Iterator<Item = [f64; 2]> {
    pieces_within(t0, t1, k, 0..k)
}

/// The pieces `range` of [t0, t1] cut into `k` equal pieces.
fn pieces_within(
    t0: f64,
    t1: f64,
    k: usize,
    range: std::ops::Range<usize>,
) -> impl Iterator<Item = [f64; 2]> {
    range.map(move |i| [piece_end(t0, t1, k, i), piece_end(t0, t1, k, i + 1)])
}

/// Where piece `i` of [t0, t1] cut into `k` equal pieces starts (and piece `i − 1` ends).
fn piece_end(t0: f64, t1: f64, k: usize, i: usize) -> f64 {
    t0 + (t1 - t0) * i as f64 / k as f64
}

/// Distance of `p` from the segment a–b.
fn distance_to_segment(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let s = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * s)
}

/// How far `k` equal pieces of a keyframe interval are from what one footprint per piece can
/// stand for, worst over the probes.
#[derive(Clone, Copy, Debug, Default)]
struct Fit {
    /// Largest distance of a screen path from its piece's chord, px.
    deviation: f64,
    /// Longest chord, px.
    longest: f64,
    /// Largest departure of a probe's screen weight from its chord over a piece (see
    /// [`MAX_WEIGHT_DEVIATION`]).
    weight: f64,
    /// Largest distance, px, between where a probe is at a time and where it would be moving
    /// uniformly along its camera-space chord (a triangle corner's path): off the path, or
    /// ahead of or behind itself along it.
    timed: f64,
    /// The same on screen: from where uniform motion along its screen chord puts it (an exact
    /// streak's path).
    uniform: f64,
    /// Largest change of a probe's screen size (its splat's largest standard deviation) over a
    /// piece, px.
    size_change: f64,
}

impl Fit {
    /// The larger of each measure of `self` and `other`.
    fn worst(self, other: Fit) -> Fit {
        Fit {
            deviation: self.deviation.max(other.deviation),
            longest: self.longest.max(other.longest),
            weight: self.weight.max(other.weight),
            timed: self.timed.max(other.timed),
            uniform: self.uniform.max(other.uniform),
            size_change: self.size_change.max(other.size_change),
        }
    }

    /// Whether the pieces hold the tolerance: chord deviation (as [`Drawn::error`] puts it, once
    /// set), length and weight departure within their limits.
    fn holds(&self, tolerance_px: f64, max_length: f64, max_weight: f64) -> bool {
        self.deviation <= tolerance_px && self.longest <= max_length && self.weight <= max_weight
    }
}

/// Worst chord deviation, longest chord and largest weight departure over probes for `k` equal
/// pieces of [t0, t1], sampled at equal shares of each piece and at the `corners` (keyframe
/// times, in order) within it.
fn measure(
    camera: &Camera,
    object: &Object,
    probes: &[usize],
    [t0, t1]: [f64; 2],
    k: usize,
    corners: &[f64],
) -> Fit {
    let run = |first: usize, last: usize| {
        // The corners inside the run's pieces, as each piece takes them: after its start, before
        // its end.
        let [start, end] = [first, last].map(|i| piece_end(t0, t1, k, i));
        let from = corners.partition_point(|&t| t <= start);
        let to = corners.partition_point(|&t| t < end);
        let run = Run {
            first,
            last,
            corners: &corners[from..to.max(from)],
        };
        measure_run(camera, object, probes, [t0, t1], k, run)
    };
    if k < PARALLEL_PIECES {
        return run(0, k);
    }
    // Every measure is a largest value, the same whatever the runs: the same fit as in one run.
    (0..k.div_ceil(PARALLEL_PIECES))
        .into_par_iter()
        .map(|chunk| {
            run(
                chunk * PARALLEL_PIECES,
                ((chunk + 1) * PARALLEL_PIECES).min(k),
            )
        })
        .reduce(Fit::default, Fit::worst)
}

/// Equal pieces measured in parallel runs of this many, past as many: the 671,088 pieces of an
/// object's share of the motion footprints took a third of a 26 s plan on one thread.
const PARALLEL_PIECES: usize = 4096;

/// Pieces `first..last` of `k` equal pieces, and the keyframe corners inside them.
struct Run<'a> {
    first: usize,
    last: usize,
    corners: &'a [f64],
}

/// [`measure`] over one run of its pieces.
fn measure_run(
    camera: &Camera,
    object: &Object,
    probes: &[usize],
    [t0, t1]: [f64; 2],
    k: usize,
    run: Run,
) -> Fit {
    let (mut deviation, mut longest, mut weight, mut timed, mut uniform, mut size_change) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let at = |t: f64| probes_at(camera, object, probes, t);
    let mut pieces = pieces_within(t0, t1, k, run.first..run.last).peekable();
    let Some(&[first_start, _]) = pieces.peek() else {
        return Fit::default();
    };
    // Each piece starts where the one before ends.
    let mut starts = at(first_start);
    // The corners are in time order, as the pieces are: each piece takes the ones inside it
    // from the front, and none is looked at twice.
    let mut corners = run.corners.iter().copied().peekable();
    for [a, b] in pieces {
        let ends = at(b);
        while corners.next_if(|&t| t <= a).is_some() {}
        // Equal shares of the piece, and the keyframe corners within it, where a path bends
        // most and the deviation peaks between the equal samples.
        let shares: Vec<f64> = (1..DEVIATION_SAMPLES)
            .map(|s| s as f64 / DEVIATION_SAMPLES as f64)
            .chain(std::iter::from_fn(|| corners.next_if(|&t| t < b)).map(|t| (t - a) / (b - a)))
            .collect();
        let inside: Vec<Vec<Option<ProbeView>>> = shares
            .iter()
            .map(|&share| at(a + (b - a) * share))
            .collect();
        for (probe, (&pa, &pb)) in starts.iter().zip(&ends).enumerate() {
            let (Some(pa), Some(pb)) = (pa, pb) else {
                // A path that crosses the near plane runs off to infinity on screen: no chord
                // stands for it, and the renderers drop the piece, so it must be cut finer. So
                // must one behind it at both ends that comes in front between them (a point
                // orbiting close to the eye), or the piece it is seen in is dropped whole.
                if pa.is_some() != pb.is_some() || inside.iter().any(|views| views[probe].is_some())
                {
                    (deviation, uniform) = (f64::INFINITY, f64::INFINITY);
                }
                continue;
            };
            longest = longest.max(pa.screen.distance(pb.screen));
            size_change = size_change.max((pb.screen_sigma - pa.screen_sigma).abs());
            for (&share, views) in shares.iter().zip(&inside) {
                let Some(p) = views[probe] else {
                    (deviation, uniform) = (f64::INFINITY, f64::INFINITY);
                    continue;
                };
                deviation = deviation.max(distance_to_segment(p.screen, pa.screen, pb.screen));
                uniform = uniform.max(pa.screen.lerp(pb.screen, share).distance(p.screen));
                // In camera space, to px at the probe's depth: a corner's chord may cross the
                // near plane, where the triangle is clipped in time rather than cut.
                let depth = (-p.view.z).max(camera.near);
                timed = timed
                    .max(pa.view.lerp(pb.view, share).distance(p.view) * camera.focal_px / depth);
                let chord = pa.weight + (pb.weight - pa.weight) * share;
                if p.facing_weight > 0.0 {
                    weight = weight.max((p.weight - chord).abs() / p.facing_weight);
                }
            }
        }
        starts = ends;
    }
    Fit {
        deviation,
        longest,
        weight,
        timed,
        uniform,
        size_change,
    }
}

/// The sub-segments of `object`'s motion over [open, close], within `tolerance_px` unless more
/// than `max_segments` would be needed: then `max_segments` equal ones, marked capped by `cap`
/// unless they hold the tolerance themselves. How they
/// are `drawn` decides the error ([`Drawn::error`]): triangles' corners move uniformly along
/// camera-space chords, so a point's error is its distance from where the chord puts it at the
/// same time, and neither a chord's length nor a splat's weight bends anything; an exact streak
/// slides uniformly along its screen chord, for any length; an ellipse stands for a path within
/// the tolerance of its chord. Surfels' sub-segments are at most `length_per_tolerance` tolerances
/// long ([`SEGMENT_LENGTH_PER_TOLERANCE`], or [`SHAPED_SEGMENT_LENGTH_PER_TOLERANCE`] under a
/// shaped shutter), but streaks whose splat keeps its shape along them.
fn plan_motion(
    camera: &Camera,
    object: &Object,
    [open, close]: [f64; 2],
    (tolerance_px, length_per_tolerance): (f64, f64),
    (max_segments, cap): (usize, SegmentCap),
    drawn: Drawn,
) -> ObjectMotion {
    let probes = probes_of(object);
    let breaks = object.motion.keyframe_ends(open, close);

    let (mut segments, mut deviation_px, mut longest_segment_px, mut capped) =
        (Vec::new(), 0.0f64, 0.0f64, None);
    let mut uncapped_streaks = matches!(drawn, Drawn::Streaks { .. });
    // The longest sub-segment and the largest weight deviation allowed, for a streak free of the
    // length cap or not.
    let limits = |uncapped: bool| match drawn {
        Drawn::Triangles => (f64::INFINITY, f64::INFINITY),
        Drawn::Streaks { .. } if uncapped => (f64::INFINITY, MAX_WEIGHT_DEVIATION),
        Drawn::Streaks { .. } | Drawn::Ellipses => {
            (length_per_tolerance * tolerance_px, MAX_WEIGHT_DEVIATION)
        }
    };
    for pair in breaks.windows(2) {
        if segments.len() > max_segments {
            break;
        }
        let (t0, t1) = (pair[0], pair[1]);
        // A streak holds its splat's shape over its chord (its light and colour change along it
        // only linearly): free of the length cap where the object does not turn, no spot light
        // shades it, and no probe's size on screen changes by more than the tolerance.
        let turns = object.motion.turns_within(t0, t1);
        let uncapped = |fit: &Fit| {
            drawn == Drawn::Streaks { spot_lit: false } && !turns && fit.size_change <= tolerance_px
        };
        let mut k = 1;
        let fit = loop {
            let mut fit = measure(camera, object, &probes, [t0, t1], k, &[]);
            fit.deviation = drawn.error(&fit);
            let (max_length, max_weight) = limits(uncapped(&fit));
            let holds = fit.holds(tolerance_px, max_length, max_weight);
            if holds || k >= MAX_SEGMENTS_PER_INTERVAL {
                if !holds {
                    capped = Some(SegmentCap::PerInterval);
                }
                break fit;
            }
            // Chord deviations (of the screen path and of the weight) of a smooth motion fall as
            // 1/k², chord length as 1/k: jump to the count all three predict, and at least one
            // more.
            let factor = (fit.deviation / tolerance_px)
                .sqrt()
                .max((fit.weight / max_weight).sqrt())
                .max(fit.longest / max_length);
            let next = (k as f64 * factor).ceil();
            k = if next.is_finite() {
                (next as usize).max(k + 1)
            } else {
                MAX_SEGMENTS_PER_INTERVAL
            }
            .min(MAX_SEGMENTS_PER_INTERVAL);
        };
        uncapped_streaks &= uncapped(&fit);
        deviation_px = deviation_px.max(fit.deviation);
        longest_segment_px = longest_segment_px.max(fit.longest);
        segments.extend(pieces(t0, t1, k));
    }
    // Equal pieces over the exposure cut corners at the keyframes they straddle; so would a
    // path summed over equal steps.
    let equal_pieces = segments.len() > max_segments;
    if equal_pieces {
        segments = pieces(open, close, max_segments).collect();
        // Equal pieces straddle keyframes, whose corners are measured too.
        let corners = &breaks[1..breaks.len() - 1];
        let mut fit = measure(
            camera,
            object,
            &probes,
            [open, close],
            max_segments,
            corners,
        );
        fit.deviation = drawn.error(&fit);
        (deviation_px, longest_segment_px) = (fit.deviation, fit.longest);
        // Per interval the counts overshoot what holds (each jump adds at least one), so equal
        // sub-segments within the share may still hold the tolerance: then nothing was given up.
        // Streaks free of the length cap in every interval are free of it here too, unless
        // their size changes along an equal piece by more than the tolerance.
        let free = uncapped_streaks && fit.size_change <= tolerance_px;
        let (max_length, max_weight) = limits(free);
        capped = (!fit.holds(tolerance_px, max_length, max_weight)).then_some(cap);
        uncapped_streaks = false;
    }
    let samples = 4 * segments.len().max(16);
    let path_px = if equal_pieces {
        path_through_keyframes_px(camera, object, &probes, &breaks)
    } else {
        longest_probe_path_px(
            camera,
            object,
            &probes,
            (0..=samples).map(|i| open + (close - open) * i as f64 / samples as f64),
        )
    };
    ObjectMotion::Moving {
        segments,
        path_px,
        deviation_px,
        longest_segment_px,
        capped,
        uncapped_streaks,
    }
}

/// Surfels probed to measure an object's screen paths: [`PROBES`] spread over its surfels.
fn probes_of(object: &Object) -> Vec<usize> {
    let stride = object.surfels().len().div_ceil(PROBES).max(1);
    (0..object.surfels().len()).step_by(stride).collect()
}

/// The longest screen path of a probe, summed over chords between consecutive `times` (in
/// order), px.
fn longest_probe_path_px(
    camera: &Camera,
    object: &Object,
    probes: &[usize],
    mut times: impl Iterator<Item = f64>,
) -> f64 {
    let mut paths = vec![0.0f64; probes.len()];
    let Some(first) = times.next() else {
        return 0.0;
    };
    let mut previous = probes_at(camera, object, probes, first);
    for t in times {
        let next = probes_at(camera, object, probes, t);
        for (path, (a, b)) in paths.iter_mut().zip(previous.iter().zip(&next)) {
            if let (Some(a), Some(b)) = (a, b) {
                *path += a.screen.distance(b.screen);
            }
        }
        previous = next;
    }
    paths.into_iter().fold(0.0, f64::max)
}

/// The longest screen path of `probes` through the keyframe `ends` ([`Motion::keyframe_ends`];
/// for the methods that draw instants, and where equal pieces replace the sub-segments): chords
/// between keyframes, each interval cut in four, and at least 64 in all (at most
/// 4 × [`crate::scene::motion::MAX_KEYFRAMES`] + 4 instants).
fn path_through_keyframes_px(
    camera: &Camera,
    object: &Object,
    probes: &[usize],
    ends: &[f64],
) -> f64 {
    let cuts = (64 / (ends.len() - 1)).max(4);
    let times = ends.windows(2).flat_map(|pair| {
        let [t0, t1] = [pair[0], pair[1]];
        (0..cuts).map(move |i| t0 + (t1 - t0) * i as f64 / cuts as f64)
    });
    longest_probe_path_px(camera, object, probes, times.chain(ends.last().copied()))
}

/// What a moving mesh's level of detail depends on besides its method: the mesh, and how it is
/// seen over the shutter. Equal views give equal screen speeds, so they share one simplification
/// without measuring the speeds again.
#[derive(PartialEq)]
struct MeshView {
    mesh_key: u64,
    camera: Camera,
    motion: Motion,
    shutter: [f64; 2],
    rule: DetailRule,
}

/// The simplified mesh and the range of its screen speeds (px per shutter) for each recent view.
static SIMPLIFIED_IN_VIEW: Recent<MeshView, (speed::Shared, [f64; 2])> =
    Recent::new(speed::CACHE_ENTRIES);

/// Surfels resampled per face of a simplified mesh, at the least. One per face (as the
/// armadillo's 100,000 surfels on its 99,976 faces) leaves the few faces of a fast mesh one large
/// splat each: the armadillo at 90 px per shutter, kept at 1,832 faces, had `blur` ꟻLIP 0.035
/// against full detail with 1, 0.023 with 4 and 0.021 with 16, in 0.033, 0.038 and 0.042 s
/// (docs/math.md, "Mesh level of detail").
const MIN_RESAMPLED_PER_FACE: f64 = 4.0;

/// Surfels resampled from recent simplified meshes, by mesh and count (sampling the bunny's
/// 40 k took 15–20 ms of every plan).
static RESAMPLED: Recent<(speed::Shared, usize), Arc<Vec<Surfel>>> =
    Recent::new(speed::CACHE_ENTRIES);

/// The level of detail of a moving triangle mesh for `method` (Zhang et al. 2014 §5, Appendix B):
/// simplified as far as each vertex's screen speed allows for the shutter, drawn so by
/// `analytic` and each `reference` frame, and resampled into surfels for `blur` and `kernel3d`
/// when the mesh has one colour. Still meshes, `static` (a sharp instant) and hints (whose
/// object is drawn sharp) keep full detail. Returns it with the resampled surfels.
fn mesh_lod(
    scene: &Scene,
    object: &Object,
    moves: bool,
    method: &Method,
    lod: Lod,
) -> Result<(MeshLod, Option<Arc<Vec<Surfel>>>)> {
    let Some(mesh) = object.mesh() else {
        return Ok((MeshLod::NoMesh, None));
    };
    let why = match method {
        _ if lod == Lod::Off => Some("--lod off"),
        _ if !moves => Some("still while the shutter is open"),
        Method::Static { .. } => Some("a sharp instant"),
        Method::Hint { .. } => Some("a hint draws the object sharp"),
        _ => None,
    };
    if let Some(why) = why {
        return Ok((MeshLod::Full(why.into()), None));
    }
    // Drawn as surfels, a simplified mesh is resampled in one colour: a mesh of several keeps
    // its own surfels, so it is not simplified at all.
    let as_triangles = draws_triangles(method, object);
    if !as_triangles && !mesh.colours.windows(2).all(|w| w[0] == w[1]) {
        return Ok((
            MeshLod::Full("several colours, drawn as its own surfels".into()),
            None,
        ));
    }
    let shutter = [scene.shutter.open, scene.shutter.close];
    let mesh_key = speed::content_key(mesh);
    let view = MeshView {
        mesh_key,
        camera: scene.camera.clone(),
        motion: object.motion.clone(),
        shutter,
        rule: scene.mesh_detail,
    };
    let (shared, speed_px) = match SIMPLIFIED_IN_VIEW.find(|v| *v == view) {
        Some(found) => found,
        None => {
            let motion = ScreenMotion::of(&scene.camera, object, &mesh.positions, shutter);
            let limits = motion.limits(&scene.mesh_detail);
            let speed_px = motion
                .speed_px
                .iter()
                .fold([f64::INFINITY, 0.0], |[lo, hi], &v| [lo.min(v), hi.max(v)]);
            // A mesh the simplifier cannot take (split at colour seams, or no face with an area
            // left) is drawn as it is, and `--explain` says why.
            let shared = match speed::simplified(mesh, mesh_key, limits, motion.motion) {
                Ok(shared) => shared,
                Err(e) => {
                    let why = format!("the simplifier could not take it ({e})");
                    return Ok((MeshLod::Full(why), None));
                }
            };
            SIMPLIFIED_IN_VIEW.keep(view, (Arc::clone(&shared), speed_px));
            (shared, speed_px)
        }
    };
    // The simplifier interpolates colours, so one colour stays exactly one.
    let surfels = if as_triangles {
        None
    } else {
        // As many surfels per face as the full mesh had, and at least a few, but never more
        // than the full mesh's.
        let faces = shared.0.triangles.len() as f64;
        let per_face = object.surfels().len() as f64 / mesh.triangles.len() as f64;
        let count = (faces * per_face.max(MIN_RESAMPLED_PER_FACE))
            .ceil()
            .min(object.surfels().len() as f64)
            .max(1.0) as usize;
        let resampled = match RESAMPLED.find(|(m, c)| Arc::ptr_eq(m, &shared) && *c == count) {
            Some(found) => found,
            None => {
                let simplified = &shared.0;
                let source = Mesh {
                    positions: simplified.positions.clone(),
                    triangles: simplified.triangles.clone(),
                };
                let colour = simplified.colours.first().copied().unwrap_or_default();
                let mut surfels = crate::surfels::from_mesh(&source, count, false)?;
                Colouring::Rgb(colour).apply(&mut surfels);
                let surfels = Arc::new(surfels);
                RESAMPLED.keep((Arc::clone(&shared), count), Arc::clone(&surfels));
                surfels
            }
        };
        Some(resampled)
    };
    let lod = MeshLod::Simplified {
        mesh: shared,
        speed_px,
        resampled: surfels.as_ref().map(|s| s.len()),
    };
    Ok((lod, surfels))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Keyframe, Pose};
    use crate::surfels::from_mesh;
    use crate::surfels::mesh::tests::square;

    /// A 64 × 48 image looking down −z at the origin from z = 10.
    fn camera_10_units_away() -> Camera {
        Camera::new(
            DVec3::new(0.0, 0.0, 10.0),
            DVec3::ZERO,
            DVec3::Y,
            30.0,
            64,
            48,
        )
        .unwrap()
    }

    /// Equal pieces measured in parallel runs give the fit of one run over them all, to the bit:
    /// a square zig-zagging through 40 keyframes, cut into 10,007 pieces (three runs, the last
    /// short), with its keyframe corners inside them.
    #[test]
    fn pieces_measured_in_parallel_runs_fit_as_in_one() {
        let camera = camera_10_units_away();
        let keyframes = (0..40)
            .map(|i| Keyframe {
                t: f64::from(i) / 39.0,
                pose: Pose {
                    translation: DVec3::new(
                        if i % 2 == 0 { -1.0 } else { 1.0 },
                        0.1 * f64::from(i % 3),
                        0.0,
                    ),
                    ..Pose::IDENTITY
                },
            })
            .collect();
        let surfels = from_mesh(&square(1.0), 25, false).unwrap();
        let object = Object::new("zigzag", surfels, Motion::new(keyframes).unwrap());
        let probes: Vec<usize> = (0..object.surfels().len()).collect();
        let corners: Vec<f64> = (1..39).map(|i| f64::from(i) / 39.0).collect();
        let k = 10_007;
        assert!(k > 2 * PARALLEL_PIECES);
        let whole = Run {
            first: 0,
            last: k,
            corners: &corners,
        };
        let serial = measure_run(&camera, &object, &probes, [0.0, 1.0], k, whole);
        let parallel = measure(&camera, &object, &probes, [0.0, 1.0], k, &corners);
        let bits = |f: Fit| {
            [
                f.deviation,
                f.longest,
                f.weight,
                f.timed,
                f.uniform,
                f.size_change,
            ]
            .map(f64::to_bits)
        };
        assert_eq!(bits(parallel), bits(serial));
        assert!(serial.deviation > 0.0 && serial.longest > 0.0, "{serial:?}");
    }

    /// `static` and `reference` draw instants, so they plan no sub-segments however many
    /// keyframes there are, and still measure the path through every keyframe: a square
    /// zig-zagging 1,000 times between x = ±1 in the plane 10 units in front of the eye has a
    /// screen path of 1,000 legs of 2 f / 10 px (f the focal length in px), to rounding. The
    /// same motion under `blur` is cut at every keyframe.
    #[test]
    fn instants_plan_no_sub_segments_and_measure_the_path_through_every_keyframe() {
        let camera = camera_10_units_away();
        let legs = 1000;
        let keyframes = (0..=legs)
            .map(|i| Keyframe {
                t: f64::from(i) / f64::from(legs),
                pose: Pose {
                    translation: DVec3::new(if i % 2 == 0 { -1.0 } else { 1.0 }, 0.0, 0.0),
                    ..Pose::IDENTITY
                },
            })
            .collect();
        let surfels = from_mesh(&square(1.0), 25, false).unwrap();
        let object = Object::new("zigzag", surfels, Motion::new(keyframes).unwrap());
        let expected = f64::from(legs) * 2.0 * camera.focal_px / 10.0;
        let scene = Scene::new(camera).with_object(object);
        for method in [Method::STATIC, Method::Reference { samples: 16 }] {
            let plan = Plan::new(&scene, &method).unwrap();
            let ObjectMotion::Instants { path_px } = plan.objects[0].motion else {
                panic!("{method:?} planned {:?}", plan.objects[0].motion);
            };
            assert!(
                (path_px - expected).abs() <= 1e-9 * expected,
                "{path_px} px against {expected}"
            );
            assert!(plan.explain(None).contains("no sub-segments planned"));
        }
        let blur = Plan::new(&scene, &Method::BLUR).unwrap();
        let ObjectMotion::Moving { segments, .. } = &blur.objects[0].motion else {
            panic!("blur planned {:?}", blur.objects[0].motion);
        };
        assert!(segments.len() >= legs as usize);
    }
}
