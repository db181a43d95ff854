//! streak renders moving point-based geometry (surfels: oriented Gaussian disks) two ways from
//! one pipeline: physically based motion blur, and (later) stylized motion hints.
//!
//! The pipeline, one module per stage: a [`scene`] file is validated into surfels
//! ([`geometry`], [`pointcloud`]) with keyframed [`motion`], a [`camera`] and a [`shutter`];
//! a [`plan`] decides what the scene needs; the shared [`project`]ion stage turns surfels into
//! screen-space footprints that the shared [`raster`]izer composites; the [`render`]ers differ
//! only in the footprints they make. [`metrics`] and [`study`] measure error against run time,
//! [`plot`] draws it, [`output`] writes images.

// Guards are written `if !(x > lo)` on purpose, so that a NaN fails them and is rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod camera;
pub mod error;
pub mod framebuffer;
pub mod geometry;
pub mod metrics;
pub mod motion;
pub mod output;
pub mod plan;
pub mod plot;
pub mod pointcloud;
pub mod project;
pub mod raster;
pub mod render;
pub mod scene;
pub mod shutter;
pub mod study;

pub use error::{Error, Result};
pub use framebuffer::Framebuffer;
pub use plan::Plan;
pub use render::{render, Method, Render, Settings};
pub use scene::Scene;
