//! Motion hints (Guan & Mueller 2004): the object drawn sharp, as by a flash, over a trail that
//! tells where it came from. Two layers from the shared pipeline (§3.1, §4): the object layer,
//! static EWA splatting at the flash; and the trail layer, motion ellipses made by the same code
//! as `blur`'s over the trail's time window, so that a trail spanning the whole exposure is
//! exactly `blur`'s image. The [`crate::style`] decides the rest: window, stroboscopic copies,
//! colour ramps, textures, N·L and N·V modulation, blending, how the layers meet, and speed
//! lines. Beyond the paper (its §6 future work): trails bend along rotational paths, and points
//! hidden at the flash emit none. Details: docs/math.md, "Hint trails".

mod speed_lines;

use super::blur::TIME_BINS;
use super::{MethodStats, Render, Stats};
use crate::framebuffer::Framebuffer;
use crate::plan::{ObjectMotion, Plan};
use crate::project::{
    middle_instants, motion_ellipse, per_surfel, static_footprint, view_surfel, Cull, Culled,
    Instant, SubSegmentView, SurfelView,
};
use crate::raster::{rasterize, Footprint, Layer, RasterStats, ScreenSplat, Target, TimeBins};
use crate::scene::shutter::{Shutter, ShutterShape};
use crate::scene::{Object, Scene};
use crate::style::{
    ramp_colour, Blend, Composite, Emitters, RampBy, Select, SpeedLines, Style, Trail, TrailColour,
};
use crate::surfels::Surfel;
use glam::DVec2;
use rayon::prelude::*;
use speed_lines::{LineLook, LineWork, SpeedLine};

/// A trail copy's own time axis: its slot mapped onto [0, 1], uniformly weighted. A hint's trail
/// is drawn, not exposed, so the scene's shutter shape does not weight it.
const COPY_TIME: Shutter = Shutter {
    open: 0.0,
    close: 1.0,
    shape: ShutterShape::Box,
};

/// When the trail's colour or opacity changes along it, its pieces are at most this share of the
/// trail window long, so that the change shows as a gradient rather than steps.
const GRADIENT_PIECES: f64 = 16.0;

/// Speed lines follow their point's path sampled at least this many times.
const LINE_SAMPLES: usize = 32;

/// A visible point counts as on the silhouette when the cosine between its normal and the view
/// direction is below this (the normal more than about 70° from it: within about 20° of edge-on).
const SILHOUETTE_COSINE: f64 = 0.35;

/// What the hint renderer did beyond the shared counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HintStats {
    /// Surfels of moving objects that emit a trail.
    pub emitting: usize,
    /// Surfels that would emit a trail but are left out by the trail's density.
    pub sparse: usize,
    /// Surfels that emit no trail because they face away from the camera at flash time.
    pub back_facing: usize,
    /// Surfels that emit no trail because they are hidden in the object image at flash time.
    pub hidden: usize,
    /// Trail splats made.
    pub trail_splats: usize,
    /// Trail sub-segments left out, by reason.
    pub trail_culled: Culled,
    /// Speed lines made, drawn or not.
    pub speed_lines: usize,
    /// The speed lines' work against its budget.
    pub line_work: LineWork,
}

impl HintStats {
    /// Human-readable account for `--explain`.
    #[must_use]
    pub fn explain(&self) -> String {
        let c = &self.trail_culled;
        format!(
            "hint: {} surfels emit trails; left out: {} back-facing and {} hidden in the object image at the flash, {} by the trail's density\n\
             \x20 {} trail splats; trail sub-segments left out: {} back-facing throughout, {} off-screen, {} behind the near plane, {} without weight\n\
             \x20 {} speed lines{}\n",
            self.emitting,
            self.back_facing,
            self.hidden,
            self.sparse,
            self.trail_splats,
            c.back_facing,
            c.off_screen,
            c.behind_near,
            c.degenerate,
            self.speed_lines,
            self.line_work_account(),
        )
    }

    /// Where the render departed from its style: speed lines left out or drawn in part when
    /// their budget of pixel tests was spent.
    #[must_use]
    pub fn departures(&self) -> Vec<String> {
        let w = &self.line_work;
        if w.left_out == 0 && !w.cut {
            return Vec::new();
        }
        let drawn = self.speed_lines - w.left_out;
        let part = if w.cut {
            ", the last of them in part"
        } else {
            ""
        };
        vec![format!(
            "{drawn} of {} speed lines drawn{part}: the lines' budget of {} pixel tests was spent \
             (the lines left out are the lowest; fewer, narrower or straighter lines fit)",
            self.speed_lines, w.budget
        )]
    }

