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

mod hull;
pub(crate) mod intervals;
mod occluders;
mod shading;
pub(crate) mod shadow;
pub(crate) mod tct;

use glam::{DAffine3, DMat3, DVec2, DVec3};

use crate::framebuffer::Framebuffer;
use crate::plan::{ObjectMotion, Plan};
use crate::raster::{TileGrid, TileLists, TILE_PX};
use crate::render::{Method, Receivers};
use crate::scene::{Camera, LightSource, Object, Scene, TriangleMesh, MIN_SHADOW_MAP};
use hull::{screen_corners, PathHull};
use intervals::{resolve, BentDepth, Interval, ResolveScratch};
use occluders::shadow_occluders;
use shading::{unit_between, PlainFace, ShadingScratch};
pub use shadow::MAX_SHADOWED_LIGHTS;
use shadow::{Casters, Occluder, ShadowMap, TEXEL_RECORD_BYTES};
pub use shadow::{ShadowLists, MAX_SHADOW_PIECES};
use tct::{DepthFunction, EdgeFunctions, MovingTriangle, RayDepth};

/// Most triangle items (a triangle over one sub-segment, 28 bytes each plus its corners) one
/// render may hold.
pub const MAX_TRIANGLE_ITEMS: usize = 1 << 24;

/// Most items one tile keeps a shared copy of for its samples (`TileItem`: its depth function,
/// plain face and which shadow maps leave it unshadowed, 240 bytes; 15 MiB a thread). A tile's
/// further items are read from their corners by each sample, as the shared copy would give them,
/// more slowly. A bunny of 69,451 triangles spun over 241 sub-segments at 48 × 36 put millions
/// of items in one tile and peaked at 5.7 GB with every one copied.
pub const MAX_TILE_SHARED_ITEMS: usize = 1 << 16;

