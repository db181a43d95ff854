//! Files in and out: the readers map what they find to the model's types and place every error
//! in its file (`file: field: message`); the model itself never touches a file.
//!
//! - [`scene_file`] and [`style_file`]: TOML scenes and styles;
//! - [`ply`], [`obj`] and [`raw_volume`]: point clouds, meshes and volumes;
//! - [`read`]: whole files read with a bound, gunzipped on the fly;
//! - [`image`]: PNG and OpenEXR output;
//! - [`write`](mod@write): files written whole, with nothing partial left where writing failed.

mod exact;
pub mod image;
pub mod obj;
pub mod ply;
pub mod raw_volume;
pub mod read;
pub mod scene_file;
pub mod style_file;
pub mod write;
