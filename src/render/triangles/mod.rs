//! Triangle objects drawn as triangles: at an instant with a z-buffer per spatial sample
//! (`static` and each `reference` frame), and over the exposure with analytic visibility in time
//! (`analytic`: time-continuous triangles, interval lists and their resolve, deferred shading;
//! Gribel et al. 2010 as summarised in Palmér §2.1–2.2).
//!
//! Each triangle of each object becomes one item per plan sub-segment (one for a still object or
//! an instant), with its corners' camera-space positions at the segment's ends and its pixel
//! bounds. Items are binned into the rasterizer's tiles; each task renders a row of tiles, and
//! in a tile every item visits the spatial samples inside its bounds. A sample's colour is the
//! shutter-weighted integral of what is visible there, shaded at three Gauss–Legendre times per
//! visible piece; a pixel is the mean of its samples (a box filter over an n × n grid).

pub(crate) mod intervals;
pub(crate) mod shadow;
pub(crate) mod tct;

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DAffine3, DMat3, DVec2, DVec3};
use rayon::prelude::*;

use crate::framebuffer::Framebuffer;
use crate::plan::{ObjectMotion, Plan};
use crate::raster::TILE_PX;
use crate::raster::{TileGrid, TileLists};
use crate::render::{Method, Receivers};
use crate::scene::{
    Camera, LightSource, Object, Scene, ShutterShape, TriangleMesh, MIN_SHADOW_MAP,
};
use intervals::{resolve, AsIs, BentDepth, Interval, ResolveScratch};
pub use shadow::MAX_SHADOWED_LIGHTS;
use shadow::{cap_within, Casters, Occluder, Occluders, Receiver, ShadowMap, TEXEL_RECORD_BYTES};
pub use shadow::{ShadowLists, MAX_SHADOW_PIECES};
use tct::{DepthFunction, EdgeFunctions, MovingTriangle, RayDepth, RayHit};

/// Most triangle items (a triangle over one sub-segment, 28 bytes each plus its corners) one
/// render may hold.
pub const MAX_TRIANGLE_ITEMS: usize = 1 << 24;

/// Most intervals one sample's list keeps, an image sample's or a shadow-map texel's (about
/// 40 kB): past it the list is resolved to its visible pieces (Gribel's compression); when that
/// leaves less than [`LIST_SLACK`] free, each triangle's consecutive pieces are joined into one
/// line; and only then are the shortest pieces dropped, down to that slack (all counted). A dense
/// mesh moving fast fills many: the armadillo's 100,000 triangles sliding 90 px at 320 × 240 peak
/// at 554 on one sample, and at a cap of 256 its samples dropped 902,734 pieces, RMSE against the
/// reference 2.7·10⁻³ (1.2·10⁻⁴ with none dropped). In a shadow map a dropped piece is a shadow
/// missing for its time; what the texels keep together is bounded by [`MAX_SHADOW_PIECES`].
pub const MAX_INTERVALS_PER_SAMPLE: usize = 1024;

/// Most intervals a tile's lists keep together (40 MiB, per worker thread): a tile with more
/// samples per pixel than four gives each sample's list less than [`MAX_INTERVALS_PER_SAMPLE`],
/// down to [`MIN_INTERVALS_PER_SAMPLE`] ([`list_cap`]).
pub const MAX_INTERVALS_PER_TILE: usize = 1 << 20;

/// Fewest intervals a sample's list keeps, however many samples its pixel has (at 16 per pixel
/// and more; a tile's lists then take up to 40 MiB at 16 and 160 MiB at 64).
pub const MIN_INTERVALS_PER_SAMPLE: usize = 256;

/// The intervals each sample's list keeps where pixels (or texels) have `samples_per_pixel`.
#[must_use]
pub fn list_cap(samples_per_pixel: usize) -> usize {
    let tile_samples = (TILE_PX * TILE_PX) as usize * samples_per_pixel.max(1);
    (MAX_INTERVALS_PER_TILE / tile_samples)
        .clamp(MIN_INTERVALS_PER_SAMPLE, MAX_INTERVALS_PER_SAMPLE)
}

/// Room a full list's compression leaves, at least, for the intervals that follow, so that a
/// sample compresses at most once per this many of them. A sample with more visible pieces than
/// the cap (a cube zig-zagging over a floor 150 times in one exposure, at a cap of 256) otherwise
/// resolved its whole list again for every interval after the first 256: `analytic` took 21 s at
/// 64 × 48, and over a minute at 250 zig-zags.
pub const LIST_SLACK: usize = list_slack(MAX_INTERVALS_PER_SAMPLE);

/// The room a full list of at most `cap` intervals keeps after compression: a quarter of it.
const fn list_slack(cap: usize) -> usize {
    cap / 4
}

/// Gauss–Legendre nodes and weights on [−1, 1], three points: exact for polynomials of degree 5,
/// enough for a Lambert term turning within one visible piece.
const GAUSS_LEGENDRE_3: [(f64, f64); 3] = [
    (-0.774_596_669_241_483_4, 5.0 / 9.0),
    (0.0, 8.0 / 9.0),
    (0.774_596_669_241_483_4, 5.0 / 9.0),
];

/// Cut `span` where a surface turns towards or away from a light: N·L is quadratic in time
/// (Palmér eq. 2.5) and taken through its values `[f0, fm, f1]` at the span's start, middle and
/// end, N the normal lerped between the span's ends and not made unit (a positive scale keeps
/// the sign, and only then is N·L a polynomial); its roots inside the span are appended to
/// `cuts`. Returns whether the surface faces away all along.
fn cut_where_turning([f0, fm, f1]: [f64; 3], span: [f64; 2], cuts: &mut Vec<f64>) -> bool {
    // The quadratic through the three values, in u = (t − t0)/(t1 − t0).
    let (a, b, c) = (
        2.0 * f0 - 4.0 * fm + 2.0 * f1,
        -3.0 * f0 + 4.0 * fm - f1,
        f0,
    );
    let before = cuts.len();
    // A piece mostly turns without crossing edge-on.
    if !crate::math::keeps_sign(a, b, c, [0.0, 1.0]) {
        let (roots, n) = crate::math::quadratic_roots(a, b, c);
        for &u in &roots[..n] {
            if u > 0.0 && u < 1.0 {
                cuts.push(span[0] + u * (span[1] - span[0]));
            }
        }
    }
    cuts.len() == before && f0.max(fm).max(f1) <= 0.0
}

/// Cut `span` where a point moving straight from `path[0]` to `path[1]` over it crosses the
/// edges of a spot light's cone, between which its reach ramps
/// ([`crate::scene::Spot::cone_crossings`]): a piece crossing the ramp in a small part of its
/// time would otherwise be integrated by three Gauss–Legendre points that miss it.
fn cut_at_cone_edges(source: &LightSource, path: [DVec3; 2], span: [f64; 2], cuts: &mut Vec<f64>) {
    if let LightSource::Spot(spot) = source {
        spot.cone_crossings(path, |u| cuts.push(span[0] + u * (span[1] - span[0])));
    }
}

/// Cut `span` where the shutter's weight keeps three Gauss–Legendre points from integrating it:
/// at the tent's kink, and at a Gaussian's middle and ±1.5σ. Three points weighted by a Gaussian
/// over its whole width put 0.89 of the weight on the middle one (a face turning ±40° under a
/// light in front came out 1.5·10⁻² too bright); over quarters of the exposure, 3·10⁻⁶.
fn cut_for_shutter_weight(shutter: &crate::scene::Shutter, span: [f64; 2], cuts: &mut Vec<f64>) {
    let quarter = |q: f64| shutter.open + q * shutter.duration();
    let (times, count) = match shutter.shape {
        ShutterShape::Box => ([0.0; 3], 0),
        ShutterShape::Tent => ([shutter.middle(), 0.0, 0.0], 1),
        ShutterShape::Gaussian => ([quarter(0.25), shutter.middle(), quarter(0.75)], 3),
    };
    cuts.extend(
        times[..count]
            .iter()
            .filter(|&&t| t > span[0] && t < span[1]),
    );
}

/// Each corner's straight path over the sub-segment [t0, t1], as its positions at the two ends
/// (`positions_at` gives every corner's at a time): where the true path is straight, its chord;
/// where it bends, the least-squares line through it over the sub-segment, found with three
/// Gauss–Legendre points. A chord meets an arc at its ends and misses it by the sagitta M at its
/// middle (RMS 0.73 M over the sub-segment); the fitted line is that chord moved outward by 2M/3,
/// so it lies M/3 inside the arc at the middle and 2M/3 outside it at the ends, RMS 0.30 M: the
/// same sub-segments follow a turn 2.4 times as closely. Consecutive lines then meet only nearly
/// (both move outward alike at a shared end); a jump at one instant has no weight in time.
fn fitted_paths(
    positions_at: impl Fn(f64) -> Vec<DVec3>,
    [t0, t1]: [f64; 2],
) -> (Vec<DVec3>, Vec<DVec3>) {
    let (mut start, mut end) = (positions_at(t0), positions_at(t1));
    let nodes =
        GAUSS_LEGENDRE_3.map(|(x, w)| (x, w, positions_at(t0 + (t1 - t0) * 0.5 * (1.0 + x))));
    for (v, (first, last)) in start.iter_mut().zip(&mut end).enumerate() {
        // The middle node is the path's middle: straight where it is the chord's, to rounding.
        let middle = nodes[1].2[v];
        if (middle - 0.5 * (*first + *last)).length() <= 1e-12 * first.length().max(last.length()) {
            continue;
        }
        // The line mean + slope (u − ½) with u in [0, 1]: mean = ∫p du, slope = 12∫p (u − ½) du,
        // and u − ½ = x/2 at node x of weight w/2.
        let (mut mean, mut slope) = (DVec3::ZERO, DVec3::ZERO);
        for (x, w, positions) in &nodes {
            mean += 0.5 * w * positions[v];
            slope += 3.0 * w * x * positions[v];
        }
        (*first, *last) = (mean - 0.5 * slope, mean + 0.5 * slope);
    }
    (start, end)
}

/// What drawing triangles did, for `--explain`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TriangleStats {
    /// Triangle items drawn (a triangle over one sub-segment, or at one instant).
    pub items: usize,
    /// Items left out because a corner stayed behind the near plane the whole time.
    pub behind_near: usize,
    /// Items left out because a camera-space corner coordinate (or its motion) lies beyond
    /// 10¹⁰⁰ (`tct::MAX_CORNER_COORDINATE`), where the depth's products of three overflow a double.
    pub too_far: usize,
    /// Intervals inserted into sample lists (`analytic`).
    pub intervals: usize,
    /// The longest interval list of one sample.
    pub peak_per_sample: usize,
    /// Times a sample's full list was resolved to its visible pieces to make room.
    pub compressed: usize,
    /// Times a resolved list was still full and each item's pieces were joined into one line.
    pub joined: usize,
    /// Intervals dropped because a list was still full after compression.
    pub dropped: usize,
    /// Samples a triangle item was left out of unsolved: it lies wholly deeper there than a
    /// still triangle covering the sample all along.
    pub hidden_behind_still: usize,
    /// Visible pieces shaded (`analytic`).
    pub pieces: usize,
    /// Runs of visible pieces: a triangle's pieces back to back in time, one per sub-segment it
    /// crosses, shaded together where no shadow changes along them.
    pub runs: usize,
    /// Of those, runs of more than one piece that were shaded as one.
    pub joined_runs: usize,
    /// Of those, pieces whose receiver swept shadow-map texels and was point-sampled for a
    /// shadow that may start or end (the rest are shaded exactly, or lit for sure).
    pub point_sampled: usize,
    /// Spatial samples per pixel.
    pub spatial_samples: u32,
    /// Tiles of the shadow maps (every light's, every frame's).
    pub shadow_tiles: usize,
    /// Of those, tiles left without occluders: every object that reaches them cannot shadow
    /// itself and lies wholly deeper there than every other object.
    pub shadow_tiles_left_empty: usize,
    /// Item × shadow-map tile pairs left out: objects that cannot shadow themselves, wholly
    /// deeper there than every other object.
    pub shadow_items_left_out: usize,
    /// What the shadow maps' texel lists hold and left out.
    pub shadow_lists: ShadowLists,
}

impl TriangleStats {
    /// Human-readable account for `--explain` (empty when no triangle was drawn).
    #[must_use]
    pub fn explain(&self) -> String {
        if self.items == 0 && self.behind_near == 0 && self.too_far == 0 {
            return String::new();
        }
        let mut out = format!(
            "triangles: {} items (triangle × sub-segment or instant), {} spatial samples per pixel; {} left out behind the near plane\n",
            self.items, self.spatial_samples, self.behind_near
        );
        if self.too_far > 0 {
            out.push_str(&format!(
                "  {} items left out too far out for double precision (a camera-space corner beyond {:e} of the eye: scale the scene down)\n",
                self.too_far,
                tct::MAX_CORNER_COORDINATE
            ));
        }
        if self.shadow_tiles > 0 {
            out.push_str(&format!(
                "  shadow maps: {} item × tile pairs left out, and {} of {} tiles left empty (objects that cannot shadow themselves, wholly deeper there than every other object)\n",
                self.shadow_items_left_out, self.shadow_tiles_left_empty, self.shadow_tiles
            ));
            let lists = &self.shadow_lists;
            out.push_str(&format!(
                "  shadow-map texels: {} occluder pieces and {} texel records held ({:.1} MiB), at most {} pieces on one texel; {} texel lists compressed, {} intervals dropped from full ones\n",
                lists.pieces,
                lists.records,
                (lists.pieces * std::mem::size_of::<Occluder>() + lists.records * TEXEL_RECORD_BYTES) as f64 / f64::from(1 << 20),
                lists.peak_per_texel,
                lists.compressed,
                lists.dropped
            ));
            if let Some((asked, drawn)) = lists.coarsened {
                out.push_str(&format!(
                    "  shadow-map budget ({MAX_SHADOW_PIECES} pieces and texel records over a render's maps) spent at {asked}² texels: drawn at {drawn}² (shadows of the same strength, softer edges)\n"
                ));
            }
            if let Some(cap) = lists.cap {
                out.push_str(&format!(
                    "  shadow-map budget spent even at {MIN_SHADOW_MAP}² texels: each texel kept its {cap} longest pieces, {} shorter ones left out (shadows that short are missing)\n",
                    lists.cut
                ));
            }
        }
        if self.intervals > 0 {
            out.push_str(&format!(
                "  analytic visibility: {} intervals, at most {} on one sample (cap {}); {} lists compressed, {} of them joined to one line per triangle, {} intervals dropped; {} item × sample pairs left out unsolved, wholly behind a still triangle covering the sample all along\n",
                self.intervals, self.peak_per_sample, list_cap(self.spatial_samples as usize), self.compressed, self.joined, self.dropped, self.hidden_behind_still
            ));
            out.push_str(&format!(
                "  shading: {} visible pieces in {} runs of one triangle ({} runs of several sub-segments shaded as one), {} pieces point-sampled in shadow-map time (dynamic receivers that may be shadowed)\n",
                self.pieces, self.runs, self.joined_runs, self.point_sampled
            ));
        }
        out
    }

