//! The linear float image every renderer writes, and its encodings (sRGB PNG, OpenEXR).

/// A linear-light RGB image, row-major, pixel (0,0) top-left.
#[derive(Clone, Debug, PartialEq)]
pub struct Framebuffer {
    pub width: u32,
    pub height: u32,
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
