//! Image files: sRGB PNG for looking, linear OpenEXR for analysis (and the study's cache).

use crate::error::{Error, Result};
use crate::framebuffer::Framebuffer;
use crate::scene::camera::MAX_IMAGE_SIDE;
use image::ImageEncoder;
use std::io::Write;
use std::path::Path;

use super::write::write_whole;

/// The kinds of image file written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageKind {
    /// 8-bit sRGB PNG, for looking.
    Png,
    /// Linear 32-bit float OpenEXR, for analysis.
    Exr,
}

impl ImageKind {
    /// The kind a file name asks for by its extension (`.png`, `.exr`, any case), or an error
    /// saying which names are understood.
    pub fn of(path: &Path) -> Result<ImageKind> {
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match extension.as_deref() {
            Some("png") => Ok(ImageKind::Png),
            Some("exr") => Ok(ImageKind::Exr),
            _ => Err(Error::Usage(format!(
                "{}: unknown image type; use a .png (sRGB) or .exr (linear float) file name",
                path.display()
            ))),
        }
    }
}

/// Write `image` as its file name says: `.png` (8-bit sRGB) or `.exr` (linear 32-bit float).
pub fn write_image(image: &Framebuffer, path: &Path) -> Result<()> {
    match ImageKind::of(path)? {
        ImageKind::Png => write_png(image, path),
        ImageKind::Exr => write_exr(image, path),
    }
}

fn image_error(path: &Path, e: image::ImageError) -> Error {
    Error::io(path, std::io::Error::other(e))
}

/// The error for an image whose pixels are not `width × height`, as a library caller's
/// hand-built [`Framebuffer`] may be.
fn size_error(image: &Framebuffer, path: &Path) -> Error {
    Error::Usage(format!(
        "{}: the image holds {} pixels, not {} × {}: not written",
        path.display(),
        image.pixels.len(),
        image.width,
        image.height
    ))
}

/// Write an 8-bit sRGB PNG.
pub fn write_png(image: &Framebuffer, path: &Path) -> Result<()> {
    if image.pixels.len() as u64 != u64::from(image.width) * u64::from(image.height) {
        return Err(size_error(image, path));
    }
    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| p.map(linear_to_srgb8))
        .collect();
    // Encoded in memory, then written as a whole: the image crate's PNG encoder writes its last
    // chunk and flushes the file as they are dropped, where a failed write (a full disk) is lost,
    // and a truncated file was reported as written.
    let mut encoded = Vec::new();
    image::codecs::png::PngEncoder::new(&mut encoded)
        .write_image(
            &bytes,
            image.width,
            image.height,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| image_error(path, e))?;
    write_whole(path, |out| out.write_all(&encoded)).map_err(|e| Error::io(path, e))
}

/// Write a linear float OpenEXR.
pub fn write_exr(image: &Framebuffer, path: &Path) -> Result<()> {
    let data: Vec<f32> = image.pixels.iter().flatten().copied().collect();
    let buffer = image::Rgb32FImage::from_raw(image.width, image.height, data)
        .ok_or_else(|| size_error(image, path))?;
    write_whole(path, |out| {
        image::DynamicImage::ImageRgb32F(buffer)
            .write_to(out, image::ImageFormat::OpenExr)
            .map_err(std::io::Error::other)
    })
    .map_err(|e| Error::io(path, e))
}

/// Read a linear float OpenEXR written by [`write_exr`].
pub fn read_exr(path: &Path) -> Result<Framebuffer> {
    let (width, height, pixels) = decode(path)?;
    Ok(Framebuffer {
        width,
        height,
        pixels,
    })
}

/// Read an image as linear RGB, as its file name says: `.exr` as stored, `.png` (any bit depth and
/// channel layout; alpha is ignored) decoded from sRGB. A PNG that [`write_png`] wrote reads back
/// to values that encode to the same 8-bit codes.
pub fn read_image(path: &Path) -> Result<Framebuffer> {
    match ImageKind::of(path)? {
        ImageKind::Exr => read_exr(path),
        ImageKind::Png => {
            let (width, height, encoded) = decode(path)?;
            Ok(Framebuffer {
                width,
                height,
                pixels: encoded
                    .into_iter()
                    .map(|p| p.map(|v| srgb_to_linear(f64::from(v))))
                    .collect(),
            })
        }
    }
}

/// An image file's size and RGB values as stored: at most [`MAX_IMAGE_SIDE`] pixels a side,
/// refused from the header before anything is decoded.
fn decode(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    let mut reader = image::ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    // The sides bound the decoded pixels, at most 16 bytes each (RGBA float). The image crate's
    // default bound, 512 MiB, refused the EXRs streak writes from about 6,700 pixels square.
    limits.max_alloc = Some(u64::from(MAX_IMAGE_SIDE).pow(2) * 16);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| match e {
        image::ImageError::Limits(_) => Error::Usage(format!(
            "{}: larger than streak reads (at most {MAX_IMAGE_SIDE} pixels a side)",
            path.display()
        )),
        other => image_error(path, other),
    })?;
    let rgb = decoded.into_rgb32f();
    let (width, height) = rgb.dimensions();
    Ok((width, height, rgb.pixels().map(|p| p.0).collect()))
}

