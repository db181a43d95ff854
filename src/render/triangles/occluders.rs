//! A light's shadow map built from the same items and samples as the image, seen from the
//! light's camera with one sample per texel (Palmér §2.3), within a memory budget: coarser maps
//! first, then texel lists cut to their longest pieces.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::intervals::{resolve, AsIs, Interval};
use super::shadow::{cap_within, Occluder, Occluders, ShadowLists};
use super::{
    depth_bounds_within, longest, DepthPieces, Exposure, Prepared, Scratch, ScratchPool,
    TriangleStats,
};
use crate::plan::Plan;
use crate::raster::TileGrid;
use crate::scene::{Camera, MIN_SHADOW_MAP};

/// The occluders of the shadow map `camera` sees, within `budget` pieces: at the map's own
/// resolution where they fit, else with half the texels per side, and so on down to
/// [`MIN_SHADOW_MAP`]; only a map that does not fit even there has its texel lists cut
/// ([`Prepared::occluders_within`]). A coarser map keeps every occluder's time, so its shadows
/// keep their strength and soften at their edges, where cut lists would lose the shortest
/// shadows (a cube zig-zagging 150 times over a floor, texel lists then of 256: RMSE against the
/// converged reference 0.0364 cut to 80 pieces a texel, 0.0186 with half the texels per side,
/// as uncut).
pub(super) fn shadow_occluders(
    plan: &Plan,
    camera: &Camera,
    exposure: Exposure,
    budget: usize,
) -> Occluders {
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
    /// record: 20 bytes, less than a piece's 48) and for the end of its last list, so that a map
    /// of many texels cannot pass the budget one piece a texel.
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

impl Prepared<'_> {
    /// The occluders of every texel, seen from this (a light's) camera with one sample per texel,
    /// within `budget` ([`ShadowTile::held`]: pieces plus the texel records of tiles that hold
    /// any); `None` when they do not fit and `cut` is false. Tiles are built in parallel, each
    /// keeping its lists while the pieces held so far fit; once they would not, the rest are
    /// only counted, and at the end,
    /// if the map did not fit, every texel's list is cut to its longest pieces, as many as fit
    /// ([`cap_within`]), the tiles that were only counted built again. Which tiles were held
    /// depends on the thread schedule, the result does not: a map that fits was held whole, and
    /// one that does not is cut alike everywhere (or, not to be cut, given up once over, its tiles
    /// left unbuilt). At most about twice the budget is held while it is cut.
    pub(super) fn occluders_within(&self, budget: usize, cut: bool) -> Option<Occluders> {
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
                built.dropped = stats.dropped + stats.absorbed;
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

#[cfg(test)]
mod tests {
    use super::super::tests::{prepared_light, zigzag_over_floor};
    use super::*;
    use crate::lod::Lod;
    use crate::raster::TILE_PX;
    use crate::render::Method;

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
        // budget (eight lights' 4096² maps over a floor: 62.8 M pieces, 4.22 GB).
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
}
