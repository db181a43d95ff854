//! Which samples a moving triangle may cover: the convex hull of its corners' screen paths,
//! widened by the rounding of its own arithmetic. The exact test is the edge functions'
//! ([`super::tct`]); the hull only skips, a row at a time, samples that cannot pass it.

use glam::DVec2;

use super::tct::MovingTriangle;
use crate::scene::Camera;

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
pub(super) fn screen_corners(
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

/// The screen hull of a triangle's path over a window of its time, with the slack its rounding
/// needs: which columns of a row of samples it may cover.
pub(super) struct PathHull {
    hull: ScreenHull,
    /// How far the band of rows is widened each way, px.
    band: f64,
    /// How far a row's range is widened each way, px.
    margin: f64,
}

impl PathHull {
    /// The hull of `triangle` over `window`. Its corners' projections and an edge's x at a row
    /// round by a few ulps of the largest corner coordinate, which [`HULL_MARGIN_PX`] covers up to
    /// about 10¹¹ px; beyond, the band of rows and the range widen by the rounding itself. `None`
    /// when a corner does not project or the rounding is not finite: such a hull bounds nothing,
    /// and every sample in the triangle's bounds is tested.
    pub(super) fn new(
        camera: &Camera,
        triangle: &MovingTriangle,
        window: [f64; 2],
    ) -> Option<PathHull> {
        let hull = ScreenHull::new(&screen_corners(camera, triangle, window)?);
        let (band, margin) = match HULL_ROUNDING * hull.reach {
            r if r <= HULL_MARGIN_PX => (0.0, HULL_MARGIN_PX),
            r if r.is_finite() => (r, r),
            _ => return None,
        };
        Some(PathHull { hull, band, margin })
    }

    /// The columns [from, to) of pixel row `y` holding samples the hull may cover, the samples
    /// lying at offsets within `[ox0, oy0, ox1, oy1]` of their pixel's corner; `None` when the
    /// hull misses the row.
    pub(super) fn columns(&self, y: u32, [ox0, oy0, ox1, oy1]: [f64; 4]) -> Option<[u32; 2]> {
        let rows = [
            f64::from(y) + oy0 - self.band,
            f64::from(y) + oy1 + self.band,
        ];
        let [lo, hi] = self.hull.x_range(rows[0], rows[1])?;
        let pixel = |x: f64| x.clamp(0.0, f64::from(u32::MAX)) as u32;
        Some([
            pixel((lo - ox1 - self.margin).ceil()),
            pixel((hi - ox0 + self.margin).floor() + 1.0),
        ])
    }
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