    /// Add another render's counts (the reference's frames).
    pub(crate) fn add(&mut self, other: &TriangleStats) {
        self.items += other.items;
        self.behind_near += other.behind_near;
        self.too_far += other.too_far;
        self.intervals += other.intervals;
        self.peak_per_sample = self.peak_per_sample.max(other.peak_per_sample);
        self.compressed += other.compressed;
        self.joined += other.joined;
        self.dropped += other.dropped;
        self.hidden_behind_still += other.hidden_behind_still;
        self.pieces += other.pieces;
        self.runs += other.runs;
        self.joined_runs += other.joined_runs;
        self.point_sampled += other.point_sampled;
        self.spatial_samples = self.spatial_samples.max(other.spatial_samples);
        self.shadow_tiles += other.shadow_tiles;
        self.shadow_tiles_left_empty += other.shadow_tiles_left_empty;
        self.shadow_items_left_out += other.shadow_items_left_out;
        self.shadow_lists.add(&other.shadow_lists);
    }
}

/// When the triangles are seen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    /// At one instant, with a z-buffer.
    Instant(f64),
    /// Over the whole shutter, with analytic visibility.
    Shutter,
}

/// One object's corners in camera space at the ends of one of its sub-segments.
struct Segment {
    time: [f64; 2],
    start: Vec<DVec3>,
    end: Vec<DVec3>,
    /// Object → world rotation at the ends, for shading normals (interpolated linearly in
    /// between and normalized, as Palmér §2.3.2 interpolates normals).
    rotation: [DMat3; 2],
    /// Whether nothing changes over the segment (a still object): shaded once per piece.
    still: bool,
}

/// A triangle item's corners over its segment.
struct Placed {
    triangle: MovingTriangle,
    edges: EdgeFunctions,
    /// The part of the segment (as fractions of it) when every corner is in front of the near
    /// plane.
    window: [f64; 2],
    /// The segment's start and end time.
    time: [f64; 2],
    /// How far a linear depth piece may stray from the exact depth, as a share of the depth
    /// ([`Prepared::depth_tolerance`]).
    depth_tolerance: f64,
    /// Whether no corner moves: the triangle covers a sample all the time or never, at one depth.
    still: bool,
    /// Whether it is still and in front of the near plane over the whole exposure: a sample it
    /// covers, it covers all along.
    all_along: bool,
    /// Its depth along any ray over the segment.
    depth: DepthFunction,
}

/// One triangle over one sub-segment.
#[derive(Clone, Copy)]
struct Item {
    object: u32,
    segment: u32,
    triangle: u32,
    /// Pixel bounds [x0, y0, x1, y1).
    bounds: [u32; 4],
    /// Its corners share one colour: its albedo needs no barycentric weights.
    one_colour: bool,
    /// Its corners also share one shading normal (a flat face in one colour): where a ray meets
    /// it, no barycentric weights are needed.
    plain: bool,
}

/// Triangle objects prepared for one exposure, seen by one camera (the scene's, or a light's).
struct Prepared<'a> {
    scene: &'a Scene,
    camera: Camera,
    /// Camera space → world, for where shading happens.
    view_to_world: DAffine3,
    exposure: Exposure,
    /// Every light, in [`crate::scene::Lighting::sources`] order.
    sources: Vec<LightSource<'a>>,
    /// The shadow map of each light that casts shadows, in the same order.
    shadows: Vec<ShadowMap>,
    /// How receivers sweeping shadow-map texels are shadowed.
    receivers: Receivers,
    objects: Vec<(&'a Object, &'a TriangleMesh, Vec<Segment>)>,
    items: Vec<Item>,
    /// Triangle × segment pairs left out, wholly behind the near plane.
    behind_near: usize,
    /// Triangle × segment pairs left out, too far out for double precision.
    too_far: usize,
    /// Whether some item is behind the near plane part of its segment.
    near_clipped: bool,
    /// Whether surfels are drawn behind these triangles, which [`TriangleImage::hidden_beyond`]
    /// leaves out.
    occludes_surfels: bool,
    /// How far a linear depth piece may stray from the exact depth, as a share of the depth:
    /// [`tct::DEPTH_TOLERANCE_PX`] in the image, [`shadow::DEPTH_TOLERANCE_TEXELS`] in a shadow
    /// map, over the focal length.
    depth_tolerance: f64,
}

/// An image of the triangle objects and where they hide what lies behind.
pub struct TriangleImage {
    /// Linear RGB over the scene's background.
    pub image: Framebuffer,
    /// Per pixel, the depth behind which everything is hidden by triangles at every sample and
    /// instant (+∞ where some sample sees past them): the occluder for surfels drawn after.
    /// `None` where the scene draws no surfels.
    pub hidden_beyond: Option<Vec<f32>>,
    /// What was drawn.
    pub stats: TriangleStats,
}

/// Draw the triangle objects of `plan` (those [`Plan::draws_triangles`] says) over the scene's
/// background, at `exposure`. The plan has checked that their items stay within
/// [`MAX_TRIANGLE_ITEMS`].
#[must_use]
pub fn draw(plan: &Plan, exposure: Exposure) -> TriangleImage {
    let scene = plan.scene();
    let budget = MAX_SHADOW_PIECES / plan.shadow_cameras.len().max(1);
    let shadows = plan
        .shadow_cameras
        .iter()
        .map(|camera| {
            let map = ShadowMap::new(shadow_occluders(plan, camera, exposure, budget));
            match exposure {
                Exposure::Shutter => map.summarised(),
                Exposure::Instant(_) => map,
            }
        })
        .collect();
    Prepared::new(plan, scene.camera.clone(), exposure, shadows).render()
}

/// The occluders of the shadow map `camera` sees, within `budget` pieces: at the map's own
/// resolution where they fit, else with half the texels per side, and so on down to
/// [`MIN_SHADOW_MAP`]; only a map that does not fit even there has its texel lists cut
/// ([`Prepared::occluders_within`]). A coarser map keeps every occluder's time, so its shadows
/// keep their strength and soften at their edges, where cut lists would lose the shortest
/// shadows (a cube zig-zagging 150 times over a floor, texel lists then of 256: RMSE against the
/// converged reference 0.0364 cut to 80 pieces a texel, 0.0186 with half the texels per side,
/// as uncut).
fn shadow_occluders(plan: &Plan, camera: &Camera, exposure: Exposure, budget: usize) -> Occluders {
    let mut camera = camera.clone();
    let asked = camera.width;
    loop {
        let half = camera.width / 2;
        let coarser = (half >= MIN_SHADOW_MAP)
            .then(|| camera.resized(half, camera.height / 2).ok())
            .flatten();
        let prepared = Prepared::new(plan, camera.clone(), exposure, Vec::new()).for_shadow_map();
        match (
            prepared.occluders_within(budget, coarser.is_none()),
            coarser,
        ) {
            (Some(mut occluders), _) => {
                if camera.width != asked {
                    occluders.lists.coarsened = Some((asked, camera.width));
                }
                return occluders;
            }
            (None, Some(coarser)) => camera = coarser,
            (None, None) => unreachable!("a map that cannot be coarsened is cut to fit"),
        }
    }
}

