//! streak renders moving geometry (surfels: oriented Gaussian disks; and triangle meshes,
//! drawn with analytic visibility in time and motion-blurred shadows by `Method::Analytic`)
//! two ways from one pipeline: physically based motion blur, and stylized motion hints (the
//! object sharp at a flash over a trail drawn in a [`style`]).
//!
//! Build a [`Scene`] in code from a [`Camera`], objects made by a [`surfels`] source and a
//! keyframed [`Motion`], pick a [`Method`], and [`render()`] it. This is
//! `examples/moving_knot.rs`, which writes a blurred and a hinted picture of a moving knot:
//!
#![doc = concat!("```no_run\n", include_str!("../examples/moving_knot.rs"), "```")]
//!
//! A scene file says the same in TOML ([`Scene::load`], [`Scene::parse`]; the format is in the
//! README):
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
//!
//! The modules, in the order data flows through them (docs/architecture.md has the whole map):
//! the [`scene`] model and the [`surfels`] sources that fill it, read from files by [`io`]; the
//! [`plan`] of what a scene needs; the [`render`](mod@render)ers, which share a crate-private
//! projection stage and tiled rasterizer and write a [`Framebuffer`]; [`math`] for the small
//! linear algebra they share. With the default `cli` feature come the tools: `metrics` and
//! `study` measure error against run time, `plot` draws it, and `gallery` puts renders side by
//! side on a page. Without it (`default-features = false`) the crate is a pure-Rust core.

// Guards are written `if !(x > lo)` on purpose, so that a NaN fails them and is rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![warn(missing_docs)]

mod cache;
pub mod error;
pub mod framebuffer;
#[cfg(feature = "cli")]
pub mod gallery;
pub mod io;
pub mod lod;
pub mod math;
mod memory;
#[cfg(feature = "cli")]
pub mod metrics;
pub mod plan;
#[cfg(feature = "cli")]
pub mod plot;
mod project;
mod raster;
pub mod render;
pub mod scene;
pub mod simplify;
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
