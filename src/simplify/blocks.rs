//! The first stretch of a large simplification, in parallel. The vertices, laid out along a
//! Morton curve, are cut into blocks of consecutive vertices. A collapse changes only the faces
//! around its two ends, so an edge whose ends touch only faces with all three corners in one
//! block can be collapsed without looking outside it: each block runs its own collapser, and the
//! vertices on faces that cross blocks (the seams) stay where they are.
//!
//! The blocks advance together in rounds, each collapsing what costs less than four times the
//! cheapest cost any block still has queued, so the mesh as a whole is collapsed cheapest first
//! to within those two octaves (the single queue orders to within 0.4 %): flat parts go before
//! detailed ones whatever block they lie in. Narrower rounds are more of them for the same result
//! (a quarter octave: 101 rounds instead of 17 on the 1.6 M-face armadillo, a quarter more time,
//! the same mean distance). They
//! stop short of the face target by twice the seams' share of the reduction; the single collapser
//! that finishes the job (`super::simplify`) then takes the seams down with the rest.
//! The blocks depend on the vertex count alone, never on the thread count, so the result does
//! not either.

use std::ops::Range;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::collapse::{Collapser, Edges, FacesAround, Known, Vertices, VerticesMut};
use super::heap::Heap;
use super::Stats;

/// Vertices per block, at least: below this, a block's seams (the vertices that stay, on faces
/// that cross to other blocks) would be a large share of it.
pub const BLOCK_VERTICES: usize = 8192;

/// Blocks, at most. The seams grow as the square root of the block count, and the queue that
/// finishes them is serial: on the 1.6 M-face armadillo, 16 blocks left it 20,392 collapses
/// against 40,294 with 64, and ran 7–10 % faster on two threads (docs/math.md, "Blocks").
pub const MAX_BLOCKS: usize = 16;

/// What the blocks leave for the single collapser (the vertices were collapsed in place: dead
/// ones are simply no longer used).
pub(super) struct Blocked {
    /// The live faces in the order given, with their places among the faces given.
    pub faces: Vec<([u32; 3], u32)>,
    /// The faces around each vertex and the edges given, if still those of the faces (no block
    /// ran).
    pub known: Known,
    /// What the blocks counted.
    pub stats: Stats,
}