impl<'a> Prepared<'a> {
    fn new(
        plan: &'a Plan<'a>,
        camera: Camera,
        exposure: Exposure,
        shadows: Vec<ShadowMap>,
    ) -> Prepared<'a> {
        let scene = plan.scene();
        let depth_tolerance = tct::DEPTH_TOLERANCE_PX / camera.focal_px;
        let camera_ref = &camera;
        let mut objects = Vec::new();
        for (index, (object, object_plan)) in scene.objects.iter().zip(&plan.objects).enumerate() {
            if !plan.draws_triangles(index) {
                continue;
            }
            let Some(mesh) = plan.mesh_of(index) else {
                continue;
            };
            // Per segment: the instants its corners are posed at, and the time it stands for (a
            // still object's one pose stands for the whole shutter).
            let shutter = [scene.shutter.open, scene.shutter.close];
            let segments: Vec<([f64; 2], [f64; 2])> = match (exposure, &object_plan.motion) {
                (Exposure::Instant(t), _) => vec![([t, t], [t, t])],
                (Exposure::Shutter, ObjectMotion::Still) => {
                    let middle = scene.shutter.middle();
                    vec![([middle, middle], shutter)]
                }
                (Exposure::Shutter, ObjectMotion::Moving { segments, .. }) => {
                    segments.iter().map(|&s| (s, s)).collect()
                }
            };
            let corners_at = |t: f64| {
                let to_view = camera_ref.view * object.motion.pose_at(t).to_affine();
                mesh.positions
                    .iter()
                    .map(|&p| to_view.transform_point3(p))
                    .collect::<Vec<DVec3>>()
            };
            let segments: Vec<Segment> = segments
                .into_iter()
                .map(|([t0, t1], time)| {
                    let (start, end) = if t1 == t0 {
                        let at = corners_at(t0);
                        (at.clone(), at)
                    } else {
                        fitted_paths(corners_at, [t0, t1])
                    };
                    Segment {
                        rotation: [t0, t1].map(|t| object.motion.pose_at(t).rotation_matrix()),
                        still: t1 == t0,
                        time,
                        start,
                        end,
                    }
                })
                .collect();
            objects.push((object, mesh, segments));
        }
        let count: usize = objects
            .iter()
            .map(|(_, mesh, segments)| mesh.triangles.len() * segments.len())
            .sum();
        let view_to_world = camera.view.inverse();
        let mut prepared = Prepared {
            scene,
            camera,
            view_to_world,
            exposure,
            sources: scene.lighting.sources().collect(),
            shadows,
            receivers: match plan.method() {
                Method::Analytic { receivers, .. } => *receivers,
                _ => Receivers::default(),
            },
            objects,
            items: Vec::new(),
            behind_near: 0,
            too_far: 0,
            near_clipped: false,
            occludes_surfels: (0..scene.objects.len()).any(|index| !plan.draws_triangles(index)),
            depth_tolerance,
        };
        (
            prepared.items,
            [prepared.behind_near, prepared.too_far],
            prepared.near_clipped,
        ) = prepared.make_items(count);
        prepared
    }

    /// The same as a light's view for its shadow map: depth pieces within
    /// [`shadow::DEPTH_TOLERANCE_TEXELS`] texels' width of the exact depth.
    fn for_shadow_map(mut self) -> Self {
        self.depth_tolerance = shadow::DEPTH_TOLERANCE_TEXELS / self.camera.focal_px;
        self
    }

    /// The segment of `item`.
    fn segment(&self, item: &Item) -> &Segment {
        &self.objects[item.object as usize].2[item.segment as usize]
    }

    /// The corners of `item` over its segment.
    fn corners(&self, item: &Item) -> MovingTriangle {
        let (_, mesh, segments) = &self.objects[item.object as usize];
        let segment = &segments[item.segment as usize];
        let corners = mesh.triangles[item.triangle as usize];
        let start = corners.map(|v| segment.start[v as usize]);
        let end = corners.map(|v| segment.end[v as usize]);
        MovingTriangle {
            start,
            delta: [0, 1, 2].map(|k| end[k] - start[k]),
        }
    }

    /// The moving triangle of `item`, placed in its segment.
    fn triangle(&self, item: &Item) -> Placed {
        let segment = self.segment(item);
        let triangle = self.corners(item);
        let window = triangle.in_front(self.camera.near).unwrap_or([0.0, 0.0]);
        let still = triangle.delta == [DVec3::ZERO; 3];
        Placed {
            edges: triangle.edge_functions(),
            depth: triangle.depth_function(),
            triangle,
            window,
            time: segment.time,
            depth_tolerance: self.depth_tolerance,
            still,
            all_along: still
                && window == [0.0, 1.0]
                && segment.time == [self.scene.shutter.open, self.scene.shutter.close],
        }
    }

    /// Every triangle over every segment that is in front of the near plane some of the time and
    /// on screen, with its pixel bounds: the projections of its corners at the ends of its time
    /// in front (a segment's straight path in camera space projects to a straight path on
    /// screen, so they bound it), widened by a pixel.
    /// Also returns how many were left out behind the near plane and too far out for double
    /// precision, and whether some item is behind the near plane part of the time. `count` is the
    /// number of triangle × segment pairs.
    fn make_items(&self, count: usize) -> (Vec<Item>, [usize; 2], bool) {
        let camera = &self.camera;
        let (width, height) = (camera.width, camera.height);
        let mut items = Vec::with_capacity(count);
        let mut behind_near = 0;
        let mut too_far = 0;
        let mut near_clipped = false;
        for (o, (_, mesh, segments)) in self.objects.iter().enumerate() {
            for s in 0..segments.len() {
                for t in 0..mesh.triangles.len() {
                    let [n0, n1, n2] = mesh.normals[t];
                    let [c0, c1, c2] = mesh.triangles[t].map(|v| mesh.colours[v as usize]);
                    let one_colour = c0 == c1 && c1 == c2;
                    let mut item = Item {
                        object: o as u32,
                        segment: s as u32,
                        triangle: t as u32,
                        bounds: [0; 4],
                        one_colour,
                        plain: one_colour && n0 == n1 && n1 == n2,
                    };
                    let triangle = self.corners(&item);
                    if !triangle.within_double_range() {
                        too_far += 1;
                        continue;
                    }
                    let Some(window) = triangle.in_front(camera.near) else {
                        behind_near += 1;
                        continue;
                    };
                    near_clipped |= window != [0.0, 1.0];
                    if mesh.closed && triangle.back_facing_throughout() {
                        continue;
                    }
                    // A corner at the near plane itself (a window's end) may round to behind it:
                    // it projects far off screen anyway, so the whole image bounds it.
                    let (lo, hi) = match screen_corners(camera, &triangle, window) {
                        Some(corners) => corners
                            .iter()
                            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &p| {
                                (lo.min(p), hi.max(p))
                            }),
                        None => (DVec2::NEG_INFINITY, DVec2::INFINITY),
                    };
                    let clip = |v: f64, max: u32| v.clamp(0.0, f64::from(max)) as u32;
                    let bounds = [
                        clip((lo.x - 1.0).floor(), width),
                        clip((lo.y - 1.0).floor(), height),
                        clip((hi.x + 1.0).ceil(), width),
                        clip((hi.y + 1.0).ceil(), height),
                    ];
                    if bounds[0] < bounds[2] && bounds[1] < bounds[3] {
                        item.bounds = bounds;
                        items.push(item);
                    }
                }
            }
        }
        (items, [behind_near, too_far], near_clipped)
    }

    /// The items binned to the tiles of `grid` by their bounds.
    fn tile_lists(&self, grid: &TileGrid) -> TileLists {
        TileLists::new(grid, self.items.len(), |index, visit| {
            let [x0, y0, x1, y1] = self.items[index as usize].bounds;
            for ty in y0 / TILE_PX..=(y1 - 1) / TILE_PX {
                for tx in x0 / TILE_PX..=(x1 - 1) / TILE_PX {
                    visit(grid.index(tx, ty));
                }
            }
        })
    }

    fn render(&self) -> TriangleImage {
        let camera = &self.camera;
        let (width, height) = (camera.width, camera.height);
        let grid = TileGrid::new(width, height);
        let lists = self.tile_lists(&grid);
        let offsets = camera.sample_offsets();
        let band = grid.band_len();
        // Every pixel is written by its tile: zeroed pages the OS hands out untouched, so the
        // first touch happens in the parallel pass.
        let mut image = Framebuffer::filled(width, height, [0.0; 3]);
        let mut hidden_beyond = self
            .occludes_surfels
            .then(|| vec![f32::INFINITY; width as usize * height as usize]);
        let hidden_bands: Vec<Option<&mut [f32]>> = match &mut hidden_beyond {
            Some(hidden) => hidden.chunks_mut(band).map(Some).collect(),
            None => (0..image.pixels.len().div_ceil(band))
                .map(|_| None)
                .collect(),
        };
        let pool = ScratchPool::default();
        let bands: Vec<_> = image.pixels.chunks_mut(band).zip(hidden_bands).collect();
        let stats = lists.by_rows_costliest_first(&grid, bands, |ty, (pixels, mut hidden)| {
            pool.with(|scratch| {
                let mut stats = TriangleStats::default();
                for tile in grid.row(ty) {
                    let bounds = grid.pixels(tile);
                    self.render_tile(lists.list(tile), bounds, &offsets, scratch, &mut stats);
                    for (at, (colour, hide)) in grid.in_band(tile).zip(&scratch.pixels) {
                        pixels[at] = *colour;
                        if let Some(hidden) = &mut hidden {
                            hidden[at] = *hide;
                        }
                    }
                }
                stats
            })
        });
        let mut total = TriangleStats {
            items: self.items.len(),
            behind_near: self.behind_near,
            too_far: self.too_far,
            spatial_samples: camera.spatial_samples,
            shadow_tiles: self.shadows.iter().map(ShadowMap::tiles).sum(),
            shadow_tiles_left_empty: self.shadows.iter().map(ShadowMap::left_empty).sum(),
            shadow_items_left_out: self.shadows.iter().map(ShadowMap::left_out).sum(),
            shadow_lists: self
                .shadows
                .iter()
                .fold(ShadowLists::default(), |mut all, map| {
                    all.add(&map.lists());
                    all
                }),
            ..TriangleStats::default()
        };
        for s in &stats {
            total.add(s);
        }
        TriangleImage {
            image,
            hidden_beyond,
            stats: total,
        }
    }

    /// Insert every item of a tile into its samples: intervals (`Shutter`, their depth as
    /// `depth` says) or the nearest (`Instant`).
    fn fill_tile(
        &self,
        list: &[u32],
        bounds @ [x0, y0, x1, y1]: [u32; 4],
        offsets: &[[f64; 2]],
        depth: DepthPieces,
        scratch: &mut Scratch,
        stats: &mut TriangleStats,
    ) {
        let samples = ((x1 - x0) * (y1 - y0)) as usize * offsets.len();
        scratch.reset(samples, list_cap(offsets.len()));
        let grid = SampleGrid::new(bounds, offsets);
        scratch.tile.clear(self.items.len());
        let cut_later = self.exposure == Exposure::Shutter && depth == DepthPieces::OnDemand;
        let rays = self.corner_rays(bounds);
        let mut depth_bounds = [f64::INFINITY, f64::NEG_INFINITY];
        // Still items first: where one covers a sample all along, a later item lying wholly
        // deeper than it there can never be seen, and is left out before its coverage is
        // solved (a floor or a still occluder hides what passes behind it, as a shadow map's
        // still occluders hide the moving receivers behind them).
        for still in [true, false] {
            for &index in list {
                let item = &self.items[index as usize];
                if self.segment(item).still != still {
                    continue;
                }
                let placed = self.triangle(item);
                if cut_later {
                    let bounds @ [near, far] = depth_bounds_within(&placed.triangle, rays);
                    depth_bounds = [depth_bounds[0].min(near), depth_bounds[1].max(far)];
                    scratch.tile.push(TileItem {
                        index,
                        depth: placed.depth,
                        bounds,
                        unshadowed: [false; MAX_SHADOWED_LIGHTS],
                        plain: item.plain.then(|| {
                            let normals = self.world_normals(item, [1.0 / 3.0; 3]);
                            PlainFace {
                                normals,
                                at_start: unit_between(normals, 0.0),
                                albedo: self.albedo_with(item, [1.0 / 3.0; 3]),
                            }
                        }),
                    });
                }
                self.cover_samples(index, &placed, &grid, depth, scratch, stats);
            }
        }
        if cut_later {
            let casters = self.casters_seen(rays, depth_bounds);
            for entry in &mut scratch.tile.entries {
                let own = self.shadow_id(&self.items[entry.index as usize]);
                entry.unshadowed =
                    casters.map(|casters| casters.is_some_and(|casters| casters.none_but(own)));
            }
        }
    }

    /// The rays through the corners of pixels `[x0, y0, x1, y1)`: (x0, y0), (x1, y0), (x0, y1),
    /// (x1, y1). Every sample of those pixels lies between them.
    fn corner_rays(&self, [x0, y0, x1, y1]: [u32; 4]) -> [DVec3; 4] {
        [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
            .map(|(x, y)| self.camera.ray(f64::from(x), f64::from(y)))
    }

    /// Per shadow map, whose occluders lie in the texels that a receiver seen between the corner
    /// `rays` of a tile ([`Prepared::corner_rays`]) at a depth within `[near, far]` can read.
    /// Such receivers lie in the frustum piece between those depths, the convex hull of its
    /// eight corners, which [`ShadowMap::casters_around`] reads at once for the whole tile:
    /// where it holds nothing but a run's own occluders, no sample of the tile walks the map to
    /// find that the run is lit.
    fn casters_seen(
        &self,
        rays: [DVec3; 4],
        [near, far]: [f64; 2],
    ) -> [Option<Casters>; MAX_SHADOWED_LIGHTS] {
        let mut casters = [None; MAX_SHADOWED_LIGHTS];
        let near = near.max(self.camera.near);
        if !(far >= near && far.is_finite()) {
            return casters;
        }
        let mut corners = [DVec3::ZERO; 8];
        for (k, corner) in corners.iter_mut().enumerate() {
            let depth = if k & 4 == 0 { near } else { far };
            *corner = self.view_to_world.transform_point3(rays[k & 3] * depth);
        }
        for (seen, map) in casters.iter_mut().zip(&self.shadows) {
            *seen = map.casters_around(&corners);
        }
        casters
    }

    /// Insert item `index` (`placed`) into the lists (or the z-buffer) of the samples of the
    /// tile it may cover.
    fn cover_samples(
        &self,
        index: u32,
        placed: &Placed,
        grid: &SampleGrid,
        depth: DepthPieces,
        scratch: &mut Scratch,
        stats: &mut TriangleStats,
    ) {
        let camera = &self.camera;
        let SampleGrid {
            bounds: [x0, y0, x1, y1],
            offsets,
            spread: [ox0, oy0, ox1, oy1],
        } = *grid;
        let w = (x1 - x0) as usize;
        let per_pixel = offsets.len();
        let [ix0, iy0, ix1, iy1] = self.items[index as usize].bounds;
        // A triangle covers samples within the hull of its corners' screen paths only; the
        // rest of its bounds are skipped a row at a time.
        // Its corners' projections and an edge's x at a row round by a few ulps of the largest
        // corner coordinate, which HULL_MARGIN_PX covers up to about 10¹¹ px; beyond, the band of
        // rows and the range widen by the rounding itself (a hull whose rounding is not finite
        // bounds nothing, and the item's bounds are tested in full).
        let hull = screen_corners(camera, &placed.triangle, placed.window)
            .map(|corners| ScreenHull::new(&corners))
            .and_then(|hull| {
                let rounding = HULL_ROUNDING * hull.reach;
                match rounding {
                    r if r <= HULL_MARGIN_PX => Some((hull, 0.0, HULL_MARGIN_PX)),
                    r if r.is_finite() => Some((hull, r, r)),
                    _ => None,
                }
            });
        let [nearest, _] = placed.triangle.depth_bounds();
        let no_tile = TileShared::default();
        for y in iy0.max(y0)..iy1.min(y1) {
            let (mut from, mut to) = (ix0.max(x0), ix1.min(x1));
            if let Some((hull, band, margin)) = &hull {
                let rows = [f64::from(y) + oy0 - band, f64::from(y) + oy1 + band];
                let Some([lo, hi]) = hull.x_range(rows[0], rows[1]) else {
                    continue;
                };
                let pixel = |x: f64| x.clamp(0.0, f64::from(u32::MAX)) as u32;
                from = from.max(pixel((lo - ox1 - margin).ceil()));
                to = to.min(pixel((hi - ox0 + margin).floor() + 1.0));
            }
            for x in from..to {
                let pixel = (y - y0) as usize * w + (x - x0) as usize;
                for (k, [ox, oy]) in offsets.iter().enumerate() {
                    let d = camera.ray(f64::from(x) + ox, f64::from(y) + oy);
                    let sample = pixel * per_pixel + k;
                    match self.exposure {
                        Exposure::Instant(_) => scratch.nearer(sample, placed, d, index),
                        Exposure::Shutter => {
                            if nearest > scratch.covered_all_along[sample] {
                                stats.hidden_behind_still += 1;
                                continue;
                            }
                            // Only a full list's resolve cuts intervals here, rarely: their
                            // items' depth functions are worked out again.
                            let along = AlongRay {
                                prepared: self,
                                d,
                                tile: &no_tile,
                            };
                            scratch.insert(sample, placed, d, index, depth, &along, stats);
                        }
                    }
                }
            }
        }
    }

    /// Render one tile into `scratch.pixels` (colour and hidden-beyond depth, row by row).
    fn render_tile(
        &self,
        list: &[u32],
        bounds @ [x0, y0, x1, y1]: [u32; 4],
        offsets: &[[f64; 2]],
        scratch: &mut Scratch,
        stats: &mut TriangleStats,
    ) {
        self.fill_tile(list, bounds, offsets, DepthPieces::OnDemand, scratch, stats);
        let camera = &self.camera;
        let w = (x1 - x0) as usize;
        let per_pixel = offsets.len();
        let background = self.scene.background.map(f64::from);
        let mut pixels = std::mem::take(&mut scratch.pixels);
        pixels.clear();
        for pixel in 0..w * (y1 - y0) as usize {
            let (x, y) = (x0 + (pixel % w) as u32, y0 + (pixel / w) as u32);
            let mut sum = [0.0f64; 3];
            let mut hidden = f64::NEG_INFINITY;
            for (k, [ox, oy]) in offsets.iter().enumerate() {
                let d = camera.ray(f64::from(x) + ox, f64::from(y) + oy);
                let (colour, beyond) =
                    self.sample_colour(scratch, pixel * per_pixel + k, d, background, stats);
                for c in 0..3 {
                    sum[c] += colour[c];
                }
                hidden = hidden.max(beyond);
            }
            let n = per_pixel as f64;
            pixels.push((sum.map(|c| (c / n) as f32), hidden as f32));
        }
        scratch.pixels = pixels;
    }

    /// The colour of one sample over the exposure, and the depth beyond which it sees nothing.
    fn sample_colour(
        &self,
        scratch: &mut Scratch,
        sample: usize,
        d: DVec3,
        background: [f64; 3],
        stats: &mut TriangleStats,
    ) -> ([f64; 3], f64) {
        match self.exposure {
            Exposure::Instant(_) => match scratch.nearest[sample] {
                Some((depth, index)) => {
                    let item = &self.items[index as usize];
                    let t = self.segment(item).time[0];
                    (self.shade(item, &self.corners(item), d, 0.0, t), depth)
                }
                None => (background, f64::INFINITY),
            },
            Exposure::Shutter => {
                let Scratch {
                    lists,
                    resolving,
                    visible,
                    shading,
                    tile,
                    ..
                } = scratch;
                visible.clear();
                let along = AlongRay {
                    prepared: self,
                    d,
                    tile,
                };
                resolve(&lists[sample], resolving, visible, &along);
                let shutter = &self.scene.shutter;
                let mut colour = [0.0f64; 3];
                let mut covered = 0.0;
                let mut farthest = f64::NEG_INFINITY;
                let same_triangle = |a: &Interval, b: &Interval| {
                    let (a, b) = (&self.items[a.item as usize], &self.items[b.item as usize]);
                    a.object == b.object && a.triangle == b.triangle
                };
                for run in visible.chunk_by(|a, b| a.t[1] == b.t[0] && same_triangle(a, b)) {
                    let span = [run[0].t[0], run[run.len() - 1].t[1]];
                    let mass = shutter.mass(span[0], span[1]);
                    if !(mass > 0.0) {
                        continue;
                    }
                    let mean = self.run_colour(run, d, shading, tile, stats);
                    for c in 0..3 {
                        colour[c] += mass * mean[c];
                    }
                    covered += mass;
                    for piece in run {
                        let ends = piece.depth[0].max(piece.depth[1]);
                        // Surfels behind this depth are left out: past the line's ends where the
                        // depth bends.
                        let deepest = if self.occludes_surfels {
                            self.depth_range(piece, d, tile)
                                .map_or(ends, |range| range[1])
                        } else {
                            ends
                        };
                        farthest = farthest.max(deepest);
                    }
                }
                let uncovered = (1.0 - covered).max(0.0);
                for c in 0..3 {
                    colour[c] += uncovered * background[c];
                }
                let beyond = if uncovered < 1e-9 {
                    farthest
                } else {
                    f64::INFINITY
                };
                (colour, beyond)
            }
        }
    }

    /// Mean colour of a run of visible pieces of one triangle, back to back in time (one per
    /// sub-segment it crosses), weighted by the shutter: as one where no shadow can change along
    /// it ([`Prepared::lit_run_colour`]), else each of its linear depth pieces on its own (as is
    /// a lone piece whose depth is one line).
    fn run_colour(
        &self,
        run: &[Interval],
        d: DVec3,
        work: &mut ShadingScratch,
        tile: &TileShared,
        stats: &mut TriangleStats,
    ) -> [f64; 3] {
        stats.runs += 1;
        if let [piece @ Interval { bends: false, .. }] = run {
            stats.pieces += 1;
            return self.piece_colour(piece, d, &mut work.cuts, tile, stats);
        }
        if let Some(colour) = self.lit_run_colour(run, d, work, tile) {
            stats.pieces += run.len();
            stats.joined_runs += usize::from(run.len() > 1);
            return colour;
        }
        let mut pieces = std::mem::take(&mut work.pieces);
        pieces.clear();
        for piece in run {
            self.depth_pieces_of(piece, d, tile, &mut pieces);
        }
        let (mut sum, mut mass) = ([0.0; 3], 0.0);
        for piece in &pieces {
            let m = self.scene.shutter.mass(piece.t[0], piece.t[1]);
            if !(m > 0.0) {
                continue;
            }
            stats.pieces += 1;
            let mean = self.piece_colour(piece, d, &mut work.cuts, tile, stats);
            for c in 0..3 {
                sum[c] += m * mean[c];
            }
            mass += m;
        }
        work.pieces = pieces;
        sum.map(|c| if mass > 0.0 { c / mass } else { 0.0 })
    }

    /// The mean colour of a run of pieces when no shadow map can change its light: it faces away
    /// from each shadowed light all along, or is lit for sure all along its stretch of the
    /// sample's ray (between the depths [`Prepared::depth_range`] bounds), or each piece on its
    /// own path ([`ShadowMap::surely_lit_between`]). The surface (normal, point, colour) is found
    /// exactly at every piece's ends and interpolated linearly within each piece, as
    /// [`Prepared::piece_colour`] does (the point stays on the ray: a bend of the depth within a
    /// piece moves it along the ray only, which a directional light does not see); the run is
    /// cut where it turns towards or away from a light (eq. 2.5, per piece) and integrated at
    /// three Gauss–Legendre times per cut piece, not per sub-segment: the light changes smoothly
    /// across a sub-segment's end, where the pose is continuous. `None` when a shadow may fall
    /// on the run.
    fn lit_run_colour(
        &self,
        run: &[Interval],
        d: DVec3,
        work: &mut ShadingScratch,
        tile: &TileShared,
    ) -> Option<[f64; 3]> {
        let ShadingScratch {
            cuts, ends, ranges, ..
        } = work;
        ends.clear();
        for (i, piece) in run.iter().enumerate() {
            let times = if i + 1 == run.len() {
                &piece.t[..]
            } else {
                &piece.t[..1]
            };
            self.surface_points(piece.item, d, tile, times, ends);
        }
        let ends = &ends[..];
        let time = |i: usize| run.get(i).map_or(run[run.len() - 1].t[1], |p| p.t[0]);
        let surface_at = |t: f64| {
            let i = run.partition_point(|p| p.t[1] < t).min(run.len() - 1);
            let span = run[i].t;
            let u = if span[1] > span[0] {
                ((t - span[0]) / (span[1] - span[0])).clamp(0.0, 1.0)
            } else {
                0.0
            };
            ends[i].lerp(&ends[i + 1], u)
        };
        let span = [run[0].t[0], run[run.len() - 1].t[1]];
        cuts.clear();
        cuts.extend(span);
        if self.scene.lighting.is_lit() {
            let item = &self.items[run[0].item as usize];
            let own = self.shadow_id(item);
            // Every point of the run lies on the sample's ray, each piece's between the depths its
            // range bounds: its path in a shadow map is the straight one between the nearest and
            // the farthest, and none of it lies deeper from the light than they do.
            let unshadowed = tile.unshadowed(run[0].item);
            ranges.clear();
            if !unshadowed[..self.shadows.len()].iter().all(|&clear| clear) {
                ranges.extend(run.iter().map(|piece| self.depth_range(piece, d, tile)));
            }
            let whole = ranges
                .iter()
                .try_fold([f64::INFINITY, 0.0], |[lo, hi], range| {
                    range.map(|[a, b]| [lo.min(a), hi.max(b)])
                });
            let on_ray = |depth: f64| self.view_to_world.transform_point3(d * depth);
            let mut maps = self.shadows.iter().zip(unshadowed);
            for source in &self.sources {
                // The sign of N·L at each piece's ends (shared with its neighbours) and middle,
                // as the surface within a piece is interpolated: quadratic in time, so that the
                // cuts are its roots.
                let facing = |end: &SurfacePoint| source.facing(end.normal, end.point);
                let mut away = true;
                let mut start = facing(&ends[0]);
                for i in 0..run.len() {
                    let end = facing(&ends[i + 1]);
                    let middle = ends[i].facing_midway(&ends[i + 1], source);
                    let piece = [time(i), time(i + 1)];
                    away &= cut_where_turning([start, middle, end], piece, cuts);
                    cut_at_cone_edges(source, [ends[i].point, ends[i + 1].point], piece, cuts);
                    start = end;
                }
                if !source.shadows() {
                    continue;
                }
                let (map, unshadowed) = maps.next()?;
                // A walk along a stretch of the ray over a time span, with the depth from the light
                // of its deeper end as the limit (no bias: stricter than any point's).
                let lit_along = |[nearest, farthest]: [f64; 2], span: [f64; 2]| {
                    let (a, depth_a) = map.locate(on_ray(nearest))?;
                    let (b, depth_b) = map.locate(on_ray(farthest))?;
                    let limit = depth_a.max(depth_b);
                    map.surely_lit_between((a, limit), (b, limit), span, own)
                        .then_some(())
                };
                // One walk for the whole run settles most; the rest go piece by piece, each on
                // its own path and time: between its ends, each placed with the least bias its
                // normal takes within the piece, or where it bends, along its stretch of the ray.
                let lit = || {
                    if lit_along(whole?, span).is_some() {
                        return Some(());
                    }
                    for (i, piece) in run.iter().enumerate() {
                        if piece.bends {
                            lit_along(ranges[i]?, piece.t)?;
                        } else {
                            // Each end with the least bias the piece's turning normal takes.
                            let normals = [ends[i].normal, ends[i + 1].normal];
                            let from = map.place_turning(ends[i].point, normals)?;
                            let to = map.place_turning(ends[i + 1].point, normals)?;
                            map.surely_lit_between(from, to, [time(i), time(i + 1)], own)
                                .then_some(())?;
                        }
                    }
                    Some(())
                };
                if !(away || unshadowed || lit().is_some()) {
                    return None;
                }
            }
        }
        let shutter = &self.scene.shutter;
        cut_for_shutter_weight(shutter, span, cuts);
        cuts.sort_unstable_by(f64::total_cmp);
        cuts.dedup();
        let mut sum = [0.0; 3];
        let mut weight = 0.0;
        let lit = [1.0; MAX_SHADOWED_LIGHTS];
        for pair in cuts.windows(2) {
            let [a, b] = [pair[0], pair[1]];
            if !(b > a) {
                continue;
            }
            let (centre, half) = (0.5 * (a + b), 0.5 * (b - a));
            for (node, w) in GAUSS_LEGENDRE_3 {
                let t = centre + half * node;
                let w = w * half * shutter.weight(t).max(1e-300);
                let end = surface_at(t);
                let irradiance = self.irradiance(end.normal, end.point, &lit);
                for (total, albedo) in sum.iter_mut().zip(end.albedo) {
                    *total += w * albedo * irradiance;
                }
                weight += w;
            }
        }
        (weight > 0.0).then(|| sum.map(|c| c / weight))
    }

    /// The mean irradiance over `span` of a still receiver (its `normal` and `point`, on
    /// `item`), weighted by the shutter. A shadow map whose light gives it nothing, or that holds
    /// no nearer occluder in its texels over the span (`unshadowed` for the whole tile, else
    /// [`ShadowMap::surely_lit`]), leaves it lit; the others give the mean share of their light
    /// over the span in closed form ([`ShadowMap::mean_visibility`]), and light is linear in it.
    fn still_irradiance(
        &self,
        (normal, point): (DVec3, DVec3),
        span: [f64; 2],
        item: &Item,
        unshadowed: [bool; MAX_SHADOWED_LIGHTS],
    ) -> f64 {
        self.irradiance_with(normal, point, |k| {
            let (Some(map), Some(false)) = (self.shadows.get(k), unshadowed.get(k).copied()) else {
                return 1.0;
            };
            // Placed once, for the lit-for-sure test and the mean; behind its light a point
            // takes no shadow from it.
            let own = self.shadow_id(item);
            match map.place(point, normal) {
                Some(placed) if !map.surely_lit_between(placed, placed, span, own) => {
                    map.mean_visibility(placed, span, own, &self.scene.shutter)
                }
                _ => 1.0,
            }
        })
    }

    /// Mean colour of a visible piece, weighted by the shutter. A still triangle's piece is shaded
    /// once, its shadows in closed form ([`Prepared::still_irradiance`]; a plain face's surface
    /// from the tile's copy of its plane). A moving one is cut where the surface turns towards or
    /// away from a light (eq. 2.5: N·L, quadratic in time, through its values at the piece's ends
    /// and middle) and where a shadow can start or end (exact for a receiver within one texel
    /// footprint, [`ShadowMap::breakpoints`]; for one sweeping texels, max(2|pₑ − pₛ|, 5) equal
    /// cuts, or with `Receivers::Traced` the cuts of [`ShadowMap::traced_breakpoints`]);
    /// visibility is taken at each cut piece's middle and the rest integrated at three
    /// Gauss–Legendre times.
    fn piece_colour(
        &self,
        piece: &Interval,
        d: DVec3,
        cuts: &mut Vec<f64>,
        tile: &TileShared,
        stats: &mut TriangleStats,
    ) -> [f64; 3] {
        let item = &self.items[piece.item as usize];
        let segment = self.segment(item);
        let [t0, t1] = segment.time;
        let fraction = |t: f64| if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        let span = piece.t;
        if segment.still {
            // A plain face's surface from the tile's copy of its plane and shading.
            let entry = tile.of(piece.item);
            let plain = entry.and_then(|entry| Some((entry.depth.hit_at_start(d), entry.plain?)));
            let surface = match plain {
                Some((hit, face)) => self.plain_surface_point(&hit, d, 0.0, &face),
                None => self.surface_point(item, &self.corners(item), d, 0.0),
            };
            let unshadowed = unshadowed_of(entry);
            let irradiance =
                self.still_irradiance((surface.normal, surface.point), span, item, unshadowed);
            return surface.albedo.map(|c| c * irradiance);
        }
        let own = self.shadow_id(item);
        let triangle = self.corners(item);
        // The receiver between the piece's ends: its point and normal interpolated linearly in
        // time (Palmér's sample interval), exact at the ends. Within a sub-segment the normal
        // already turns linearly; the point departs from its chord by the perspective of a plane
        // moving in depth, far below a pixel over one piece.
        let ends = span.map(|t| self.surface(item, &triangle, d, fraction(t)));
        let receiver = Receiver {
            path: [ends[0].1, ends[1].1],
            normals: [ends[0].0, ends[1].0],
            span,
            own,
        };
        // The normal and point between the ends, the normal not made unit: N·L then has the
        // unit normal's sign and is exactly quadratic in time (`cut_where_turning`).
        let between = |t: f64| receiver.between(t);
        let surface_at = |t: f64| {
            let (normal, p) = between(t);
            (normal.normalize_or_zero(), p)
        };
        cuts.clear();
        cuts.extend(span);
        let mut point_sampled = false;
        // Per shadow map, whether its shadows cannot change anything here: the piece faces away
        // from its light all along, or is lit all along.
        let mut surely_lit = [true; MAX_SHADOWED_LIGHTS];
        if self.scene.lighting.is_lit() {
            let mut maps = self
                .shadows
                .iter()
                .zip(tile.unshadowed(piece.item))
                .zip(&mut surely_lit);
            for source in &self.sources {
                let facing = |t: f64| {
                    let (normal, p) = between(t);
                    source.facing(normal, p)
                };
                let middle = 0.5 * (span[0] + span[1]);
                let values = [facing(span[0]), facing(middle), facing(span[1])];
                let away = cut_where_turning(values, span, cuts);
                cut_at_cone_edges(source, [ends[0].1, ends[1].1], span, cuts);
                if source.shadows() {
                    if let Some(((map, unshadowed), lit)) = maps.next() {
                        *lit = away || unshadowed || map.surely_lit(&receiver);
                    }
                }
            }
        }
        for (map, _) in self
            .shadows
            .iter()
            .zip(&surely_lit)
            .filter(|(_, &lit)| !lit)
        {
            let sweep = map.sweep(receiver.path[0], receiver.path[1]);
            if sweep < 1.0 {
                map.breakpoints(&receiver, cuts);
            } else if !(self.receivers == Receivers::Traced
                && map.traced_breakpoints(&receiver, cuts))
            {
                point_sampled = true;
                let count = (2.0 * sweep)
                    .max(5.0)
                    .min(shadow::MAX_RECEIVER_SAMPLES as f64) as usize;
                cuts.extend(
                    (1..count).map(|i| span[0] + (span[1] - span[0]) * i as f64 / count as f64),
                );
            }
        }
        stats.point_sampled += usize::from(point_sampled);
        cut_for_shutter_weight(&self.scene.shutter, span, cuts);
        cuts.sort_unstable_by(f64::total_cmp);
        cuts.dedup();
        // The share of each shadow map's light reaching the receiver at t, in the order
        // `irradiance` reads them (entries past the last map stay 1).
        let visibility_at = |t: f64| {
            let mut visibility = [1.0; MAX_SHADOWED_LIGHTS];
            if !surely_lit.iter().all(|&lit| lit) {
                let (normal, p) = surface_at(t);
                for ((v, map), lit) in visibility.iter_mut().zip(&self.shadows).zip(surely_lit) {
                    if !lit {
                        *v = map.visibility(p, normal, t, own);
                    }
                }
            }
            visibility
        };
        // Cut pieces with exact ends (turning, shadow edges within one texel) are integrated
        // at three Gauss–Legendre times each; a receiver point-sampled across texels by their
        // middles, which is the point sampling itself.
        if point_sampled {
            // Each point sample shades the interpolated receiver at its time, its colour too.
            let (mut sum, mut weight) = ([0.0; 3], 0.0);
            for pair in cuts.windows(2) {
                let t = 0.5 * (pair[0] + pair[1]);
                let w = (pair[1] - pair[0]) * self.scene.shutter.weight(t).max(1e-300);
                let (normal, p) = surface_at(t);
                let light = w * self.irradiance(normal, p, &visibility_at(t));
                let albedo = self.albedo(item, &triangle, d, fraction(t));
                for c in 0..3 {
                    sum[c] += light * albedo[c];
                }
                weight += w;
            }
            return sum.map(|c| if weight > 0.0 { c / weight } else { 0.0 });
        }
        let mut sum = [0.0; 3];
        let mut weight = 0.0;
        for pair in cuts.windows(2) {
            let [a, b] = [pair[0], pair[1]];
            if !(b > a) {
                continue;
            }
            let (centre, half) = (0.5 * (a + b), 0.5 * (b - a));
            let visibility = visibility_at(centre);
            let albedo = self.albedo(item, &triangle, d, fraction(centre));
            for (node, w) in GAUSS_LEGENDRE_3 {
                let t = centre + half * node;
                let w = w * half * self.scene.shutter.weight(t).max(1e-300);
                let (normal, p) = surface_at(t);
                let irradiance = self.irradiance(normal, p, &visibility);
                for c in 0..3 {
                    sum[c] += w * albedo[c] * irradiance;
                }
                weight += w;
            }
        }
        if weight > 0.0 {
            sum.map(|c| c / weight)
        } else {
            self.shade(item, &triangle, d, fraction(span[0]), span[0])
        }
    }

    /// `interval` of the ray `d` as the linear depth pieces [`DepthPieces::AtOnce`] would have
    /// inserted, appended to `out`, its ends kept exactly. A still triangle's depth is one line;
    /// where the depth is undefined inside the interval, it stays the line between its ends.
    fn depth_pieces_of(
        &self,
        interval: &Interval,
        d: DVec3,
        tile: &TileShared,
        out: &mut Vec<Interval>,
    ) {
        let Some((along, span, time)) = self.bend(interval, d, tile) else {
            out.push(*interval);
            return;
        };
        let tolerance = self.depth_tolerance;
        let first = out.len();
        let cut = depth_pieces(&along, span, time, interval.item, tolerance, &mut |p| {
            out.push(p);
        });
        if cut.is_none() {
            out.truncate(first);
            out.push(*interval);
            return;
        }
        let last = out.len() - 1;
        (out[first].t[0], out[first].depth[0]) = (interval.t[0], interval.depth[0]);
        (out[last].t[1], out[last].depth[1]) = (interval.t[1], interval.depth[1]);
    }

    /// Where `interval` of the ray `d` bends: its item's depth along the ray (from `tile` where
    /// it has it), its span as fractions of the item's segment, and the segment's
    /// time. `None` for a line.
    fn bend(
        &self,
        interval: &Interval,
        d: DVec3,
        tile: &TileShared,
    ) -> Option<(RayDepth, [f64; 2], [f64; 2])> {
        if !interval.bends {
            return None;
        }
        let item = &self.items[interval.item as usize];
        let time @ [t0, t1] = self.segment(item).time;
        if !(t1 > t0) {
            return None;
        }
        let along = match tile.of(interval.item) {
            Some(entry) => entry.depth.along(d),
            None => self.corners(item).depth_function().along(d),
        };
        Some((along, interval.t.map(|t| (t - t0) / (t1 - t0)), time))
    }

    /// Bounds [nearest, farthest] on the depth of `interval` along the ray `d`
    /// ([`RayDepth::range`]); `None` where they cannot be had.
    fn depth_range(&self, interval: &Interval, d: DVec3, tile: &TileShared) -> Option<[f64; 2]> {
        let ends = [
            interval.depth[0].min(interval.depth[1]),
            interval.depth[0].max(interval.depth[1]),
        ];
        let Some((along, span, _)) = self.bend(interval, d, tile) else {
            return Some(ends);
        };
        let [nearest, farthest] = along.range(span)?;
        // The ends are exact; the bound's own rounding may fall just inside them.
        Some([nearest.min(ends[0]), farthest.max(ends[1])])
    }

    /// The shading normal (world, on the side of the triangle the eye sees: both sides are
    /// drawn) and the world point the ray `d` sees on `item` at segment fraction `s`.
    fn surface(&self, item: &Item, triangle: &MovingTriangle, d: DVec3, s: f64) -> (DVec3, DVec3) {
        self.surface_with(item, &self.hit(item, triangle, d, s), d, s)
    }

    /// Where the ray `d` meets `item` (as `triangle`) at segment fraction `s`: from its plane
    /// alone where its corners share what the weights would blend.
    fn hit(&self, item: &Item, triangle: &MovingTriangle, d: DVec3, s: f64) -> RayHit {
        if item.plain {
            triangle.plane_hit(d, s)
        } else {
            triangle.ray_hit(d, s)
        }
    }

    /// [`Prepared::surface`] and [`Prepared::albedo`] at once, where the ray `d` meets item
    /// `index` at each of `times` (within its segment), appended to `out`. A plain item is met
    /// from the tile's polynomials of its plane (three dot products for all its times) rather
    /// than from its corners at each time.
    fn surface_points(
        &self,
        index: u32,
        d: DVec3,
        tile: &TileShared,
        times: &[f64],
        out: &mut Vec<SurfacePoint>,
    ) {
        let item = &self.items[index as usize];
        let [t0, t1] = self.segment(item).time;
        let plain = tile
            .of(index)
            .and_then(|entry| Some((entry.depth.along(d), entry.plain?)));
        let mut triangle = None;
        for &t in times {
            let s = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
            out.push(match &plain {
                Some((plane, face)) => self.plain_surface_point(&plane.plane_hit(s), d, s, face),
                None => {
                    let triangle = triangle.get_or_insert_with(|| self.corners(item));
                    self.surface_point(item, triangle, d, s)
                }
            });
        }
    }

    /// The surface (shading normal, world point, colour) where the ray `d` meets `item`, as
    /// `triangle`, at segment fraction `s`: [`Prepared::surface`] and [`Prepared::albedo`] from
    /// one hit.
    fn surface_point(
        &self,
        item: &Item,
        triangle: &MovingTriangle,
        d: DVec3,
        s: f64,
    ) -> SurfacePoint {
        let hit = self.hit(item, triangle, d, s);
        let (normal, point) = self.surface_with(item, &hit, d, s);
        SurfacePoint {
            normal,
            point,
            albedo: self.albedo_with(item, hit.weights),
        }
    }

    /// The surface where the ray `d` meets a plain item at segment fraction `s`, at `hit`, from
    /// its tile's copy of its shading `face`.
    fn plain_surface_point(
        &self,
        hit: &RayHit,
        d: DVec3,
        s: f64,
        face: &PlainFace,
    ) -> SurfacePoint {
        let unit = if s == 0.0 {
            face.at_start
        } else {
            unit_between(face.normals, s)
        };
        let (normal, point) = self.on_side(hit, d, unit);
        SurfacePoint {
            normal,
            point,
            albedo: face.albedo,
        }
    }

    /// The shading normal and world point where the ray `d` meets `item` at segment fraction
    /// `s`, at `hit`.
    fn surface_with(&self, item: &Item, hit: &RayHit, d: DVec3, s: f64) -> (DVec3, DVec3) {
        self.on_side(
            hit,
            d,
            unit_between(self.world_normals(item, hit.weights), s),
        )
    }

    /// The shading normal of `item` at barycentric `weights` in world space, at its segment's
    /// ends.
    fn world_normals(&self, item: &Item, weights: [f64; 3]) -> [DVec3; 2] {
        let (_, mesh, _) = &self.objects[item.object as usize];
        let normals = mesh.normals[item.triangle as usize];
        let local: DVec3 = if item.plain {
            normals[0]
        } else {
            (0..3).map(|k| normals[k] * weights[k]).sum()
        };
        self.segment(item).rotation.map(|r| r * local)
    }

    /// The unit shading normal `unit` on the side of `hit`, and the world point of `hit` on the
    /// ray `d`.
    fn on_side(&self, hit: &RayHit, d: DVec3, unit: DVec3) -> (DVec3, DVec3) {
        let mut world = unit;
        // Both sides are drawn, and the side the ray meets turns the normal: not the shading
        // normal's own direction, which near a smooth mesh's silhouette faces away from the eye
        // on triangles that face it, and flipped would be lit from inside.
        if hit.back {
            world = -world;
        }
        let depth = hit.depth.unwrap_or(0.0);
        (world, self.view_to_world.transform_point3(d * depth))
    }

    /// The colour the ray `d` sees on `item` at segment fraction `s` (time `t`), in the shadows
    /// of that instant: corner colours and normals interpolated perspective-correctly, Lambert
    /// shading.
    fn shade(&self, item: &Item, triangle: &MovingTriangle, d: DVec3, s: f64, t: f64) -> [f64; 3] {
        if !self.scene.lighting.is_lit() {
            return self.albedo(item, triangle, d, s);
        }
        let SurfacePoint {
            normal,
            point: p,
            albedo,
        } = self.surface_point(item, triangle, d, s);
        let own = self.shadow_id(item);
        let mut visibility = [1.0; MAX_SHADOWED_LIGHTS];
        for (v, map) in visibility.iter_mut().zip(&self.shadows) {
            *v = map.visibility(p, normal, t, own);
        }
        let irradiance = self.irradiance(normal, p, &visibility);
        albedo.map(|c| c * irradiance)
    }

    /// What `item`'s pieces are known by in shadow maps, and what its receivers leave out of
    /// them: its triangle (Palmér's polygon IDs), or the whole object, as [`WHOLE_OBJECT`],
    /// where the object cannot shadow itself ([`TriangleMesh::shadows_itself`]).
    fn shadow_id(&self, item: &Item) -> (u32, u32) {
        if !self.objects[item.object as usize].1.shadows_itself {
            (item.object, WHOLE_OBJECT)
        } else {
            (item.object, item.triangle)
        }
    }

    /// The corner colours interpolated perspective-correctly where the ray `d` meets `item` at
    /// segment fraction `s`.
    fn albedo(&self, item: &Item, triangle: &MovingTriangle, d: DVec3, s: f64) -> [f64; 3] {
        // One colour needs no hit (most meshes are one-coloured): any weights give it.
        if item.one_colour {
            return self.albedo_with(item, [1.0, 0.0, 0.0]);
        }
        self.albedo_with(item, self.hit(item, triangle, d, s).weights)
    }

    /// The corner colours of `item` at barycentric `weights`.
    fn albedo_with(&self, item: &Item, weights: [f64; 3]) -> [f64; 3] {
        let (_, mesh, _) = &self.objects[item.object as usize];
        let corners = mesh.triangles[item.triangle as usize];
        if item.one_colour {
            return mesh.colours[corners[0] as usize].map(f64::from);
        }
        [0, 1, 2].map(|c| {
            (0..3)
                .map(|k| weights[k] * f64::from(mesh.colours[corners[k] as usize][c]))
                .sum::<f64>()
        })
    }

    /// Lambertian irradiance at world point `p` with unit `normal`: ambient plus each light's
    /// reach × max(0, N·L), the shadowed ones scaled by their share in `visibility`. 1 unlit.
    fn irradiance(&self, normal: DVec3, p: DVec3, visibility: &[f64]) -> f64 {
        self.irradiance_with(normal, p, |k| visibility.get(k).copied().unwrap_or(1.0))
    }

    /// [`Prepared::irradiance`] with the share of the k-th shadowed light from `share(k)`, asked
    /// only where that light reaches the point (a share of nothing is not worked out).
    fn irradiance_with(&self, normal: DVec3, p: DVec3, mut share: impl FnMut(usize) -> f64) -> f64 {
        let lighting = &self.scene.lighting;
        if !lighting.is_lit() {
            return 1.0;
        }
        let mut shadowed = 0;
        let direct: f64 = self
            .sources
            .iter()
            .map(|source| {
                let light = source.irradiance(normal, p);
                if !source.shadows() {
                    return light;
                }
                shadowed += 1;
                if light > 0.0 {
                    share(shadowed - 1) * light
                } else {
                    light
                }
            })
            .sum();
        lighting.ambient + direct
    }

    /// The occluders of every texel, seen from this (a light's) camera with one sample per texel,
    /// within `budget` ([`ShadowTile::held`]: pieces plus the texel records of tiles that hold
    /// any); `None` when they do not fit and `cut` is false. Tiles are built in parallel, each keeping its lists while
    /// the pieces held so far fit; once they would not, the rest are only counted, and at the end,
    /// if the map did not fit, every texel's list is cut to its longest pieces, as many as fit
    /// ([`cap_within`]), the tiles that were only counted built again. Which tiles were held
    /// depends on the thread schedule, the result does not: a map that fits was held whole, and
    /// one that does not is cut alike everywhere (or, not to be cut, given up once over, its tiles
    /// left unbuilt). At most about twice the budget is held while it is cut.
    fn occluders_within(&self, budget: usize, cut: bool) -> Option<Occluders> {
        let camera = &self.camera;
        let grid = TileGrid::new(camera.width, camera.height);
        let lists = self.tile_lists(&grid);
        let offsets = camera.sample_offsets();
        let pool = ScratchPool::default();
        let build = |tile: usize| -> ShadowTile {
            let bounds @ [x0, y0, x1, y1] = grid.pixels(tile);
            let texels = ((x1 - x0) * (y1 - y0)) as usize;
            let all = lists.list(tile);
            let list = self.casting(all, bounds);
            let mut built = ShadowTile {
                left_out: all.len() - list.len(),
                ..ShadowTile::default()
            };
            if list.is_empty() {
                built.left_empty = built.left_out > 0;
                return built;
            }
            pool.with(|scratch| {
                let mut stats = TriangleStats::default();
                let depth = DepthPieces::AtOnce;
                self.fill_tile(&list, bounds, &offsets, depth, scratch, &mut stats);
                built.compressed = stats.compressed;
                built.dropped = stats.dropped;
                built.starts.reserve(texels + 1);
                built.starts.push(0u32);
                for texel in 0..texels {
                    match self.exposure {
                        Exposure::Instant(t) => {
                            if let Some((depth, index)) = scratch.nearest[texel] {
                                built.pieces.push(Interval {
                                    t: [t, t],
                                    depth: [depth, depth],
                                    item: index,
                                    bends: false,
                                });
                            }
                        }
                        Exposure::Shutter => {
                            let Scratch {
                                lists, resolving, ..
                            } = scratch;
                            resolve(&lists[texel], resolving, &mut built.pieces, &AsIs);
                        }
                    }
                    built.starts.push(built.pieces.len() as u32);
                }
            });
            // A tile that holds no occluder keeps no starts either.
            if built.pieces.is_empty() {
                built.starts = Vec::new();
            }
            built
        };
        let held = AtomicUsize::new(0);
        // A map that will not be cut is given up as soon as it is over: its tiles left are not
        // built at all.
        let given_up = || !cut && held.load(Ordering::Relaxed) > budget;
        let mut tiles: Vec<ShadowTile> = (0..grid.count())
            .into_par_iter()
            .with_max_len(1)
            .map(|tile| {
                if given_up() {
                    return ShadowTile::default();
                }
                let mut built = build(tile);
                let cost = built.held();
                if held.fetch_add(cost, Ordering::Relaxed) + cost > budget {
                    built.pieces = Vec::new();
                    built.counted_only = true;
                }
                built
            })
            .collect();
        if given_up() {
            return None;
        }
        let counts = || {
            tiles
                .iter()
                .flat_map(|t| t.starts.windows(2))
                .map(|s| (s[1] - s[0]) as usize)
        };
        let mut lists_stats = ShadowLists {
            pieces: counts().sum(),
            records: tiles.iter().map(|t| t.starts.len()).sum(),
            peak_per_texel: counts().max().unwrap_or(0),
            compressed: tiles.iter().map(|t| t.compressed).sum(),
            dropped: tiles.iter().map(|t| t.dropped).sum(),
            ..ShadowLists::default()
        };
        if lists_stats.pieces + lists_stats.records > budget {
            // Cut only at the coarsest map, whose records are a few hundred.
            let cap = cap_within(counts(), budget.saturating_sub(lists_stats.records));
            tiles
                .par_iter_mut()
                .enumerate()
                .with_max_len(1)
                .for_each(|(tile, built)| {
                    if built.counted_only {
                        *built = build(tile);
                    }
                    built.keep_longest(cap);
                });
            let pieces = tiles.iter().map(|t| t.pieces.len()).sum();
            lists_stats.cap = Some(cap);
            lists_stats.peak_per_texel = lists_stats.peak_per_texel.min(cap);
            lists_stats.cut = lists_stats.pieces - pieces;
            lists_stats.pieces = pieces;
        }
        let left_empty = tiles.iter().filter(|t| t.left_empty).count();
        let left_out = tiles.iter().map(|t| t.left_out).sum();
        Some(Occluders {
            camera: self.camera.clone(),
            tiles: tiles
                .into_iter()
                .map(|t| {
                    let occluders = t
                        .pieces
                        .into_iter()
                        .map(|piece| Occluder {
                            piece,
                            id: self.shadow_id(&self.items[piece.item as usize]),
                        })
                        .collect();
                    (t.starts, occluders)
                })
                .collect(),
            left_empty,
            left_out,
            lists: lists_stats,
        })
    }

    /// The items of `list`, a shadow-map tile's (pixels `bounds`), that may shadow a receiver
    /// whose lookups read the tile. A receiver's lookups read only texels within its own item's
    /// bounds (its point lies on its triangle, whose corners' projections over the segment,
    /// widened by a texel, bound the item; a bilinear lookup reads half a texel further), so only
    /// the receivers of the tile's items read it, at depths within their items' bounds there.
    /// An object that cannot shadow itself and lies, over the tile, wholly deeper than every
    /// other object's items shadows none of them, and its own lookups leave it out: its items
    /// are left out (all of them where it is the only object). Not where a triangle crosses the
    /// light's near plane: its bounds then hold only the part in front.
    fn casting(&self, list: &[u32], bounds: [u32; 4]) -> Vec<u32> {
        if self.near_clipped || self.behind_near > 0 {
            return list.to_vec();
        }
        let may_leave_out = |index: &u32| {
            let object = self.items[*index as usize].object;
            !self.objects[object as usize].1.shadows_itself
        };
        if !list.iter().any(may_leave_out) {
            return list.to_vec();
        }
        let rays = self.corner_rays(bounds);
        // Per object of the tile (its items come grouped, in item order): its depth bounds.
        let mut objects: Vec<(u32, [f64; 2])> = Vec::new();
        for &index in list {
            let item = &self.items[index as usize];
            let [near, far] = depth_bounds_within(&self.corners(item), rays);
            match objects.last_mut() {
                Some((object, range)) if *object == item.object => {
                    *range = [range[0].min(near), range[1].max(far)];
                }
                _ => objects.push((item.object, [near, far])),
            }
        }
        let behind_the_rest = |object: u32, [near, _]: [f64; 2]| {
            !self.objects[object as usize].1.shadows_itself
                && objects
                    .iter()
                    .filter(|(other, _)| *other != object)
                    .all(|(_, [_, far])| *far < near)
        };
        list.iter()
            .copied()
            .filter(|&index| {
                let object = self.items[index as usize].object;
                !objects
                    .iter()
                    .any(|&(o, range)| o == object && behind_the_rest(o, range))
            })
            .collect()
    }
}

