//! Style presets for motion hints: everything that makes a hint look the way it does.
//!
//! A style is a TOML file (the presets live in `styles/`; every field is documented in the
//! README). Parsing mirrors scene files: serde reads a `*Spec` that rejects unknown keys, then
//! validation checks each value and names the field of any mistake. Every field has a default,
//! so an empty file is the default style: the object sharp at shutter close over an
//! alpha-blended trail of its own colours (Guan & Mueller §3.1, the flash-and-trail photograph).

use crate::error::{Error, Result};
use crate::raster::{Profile, Texture};
use crate::scene::{colour, finite, parse_toml};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Most stroboscopic copies a trail may be cut into.
pub const MAX_COPIES: u32 = 64;

/// Most speed lines drawn.
pub const MAX_SPEED_LINES: u32 = 10_000;

/// Largest side of a trail texture image, px.
pub const MAX_TEXTURE_SIDE: u32 = 2048;

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct StyleSpec {
    description: Option<String>,
    background: Option<[f64; 3]>,
    #[serde(default)]
    object: ObjectLookSpec,
    #[serde(default)]
    trail: TrailSpec,
    #[serde(default)]
    speed_lines: SpeedLinesSpec,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct ObjectLookSpec {
    draw: bool,
    flash: f64,
    opacity: f64,
    colour: Option<[f64; 3]>,
}

impl Default for ObjectLookSpec {
    fn default() -> Self {
        ObjectLookSpec {
            draw: true,
            flash: 1.0,
            opacity: 1.0,
            colour: None,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct TrailSpec {
    draw: bool,
    length: f64,
    offset: f64,
    copies: u32,
    duty: f64,
    blend: Blend,
    composite: Composite,
    intensity: f64,
    density: f64,
    width: f64,
    colour: TrailColourSpec,
    ramp: Option<Vec<[f64; 3]>>,
    ramp_by: RampBy,
    speed_range: Option<[f64; 2]>,
    fade: f64,
    texture: TextureSpec,
    modulate_light: bool,
    modulate_view: bool,
    emitters: Emitters,
}

impl Default for TrailSpec {
    fn default() -> Self {
        TrailSpec {
            draw: true,
            length: 1.0,
            offset: 0.0,
            copies: 1,
            duty: 1.0,
            blend: Blend::Alpha,
            composite: Composite::Under,
            intensity: 1.0,
            density: 1.0,
            width: 1.0,
            colour: TrailColourSpec::Object,
            ramp: None,
            ramp_by: RampBy::Speed,
            speed_range: None,
            fade: 1.0,
            texture: TextureSpec::Name(TextureName::Gaussian),
            modulate_light: false,
            modulate_view: false,
            emitters: Emitters::Visible,
        }
    }
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "kebab-case")]
enum TrailColourSpec {
    Object,
    Ramp,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum TextureSpec {
    Name(TextureName),
    Image { image: PathBuf },
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "kebab-case")]
enum TextureName {
    Gaussian,
    Disc,
    Ring,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct SpeedLinesSpec {
    draw: bool,
    count: u32,
    select: Select,
    spacing: f64,
    length: f64,
    offset: f64,
    width: f64,
    taper: f64,
    fade: f64,
    opacity: f64,
    colour: [f64; 3],
}

impl Default for SpeedLinesSpec {
    fn default() -> Self {
        SpeedLinesSpec {
            draw: false,
            count: 40,
            select: Select::Silhouette,
            spacing: 12.0,
            length: 1.0,
            offset: 0.0,
            width: 2.0,
            taper: 0.2,
            fade: 0.0,
            opacity: 0.9,
            colour: [0.0; 3],
        }
    }
}

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
    /// Share of the emitting points that do emit, in (0, 1], their splats made heavier in
    /// proportion: sparse, separate strokes for textured looks.
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
    fn default() -> Self {
        validate(StyleSpec::default(), Path::new("(default style)"))
            .expect("the default style is valid")
    }
}

impl Style {
    /// Read and validate a style file; a texture image is found relative to it.
    pub fn load(path: &Path) -> Result<Style> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Style::parse(&text, path)
    }

    /// Validate style text; `path` names the file in messages and anchors a texture's path.
    pub fn parse(text: &str, path: &Path) -> Result<Style> {
        let mut style = validate(parse_toml(text, path)?, path)?;
        style.source = Some(path.to_path_buf());
        Ok(style)
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

/// A number in [lo, hi].
fn within(path: &Path, field: &str, v: f64, lo: f64, hi: f64) -> Result<f64> {
    if (lo..=hi).contains(&finite(path, field, v)?) {
        Ok(v)
    } else {
        Err(Error::input(
            path,
            field,
            format!("{v}: must be between {lo} and {hi}"),
        ))
    }
}

/// A share in (0, 1].
fn share(path: &Path, field: &str, v: f64) -> Result<f64> {
    if finite(path, field, v)? > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err(Error::input(
            path,
            field,
            format!("{v}: must be greater than 0 and at most 1"),
        ))
    }
}

/// A count from 1 to `max`.
fn count(path: &Path, field: &str, v: u32, max: u32) -> Result<u32> {
    if (1..=max).contains(&v) {
        Ok(v)
    } else {
        Err(Error::input(
            path,
            field,
            format!("{v}: use between 1 and {max}"),
        ))
    }
}

fn validate(spec: StyleSpec, path: &Path) -> Result<Style> {
    let o = &spec.object;
    let object = ObjectLook {
        draw: o.draw,
        flash: within(path, "object.flash", o.flash, 0.0, 1.0)?,
        opacity: within(path, "object.opacity", o.opacity, 0.0, 1.0)?,
        colour: o
            .colour
            .map(|c| colour(path, "object.colour", c))
            .transpose()?,
    };
    let t = &spec.trail;
    let trail_colour = match (t.colour, &t.ramp) {
        (TrailColourSpec::Object, _) => TrailColour::Object,
        (TrailColourSpec::Ramp, None) => {
            return Err(Error::input(
                path,
                "trail.ramp",
                "colour = \"ramp\" needs `ramp`, a list of at least two [r, g, b] stops",
            ))
        }
        (TrailColourSpec::Ramp, Some(stops)) => {
            if stops.len() < 2 {
                return Err(Error::input(
                    path,
                    "trail.ramp",
                    format!("has {} stop(s): a ramp needs at least two", stops.len()),
                ));
            }
            let stops = stops
                .iter()
                .enumerate()
                .map(|(i, c)| colour(path, &format!("trail.ramp[{i}]"), *c))
                .collect::<Result<_>>()?;
            let speed_range = match t.speed_range {
                None => None,
                Some([lo, hi]) => {
                    let lo = finite(path, "trail.speed_range[0]", lo)?;
                    let hi = finite(path, "trail.speed_range[1]", hi)?;
                    if !(0.0 <= lo && lo < hi) {
                        return Err(Error::input(
                            path,
                            "trail.speed_range",
                            format!("[{lo}, {hi}]: need 0 ≤ slowest < fastest (px per exposure)"),
                        ));
                    }
                    Some([lo, hi])
                }
            };
            TrailColour::Ramp {
                stops,
                by: t.ramp_by,
                speed_range,
            }
        }
    };
    let (profile, texture) = match &t.texture {
        TextureSpec::Name(TextureName::Gaussian) => (Profile::Gaussian, None),
        TextureSpec::Name(TextureName::Disc) => (Profile::Disc, None),
        TextureSpec::Name(TextureName::Ring) => (Profile::Ring, None),
        TextureSpec::Image { image } => {
            let base = path.parent().unwrap_or(Path::new("."));
            (
                Profile::Texture,
                Some(load_texture(&base.join(image), path)?),
            )
        }
    };
    let trail = Trail {
        draw: t.draw,
        length: within(path, "trail.length", t.length, 0.0, 1.0)?,
        offset: within(path, "trail.offset", t.offset, 0.0, 1.0)?,
        copies: count(path, "trail.copies", t.copies, MAX_COPIES)?,
        duty: share(path, "trail.duty", t.duty)?,
        blend: t.blend,
        composite: t.composite,
        intensity: within(path, "trail.intensity", t.intensity, 0.0, 100.0)?,
        width: within(path, "trail.width", t.width, 0.1, 20.0)?,
        density: share(path, "trail.density", t.density)?,
        colour: trail_colour,
        fade: within(path, "trail.fade", t.fade, 0.0, 1.0)?,
        profile,
        texture,
        modulate_light: t.modulate_light,
        modulate_view: t.modulate_view,
        emitters: t.emitters,
    };
    let s = &spec.speed_lines;
    let speed_lines = SpeedLines {
        draw: s.draw,
        count: count(path, "speed_lines.count", s.count, MAX_SPEED_LINES)?,
        select: s.select,
        spacing: within(path, "speed_lines.spacing", s.spacing, 0.0, 1e4)?,
        length: within(path, "speed_lines.length", s.length, 0.0, 1.0)?,
        offset: within(path, "speed_lines.offset", s.offset, 0.0, 1.0)?,
        width: within(path, "speed_lines.width", s.width, 0.01, 100.0)?,
        taper: within(path, "speed_lines.taper", s.taper, 0.0, 1.0)?,
        fade: within(path, "speed_lines.fade", s.fade, 0.0, 1.0)?,
        opacity: within(path, "speed_lines.opacity", s.opacity, 0.0, 1.0)?,
        colour: colour(path, "speed_lines.colour", s.colour)?,
    };
    Ok(Style {
        source: None,
        description: spec.description.unwrap_or_default(),
        background: spec
            .background
            .map(|c| colour(path, "background", c))
            .transpose()?,
        object,
        trail,
        speed_lines,
    })
}

/// A trail texture from an image file: its luminance times its alpha, in [0, 1].
fn load_texture(image_path: &Path, style_path: &Path) -> Result<Texture> {
    let field = "trail.texture.image";
    let image = image::open(image_path).map_err(|e| {
        Error::input(
            style_path,
            field,
            format!("cannot read {}: {e}", image_path.display()),
        )
    })?;
    let (width, height) = (image.width(), image.height());
    if width > MAX_TEXTURE_SIDE || height > MAX_TEXTURE_SIDE {
        return Err(Error::input(
            style_path,
            field,
            format!(
                "{} is {width}×{height}: textures may be at most {MAX_TEXTURE_SIDE} px a side",
                image_path.display()
            ),
        ));
    }
    let rgba = image.to_rgba32f();
    let values = rgba
        .pixels()
        .map(|p| {
            let [r, g, b, a] = p.0;
            ((0.2126 * r + 0.7152 * g + 0.0722 * b) * a).clamp(0.0, 1.0)
        })
        .collect();
    Texture::new(width, height, values).ok_or_else(|| {
        Error::input(
            style_path,
            field,
            format!(
                "{} is blank: a texture needs some light inside its inscribed circle",
                image_path.display()
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error_of(text: &str) -> String {
        Style::parse(text, Path::new("look.toml"))
            .expect_err("should be rejected")
            .to_string()
    }

    #[test]
    fn an_empty_style_is_the_flash_and_trail_default() {
        let style = Style::parse("", Path::new("plain.toml")).unwrap();
        assert_eq!(style.name(), "plain");
        assert!(style.object.draw && style.object.flash == 1.0 && style.trail.draw);
        assert_eq!(style.trail.blend, Blend::Alpha);
        assert_eq!(style.trail.emitters, Emitters::Visible);
        assert!(!style.speed_lines.draw);
        assert_eq!(
            Style {
                source: None,
                ..style
            },
            Style::default()
        );
    }

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
    fn mistakes_name_their_field() {
        assert!(error_of("[trail]\nlength = 1.5").contains("trail.length"));
        assert!(error_of("[trail]\nfade = nan").contains("trail.fade"));
        assert!(error_of("[trail]\ncopies = 0").contains("trail.copies"));
        assert!(error_of("[trail]\ncolour = \"ramp\"").contains("trail.ramp"));
        assert!(
            error_of("[trail]\ncolour = \"ramp\"\nramp = [[1, 0, 0], [2e5, 0, 0]]")
                .contains("trail.ramp[1][0]")
        );
        assert!(error_of("[object]\nflash = -0.1").contains("object.flash"));
        assert!(error_of("[speed_lines]\nwidth = 0").contains("speed_lines.width"));
        let unknown = error_of("[trail]\nlenght = 0.5");
        assert!(
            unknown.contains("lenght") && unknown.contains("line 2"),
            "{unknown}"
        );
        let texture = error_of("[trail]\ntexture = { image = \"no-such.png\" }");
        assert!(
            texture.contains("trail.texture.image") && texture.contains("no-such.png"),
            "{texture}"
        );
    }
}