    /// The speed lines' pixel tests against their budget, for `--explain`.
    fn line_work_account(&self) -> String {
        let w = &self.line_work;
        if self.speed_lines == 0 {
            return String::new();
        }
        format!(
            ", {} pixels tested against a segment and {} mask pixels of their budget of {} tests{}",
            w.tests,
            w.mask_pixels,
            w.budget,
            if w.left_out > 0 || w.cut {
                format!(
                    " ({} left out, {} drawn in part)",
                    w.left_out,
                    usize::from(w.cut)
                )
            } else {
                String::new()
            }
        )
    }
}

/// A time interval [start, end] of the frame.
type Window = [f64; 2];

/// What one trail splat needs to know beyond its two views.
struct Piece {
    /// Real times of its ends.
    real: Window,
    /// Times of its ends on its copy's own axis.
    local: Window,
    /// Indices of its ends' instants in the copy's list.
    ends: [usize; 2],
    chained: bool,
}

pub(super) fn render(scene: &Scene, plan: &Plan, style: &Style) -> Render {
    let camera = &scene.camera;
    let (width, height) = (camera.width, camera.height);
    let shutter = &scene.shutter;
    let flash = flash_time(shutter, style);
    let background = style.background.unwrap_or(scene.background);
    let mut stats = Stats::default();
    let mut hint = HintStats::default();

    // The object layer at the flash, which also tells which points are visible.
    let mut stills = 0;
    let flash_views: Vec<Vec<Option<SurfelView>>> = scene
        .objects
        .iter()
        .map(|object| views_at(scene, (object, object.surfels()), flash))
        .collect();
    // Footprints of still objects, then of moving ones: `object.draw`, `object.colour` and
    // `object.opacity` are the moving ones' (all of them hide points).
    let mut object_footprints = Vec::new();
    for still in [true, false] {
        for (views, object_plan) in flash_views.iter().zip(&plan.objects) {
            if (object_plan.motion == ObjectMotion::Still) != still {
                continue;
            }
            for view in views {
                let colour = if still { None } else { style.object.colour };
                let result = match view {
                    Some(v) => static_footprint(camera, &recoloured(v, colour)),
                    None => Err(Cull::BehindNear),
                };
                stats.culled.keep(result, &mut object_footprints);
            }
        }
        if still {
            stills = object_footprints.len();
        }
    }
    let target = Target::new(width, height);
    let (object_layer, raster) = rasterize(&object_footprints, &target, &TimeBins::INSTANT);
    stats.add_raster(&raster);

    let trail = &style.trail;
    let window = trail_window(shutter, style);
    let copies = copy_windows(window, trail.copies, trail.duty);
    let gradient = trail.fade < 1.0
        || matches!(
            trail.colour,
            TrailColour::Ramp {
                by: RampBy::Time,
                ..
            }
        );
    let fineness = Fineness {
        whole: window[1] - window[0],
        pieces: if gradient { GRADIENT_PIECES } else { 1.0 },
    };
    let fastest = plan.longest_path_px();

    let mut trail_footprints = Vec::new();
    let mut starts = Vec::new();
    let line_window = before_flash(
        shutter,
        flash,
        style.speed_lines.offset,
        style.speed_lines.length,
    );
    for (index, ((object, object_plan), views)) in scene
        .objects
        .iter()
        .zip(&plan.objects)
        .zip(&flash_views)
        .enumerate()
    {
        let ObjectMotion::Moving { segments, .. } = &object_plan.motion else {
            continue;
        };
        let seen = seen_at_flash(views, &object_layer);
        let emits = emitters(&seen, trail, &mut hint);
        // The trail is drawn from the plan's surfels: where it merged them, they emit by how
        // they are seen at the flash themselves (the counts and the speed lines keep the
        // object's own surfels).
        let trail_surfels = plan.surfels(index);
        let merged_emits = (object_plan.lod.merged.is_some() && trail.draw).then(|| {
            let views = views_at(scene, (object, trail_surfels), flash);
            let seen = seen_at_flash(&views, &object_layer);
            emitters(&seen, trail, &mut HintStats::default())
        });
        let trail_emits = merged_emits.as_deref().unwrap_or(&emits);
        if trail.draw && window[1] > window[0] {
            let context = TrailContext {
                scene,
                style,
                window,
                fastest_px: fastest,
                exact_streaks: super::draws_exact_streaks(plan.method(), &scene.shutter),
            };
            let before = trail_footprints.len();
            let culled = object_trails(
                &context,
                (object, trail_surfels),
                segments,
                &copies,
                fineness,
                trail_emits,
                &mut trail_footprints,
            );
            hint.trail_splats += trail_footprints.len() - before;
            hint.trail_culled.add(&culled);
        }
        if style.speed_lines.draw && line_window[1] > line_window[0] {
            starts.extend(line_starts(
                scene,
                &style.speed_lines,
                index,
                line_window[1],
                views,
                &seen,
            ));
        }
    }
    let lines: Vec<SpeedLine> = pick_starts(starts, &style.speed_lines)
        .par_iter()
        .filter_map(|start| {
            let ObjectMotion::Moving { segments, .. } = &plan.objects[start.object].motion else {
                return None;
            };
            let object = &scene.objects[start.object];
            speed_line(
                scene,
                &style.speed_lines,
                object,
                segments,
                line_window,
                start.surfel,
            )
        })
        .collect();
    hint.speed_lines = lines.len();
    let look = &style.speed_lines;
    let draw_lines = |image: &mut Framebuffer| {
        let look = LineLook {
            width: look.width,
            taper: look.taper,
            fade: look.fade,
            opacity: look.opacity,
        };
        speed_lines::draw_over(&lines, &look, image)
    };

    // The moving objects are drawn as `object.draw` and `object.opacity` say, the still ones
    // always and opaque: where the two differ, the stills are drawn on their own (the whole layer
    // is dropped first where it is not drawn: one layer less held).
    let opacity = style.object.opacity as f32;
    let drawn_layer = if style.object.draw && opacity >= 1.0 {
        object_layer
    } else {
        let moving_drawn = style.object.draw.then_some(object_layer);
        let (stills, raster) = rasterize(&object_footprints[..stills], &target, &TimeBins::INSTANT);
        stats.add_raster(&raster);
        match moving_drawn {
            Some(layer) => layer.faded_beyond(&stills, opacity),
            None => stills,
        }
    };
    // Each layer is made when it is drawn over the image, and dropped after: the image holds
    // at most the object's layer and one other besides itself.
    let mut image = Framebuffer::filled(width, height, background);
    let mut trail_target = Target {
        texture: trail.texture.as_ref(),
        ..target
    };
    match trail.composite {
        Composite::Under => {
            let (layer, raster) = draw_trails(&trail_footprints, &trail_target, trail);
            stats.add_raster(&raster);
            layer.draw_over(&mut image);
            drop(layer);
            hint.line_work = draw_lines(&mut image);
            drawn_layer.draw_over(&mut image);
        }
        Composite::Merged => {
            hint.line_work = draw_lines(&mut image);
            drawn_layer.draw_over(&mut image);
            trail_target.occluder = Some(&drawn_layer.front_depth);
            let (layer, raster) = draw_trails(&trail_footprints, &trail_target, trail);
            stats.add_raster(&raster);
            layer.draw_over(&mut image);
        }
    }
    stats.method = MethodStats::Hint(hint);
    Render { image, stats }
}