/// How a moving triangle's depth over a covered interval enters a sample's list.
#[derive(Clone, Copy, Debug, PartialEq)]
enum DepthPieces {
    /// As linear pieces at once: a shadow map's lookups compare depths at every time.
    AtOnce,
    /// As the line between its exact ends, cut into pieces only where something compares or
    /// follows the depth within it ([`Prepared::depth_pieces_of`]): the sweep among intervals
    /// that overlap in time, a run that may be shadowed. Most of an image's samples see one
    /// surface at a time, lit or unlit for sure, and need neither.
    OnDemand,
}

/// Bounds on the depth of `triangle` where the rays between the corner `rays` of a tile meet it:
/// its corners' over its segment, or, still, its plane's over those rays
/// ([`MovingTriangle::plane_depths_within`]) where they are tighter.
fn depth_bounds_within(triangle: &MovingTriangle, rays: [DVec3; 4]) -> [f64; 2] {
    let bounds = triangle.depth_bounds();
    let still = triangle.delta == [DVec3::ZERO; 3];
    match still.then(|| triangle.plane_depths_within(rays)) {
        Some(Some(plane)) => [bounds[0].max(plane[0]), bounds[1].min(plane[1])],
        _ => bounds,
    }
}

/// The linear depth pieces of `item` along a ray whose depth is `along`, over the fractions
/// `span` of a segment lasting `time` ([`RayDepth::knots`] at `tolerance`), handed to `piece` in
/// time order. `None` when the depth is undefined somewhere in the span.
fn depth_pieces(
    along: &RayDepth,
    span: [f64; 2],
    time: [f64; 2],
    item: u32,
    tolerance: f64,
    piece: &mut impl FnMut(Interval),
) -> Option<()> {
    let at_time = |s: f64| time[0] + (time[1] - time[0]) * s;
    let mut previous: Option<[f64; 2]> = None;
    along.knots(span, tolerance, &mut |knot| {
        if let Some(previous) = previous {
            piece(Interval {
                t: [at_time(previous[0]), at_time(knot[0])],
                depth: [previous[1], knot[1]],
                item,
                bends: false,
            });
        }
        previous = Some(knot);
    })
}

