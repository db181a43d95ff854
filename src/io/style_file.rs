//! Style files (TOML): serde reads a `*Spec` that mirrors the format and rejects unknown keys,
//! then [`Style::check`] checks every value and the error is placed in the file.

use serde::Deserialize;
use std::path::{Path, PathBuf};

use super::scene_file::parse_toml;
use crate::error::{Error, Result};
use crate::raster::{Profile, Texture};
use crate::scene::rgb;
use crate::style::{
    Blend, Composite, Emitters, ObjectLook, RampBy, Select, SpeedLines, Style, Trail, TrailColour,
    MAX_TEXTURE_SIDE,
};

/// Largest style file read, bytes: a style is a page of settings (the presets are under 2 KB),
/// and a file of megabytes of ramp stops parsed into a gigabyte of TOML values.
pub const MAX_STYLE_BYTES: u64 = 1 << 20;

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct StyleSpec {
    description: Option<String>,
    #[serde(default, deserialize_with = "super::exact::exact_option")]
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
    #[serde(default, deserialize_with = "super::exact::exact_option")]
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
    #[serde(default, deserialize_with = "super::exact::exact_list")]
    ramp: Option<Vec<[f64; 3]>>,
    ramp_by: Option<RampBy>,
    #[serde(default, deserialize_with = "super::exact::exact_option")]
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
            ramp_by: None,
            speed_range: None,
            fade: 1.0,
            texture: TextureSpec::Builtin(Profile::Gaussian),
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

/// `trail.texture`: a built-in profile by name, or `{ image = "file.png" }`.
#[derive(Deserialize)]
#[serde(try_from = "toml::Value")]
enum TextureSpec {
    Builtin(Profile),
    Image(PathBuf),
}

/// The built-in trail profiles by name.
const PROFILES: [(&str, Profile); 3] = [
    ("gaussian", Profile::Gaussian),
    ("disc", Profile::Disc),
    ("ring", Profile::Ring),
];

impl TryFrom<toml::Value> for TextureSpec {
    type Error = String;
    fn try_from(value: toml::Value) -> std::result::Result<Self, String> {
        let choices = "\"gaussian\", \"disc\", \"ring\" or { image = \"file.png\" }";
        match &value {
            toml::Value::String(name) => PROFILES
                .iter()
                .find(|(n, _)| n == name)
                .map(|&(_, profile)| TextureSpec::Builtin(profile))
                .ok_or_else(|| format!("trail.texture = \"{name}\": use {choices}")),
            toml::Value::Table(table) => {
                if let Some(key) = table.keys().find(|k| *k != "image") {
                    return Err(format!(
                        "trail.texture: unknown key `{key}`: a texture image is written {{ image = \"file.png\" }}"
                    ));
                }
                match table.get("image") {
                    Some(toml::Value::String(file)) => Ok(TextureSpec::Image(file.into())),
                    _ => Err(
                        "trail.texture: an image texture needs `image`, the image file's path, \
                              as text: { image = \"file.png\" }"
                            .to_string(),
                    ),
                }
            }
            _ => Err(format!("trail.texture = {value}: use {choices}")),
        }
    }
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
    #[serde(deserialize_with = "super::exact::exact")]
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

impl Style {
    /// Read and validate a style file; a texture image is found relative to it.
    pub fn load(path: &Path) -> Result<Style> {
        let text = super::read::read_text(path, MAX_STYLE_BYTES)?;
        Style::parse(&text, path)
    }

    /// Validate style text; `path` names the file in messages and anchors a texture's path.
    pub fn parse(text: &str, path: &Path) -> Result<Style> {
        let mut style = build(parse_toml(text, path)?, path)?;
        style.source = Some(path.to_path_buf());
        Ok(style)
    }
}

/// The style an empty file gives.
pub(crate) fn default_style() -> Style {
    build(StyleSpec::default(), Path::new("(default style)")).expect("the default style is valid")
}

/// A colour as the renderers store it, checked as written (converted to `f32` first, a value
/// beyond its range became infinite and was called not finite).
fn linear(field: &str, c: [f64; 3], path: &Path) -> Result<[f32; 3]> {
    rgb(field, c).map_err(|e| e.in_file(path, ""))
}

fn build(spec: StyleSpec, path: &Path) -> Result<Style> {
    let o = &spec.object;
    let object = ObjectLook {
        draw: o.draw,
        flash: o.flash,
        opacity: o.opacity,
        colour: o
            .colour
            .map(|c| linear("object.colour", c, path))
            .transpose()?,
    };
    let t = &spec.trail;
    // A key the colour rule does not read is a mistake to point out, not to ignore.
    let unused = match (t.colour, t.ramp_by) {
        (TrailColourSpec::Object, _) => [
            ("trail.ramp", t.ramp.is_some()),
            ("trail.ramp_by", t.ramp_by.is_some()),
            ("trail.speed_range", t.speed_range.is_some()),
        ]
        .into_iter()
        .find(|&(_, given)| given)
        .map(|(key, _)| (key, "colour = \"object\" does not use it: set colour = \"ramp\", or remove it")),
        (TrailColourSpec::Ramp, Some(RampBy::Time)) => t.speed_range.is_some().then_some((
            "trail.speed_range",
            "ramp_by = \"time\" does not use it (it maps speeds to the ramp): remove it, or ramp by speed",
        )),
        (TrailColourSpec::Ramp, _) => None,
    };
    if let Some((key, why)) = unused {
        return Err(Error::input(path, key, why));
    }
    let trail_colour = match (t.colour, &t.ramp) {
        (TrailColourSpec::Object, _) => TrailColour::Object,
        (TrailColourSpec::Ramp, None) => {
            return Err(Error::input(
                path,
                "trail.ramp",
                "colour = \"ramp\" needs `ramp`, a list of at least two [r, g, b] stops",
            ))
        }
        (TrailColourSpec::Ramp, Some(stops)) => TrailColour::Ramp {
            stops: stops
                .iter()
                .enumerate()
                .map(|(i, &c)| linear(&format!("trail.ramp[{i}]"), c, path))
                .collect::<Result<_>>()?,
            by: t.ramp_by.unwrap_or(RampBy::Speed),
            speed_range: t.speed_range,
        },
    };
    let (profile, texture) = match &t.texture {
        TextureSpec::Builtin(profile) => (*profile, None),
        TextureSpec::Image(image) => {
            let base = path.parent().unwrap_or(Path::new("."));
            (
                Profile::Texture,
                Some(load_texture(&base.join(image), path)?),
            )
        }
    };
    let trail = Trail {
        draw: t.draw,
        length: t.length,
        offset: t.offset,
        copies: t.copies,
        duty: t.duty,
        blend: t.blend,
        composite: t.composite,
        intensity: t.intensity,
        width: t.width,
        density: t.density,
        colour: trail_colour,
        fade: t.fade,
        profile,
        texture,
        modulate_light: t.modulate_light,
        modulate_view: t.modulate_view,
        emitters: t.emitters,
    };
    let s = &spec.speed_lines;
    let speed_lines = SpeedLines {
        draw: s.draw,
        count: s.count,
        select: s.select,
        spacing: s.spacing,
        length: s.length,
        offset: s.offset,
        width: s.width,
        taper: s.taper,
        fade: s.fade,
        opacity: s.opacity,
        colour: linear("speed_lines.colour", s.colour, path)?,
    };
    let style = Style {
        source: None,
        description: spec.description.unwrap_or_default(),
        background: spec
            .background
            .map(|c| linear("background", c, path))
            .transpose()?,
        object,
        trail,
        speed_lines,
    };
    style.check().map_err(|e| e.in_file(path, ""))?;
    Ok(style)
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
    use crate::style::MAX_RAMP_STOPS;

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

    /// A colour too large for the renderers' `f32` is out of range as written: converted first,
    /// it was called "inf is not a finite number".
    #[test]
    fn a_colour_beyond_f32_is_out_of_range_as_written() {
        for (text, field) in [
            (
                "[speed_lines]\ncolour = [1e39, 0, 0]",
                "speed_lines.colour[0]",
            ),
            ("background = [0, 1e39, 0]", "background[1]"),
            ("[object]\ncolour = [0, 0, 1e39]", "object.colour[2]"),
            (
                "[trail]\ncolour = \"ramp\"\nramp = [[0, 0, 0], [1e39, 0, 0]]",
                "trail.ramp[1][0]",
            ),
        ] {
            let message = error_of(text);
            let expected = format!("{field}: {}: must be between 0 and 10000", 1e39);
            assert!(message.contains(&expected), "{message}");
        }
    }

    /// A value of the wrong type is refused with its field's path beside its line: the reader's
    /// message names the value and the type only.
    #[test]
    fn a_value_of_the_wrong_type_names_its_field() {
        for (text, expected) in [
            (
                "[speed_lines]\ndraw = true\ncount = 2.5",
                "look.toml: line 3, speed_lines.count: invalid type: floating point `2.5`, expected u32",
            ),
            (
                "[trail]\ncopies = -3",
                "line 2, trail.copies: invalid value: integer `-3`, expected u32",
            ),
            (
                "[trail]\ncolour = \"ramp\"\nramp = [[0, 0, 0], [1, 1, 1, 1]]",
                "line 3, trail.ramp[1]: invalid length 4",
            ),
            ("[trail\nwidth = 2", "look.toml: line 1: unclosed table"),
        ] {
            let message = error_of(text);
            assert!(message.contains(expected), "{text}: {message}");
        }
    }

    #[test]
    fn ramps_past_their_stops_arrays_past_their_length_and_files_past_their_size_are_refused() {
        let ramp = |stops: usize| {
            format!(
                "[trail]\ncolour = \"ramp\"\nramp = [{}]",
                vec!["[0.5, 0.5, 0.5]"; stops].join(", ")
            )
        };
        assert!(Style::parse(&ramp(MAX_RAMP_STOPS), Path::new("look.toml")).is_ok());
        let message = error_of(&ramp(MAX_RAMP_STOPS + 1));
        assert!(
            message.contains("trail.ramp: has 1025 stop(s): a ramp has from 2 to 1024"),
            "{message}"
        );
        // A fourth entry was dropped without a word.
        for text in [
            "background = [0, 0, 0, 5]",
            "[trail]\ncolour = \"ramp\"\nramp = [[1, 0, 0, 9], [0, 0, 1]]",
            "[trail]\nspeed_range = [0, 1, 2]",
        ] {
            let message = error_of(text);
            assert!(message.contains("invalid length"), "{text}: {message}");
        }
        let message = crate::io::read::tests::refusal_past_size("", MAX_STYLE_BYTES, |path| {
            Style::load(path).map(|_| ())
        });
        assert!(
            message.contains("large.toml: file: larger than 1048576 bytes"),
            "{message}"
        );
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
        let misspelt = error_of("[trail]\ntexture = \"gausian\"");
        assert!(
            misspelt.contains("trail.texture = \"gausian\": use \"gaussian\", \"disc\"")
                && misspelt.contains("line 2"),
            "{misspelt}"
        );
        let extra = error_of("[trail]\ntexture = { image = \"brush.png\", scale = 2 }");
        assert!(extra.contains("unknown key `scale`"), "{extra}");
        let texture = error_of("[trail]\ntexture = { image = \"no-such.png\" }");
        assert!(
            texture.contains("trail.texture.image") && texture.contains("no-such.png"),
            "{texture}"
        );
    }
}
