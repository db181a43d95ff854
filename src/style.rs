//! Style presets for motion hints: everything that makes a hint look the way it does.
//!
//! A style is built in code ([`Style::new`]) or read from a TOML file ([`Style::load`],
//! [`crate::io::style_file`]; the presets live in `styles/`, every field is documented in the
//! README). Either way [`Style::check`] checks each value and names the field of any mistake.
//! Every field has a default, so an empty file is the default style: the object sharp at
//! shutter close over an alpha-blended trail of its own colours (Guan & Mueller §3.1, the
//! flash-and-trail photograph).

use crate::error::{shown, Error, Result};
pub use crate::raster::{Profile, Texture};
use crate::scene::{finite, rgb};
use serde::Deserialize;
use std::path::PathBuf;

/// Most stroboscopic copies a trail may be cut into.
pub const MAX_COPIES: u32 = 64;

/// Least share of the emitting points a sparse trail may keep. Each kept point's splat is made
/// 1/density heavier; at 10⁻³⁹ and below that weight overflowed the rasterizer's single
/// precision and left NaN pixels, and far above it a trail of one point in ten thousand is
/// already a few scattered strokes.
pub const MIN_TRAIL_DENSITY: f64 = 1e-4;

/// Most speed lines drawn.
pub const MAX_SPEED_LINES: u32 = 10_000;

/// Most stops a colour ramp may have: a colour map of 256 entries is the usual finest.
pub const MAX_RAMP_STOPS: usize = 1024;

/// Largest side of a trail texture image, px.
pub const MAX_TEXTURE_SIDE: u32 = 2048;

/// How the trail layer is added to what lies behind it (Guan & Mueller §4).
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Blend {
    /// Covers what lies behind by its coverage: better blending.
    Alpha,
    /// Adds its light: "more true to the photographic model".
    Add,
}

/// How the trail and the object are put together (Guan & Mueller §4).
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Composite {
    /// Two images: the trail, then the object over it with its opacity, so that trails within
    /// the object's extent are de-emphasized.
    Under,
    /// One depth order for object and trail splats: closer object parts hide farther trails.
    Merged,
}

/// What drives a trail's colour ramp.
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum RampBy {
    /// Screen speed in px per exposure: later stops are faster (Guan & Mueller Fig. 7, "redder
    /// trails have larger motion").
    Speed,
    /// Time along the trail: the first stop at its oldest end, the last at its newest.
    Time,
}

/// Which points emit trails.
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Emitters {
    /// Points that face the camera and are not hidden in the object image at flash time (the
    /// visibility test of Guan & Mueller §6's future work).
    Visible,
    /// Points that face the camera at flash time (Guan & Mueller §4).
    FrontFacing,
    /// Every point, for as long as it faces the camera.
    All,
}

/// Which points carry speed lines.
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Select {
    /// Visible points seen almost edge-on at flash time: the object's outline.
    Silhouette,
    /// Any visible point, a sparse sample spread over the object.
    Sample,
}

/// How the sharp object is drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectLook {
    /// Whether the object is drawn at all (else: the trail alone).
    pub draw: bool,
    /// Flash time as a fraction of the exposure: 0 at shutter open, 1 at close.
    pub flash: f64,
    /// Opacity of the object layer, in [0, 1].
    pub opacity: f64,
    /// A flat colour instead of the shaded surfels.
    pub colour: Option<[f32; 3]>,
}

/// Where a trail's colour comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum TrailColour {
    /// The surfels' own shaded colours.
    Object,
    /// A ramp of evenly spaced linear RGB stops, driven by `by`.
    Ramp {
        /// At least two stops.
        stops: Vec<[f32; 3]>,
        /// What drives it.
        by: RampBy,
        /// Speeds mapped to the first and last stop, px per exposure (default: 0 and the
        /// fastest path in the scene).
        speed_range: Option<[f64; 2]>,
    },
}

/// The trail layer.
#[derive(Clone, Debug, PartialEq)]
pub struct Trail {
    /// Whether trails are drawn at all.
    pub draw: bool,
    /// Fraction of the exposure the trail spans.
    pub length: f64,
    /// Fraction of the exposure between the flash and the trail's newest end.
    pub offset: f64,
    /// Stroboscopic copies the trail is cut into.
    pub copies: u32,
    /// Fraction of each copy's slot drawn, in (0, 1].
    pub duty: f64,
    /// How the trail adds to what lies behind.
    pub blend: Blend,
    /// How trail and object are put together.
    pub composite: Composite,
    /// Weight multiplier of the trail splats.
    pub intensity: f64,
    /// Share of the emitting points that do emit, from [`MIN_TRAIL_DENSITY`] to 1, their splats
    /// made heavier in proportion: sparse, separate strokes for textured looks.
    pub density: f64,
    /// Scale of each trail splat's own size (its spread across the motion), its weight scaled
    /// by the change of area so that its amplitude stays.
    pub width: f64,
    /// Where its colour comes from.
    pub colour: TrailColour,
    /// Opacity at the oldest end relative to the newest, in [0, 1].
    pub fade: f64,
    /// Footprint profile of the trail splats.
    pub profile: Profile,
    /// The image a [`Profile::Texture`] trail maps.
    pub texture: Option<Texture>,
    /// Scale each trail splat by N·L of the scene's lights.
    pub modulate_light: bool,
    /// Scale each trail splat by N·V.
    pub modulate_view: bool,
    /// Which points emit trails.
    pub emitters: Emitters,
}

