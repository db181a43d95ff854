//! Level of detail for a moving mesh from its screen speed (Zhang et al. 2014, §5 and
//! Appendix B): a triangle whose projected perimeter is below σ₁ v + σ₂ pixels (v the screen
//! speed in px per shutter) shows no detail the blur keeps, so each vertex gets a detail limit:
//! that perimeter, capped (measured, the blur does not hide more at higher speeds), in object
//! units. The limit is conservative over the shutter: the scale is the largest (nearest) the
//! vertex has on screen at any sampled time, as Appendix B takes the nearest position; the speed
//! is the length of its screen path. Each vertex also gets its screen motion, lifted back to
//! object space (its component along the view axis dropped), to weight edge costs by their angle
//! to the motion (§4) when the object turns.
//!
//! Simplified meshes are kept in a small process-wide cache keyed by the mesh and the limits
//! (quantized to quarter octaves, downwards), so a study's repeats and a gallery's methods
//! simplify once.

use std::hash::{Hash, Hasher};
use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;

use super::{simplify, Limits, Options, Simplified, Stats, Weighting};
use crate::cache::{hash_words, hasher, Recent};
use crate::error::Result;
use crate::scene::camera::Camera;
use crate::scene::{Object, TriangleMesh};
use crate::surfels::Mesh;

/// Zhang et al.'s σ₁ (eq. 8), px of perimeter per px of screen speed.
pub const ZHANG_SIGMA_SPEED: f64 = 7.3;

/// The σ₁ the plan uses unless a scene says otherwise: Zhang's 7.3, with v in px per shutter,
/// took the armadillo to 14 faces at 30 px per shutter (ꟻLIP 0.115 against full detail); 0.5
/// keeps ꟻLIP at 0.033 at 90 px per shutter with a 13× faster `analytic` (docs/math.md, "Mesh
/// level of detail"; `cargo bench --bench mesh_lod`).
pub const DEFAULT_SIGMA_SPEED: f64 = 0.5;

/// Zhang et al.'s σ₂ (eq. 8), px of perimeter at no speed.
pub const ZHANG_SIGMA_BASE: f64 = 0.36;

/// The longest projected perimeter, px, the plan lets a triangle reach however fast it moves,
/// unless a scene says otherwise. Measured, ꟻLIP against full detail grows with the perimeter
/// kept and not less at higher speed: σ₁ v + σ₂ alone took the armadillo at 270 px per shutter
/// to 190 faces and ꟻLIP 0.074; capped at 45 px it keeps 800 and 0.039 (docs/math.md, "Mesh
/// level of detail"; `cargo bench --features cli --bench mesh_lod -- 320 0.5 270`).
pub const DEFAULT_MAX_PERIMETER_PX: f64 = 45.0;

/// Times sampled over the shutter for each vertex's screen path.
pub const PATH_SAMPLES: usize = 17;

/// Simplified meshes kept in the cache; the oldest goes first.
pub const CACHE_ENTRIES: usize = 8;

/// Eq. 8 of Zhang et al.: the kept spatial frequency ρ = 1/(σ₁ v + σ₂), a triangle's frequency
/// taken as the reciprocal of its projected perimeter in px; the perimeter is also capped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetailRule {
    /// σ₁: perimeter px per px of screen speed per shutter.
    pub sigma_speed: f64,
    /// σ₂: perimeter px at no speed.
    pub sigma_base: f64,
    /// The longest perimeter, px, at any speed.
    pub max_perimeter_px: f64,
}

impl Default for DetailRule {
    fn default() -> DetailRule {
        DetailRule {
            sigma_speed: DEFAULT_SIGMA_SPEED,
            sigma_base: ZHANG_SIGMA_BASE,
            max_perimeter_px: DEFAULT_MAX_PERIMETER_PX,
        }
    }
}

impl DetailRule {
    /// The largest projected perimeter, px, a triangle moving `speed_px` per shutter may have:
    /// min(σ₁ v + σ₂, the cap).
    #[must_use]
    pub fn perimeter_px(&self, speed_px: f64) -> f64 {
        (self.sigma_speed * speed_px + self.sigma_base).min(self.max_perimeter_px)
    }
}

/// How each vertex of a mesh moves on screen over the shutter.
#[derive(Clone, Debug, PartialEq)]
pub struct ScreenMotion {
    /// Length of each vertex's screen path, px.
    pub speed_px: Vec<f64>,
    /// Largest px per object unit each vertex has on screen; 0 where it is ever behind the
    /// near plane (such a vertex is never simplified).
    pub px_per_unit: Vec<f64>,
    /// Each vertex's screen motion at mid-shutter, in object space, view-axis part dropped.
    pub motion: Vec<DVec3>,
}

