//! Footprint profiles: the shape of a footprint's value across its ellipse.
//!
//! Physically based renderers use the elliptical Gaussian. Motion hints may map other textures
//! onto the motion ellipse (Guan & Mueller §3.3 end and §4, Fig. 7): a hard disc, a ring, or an
//! image. Every profile is a function of the footprint's own (Mahalanobis) coordinates, zero
//! beyond the rasterizer's cut-off radius, and normalized so that it integrates to the footprint's
//! weight: coverage and energy mean the same whatever the texture.

use super::{larger, nearest_step, CUTOFF_Q, CUTOFF_SIGMAS};
use std::sync::LazyLock;

/// Steps of the table of exp(−q/2) over q ∈ [0, cut-off²] that Gaussian footprints are evaluated
/// from. Each entry holds the value and its slope, taken at the nearest entry: at most half a step
/// h = 9/1024 away, the tangent errs by at most (h/2)²/2 · ¼ ≈ 2.4·10⁻⁶ of the value (the second
/// derivative of exp(−q/2) is a quarter of it), as linear interpolation between entries would.
/// `f32::exp` was a tenth of the rasterizer's time.
const GAUSSIAN_STEPS: usize = 1024;

/// exp(−q/2) and its slope per step at q = i · cut-off² / [`GAUSSIAN_STEPS`].
pub(super) type GaussianTable = [[f32; 2]; GAUSSIAN_STEPS + 1];

/// The table, made on first use.
pub(super) fn gaussian_table() -> &'static GaussianTable {
    &GAUSSIAN_TABLE
}

/// The table of [`exp_half`].
static GAUSSIAN_TABLE: LazyLock<GaussianTable> = LazyLock::new(|| {
    let step = f64::from(CUTOFF_Q) / GAUSSIAN_STEPS as f64;
    std::array::from_fn(|i| {
        let value = (-0.5 * step * i as f64).exp();
        [value as f32, (-0.5 * step * value) as f32]
    })
});

/// exp(−q/2) for q in [0, cut-off²], from the tangent at the nearest entry of the
/// [`GAUSSIAN_TABLE`] that [`gaussian_table`] gives.
#[inline]
pub(super) fn exp_half(table: &GaussianTable, q: f32) -> f32 {
    // q ≥ 0 up to rounding; a negative q is taken as 0.
    let u = larger(q * (GAUSSIAN_STEPS as f32 / CUTOFF_Q), 0.0);
    let (i, entry) = nearest_step(u);
    let [value, slope] = table[i.min(GAUSSIAN_STEPS)];
    value + slope * (u - entry)
}

/// Radius of the disc profile, in standard deviations: where a Gaussian splat visibly ends.
const DISC_RADIUS: f32 = 2.0;

/// Inner and outer radius of the ring profile, in standard deviations.
const RING_RADII: [f32; 2] = [1.2, 2.2];

/// Width of the linear ramp that softens disc and ring edges, in standard deviations: sampled at
/// pixel centres, a hard edge would alias.
const EDGE_WIDTH: f32 = 0.5;

/// A footprint's profile.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Profile {
    /// The elliptical Gaussian of EWA splatting.
    #[default]
    Gaussian,
    /// Flat inside two standard deviations, with a soft edge.
    Disc,
    /// A soft ring between 1.2 and 2.2 standard deviations.
    Ring,
    /// The rasterizer's [`Texture`], its horizontal axis along the ellipse's major axis.
    Texture,
}

impl Profile {
    /// ∫ profile over the plane in the footprint's unit coordinates (where the covariance is the
    /// identity); the footprint's amplitude is its weight / (this · √det Σ).
    pub(super) fn integral(self) -> f64 {
        use std::f64::consts::PI;
        let (r, d) = (f64::from(DISC_RADIUS), f64::from(EDGE_WIDTH));
        let [r0, r1] = RING_RADII.map(f64::from);
        match self {
            // ∫ exp(−r²/2) over the disc of the cut-off radius, which the truncation gain restores.
            Profile::Gaussian => std::f64::consts::TAU / super::TRUNCATION_GAIN,
            // A linear ramp of width d centred on radius R adds π d²/12 to π R².
            Profile::Disc => PI * (r * r + d * d / 12.0),
            // The inner edge's ramp takes away what the outer's adds.
            Profile::Ring => PI * (r1 * r1 - r0 * r0),
            // Textures are scaled to integrate to one when they are made.
            Profile::Texture => 1.0,
        }
    }
}

