//! Motion-blurred shadows from time-dependent shadow maps (Palmér §2.3): each light that casts
//! shadows sees the triangle objects through a camera of its own, and every texel keeps, over the
//! exposure, the resolved interval list of its nearest occluders (the same time-continuous
//! triangles and resolve as the image), or the nearest occluder at an instant.
//!
//! A receiver point is lit at time t when the texel's occluder at t is its own triangle (Palmér's
//! polygon IDs; its whole mesh where the mesh cannot shadow itself) or lies no nearer than the
//! receiver's depth less a bias of [`BIAS_TEXELS`] texels' width. Lookups are bilinear over four
//! texels (percentage-closer filtering). A static receiver's lit times are exact: within a texel
//! each occluder piece's depth is linear in time, so the times where it passes the receiver's
//! depth are roots of a line;
//! [`ShadowMap::breakpoints`] gives them, and visibility is constant between them. A receiver
//! that sweeps texels is point-sampled at max(2|pₑ − pₛ|, 5) times (Palmér §4.1), or with
//! `Receivers::Traced` has its path cut where it crosses the texel grid and each cut found as a
//! static one's ([`ShadowMap::traced_breakpoints`]).

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::intervals::Interval;
use crate::error::{Error, Result};
use crate::math::{box_corners, floor_to_i64};
use crate::plan::Plan;
use crate::scene::{Camera, LightSource, Motion, Scene, Shutter};
use std::cell::OnceCell;

/// Depth bias against self-shadowing, in texel widths at the receiver's depth, times
/// 1 + tan of the angle between the receiver's normal and the light (capped at
/// [`MAX_BIAS_SLOPE`]): a surface lit at a grazing angle changes depth fast across a texel, and
/// its neighbouring triangles would shadow it.
pub const BIAS_TEXELS: f64 = 2.0;

/// How far an occluder's linear depth pieces may stray from its exact depth, in texel widths at
/// that depth: half the least bias, so that a receiver the bias keeps from shadowing itself
/// stays clear by at least as much again. The image's own pieces follow the depth four times
/// as closely ([`super::tct::DEPTH_TOLERANCE_PX`]), where they decide which surface is seen.
pub const DEPTH_TOLERANCE_TEXELS: f64 = 0.5 * BIAS_TEXELS;

/// Largest slope factor of the bias.
pub const MAX_BIAS_SLOPE: f64 = 20.0;

/// The directional light's shadow camera stands this many scene radii from the scene's centre,
/// so that its perspective is within 1/this of an orthographic view.
const DIRECTIONAL_DISTANCE: f64 = 50.0;

/// Most radii of the sphere a directional light's map frames that the objects may reach beyond
/// it towards the light: its camera's view is then 2.4 · 10⁻³ degrees wide, above the least a
/// camera takes ([`crate::scene::camera::MIN_FOV_Y_DEGREES`]). Farther, the sphere widens.
const MAX_REACH_RADII: f64 = 1000.0;

/// Most point samples of a receiver sweeping the shadow map, per visible piece.
pub const MAX_RECEIVER_SAMPLES: usize = 256;

/// Most lights that cast shadows in one scene: each has a shadow map of up to
/// [`crate::scene::MAX_SHADOW_MAP`]² texels' interval lists.
pub const MAX_SHADOWED_LIGHTS: usize = 8;

/// Most occluder pieces the shadow maps of one render hold together (48 bytes each: 384 MiB),
/// shared evenly between the maps, where each texel record of a tile that holds occluders (its
/// list start and nearest-occluder summary, 20 bytes) counts as one piece. A map of more texels
/// than its share is drawn coarser like any other: eight shadowed lights with 4096² maps over a
/// floor of 3,200 triangles once held 62.8 M pieces (4.22 GB at peak, at 320 × 256), one per
/// texel past their shares; now 3.9 M pieces and 3.5 M texel records (283 MB). A cube
/// zig-zagging 150 times over a floor in one exposure put 256 pieces (as many as a texel then
/// kept) on each texel under its path, 1 GB in a 1024² map (and a 4096² map could have asked
/// sixteen times that). A map whose lists would hold more than its share is drawn again with
/// half the texels per side, as often as it takes: its shadows keep their strength and soften.
/// Only where even a map of [`crate::scene::MIN_SHADOW_MAP`] texels would not fit is each
/// texel's list cut to its longest pieces, as many as fit (`cap_within`), at least one each (at
/// most 8 × 16² more pieces). `--explain` says which. The gallery's scenes hold at most 1.2 M
/// (`armadillo_shadow`).
pub const MAX_SHADOW_PIECES: usize = 1 << 23;

/// Bytes of one texel record: its list start and its nearest-occluder summary.
pub(super) const TEXEL_RECORD_BYTES: usize =
    std::mem::size_of::<u32>() + std::mem::size_of::<Nearest>();

/// Longest path, in texels, that [`ShadowMap::surely_lit`] walks (about three texels per texel of
/// path are read; a longer path is point-sampled or traced).
pub const MAX_SURELY_LIT_TEXELS: f64 = 1024.0;

/// A receiver point moving linearly over part of the exposure, as the shadow cuts see it.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// Its world positions at the span's ends.
    pub path: [DVec3; 2],
    /// Its unit surface normals at the span's ends; between them the normal turns along the
    /// shorter arc (their linear interpolation, made unit), and so does its depth bias.
    pub normals: [DVec3; 2],
    /// The times it moves between.
    pub span: [f64; 2],
    /// What of its own does not shadow it: its triangle (object and triangle index), or its whole
    /// object where that cannot shadow itself (the triangle index then `u32::MAX`).
    pub own: (u32, u32),
}

impl Receiver {
    /// Its normal, not made unit, and its point at time `t` of its span: the ends' interpolated
    /// linearly (Palmér's sample interval), as the receiver is shaded.
    #[must_use]
    pub fn between(&self, t: f64) -> (DVec3, DVec3) {
        let [t0, t1] = self.span;
        let u = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        (
            self.normals[0].lerp(self.normals[1], u),
            self.path[0].lerp(self.path[1], u),
        )
    }

    /// Its unit normal at time `t` ([`Receiver::between`], made unit).
    #[must_use]
    pub fn normal_at(&self, t: f64) -> DVec3 {
        self.between(t).0.normalize_or_zero()
    }
}

/// The camera of each shadow-casting light's map, in [`crate::scene::Lighting::sources`]
/// order (the plan makes them once, [`Plan::shadow_cameras`]), a note for each triangle object a
/// directional light's map is too coarse to shadow ([`coarse_directional_shadows`]), and for
/// `--explain` what each directional light's map spans. The triangle objects' bounds that
/// directional lights frame are found once for all of them.
///
/// Errors: those of [`light_camera`].
pub fn shadow_cameras(
    scene: &Scene,
    plan: &Plan,
) -> Result<(Vec<Camera>, Vec<String>, Vec<String>)> {
    let frame = OnceCell::new();
    let cameras = (scene.lighting.sources())
        .filter(|source| source.shadows())
        .map(|source| {
            light_camera(&source, scene, || {
                frame.get_or_init(|| DirectionalFrame::new(scene, plan))
            })
        })
        .collect::<Result<_>>()?;
    let Some(frame) = frame.get() else {
        return Ok((cameras, Vec::new(), Vec::new()));
    };
    let size = scene.lighting.shadow_map;
    let lights: Vec<_> = (scene.lighting.sources())
        .filter_map(|source| match source {
            LightSource::Directional(l) if l.shadows => {
                Some((l.direction, frame.framing(l.direction)))
            }
            _ => None,
        })
        .collect();
    let framing = (lights.iter())
        .map(|&(_, (centre, radius, reach))| {
            let [x, y, z] = centre.to_array();
            format!(
                "the directional light's {size}² shadow map spans {:.4} units about [{x:.4}, {y:.4}, {z:.4}] (what the camera sees of the triangle objects), texels {:.4e} wide; its near plane {:.4} units towards the light from there",
                2.1 * radius,
                2.1 * radius / f64::from(size),
                1.5 * reach,
            )
        })
        .collect();
    Ok((
        cameras,
        coarse_directional_shadows(scene, plan, frame, &lights),
        framing,
    ))
}

