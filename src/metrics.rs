//! How far a rendered image is from a reference (RMSE, PSNR, SSIM, ꟻLIP), and the one
//! linear→sRGB encoding that PNG output and the metrics share.

use crate::error::{Error, Result};
use crate::framebuffer::{root_mean_square_difference, Framebuffer};
use crate::io::image::linear_to_srgb8;
use rayon::prelude::*;

/// Error of an image against a reference of the same size.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ImageError {
    /// Root-mean-square difference of the linear RGB values over all channels; 0 when identical.
    pub rmse: f64,
    /// Peak signal-to-noise ratio in dB for a peak of 1.0; `f64::INFINITY` (printed "inf") when identical.
    pub psnr_db: f64,
    /// Mean structural similarity (SSIM) of the sRGB luma; 1 when identical, lower is worse.
    pub ssim: f64,
    /// Mean LDR-ꟻLIP error of the sRGB images, in [0, 1]; 0 when identical.
    pub flip: f64,
}

/// Compares `test` against `reference`.
///
/// - RMSE and PSNR are computed on the linear colour values as they are (not clamped), with a
///   peak of 1.0. PSNR of identical images is `f64::INFINITY`.
/// - SSIM is computed on the luma of the sRGB-encoded 8-bit images (see [`crate::io::image::linear_to_srgb8`]):
///   Wang et al. 2004, 11×11 Gaussian window with σ = 1.5, K1 = 0.01, K2 = 0.03, luma in [0, 1];
///   near the border the window is cut to the image and renormalised, so every pixel counts.
/// - ꟻLIP is NVIDIA's LDR-ꟻLIP on the sRGB-encoded 8-bit images at the default
///   67 pixels per degree; the mean over all pixels is reported.
///
/// Colours are clamped to [0, 1] before sRGB encoding. A NaN or infinite channel is treated as
/// maximal error: it is replaced by whichever of 0 and 1 lies farther from the other image's value
/// in that channel (if both images are invalid there, the pair becomes 1 against 0), so a broken
/// pixel always makes every metric worse, never better.
///
/// Errors with [`Error::Usage`] when the sizes differ, when an image is empty, or when an image
/// holds a different number of pixels than its width × height.
pub fn compare(test: &Framebuffer, reference: &Framebuffer) -> Result<ImageError> {
    check_comparable(test, reference)?;
    let (test_pixels, reference_pixels) = with_invalid_values_as_maximal_error(test, reference);
    let rmse = root_mean_square_difference(&test_pixels, &reference_pixels);
    let psnr_db = if rmse == 0.0 {
        f64::INFINITY
    } else {
        -20.0 * rmse.log10()
    };

    let test_srgb = encode_srgb8(&test_pixels);
    let reference_srgb = encode_srgb8(&reference_pixels);
    // ꟻLIP runs single-threaded in C++, so SSIM can use the other cores meanwhile.
    let (ssim, flip) = rayon::join(
        || {
            mean_ssim(
                &srgb_luma(&test_srgb),
                &srgb_luma(&reference_srgb),
                test.width as usize,
            )
        },
        || mean_flip(&test_srgb, &reference_srgb, test.width, test.height),
    );

    Ok(ImageError {
        rmse,
        psnr_db,
        ssim,
        flip,
    })
}

/// Where two images differ, channel by channel (a non-finite value counted as in [`compare`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Differences {
    /// Largest absolute difference of one channel's linear value; 0 when identical.
    pub largest: f32,
    /// The pixel (x, y) holding it, the first in row order.
    pub at: [u32; 2],
    /// Pixels with any channel different.
    pub pixels: usize,
}

impl Differences {
    /// The largest difference and how many pixels differ, in a [`difference_image`].
    #[must_use]
    pub fn of(difference: &Framebuffer) -> Differences {
        let mut found = Differences {
            largest: 0.0,
            at: [0, 0],
            pixels: 0,
        };
        let width = difference.width as usize;
        for (i, pixel) in difference.pixels.iter().enumerate() {
            let largest = pixel.iter().copied().fold(0.0, f32::max);
            if largest > 0.0 {
                found.pixels += 1;
            }
            if largest > found.largest {
                found.largest = largest;
                found.at = [(i % width) as u32, (i / width) as u32];
            }
        }
        found
    }
}

