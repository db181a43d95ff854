//! The tile grid both rasterizers work on: the image cut into [`TILE_PX`] squares, each owning
//! its pixels (so tiles render in parallel without locks), items binned into per-tile lists, and
//! per-tile results put back into one image.

use super::TILE_PX;

/// The image cut into tiles, row by row: tile `ty · tiles_x + tx` covers the pixels from
/// (tx, ty)·[`TILE_PX`], cut at the image's edges.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileGrid {
    width: u32,
    height: u32,
    tiles_x: usize,
    tiles_y: usize,
}

impl TileGrid {
    /// The grid over a `width` × `height` image.
    pub(crate) fn new(width: u32, height: u32) -> TileGrid {
        TileGrid {
            width,
            height,
            tiles_x: width.div_ceil(TILE_PX) as usize,
            tiles_y: height.div_ceil(TILE_PX) as usize,
        }
    }

    /// How many tiles there are.
    pub(crate) fn count(&self) -> usize {
        self.tiles_x * self.tiles_y
    }

    /// The index of the tile in column `tx` and row `ty`.
    pub(crate) fn index(&self, tx: u32, ty: u32) -> usize {
        ty as usize * self.tiles_x + tx as usize
    }

    /// The pixel rectangle [x0, y0, x1, y1) of `tile`.
    pub(crate) fn pixels(&self, tile: usize) -> [u32; 4] {
        let x0 = (tile % self.tiles_x) as u32 * TILE_PX;
        let y0 = (tile / self.tiles_x) as u32 * TILE_PX;
        [
            x0,
            y0,
            (x0 + TILE_PX).min(self.width),
            (y0 + TILE_PX).min(self.height),
        ]
    }

    /// Calls `put(pixel, value)` for every value of every tile's block, where a block holds its
    /// tile's pixels row by row and `pixel` indexes the whole image row by row.
    pub(crate) fn scatter<T>(&self, blocks: &[Vec<T>], mut put: impl FnMut(usize, &T)) {
        for (tile, block) in blocks.iter().enumerate() {
            let [x0, y0, x1, _] = self.pixels(tile);
            let w = (x1 - x0) as usize;
            for (row, chunk) in block.chunks(w).enumerate() {
                let start = (y0 as usize + row) * self.width as usize + x0 as usize;
                for (i, value) in chunk.iter().enumerate() {
                    put(start + i, value);
                }
            }
        }
    }
}

/// Item indices binned by tile, each tile's in the order the items were offered (a compressed
/// list: one array of entries and each tile's start in it).
#[derive(Clone, Debug, Default)]
pub(crate) struct TileLists {
    starts: Vec<usize>,
    entries: Vec<u32>,
}

impl TileLists {
    /// Bin the items `order` names, in that order; `tiles_of(item, visit)` calls `visit` with
    /// each tile the item touches. It is called twice per item (to count, then to fill), and must
    /// name the same tiles both times.
    pub(crate) fn new(
        grid: &TileGrid,
        order: &[u32],
        tiles_of: impl Fn(u32, &mut dyn FnMut(usize)),
    ) -> TileLists {
        let mut starts = vec![0usize; grid.count() + 1];
        for &item in order {
            tiles_of(item, &mut |tile| starts[tile + 1] += 1);
        }
        for i in 1..starts.len() {
            starts[i] += starts[i - 1];
        }
        let mut fill = starts.clone();
        let mut entries = vec![0u32; starts[grid.count()]];
        for &item in order {
            tiles_of(item, &mut |tile| {
                entries[fill[tile]] = item;
                fill[tile] += 1;
            });
        }
        TileLists { starts, entries }
    }

    /// The items binned to `tile`.
    pub(crate) fn list(&self, tile: usize) -> &[u32] {
        &self.entries[self.starts[tile]..self.starts[tile + 1]]
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
    fn lists_keep_the_offered_order_and_blocks_land_on_their_pixels() {
        // 40 × 20 px: 3 × 2 tiles, the last column and row cut short.
        let grid = TileGrid::new(40, 20);
        assert_eq!(grid.count(), 6);
        assert_eq!(grid.pixels(5), [32, 16, 40, 20]);
        // Item i touches tiles i and i + 1.
        let lists = TileLists::new(&grid, &[2, 0, 1], |item, visit| {
            visit(item as usize);
            visit(item as usize + 1);
        });
        assert_eq!(lists.list(1), &[0, 1]);
        assert_eq!(lists.list(2), &[2, 1]);
        assert_eq!((lists.entries(), lists.longest()), (6, 2));
        let blocks: Vec<Vec<usize>> = (0..grid.count())
            .map(|tile| {
                let [x0, y0, x1, y1] = grid.pixels(tile);
                (y0..y1)
                    .flat_map(|y| (x0..x1).map(move |x| (y * 40 + x) as usize))
                    .collect()
            })
            .collect();
        let mut image = vec![usize::MAX; 800];
        grid.scatter(&blocks, |pixel, &value| image[pixel] = value);
        assert!(image.iter().enumerate().all(|(i, &v)| v == i));
    }
}