/// What a directional light's map frames: a sphere (centre, radius) around what the camera can
/// see of the triangle objects over the exposure, and the objects' boxes, whose parts towards
/// the light over what is seen the map's depth range must hold (they may shadow it).
#[derive(Clone, Debug)]
struct DirectionalFrame {
    seen: (DVec3, f64),
    /// Each triangle object's index and box ([`triangle_boxes`]).
    boxes: Vec<(usize, [DVec3; 2])>,
}

impl DirectionalFrame {
    /// The frame of `scene`'s triangle objects ([`triangle_boxes`]). Each object's box is cut
    /// to the box around the camera's frustum between its near plane and the object's farthest
    /// depth, which holds every point of the object the camera can see: an object leaving the
    /// view, or one far off screen, no longer stretches the map's texels over what is not seen.
    /// Where nothing can be seen, the frame is all of them.
    fn new(scene: &Scene, plan: &Plan) -> DirectionalFrame {
        let boxes = triangle_boxes(scene, plan);
        let all = crate::math::bounds(boxes.iter().flat_map(|&(_, ends)| ends));
        let all = [all.0, all.1];
        let camera = &scene.camera;
        let to_world = camera.view.inverse();
        let (w, h) = (f64::from(camera.width), f64::from(camera.height));
        let edges = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)].map(|(x, y)| camera.ray(x, y));
        let mut seen = [DVec3::INFINITY, DVec3::NEG_INFINITY];
        for &(_, [lo, hi]) in &boxes {
            let farthest = (box_corners(lo, hi).iter())
                .map(|&corner| -camera.view.transform_point3(corner).z)
                .fold(f64::NEG_INFINITY, f64::max);
            if !(farthest >= camera.near) {
                continue;
            }
            let frustum = crate::math::bounds(edges.iter().flat_map(|&ray| {
                [camera.near, farthest].map(|depth| to_world.transform_point3(ray * depth))
            }));
            let (cut_lo, cut_hi) = (lo.max(frustum.0), hi.min(frustum.1));
            if cut_lo.cmple(cut_hi).all() {
                seen = [seen[0].min(cut_lo), seen[1].max(cut_hi)];
            }
        }
        let sphere = |[lo, hi]: [DVec3; 2]| {
            if lo.x <= hi.x {
                (0.5 * (lo + hi), (0.5 * (hi - lo).length()).max(1e-9))
            } else {
                (DVec3::ZERO, 1.0)
            }
        };
        DirectionalFrame {
            seen: sphere(if seen[0].x <= seen[1].x { seen } else { all }),
            boxes,
        }
    }

    /// Whether `bounds` reach into the cylinder along the unit `direction` of 1.05 × `radius`
    /// about the seen sphere's centre, allowing for the rounding of a box far along it.
    fn within(&self, [lo, hi]: [DVec3; 2], direction: DVec3, radius: f64) -> bool {
        // In units of the offset's largest coordinate, whose squares do not overflow.
        let offset = 0.5 * (lo + hi) - self.seen.0;
        let unit = offset.abs().max_element().max(f64::MIN_POSITIVE);
        let (offset, half) = (offset / unit, 0.5 * (hi - lo) / unit);
        let across = offset - offset.dot(direction) * direction;
        across.length() - half.length() <= 1.05 * radius / unit + 1e-12 * offset.length()
    }

    /// For a light along the unit `direction`, the centre and radius of the sphere its map
    /// frames, and how far the objects that may shadow the seen sphere (in its cylinder along
    /// the light) reach from its centre towards the light (at least its radius). The sphere is
    /// the seen one, widened to [`MAX_REACH_RADII`]⁻¹ of the reach where objects lie farther
    /// towards the light than that many radii: the light's camera stands
    /// [`DIRECTIONAL_DISTANCE`] reaches away, and its view may be no narrower than a camera's.
    fn framing(&self, direction: DVec3) -> (DVec3, f64, f64) {
        let (centre, radius) = self.seen;
        let reach = (self.boxes.iter())
            .filter(|(_, bounds)| self.within(*bounds, direction, radius))
            .flat_map(|&(_, [lo, hi])| box_corners(lo, hi))
            .map(|corner| (corner - centre).dot(direction))
            .fold(radius, f64::max);
        (centre, radius.max(reach / MAX_REACH_RADII), reach)
    }
}

/// The camera of `source`'s shadow map: the spot's own view of its cone, or for a directional
/// light a narrow perspective view from far along its direction, framing what the camera can
/// see of the triangle objects over the exposure, its near plane before all of them (`frame`,
/// [`DirectionalFrame`]).
///
/// Errors: a spot so far from the origin that one step along its direction does not change its
/// position in double precision, or triangles so far out that a directional light's view of
/// them overflows; the error names the light and what would be right.
fn light_camera<'f>(
    source: &LightSource,
    scene: &Scene,
    frame: impl FnOnce() -> &'f DirectionalFrame,
) -> Result<Camera> {
    let size = scene.lighting.shadow_map;
    let up = |direction: DVec3| {
        if direction.cross(DVec3::Y).length() > 1e-3 {
            DVec3::Y
        } else {
            DVec3::X
        }
    };
    let camera = match source {
        LightSource::Spot(s) => {
            let fov = 2.0 * s.angle.to_degrees();
            Camera::new(
                s.position,
                s.position + s.direction,
                up(s.direction),
                fov,
                size,
                size,
            )
        }
        LightSource::Directional(l) => {
            // Far enough along the light for every object towards it to lie in front of the
            // near plane, and as narrow as to frame 1.05 radii each way at the centre.
            let (centre, radius, reach) = frame().framing(l.direction);
            let distance = DIRECTIONAL_DISTANCE * reach;
            let fov = 2.0 * ((1.05 / DIRECTIONAL_DISTANCE) * (radius / reach)).atan();
            Camera::new(
                centre + l.direction * distance,
                centre,
                up(l.direction),
                fov.to_degrees(),
                size,
                size,
            )
            .and_then(|c| c.with_near(distance - 1.5 * reach))
        }
    };
    camera
        .and_then(|c| c.with_spatial_samples(1))
        .map_err(|error| {
            let (light, remedy) = match source {
                LightSource::Spot(s) => (
                    format!("the spot light at {}", s.position),
                    "place it nearer the scene, or use a directional light for a distant source",
                ),
                LightSource::Directional(l) => (
                    format!("the directional light along {}", l.direction),
                    "keep the triangle objects within a finite, double-precision distance of the origin",
                ),
            };
            Error::invalid(
                "lighting",
                format!("{light} casts shadows, but its shadow map's camera cannot be made ({error}): {remedy}"),
            )
        })
}

/// Notes for the triangle objects too small for a directional light's shadow map to show: the
/// map frames what the camera can see of the triangle objects over the whole exposure (the same
/// for every method, [`DirectionalFrame`]), so a wide view, or an object seen far off, stretches
/// its texels until a nearby object's shadow falls within two of them, lost or faint. `lights`
/// holds each shadowed directional light's direction and [`DirectionalFrame::framing`].
fn coarse_directional_shadows(
    scene: &Scene,
    plan: &Plan,
    frame: &DirectionalFrame,
    lights: &[(DVec3, (DVec3, f64, f64))],
) -> Vec<String> {
    // The light camera frames 1.05 radii each way ([`light_camera`]).
    let texel = |radius: f64| 2.1 * radius / f64::from(scene.lighting.shadow_map);
    let middle = scene.shutter.middle();
    let length = |v: f64| {
        if v >= 1e-3 {
            format!("{v:.3}")
        } else {
            format!("{v:.2e}")
        }
    };
    frame
        .boxes
        .iter()
        .filter_map(|&(index, bounds)| {
            let object = &scene.objects[index];
            let mesh = plan.mesh_of(index)?;
            let (lo, hi) = crate::math::bounds(mesh.positions.iter().copied());
            let across = (hi - lo).length() * object.motion.pose_at(middle).scale;
            // The first map whose cylinder the object reaches into and that is too coarse for it.
            let radius = (lights.iter())
                .filter(|&&(d, (_, radius, _))| frame.within(bounds, d, radius))
                .map(|&(_, (_, radius, _))| radius)
                .find(|&radius| across < 2.0 * texel(radius))?;
            Some(format!(
                    "{:?} is {} across, within two texels of the directional light's shadow map ({} each: the map frames what the camera sees of the triangle objects over the exposure, {} across), so its shadow is lost or faint: a larger shadow_map, or a narrower view, would show it",
                    object.name,
                    length(across),
                    length(texel(radius)),
                    length(2.0 * radius)
                ))
        })
        .collect()
}