/// The sRGB transfer curve inverted (IEC 61966-2-1): the linear value of an encoded one in
/// [0, 1].
pub(crate) fn srgb_to_linear(encoded: f64) -> f32 {
    let linear = if encoded <= 0.04045 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    };
    linear as f32
}

/// Linear→sRGB 8-bit encoding used by PNG output and by the metrics (one function for the whole crate).
///
/// The value is clamped to [0, 1], encoded with the sRGB transfer curve (IEC 61966-2-1) and
/// rounded to the nearest of 0..=255. NaN encodes as 0.
///
/// The curve rises, so a value's code is the number of codes whose least value lies at or below
/// it: eight comparisons in a table found once from the curve, instead of a power per channel.
/// The same codes as the curve for every f32.
#[must_use]
pub fn linear_to_srgb8(v: f32) -> u8 {
    srgb8_thresholds().partition_point(|&least| least <= v) as u8
}

/// For each code 1..=255, the least f32 the curve encodes to it or above: found by bisection
/// over the bit patterns of [0, 1], whose order is their values' order.
fn srgb8_thresholds() -> &'static [f32; 255] {
    static THRESHOLDS: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    THRESHOLDS.get_or_init(|| {
        std::array::from_fn(|i| {
            let code = i as u8 + 1;
            // The curve gives 0 at the low end and 255 at the high end.
            let (mut low, mut high) = (0.0f32.to_bits(), 1.0f32.to_bits());
            while high - low > 1 {
                let middle = low + (high - low) / 2;
                if srgb8_by_curve(f32::from_bits(middle)) >= code {
                    high = middle;
                } else {
                    low = middle;
                }
            }
            f32::from_bits(high)
        })
    })
}