impl ScreenMotion {
    /// The screen motion of `positions` (object space) of `object` seen by `camera` over the
    /// shutter `[open, close]`.
    #[must_use]
    pub fn of(camera: &Camera, object: &Object, positions: &[DVec3], shutter: [f64; 2]) -> Self {
        let [open, close] = shutter;
        let times: Vec<f64> = (0..PATH_SAMPLES)
            .map(|i| open + (close - open) * i as f64 / (PATH_SAMPLES - 1) as f64)
            .collect();
        let poses: Vec<_> = times
            .iter()
            .map(|&t| {
                let pose = object.motion.pose_at(t);
                (camera.view * pose.to_affine(), pose.scale)
            })
            .collect();
        let middle = 0.5 * (open + close);
        let step = 1e-3 * (close - open);
        let [before, after] = [middle - step, middle + step].map(|t| {
            let pose = object.motion.pose_at(t);
            camera.view * pose.to_affine()
        });
        let mid_pose = object.motion.pose_at(middle);
        // View → object for directions: the inverse of the view rotation and the pose's
        // rotation and scale.
        let to_object = (camera.view.matrix3 * mid_pose.to_affine().matrix3).inverse();
        let per_vertex: Vec<(f64, f64, DVec3)> = positions
            .par_iter()
            .map(|&p| {
                let mut length = 0.0;
                let mut scale: f64 = 0.0;
                let mut previous: Option<glam::DVec2> = None;
                let mut visible = true;
                for (to_view, pose_scale) in &poses {
                    match camera.project(to_view.transform_point3(p)) {
                        Some((px, depth)) => {
                            scale = scale.max(camera.focal_px * pose_scale / depth);
                            if let Some(q) = previous {
                                length += (px - q).length();
                            }
                            previous = Some(px);
                        }
                        None => visible = false,
                    }
                }
                let velocity = after.transform_point3(p) - before.transform_point3(p);
                let motion = to_object * DVec3::new(velocity.x, velocity.y, 0.0);
                (
                    length,
                    if visible { scale } else { 0.0 },
                    if motion.is_finite() {
                        motion
                    } else {
                        DVec3::ZERO
                    },
                )
            })
            .collect();
        ScreenMotion {
            speed_px: per_vertex.iter().map(|v| v.0).collect(),
            px_per_unit: per_vertex.iter().map(|v| v.1).collect(),
            motion: per_vertex.iter().map(|v| v.2).collect(),
        }
    }

    /// Each vertex's detail limit under `rule`, object units, quantized down to a quarter octave
    /// (so nearby views share a cache entry and the limit never grows).
    #[must_use]
    pub fn limits(&self, rule: &DetailRule) -> Limits {
        let per_vertex = self
            .speed_px
            .iter()
            .zip(&self.px_per_unit)
            .map(|(&v, &s)| {
                let limit = rule.perimeter_px(v) / s;
                if limit.is_finite() && limit > 0.0 {
                    ((4.0 * limit.log2()).floor() / 4.0)
                        .exp2()
                        .clamp(f64::MIN_POSITIVE, f64::MAX)
                } else {
                    f64::MIN_POSITIVE
                }
            })
            .collect();
        Limits { per_vertex }
    }
}

/// A simplified mesh and what its collapse loop did, shared by the cache.
pub type Shared = Arc<(TriangleMesh, Stats)>;

static CACHE: Recent<u64, Shared> = Recent::new(CACHE_ENTRIES);

/// A hash of everything in `mesh`, to tell meshes apart in caches: fed to foldhash in long runs
/// of words, a third of the 5 ms per plan that SipHash took element by element over the
/// armadillo's 100 k faces (a tenth of a simplified render).
#[must_use]
pub fn content_key(mesh: &TriangleMesh) -> u64 {
    let mut hasher = hasher();
    hash_words(
        &mut hasher,
        mesh.positions
            .iter()
            .flat_map(|p| p.to_array().map(f64::to_bits)),
    );
    mesh.triangles.as_flattened().hash(&mut hasher);
    hash_words(
        &mut hasher,
        mesh.colours
            .iter()
            .flat_map(|c| c.map(|v| u64::from(v.to_bits()))),
    );
    hasher.finish()
}