/// The index and box [lo, hi] of each triangle object drawn as triangles over the exposure, the same
/// whatever the method (so that `static` and each `reference` frame see the shadow map
/// `analytic` sees, at any tolerance): each vertex at the shutter's ends and middle, at every
/// keyframe, and every [`BOUND_TURN_STEP`] of a turn between keyframes. Where that is more than
/// [`BOUND_VERTEX_POSES`] vertex poses, around the sphere about the object's origin that holds it
/// in any orientation, at the shutter's ends and keyframes (looser, so texels are coarser).
fn triangle_boxes(scene: &Scene, plan: &Plan) -> Vec<(usize, [DVec3; 2])> {
    let (open, close) = (scene.shutter.open, scene.shutter.close);
    let mut boxes = Vec::new();
    for (index, object) in scene.objects.iter().enumerate() {
        let Some(mesh) = plan.mesh_of(index).filter(|_| plan.draws_triangles(index)) else {
            continue;
        };
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let motion = &object.motion;
        let keys = motion.keyframe_ends(open, close);
        let most_poses = BOUND_VERTEX_POSES / mesh.positions.len().max(1);
        if let Some(mut times) = bound_times(motion, &keys, most_poses) {
            times.push(scene.shutter.middle());
            for t in times {
                let pose = motion.pose_at(t).to_affine();
                for &p in &mesh.positions {
                    let w = pose.transform_point3(p);
                    lo = lo.min(w);
                    hi = hi.max(w);
                }
            }
            boxes.push((index, [lo, hi]));
            continue;
        }
        // Translation and scale are linear between keyframes, so the sphere's centre and radius
        // are too, and its box at the keyframes holds it throughout.
        let reach = mesh
            .positions
            .iter()
            .map(|p| p.length())
            .fold(0.0, f64::max);
        for t in keys {
            let pose = motion.pose_at(t);
            let radius = DVec3::splat(reach * pose.scale);
            lo = lo.min(pose.translation - radius);
            hi = hi.max(pose.translation + radius);
        }
        boxes.push((index, [lo, hi]));
    }
    boxes.retain(|(_, [lo, hi])| lo.x <= hi.x);
    boxes
}

/// The keyframe `ends` and every [`BOUND_TURN_STEP`] of a turn between them, unless that is more
/// than `most` instants.
fn bound_times(motion: &Motion, ends: &[f64], most: usize) -> Option<Vec<f64>> {
    let rotations: Vec<_> = ends.iter().map(|&t| motion.pose_at(t).rotation).collect();
    let mut times = Vec::new();
    for (pair, turn) in ends.windows(2).zip(rotations.windows(2)) {
        let [t0, t1] = [pair[0], pair[1]];
        let steps = (turn[0].angle_between(turn[1]) / BOUND_TURN_STEP)
            .ceil()
            .max(1.0);
        if times.len() as f64 + steps >= most as f64 {
            return None;
        }
        times.extend((0..steps as usize).map(|i| t0 + (t1 - t0) * i as f64 / steps));
    }
    times.extend(ends.last());
    Some(times)
}

/// Largest turn between the poses at which a turning object's extent is taken, radians (1°): a
/// point r from the turn's axis leaves the chord between two of them by r (1 − cos 0.5°),
/// 4·10⁻⁵ r, well inside the light camera's 5 % margin.
const BOUND_TURN_STEP: f64 = std::f64::consts::PI / 180.0;

/// Most vertex poses [`triangle_boxes`] takes of one object (2²⁴, tenths of a second).
const BOUND_VERTEX_POSES: usize = 1 << 24;

/// One occluder piece of a texel: when, how deep, and which triangle (object, triangle).
#[derive(Clone, Copy, Debug)]
pub struct Occluder {
    /// The visible piece from the light.
    pub piece: Interval,
    /// The triangle it belongs to.
    pub id: (u32, u32),
}

/// Whose occluders a region of a shadow map holds ([`ShadowMap::casters_around`]): the merged
/// record of its tiles.
#[derive(Clone, Copy, Debug)]
pub struct Casters(Nearest);

impl Casters {
    /// Whether every occluder there is `own`'s (or there is none): a receiver of `own` whose
    /// lookups read only there is lit throughout. `Casters::none_but(NO_TRIANGLE)`: the region
    /// holds no occluder at all.
    #[must_use]
    pub fn none_but(&self, own: (u32, u32)) -> bool {
        self.0.except(own) == f32::INFINITY
    }
}

/// The largest f32 at most `x`: a nearest depth rounded to the nearest f32 may lie beyond the
/// occluder, and a receiver between the two would pass as surely lit.
fn f32_at_most(x: f64) -> f32 {
    let rounded = x as f32;
    if f64::from(rounded) > x {
        rounded.next_down()
    } else {
        rounded
    }
}

/// An id no triangle has: [`Casters::none_but`] it holds where no occluder lies.
pub const NO_TRIANGLE: (u32, u32) = (u32::MAX, u32::MAX);

/// The nearest occluder depth over all time of a texel (or of a tile's texels), its triangle,
/// and the nearest depth of every other triangle (+∞ where there is none): the nearest that can
/// shadow any receiver, its own triangle left out, in one look.
#[derive(Clone, Copy, Debug)]
struct Nearest {
    depth: f32,
    id: (u32, u32),
    others: f32,
}

impl Nearest {
    const NONE: Nearest = Nearest {
        depth: f32::INFINITY,
        id: NO_TRIANGLE,
        others: f32::INFINITY,
    };

    fn of(occluders: &[Occluder]) -> Nearest {
        occluders
            .iter()
            .map(|o| Nearest {
                depth: f32_at_most(o.piece.depth[0].min(o.piece.depth[1])),
                id: o.id,
                others: f32::INFINITY,
            })
            .fold(Nearest::NONE, Nearest::merge)
    }

    /// The nearest occluders of both texel sets together.
    fn merge(self, other: Nearest) -> Nearest {
        if self.id == other.id {
            return Nearest {
                depth: self.depth.min(other.depth),
                id: self.id,
                others: self.others.min(other.others),
            };
        }
        let (near, far) = if self.depth <= other.depth {
            (self, other)
        } else {
            (other, self)
        };
        // The far set's nearest is another triangle's than the near set's, and no farther than
        // its others.
        Nearest {
            depth: near.depth,
            id: near.id,
            others: near.others.min(far.depth),
        }
    }

    /// The nearest depth of any triangle but `own`.
    fn except(&self, own: (u32, u32)) -> f32 {
        if own == self.id {
            self.others
        } else {
            self.depth
        }
    }
}

/// What a shadow map's texel lists hold and what making them left out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShadowLists {
    /// Occluder pieces held.
    pub pieces: usize,
    /// Texel records held (a list start each, and a nearest-occluder summary over a shutter), in
    /// the tiles that hold occluders; each counts as a piece against [`MAX_SHADOW_PIECES`].
    pub records: usize,
    /// The most on one texel.
    pub peak_per_texel: usize,
    /// Times a texel's interval list was full ([`super::MAX_INTERVALS_PER_SAMPLE`]) and was
    /// resolved to make room, as an image sample's is.
    pub compressed: usize,
    /// Intervals that went from texel lists still full after that (each one's time given to a
    /// piece it adjoins where one does, as an image sample's).
    pub dropped: usize,
    /// When a map's lists would have held more than its share of [`MAX_SHADOW_PIECES`] at the
    /// resolution asked for: that side and the side it was drawn at, coarser (the smallest over
    /// the maps).
    pub coarsened: Option<(u32, u32)>,
    /// When even the coarsest map would have held more: the longest pieces each texel kept.
    pub cap: Option<usize>,
    /// The pieces that cap left out.
    pub cut: usize,
}