/// A grey-level image mapped onto footprints, row-major, row 0 at the top. Across the footprint
/// it spans ±[`CUTOFF_SIGMAS`] standard deviations on both axes and is cut to the inscribed disc
/// like every profile; its values are scaled so that it integrates to one there.
///
/// Where a footprint's pixels are larger than its texels, each pixel takes the mean of the
/// texels over its own extent, from a summed-area table: sampled at pixel centres, detail finer
/// than a pixel was caught or missed by chance (a texture lit at one texel of 64² kept 1.4 % of
/// its light). Where they are smaller, the image is sampled bilinearly.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: u32,
    height: u32,
    values: Vec<f32>,
    /// `(width + 1) × (height + 1)` sums of the values above and left of each texel corner, in
    /// f64: the sums of a 2048² image differ by single texels' values.
    sums: Vec<f64>,
    /// The largest value, its peak: what a footprint's faintness is measured against.
    peak: f32,
}

impl Texture {
    /// A texture from `width`×`height` grey values in [0, 1]; `None` when the sizes disagree, a
    /// value is outside [0, 1], or the image is blank inside its inscribed disc.
    #[must_use]
    pub fn new(width: u32, height: u32, values: Vec<f32>) -> Option<Texture> {
        if width == 0
            || height == 0
            || values.len() != width as usize * height as usize
            || !values.iter().all(|v| (0.0..=1.0).contains(v))
        {
            return None;
        }
        let mut texture = Texture {
            width,
            height,
            values,
            sums: Vec::new(),
            peak: 0.0,
        };
        // Midpoint rule on a fine grid over the cut-off square, counting only the inscribed disc.
        const STEPS: usize = 256;
        let h = 2.0 * CUTOFF_SIGMAS / STEPS as f64;
        let mut sum = 0.0;
        for j in 0..STEPS {
            for i in 0..STEPS {
                let u = -CUTOFF_SIGMAS + (i as f64 + 0.5) * h;
                let v = -CUTOFF_SIGMAS + (j as f64 + 0.5) * h;
                if u * u + v * v <= CUTOFF_SIGMAS * CUTOFF_SIGMAS {
                    sum += f64::from(texture.sample(u as f32, v as f32));
                }
            }
        }
        let integral = sum * h * h;
        if !(integral > 1e-6) {
            return None;
        }
        let scale = (1.0 / integral) as f32;
        for v in &mut texture.values {
            *v *= scale;
        }
        texture.peak = texture.values.iter().fold(0.0, |a: f32, &v| a.max(v));
        let (w, h) = (width as usize, height as usize);
        let mut sums = vec![0.0; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0.0;
            for x in 0..w {
                row += f64::from(texture.values[y * w + x]);
                sums[(y + 1) * (w + 1) + x + 1] = sums[y * (w + 1) + x + 1] + row;
            }
        }
        texture.sums = sums;
        Some(texture)
    }

    /// Texels per unit coordinate, along x and y.
    fn texels_per_unit(&self) -> [f32; 2] {
        let per_unit = 0.5 / CUTOFF_SIGMAS as f32;
        [self.width as f32 * per_unit, self.height as f32 * per_unit]
    }