/// The triangle index in every shadow-map id of an object that cannot shadow itself
/// ([`Prepared::shadow_id`]).
const WHOLE_OBJECT: u32 = u32::MAX;

/// Slack around a moving triangle's screen hull, px: samples this near it are still tested
/// exactly, so that rounding in the projection never drops one the edge functions cover.
const HULL_MARGIN_PX: f64 = 1e-3;

/// Rounding of a screen hull's edges per px of its largest corner coordinate: a corner's
/// projection rounds by a few ulps of it, and an edge's x at a row, p.x + slope·(y − p.y), by a
/// few more (its terms reach twice it). Past 10¹⁶ px the edges are off by whole pixels.
const HULL_ROUNDING: f64 = 32.0 * f64::EPSILON;

/// Where the corners of `triangle` project at the ends of `window`: each corner moves on a
/// straight line in camera space, which projects to a straight line on screen, so the triangle
/// at every time in the window lies in their convex hull. `None` when one does not project (a
/// corner at the near plane rounded to behind it).
fn screen_corners(
    camera: &Camera,
    triangle: &MovingTriangle,
    window: [f64; 2],
) -> Option<[DVec2; 6]> {
    let [a, b] = window.map(|s| triangle.at(s));
    let corners = [a[0], a[1], a[2], b[0], b[1], b[2]];
    let mut screen = [DVec2::ZERO; 6];
    for (out, p) in screen.iter_mut().zip(corners) {
        *out = camera.project(p)?.0;
    }
    Some(screen)
}