/// `mesh` (whose [`content_key`] is `mesh_key`) simplified as far as `limits` allow with edges
/// weighted by the per-vertex `motion`, from the cache when it holds it. Colours are carried
/// along; corner normals are made anew.
pub fn simplified(
    mesh: &TriangleMesh,
    mesh_key: u64,
    limits: Limits,
    motion: Vec<DVec3>,
) -> Result<Shared> {
    let mut hasher = hasher();
    mesh_key.hash(&mut hasher);
    hash_words(&mut hasher, limits.per_vertex.iter().map(|l| l.to_bits()));
    // The motions exactly, as the simplifier weighs them: rounded, a view would be handed the
    // mesh of whichever nearby view was simplified first (a weight near a right angle moves by
    // 6 % within one rounding step), and the image would depend on what the process drew before.
    hash_words(
        &mut hasher,
        motion.iter().flat_map(|m| m.to_array().map(f64::to_bits)),
    );
    let key = hasher.finish();
    if let Some(shared) = CACHE.find(|&k| k == key) {
        return Ok(shared);
    }
    let options = Options {
        target_faces: 0,
        weighting: Weighting::PerVertex(motion),
        limits: Some(limits),
    };
    let input = Mesh {
        positions: mesh.positions.clone(),
        triangles: mesh.triangles.clone(),
    };
    let colours: Vec<f32> = mesh.colours.iter().flatten().copied().collect();
    let Simplified {
        mesh: out,
        carried,
        stats,
        ..
    } = simplify(&input, &options, (&colours, 3), &mut |_| {})?;
    let colours = carried
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let triangles = TriangleMesh::from_parts(out.positions, out.triangles, colours)?;
    let shared = Arc::new((triangles, stats));
    CACHE.keep(key, Arc::clone(&shared));
    Ok(shared)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surfels::Colouring;

    /// A strip of `quads` quads, more vertices than a run of hashed words holds.
    fn strip(quads: u32) -> TriangleMesh {
        let positions = (0..=quads)
            .flat_map(|i| {
                [
                    DVec3::new(f64::from(i), 0.0, 0.0),
                    DVec3::new(f64::from(i), 1.0, 0.0),
                ]
            })
            .collect();
        let triangles = (0..quads)
            .flat_map(|i| {
                [
                    [2 * i, 2 * i + 2, 2 * i + 1],
                    [2 * i + 1, 2 * i + 2, 2 * i + 3],
                ]
            })
            .collect();
        grey(positions, triangles)
    }

    /// The key is the same for the same content and changes with any one bit of a position, an
    /// index or a colour, also in a run's last partial stretch, and with a vertex more.
    #[test]
    fn content_keys_tell_apart_meshes_that_differ_anywhere() {
        let mesh = strip(700);
        let key = content_key(&mesh);
        assert_eq!(key, content_key(&strip(700)));
        let mut changed = Vec::new();
        for vertex in [0, 400, mesh.positions.len() - 1] {
            let mut m = mesh.clone();
            m.positions[vertex].z = f64::from_bits(1);
            changed.push(m);
            let mut m = mesh.clone();
            m.colours[vertex][2] = f32::from_bits(m.colours[vertex][2].to_bits() ^ 1);
            changed.push(m);
        }
        let mut m = mesh.clone();
        m.triangles.last_mut().unwrap().swap(0, 1);
        changed.push(m);
        let mut m = mesh.clone();
        m.positions.push(DVec3::ZERO);
        changed.push(m);
        for m in &changed {
            assert_ne!(content_key(m), key);
        }
    }

    /// A mid-grey triangle mesh.
    fn grey(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> TriangleMesh {
        let mesh = Mesh {
            positions,
            triangles,
        };
        TriangleMesh::new(&mesh, DVec3::ZERO, Colouring::Rgb([0.5; 3])).unwrap()
    }

    /// A bumpy height field of `n` × `n` quads over the unit square.
    fn bumps(n: u32) -> TriangleMesh {
        let positions = (0..=n)
            .flat_map(|j| {
                (0..=n).map(move |i| {
                    let (x, y) = (f64::from(i) / f64::from(n), f64::from(j) / f64::from(n));
                    DVec3::new(
                        x,
                        y,
                        0.05 * (7.0 * x).sin() * (5.0 * y).cos() + 0.02 * (13.0 * x * y).sin(),
                    )
                })
            })
            .collect();
        let row = n + 1;
        let triangles = (0..n)
            .flat_map(|j| {
                (0..n).flat_map(move |i| {
                    let v = j * row + i;
                    [[v, v + 1, v + row + 1], [v, v + row + 1, v + row]]
                })
            })
            .collect();
        grey(positions, triangles)
    }

    /// The cache hands out what `simplified` would make for these very motions: a view whose
    /// motions round to the same directions as a view simplified before it (as nearby views'
    /// do) must not get that other view's mesh.
    #[test]
    fn a_cached_simplification_is_the_one_its_own_motions_give() {
        let mesh = bumps(24);
        let key = content_key(&mesh);
        let limits = Limits {
            per_vertex: vec![0.25; mesh.positions.len()],
        };
        // Both round to (1, 0, 0) at 1/64 per component: along x, and half a degree off it.
        let along = |y: f64| vec![DVec3::new(1.0, y, 0.0); mesh.positions.len()];
        let (a, b) = (along(0.0077), along(0.0));
        let b_alone = simplified(&mesh, key, limits.clone(), b.clone()).unwrap();
        // Push it out of the cache.
        let filler = bumps(2);
        for k in 0..2 * CACHE_ENTRIES as u64 {
            let n = filler.positions.len();
            simplified(
                &filler,
                k,
                Limits {
                    per_vertex: vec![1.0; n],
                },
                vec![DVec3::X; n],
            )
            .unwrap();
        }
        let a_first = simplified(&mesh, key, limits.clone(), a).unwrap();
        assert_ne!(
            a_first.0.positions, b_alone.0.positions,
            "the motions matter"
        );
        let b_after_a = simplified(&mesh, key, limits, b).unwrap();
        assert_eq!(b_after_a.0.positions, b_alone.0.positions);
    }
}