/// Rasterize trail footprints. Alpha-blended trails of whole surfaces are composited in bins of
/// their copies' time, as `blur` does, so that a surface sliding past a pixel covers it for the
/// time it takes. A sparse trail (density below one) is a set of separate strokes rather than a
/// surface: its strokes are composited as layers, each covering by its own weight. Additive trails
/// need no bins.
fn draw_trails(footprints: &[Footprint], target: &Target, trail: &Trail) -> (Layer, RasterStats) {
    if trail.blend == Blend::Alpha && trail.density >= 1.0 {
        rasterize(footprints, target, &TimeBins::<TIME_BINS>::over(&COPY_TIME))
    } else {
        rasterize(footprints, target, &TimeBins::INSTANT)
    }
}

/// The instant of the flash, when the object is drawn sharp.
fn flash_time(shutter: &Shutter, style: &Style) -> f64 {
    shutter.open + style.object.flash * shutter.duration()
}

/// The interval `style`'s trail is drawn over.
pub(crate) fn trail_window(shutter: &Shutter, style: &Style) -> Window {
    let trail = &style.trail;
    before_flash(
        shutter,
        flash_time(shutter, style),
        trail.offset,
        trail.length,
    )
}

/// Every one of `surfels` moving with `object` seen at time `t`.
fn views_at(
    scene: &Scene,
    (object, surfels): (&Object, &[Surfel]),
    t: f64,
) -> Vec<Option<SurfelView>> {
    let instant = Instant::new(&scene.camera, &object.motion.pose_at(t));
    surfels
        .par_iter()
        .map(|s| view_surfel(&scene.camera, &instant, &scene.lighting, s))
        .collect()
}

