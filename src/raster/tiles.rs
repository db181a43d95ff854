//! The tile grid both rasterizers work on: the image cut into squares ([`TILE_PX`] unless the
//! splat rasterizer asks for larger), each owning its pixels (so tiles render in parallel without
//! locks), items binned into per-tile lists, and per-tile results put back into one image.

use super::TILE_PX;
use rayon::prelude::*;
use std::cmp::Reverse;
use std::sync::{Mutex, PoisonError};

/// The image cut into tiles, row by row: tile `ty · tiles_x + tx` covers the pixels from
/// (tx, ty)·`tile_px`, cut at the image's edges.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileGrid {
    width: u32,
    height: u32,
    tile_px: u32,
    tiles_x: usize,
    tiles_y: usize,
}

impl TileGrid {
    /// The grid of [`TILE_PX`] tiles over a `width` × `height` image.
    pub(crate) fn new(width: u32, height: u32) -> TileGrid {
        TileGrid::with_tile_px(width, height, TILE_PX)
    }

    /// The grid of tiles `tile_px` on a side over a `width` × `height` image.
    pub(crate) fn with_tile_px(width: u32, height: u32, tile_px: u32) -> TileGrid {
        TileGrid {
            width,
            height,
            tile_px,
            tiles_x: width.div_ceil(tile_px) as usize,
            tiles_y: height.div_ceil(tile_px) as usize,
        }
    }

    /// The side of a tile, px.
    pub(crate) fn tile_px(&self) -> u32 {
        self.tile_px
    }

    /// Pixels in one row of tiles.
    pub(crate) fn band_len(&self) -> usize {
        self.width as usize * self.tile_px as usize
    }

    /// How many tiles there are.
    pub(crate) fn count(&self) -> usize {
        self.tiles_x * self.tiles_y
    }

    /// The index of the tile in column `tx` and row `ty`.
    pub(crate) fn index(&self, tx: u32, ty: u32) -> usize {
        ty as usize * self.tiles_x + tx as usize
    }

    /// The tiles of tile row `ty`, left to right.
    pub(crate) fn row(&self, ty: usize) -> std::ops::Range<usize> {
        ty * self.tiles_x..(ty + 1) * self.tiles_x
    }

    /// The pixel rectangle [x0, y0, x1, y1) of `tile`.
    pub(crate) fn pixels(&self, tile: usize) -> [u32; 4] {
        let x0 = (tile % self.tiles_x) as u32 * self.tile_px;
        let y0 = (tile / self.tiles_x) as u32 * self.tile_px;
        [
            x0,
            y0,
            (x0 + self.tile_px).min(self.width),
            (y0 + self.tile_px).min(self.height),
        ]
    }

    /// Where the pixels of `tile`'s block (its pixels row by row) lie in the band of its row of
    /// tiles: the [`Self::band_len`] pixels of the image's rows from the tile row's top.
    pub(crate) fn in_band(&self, tile: usize) -> impl Iterator<Item = usize> {
        let [x0, y0, x1, y1] = self.pixels(tile);
        let width = self.width as usize;
        (0..(y1 - y0) as usize)
            .flat_map(move |r| (x0 as usize..x1 as usize).map(move |x| r * width + x))
    }
}

/// `work(index, item)` for each of `items` in parallel, the results in item order. Items are
/// handed out one at a time, the costliest first (by `cost` of the index, ties in index order), to
/// whichever thread is free: an image's work gathers in the tiles its objects cover, and rayon's
/// halving split of the items in image order can leave one thread the last heavy rows while the
/// others wait. Which thread runs an item changes nothing in its result.
fn costliest_first<T: Send, R: Send>(
    items: Vec<T>,
    cost: impl Fn(usize) -> usize,
    work: impl Fn(usize, T) -> R + Sync,
) -> Vec<R> {
    let count = items.len();
    let mut queue: Vec<(usize, T)> = items.into_iter().enumerate().collect();
    queue.sort_by_key(|&(index, _)| (Reverse(cost(index)), index));
    let queue = Mutex::new(queue.into_iter());
    let next = || queue.lock().unwrap_or_else(PoisonError::into_inner).next();
    let mut done: Vec<(usize, R)> = (0..rayon::current_num_threads().min(count))
        .into_par_iter()
        .with_max_len(1)
        .flat_map_iter(|_| {
            let mut done = Vec::new();
            while let Some((index, item)) = next() {
                done.push((index, work(index, item)));
            }
            done
        })
        .collect();
    done.sort_unstable_by_key(|&(index, _)| index);
    done.into_iter().map(|(_, result)| result).collect()
}

/// Items binned per tile in fixed chunks of this many, in parallel; the chunks' lists are then
/// joined in item order, so the lists do not depend on the thread count.
const BINNING_CHUNK: usize = 1 << 13;

