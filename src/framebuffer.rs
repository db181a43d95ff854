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