/// `view` with its colour replaced by `colour`, when given.
fn recoloured(view: &SurfelView, colour: Option<[f32; 3]>) -> SurfelView {
    let mut view = *view;
    if let Some(c) = colour {
        view.splat.colour = c;
    }
    view
}

/// Whether a splat lies behind the visible surface of `layer` at the pixel under its centre.
/// Off-screen centres count as visible: there is nothing to test them against.
fn is_hidden(splat: &ScreenSplat, layer: &Layer) -> bool {
    let (x, y) = (splat.center.x.floor(), splat.center.y.floor());
    if !(x >= 0.0 && y >= 0.0 && x < f64::from(layer.width) && y < f64::from(layer.height)) {
        return false;
    }
    let front = layer.front_depth[y as usize * layer.width as usize + x as usize];
    let offset = DVec2::new(x + 0.5, y + 0.5) - splat.center;
    let depth = splat.depth + splat.depth_gradient.dot(offset);
    depth > f64::from(front) + splat.depth_tolerance
}

/// The window of `length` (a share of the exposure) ending `offset` before the flash, clipped to
/// the exposure; empty (start = end) when nothing of it is left.
fn before_flash(shutter: &Shutter, flash: f64, offset: f64, length: f64) -> Window {
    let duration = shutter.duration();
    let end = (flash - offset * duration).clamp(shutter.open, shutter.close);
    let start = (flash - (offset + length) * duration).clamp(shutter.open, end);
    [start, end]
}

/// `window` cut into `copies` equal slots, each drawn over its last `duty` share, and over at
/// least the last step of time before the slot's end that f64 can tell (a duty too small to move
/// the start by that much is a sharp ghost, not nothing).
fn copy_windows([start, end]: Window, copies: u32, duty: f64) -> Vec<Window> {
    let slot = (end - start) / f64::from(copies);
    (1..=copies)
        .map(|k| {
            let slot_end = start + slot * f64::from(k);
            [(slot_end - slot * duty).min(slot_end.next_down()), slot_end]
        })
        .collect()
}

/// How finely a stretch of time within a window is cut: into pieces no longer than `whole` /
/// `pieces`.
#[derive(Clone, Copy)]
struct Fineness {
    /// The window's length.
    whole: f64,
    /// Pieces of the whole window.
    pieces: f64,
}

impl Fineness {
    /// Pieces of a stretch `length` long within the window: at most [`Fineness::pieces`], however
    /// short the window (a window of a few subnormals has no finite piece length).
    fn of(self, length: f64) -> usize {
        (self.pieces * (length / self.whole))
            .ceil()
            .max(1.0)
            .min(self.pieces) as usize
    }
}

/// Times cutting `window` at the plan's sub-segment ends (so trails bend along arcs as the blur's
/// ellipses do) and each stretch between into pieces as `fineness` says.
fn times_within(segments: &[[f64; 2]], [start, end]: Window, fineness: Fineness) -> Vec<f64> {
    let mut cuts = vec![start];
    cuts.extend(
        segments
            .iter()
            .map(|s| s[1])
            .filter(|&t| t > start && t < end),
    );
    cuts.push(end);
    let mut times = vec![start];
    for pair in cuts.windows(2) {
        let k = fineness.of(pair[1] - pair[0]);
        times.extend((1..=k).map(|i| pair[0] + (pair[1] - pair[0]) * i as f64 / k as f64));
    }
    times
}