/// Item indices binned by tile, each tile's in increasing item order (a compressed list: one
/// array of entries and each tile's start in it).
#[derive(Clone, Debug, Default)]
pub(crate) struct TileLists {
    starts: Vec<usize>,
    entries: Vec<u32>,
}

impl TileLists {
    /// Bin items 0..`count`; `tiles_of(item, visit)` calls `visit` with each tile the item
    /// touches (each at most once).
    pub(crate) fn new(
        grid: &TileGrid,
        count: usize,
        tiles_of: impl Fn(u32, &mut dyn FnMut(usize)) + Sync,
    ) -> TileLists {
        let chunks: Vec<Vec<(u32, u32)>> = (0..count.div_ceil(BINNING_CHUNK))
            .into_par_iter()
            .map(|chunk| {
                let items = chunk * BINNING_CHUNK..((chunk + 1) * BINNING_CHUNK).min(count);
                let mut pairs = Vec::new();
                for item in items {
                    tiles_of(item as u32, &mut |tile| {
                        pairs.push((tile as u32, item as u32))
                    });
                }
                pairs
            })
            .collect();
        let mut starts = vec![0usize; grid.count() + 1];
        for &(tile, _) in chunks.iter().flatten() {
            starts[tile as usize + 1] += 1;
        }
        for i in 1..starts.len() {
            starts[i] += starts[i - 1];
        }
        let mut fill = starts.clone();
        let mut entries = vec![0u32; starts[grid.count()]];
        for &(tile, item) in chunks.iter().flatten() {
            entries[fill[tile as usize]] = item;
            fill[tile as usize] += 1;
        }
        TileLists { starts, entries }
    }

    /// The items binned to `tile`, in ascending order (each chunk's pairs are made, and
    /// counted out, in item order).
    pub(crate) fn list(&self, tile: usize) -> &[u32] {
        &self.entries[self.starts[tile]..self.starts[tile + 1]]
    }

    /// `work(ty, band)` for the `bands` item of each tile row `ty`, in parallel, the rows with the
    /// most item–tile pairs first ([`costliest_first`]); the results in row order.
    pub(crate) fn by_rows_costliest_first<T: Send, R: Send>(
        &self,
        grid: &TileGrid,
        bands: Vec<T>,
        work: impl Fn(usize, T) -> R + Sync,
    ) -> Vec<R> {
        let row_entries = |ty| {
            let tiles = grid.row(ty);
            self.starts[tiles.end] - self.starts[tiles.start]
        };
        costliest_first(bands, row_entries, work)
    }

    /// Item–tile pairs in all.
    pub(crate) fn entries(&self) -> usize {
        self.entries.len()
    }

    /// The most items in one tile.
    pub(crate) fn longest(&self) -> usize {
        self.starts
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_keep_item_order_and_blocks_land_on_their_pixels() {
        // 40 × 20 px: 3 × 2 tiles, the last column and row cut short.
        let grid = TileGrid::new(40, 20);
        assert_eq!(grid.count(), 6);
        assert_eq!(grid.pixels(5), [32, 16, 40, 20]);
        // Item i touches tiles i and i + 1.
        let lists = TileLists::new(&grid, 3, |item, visit| {
            visit(item as usize);
            visit(item as usize + 1);
        });
        assert_eq!(lists.list(1), &[0, 1]);
        assert_eq!(lists.list(2), &[1, 2]);
        assert_eq!((lists.entries(), lists.longest()), (6, 2));
        let blocks: Vec<Vec<usize>> = (0..grid.count())
            .map(|tile| {
                let [x0, y0, x1, y1] = grid.pixels(tile);
                (y0..y1)
                    .flat_map(|y| (x0..x1).map(move |x| (y * 40 + x) as usize))
                    .collect()
            })
            .collect();
        // Lists longer than a binning chunk are joined in item order.
        let many = 3 * BINNING_CHUNK + 5;
        let lists = TileLists::new(&grid, many, |item, visit| visit(item as usize % 6));
        for tile in 0..6 {
            let expected: Vec<u32> = (tile as u32..many as u32).step_by(6).collect();
            assert_eq!(lists.list(tile), expected.as_slice());
        }
        // Rows handed out costliest first come back in row order, each worked on once.
        let rows: Vec<usize> = (0..40).collect();
        let visits = std::sync::atomic::AtomicUsize::new(0);
        let done = costliest_first(
            rows,
            |row| row % 7,
            |row, item| {
                visits.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                (row, item * 2)
            },
        );
        assert_eq!(visits.into_inner(), 40);
        assert!(done
            .iter()
            .enumerate()
            .all(|(i, &(row, twice))| row == i && twice == 2 * i));
        let mut image = vec![usize::MAX; 800];
        for (ty, band) in image.chunks_mut(grid.band_len()).enumerate() {
            for tile in grid.row(ty) {
                for (at, &value) in grid.in_band(tile).zip(&blocks[tile]) {
                    band[at] = value;
                }
            }
        }
        assert!(image.iter().enumerate().all(|(i, &v)| v == i));
    }
}