impl ShadowLists {
    /// Add another map's counts (each light's, each frame's); the tightest cap stands for them.
    pub fn add(&mut self, other: &ShadowLists) {
        self.pieces += other.pieces;
        self.records += other.records;
        self.peak_per_texel = self.peak_per_texel.max(other.peak_per_texel);
        self.compressed += other.compressed;
        self.dropped += other.dropped;
        self.coarsened = match (self.coarsened, other.coarsened) {
            (Some(a), Some(b)) => Some(if a.1 <= b.1 { a } else { b }),
            (a, b) => a.or(b),
        };
        self.cap = match (self.cap, other.cap) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        self.cut += other.cut;
    }
}

/// The largest number of pieces each texel may keep so that texels holding `counts` keep at most
/// `budget` together (at least one each: a budget below the texel count keeps one).
#[must_use]
pub fn cap_within(counts: impl Iterator<Item = usize>, budget: usize) -> usize {
    let mut at_least = Vec::new();
    for count in counts {
        if count >= at_least.len() {
            at_least.resize(count + 1, 0usize);
        }
        at_least[count] += 1;
    }
    // at_least[k] becomes the number of texels holding k pieces or more.
    for k in (1..at_least.len().saturating_sub(1)).rev() {
        at_least[k] += at_least[k + 1];
    }
    // Each texel keeps min(count, cap): raising the cap by one adds one piece per texel that
    // holds more.
    let mut kept = 0;
    let mut cap = 0;
    while cap + 1 < at_least.len() && kept + at_least[cap + 1] <= budget {
        cap += 1;
        kept += at_least[cap];
    }
    cap.max(1)
}

/// The occluders of every texel: per tile of the light's view, the texels' lists one after the
/// other (`starts` has one more entry than the tile has texels, or none at all where the tile
/// holds no occluder).
pub struct Occluders {
    /// The light's camera.
    pub camera: Camera,
    /// Per tile: where each texel's list starts, and the lists.
    pub tiles: Vec<(Vec<u32>, Vec<Occluder>)>,
    /// Tiles left without occluders: every object that reaches them cannot shadow itself and
    /// lies wholly deeper there than every other object.
    pub left_empty: usize,
    /// Item × tile pairs left out so.
    pub left_out: usize,
    /// What the texel lists hold and left out.
    pub lists: ShadowLists,
}

/// A light's shadow map, ready for lookups.
pub struct ShadowMap {
    occluders: Occluders,
    tiles_x: u32,
    /// The nearest occluders of each texel over all time, per tile as its texels' lists are (none
    /// where the tile holds no occluder): a receiver whose depth limit lies nearer than every
    /// other triangle's occluder its path reads is lit throughout.
    nearest: Vec<Vec<Nearest>>,
    /// The same for each tile's texels, row by row: one look for a path within a tile.
    nearest_in_tile: Vec<Nearest>,
}

impl ShadowMap {
    /// The map of `occluders`, ready for [`ShadowMap::visibility`] lookups; for
    /// [`ShadowMap::surely_lit`], [`ShadowMap::summarised`].
    #[must_use]
    pub fn new(occluders: Occluders) -> ShadowMap {
        let tiles_x = occluders.camera.width.div_ceil(crate::raster::TILE_PX);
        ShadowMap {
            occluders,
            tiles_x,
            nearest: Vec::new(),
            nearest_in_tile: Vec::new(),
        }
    }

    /// The map with each texel's and each tile's nearest occluders over all time, which the
    /// lit-for-sure tests read (texel records only in tiles that hold occluders). Over a shutter
    /// only: at an instant receivers look up their visibility alone, and a reference frame would
    /// pay for records it never reads ([`ShadowMap::summarised_by_tile`] instead).
    #[must_use]
    pub fn summarised(mut self) -> ShadowMap {
        let nearest: Vec<Vec<Nearest>> = self
            .occluders
            .tiles
            .par_iter()
            .map(|(starts, list)| {
                starts
                    .windows(2)
                    .map(|s| Nearest::of(&list[s[0] as usize..s[1] as usize]))
                    .collect()
            })
            .collect();
        self.nearest_in_tile = nearest
            .iter()
            .map(|texels| texels.iter().copied().fold(Nearest::NONE, Nearest::merge))
            .collect();
        self.nearest = nearest;
        self
    }

    /// The map with each tile's nearest occluders, which [`ShadowMap::casters_around`] reads,
    /// and no texel records: a map of an instant, whose receivers look up their visibility one
    /// by one, learns only where a whole image tile's lookups would find nothing but their own
    /// occluders, for the cost of one pass over its occluders.
    #[must_use]
    pub fn summarised_by_tile(mut self) -> ShadowMap {
        self.nearest_in_tile = (self.occluders.tiles.par_iter())
            .map(|(_, list)| Nearest::of(list))
            .collect();
        self
    }

    /// The tile holding texel (x, y), which lies in the map.
    fn tile_of(&self, x: u32, y: u32) -> usize {
        let tile_px = crate::raster::TILE_PX;
        ((y / tile_px) * self.tiles_x + x / tile_px) as usize
    }

    /// Whether no occluder of a triangle other than `own` in the tiles holding texels
    /// `[x0, y0, x1, y1)` lies nearer than `depth`: a receiver that reads only those texels
    /// and lies no deeper is lit throughout.
    fn surely_lit_within(&self, texels: [u32; 4], depth: f64, own: (u32, u32)) -> bool {
        self.records_within(texels)
            .all(|nearest| f64::from(nearest.except(own)) >= depth)
    }

    /// The merged records of the tiles holding texels `[x0, y0, x1, y1)`.
    fn nearest_within(&self, texels: [u32; 4]) -> Nearest {
        self.records_within(texels)
            .fold(Nearest::NONE, |nearest, tile| nearest.merge(tile))
    }

