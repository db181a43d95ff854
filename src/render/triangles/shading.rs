//! The colour of a sample over the exposure: its visible pieces cut where shading changes
//! within them, shaded (deferred, after the resolve; Palmér §2.3.2) and integrated over time.

use glam::DVec3;

use super::intervals::{resolve, Interval};
use super::shadow::{self, Receiver, MAX_SHADOWED_LIGHTS};
use super::tct::{MovingTriangle, RayDepth, RayHit};
use super::{
    depth_pieces, unshadowed_of, AlongRay, Exposure, Item, Prepared, Scratch, TileShared,
    TriangleStats, GAUSS_LEGENDRE_3, WHOLE_OBJECT,
};
use crate::render::Receivers;
use crate::scene::{LightSource, ShutterShape};

/// The shading normal at segment fraction `s` between the world `normals` at its ends
/// (interpolated linearly and normalized, Palmér §2.3.2).
pub(super) fn unit_between([n0, n1]: [DVec3; 2], s: f64) -> DVec3 {
    n0.lerp(n1, s).normalize_or_zero()
}

/// A plain item's world shading normals at its segment's ends, and its colour.
#[derive(Clone, Copy)]
pub(super) struct PlainFace {
    pub(super) normals: [DVec3; 2],
    /// The unit normal at the segment's start ([`unit_between`] at 0): a still face's at
    /// every sample.
    pub(super) at_start: DVec3,
    pub(super) albedo: [f64; 3],
}

/// Working memory of a run's shading, reused from run to run.
#[derive(Default)]
pub(super) struct ShadingScratch {
    /// The times a visible piece is cut at for shading.
    cuts: Vec<f64>,
    /// The surface at the ends of a run's pieces.
    ends: Vec<SurfacePoint>,
    /// Bounds on each piece's depth along the ray.
    ranges: Vec<Option<[f64; 2]>>,
    /// The run's linear depth pieces, where they are shaded one by one.
    pieces: Vec<Interval>,
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

impl Prepared<'_> {
    /// The colour of one sample over the exposure, and the depth beyond which it sees nothing.
    pub(super) fn sample_colour(
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
                    let unshadowed = scratch.tile.unshadowed(index);
                    if self.scene.lighting.is_lit() {
                        let left_out = unshadowed.iter().take(self.shadows.len());
                        let left_out = left_out.filter(|&&u| u).count();
                        stats.shadow_lookups_left_out += left_out;
                        stats.shadow_lookups += self.shadows.len() - left_out;
                    }
                    let colour = match self.plain_at_start(index, d, depth, &scratch.tile) {
                        Some(surface) => self.shade_at(item, surface, t, unshadowed),
                        None => self.shade(item, &self.corners(item), d, (0.0, t), unshadowed),
                    };
                    (colour, depth)
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
    ///
    /// [`ShadowMap::surely_lit_between`]: shadow::ShadowMap::surely_lit_between
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
    ///
    /// [`ShadowMap::surely_lit`]: shadow::ShadowMap::surely_lit
    /// [`ShadowMap::mean_visibility`]: shadow::ShadowMap::mean_visibility
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
    ///
    /// [`ShadowMap::breakpoints`]: shadow::ShadowMap::breakpoints
    /// [`ShadowMap::traced_breakpoints`]: shadow::ShadowMap::traced_breakpoints
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
            // At the depth its interval keeps (a still face's all along, as it was inserted).
            let surface = self
                .plain_at_start(piece.item, d, piece.depth[0], tile)
                .unwrap_or_else(|| self.surface_point(item, &self.corners(item), d, 0.0));
            let unshadowed = unshadowed_of(tile.of(piece.item));
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
            let unshadowed = tile.unshadowed(piece.item);
            self.shade(item, &triangle, d, (fraction(span[0]), span[0]), unshadowed)
        }
    }

    /// `interval` of the ray `d` as the linear depth pieces [`DepthPieces::AtOnce`] would have
    /// inserted, appended to `out`, its ends kept exactly. A still triangle's depth is one line;
    /// where the depth is undefined inside the interval, it stays the line between its ends.
    ///
    /// [`DepthPieces::AtOnce`]: super::DepthPieces::AtOnce
    pub(super) fn depth_pieces_of(
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

    /// The surface where the ray `d` meets item `index` at `depth` at its segment's start, from
    /// the tile's copy of its plane and shading: `None` unless the tile holds it as a plain face.
    fn plain_at_start(
        &self,
        index: u32,
        d: DVec3,
        depth: f64,
        tile: &TileShared,
    ) -> Option<SurfacePoint> {
        let entry = tile.of(index)?;
        let hit = entry.depth.hit_at_start_with(d, depth);
        Some(self.plain_surface_point(&hit, d, 0.0, &entry.plain?))
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
    pub(super) fn world_normals(&self, item: &Item, weights: [f64; 3]) -> [DVec3; 2] {
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
    /// shading. The shadow maps `unshadowed` marks (they hold nothing but the item's own
    /// occluders where its tile's samples can look) are not looked up: they leave it lit.
    fn shade(
        &self,
        item: &Item,
        triangle: &MovingTriangle,
        d: DVec3,
        (s, t): (f64, f64),
        unshadowed: [bool; MAX_SHADOWED_LIGHTS],
    ) -> [f64; 3] {
        if !self.scene.lighting.is_lit() {
            return self.albedo(item, triangle, d, s);
        }
        self.shade_at(
            item,
            self.surface_point(item, triangle, d, s),
            t,
            unshadowed,
        )
    }

    /// [`Prepared::shade`] of the `surface` a sample sees on `item` at time `t`.
    fn shade_at(
        &self,
        item: &Item,
        surface: SurfacePoint,
        t: f64,
        unshadowed: [bool; MAX_SHADOWED_LIGHTS],
    ) -> [f64; 3] {
        let SurfacePoint {
            normal,
            point: p,
            albedo,
        } = surface;
        if !self.scene.lighting.is_lit() {
            return albedo;
        }
        let own = self.shadow_id(item);
        let mut visibility = [1.0; MAX_SHADOWED_LIGHTS];
        for ((v, map), unshadowed) in visibility.iter_mut().zip(&self.shadows).zip(unshadowed) {
            if !unshadowed {
                *v = map.visibility(p, normal, t, own);
            }
        }
        let irradiance = self.irradiance(normal, p, &visibility);
        albedo.map(|c| c * irradiance)
    }

    /// What `item`'s pieces are known by in shadow maps, and what its receivers leave out of
    /// them: its triangle (Palmér's polygon IDs), or the whole object, as [`WHOLE_OBJECT`],
    /// where the object cannot shadow itself ([`TriangleMesh::shadows_itself`]).
    ///
    /// [`TriangleMesh::shadows_itself`]: crate::scene::TriangleMesh::shadows_itself
    pub(super) fn shadow_id(&self, item: &Item) -> (u32, u32) {
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
    pub(super) fn albedo_with(&self, item: &Item, weights: [f64; 3]) -> [f64; 3] {
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
}

#[cfg(test)]
mod tests {
    use super::*;

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
