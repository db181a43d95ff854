//! streak renders moving point-based geometry (surfels: oriented Gaussian disks) two ways from
//! one pipeline: physically based motion blur, and stylized motion hints (the object sharp at a
//! flash over a trail drawn in a [`style`]).
//!
//! The pipeline, one module per stage: a [`scene`] file is validated into surfels
//! ([`geometry`], [`pointcloud`], [`volume`], [`mesh`]) with keyframed [`motion`], a [`camera`]
//! and a [`shutter`]; a [`plan`] decides what the scene needs; the shared [`project`]ion stage
//! turns surfels into screen-space footprints that the shared [`raster`]izer composites; the
//! [`render`](mod@render)ers differ only in the footprints they make. [`metrics`] and [`study`] measure
//! error against run time, [`plot`] draws it, [`gallery`] puts renders side by side on a page,
//! [`output`] writes images.
//!
//! ```
//! use streak::{render, Method, Scene};
//! let text = r#"
//!     background = [0, 0, 0]
//!     [camera]
//!     eye = [0, 0, 4]
//!     target = [0, 0, 0]
//!     fov_y = 40
//!     width = 64
//!     height = 48
//!     [[object]]
//!     shape = { type = "sphere", radius = 0.5 }
//!     spacing = 0.02
//!     [[object.keyframe]]
//!     t = 0
//!     [[object.keyframe]]
//!     t = 1
//!     translate = [1, 0, 0]
//! "#;
//! let scene = Scene::parse(text, "ball.toml".as_ref())?;
//! let image = render(&scene, &Method::BLUR, None)?.image;
//! assert_eq!(image.pixels.len(), 64 * 48);
//! # Ok::<(), streak::Error>(())
//! ```

// Guards are written `if !(x > lo)` on purpose, so that a NaN fails them and is rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![warn(missing_docs)]

pub mod error;
pub mod framebuffer;
#[cfg(feature = "cli")]
pub mod gallery;
pub mod io;
pub mod math;
#[cfg(feature = "cli")]
pub mod metrics;
pub mod plan;
#[cfg(feature = "cli")]
pub mod plot;
mod project;
mod raster;
pub mod render;
pub mod scene;
#[cfg(feature = "cli")]
pub mod study;
pub mod style;
pub mod surfels;

pub use glam;

pub use error::{Error, Result};
pub use framebuffer::Framebuffer;
pub use plan::Plan;
pub use render::{render, Method, Render, Stats, Subframes};
pub use scene::{Camera, Keyframe, Light, Lighting, Motion, Object, Pose, Scene, Shutter};