/// Most intervals one sample's list keeps, an image sample's or a shadow-map texel's (about
/// 40 kB): past it the list is resolved to its visible pieces (Gribel's compression); when that
/// leaves less than [`LIST_SLACK`] free, each triangle's consecutive pieces are joined into one
/// line; and only then do the shortest pieces go, down to that slack (all counted), each one's
/// time given to a kept piece it adjoins (docs/math.md, "Resolve"), so that a surface covering the
/// sample all along keeps covering it. A dense mesh moving fast fills many: the armadillo's
/// 100,000 triangles sliding 90 px at 320 × 240 peak at 554 on one sample, and at a cap of 256
/// its samples dropped 902,734 pieces, RMSE against the reference 2.7·10⁻³ (1.2·10⁻⁴ with none
/// dropped). In a shadow map a dropped piece is a shadow missing for its time; what the texels
/// keep together is bounded by [`MAX_SHADOW_PIECES`].
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
    /// Intervals that went because a list was still full after compression, their time left
    /// to what lies behind.
    pub dropped: usize,
    /// Intervals that went so, their time given to a kept piece they adjoined.
    pub absorbed: usize,
    /// Samples a triangle item was left out of unsolved: it lies wholly deeper there than a
    /// still triangle covering the sample all along.
    pub hidden_behind_still: usize,
    /// Item × tile pairs past [`MAX_TILE_SHARED_ITEMS`] in their tile, read from their corners.
    pub unshared_tile_items: usize,
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
    /// Shadow-map lookups at an instant (`static`, each `reference` frame): one per lit sample
    /// and shadow map, made.
    pub shadow_lookups: usize,
    /// Of the same, left out: the sample's tile reads nothing in that map but its own
    /// triangle's occluders (docs/math.md, "Tiles no shadow reaches"), so it is lit.
    pub shadow_lookups_left_out: usize,
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
        if self.unshared_tile_items > 0 {
            out.push_str(&format!(
                "  {} item × tile pairs past the {MAX_TILE_SHARED_ITEMS} items a tile keeps a shared copy of: read from their corners at each sample (the same surfaces, more slowly)\n",
                self.unshared_tile_items
            ));
        }
        if self.shadow_lookups + self.shadow_lookups_left_out > 0 {
            out.push_str(&format!(
                "  shadow lookups at an instant: {} made, {} left out (the sample's tile reads nothing in that map but its own triangle's occluders)\n",
                self.shadow_lookups, self.shadow_lookups_left_out
            ));
        }
        if self.intervals > 0 {
            out.push_str(&format!(
                "  analytic visibility: {} intervals, at most {} on one sample (cap {}); {} lists compressed, {} of them joined to one line per triangle, {} short pieces given to the piece they adjoin in time and {} dropped; {} item × sample pairs left out unsolved, wholly behind a still triangle covering the sample all along\n",
                self.intervals, self.peak_per_sample, list_cap(self.spatial_samples as usize), self.compressed, self.joined, self.absorbed, self.dropped, self.hidden_behind_still
            ));
            out.push_str(&format!(
                "  shading: {} visible pieces in {} runs of one triangle ({} runs of several sub-segments shaded as one), {} pieces point-sampled in shadow-map time (dynamic receivers that may be shadowed)\n",
                self.pieces, self.runs, self.joined_runs, self.point_sampled
            ));
        }
        out
    }

    /// Where drawing the triangles departed from the scene, one short line each: items left
    /// out too far out for double precision, and shadow maps drawn coarser or with their lists
    /// cut to fit their budget. [`TriangleStats::explain`] says more.
    #[must_use]
    pub fn departures(&self) -> Vec<String> {
        let lists = &self.shadow_lists;
        let too_far = (self.too_far > 0).then(|| {
            format!(
                "{} triangle item(s) left out: a corner lies beyond {:e} of the eye, where double precision overflows (scale the scene down)",
                self.too_far,
                tct::MAX_CORNER_COORDINATE
            )
        });
        let coarsened = lists.coarsened.map(|(asked, drawn)| {
            format!("a shadow map of {asked}² texels drawn at {drawn}² to fit its memory budget (softer shadow edges)")
        });
        let cut = lists.cap.map(|cap| {
            format!(
                "shadow-map texel lists cut to their {cap} longest pieces to fit their memory budget ({} shorter shadows left out)",
                lists.cut
            )
        });
        let full_texels = (lists.dropped > 0).then(|| {
            format!(
                "shadow-map texel lists full at their cap: {} short occluder pieces went (shadows that short may be missing)",
                lists.dropped
            )
        });
        let full = (self.absorbed + self.dropped > 0).then(|| {
            format!(
                "sample lists full at their cap of {}: {} short visible pieces given to the piece they adjoin in time (drawn as that surface), {} dropped (their time shows what lies behind)",
                list_cap(self.spatial_samples as usize),
                self.absorbed,
                self.dropped
            )
        });
        [too_far, coarsened, cut, full_texels, full]
            .into_iter()
            .flatten()
            .collect()
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
        self.absorbed += other.absorbed;
        self.hidden_behind_still += other.hidden_behind_still;
        self.unshared_tile_items += other.unshared_tile_items;
        self.shadow_lookups += other.shadow_lookups;
        self.shadow_lookups_left_out += other.shadow_lookups_left_out;
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
    /// For a still triangle reaching behind the near plane (a floor under the eye, a wall past
    /// a spot light), the near plane's depth: it covers a sample only where the sample's ray
    /// meets it at least that deep. Its edge tests, planes through the eye, hold on either side
    /// of the eye, and its hit behind the eye is met at a negative depth.
    near: Option<f64>,
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
                Exposure::Instant(_) => map.summarised_by_tile(),
            }
        })
        .collect();
    Prepared::new(plan, scene.camera.clone(), exposure, shadows).render()
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
                // A plan for instants draws no exposure; were it asked to, one chord over the
                // shutter is its coarsest reading.
                (Exposure::Shutter, ObjectMotion::Instants { .. }) => vec![(shutter, shutter)],
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
        let still = triangle.is_still();
        let (window, near) = triangle
            .near_window(self.camera.near)
            .map_or(([0.0, 0.0], None), |(window, tested)| {
                (window, tested.then_some(self.camera.near))
            });
        Placed {
            near,
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

    /// Every triangle over every segment that is in front of the near plane some of the time (a
    /// still one: some of it) and on screen, with its pixel bounds: the projections of its
    /// corners at the ends of its time in front (a segment's straight path in camera space
    /// projects to a straight path on screen, so they bound it), widened by a pixel; the whole
    /// image for a still one reaching behind the near plane.
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
            for (s, segment) in segments.iter().enumerate() {
                // A closed mesh's back faces lie behind its front faces only for an eye outside
                // it. Its vertices move on straight lines over the segment, so it lies within the
                // box of their ends all along, and an eye (the origin) outside that box is
                // outside the mesh; a light inside a closed box sees only back faces.
                let cull_back = mesh.closed
                    && !box_holds_origin(segment.start.iter().chain(&segment.end).copied());
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
                    let Some((window, _)) = triangle.near_window(camera.near) else {
                        behind_near += 1;
                        continue;
                    };
                    near_clipped |= window != [0.0, 1.0];
                    if cull_back && triangle.back_facing_throughout() {
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
        let mut rays = std::mem::take(&mut scratch.rays);
        rays.clear();
        for y in y0..y1 {
            for x in x0..x1 {
                rays.extend(
                    offsets
                        .iter()
                        .map(|[ox, oy]| self.camera.ray(f64::from(x) + ox, f64::from(y) + oy)),
                );
            }
        }
        let grid = SampleGrid::new(bounds, offsets, &rays);
        scratch.tile.clear(self.items.len());
        let cut_later = self.exposure == Exposure::Shutter && depth == DepthPieces::OnDemand;
        // At an instant the tile's items are kept to learn which shadow maps shadow none of them,
        // so that their samples look up no shadow there, and for a plain item's shading, which
        // its samples then read from the tile rather than from its corners.
        let instant = matches!(self.exposure, Exposure::Instant(_));
        let kept_shared = cut_later || instant;
        let corners = self.corner_rays(bounds);
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
                let share = kept_shared && scratch.tile.entries.len() < MAX_TILE_SHARED_ITEMS;
                stats.unshared_tile_items += usize::from(kept_shared && !share);
                if share {
                    let bounds @ [near, far] = depth_bounds_within(&placed.triangle, corners);
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
        scratch.rays = rays;
        if kept_shared {
            let casters = self.casters_seen(corners, depth_bounds);
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
            spread,
            rays,
        } = *grid;
        let w = (x1 - x0) as usize;
        let per_pixel = offsets.len();
        let [ix0, iy0, ix1, iy1] = self.items[index as usize].bounds;
        // A triangle covers samples within the hull of its corners' screen paths only; the
        // rest of its bounds are skipped a row at a time.
        let hull = PathHull::new(camera, &placed.triangle, placed.window);
        let [nearest, _] = placed.triangle.depth_bounds();
        let no_tile = TileShared::default();
        for y in iy0.max(y0)..iy1.min(y1) {
            let (mut from, mut to) = (ix0.max(x0), ix1.min(x1));
            if let Some(hull) = &hull {
                let Some([lo, hi]) = hull.columns(y, spread) else {
                    continue;
                };
                (from, to) = (from.max(lo), to.min(hi));
            }
            for x in from..to {
                let pixel = (y - y0) as usize * w + (x - x0) as usize;
                let first = pixel * per_pixel;
                for (sample, &d) in (first..).zip(&rays[first..first + per_pixel]) {
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
        let w = (x1 - x0) as usize;
        let per_pixel = offsets.len();
        let background = self.scene.background.map(f64::from);
        let mut pixels = std::mem::take(&mut scratch.pixels);
        pixels.clear();
        for pixel in 0..w * (y1 - y0) as usize {
            let mut sum = [0.0f64; 3];
            let mut hidden = f64::NEG_INFINITY;
            for sample in pixel * per_pixel..(pixel + 1) * per_pixel {
                let d = scratch.rays[sample];
                let (colour, beyond) = self.sample_colour(scratch, sample, d, background, stats);
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
}

/// Whether the bounding box of `points` holds the origin (on its faces included).
fn box_holds_origin(points: impl Iterator<Item = DVec3>) -> bool {
    let (lo, hi) = crate::math::bounds(points);
    lo.cmple(DVec3::ZERO).all() && hi.cmpge(DVec3::ZERO).all()
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
    match triangle
        .is_still()
        .then(|| triangle.plane_depths_within(rays))
    {
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

/// A tile's samples: its pixels, the samples' offsets within each, and their rays.
#[derive(Clone, Copy)]
struct SampleGrid<'o> {
    /// Pixel bounds [x0, y0, x1, y1).
    bounds: [u32; 4],
    offsets: &'o [[f64; 2]],
    /// The box the offsets span, [x0, y0, x1, y1].
    spread: [f64; 4],
    /// Each sample's ray, pixel by pixel along rows, a pixel's samples in `offsets`' order.
    rays: &'o [DVec3],
}

impl<'o> SampleGrid<'o> {
    fn new(bounds: [u32; 4], offsets: &'o [[f64; 2]], rays: &'o [DVec3]) -> SampleGrid<'o> {
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
            rays,
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
    /// The ray of each sample of the tile ([`Camera::ray`]), worked out once for its items.
    ///
    /// [`Camera::ray`]: crate::scene::Camera::ray
    rays: Vec<DVec3>,
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
        let in_front = |depth: &f64| placed.near.is_none_or(|near| *depth >= near);
        if let Some(depth) = triangle.depth(d, 0.0).filter(in_front) {
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
                .filter(|&z| placed.near.is_none_or(|near| z >= near))
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
            if list.len() >= room {
                // Still nearly full: the shortest visible pieces go, down to the slack with the
                // new interval, their time to the pieces they adjoin. The new interval stays: it
                // is not resolved yet, and its time may be no one else's.
                let before = list.len();
                let absorbed = absorb_shortest(list, room - 1, &mut self.by_length);
                stats.absorbed += absorbed;
                stats.dropped += before - list.len() - absorbed;
            }
        }
        let list = &mut self.lists[sample];
        list.push(interval);
        stats.intervals += 1;
        stats.peak_per_sample = stats.peak_per_sample.max(list.len());
    }
}

/// How far apart in time (of the frame) two pieces' ends may lie and still adjoin: the roots that
/// end one face's coverage and start the next one's are solved apart, and round apart.
const ADJOINING: f64 = 1e-9;

/// Keep the `keep` longest of `list`'s visible pieces (in time order; ties to the earlier), each
/// one that goes handing its time to a kept piece it adjoins: within a run of pieces back to back
/// in time, to the kept piece before it, or at the run's start to the first one after, that
/// piece's depth then the line between the two ends; a run holding none of the longest keeps its
/// own longest. A surface that covered the sample all along still covers it, drawn there as its
/// neighbour's triangle; only a piece with no neighbour in time leaves its time to what lies
/// behind. Returns how many went so (the others that went were dropped); a few more than `keep`
/// may stay, one per run that held none of the longest.
fn absorb_shortest(
    list: &mut Vec<Interval>,
    keep: usize,
    longest_first: &mut Vec<(f64, u32)>,
) -> usize {
    let mut kept = longest(list, keep, longest_first);
    let mut out = Vec::with_capacity(keep + 1);
    let mut absorbed = 0;
    let mut start = 0;
    while start < list.len() {
        let mut end = start + 1;
        while end < list.len() && (list[end].t[0] - list[end - 1].t[1]).abs() <= ADJOINING {
            end += 1;
        }
        if end - start > 1 && !kept[start..end].contains(&true) {
            let longest = (start..end)
                .max_by(|&a, &b| {
                    let length = |i: usize| list[i].t[1] - list[i].t[0];
                    length(a).total_cmp(&length(b)).then(b.cmp(&a))
                })
                .expect("a run holds pieces");
            kept[longest] = true;
        }
        let mut anchor = None;
        let mut before_first: Option<(f64, f64)> = None;
        for i in start..end {
            let mut piece = list[i];
            if kept[i] {
                if let Some((t, depth)) = before_first.take() {
                    (piece.t[0], piece.depth[0], piece.bends) = (t, depth, false);
                }
                out.push(piece);
                anchor = Some(out.len() - 1);
            } else if end - start > 1 {
                absorbed += 1;
                match anchor {
                    Some(a) => {
                        let into: &mut Interval = &mut out[a];
                        (into.t[1], into.depth[1], into.bends) =
                            (piece.t[1], piece.depth[1], false);
                    }
                    None => {
                        before_first.get_or_insert((piece.t[0], piece.depth[0]));
                    }
                }
            }
        }
        start = end;
    }
    *list = out;
    absorbed
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::Lod;

    /// A square crossing a floor `passes` times in one exposure under a light from above, with a
    /// shadow map `map` texels a side.
    pub(super) fn zigzag_over_floor(map: u32, passes: u32) -> Scene {
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
    pub(super) fn prepared_light<'a>(plan: &'a Plan<'a>, camera: Camera) -> Prepared<'a> {
        Prepared::new(plan, camera, Exposure::Shutter, Vec::new()).for_shadow_map()
    }

    #[test]
    fn each_departure_from_the_scene_is_one_note_and_routine_counts_none() {
        let routine = TriangleStats {
            items: 10,
            compressed: 3,
            shadow_lists: ShadowLists {
                compressed: 2,
                ..ShadowLists::default()
            },
            ..TriangleStats::default()
        };
        assert!(routine.departures().is_empty());
        let departed = TriangleStats {
            too_far: 2,
            dropped: 5,
            absorbed: 4,
            spatial_samples: 4,
            shadow_lists: ShadowLists {
                coarsened: Some((4096, 1024)),
                cap: Some(40),
                cut: 7,
                dropped: 6,
                ..ShadowLists::default()
            },
            ..routine
        };
        let notes = departed.departures();
        assert_eq!(notes.len(), 5, "{notes:?}");
        assert!(notes[0].starts_with("2 triangle item(s) left out"));
        assert!(notes[1].contains("4096² texels drawn at 1024²"));
        assert!(notes[2].contains("their 40 longest pieces") && notes[2].contains("(7 shorter"));
        assert!(notes[3].contains("6 short occluder pieces went"));
        assert!(
            notes[4].contains("cap of 1024: 4 short visible pieces given")
                && notes[4].contains("5 dropped")
        );
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
    fn a_sample_with_more_visible_pieces_than_it_holds_compresses_seldom_and_keeps_their_time() {
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
        // Every piece that went adjoined a kept one, which took its time.
        assert!(stats.absorbed > 0 && stats.dropped == 0, "{stats:?}");
        // The pieces still cover the whole time, back to back: the surface is not thinned (each
        // long piece took in the short ones after it, and the next compression joined the long
        // ones of one item).
        let list = &scratch.lists[0];
        assert_eq!(list[0].t[0], 0.0);
        assert!(list.windows(2).all(|pair| pair[0].t[1] == pair[1].t[0]));
        assert_eq!(list[list.len() - 1].t[1], t);
    }

    #[test]
    fn a_short_piece_with_no_neighbour_in_time_is_dropped_and_counted() {
        // Pieces with gaps between them: none adjoins another, so the shortest go with their
        // time, and are counted as dropped.
        let mut scratch = Scratch::default();
        scratch.reset(1, MAX_INTERVALS_PER_SAMPLE);
        let mut stats = TriangleStats::default();
        for k in 0..1500u32 {
            let start = f64::from(k) * 1e-3;
            let length = if k % 3 == 0 { 1e-4 } else { 5e-4 };
            let piece = Interval {
                t: [start, start + length],
                depth: [1.0, 1.0],
                item: k,
                bends: false,
            };
            scratch.push(0, piece, &intervals::AsIs, &mut stats);
        }
        assert!(stats.dropped > 0 && stats.absorbed == 0, "{stats:?}");
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
}