/// The convex hull of a few screen points, as its edges.
struct ScreenHull {
    /// Each edge: its lower and upper end in y and its dx/dy (0 for a level edge).
    edges: [(DVec2, DVec2, f64); 6],
    count: usize,
    /// Its largest corner coordinate in magnitude, px.
    reach: f64,
}

impl ScreenHull {
    /// The hull of `points` (Andrew's monotone chain).
    fn new(points: &[DVec2; 6]) -> ScreenHull {
        let mut sorted = *points;
        sorted.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        let turn = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
        let mut chain = [DVec2::ZERO; 12];
        let mut n = 0;
        for pass in 0..2 {
            let start = n;
            for i in 0..6 {
                let p = if pass == 0 { sorted[i] } else { sorted[5 - i] };
                while n >= start + 2 && turn(chain[n - 2], chain[n - 1], p) <= 0.0 {
                    n -= 1;
                }
                chain[n] = p;
                n += 1;
            }
            // The chain's last point starts the other one.
            n -= 1;
        }
        let count = n.clamp(1, 6);
        let mut edges = [(DVec2::ZERO, DVec2::ZERO, 0.0); 6];
        for (i, edge) in edges[..count].iter_mut().enumerate() {
            let (p, q) = (chain[i], chain[(i + 1) % count]);
            let (p, q) = if p.y <= q.y { (p, q) } else { (q, p) };
            let slope = if q.y > p.y {
                (q.x - p.x) / (q.y - p.y)
            } else {
                0.0
            };
            *edge = (p, q, slope);
        }
        let reach = points
            .iter()
            .fold(0.0f64, |m, p| m.max(p.x.abs()).max(p.y.abs()));
        ScreenHull {
            edges,
            count,
            reach,
        }
    }

    /// The x extent of the hull within the band of rows y0 ≤ y ≤ y1, `None` when it misses it.
    fn x_range(&self, y0: f64, y1: f64) -> Option<[f64; 2]> {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &(p, q, slope) in &self.edges[..self.count] {
            if q.y < y0 || p.y > y1 {
                continue;
            }
            let (xa, xb) = if q.y > p.y {
                let x_at = |y: f64| p.x + slope * (y - p.y);
                (x_at(y0.max(p.y)), x_at(y1.min(q.y)))
            } else {
                (p.x, q.x)
            };
            lo = lo.min(xa.min(xb));
            hi = hi.max(xa.max(xb));
        }
        (lo <= hi).then_some([lo, hi])
    }
}

/// What a sample's ray sees on a surface at one time.
#[derive(Clone, Copy, Debug)]
struct SurfacePoint {
    /// Shading normal (world, unit).
    normal: DVec3,
    /// World point.
    point: DVec3,
    /// Colour.
    albedo: [f64; 3],
}

impl SurfacePoint {
    /// N·L for `source` halfway to `other`, the normal lerped and not made unit: with the values
    /// at the two ends, what [`cut_where_turning`] fits its quadratic through.
    fn facing_midway(&self, other: &SurfacePoint, source: &LightSource) -> f64 {
        source.facing(
            self.normal.lerp(other.normal, 0.5),
            self.point.lerp(other.point, 0.5),
        )
    }

    /// Linear interpolation towards `other` by `u` (the normal normalized again).
    fn lerp(&self, other: &SurfacePoint, u: f64) -> SurfacePoint {
        SurfacePoint {
            normal: self.normal.lerp(other.normal, u).normalize_or_zero(),
            point: self.point.lerp(other.point, u),
            albedo: [0, 1, 2].map(|c| self.albedo[c] + (other.albedo[c] - self.albedo[c]) * u),
        }
    }
}

/// A tile's samples: its pixels and the samples' offsets within each.
#[derive(Clone, Copy)]
struct SampleGrid<'o> {
    /// Pixel bounds [x0, y0, x1, y1).
    bounds: [u32; 4],
    offsets: &'o [[f64; 2]],
    /// The box the offsets span, [x0, y0, x1, y1].
    spread: [f64; 4],
}

impl<'o> SampleGrid<'o> {
    fn new(bounds: [u32; 4], offsets: &'o [[f64; 2]]) -> SampleGrid<'o> {
        let spread = offsets.iter().fold(
            [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ],
            |[x0, y0, x1, y1], &[x, y]| [x0.min(x), y0.min(y), x1.max(x), y1.max(y)],
        );
        SampleGrid {
            bounds,
            offsets,
            spread,
        }
    }
}

/// The depth of intervals along the ray `d`, for the resolve: their items' depth functions from
/// `tile` where it holds them.
struct AlongRay<'r, 'a> {
    prepared: &'r Prepared<'a>,
    d: DVec3,
    tile: &'r TileShared,
}

impl BentDepth for AlongRay<'_, '_> {
    fn pieces(&self, interval: &Interval, out: &mut Vec<Interval>) {
        self.prepared
            .depth_pieces_of(interval, self.d, self.tile, out);
    }

    fn bounds(&self, interval: &Interval) -> Option<[f64; 2]> {
        self.tile.of(interval.item).map(|entry| entry.bounds)
    }
}

/// What a tile's samples share: its items, found by item index in constant time (a sample's
/// run looks up each of its pieces' items twice), and which shadow maps shadow none of them.
#[derive(Default)]
struct TileShared {
    entries: Vec<TileItem>,
    /// Per item of the image, its place in `entries`, or [`NOT_IN_TILE`].
    slots: Vec<u32>,
}

/// A [`TileShared`] slot of an item the tile does not hold.
const NOT_IN_TILE: u32 = u32::MAX;

impl TileShared {
    /// Empty, for a tile among `items` items.
    fn clear(&mut self, items: usize) {
        for entry in &self.entries {
            self.slots[entry.index as usize] = NOT_IN_TILE;
        }
        self.entries.clear();
        if self.slots.len() < items {
            self.slots.resize(items, NOT_IN_TILE);
        }
    }

    fn push(&mut self, entry: TileItem) {
        self.slots[entry.index as usize] = self.entries.len() as u32;
        self.entries.push(entry);
    }

    fn of(&self, item: u32) -> Option<&TileItem> {
        self.entries.get(*self.slots.get(item as usize)? as usize)
    }