/// [`linear_to_srgb8`] evaluated on the curve itself.
fn srgb8_by_curve(v: f32) -> u8 {
    let linear = if v.is_nan() {
        0.0
    } else {
        f64::from(v).clamp(0.0, 1.0)
    };
    let encoded = if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    };
    (encoded * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trips_linear_values_exactly() {
        let mut image = Framebuffer::filled(5, 3, [0.25, 1.5, 1e-4]);
        image.pixels[7] = [0.0, 0.123_456_78, 3.0];
        let path = std::env::temp_dir().join(format!("streak-exr-{}.exr", std::process::id()));
        write_exr(&image, &path).unwrap();
        let back = read_exr(&path).unwrap();
        std::fs::remove_file(&path).ok();
        assert_eq!(back, image);
    }

    /// The bytes of a 1 × 1 EXR whose header claims `width` × `height`: read, it meets the size
    /// bounds with no more than a header's worth of data behind them.
    fn exr_claiming(width: u32, height: u32) -> Vec<u8> {
        let path = std::env::temp_dir().join(format!("streak-exr-1-{}.exr", std::process::id()));
        write_exr(&Framebuffer::filled(1, 1, [0.5; 3]), &path).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).ok();
        // Each attribute's value, after its name, its type and its size.
        let value = |bytes: &[u8], name: &str, kind: &str| {
            let key = format!("{name}\0{kind}\0");
            let at = bytes
                .windows(key.len())
                .position(|w| w == key.as_bytes())
                .unwrap();
            at + key.len() + 4
        };
        let word =
            |bytes: &[u8], at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        let tiles = value(&bytes, "tiles", "tiledesc");
        let (tile_width, tile_height) = (word(&bytes, tiles), word(&bytes, tiles + 4));
        let chunks = width.div_ceil(tile_width) * height.div_ceil(tile_height);
        let at = value(&bytes, "chunkCount", "int");
        bytes[at..at + 4].copy_from_slice(&chunks.to_le_bytes());
        for name in ["dataWindow", "displayWindow"] {
            // x min, y min, x max and y max.
            let at = value(&bytes, name, "box2i") + 8;
            bytes[at..at + 4].copy_from_slice(&(width - 1).to_le_bytes());
            bytes[at + 4..at + 8].copy_from_slice(&(height - 1).to_le_bytes());
        }
        bytes
    }

    #[test]
    fn an_exr_as_large_as_streak_renders_is_not_refused_for_its_size() {
        let path = std::env::temp_dir().join(format!("streak-exr-big-{}.exr", std::process::id()));
        let side = MAX_IMAGE_SIDE;
        std::fs::write(&path, exr_claiming(side, side)).unwrap();
        // Its pixel data is missing, so it cannot be read; but not for being too large.
        let largest = read_exr(&path).unwrap_err().to_string();
        std::fs::write(&path, exr_claiming(side + 1, 1)).unwrap();
        let wider = read_exr(&path).unwrap_err().to_string();
        std::fs::remove_file(&path).ok();
        assert!(!largest.contains("larger than streak reads"), "{largest}");
        assert!(wider.contains("larger than streak reads"), "{wider}");
    }

    /// `/dev/full` takes any file name and fails every write, as a full disk does.
    #[cfg(target_os = "linux")]
    #[test]
    fn an_image_that_cannot_be_written_is_an_error() {
        let dir = std::env::temp_dir().join(format!("streak-full-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let image = Framebuffer::filled(16, 16, [0.5; 3]);
        for name in ["full.png", "full.exr"] {
            let path = dir.join(name);
            std::os::unix::fs::symlink("/dev/full", &path).unwrap();
            let written = write_image(&image, &path);
            std::fs::remove_file(&path).unwrap();
            let message = written.map_err(|e| e.to_string()).unwrap_err();
            assert!(message.contains("No space left"), "{name}: {message}");
        }
        std::fs::remove_dir(&dir).unwrap();
    }

    #[test]
    fn every_8_bit_code_reads_back_to_itself() {
        for code in 0..=255u8 {
            let linear = srgb_to_linear(f64::from(code) / 255.0);
            assert_eq!(
                linear_to_srgb8(linear),
                code,
                "code {code} read as {linear}"
            );
        }
    }

    #[test]
    fn an_image_of_the_wrong_size_is_an_error_and_no_file() {
        // A library caller's hand-built image: 3 pixels said to be 4 × 4 (the PNG encoder
        // asserted on it and the program panicked).
        let image = Framebuffer {
            width: 4,
            height: 4,
            pixels: vec![[0.5; 3]; 3],
        };
        let dir = std::env::temp_dir().join(format!("streak-size-{}", std::process::id()));
        for name in ["short.png", "short.exr"] {
            let path = dir.join(name);
            let message = write_image(&image, &path).unwrap_err().to_string();
            assert!(message.contains("holds 3 pixels, not 4 × 4"), "{message}");
            assert!(!path.exists(), "{name} was written");
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_png_reads_back_to_the_codes_written() {
        let mut image = Framebuffer::filled(4, 2, [0.0, 0.5, 1.0]);
        image.pixels[5] = [0.003, 0.2, 0.9];
        let path = std::env::temp_dir().join(format!("streak-png-{}.png", std::process::id()));
        write_png(&image, &path).unwrap();
        let back = read_image(&path).unwrap();
        std::fs::remove_file(&path).ok();
        assert_eq!((back.width, back.height), (4, 2));
        for (read, written) in back.pixels.iter().zip(&image.pixels) {
            assert_eq!(read.map(linear_to_srgb8), written.map(linear_to_srgb8));
        }
    }

    #[test]
    fn unknown_extensions_are_refused_with_advice() {
        let e =
            write_image(&Framebuffer::filled(1, 1, [0.0; 3]), Path::new("out.jpg")).unwrap_err();
        assert!(e.to_string().contains(".png"));
    }

    #[test]
    fn srgb_encoding_follows_the_standard_curve() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        // The linear segment ends at 0.0031308 → 12.92 × 0.0031308 × 255 = 10.31.
        assert_eq!(linear_to_srgb8(0.003_130_8), 10);
        // 1.055 × 0.5^(1/2.4) − 0.055 = 0.7354 → 187.5 → 188.
        assert_eq!(linear_to_srgb8(0.5), 188);
        assert_eq!(linear_to_srgb8(-0.5), 0);
        assert_eq!(linear_to_srgb8(7.0), 255);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
    }

    #[test]
    fn the_table_gives_the_curves_codes() {
        // Each code's least value, and the float just below it, which still gets the code before.
        for (i, &least) in srgb8_thresholds().iter().enumerate() {
            let code = i as u8 + 1;
            assert_eq!(srgb8_by_curve(least), code);
            assert_eq!(linear_to_srgb8(least), code);
            let below = f32::from_bits(least.to_bits() - 1);
            assert_eq!(srgb8_by_curve(below), code - 1);
            assert_eq!(linear_to_srgb8(below), code - 1);
        }
        // A million values spread over the bit patterns of [0, 2], both signs, and the odd ones.
        let top = 2.0f32.to_bits();
        for k in 0..1_000_000u32 {
            let bits = (u64::from(k) * u64::from(top) / 1_000_000) as u32;
            for v in [f32::from_bits(bits), -f32::from_bits(bits)] {
                assert_eq!(linear_to_srgb8(v), srgb8_by_curve(v), "{v}");
            }
        }
        for v in [
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -0.0,
            f32::MIN_POSITIVE,
        ] {
            assert_eq!(linear_to_srgb8(v), srgb8_by_curve(v), "{v}");
        }
    }
}