/// |`test` − `reference`| per channel. Errors as [`compare`] does.
pub fn difference_image(test: &Framebuffer, reference: &Framebuffer) -> Result<Framebuffer> {
    check_comparable(test, reference)?;
    let (test_pixels, reference_pixels) = with_invalid_values_as_maximal_error(test, reference);
    Ok(Framebuffer {
        width: test.width,
        height: test.height,
        pixels: test_pixels
            .iter()
            .zip(&reference_pixels)
            .map(|(t, r)| std::array::from_fn(|c| (t[c] - r[c]).abs()))
            .collect(),
    })
}

/// Both images hold their width × height pixels, the sizes match, and they are not empty.
fn check_comparable(test: &Framebuffer, reference: &Framebuffer) -> Result<()> {
    check_pixel_count(test, "test image")?;
    check_pixel_count(reference, "reference image")?;
    if (test.width, test.height) != (reference.width, reference.height) {
        return Err(Error::Usage(format!(
            "cannot compare a {}×{} image with a {}×{} reference: the sizes must match",
            test.width, test.height, reference.width, reference.height
        )));
    }
    if test.pixels.is_empty() {
        return Err(Error::Usage(format!(
            "cannot compare empty {}×{} images",
            test.width, test.height
        )));
    }
    Ok(())
}

fn check_pixel_count(image: &Framebuffer, role: &str) -> Result<()> {
    let expected = image.width as usize * image.height as usize;
    if image.pixels.len() == expected {
        Ok(())
    } else {
        Err(Error::Usage(format!(
            "the {role} is {}×{} but holds {} pixels instead of {expected}",
            image.width,
            image.height,
            image.pixels.len()
        )))
    }
}

/// Copies of both images in which every non-finite channel is replaced so that the pair differs
/// as much as an in-range value can (see [`compare`]).
fn with_invalid_values_as_maximal_error(
    test: &Framebuffer,
    reference: &Framebuffer,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    test.pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(test_pixel, reference_pixel)| {
            let mut test_out = *test_pixel;
            let mut reference_out = *reference_pixel;
            for channel in 0..3 {
                (test_out[channel], reference_out[channel]) =
                    valid_channel_pair(test_pixel[channel], reference_pixel[channel]);
            }
            (test_out, reference_out)
        })
        .unzip()
}

fn valid_channel_pair(test: f32, reference: f32) -> (f32, f32) {
    let farthest_in_range = |other: f32| if other < 0.5 { 1.0 } else { 0.0 };
    match (test.is_finite(), reference.is_finite()) {
        (true, true) => (test, reference),
        (false, true) => (farthest_in_range(reference), reference),
        (true, false) => (test, farthest_in_range(test)),
        (false, false) => (1.0, 0.0),
    }
}

/// Tightly packed RGB8, as ꟻLIP takes it.
fn encode_srgb8(pixels: &[[f32; 3]]) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|pixel| pixel.map(linear_to_srgb8))
        .collect()
}

/// Rec. 709 luma (the sRGB primaries) of packed RGB8, in [0, 1].
fn srgb_luma(rgb8: &[u8]) -> Vec<f64> {
    rgb8.chunks_exact(3)
        .map(|rgb| {
            (0.2126 * f64::from(rgb[0]) + 0.7152 * f64::from(rgb[1]) + 0.0722 * f64::from(rgb[2]))
                / 255.0
        })
        .collect()
}