    /// [`TileItem::unshadowed`] of item `item` (none where the tile does not hold it).
    fn unshadowed(&self, item: u32) -> [bool; MAX_SHADOWED_LIGHTS] {
        unshadowed_of(self.of(item))
    }
}

/// [`TileItem::unshadowed`] of a tile's `entry` for an item (none where it has none).
fn unshadowed_of(entry: Option<&TileItem>) -> [bool; MAX_SHADOWED_LIGHTS] {
    entry.map_or([false; MAX_SHADOWED_LIGHTS], |entry| entry.unshadowed)
}

/// One item of a tile, as its samples reuse it.
struct TileItem {
    index: u32,
    /// What a sample's interval needs to be cut into depth pieces or bounded in depth.
    depth: DepthFunction,
    /// Bounds [nearest, farthest] on its depth at every sample of the tile and every time.
    bounds: [f64; 2],
    /// For a plain item, its shading, the same at every sample.
    plain: Option<PlainFace>,
    /// Per shadow map, whether it shadows none of the item's receivers the tile's samples see:
    /// all it holds where they can be seen ([`Prepared::casters_seen`]) is their own.
    unshadowed: [bool; MAX_SHADOWED_LIGHTS],
}

/// The shading normal at segment fraction `s` between the world `normals` at its ends
/// (interpolated linearly and normalized, Palmér §2.3.2).
fn unit_between([n0, n1]: [DVec3; 2], s: f64) -> DVec3 {
    n0.lerp(n1, s).normalize_or_zero()
}

/// A plain item's world shading normals at its segment's ends, and its colour.
#[derive(Clone, Copy)]
struct PlainFace {
    normals: [DVec3; 2],
    /// The unit normal at the segment's start ([`unit_between`] at 0): a still face's at
    /// every sample.
    at_start: DVec3,
    albedo: [f64; 3],
}

/// Working memory of a run's shading, reused from run to run.
#[derive(Default)]
struct ShadingScratch {
    /// The times a visible piece is cut at for shading.
    cuts: Vec<f64>,
    /// The surface at the ends of a run's pieces.
    ends: Vec<SurfacePoint>,
    /// Bounds on each piece's depth along the ray.
    ranges: Vec<Option<[f64; 2]>>,
    /// The run's linear depth pieces, where they are shaded one by one.
    pieces: Vec<Interval>,
}

/// The working memory of one pass's tasks, handed from task to task so that sample lists keep
/// their capacity (a task is a tile or a row of tiles; no more are in use than threads).
#[derive(Default)]
struct ScratchPool(std::sync::Mutex<Vec<Scratch>>);

impl ScratchPool {
    /// Run `work` with a scratch from the pool (or a new one), then return it.
    fn with<R>(&self, work: impl FnOnce(&mut Scratch) -> R) -> R {
        let mut scratch = self
            .0
            .lock()
            .ok()
            .and_then(|mut free| free.pop())
            .unwrap_or_default();
        let result = work(&mut scratch);
        if let Ok(mut free) = self.0.lock() {
            free.push(scratch);
        }
        result
    }
}

/// Per-tile working memory, reused from tile to tile.
#[derive(Default)]
struct Scratch {
    /// `Instant`: the nearest (depth, item) per sample.
    nearest: Vec<Option<(f64, u32)>>,
    /// `Shutter`: the interval list per sample.
    lists: Vec<Vec<Interval>>,
    /// Most intervals a list keeps ([`list_cap`] of its tile's samples per pixel).
    list_cap: usize,
    /// `Shutter`: per sample, the depth of the nearest still triangle covering it all along
    /// (+∞ while there is none).
    covered_all_along: Vec<f64>,
    resolving: ResolveScratch,
    visible: Vec<Interval>,
    /// A full list's intervals by length, for dropping the shortest.
    by_length: Vec<(f64, u32)>,
    /// One covered interval's depth pieces, before they enter a list.
    pieces: Vec<Interval>,
    shading: ShadingScratch,
    tile: TileShared,
    /// The finished pixels: colour and hidden-beyond depth.
    pixels: Vec<([f32; 3], f32)>,
}

impl Scratch {
    fn reset(&mut self, samples: usize, list_cap: usize) {
        self.list_cap = list_cap;
        self.nearest.clear();
        self.nearest.resize(samples, None);
        if self.lists.len() < samples {
            self.lists.resize_with(samples, Vec::new);
        }
        for list in &mut self.lists[..samples] {
            list.clear();
        }
        self.covered_all_along.clear();
        self.covered_all_along.resize(samples, f64::INFINITY);
    }

    /// Z-buffer test at an instant: keep `item` at `sample` if it covers it nearer.
    fn nearer(&mut self, sample: usize, placed: &Placed, d: DVec3, item: u32) {
        let triangle = &placed.triangle;
        if placed.window != [0.0, 1.0] {
            return;
        }
        if !placed.edges.inside_at_start(d) {
            return;
        }
        if let Some(depth) = triangle.depth(d, 0.0) {
            if self.nearest[sample].is_none_or(|(z, _)| depth < z) {
                self.nearest[sample] = Some((depth, item));
            }
        }
    }

    /// Insert the intervals during which the placed triangle covers `sample`, with their
    /// depth, in absolute time: as linear depth pieces at once or as the line between exact
    /// ends, per `depth`; `bent` cuts a list's intervals into linear depth pieces where a full
    /// list is resolved.
    #[allow(clippy::too_many_arguments)]
    fn insert(
        &mut self,
        sample: usize,
        placed: &Placed,
        d: DVec3,
        item: u32,
        depth: DepthPieces,
        bent: &impl BentDepth,
        stats: &mut TriangleStats,
    ) {
        let Placed {
            edges,
            window,
            time: [t0, t1],
            still,
            ..
        } = placed;
        let (window, t0, t1) = (*window, *t0, *t1);
        if !(window[1] > window[0]) {
            return;
        }
        if *still {
            // What the edge quadratics and depth pieces below give when nothing moves.
            if let Some(z) = edges
                .inside_at_start(d)
                .then(|| placed.depth.hit_at_start(d).depth)
                .flatten()
            {
                if placed.all_along {
                    let nearest = &mut self.covered_all_along[sample];
                    *nearest = nearest.min(z);
                }
                let interval = Interval {
                    t: [t0 + (t1 - t0) * window[0], t0 + (t1 - t0) * window[1]],
                    depth: [z, z],
                    item,
                    bends: false,
                };
                self.push(sample, interval, bent, stats);
            }
            return;
        }
        let along = placed.depth.along(d);
        let tolerance = placed.depth_tolerance;
        edges.covered(d, window, |start, end| {
            let span = [start, end];
            match depth {
                DepthPieces::AtOnce => {
                    self.pieces.clear();
                    let pieces = &mut self.pieces;
                    let cut = depth_pieces(&along, span, placed.time, item, tolerance, &mut |p| {
                        pieces.push(p);
                    });
                    if cut.is_some() {
                        for j in 0..self.pieces.len() {
                            let interval = self.pieces[j];
                            self.push(sample, interval, bent, stats);
                        }
                    }
                }
                // One line per span, pushed as it is made.
                DepthPieces::OnDemand => {
                    if let Some((depth, bends)) = along.line(span, tolerance) {
                        let interval = Interval {
                            t: span.map(|s| t0 + (t1 - t0) * s),
                            depth,
                            item,
                            bends,
                        };
                        self.push(sample, interval, bent, stats);
                    }
                }
            }
        });
    }

    /// Add one interval to a sample's list, compressing a full list first (its intervals cut
    /// into linear depth pieces by `pieces`).
    fn push(
        &mut self,
        sample: usize,
        interval: Interval,
        pieces: &impl BentDepth,
        stats: &mut TriangleStats,
    ) {
        let room = self.list_cap - list_slack(self.list_cap);
        let mut crowded = false;
        if self.lists[sample].len() >= self.list_cap {
            stats.compressed += 1;
            self.visible.clear();
            resolve(
                &self.lists[sample],
                &mut self.resolving,
                &mut self.visible,
                pieces,
            );
            let list = &mut self.lists[sample];
            list.clear();
            list.extend_from_slice(&self.visible);
            if list.len() > room {
                // Nearly full of visible pieces: join each item's consecutive pieces into one
                // line (its depth bends no longer followed, its coverage kept).
                stats.joined += 1;
                list.dedup_by(|next, last| {
                    let joins = last.item == next.item && last.t[1] == next.t[0];
                    if joins {
                        last.t[1] = next.t[1];
                        last.depth[1] = next.depth[1];
                        last.bends = false;
                    }
                    joins
                });
            }
            crowded = list.len() > room;
        }
        let list = &mut self.lists[sample];
        list.push(interval);
        stats.intervals += 1;
        if crowded {
            // Still nearly full: the shortest pieces go, the new interval among them, down to
            // the slack.
            stats.dropped += list.len() - room;
            drop_shortest(list, room, &mut self.by_length);
        }
        stats.peak_per_sample = stats.peak_per_sample.max(list.len());
    }
}

/// Keep the `keep` longest intervals of `list` (ties to the earlier), in their order: the list
/// holds visible pieces, and the shortest show the least.
fn drop_shortest(list: &mut Vec<Interval>, keep: usize, longest_first: &mut Vec<(f64, u32)>) {
    let kept = longest(list, keep, longest_first);
    let mut flags = kept.iter();
    list.retain(|_| *flags.next().expect("one flag per interval"));
}

/// Which of `list`'s intervals are its `keep` longest (ties to the earlier).
fn longest(list: &[Interval], keep: usize, longest_first: &mut Vec<(f64, u32)>) -> Vec<bool> {
    longest_first.clear();
    longest_first.extend(
        list.iter()
            .zip(0..)
            .map(|(i, index)| (i.t[0] - i.t[1], index)),
    );
    longest_first.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut kept = vec![false; list.len()];
    for &(_, index) in &longest_first[..keep.min(list.len())] {
        kept[index as usize] = true;
    }
    kept
}

/// One tile of a shadow map as it is built: its texels' lists one after the other.
#[derive(Default)]
struct ShadowTile {
    /// Where each texel's list starts (one more than the texels), or nothing when no texel holds
    /// an occluder.
    starts: Vec<u32>,
    /// The occluder pieces, or nothing when they were only counted.
    pieces: Vec<Interval>,
    /// Whether the pieces were let go, the map's budget spent (`starts` still counts them).
    counted_only: bool,
    /// Every item that reached the tile was left out.
    left_empty: bool,
    /// Items left out of it.
    left_out: usize,
    /// Full texel lists compressed, and intervals dropped from them.
    compressed: usize,
    dropped: usize,
}

impl ShadowTile {
    /// What the tile holds against its map's budget, in pieces: its pieces (counted, if let go)
    /// and one for each texel record (a list start and, over a shutter, a nearest-occluder
    /// record: 20 bytes, less than a piece's 48), so that a map of many texels cannot pass the
    /// budget one piece a texel.
    fn held(&self) -> usize {
        self.starts.last().map_or(0, |&end| end as usize) + self.starts.len()
    }

    /// Keep each texel's `cap` longest pieces, in their order.
    fn keep_longest(&mut self, cap: usize) {
        let mut longest_first = Vec::new();
        let mut pieces = Vec::new();
        let mut starts = vec![0u32];
        for s in self.starts.windows(2) {
            let list = &self.pieces[s[0] as usize..s[1] as usize];
            if list.len() > cap {
                let kept = longest(list, cap, &mut longest_first);
                pieces.extend(list.iter().zip(kept).filter(|(_, k)| *k).map(|(p, _)| *p));
            } else {
                pieces.extend_from_slice(list);
            }
            starts.push(pieces.len() as u32);
        }
        if pieces.is_empty() {
            starts = Vec::new();
        }
        self.starts = starts;
        self.pieces = pieces;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::Lod;

    /// A square crossing a floor `passes` times in one exposure under a light from above, with a
    /// shadow map `map` texels a side.
    fn zigzag_over_floor(map: u32, passes: u32) -> Scene {
        use crate::scene::{Keyframe, Light, Lighting, Motion, Pose};
        use crate::surfels::mesh::tests::square;
        use crate::surfels::{from_mesh, Colouring};
        // A square `side` wide centred at (x, 0, z) at each key (t, x, z).
        let object = |name: &str, side: f64, keys: Vec<(f64, f64, f64)>| {
            let mesh = square(side);
            let colour = Colouring::Rgb([1.0; 3]);
            let triangles = TriangleMesh::new(&mesh, DVec3::ZERO, colour).unwrap();
            let mut surfels = from_mesh(&mesh, 100, false).unwrap();
            colour.apply(&mut surfels);
            let keyframes = keys
                .into_iter()
                .map(|(t, x, z)| Keyframe {
                    t,
                    pose: Pose {
                        translation: DVec3::new(x - 0.5 * side, -0.5 * side, z),
                        ..Pose::IDENTITY
                    },
                })
                .collect();
            Object::triangles(name, triangles, surfels, Motion::new(keyframes).unwrap())
        };
        // The texels on the square's way hold up to two pieces a pass, the square's and the
        // floor's between, at full detail (`Lod::Off`: this fast, the level of detail draws the
        // square as one triangle).
        let zigzag = (0..=passes)
            .map(|i| {
                (
                    f64::from(i) / f64::from(passes),
                    if i % 2 == 0 { -2.0 } else { 2.0 },
                    1.0,
                )
            })
            .collect();
        let camera = Camera::new(
            DVec3::new(0.0, 0.0, 10.0),
            DVec3::ZERO,
            DVec3::Y,
            30.0,
            16,
            16,
        )
        .unwrap();
        let light = Light::new(DVec3::Z, 0.8).unwrap().with_shadows(true);
        let lighting = Lighting::new(0.2, vec![light])
            .unwrap()
            .with_shadow_map(map)
            .unwrap();
        Scene::new(camera)
            .with_lighting(lighting)
            .with_object(object("floor", 8.0, vec![(0.0, 0.0, 0.0)]))
            .with_object(object("square", 3.0, zigzag))
    }

    /// The view of `plan` from a light's `camera`, drawn as its shadow map is.
    fn prepared_light<'a>(plan: &'a Plan<'a>, camera: Camera) -> Prepared<'a> {
        Prepared::new(plan, camera, Exposure::Shutter, Vec::new()).for_shadow_map()
    }

    #[test]
    fn a_shadow_map_over_its_budget_keeps_each_texels_longest_pieces_whatever_the_threads() {
        let scene = zigzag_over_floor(16, 20);
        let plan = Plan::with_lod(&scene, &Method::ANALYTIC, Lod::Off).unwrap();
        let prepared = prepared_light(&plan, plan.shadow_cameras[0].clone());
        let texel_lists = |o: &Occluders| -> Vec<Vec<[f64; 2]>> {
            o.tiles
                .iter()
                .flat_map(|(starts, list)| {
                    let texels = if starts.is_empty() {
                        TILE_PX * TILE_PX
                    } else {
                        0
                    };
                    let empty = (0..texels).map(|_| Vec::new());
                    starts
                        .windows(2)
                        .map(|s| {
                            list[s[0] as usize..s[1] as usize]
                                .iter()
                                .map(|o| o.piece.t)
                                .collect()
                        })
                        .chain(empty)
                        .collect::<Vec<_>>()
                })
                .collect()
        };
        let whole = prepared.occluders_within(usize::MAX, false).unwrap();
        let texels = 16 * 16;
        assert_eq!(whole.lists.cap, None);
        assert!(
            whole.lists.pieces > 4 * texels,
            "{:?} {} {} {}",
            whole.lists,
            whole.tiles.len(),
            whole.left_empty,
            whole.left_out
        );
        let budget = 2 * texels + whole.lists.records;
        let counts: Vec<usize> = texel_lists(&whole).iter().map(Vec::len).collect();
        let cap = cap_within(counts.iter().copied(), 2 * texels);
        let kept: usize = counts.iter().map(|&c| c.min(cap)).sum();
        let cut_with = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| prepared.occluders_within(budget, true).unwrap())
        };
        let cut = cut_with(1);
        assert_eq!(cut.lists.cap, Some(cap));
        assert!(cap > 1 && kept <= 2 * texels);
        assert_eq!(cut.lists.pieces, kept);
        assert_eq!(cut.lists.cut, whole.lists.pieces - kept);
        // Each texel's list is its `cap` longest pieces, in time order.
        for (all, left) in texel_lists(&whole).iter().zip(texel_lists(&cut)) {
            let mut longest: Vec<usize> = (0..all.len()).collect();
            longest.sort_by(|&a, &b| {
                (all[b][1] - all[b][0])
                    .total_cmp(&(all[a][1] - all[a][0]))
                    .then(a.cmp(&b))
            });
            longest.truncate(cap);
            longest.sort_unstable();
            let expected: Vec<[f64; 2]> = longest.iter().map(|&i| all[i]).collect();
            assert_eq!(left, expected);
        }
        assert_eq!(texel_lists(&cut_with(2)), texel_lists(&cut));
        assert!(prepared.occluders_within(budget, false).is_none());
    }