/// Collapse `faces` over `vertices` (with the faces `around` each, their `first_normals` and
/// `edges`) towards
/// `target_faces` in parallel blocks, leaving for a single collapser the seams' share of the
/// reduction. A mesh too small for two blocks comes back as it went in.
#[allow(clippy::too_many_arguments)] // One call; the mesh's parts and the collapse's settings.
pub(super) fn collapse_in_blocks(
    vertices: &mut Vertices,
    faces: Vec<[u32; 3]>,
    around: FacesAround,
    edges: Edges,
    first_normals: &[Vec3],
    target_faces: usize,
    channels: usize,
    direction: Option<DVec3>,
    progress: &mut dyn FnMut(usize),
) -> Blocked {
    let n = vertices.points.len();
    let blocks = (n / BLOCK_VERTICES).min(MAX_BLOCKS);
    if blocks < 2 || faces.len() <= target_faces {
        return Blocked {
            faces: faces.into_iter().zip(0..).collect(),
            known: Known {
                around: Some(around),
                edges: Some(edges),
            },
            stats: Stats::default(),
        };
    }
    drop(around);
    let size = n.div_ceil(blocks);
    let block_of = |v: u32| v as usize / size;
    let ranges: Vec<Range<usize>> = (0..blocks)
        .map(|k| (k * size).min(n)..(k * size + size).min(n))
        .collect();

    // Faces within one block, by block, with their place in `faces`; the rest are seams, counted
    // at their corners.
    let mut within: Vec<Vec<([u32; 3], u32)>> = vec![Vec::new(); blocks];
    let mut seams: Vec<([u32; 3], u32)> = Vec::new();
    let mut seam_faces = vec![0u32; n];
    for (f, face) in faces.iter().enumerate() {
        let k = block_of(face[0]);
        if face.iter().all(|&v| block_of(v) == k) {
            within[k].push((face.map(|v| v - ranges[k].start as u32), f as u32));
        } else {
            seams.push((*face, f as u32));
            for &v in face {
                seam_faces[v as usize] += 1;
            }
        }
    }
    let total = faces.len();
    drop(faces);

    let mut collapsers: Vec<(Collapser, Vec<u32>)> = split(vertices.as_mut(), channels, &ranges)
        .into_par_iter()
        .zip(within)
        .zip(&ranges)
        .map(|((vertices, within), range)| {
            let (local, places): (Vec<[u32; 3]>, Vec<u32>) = within.into_iter().unzip();
            let normals = places.iter().map(|&f| first_normals[f as usize]).collect();
            let elsewhere = seam_faces[range.clone()].to_vec();
            let known = Known {
                around: None,
                edges: Some(edges.within(range.clone())),
            };
            let collapser = Collapser::new(
                vertices, local, normals, elsewhere, known, channels, direction,
            );
            (collapser, places)
        })
        .collect();

    // The single queue reduces the seams later, with the faces just inside the blocks around the
    // seams' corners, which could not move and are about as many again: it gets twice the seam
    // faces' share of the reduction (with their share alone, 1,446 of 6,000 faces of a sphere
    // ended below a quarter of the mean size; `tests/simplify.rs`).
    let seam_share =
        (seams.len() as u128 * (total - target_faces) as u128 / total as u128) as usize;
    let goal = target_faces + 2 * seam_share;
    let mut last_round = None;
    loop {
        let in_blocks: usize = collapsers.iter().map(|(c, _)| c.live_faces).sum();
        let live = seams.len() + in_blocks;
        progress(live);
        let allowed = live.saturating_sub(goal);
        // Below one face per block, a round could not share the reduction out.
        if allowed < 2 * collapsers.len() {
            break;
        }
        let Some(cheapest) = collapsers
            .iter()
            .filter_map(|(c, _)| c.cheapest_bin())
            .min()
        else {
            break;
        };
        // A round that neither collapsed nor emptied the cheapest bin would repeat itself: the
        // cheapest edge is in a block whose share rounds down to nothing.
        if last_round == Some((live, cheapest)) {
            break;
        }
        last_round = Some((live, cheapest));
        let below = Heap::two_octaves_past(cheapest);
        collapsers.par_iter_mut().for_each(|(c, _)| {
            let share = (allowed as u128 * c.live_faces as u128 / in_blocks as u128) as usize;
            c.run(c.live_faces.saturating_sub(share), below, &mut |_| {});
        });
    }

    let mut stats = Stats::default();
    let mut live = seams;
    let blocks: Vec<_> = collapsers
        .into_par_iter()
        .map(|(collapser, places)| (collapser.stats, collapser.into_faces(), places))
        .collect();
    for ((block_stats, faces, places), range) in blocks.into_iter().zip(&ranges) {
        stats += block_stats;
        let offset = range.start as u32;
        live.extend(
            faces
                .into_iter()
                .map(|(face, f)| (face.map(|v| v + offset), places[f as usize])),
        );
    }
    live.par_sort_unstable_by_key(|&(_, place)| place);
    Blocked {
        faces: live,
        known: Known::default(),
        stats,
    }
}

/// `vertices` (with `channels` carried numbers each) cut into the consecutive runs `ranges`.
fn split<'a>(
    vertices: VerticesMut<'a>,
    channels: usize,
    ranges: &[Range<usize>],
) -> Vec<VerticesMut<'a>> {
    let mut parts = Vec::with_capacity(ranges.len());
    let mut rest = vertices;
    for range in ranges {
        let (part, after) = rest.split_at(range.len(), channels);
        parts.push(part);
        rest = after;
    }
    parts
}