fn mean_flip(test_rgb8: &[u8], reference_rgb8: &[u8], width: u32, height: u32) -> f64 {
    let test_image = nv_flip::FlipImageRgb8::with_data(width, height, test_rgb8);
    let reference_image = nv_flip::FlipImageRgb8::with_data(width, height, reference_rgb8);
    let error_map = nv_flip::flip(
        reference_image,
        test_image,
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    // Summed in f64 here: ꟻLIP's own pool accumulates in f32, which drifts on large images.
    let errors = error_map.to_vec();
    errors.iter().map(|&e| f64::from(e)).sum::<f64>() / errors.len() as f64
}

const SSIM_WINDOW_RADIUS: usize = 5;
const SSIM_WINDOW_SIGMA: f64 = 1.5;
const SSIM_C1: f64 = 0.01 * 0.01;
const SSIM_C2: f64 = 0.03 * 0.03;

/// Mean SSIM of two luma planes in [0, 1] (dynamic range L = 1).
fn mean_ssim(test: &[f64], reference: &[f64], width: usize) -> f64 {
    let products = |f: fn(f64, f64) -> f64| -> Vec<f64> {
        test.iter().zip(reference).map(|(&x, &y)| f(x, y)).collect()
    };
    let mean_x = gaussian_window_mean(test, width);
    let mean_y = gaussian_window_mean(reference, width);
    let mean_xx = gaussian_window_mean(&products(|x, _| x * x), width);
    let mean_yy = gaussian_window_mean(&products(|_, y| y * y), width);
    let mean_xy = gaussian_window_mean(&products(|x, y| x * y), width);

    let ssim_sum: f64 = (0..test.len())
        .into_par_iter()
        .map(|i| {
            let (mx, my) = (mean_x[i], mean_y[i]);
            let variance_x = mean_xx[i] - mx * mx;
            let variance_y = mean_yy[i] - my * my;
            let covariance = mean_xy[i] - mx * my;
            ((2.0 * mx * my + SSIM_C1) * (2.0 * covariance + SSIM_C2))
                / ((mx * mx + my * my + SSIM_C1) * (variance_x + variance_y + SSIM_C2))
        })
        .sum();
    ssim_sum / test.len() as f64
}

/// Gaussian-weighted local mean at every pixel of a row-major plane. The separable window is
/// cut at the image border and renormalised; because it is separable, renormalising each 1-D
/// pass is exactly renormalising the cut 2-D window.
fn gaussian_window_mean(plane: &[f64], width: usize) -> Vec<f64> {
    let height = plane.len() / width;
    let weights: Vec<f64> = (0..=2 * SSIM_WINDOW_RADIUS)
        .map(|k| {
            let offset = k as f64 - SSIM_WINDOW_RADIUS as f64;
            (-offset * offset / (2.0 * SSIM_WINDOW_SIGMA * SSIM_WINDOW_SIGMA)).exp()
        })
        .collect();
    // Weighted mean of sample(i) for i in the window around `centre`, clipped to 0..len.
    let window_mean = |centre: usize, len: usize, sample: &dyn Fn(usize) -> f64| {
        let first = centre.saturating_sub(SSIM_WINDOW_RADIUS);
        let last = (centre + SSIM_WINDOW_RADIUS).min(len - 1);
        let (weighted_sum, weight_sum) = (first..=last).fold((0.0, 0.0), |(sum, total), i| {
            let weight = weights[i + SSIM_WINDOW_RADIUS - centre];
            (sum + weight * sample(i), total + weight)
        });
        weighted_sum / weight_sum
    };

    let mut horizontal = vec![0.0; plane.len()];
    horizontal
        .par_chunks_mut(width)
        .zip(plane.par_chunks(width))
        .for_each(|(out_row, in_row)| {
            for (x, out) in out_row.iter_mut().enumerate() {
                *out = window_mean(x, width, &|i| in_row[i]);
            }
        });
    let mut both = vec![0.0; plane.len()];
    both.par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, out_row)| {
            for (x, out) in out_row.iter_mut().enumerate() {
                *out = window_mean(y, height, &|i| horizontal[i * width + x]);
            }
        });
    both
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random value in [-1, 1] for pixel `index` (a small integer hash).
    fn noise(index: usize) -> f32 {
        let mut h = (index as u32).wrapping_mul(0x9E37_79B9) ^ 0x85EB_CA6B;
        h ^= h >> 15;
        h = h.wrapping_mul(0x2C1B_3C6D);
        h ^= h >> 12;
        h = h.wrapping_mul(0x297A_2D39);
        h ^= h >> 15;
        (h as f32 / u32::MAX as f32) * 2.0 - 1.0
    }

    /// A smooth, textured image with every value in [0.2, 0.8].
    fn textured(width: u32, height: u32) -> Framebuffer {
        let pixels = (0..width * height)
            .map(|i| {
                let (x, y) = ((i % width) as f32, (i / width) as f32);
                [
                    0.5 + 0.3 * (x * 0.31).sin() * (y * 0.17).cos(),
                    0.5 + 0.3 * (x * 0.11 + y * 0.23).sin(),
                    0.5 + 0.3 * ((x - y) * 0.07).cos(),
                ]
            })
            .collect();
        Framebuffer {
            width,
            height,
            pixels,
        }
    }

    fn with_noise(image: &Framebuffer, amplitude: f32) -> Framebuffer {
        let mut noisy = image.clone();
        for (i, pixel) in noisy.pixels.iter_mut().enumerate() {
            for (c, value) in pixel.iter_mut().enumerate() {
                *value += amplitude * noise(3 * i + c);
            }
        }
        noisy
    }

    #[test]
    fn identical_images_have_no_error() {
        let image = with_noise(&textured(48, 32), 0.15);
        let error = compare(&image, &image).unwrap();
        assert_eq!(error.rmse, 0.0);
        assert_eq!(error.psnr_db, f64::INFINITY);
        assert_eq!(error.psnr_db.to_string(), "inf");
        assert!((error.ssim - 1.0).abs() <= 1e-6, "ssim {}", error.ssim);
        assert_eq!(error.flip, 0.0);
    }

    #[test]
    fn constant_offset_gives_analytic_rmse_and_psnr() {
        let reference = textured(40, 30);
        let mut test = reference.clone();
        for pixel in &mut test.pixels {
            *pixel = pixel.map(|v| v + 0.05);
        }
        let error = compare(&test, &reference).unwrap();
        assert!((error.rmse - 0.05).abs() < 1e-6, "rmse {}", error.rmse);
        let expected_psnr = -20.0 * 0.05f64.log10(); // 26.0206 dB
        assert!(
            (error.psnr_db - expected_psnr).abs() < 1e-4,
            "psnr {}",
            error.psnr_db
        );
    }

    #[test]
    fn ssim_of_flat_images_matches_the_formula() {
        // With no variance SSIM reduces to its luminance term (2xy + C1) / (x² + y² + C1).
        // Linear 0.5 encodes to 188 and 1.0 to 255 in every channel, so luma is 188/255 and 1.
        let reference = Framebuffer::filled(20, 20, [0.5; 3]);
        let test = Framebuffer::filled(20, 20, [1.0; 3]);
        let (x, y) = (1.0, 188.0 / 255.0);
        let expected = (2.0 * x * y + SSIM_C1) / (x * x + y * y + SSIM_C1);
        let error = compare(&test, &reference).unwrap();
        assert!((error.ssim - expected).abs() < 1e-12, "ssim {}", error.ssim);
    }

    #[test]
    fn every_metric_worsens_as_noise_grows() {
        let reference = textured(64, 64);
        let errors: Vec<ImageError> = [0.005, 0.02, 0.05, 0.15, 0.4]
            .iter()
            .map(|&amplitude| compare(&with_noise(&reference, amplitude), &reference).unwrap())
            .collect();
        for pair in errors.windows(2) {
            let (less, more) = (pair[0], pair[1]);
            assert!(more.rmse > less.rmse, "{less:?} then {more:?}");
            assert!(more.psnr_db < less.psnr_db, "{less:?} then {more:?}");
            assert!(more.ssim < less.ssim, "{less:?} then {more:?}");
            assert!(more.flip > less.flip, "{less:?} then {more:?}");
        }
    }

    #[test]
    fn nan_pixel_counts_as_maximal_error() {
        let reference = Framebuffer::filled(10, 10, [0.25; 3]);
        let mut test = reference.clone();
        test.pixels[0] = [f32::NAN; 3];
        let error = compare(&test, &reference).unwrap();
        // Each NaN channel becomes 1.0, 0.75 away from the reference, in 1 pixel of 100.
        let expected_rmse = 0.75 / 100f64.sqrt();
        assert!((error.rmse - expected_rmse).abs() < 1e-9, "{error:?}");
        assert!(error.ssim < 1.0 && error.flip > 0.0, "{error:?}");

        let both_nan = compare(&test, &test).unwrap();
        assert!(
            (both_nan.rmse - 1.0 / 100f64.sqrt()).abs() < 1e-9,
            "{both_nan:?}"
        );
    }

    #[test]
    fn mismatched_or_malformed_images_are_usage_errors() {
        let small = Framebuffer::filled(4, 4, [0.5; 3]);
        let wide = Framebuffer::filled(5, 4, [0.5; 3]);
        assert!(matches!(compare(&small, &wide), Err(Error::Usage(_))));

        let mut short = small.clone();
        short.pixels.pop();
        assert!(matches!(compare(&short, &small), Err(Error::Usage(_))));

        let empty = Framebuffer::filled(0, 3, [0.5; 3]);
        assert!(matches!(compare(&empty, &empty), Err(Error::Usage(_))));
    }

    #[test]
    fn tiny_images_still_compare() {
        let reference = Framebuffer::filled(1, 1, [0.2; 3]);
        let test = Framebuffer::filled(1, 1, [0.3; 3]);
        let error = compare(&test, &reference).unwrap();
        assert!(
            error.ssim.is_finite() && error.flip.is_finite(),
            "{error:?}"
        );
    }
}