/// Speed lines along the projected paths of a few points.
#[derive(Clone, Debug, PartialEq)]
pub struct SpeedLines {
    /// Whether they are drawn.
    pub draw: bool,
    /// Most lines.
    pub count: u32,
    /// Which points carry them.
    pub select: Select,
    /// Least distance between two lines' newest ends, px.
    pub spacing: f64,
    /// Fraction of the exposure a line spans.
    pub length: f64,
    /// Fraction of the exposure between the flash and a line's newest end.
    pub offset: f64,
    /// Stroke width at the newest end, px.
    pub width: f64,
    /// Width at the oldest end relative to the newest, in [0, 1].
    pub taper: f64,
    /// Opacity at the oldest end relative to the newest, in [0, 1].
    pub fade: f64,
    /// Opacity at the newest end, in [0, 1].
    pub opacity: f64,
    /// Linear RGB.
    pub colour: [f32; 3],
}

/// A validated style.
#[derive(Clone, Debug, PartialEq)]
pub struct Style {
    /// The file it came from, if any.
    pub source: Option<PathBuf>,
    /// What it is for.
    pub description: String,
    /// Replaces the scene's background when given.
    pub background: Option<[f32; 3]>,
    /// The sharp object.
    pub object: ObjectLook,
    /// The trail.
    pub trail: Trail,
    /// Speed lines.
    pub speed_lines: SpeedLines,
}

impl Default for Style {
    /// The flash-and-trail look: what an empty style file gives.
    fn default() -> Self {
        crate::io::style_file::default_style()
    }
}

impl Style {
    /// A style of `object`, `trail` and `speed_lines` over the scene's own background, with
    /// every value checked ([`Style::check`]).
    pub fn new(object: ObjectLook, trail: Trail, speed_lines: SpeedLines) -> Result<Style> {
        let style = Style {
            source: None,
            description: String::new(),
            background: None,
            object,
            trail,
            speed_lines,
        };
        style.check()?;
        Ok(style)
    }

    /// Check every value; an error names the field as a style file spells it (`trail.fade`) and
    /// says what would be right.
    pub fn check(&self) -> Result<()> {
        let o = &self.object;
        within("object.flash", o.flash, 0.0, 1.0)?;
        within("object.opacity", o.opacity, 0.0, 1.0)?;
        if let Some(c) = o.colour {
            rgb("object.colour", c)?;
        }
        let t = &self.trail;
        if let TrailColour::Ramp {
            stops, speed_range, ..
        } = &t.colour
        {
            if !(2..=MAX_RAMP_STOPS).contains(&stops.len()) {
                return Err(Error::invalid(
                    "trail.ramp",
                    format!(
                        "has {} stop(s): a ramp has from 2 to {MAX_RAMP_STOPS}",
                        stops.len()
                    ),
                ));
            }
            for (i, c) in stops.iter().enumerate() {
                rgb(&format!("trail.ramp[{i}]"), *c)?;
            }
            if let Some([lo, hi]) = *speed_range {
                let lo = finite("trail.speed_range[0]", lo)?;
                let hi = finite("trail.speed_range[1]", hi)?;
                if !(0.0 <= lo && lo < hi) {
                    return Err(Error::invalid(
                        "trail.speed_range",
                        format!("[{lo}, {hi}]: need 0 ≤ slowest < fastest (px per exposure)"),
                    ));
                }
            }
        }
        if (t.profile == Profile::Texture) != t.texture.is_some() {
            return Err(Error::invalid(
                "trail.texture",
                "a texture profile goes with a texture image, and only with one",
            ));
        }
        within("trail.length", t.length, 0.0, 1.0)?;
        within("trail.offset", t.offset, 0.0, 1.0)?;
        count("trail.copies", t.copies, MAX_COPIES)?;
        share("trail.duty", t.duty)?;
        within("trail.intensity", t.intensity, 0.0, 100.0)?;
        within("trail.width", t.width, 0.1, 20.0)?;
        within("trail.density", t.density, MIN_TRAIL_DENSITY, 1.0)?;
        within("trail.fade", t.fade, 0.0, 1.0)?;
        let s = &self.speed_lines;
        count("speed_lines.count", s.count, MAX_SPEED_LINES)?;
        within("speed_lines.spacing", s.spacing, 0.0, 1e4)?;
        within("speed_lines.length", s.length, 0.0, 1.0)?;
        within("speed_lines.offset", s.offset, 0.0, 1.0)?;
        within("speed_lines.width", s.width, 0.01, 100.0)?;
        within("speed_lines.taper", s.taper, 0.0, 1.0)?;
        within("speed_lines.fade", s.fade, 0.0, 1.0)?;
        within("speed_lines.opacity", s.opacity, 0.0, 1.0)?;
        rgb("speed_lines.colour", s.colour)?;
        if let Some(c) = self.background {
            rgb("background", c)?;
        }
        Ok(())
    }