    /// Bilinear sample at unit coordinates (u right, v down), zero outside the image.
    fn sample(&self, u: f32, v: f32) -> f32 {
        let scale = 0.5 / CUTOFF_SIGMAS as f32;
        let x = (u * scale + 0.5) * self.width as f32 - 0.5;
        let y = (v * scale + 0.5) * self.height as f32 - 0.5;
        if !(x > -1.0 && y > -1.0 && x < self.width as f32 && y < self.height as f32) {
            return 0.0;
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |xi: f32, yi: f32| {
            if xi < 0.0 || yi < 0.0 || xi >= self.width as f32 || yi >= self.height as f32 {
                0.0
            } else {
                self.values[yi as usize * self.width as usize + xi as usize]
            }
        };
        let top = texel(x0, y0) * (1.0 - fx) + texel(x0 + 1.0, y0) * fx;
        let bottom = texel(x0, y0 + 1.0) * (1.0 - fx) + texel(x0 + 1.0, y0 + 1.0) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The mean of the image, taken as constant over each texel and zero outside, over the box
    /// centred at unit coordinates (u, v) that reaches `reach` texels either way on each axis.
    fn box_mean(&self, u: f32, v: f32, reach: [f32; 2]) -> f32 {
        let [per_x, per_y] = self.texels_per_unit().map(f64::from);
        let x = (f64::from(u) + CUTOFF_SIGMAS) * per_x;
        let y = (f64::from(v) + CUTOFF_SIGMAS) * per_y;
        let [rx, ry] = reach.map(f64::from);
        let sum =
            self.sum_to(x + rx, y + ry) - self.sum_to(x - rx, y + ry) - self.sum_to(x + rx, y - ry)
                + self.sum_to(x - rx, y - ry);
        (sum / (4.0 * rx * ry)) as f32
    }

    /// The integral of the image (constant over each texel) over x' < x, y' < y, in texels: the
    /// summed-area table interpolated bilinearly, which is exact for such an image.
    fn sum_to(&self, x: f64, y: f64) -> f64 {
        let (w, h) = (self.width as usize, self.height as usize);
        // NaN clamps to neither end; the caller's reach is finite and positive.
        let x = x.clamp(0.0, w as f64);
        let y = y.clamp(0.0, h as f64);
        // Whole numbers within 0..=w and 0..=h.
        let (x0, y0) = (
            (x.floor() as usize).min(w.saturating_sub(1)),
            (y.floor() as usize).min(h.saturating_sub(1)),
        );
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let at = |i: usize, j: usize| self.sums[j * (w + 1) + i];
        let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
        let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// Evaluates one footprint's profile at pixel offsets; made once per footprint and tile, so the
/// texture's orientation is found once rather than per pixel.
pub(super) struct Sampler<'a> {
    kind: SamplerKind<'a>,
    /// Rows of the map from a pixel offset to unit coordinates along the major and minor axes of
    /// a texture; zero for every other profile. Kept outside the variants and always set: the
    /// compiler hoists their products with a row's offset out of the pixel loop whatever the
    /// profile, and the bytes a variant without them leaves there were at times subnormal
    /// floats, whose every product takes a microcode assist (a third of `static`'s tile pass on
    /// the torus knot, in spells that lasted as long as a thread's stack held them).
    along: [f32; 2],
    across: [f32; 2],
}

/// Rows (a, b) of the map d ↦ (a·d, b·d) from a pixel offset to a texture's unit coordinates on
/// a footprint of inverse covariance `conic` = aaᵀ + bbᵀ, so that the footprint's ellipse maps to
/// the texture's unit circle. The texture's horizontal axis (b·d = 0) lies along `motion`, its
/// left at the oldest end: with unit m along the motion and m⊥ across it, writing
/// q_mm = mᵀQm, q_mp = mᵀQm⊥, a = √q_mm m + (q_mp / √q_mm) m⊥ and b = √(det Q / q_mm) m⊥ (the
/// ellipse sheared onto the circle where its axes are not along the motion). Without motion, the
/// horizontal axis is the ellipse's major axis.
fn texture_frame([a, b, c]: [f64; 3], motion: [f32; 2]) -> [glam::DVec2; 2] {
    let conic = |u: glam::DVec2, v: glam::DVec2| {
        a * u.x * v.x + b * (u.x * v.y + u.y * v.x) + c * u.y * v.y
    };
    let m = glam::DVec2::from(motion.map(f64::from)).normalize_or_zero();
    let q_mm = conic(m, m);
    let det = a * c - b * b;
    if m != glam::DVec2::ZERO && q_mm > 0.0 && det > 0.0 {
        let across = m.perp();
        let root = q_mm.sqrt();
        return [
            m * root + across * (conic(m, across) / root),
            across * (det / q_mm).sqrt(),
        ];
    }
    // Eigenvectors of the conic: the smaller eigenvalue belongs to the major axis.
    let mean = 0.5 * (a + c);
    let radius = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (small, large) = (mean - radius, mean + radius);
    let major = if b.abs() > 1e-12 * (a.abs() + c.abs()) {
        glam::DVec2::new(b, small - a).normalize()
    } else if a <= c {
        glam::DVec2::X
    } else {
        glam::DVec2::Y
    };
    [
        major * small.max(0.0).sqrt(),
        major.perp() * large.max(0.0).sqrt(),
    ]
}

enum SamplerKind<'a> {
    /// exp(−q/2), from [`GAUSSIAN_TABLE`].
    Gaussian(&'static GaussianTable),
    Disc,
    Ring,
    /// A texture, sampled bilinearly where the footprint's pixels are smaller than its texels,
    /// and averaged over each pixel's reach in texels (half its extent on each axis, at least
    /// half a texel) where they are larger.
    Texture(&'a Texture, Option<[f32; 2]>),
    /// A texture profile with no texture given: draws nothing.
    Blank,
}

impl<'a> Sampler<'a> {
    /// The sampler for `profile` on a footprint with inverse covariance `conic` (xx, xy, yy) that
    /// moves along `motion` on screen (its covering time's gradient: any vector along the motion
    /// from its oldest end to its newest; zero without motion).
    pub(super) fn new(
        profile: Profile,
        conic: [f32; 3],
        motion: [f32; 2],
        texture: Option<&'a Texture>,
    ) -> Self {
        let untextured = |kind| Sampler {
            kind,
            along: [0.0; 2],
            across: [0.0; 2],
        };
        match (profile, texture) {
            (Profile::Gaussian, _) => untextured(SamplerKind::Gaussian(&GAUSSIAN_TABLE)),
            (Profile::Disc, _) => untextured(SamplerKind::Disc),
            (Profile::Ring, _) => untextured(SamplerKind::Ring),
            (Profile::Texture, None) => untextured(SamplerKind::Blank),
            (Profile::Texture, Some(texture)) => {
                let [along, across] = texture_frame(conic.map(f64::from), motion);
                let (along, across) = (along.as_vec2().to_array(), across.as_vec2().to_array());
                // The extent, in texels, of the box a pixel covers in the texture on each axis.
                let [per_x, per_y] = texture.texels_per_unit();
                let extent = [
                    (along[0].abs() + along[1].abs()) * per_x,
                    (across[0].abs() + across[1].abs()) * per_y,
                ];
                let reach = (extent[0] > 1.0 || extent[1] > 1.0)
                    .then(|| extent.map(|e| 0.5 * larger(e, 1.0)));
                Sampler {
                    kind: SamplerKind::Texture(texture, reach),
                    along,
                    across,
                }
            }
        }
    }

    /// The profile's largest value (before the amplitude): 1 but for a texture, which is scaled
    /// to integrate to one.
    pub(super) fn peak(&self) -> f32 {
        match self.kind {
            SamplerKind::Texture(texture, _) => texture.peak,
            _ => 1.0,
        }
    }

    /// The profile's value (before the amplitude) at pixel offset `d` with squared Mahalanobis
    /// radius `q` (already within the cut-off).
    #[inline(always)]
    pub(super) fn value(&self, [dx, dy]: [f32; 2], q: f32) -> f32 {
        let ramp = |x: f32| (x / EDGE_WIDTH + 0.5).clamp(0.0, 1.0);
        match self.kind {
            SamplerKind::Gaussian(table) => exp_half(table, q),
            SamplerKind::Disc => ramp(DISC_RADIUS - q.sqrt()),
            SamplerKind::Ring => {
                let r = q.sqrt();
                ramp(r - RING_RADII[0]).min(ramp(RING_RADII[1] - r))
            }
            SamplerKind::Texture(texture, reach) => self.textured(texture, reach, [dx, dy]),
            SamplerKind::Blank => 0.0,
        }
    }

    /// The texture's value at pixel offset `d`. Kept out of line so that [`Sampler::value`]
    /// stays small enough to inline into the pixel loop, where the Gaussian is the usual case.
    #[inline(never)]
    fn textured(&self, texture: &Texture, reach: Option<[f32; 2]>, [dx, dy]: [f32; 2]) -> f32 {
        let (along, across) = (self.along, self.across);
        let u = along[0] * dx + along[1] * dy;
        let v = across[0] * dx + across[1] * dy;
        match reach {
            None => texture.sample(u, v),
            Some(reach) => texture.box_mean(u, v, reach),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ value over the unit plane by the midpoint rule, within the cut-off.
    fn integrate(sampler: &Sampler) -> f64 {
        const STEPS: usize = 600;
        let h = 2.0 * CUTOFF_SIGMAS / STEPS as f64;
        let mut sum = 0.0;
        for j in 0..STEPS {
            for i in 0..STEPS {
                let u = (-CUTOFF_SIGMAS + (i as f64 + 0.5) * h) as f32;
                let v = (-CUTOFF_SIGMAS + (j as f64 + 0.5) * h) as f32;
                let q = u * u + v * v;
                if f64::from(q) <= CUTOFF_SIGMAS * CUTOFF_SIGMAS {
                    sum += f64::from(sampler.value([u, v], q));
                }
            }
        }
        sum * h * h
    }

    #[test]
    fn every_profile_integrates_to_its_stated_integral() {
        let identity = [1.0, 0.0, 1.0];
        let texture = Texture::new(2, 2, vec![1.0, 0.5, 0.25, 0.0]).unwrap();
        for profile in [
            Profile::Gaussian,
            Profile::Disc,
            Profile::Ring,
            Profile::Texture,
        ] {
            let sampler = Sampler::new(profile, identity, [0.0; 2], Some(&texture));
            let numeric = integrate(&sampler);
            let stated = profile.integral();
            // Midpoint rule on a 600² grid: the soft edges and bilinear texels are resolved to
            // well under 0.5 %.
            assert!(
                (numeric / stated - 1.0).abs() < 5e-3,
                "{profile:?}: {numeric} vs {stated}"
            );
        }
    }

    #[test]
    fn the_gaussian_table_matches_exp_to_its_stated_error() {
        let sampler = Sampler::new(Profile::Gaussian, [1.0, 0.0, 1.0], [0.0; 2], None);
        let worst = (0..=9000)
            .map(|i| {
                let q = i as f32 * CUTOFF_Q / 9000.0;
                let exact = (-0.5 * f64::from(q)).exp();
                (f64::from(sampler.value([0.0, 0.0], q)) / exact - 1.0).abs()
            })
            .fold(0.0, f64::max);
        // The tangent's error 2.4e-6 (see GAUSSIAN_STEPS) plus f32 rounding.
        assert!(worst < 3e-6, "{worst}");
    }

    #[test]
    fn textures_run_along_the_major_axis() {
        // Bright on the left half only: along a horizontal ellipse (σ = 4 px along x) that is
        // the −x side; two standard deviations out each way (8 px) lie on either half.
        let texture = Texture::new(2, 1, vec![1.0, 0.0]).unwrap();
        let wide = [1.0 / 16.0, 0.0, 1.0];
        let sampler = Sampler::new(Profile::Texture, wide, [0.0; 2], Some(&texture));
        let (left, right) = (
            sampler.value([-8.0, 0.0], 4.0),
            sampler.value([8.0, 0.0], 4.0),
        );
        assert!(left > 10.0 * right, "{left} {right}");
        // Turned a quarter: the same texture now runs vertically.
        let tall = [1.0, 0.0, 1.0 / 16.0];
        let sampler = Sampler::new(Profile::Texture, tall, [0.0; 2], Some(&texture));
        let (a, b) = (
            sampler.value([0.0, -8.0], 4.0),
            sampler.value([0.0, 8.0], 4.0),
        );
        assert!(a.max(b) > 10.0 * a.min(b), "{a} {b}");
    }

    #[test]
    fn invalid_textures_are_refused() {
        assert!(Texture::new(2, 2, vec![1.0; 3]).is_none());
        assert!(Texture::new(1, 1, vec![f32::NAN]).is_none());
        assert!(Texture::new(1, 1, vec![0.0]).is_none());
        assert!(Texture::new(0, 0, Vec::new()).is_none());
    }
}