    /// The records of the tiles holding texels `[x0, y0, x1, y1)` (clamped to the map).
    fn records_within(&self, [x0, y0, x1, y1]: [u32; 4]) -> impl Iterator<Item = Nearest> + '_ {
        let side = self.occluders.camera.width;
        let (x1, y1) = (x1.min(side), y1.min(side));
        let tile_px = crate::raster::TILE_PX;
        let (rows, columns) = if x0 >= x1 || y0 >= y1 {
            (0..0, 0..0)
        } else {
            (
                y0 / tile_px..(y1 - 1) / tile_px + 1,
                x0 / tile_px..(x1 - 1) / tile_px + 1,
            )
        };
        rows.flat_map(move |ty| {
            columns
                .clone()
                .map(move |tx| self.nearest_in_tile[self.tile_of(tx * tile_px, ty * tile_px)])
        })
    }

    /// Tiles of the map.
    #[must_use]
    pub fn tiles(&self) -> usize {
        self.occluders.tiles.len()
    }

    /// Tiles left without occluders ([`Occluders::left_empty`]).
    #[must_use]
    pub fn left_empty(&self) -> usize {
        self.occluders.left_empty
    }

    /// Item × tile pairs left out ([`Occluders::left_out`]).
    #[must_use]
    pub fn left_out(&self) -> usize {
        self.occluders.left_out
    }

    /// What the texel lists hold and left out ([`Occluders::lists`]).
    #[must_use]
    pub fn lists(&self) -> ShadowLists {
        self.occluders.lists
    }

    /// Whether `receiver` is lit throughout its span: in every texel its bilinear lookups can
    /// read along its path, either every other triangle's occluder of the exposure lies beyond
    /// its depth limit (one look at the texel's nearest occluders), or every other triangle's
    /// occluder during its span does. The path's texels are walked row by row (a straight path
    /// in the world projects to a straight one in the map); the depth limit is the larger of the
    /// path's ends'. A path sweeping more than [`MAX_SURELY_LIT_TEXELS`] is not checked.
    #[must_use]
    pub fn surely_lit(&self, receiver: &Receiver) -> bool {
        let Receiver {
            path: [p0, p1],
            normals,
            span,
            own,
        } = *receiver;
        // A still receiver's path is one point: placed once. Each end is placed with the least
        // bias its normal takes over the span, so that the limit is the deepest of any time's.
        let Some(a) = self.place_turning(p0, normals) else {
            return false;
        };
        let Some(b) = (if p0 == p1 {
            Some(a)
        } else {
            self.place_turning(p1, normals)
        }) else {
            return false;
        };
        self.surely_lit_between(a, b, span, own)
    }

    /// Where a receiver point `p` with unit `normal` falls (texel coordinates) and the depth
    /// nearer than which an occluder shadows it (its light depth less the bias); `None` behind
    /// the light.
    #[must_use]
    pub fn place(&self, p: DVec3, normal: DVec3) -> Option<(DVec2, f64)> {
        let (at, depth) = self.locate(p)?;
        Some((at, depth - self.bias(depth, self.bias_slope(p, normal))))
    }

    /// [`ShadowMap::place`] for a receiver point `p` whose unit normal turns from `normals[0]`
    /// to `normals[1]` (along the shorter arc): with the least bias of any normal on the arc,
    /// so that the depth limit is no nearer than any of theirs ([`ShadowMap::surely_lit`]).
    #[must_use]
    pub fn place_turning(&self, p: DVec3, normals: [DVec3; 2]) -> Option<(DVec2, f64)> {
        let (at, depth) = self.locate(p)?;
        Some((
            at,
            depth - self.bias(depth, self.least_bias_slope(p, normals)),
        ))
    }

    /// [`ShadowMap::surely_lit`] for a receiver on triangle `own` moving over `span` between two
    /// points placed by [`ShadowMap::place`] or [`ShadowMap::place_turning`]: its depth limit is
    /// the larger of theirs.
    #[must_use]
    pub fn surely_lit_between(
        &self,
        (a, limit_a): (DVec2, f64),
        (b, limit_b): (DVec2, f64),
        span: [f64; 2],
        own: (u32, u32),
    ) -> bool {
        // Without texel records (a map of an instant): nothing is known for sure.
        if self.nearest.is_empty() || !(a.distance(b) <= MAX_SURELY_LIT_TEXELS) {
            return false;
        }
        let limit = limit_a.max(limit_b);
        let side = i64::from(self.occluders.camera.width);
        let lit = |x: i64, y: i64| {
            let (tile, local) = self.tile_and_texel(x as u32, y as u32);
            let nearest = self.nearest[tile].get(local).unwrap_or(&Nearest::NONE);
            f64::from(nearest.except(own)) >= limit
                || self
                    .others_during(x, y, span, own)
                    .all(|(o, [a0, a1])| o.piece.depth_at(a0).min(o.piece.depth_at(a1)) >= limit)
        };
        let (lo, hi) = if a.y <= b.y { (a, b) } else { (b, a) };
        // A lookup at (x, y) reads texels ⌊x⌋, ⌊x⌋ + 1 of rows ⌊y⌋, ⌊y⌋ + 1: row r is read by the
        // path's points with y in [r − 1, r + 1), all of them on a path along a row.
        let x_at = |y: f64, whole: f64| {
            let u = if hi.y > lo.y {
                ((y - lo.y) / (hi.y - lo.y)).clamp(0.0, 1.0)
            } else {
                whole
            };
            lo.x + (hi.x - lo.x) * u
        };
        // Texel indices, clamped to just outside the map first so that one more stays in range.
        let index = |v: f64| floor_to_i64(v.clamp(-2.0, side as f64 + 1.0));
        // First one look per tile the path's texels lie in: enough where no other triangle's
        // occluder in them comes nearer than the limit, as on most of a lit surface.
        let texel_range = |from: f64, to: f64| {
            [
                index(from.min(to)).max(0),
                (index(from.max(to)) + 2).clamp(0, side),
            ]
            .map(|v| v as u32)
        };
        let ([x0, x1], [y0, y1]) = (texel_range(a.x, b.x), texel_range(a.y, b.y));
        if self.surely_lit_within([x0, y0, x1, y1], limit, own) {
            return true;
        }
        for row in i64::from(y0)..i64::from(y1) {
            let (xa, xb) = (x_at(row as f64 - 1.0, 0.0), x_at(row as f64 + 1.0, 1.0));
            for x in index(xa.min(xb)).max(0)..(index(xa.max(xb)) + 2).min(side) {
                if !lit(x, row) {
                    return false;
                }
            }
        }
        true
    }

    /// Whose occluders lie in the texels that a lookup at a point within the convex hull of
    /// `corners` can read. The hull's image in the map is the hull of its corners' images (the
    /// light's projection keeps straight lines straight in front of it), so their bounding box
    /// and one texel more bound what bilinear lookups read. `None` (nothing known) where a
    /// corner lies behind the light, or the map is not summarised.
    #[must_use]
    pub fn casters_around(&self, corners: &[DVec3]) -> Option<Casters> {
        if self.nearest_in_tile.is_empty() {
            return None;
        }
        let mut bounds = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for &p in corners {
            let (at, _) = self.locate(p)?;
            bounds = [
                bounds[0].min(at.x),
                bounds[1].min(at.y),
                bounds[2].max(at.x),
                bounds[3].max(at.y),
            ];
        }
        if !bounds.iter().all(|b| b.is_finite()) {
            return None;
        }
        let side = f64::from(self.occluders.camera.width);
        // Texels ⌊x⌋ and ⌊x⌋ + 1 are read at x; clamped to the map (beyond it nothing is read).
        let texel = |v: f64, more: f64| (v.floor() + more).clamp(0.0, side) as u32;
        let texels = [
            texel(bounds[0], 0.0),
            texel(bounds[1], 0.0),
            texel(bounds[2], 2.0),
            texel(bounds[3], 2.0),
        ];
        Some(Casters(self.nearest_within(texels)))
    }

    /// Where world point `p` falls: continuous texel coordinates (texel centres at integers)
    /// and its depth from the light; `None` behind the light.
    #[must_use]
    pub fn locate(&self, p: DVec3) -> Option<(DVec2, f64)> {
        let camera = &self.occluders.camera;
        let (screen, depth) = camera.project(camera.view.transform_point3(p))?;
        Some((screen - DVec2::splat(0.5), depth))
    }

    /// The occluder pieces of texel (x, y) from triangles other than `own` that overlap `span`,
    /// each with the times they overlap.
    fn others_during(
        &self,
        x: i64,
        y: i64,
        span: [f64; 2],
        own: (u32, u32),
    ) -> impl Iterator<Item = (&Occluder, [f64; 2])> {
        let [t0, t1] = span;
        // A texel's pieces are in time order and do not overlap (one resolve's output).
        let list = self.texel(x, y);
        let first = list.partition_point(|o| o.piece.t[1] < t0);
        list[first..]
            .iter()
            .take_while(move |o| o.piece.t[0] <= t1)
            .filter(move |o| o.id != own)
            .map(move |o| (o, [o.piece.t[0].max(t0), o.piece.t[1].min(t1)]))
            .filter(|(_, [a0, a1])| a0 <= a1)
    }

    /// The occluder list of texel (x, y); empty outside the map.
    fn texel(&self, x: i64, y: i64) -> &[Occluder] {
        let camera = &self.occluders.camera;
        if x < 0 || y < 0 || x >= i64::from(camera.width) || y >= i64::from(camera.height) {
            return &[];
        }
        let (tile, local) = self.tile_and_texel(x as u32, y as u32);
        let (starts, list) = &self.occluders.tiles[tile];
        match starts.get(local..local + 2) {
            Some(&[start, end]) => &list[start as usize..end as usize],
            _ => &[],
        }
    }

    /// The tile holding texel (x, y), which lies in the map, and the texel's place in it.
    fn tile_and_texel(&self, x: u32, y: u32) -> (usize, usize) {
        let camera = &self.occluders.camera;
        let tile_px = crate::raster::TILE_PX;
        let (x0, y0) = (x / tile_px * tile_px, y / tile_px * tile_px);
        let w = (x0 + tile_px).min(camera.width) - x0;
        (self.tile_of(x, y), ((y - y0) * w + (x - x0)) as usize)
    }

    /// The depth bias at light depth `depth` for a receiver whose [`ShadowMap::bias_slope`] is
    /// `slope`.
    fn bias(&self, depth: f64, slope: f64) -> f64 {
        slope * depth / self.occluders.camera.focal_px
    }

    /// [`BIAS_TEXELS`] times the slope factor of the bias for a receiver at `p` with unit
    /// `normal`, the same at every depth ([`ShadowMap::bias`]).
    fn bias_slope(&self, p: DVec3, normal: DVec3) -> f64 {
        let cos = normal
            .dot((self.occluders.camera.eye - p).normalize_or_zero())
            .abs();
        Self::slope_of_cos(cos)
    }

    /// [`ShadowMap::bias_slope`] of a receiver whose normal's |cos| to the light is `cos`.
    fn slope_of_cos(cos: f64) -> f64 {
        let cos = cos.max(1e-9);
        let slope = ((1.0 - cos * cos).max(0.0).sqrt() / cos).min(MAX_BIAS_SLOPE);
        BIAS_TEXELS * (1.0 + slope)
    }

    /// The least [`ShadowMap::bias_slope`] at `p` of the unit normals on the shorter arc from
    /// `n0` to `n1`: the one nearest the light's direction (or its opposite), which is an end
    /// or, where the direction's projection onto the arc's plane falls within the arc, that
    /// projection.
    fn least_bias_slope(&self, p: DVec3, [n0, n1]: [DVec3; 2]) -> f64 {
        let e = (self.occluders.camera.eye - p).normalize_or_zero();
        let mut cos = n0.dot(e).abs().max(n1.dot(e).abs());
        let m = n0.cross(n1).normalize_or_zero();
        if m != DVec3::ZERO {
            let q = e - m * e.dot(m);
            for q in [q, -q] {
                if n0.cross(q).dot(m) >= 0.0 && q.cross(n1).dot(m) >= 0.0 {
                    cos = cos.max(q.length());
                }
            }
        }
        Self::slope_of_cos(cos)
    }

    /// The four texels of a bilinear lookup at texel coordinates `at`, with their weights.
    fn footprint(at: DVec2) -> [((i64, i64), f64); 4] {
        let (x, y) = (floor_to_i64(at.x), floor_to_i64(at.y));
        let f = at - DVec2::new(x as f64, y as f64);
        [
            ((x, y), (1.0 - f.x) * (1.0 - f.y)),
            ((x + 1, y), f.x * (1.0 - f.y)),
            ((x, y + 1), (1.0 - f.x) * f.y),
            ((x + 1, y + 1), f.x * f.y),
        ]
    }

    /// The share of light reaching world point `p` (unit `normal`) at time `t` (bilinear over
    /// four texels), for a receiver on triangle `own`.
    #[must_use]
    pub fn visibility(&self, p: DVec3, normal: DVec3, t: f64, own: (u32, u32)) -> f64 {
        self.place(p, normal)
            .map_or(1.0, |placed| self.visibility_placed(placed, t, own))
    }

    /// [`ShadowMap::visibility`] of a receiver point placed by [`ShadowMap::place`]: a still
    /// receiver is placed once for all its times.
    #[must_use]
    pub fn visibility_placed(&self, (at, limit): (DVec2, f64), t: f64, own: (u32, u32)) -> f64 {
        Self::footprint(at)
            .iter()
            .filter(|(_, w)| *w > 0.0)
            .map(|&((x, y), w)| {
                // A texel's pieces are in time order and do not overlap (one resolve's output),
                // and instants' pieces are single times: the ones covering t start at the first
                // that has not ended before it.
                let list = self.texel(x, y);
                let first = list.partition_point(|o| o.piece.t[1] < t);
                let occluded = list[first..]
                    .iter()
                    .take_while(|o| o.piece.t[0] <= t)
                    .any(|o| o.id != own && o.piece.depth_at(t) < limit);
                if occluded {
                    0.0
                } else {
                    w
                }
            })
            .sum()
    }

    /// Texel distance between where `p0` and `p1` fall (∞ when one is behind the light).
    #[must_use]
    pub fn sweep(&self, p0: DVec3, p1: DVec3) -> f64 {
        match (self.locate(p0), self.locate(p1)) {
            (Some((a, _)), Some((b, _))) => a.distance(b),
            _ => f64::INFINITY,
        }
    }

    /// For a `receiver` moving uniformly across texels, every time in its span at which its
    /// visibility can change, appended to `out`. This goes past Palmér's point sampling,
    /// following his future work: the path is intersected with the texel grid. A point moving
    /// linearly in world space crosses the line "texel coordinate = k" at a time that solves a
    /// linear equation, since the projection is a ratio of linear functions. Between two
    /// crossings the four texels of its bilinear lookup are fixed, and
    /// [`ShadowMap::breakpoints`] finds their occluded runs exactly. Visibility taken between the
    /// cuts is then exact but for the bilinear weights, which move with the point. Returns
    /// false, adding nothing, when the path crosses more than [`MAX_RECEIVER_SAMPLES`] grid lines
    /// or leaves the light's view.
    pub fn traced_breakpoints(&self, receiver: &Receiver, out: &mut Vec<f64>) -> bool {
        let Receiver {
            path: [p0, p1],
            span: [t0, t1],
            ..
        } = *receiver;
        let (Some((a, _)), Some((b, _))) = (self.locate(p0), self.locate(p1)) else {
            return false;
        };
        let lines = (a.x.floor() - b.x.floor()).abs() + (a.y.floor() - b.y.floor()).abs();
        if !(lines <= MAX_RECEIVER_SAMPLES as f64) {
            return false;
        }
        let camera = &self.occluders.camera;
        let (q0, q1) = (
            camera.view.transform_point3(p0),
            camera.view.transform_point3(p1),
        );
        let dq = q1 - q0;
        let f = camera.focal_px;
        // Texel coordinate X = W/2 − ½ + f·x/(−z) and Y = H/2 − ½ − f·y/(−z) reach k where
        // (W/2 − ½ − k)(−z) + f·x = 0, and (H/2 − ½ − k)(−z) − f·y = 0: linear in u ∈ [0, 1].
        let mut cuts = vec![t0, t1];
        let mut cross = |from: f64, to: f64, offset: f64, along: fn(DVec3) -> f64, sign: f64| {
            let (lo, hi) = (from.min(to), from.max(to));
            let mut k = lo.floor() + 1.0;
            while k <= hi {
                let c = offset - k;
                let (base, slope) = (
                    c * -q0.z + sign * f * along(q0),
                    c * -dq.z + sign * f * along(dq),
                );
                if slope != 0.0 {
                    let u = -base / slope;
                    if u > 0.0 && u < 1.0 {
                        cuts.push(t0 + u * (t1 - t0));
                    }
                }
                k += 1.0;
            }
        };
        let (half_w, half_h) = (
            0.5 * f64::from(camera.width) - 0.5,
            0.5 * f64::from(camera.height) - 0.5,
        );
        cross(a.x, b.x, half_w, |q| q.x, 1.0);
        cross(a.y, b.y, half_h, |q| q.y, -1.0);
        cuts.sort_unstable_by(f64::total_cmp);
        let point = |t: f64| p0.lerp(p1, (t - t0) / (t1 - t0));
        for pair in cuts.windows(2) {
            let [s0, s1] = [pair[0], pair[1]];
            if s1 > s0 {
                let part = Receiver {
                    path: [point(s0), point(s1)],
                    normals: [s0, s1].map(|t| receiver.normal_at(t)),
                    span: [s0, s1],
                    ..*receiver
                };
                self.breakpoints(&part, out);
            }
        }
        out.extend(cuts.iter().copied().filter(|&t| t > t0 && t < t1));
        true
    }

    /// For a `receiver` moving within one texel footprint, every time in its span at which its
    /// visibility changes (appended to `out`): in each of its four texels, the ends of the runs
    /// of time during which some other triangle's occluder lies nearer than the receiver's depth
    /// limit. Within an occluder piece both depths are linear in time, so the part of it that
    /// occludes is one interval, found exactly; touching parts merge into runs, so a long train
    /// of occluder pieces (a surface turning over the texel) costs two cuts, not one per piece.
    pub fn breakpoints(&self, receiver: &Receiver, out: &mut Vec<f64>) {
        let Receiver {
            path: [p0, p1],
            span: [t0, t1],
            ..
        } = *receiver;
        // A still receiver is one point: located once.
        let start = self.locate(p0);
        let (end, middle) = if p0 == p1 {
            (start, start)
        } else {
            (self.locate(p1), self.locate(p0.lerp(p1, 0.5)))
        };
        let (Some((_, d0)), Some((_, d1)), Some((middle, _))) = (start, end, middle) else {
            return;
        };
        // The bias at each time from the normal at that time, as a lookup then places the
        // point ([`ShadowMap::visibility`]): a turning receiver's bias changes within the span.
        let limit = |t: f64| {
            let depth = d0 + (d1 - d0) * (t - t0) / (t1 - t0).max(f64::MIN_POSITIVE);
            let (normal, p) = receiver.between(t);
            let slope = self.bias_slope(p, normal.normalize_or_zero());
            depth - self.bias(depth, slope)
        };
        // The footprint of the middle: a traced receiver's piece starts on a grid line.
        for ((x, y), _) in Self::footprint(middle) {
            self.occluded_runs(x, y, receiver.span, receiver.own, limit, |run| {
                out.extend(run.into_iter().filter(|&t| t > t0 && t < t1));
            });
        }
    }

    /// The shutter-weighted mean share of light reaching a still receiver on triangle `own`,
    /// placed by [`ShadowMap::place`], over `span`: bilinear over its four texels, each lit
    /// except during its runs of nearer occluders ([`ShadowMap::occluded_runs`], exact). Light
    /// is linear in visibility, so this mean times a light's irradiance is the light's mean;
    /// no time needs to be cut or sampled.
    #[must_use]
    pub fn mean_visibility(
        &self,
        (at, limit): (DVec2, f64),
        span: [f64; 2],
        own: (u32, u32),
        shutter: &Shutter,
    ) -> f64 {
        let mass = shutter.mass(span[0], span[1]);
        if !(mass > 0.0) {
            return self.visibility_placed((at, limit), span[0], own);
        }
        Self::footprint(at)
            .iter()
            .filter(|(_, w)| *w > 0.0)
            .map(|&((x, y), w)| {
                let mut occluded = 0.0;
                self.occluded_runs(
                    x,
                    y,
                    span,
                    own,
                    |_| limit,
                    |[r0, r1]| {
                        occluded += shutter.mass(r0, r1);
                    },
                );
                w * (1.0 - (occluded / mass).min(1.0))
            })
            .sum()
    }

    /// The runs of time within `span`, in order and apart, during which texel (x, y) holds an
    /// occluder of another triangle than `own` nearer than `limit` at that time (the receiver's
    /// depth less its bias, linear in time), each handed to `run`. Within an occluder piece both
    /// depths are linear in time, so the part of it that occludes is one interval, found
    /// exactly; touching parts merge, so a long train of occluder pieces (a surface turning over
    /// the texel) is one run.
    fn occluded_runs(
        &self,
        x: i64,
        y: i64,
        span: [f64; 2],
        own: (u32, u32),
        limit: impl Fn(f64) -> f64,
        mut run: impl FnMut([f64; 2]),
    ) {
        let mut open: Option<[f64; 2]> = None;
        for (o, [a0, a1]) in self.others_during(x, y, span, own) {
            // The part of [a0, a1] where the occluder is nearer than the limit.
            let g = |t: f64| o.piece.depth_at(t) - limit(t);
            let (g0, g1) = (g(a0), g(a1));
            // Where the gap changes sign: exact for a linear limit, refined where a turning
            // receiver's bias bends it.
            let cross = || crate::math::sign_change(g, [a0, a1], [g0, g1]);
            let part = match (g0 < 0.0, g1 < 0.0) {
                (true, true) => Some([a0, a1]),
                (true, false) => Some([a0, cross()]),
                (false, true) => Some([cross(), a1]),
                (false, false) => None,
            };
            let Some([s0, s1]) = part else {
                continue;
            };
            open = match open {
                Some([r0, r1]) if s0 <= r1 => Some([r0, r1.max(s1)]),
                Some(done) => {
                    run(done);
                    Some([s0, s1])
                }
                None => Some([s0, s1]),
            };
        }
        if let Some(done) = open {
            run(done);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ShutterShape;

    /// A 16 × 16 map looking down −z from the origin, with one occluder piece at depth 1 in
    /// texel (8, 8) while t is in [0.6, 0.8], belonging to triangle (1, 0).
    fn map_with_one_occluder() -> ShadowMap {
        let camera = Camera::new(DVec3::ZERO, -DVec3::Z, DVec3::Y, 90.0, 16, 16)
            .and_then(|c| c.with_spatial_samples(1))
            .unwrap();
        let occluder = Occluder {
            piece: Interval {
                t: [0.6, 0.8],
                depth: [1.0, 1.0],
                item: 0,
                bends: false,
            },
            id: (1, 0),
        };
        let at = 8 * 16 + 8;
        let starts = (0..=256u32).map(|i| u32::from(i > at)).collect();
        ShadowMap::new(Occluders {
            camera,
            tiles: vec![(starts, vec![occluder])],
            left_empty: 0,
            left_out: 0,
            lists: ShadowLists::default(),
        })
        .summarised()
    }

    /// The world point that falls on texel coordinates (x, y) at depth 5.
    fn point(map: &ShadowMap, x: f64, y: f64) -> DVec3 {
        map.occluders.camera.ray(x + 0.5, y + 0.5) * 5.0
    }

    fn receiver(path: [DVec3; 2], span: [f64; 2], own: (u32, u32)) -> Receiver {
        Receiver {
            path,
            normals: [DVec3::Z; 2],
            span,
            own,
        }
    }

    #[test]
    fn a_still_receiver_is_surely_lit_only_when_no_other_triangle_occludes_it_in_its_span() {
        let map = map_with_one_occluder();
        let p = point(&map, 8.3, 8.3);
        assert_eq!(
            map.locate(p).map(|(at, _)| at.floor()),
            Some(DVec2::new(8.0, 8.0))
        );
        assert!(!map.surely_lit(&receiver([p, p], [0.0, 1.0], (0, 0))));
        assert!(!map.surely_lit(&receiver([p, p], [0.7, 0.75], (0, 0))));
        // Before the occluder arrives, or shadowed only by its own triangle.
        assert!(map.surely_lit(&receiver([p, p], [0.0, 0.5], (0, 0))));
        assert!(map.surely_lit(&receiver([p, p], [0.0, 1.0], (1, 0))));
        // Bilinear lookups from texel (6.5, 6.5) read up to texel 7: not 8.
        let beside = point(&map, 6.5, 6.5);
        assert!(map.surely_lit(&receiver([beside, beside], [0.0, 1.0], (0, 0))));
        let next = point(&map, 7.5, 7.5);
        assert!(!map.surely_lit(&receiver([next, next], [0.0, 1.0], (0, 0))));
    }

    #[test]
    fn a_hull_holds_casters_only_where_a_lookup_within_it_reads_their_occluders() {
        // A 32 × 32 map of four tiles, the occluder in texel (8, 8) of the first.
        let camera = Camera::new(DVec3::ZERO, -DVec3::Z, DVec3::Y, 90.0, 32, 32)
            .and_then(|c| c.with_spatial_samples(1))
            .unwrap();
        let one = map_with_one_occluder();
        let mut tiles = vec![(Vec::new(), Vec::new()); 4];
        tiles[0] = one.occluders.tiles[0].clone();
        let map = ShadowMap::new(Occluders {
            camera,
            tiles,
            left_empty: 3,
            left_out: 3,
            lists: ShadowLists::default(),
        })
        .summarised();
        // The eight corners of a box of texels [x0, x1] × [y0, y1] between depths 4 and 6.
        let hull = |[x0, y0, x1, y1]: [f64; 4]| -> Vec<DVec3> {
            let camera = &map.occluders.camera;
            [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
                .iter()
                .flat_map(|&(x, y)| [4.0, 6.0].map(|z| camera.ray(x + 0.5, y + 0.5) * z))
                .collect()
        };
        // Within the other tiles, or reaching the first only past its last texel.
        for texels in [
            [20.0, 20.0, 28.0, 28.0],
            [16.2, 2.0, 30.0, 14.0],
            [2.0, 16.1, 14.0, 30.0],
        ] {
            let corners = hull(texels);
            let casters = map.casters_around(&corners).unwrap();
            assert!(casters.none_but(NO_TRIANGLE), "{texels:?}");
            // Every point of the hull is then lit: its lookups read no occluder.
            for k in 0..=20 {
                let u = f64::from(k) / 20.0;
                let p = corners[0]
                    .lerp(corners[7], u)
                    .lerp(corners[(k % 8) as usize], 0.3);
                assert!(map.surely_lit(&receiver([p, p], [0.0, 1.0], (0, 0))));
            }
        }
        // A lookup at x in [15, 16) reads texel 16 and texel 15 of the first tile: the
        // occluder's triangle (1, 0) is there, and only its own receivers are lit for sure.
        for texels in [[15.5, 2.0, 30.0, 14.0], [2.0, 2.0, 14.0, 14.0]] {
            let casters = map.casters_around(&hull(texels)).unwrap();
            assert!(!casters.none_but(NO_TRIANGLE), "{texels:?}");
            assert!(!casters.none_but((0, 0)), "{texels:?}");
            assert!(casters.none_but((1, 0)), "{texels:?}");
        }
        // A corner behind the light: nothing is known.
        let mut behind = hull([20.0, 20.0, 28.0, 28.0]);
        behind[0].z = 1.0;
        assert!(map.casters_around(&behind).is_none());
        // A map of an instant, summarised by tile alone, finds the same casters in every hull,
        // and without texel records says of no receiver that it is lit for sure.
        let by_tile = ShadowMap::new(Occluders {
            camera: map.occluders.camera.clone(),
            tiles: map.occluders.tiles.clone(),
            left_empty: 3,
            left_out: 3,
            lists: ShadowLists::default(),
        })
        .summarised_by_tile();
        let ids = [NO_TRIANGLE, (0, 0), (1, 0)];
        for texels in [
            [20.0, 20.0, 28.0, 28.0],
            [16.2, 2.0, 30.0, 14.0],
            [2.0, 16.1, 14.0, 30.0],
            [15.5, 2.0, 30.0, 14.0],
            [2.0, 2.0, 14.0, 14.0],
        ] {
            let seen = |map: &ShadowMap| {
                let casters = map.casters_around(&hull(texels)).unwrap();
                ids.map(|id| casters.none_but(id))
            };
            assert_eq!(seen(&by_tile), seen(&map), "{texels:?}");
        }
        let beside = point(&by_tile, 20.5, 20.5);
        assert!(!by_tile.surely_lit(&receiver([beside, beside], [0.0, 1.0], (0, 0))));
        assert!(map.surely_lit(&receiver([beside, beside], [0.0, 1.0], (0, 0))));
    }

    #[test]
    fn a_moving_receiver_is_checked_along_its_whole_path() {
        let map = map_with_one_occluder();
        // Along a row, along a column and diagonally across the occluded texel.
        for (from, to) in [
            ((1.2, 8.4), (14.6, 8.4)),
            ((8.4, 14.6), (8.4, 1.2)),
            ((2.3, 2.1), (13.9, 14.2)),
        ] {
            let path = [point(&map, from.0, from.1), point(&map, to.0, to.1)];
            assert!(
                !map.surely_lit(&receiver(path, [0.0, 1.0], (0, 0))),
                "{from:?}"
            );
        }
        // A path along row 3 reads rows 3 and 4 only.
        let path = [point(&map, 1.2, 3.4), point(&map, 14.6, 3.4)];
        assert!(map.surely_lit(&receiver(path, [0.0, 1.0], (0, 0))));
    }

    /// A still receiver's mean light in closed form against the shutter-weighted visibility of
    /// its instants: the occluder covers texel (8, 8) during [0.6, 0.8].
    #[test]
    fn a_still_receivers_mean_visibility_is_its_lit_share_of_the_shutter() {
        let map = map_with_one_occluder();
        let mean = |x: f64, span: [f64; 2], own: (u32, u32), shutter: &Shutter| {
            let p = point(&map, x, 8.0);
            let placed = map.place(p, DVec3::Z).unwrap();
            map.mean_visibility(placed, span, own, shutter)
        };
        let open = Shutter::new(0.0, 1.0, ShutterShape::Box).unwrap();
        // On the texel's centre: lit but for a fifth of the exposure; a quarter texel aside, a
        // quarter of the lookup reads its lit neighbour.
        assert!((mean(8.0, [0.0, 1.0], (0, 0), &open) - 0.8).abs() < 1e-12);
        assert!((mean(8.25, [0.0, 1.0], (0, 0), &open) - 0.85).abs() < 1e-12);
        // Over part of the exposure, by its own triangle, and at an instant.
        assert!((mean(8.0, [0.5, 0.7], (0, 0), &open) - 0.5).abs() < 1e-12);
        assert_eq!(mean(8.0, [0.0, 1.0], (1, 0), &open), 1.0);
        assert_eq!(mean(8.0, [0.7, 0.7], (0, 0), &open), 0.0);
        // Under a tent shutter and a Gaussian one, against the shutter-weighted mean of
        // visibility at 20,000 instants.
        for shape in [ShutterShape::Tent, ShutterShape::Gaussian] {
            let shutter = Shutter::new(0.0, 1.0, shape).unwrap();
            let placed = map.place(point(&map, 8.25, 8.0), DVec3::Z).unwrap();
            let n = 20_000;
            let (mut sum, mut weight) = (0.0, 0.0);
            for i in 0..n {
                let t = (f64::from(i) + 0.5) / f64::from(n);
                let w = shutter.weight(t);
                sum += w * map.visibility_placed(placed, t, (0, 0));
                weight += w;
            }
            let closed = mean(8.25, [0.0, 1.0], (0, 0), &shutter);
            assert!((closed - sum / weight).abs() < 1e-4, "{shape:?}: {closed}");
            assert!(closed > 0.75 && closed < 1.0, "{shape:?}: {closed}");
        }
    }

    #[test]
    fn lit_for_sure_never_passes_an_occluder_nearer_than_the_limit() {
        // An occluder at depth 1 + 10⁻⁷ in texel (8, 8) during [0.6, 0.8], whose nearest f32
        // is 1.00000012: a receiver there whose limit lies between is shadowed at t = 0.7, so it
        // must not pass as lit throughout.
        let mut map = map_with_one_occluder();
        let depth = 1.0 + 1e-7;
        map.occluders.tiles[0].1[0].piece.depth = [depth, depth];
        let map = ShadowMap::new(map.occluders).summarised();
        let placed = (DVec2::new(8.0, 8.0), 1.0 + 1.1e-7);
        assert_eq!(map.visibility_placed(placed, 0.7, (0, 0)), 0.0);
        assert!(!map.surely_lit_between(placed, placed, [0.0, 1.0], (0, 0)));
    }

    #[test]
    fn the_cap_keeps_the_most_pieces_per_texel_that_fit_the_budget() {
        let counts = [0, 1, 3, 5, 10];
        // Σ min(count, cap): 1 + 3 + 3 + 3 = 10 at cap 3, 1 + 3 + 4 + 4 = 12 at cap 4.
        assert_eq!(cap_within(counts.into_iter(), 10), 3);
        assert_eq!(cap_within(counts.into_iter(), 11), 3);
        assert_eq!(cap_within(counts.into_iter(), 12), 4);
        assert_eq!(cap_within(counts.into_iter(), 19), 10);
        // Not even one each fits: one each all the same.
        assert_eq!(cap_within(counts.into_iter(), 2), 1);
        assert_eq!(cap_within(std::iter::empty(), 5), 1);
    }

    #[test]
    fn a_tiles_nearest_occluders_are_those_of_all_its_texels_together() {
        // Texels' lists over three triangles at assorted depths, merged in every split: each
        // triangle's view of the others (`except`) matches that of the lists joined.
        let occluder = |depth: f64, id: u32| Occluder {
            piece: Interval {
                t: [0.0, 1.0],
                depth: [depth, depth + 0.5],
                item: 0,
                bends: false,
            },
            id: (id, 0),
        };
        let all = [
            occluder(3.0, 0),
            occluder(1.0, 1),
            occluder(2.0, 0),
            occluder(0.5, 2),
            occluder(4.0, 1),
            occluder(0.7, 2),
        ];
        let joined = Nearest::of(&all);
        for split in 0..=all.len() {
            let (a, b) = all.split_at(split);
            let merged = Nearest::of(a).merge(Nearest::of(b));
            for own in [(0, 0), (1, 0), (2, 0), (3, 0)] {
                assert_eq!(merged.except(own), joined.except(own), "{split} {own:?}");
            }
        }
        assert_eq!(joined.except((2, 0)), 1.0);
        assert_eq!(joined.except((0, 0)), 0.5);
    }
}