    #[test]
    fn lists_keep_the_full_cap_up_to_four_samples_a_pixel_and_a_tiles_worth_beyond() {
        assert_eq!(list_cap(1), MAX_INTERVALS_PER_SAMPLE);
        assert_eq!(list_cap(4), MAX_INTERVALS_PER_SAMPLE);
        assert_eq!(list_cap(64), MIN_INTERVALS_PER_SAMPLE);
        for samples in 1..=64 {
            let tile = (TILE_PX * TILE_PX) as usize * samples * list_cap(samples);
            assert!(
                tile <= MAX_INTERVALS_PER_TILE || list_cap(samples) == MIN_INTERVALS_PER_SAMPLE,
                "{samples} samples a pixel"
            );
        }
        assert!((list_cap(9)..MAX_INTERVALS_PER_SAMPLE).contains(&list_cap(5)));
    }

    #[test]
    fn a_list_holds_hundreds_of_pieces_before_it_compresses() {
        // 200 passes: up to 400 pieces on a texel and on an image sample under the path, past the
        // 256 a list held before and within 1,024, so no list is compressed and none dropped.
        let scene = zigzag_over_floor(16, 200);
        let plan = Plan::with_lod(&scene, &Method::ANALYTIC, Lod::Off).unwrap();
        let prepared = prepared_light(&plan, plan.shadow_cameras[0].clone());
        let lists = prepared.occluders_within(usize::MAX, false).unwrap().lists;
        assert!(lists.peak_per_texel > MIN_INTERVALS_PER_SAMPLE, "{lists:?}");
        assert_eq!((lists.compressed, lists.dropped), (0, 0), "{lists:?}");
        let image = draw(&plan, Exposure::Shutter).stats;
        assert!(
            image.peak_per_sample > MIN_INTERVALS_PER_SAMPLE,
            "{image:?}"
        );
        assert_eq!((image.compressed, image.dropped), (0, 0), "{image:?}");
    }

    #[test]
    fn a_shadow_map_over_its_budget_is_drawn_coarser_before_its_lists_are_cut() {
        // The same zig-zag in a 64² map, with a budget that its 32² map fits.
        let scene = zigzag_over_floor(64, 20);
        let plan = Plan::with_lod(&scene, &Method::ANALYTIC, Lod::Off).unwrap();
        let camera = &plan.shadow_cameras[0];
        let lists = |side: u32| {
            let camera = camera.resized(side, side).unwrap();
            let whole = prepared_light(&plan, camera).occluders_within(usize::MAX, false);
            whole.unwrap().lists
        };
        let held = |side: u32| lists(side).pieces + lists(side).records;
        let budget = held(32);
        assert!(held(64) > budget, "{} {budget}", held(64));
        let occluders = shadow_occluders(&plan, camera, Exposure::Shutter, budget);
        assert_eq!(occluders.camera.width, 32);
        assert_eq!(occluders.lists.coarsened, Some((64, 32)));
        assert_eq!(
            (occluders.lists.pieces, occluders.lists.cap),
            (lists(32).pieces, None)
        );
        // With room for the whole map, it is drawn as asked.
        let whole = shadow_occluders(&plan, camera, Exposure::Shutter, held(64));
        assert_eq!((whole.camera.width, whole.lists.coarsened), (64, None));
    }

    #[test]
    fn a_shadow_map_of_more_texels_than_its_budget_is_drawn_coarser_too() {
        // One pass of the square: fewer pieces than the 64² map has texels, but not fewer than
        // its pieces and texel records together. Such a map once held one piece a texel past its
        // budget (eight lights' 4096² maps over a floor: 85.6 M pieces, 5.2 GB).
        let scene = zigzag_over_floor(64, 1);
        let plan = Plan::with_lod(&scene, &Method::ANALYTIC, Lod::Off).unwrap();
        let camera = &plan.shadow_cameras[0];
        let whole = shadow_occluders(&plan, camera, Exposure::Shutter, usize::MAX).lists;
        assert!(whole.pieces < 64 * 64 && whole.records > 0, "{whole:?}");
        let budget = whole.pieces;
        let fitted = shadow_occluders(&plan, camera, Exposure::Shutter, budget);
        assert!(fitted.camera.width < 64, "{:?}", fitted.lists);
        assert_eq!(fitted.lists.cap, None);
        assert!(fitted.lists.pieces + fitted.lists.records <= budget);
    }

    #[test]
    fn a_sample_with_more_visible_pieces_than_it_holds_compresses_seldom_and_keeps_the_longest() {
        // 2,000 pieces one after another in time, alternately of two items (nothing joins), the
        // odd ones five times longer: every piece is visible, far more than a list holds.
        let mut scratch = Scratch::default();
        scratch.reset(1, MAX_INTERVALS_PER_SAMPLE);
        let mut stats = TriangleStats::default();
        let mut t = 0.0;
        for k in 0..2000u32 {
            let length = if k % 2 == 1 { 5e-4 } else { 1e-4 };
            let piece = Interval {
                t: [t, t + length],
                depth: [1.0 + f64::from(k % 7), 1.0],
                item: k % 2,
                bends: false,
            };
            t += length;
            scratch.push(0, piece, &intervals::AsIs, &mut stats);
            assert!(scratch.lists[0].len() <= MAX_INTERVALS_PER_SAMPLE);
        }
        // Each compression leaves room for LIST_SLACK more: at most one per that many pieces
        // past the first full list.
        let most = (2000 - MAX_INTERVALS_PER_SAMPLE) / LIST_SLACK + 1;
        assert!(
            stats.compressed <= most,
            "{} compressions",
            stats.compressed
        );
        assert!(stats.dropped > 0);
        // What was dropped was short: all but a few of the long pieces are kept.
        let long = scratch.lists[0]
            .iter()
            .filter(|i| i.t[1] - i.t[0] > 2e-4)
            .count();
        assert!(
            long >= scratch.lists[0].len() - LIST_SLACK,
            "{long} long pieces"
        );
    }

    #[test]
    fn a_corner_on_an_arc_follows_its_least_squares_line_and_a_straight_path_keeps_its_chord() {
        // Corner 0 turns 30° on a unit circle, whose chord misses it by the sagitta M at its
        // middle; corner 1 moves on a straight line.
        let angle = 30f64.to_radians();
        let arc = |u: f64| DVec3::new((angle * u).cos(), (angle * u).sin(), -5.0);
        let line = |u: f64| DVec3::new(u, 2.0 * u, -3.0);
        let (start, end) = fitted_paths(|t| vec![arc(t), line(t)], [0.0, 1.0]);
        assert_eq!((start[1], end[1]), (line(0.0), line(1.0)));
        let sagitta = 1.0 - (0.5 * angle).cos();
        // RMS distance at equal times over the sub-segment: 0.73 M for the chord, 0.30 M for
        // the fitted line.
        let rms = |from: DVec3, to: DVec3| {
            let n = 1000;
            let sum: f64 = (0..n)
                .map(|i| {
                    let u = (i as f64 + 0.5) / n as f64;
                    from.lerp(to, u).distance_squared(arc(u))
                })
                .sum();
            (sum / n as f64).sqrt() / sagitta
        };
        let (chord, fitted) = (rms(arc(0.0), arc(1.0)), rms(start[0], end[0]));
        assert!((chord - 0.73).abs() < 0.01, "{chord}");
        assert!((fitted - 0.30).abs() < 0.01, "{fitted}");
    }

    #[test]
    fn a_screen_hull_bounds_each_band_of_rows_by_its_edges() {
        // A unit triangle at the origin sliding 4 px right: its hull has corners (0, 0), (5, 0),
        // (4, 1) and (0, 1); the other two points lie on or inside it and drop out.
        let start = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.0, 1.0),
        ];
        let corners: [DVec2; 6] =
            std::array::from_fn(|i| start[i % 3] + DVec2::X * if i < 3 { 0.0 } else { 4.0 });
        let hull = ScreenHull::new(&corners);
        assert_eq!(
            hull.count, 4,
            "the start's (1, 0) and the end's (4, 1) lie inside"
        );
        assert_eq!(hull.x_range(0.0, 0.0), Some([0.0, 5.0]));
        assert_eq!(hull.x_range(0.5, 0.5), Some([0.0, 4.5]));
        assert_eq!(hull.x_range(0.25, 1.5), Some([0.0, 4.75]));
        assert_eq!(hull.x_range(1.01, 2.0), None);
        assert_eq!(hull.x_range(-3.0, -0.01), None);
        // Every point of the path lies within its band's range.
        for step in 0..=8 {
            let shift = 0.5 * f64::from(step);
            for (u, v) in [(0.2, 0.3), (0.9, 0.05), (0.0, 1.0), (0.5, 0.5)] {
                let p = DVec2::new(u * (1.0 - v) + shift, v);
                let [lo, hi] = hull.x_range(p.y, p.y).unwrap();
                assert!(lo <= p.x && p.x <= hi, "{p} outside [{lo}, {hi}]");
            }
        }
        // All six points the same (a still corner set): a one-point hull.
        let point = ScreenHull::new(&[DVec2::new(2.0, 3.0); 6]);
        assert_eq!(point.x_range(2.5, 3.5), Some([2.0, 2.0]));
        assert_eq!(point.x_range(3.5, 4.0), None);
    }

    #[test]
    fn a_run_is_cut_where_its_pieces_turn_from_a_spot() {
        // One piece of a run moving past a spot light while its normal turns from facing it to
        // facing away: N·(S − P), the normal lerped and not made unit, is quadratic in u and
        // its root is where the run's light must be cut. The middle value comes from the two
        // ends alone, as the run's shading takes it.
        let spot =
            crate::scene::Spot::new(DVec3::new(0.0, 0.0, 3.0), DVec3::ZERO, 60.0, 1.0, false)
                .unwrap();
        let source = LightSource::Spot(&spot);
        let end = |normal: DVec3, point: DVec3| SurfacePoint {
            normal: normal.normalize(),
            point,
            albedo: [1.0; 3],
        };
        let (a, b) = (
            end(DVec3::new(0.2, 0.0, 1.0), DVec3::new(-1.0, 0.0, 0.0)),
            end(DVec3::new(1.0, 0.0, -0.3), DVec3::new(1.5, 0.0, 0.5)),
        );
        let exact = |u: f64| {
            a.normal
                .lerp(b.normal, u)
                .dot(spot.position - a.point.lerp(b.point, u))
        };
        // Bisection on the exact quadratic, which changes sign once on [0, 1].
        let (mut lo, mut hi) = (0.0, 1.0);
        assert!(exact(lo) > 0.0 && exact(hi) < 0.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if exact(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let span = [0.1, 0.9];
        let values = [
            source.facing(a.normal, a.point),
            a.facing_midway(&b, &source),
            source.facing(b.normal, b.point),
        ];
        let mut cuts = Vec::new();
        assert!(!cut_where_turning(values, span, &mut cuts));
        assert_eq!(cuts.len(), 1, "{cuts:?}");
        let expected = span[0] + lo * (span[1] - span[0]);
        assert!(
            (cuts[0] - expected).abs() < 1e-12,
            "{cuts:?} against {expected}"
        );
        // The middle taken from a unit normal misses it.
        let unit_middle = a.lerp(&b, 0.5);
        let mut unit_cuts = Vec::new();
        let unit_values = [
            values[0],
            source.facing(unit_middle.normal, unit_middle.point),
            values[2],
        ];
        cut_where_turning(unit_values, span, &mut unit_cuts);
        assert!((unit_cuts[0] - expected).abs() > 1e-3, "{unit_cuts:?}");
    }

    #[test]
    fn a_normal_turning_edge_on_is_cut_where_its_unnormalized_facing_crosses_zero() {
        // A piece's normal lerps from n0 to n1 over [0.2, 0.6]; under a directional light N·L
        // changes sign where the lerp's own dot product does: at u = f0/(f0 − f1), its values
        // linear in u. Taken through the unit normals instead, the fit misses that time.
        let (n0, n1) = (DVec3::X, DVec3::new(-0.3, 0.0, 1.0).normalize());
        let light = DVec3::new(1.0, 0.0, 0.2).normalize();
        let span = [0.2, 0.6];
        let exact = {
            let (f0, f1) = (n0.dot(light), n1.dot(light));
            span[0] + f0 / (f0 - f1) * (span[1] - span[0])
        };
        let root = |unit: bool| {
            let values = [0.0, 0.5, 1.0].map(|u| {
                let n = n0.lerp(n1, u);
                if unit { n.normalize() } else { n }.dot(light)
            });
            let mut cuts = Vec::new();
            assert!(!cut_where_turning(values, span, &mut cuts));
            assert_eq!(cuts.len(), 1, "{cuts:?}");
            cuts[0]
        };
        assert!((root(false) - exact).abs() < 1e-12);
        assert!((root(true) - exact).abs() > 1e-3);
    }
}