/// What every trail splat of one render shares.
struct TrailContext<'a> {
    scene: &'a Scene,
    style: &'a Style,
    /// The whole trail's window, over all copies.
    window: Window,
    /// The fastest screen path in the scene, px per exposure (the speed ramp's default top).
    fastest_px: f64,
    /// Whether pieces are drawn as exact streaks ([`super::draws_exact_streaks`]).
    exact_streaks: bool,
}

/// How a surfel is seen at the flash.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Seen {
    /// Off screen, behind the near plane, or culled.
    Not,
    /// Facing away from the camera.
    BackFacing,
    /// Facing the camera, behind the visible surface of the object image.
    Hidden,
    /// Facing the camera and on the visible surface.
    Visible,
}

/// How each of the surfels whose views at the flash are `views` is seen there.
fn seen_at_flash(views: &[Option<SurfelView>], object_layer: &Layer) -> Vec<Seen> {
    views
        .iter()
        .map(|view| match view {
            None => Seen::Not,
            Some(v) if !(v.facing > 0.0) => Seen::BackFacing,
            Some(v) if is_hidden(&v.splat, object_layer) => Seen::Hidden,
            Some(_) => Seen::Visible,
        })
        .collect()
}

/// Which of the surfels seen at the flash as `seen` emit a trail, thinned to the trail's density
/// (counting those that do and those that do not, and why, into `hint`).
fn emitters(seen: &[Seen], trail: &Trail, hint: &mut HintStats) -> Vec<bool> {
    seen.iter()
        .enumerate()
        .map(|(i, &seen)| {
            let emits = match (trail.emitters, seen) {
                (_, Seen::Not) => false,
                (Emitters::All, _) => true,
                (_, Seen::BackFacing) => {
                    hint.back_facing += 1;
                    false
                }
                (Emitters::Visible, Seen::Hidden) => {
                    hint.hidden += 1;
                    false
                }
                _ => true,
            };
            let sampled = is_sampled(i, trail.density);
            hint.sparse += usize::from(emits && !sampled);
            hint.emitting += usize::from(emits && sampled);
            emits && sampled
        })
        .collect()
}

/// The trail splats over its copy windows of `surfels` moving with `object` (its own, or merged by
/// the level of detail), appended to `out`; returns what was left out.
fn object_trails(
    context: &TrailContext,
    (object, surfels): (&Object, &[Surfel]),
    segments: &[[f64; 2]],
    copies: &[Window],
    fineness: Fineness,
    emits: &[bool],
    out: &mut Vec<Footprint>,
) -> Culled {
    let scene = context.scene;
    let camera = &scene.camera;
    let area_scale = context.style.trail.width * context.style.trail.width;
    let mut times = Vec::new();
    let mut pieces = Vec::new();
    for &copy in copies {
        let copy_times = times_within(segments, copy, fineness);
        let first = times.len();
        let span = copy[1] - copy[0];
        let chained = copy_times.len() > 2;
        for (i, pair) in copy_times.windows(2).enumerate() {
            pieces.push(Piece {
                real: [pair[0], pair[1]],
                local: [(pair[0] - copy[0]) / span, (pair[1] - copy[0]) / span].map(|t| {
                    if t.is_finite() {
                        t.clamp(0.0, 1.0)
                    } else {
                        0.0
                    }
                }),
                ends: [first + i, first + i + 1],
                chained,
            });
        }
        times.extend(copy_times);
    }
    let instants: Vec<Instant> = times
        .iter()
        .map(|&t| Instant::new(camera, &object.motion.pose_at(t)))
        .collect();
    let middles = middle_instants(
        camera,
        &object.motion,
        pieces.iter().map(|piece| piece.real),
    );
    per_surfel(surfels.len(), out, |i, kept, culled| {
        if !emits[i] {
            return;
        }
        let surfel = &surfels[i];
        let views: Vec<Option<SurfelView>> = instants
            .iter()
            .map(|instant| {
                let mut view = view_surfel(camera, instant, &scene.lighting, surfel)?;
                view.splat.covariance = view.splat.covariance.scaled(area_scale);
                view.splat.weight *= area_scale;
                Some(view)
            })
            .collect();
        for (piece, middle) in pieces.iter().zip(&middles) {
            let [ia, ib] = piece.ends;
            let result = match (&views[ia], &views[ib]) {
                (Some(a), Some(b)) => {
                    let [v0, v1] = piece.local;
                    let seen = SubSegmentView {
                        start: a,
                        middle: middle.screen_point(camera, surfel.position),
                        end: b,
                    };
                    motion_ellipse(
                        &COPY_TIME,
                        &seen,
                        piece.local,
                        &COPY_TIME.moments(v0, v1),
                        piece.chained,
                        context.exact_streaks,
                    )
                    .map(|ellipse| {
                        let normals = [&instants[ia], &instants[ib]]
                            .map(|instant| instant.world_normal(surfel.normal));
                        let position = instants[ia].world_point(surfel.position);
                        styled(context, ellipse, [a, b], normals, position, piece)
                    })
                    .and_then(|e| {
                        let mut footprint = e
                            .footprint(camera.width, camera.height)
                            .map_err(Cull::Raster)?;
                        footprint.weigh_by_pixel_samples(context.style.trail.texture.as_ref());
                        Ok(footprint)
                    })
                }
                _ => Err(Cull::BehindNear),
            };
            culled.keep(result, kept);
        }
    })
}