    /// The style's name: its file's stem, or `default`.
    #[must_use]
    pub fn name(&self) -> String {
        self.source
            .as_ref()
            .and_then(|p| p.file_stem())
            .map_or_else(|| "default".into(), |s| s.to_string_lossy().into_owned())
    }
}

/// Refuses two styles of one [`Style::name`]: hint images and study rows are named after their
/// style, so one would overwrite the other's image and share its row.
pub fn check_distinct_names(styles: &[std::sync::Arc<Style>]) -> Result<()> {
    let shown = |style: &Style| {
        style.source.as_ref().map_or_else(
            || "the built-in default".to_string(),
            |p| p.display().to_string(),
        )
    };
    for (i, style) in styles.iter().enumerate() {
        if let Some(other) = styles[..i].iter().find(|s| s.name() == style.name()) {
            return Err(Error::Usage(format!(
                "two styles are named {}: {} and {}; a hint's image is named after its style, so \
                 rename one",
                style.name(),
                shown(other),
                shown(style)
            )));
        }
    }
    Ok(())
}

/// Two styles named `comet`, from `styles/` and `mine/`: what [`check_distinct_names`] refuses.
#[cfg(all(test, feature = "cli"))]
pub(crate) fn two_comets() -> Vec<std::sync::Arc<Style>> {
    ["styles", "mine"]
        .map(|dir| {
            std::sync::Arc::new(Style {
                source: Some(std::path::Path::new(dir).join("comet.toml")),
                ..Style::default()
            })
        })
        .into()
}

/// A number in [lo, hi], or an error naming `field`.
fn within(field: &str, v: f64, lo: f64, hi: f64) -> Result<f64> {
    if (lo..=hi).contains(&finite(field, v)?) {
        Ok(v)
    } else {
        Err(Error::invalid(
            field,
            format!("{}: must be between {lo} and {hi}", shown(v)),
        ))
    }
}

/// A share in (0, 1], or an error naming `field`.
fn share(field: &str, v: f64) -> Result<f64> {
    if finite(field, v)? > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err(Error::invalid(
            field,
            format!("{}: must be greater than 0 and at most 1", shown(v)),
        ))
    }
}

/// A count from 1 to `max`, or an error naming `field`.
fn count(field: &str, v: u32, max: u32) -> Result<u32> {
    if (1..=max).contains(&v) {
        Ok(v)
    } else {
        Err(Error::invalid(
            field,
            format!("{v}: use between 1 and {max}"),
        ))
    }
}

/// The colour at `u` in [0, 1] along a ramp of evenly spaced `stops` (linear interpolation; `u`
/// outside [0, 1] or NaN takes the nearer end, NaN the first stop).
#[must_use]
pub fn ramp_colour(stops: &[[f32; 3]], u: f64) -> [f32; 3] {
    let Some(last) = stops.len().checked_sub(1) else {
        return [0.0; 3];
    };
    let x = if u > 0.0 { u.min(1.0) } else { 0.0 } * last as f64;
    let i = (x.floor() as usize).min(last.saturating_sub(1));
    let f = (x - i as f64) as f32;
    let (a, b) = (stops[i], stops[(i + 1).min(last)]);
    [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramps_interpolate_between_evenly_spaced_stops() {
        let stops = [[1.0, 1.0, 1.0], [1.0, 0.5, 0.0], [1.0, 0.0, 0.0]];
        assert_eq!(ramp_colour(&stops, 0.0), stops[0]);
        assert_eq!(ramp_colour(&stops, 0.5), stops[1]);
        assert_eq!(ramp_colour(&stops, 1.0), stops[2]);
        assert_eq!(ramp_colour(&stops, 0.75), [1.0, 0.25, 0.0]);
        assert_eq!(ramp_colour(&stops, 7.0), stops[2]);
        assert_eq!(ramp_colour(&stops, f64::NAN), stops[0]);
        // Monotone stops give a monotone ramp: green and blue never rise with u.
        let mut previous = ramp_colour(&stops, 0.0);
        for i in 1..=100 {
            let c = ramp_colour(&stops, f64::from(i) / 100.0);
            assert!(c[1] <= previous[1] && c[2] <= previous[2]);
            previous = c;
        }
    }

    #[test]
    fn styles_built_in_code_are_checked() {
        let default = Style::default();
        let built = Style::new(
            default.object.clone(),
            default.trail.clone(),
            default.speed_lines.clone(),
        )
        .unwrap();
        assert_eq!(built, default);
        let mut trail = default.trail.clone();
        trail.duty = 0.0;
        let message = Style::new(default.object.clone(), trail, default.speed_lines.clone())
            .unwrap_err()
            .to_string();
        assert!(message.starts_with("trail.duty: 0: "), "{message}");
        let mut trail = default.trail.clone();
        trail.profile = Profile::Texture;
        let message = Style::new(default.object, trail, default.speed_lines)
            .unwrap_err()
            .to_string();
        assert!(message.starts_with("trail.texture: "), "{message}");
    }
}
