//! The linear float image every renderer writes (files are written by [`crate::io::image`]).

/// A linear-light RGB image, row-major, pixel (0,0) top-left.
#[derive(Clone, Debug, PartialEq)]
pub struct Framebuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` linear RGB pixels, row by row from the top.
    pub pixels: Vec<[f32; 3]>,
}

impl Framebuffer {
    /// A `width`×`height` image filled with `colour`.
    pub fn filled(width: u32, height: u32, colour: [f32; 3]) -> Self {
        Framebuffer {
            width,
            height,
            pixels: vec![colour; width as usize * height as usize],
        }
    }
}

/// The root-mean-square difference of two images' linear channels, pixel by pixel (over the
/// shorter of the two; `streak::metrics::compare` checks sizes and stands in for values that are
/// not finite first).
#[must_use]
pub fn root_mean_square_difference(test: &[[f32; 3]], reference: &[[f32; 3]]) -> f64 {
    let sum_of_squares: f64 = test
        .iter()
        .zip(reference)
        .flat_map(|(t, r)| t.iter().zip(r))
        .map(|(&t, &r)| (f64::from(t) - f64::from(r)).powi(2))
        .sum();
    (sum_of_squares / (3 * test.len()) as f64).sqrt()
}