/// A motion ellipse of a piece, whose ends are seen as `a` and `b` with world normals `normals`
/// (and the surfel at world `position` at its start), dressed as a trail splat: colour from the style's source, weight scaled by intensity, fade,
/// N·L and N·V (Guan & Mueller §4), the style's texture and blending.
fn styled(
    context: &TrailContext,
    mut ellipse: ScreenSplat,
    [a, b]: [&SurfelView; 2],
    normals: [glam::DVec3; 2],
    position: glam::DVec3,
    piece: &Piece,
) -> ScreenSplat {
    let (scene, trail, fastest_px) = (context.scene, &context.style.trail, context.fastest_px);
    let [start, end] = context.window;
    let duration = scene.shutter.duration();
    // Where along the trail the piece lies: 0 at its oldest end, 1 at its newest.
    let along = if end > start {
        (0.5 * (piece.real[0] + piece.real[1]) - start) / (end - start)
    } else {
        1.0
    };
    if let TrailColour::Ramp {
        stops,
        by,
        speed_range,
    } = &trail.colour
    {
        let u = match by {
            RampBy::Time => along,
            RampBy::Speed => {
                let [slow, fast] = speed_range.unwrap_or([0.0, fastest_px]);
                let exposures = (piece.real[1] - piece.real[0]) / duration;
                let speed = a.splat.center.distance(b.splat.center) / exposures;
                (speed - slow) / (fast - slow)
            }
        };
        ellipse.colour = ramp_colour(stops, u);
        ellipse.colour_change = 0.0;
    }
    let mut scale = trail.intensity * (trail.fade + (1.0 - trail.fade) * along) / trail.density;
    let lighting = &scene.lighting;
    if trail.modulate_light && (!lighting.lights.is_empty() || !lighting.spots.is_empty()) {
        let normal = (normals[0] + normals[1]).normalize_or_zero();
        scale *= lighting.direct(normal, position).min(1.0);
    }
    if trail.modulate_view {
        scale *= (0.5 * (a.facing + b.facing)).max(0.0);
    }
    ellipse.weight *= scale;
    ellipse.profile = trail.profile;
    ellipse.additive = trail.blend == Blend::Add;
    ellipse
}

/// Where a speed line could start: the newest end of a point's path on screen.
struct LineStart {
    end: DVec2,
    object: usize,
    surfel: usize,
}

/// The newest ends, at time `end_time`, of the paths of the points of object `object` visible at
/// the flash (`seen`) that the style selects by how they are seen there (`views`): whatever the
/// trail's emitters and density, which are the trail's own.
fn line_starts(
    scene: &Scene,
    look: &SpeedLines,
    object: usize,
    end_time: f64,
    views: &[Option<SurfelView>],
    seen: &[Seen],
) -> Vec<LineStart> {
    let surfels = scene.objects[object].surfels();
    let motion = &scene.objects[object].motion;
    let instant = Instant::new(&scene.camera, &motion.pose_at(end_time));
    (0..surfels.len())
        .into_par_iter()
        .filter(|&i| {
            seen[i] == Seen::Visible
                && views[i].is_some_and(|v| match look.select {
                    Select::Silhouette => v.facing < SILHOUETTE_COSINE,
                    Select::Sample => true,
                })
        })
        .filter_map(|i| {
            let view = view_surfel(&scene.camera, &instant, &scene.lighting, &surfels[i])?;
            Some(LineStart {
                end: view.splat.center,
                object,
                surfel: i,
            })
        })
        .collect()
}

/// At most `look.count` starts at least `look.spacing` px apart, picked in an order that is
/// scattered but fixed, so that the same scene always gets the same lines.
fn pick_starts(mut starts: Vec<LineStart>, look: &SpeedLines) -> Vec<LineStart> {
    starts.sort_by_cached_key(|s| scatter(s.end.x.to_bits() ^ s.end.y.to_bits().rotate_left(32)));
    let cell = look.spacing.max(1.0);
    let mut taken: std::collections::HashMap<(i64, i64), Vec<DVec2>> =
        std::collections::HashMap::new();
    let mut picked = Vec::new();
    for start in starts {
        if picked.len() >= look.count as usize {
            break;
        }
        let end = start.end;
        let (cx, cy) = ((end.x / cell).floor() as i64, (end.y / cell).floor() as i64);
        // Saturating: an end far off screen (a point just past a tiny near plane) lies in the
        // last cell, where `+ 1` overflowed.
        let crowded = (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                taken
                    .get(&(cx.saturating_add(dx), cy.saturating_add(dy)))
                    .is_some_and(|ends| ends.iter().any(|e| e.distance(end) < look.spacing))
            })
        });
        if !crowded {
            taken.entry((cx, cy)).or_default().push(end);
            picked.push(start);
        }
    }
    picked
}

/// The speed line of one point: its projected path over `window`, oldest first, sampled at the
/// plan's sub-segment ends and at least [`LINE_SAMPLES`] times. Where the point is behind the
/// near plane the line stops: it keeps the part next to the object.
fn speed_line(
    scene: &Scene,
    look: &SpeedLines,
    object: &Object,
    segments: &[[f64; 2]],
    window: Window,
    surfel: usize,
) -> Option<SpeedLine> {
    let fineness = Fineness {
        whole: window[1] - window[0],
        pieces: LINE_SAMPLES as f64,
    };
    let times = times_within(segments, window, fineness);
    let mut points: Vec<DVec2> = times
        .iter()
        .rev()
        .map_while(|&t| {
            let instant = Instant::new(&scene.camera, &object.motion.pose_at(t));
            view_surfel(
                &scene.camera,
                &instant,
                &scene.lighting,
                &object.surfels()[surfel],
            )
            .map(|v| v.splat.center)
        })
        .collect();
    points.reverse();
    (points.len() >= 2).then_some(SpeedLine {
        points,
        colour: look.colour,
    })
}

/// Whether point `index` is among a `density` share of points, chosen scattered but fixed.
fn is_sampled(index: usize, density: f64) -> bool {
    density >= 1.0 || (scatter(index as u64) as f64) < density * u64::MAX as f64
}

/// A fixed bijective scramble of 64 bits (SplitMix64's finalizer), for a scattered order.
fn scatter(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Speed lines left out of their budget are a departure, said without `--explain`; lines
    /// within it are not.
    #[test]
    fn speed_lines_left_out_of_their_budget_are_said() {
        let mut stats = HintStats {
            speed_lines: 10,
            ..HintStats::default()
        };
        assert!(stats.departures().is_empty());
        stats.line_work = LineWork {
            tests: 1_000,
            mask_pixels: 10,
            budget: 1_000,
            left_out: 7,
            cut: true,
        };
        let notes = stats.departures();
        assert_eq!(notes.len(), 1);
        assert!(
            notes[0].starts_with("3 of 10 speed lines drawn, the last of them in part"),
            "{notes:?}"
        );
        assert!(stats.explain().contains("(7 left out, 1 drawn in part)"));
    }

    /// A point just in front of a near plane 10⁻²⁰ deep and one unit aside projects some 10²² px
    /// off screen: its cell, 10²¹ spacings out, saturated i64, and the cell beside it overflowed.
    #[test]
    fn starts_beyond_i64_are_picked_without_overflow() {
        let look = Style::default().speed_lines;
        let start = |x: f64| LineStart {
            end: DVec2::new(x, 10.0),
            object: 0,
            surfel: 0,
        };
        let picked = pick_starts(vec![start(1e22), start(-1e22), start(5.0)], &look);
        assert_eq!(picked.len(), 3);
    }
}
