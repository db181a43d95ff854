//! The gallery: every scene of a folder rendered with `blur`, `reference`, `static` and `hint` in
//! a set of styles (and `analytic` where it has triangle meshes), and a page (`index.html`) that
//! shows hint and blur side by side with each render's time and its error against the
//! reference. Where the level of detail simplifies a moving mesh, `blur` and `analytic` are also
//! drawn at full detail (`--lod off`), so the page shows what the simplification costs and saves.
//!
//! Times are plan + render of one run on this machine, also given as ratios to `static` of the
//! same scene; errors are measured against the gallery's own reference (the accumulation buffer
//! at `samples` frames, drawn at full detail; on the torus knot the study measures 256 frames
//! within 2·10⁻⁵ RMSE of 1024). A hint is not meant to match the reference: its error says how
//! far the illustration departs from the photograph.

use crate::error::{Error, Result};
use crate::framebuffer::Framebuffer;
use crate::io::image::write_png;
use crate::io::write::write_whole;
use crate::lod::Lod;
use crate::metrics::{compare, ImageError};
use crate::plan::Plan;
use crate::render::{Method, ANALYTIC_TOLERANCE_PX, DEFAULT_TOLERANCE_PX};
use crate::scene::Scene;
use crate::style::Style;
use crate::surfels::Budget;
use indicatif::ProgressBar;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// What to render.
#[derive(Clone, Debug)]
pub struct GalleryOptions {
    /// Scene files, in the order shown.
    pub scenes: Vec<PathBuf>,
    /// Styles every scene is drawn with as a hint (besides the scene's own style).
    pub styles: Vec<Arc<Style>>,
    /// Frames of the reference.
    pub samples: usize,
    /// Where the images and the page go.
    pub out_dir: PathBuf,
    /// Image size overriding the scenes' own.
    pub size: Option<(u32, u32)>,
    /// Spatial samples per pixel overriding the scenes' own.
    pub spatial_samples: Option<u32>,
    /// Surfels each scene may have.
    pub budget: Budget,
}

/// One rendered image.
#[derive(Clone, Debug)]
pub struct Shot {
    /// `static`, `blur`, `reference`, `analytic` or `hint`.
    pub method: String,
    /// The setting: the style's name for hints, τ or N otherwise.
    pub knob: String,
    /// Drawn with the level of detail off (`--lod off`), beside the default render of a scene
    /// whose moving meshes the level of detail simplifies.
    pub full_detail: bool,
    /// The PNG's file name, in the output folder.
    pub file: String,
    /// Plan + render, seconds.
    pub seconds: f64,
    /// Error against the reference (none for the reference itself).
    pub error: Option<ImageError>,
    /// Where the render departed from what the scene asked ([`Plan::departures_of`]).
    pub notes: Vec<String>,
}

/// One scene's row of the gallery.
#[derive(Clone, Debug)]
pub struct SceneShots {
    /// The scene file's stem.
    pub name: String,
    /// The leading comment of the scene file.
    pub description: String,
    /// Surfels in the scene.
    pub surfels: usize,
    /// Image size.
    pub size: (u32, u32),
    /// Longest screen path of a moving object, px.
    pub path_px: f64,
    /// The name of the scene's own style, if it names one.
    pub own_style: Option<String>,
    /// Every render, static first.
    pub shots: Vec<Shot>,
}

/// Every `.toml` file in `dir`, sorted.
pub fn toml_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    Ok(files)
}

/// The `#` comment lines at the top of a scene file, joined.
fn leading_comment(path: &Path) -> String {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .map_while(|l| l.strip_prefix('#'))
        .map(str::trim)
        .collect::<Vec<_>>()
        .join(" ")
}

/// What a render's label ends in when it was drawn at full detail ([`Shot::full_detail`]).
#[must_use]
pub fn full_detail_mark(full_detail: bool) -> &'static str {
    if full_detail {
        crate::lod::FULL_DETAIL_LABEL
    } else {
        ""
    }
}

/// The images every scene gets: reference, static, blur and a hint per style in
/// `options.styles`. A scene may need more (its own style, `analytic`, full detail): `run` adds
/// them to the progress bar's length as it finds them.
#[must_use]
pub fn images_per_scene(options: &GalleryOptions) -> usize {
    3 + options.styles.len()
}

/// Render the gallery into `options.out_dir` and write its page; `progress` advances once per
/// image.
pub fn run(options: &GalleryOptions, progress: Option<&ProgressBar>) -> Result<Vec<SceneShots>> {
    crate::style::check_distinct_names(&options.styles)?;
    crate::io::write::output_folder(&options.out_dir)?;
    let mut rows = Vec::new();
    for path in &options.scenes {
        let mut scene = Scene::load_within(path, options.budget)?;
        scene.camera = (scene.camera).overridden(options.size, options.spatial_samples)?;
        let name = path
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let own = scene.own_style()?.map(Arc::new);
        let mut styles: Vec<Arc<Style>> = own.iter().cloned().collect();
        styles.extend(
            options
                .styles
                .iter()
                .filter(|s| own.as_ref().is_none_or(|o| o.name() != s.name()))
                .cloned(),
        );
        let blur_knob = format!("τ={DEFAULT_TOLERANCE_PX}px");
        let analytic_knob = format!("τ={ANALYTIC_TOLERANCE_PX}px");
        let mut jobs = vec![
            (
                Method::Reference {
                    samples: options.samples,
                },
                format!("N={}", options.samples),
                Lod::GROUND_TRUTH,
            ),
            (Method::STATIC, "t=mid".to_string(), Lod::Auto),
            (Method::BLUR, blur_knob.clone(), Lod::Auto),
        ];
        if scene.objects.iter().any(|o| o.mesh().is_some()) {
            jobs.push((Method::ANALYTIC, analytic_knob.clone(), Lod::Auto));
        }
        let plan = Plan::new(&scene, &Method::BLUR).map_err(|e| e.in_file(path, ""))?;
        // What the mesh level of detail leaves out is shown by drawing it too.
        let simplified = plan.simplifies_a_mesh();
        if simplified {
            jobs.push((Method::BLUR, blur_knob, Lod::Off));
            jobs.push((Method::ANALYTIC, analytic_knob, Lod::Off));
        }
        jobs.extend(styles.iter().map(|style| {
            (
                Method::Hint {
                    style: Arc::clone(style),
                    tolerance_px: DEFAULT_TOLERANCE_PX,
                },
                style.name(),
                Lod::Auto,
            )
        }));
        if let Some(bar) = progress {
            bar.inc_length(jobs.len().saturating_sub(images_per_scene(options)) as u64);
        }
        let mut reference: Option<Framebuffer> = None;
        let mut shots = Vec::new();
        for (method, knob, lod) in jobs {
            let full_detail = lod == Lod::Off && !matches!(method, Method::Reference { .. });
            if let Some(bar) = progress {
                let detail = full_detail_mark(full_detail);
                bar.set_message(format!("{name} {} {knob}{detail}", method.name()));
            }
            let start = Instant::now();
            let plan = Plan::with_lod(&scene, &method, lod).map_err(|e| e.in_file(path, ""))?;
            let out = plan.render(None);
            let seconds = start.elapsed().as_secs_f64();
            let notes = plan.departures_of(&out);
            let image = out.image;
            let file = match method {
                Method::Hint { .. } => format!("{name}-hint-{knob}.png"),
                _ if full_detail => format!("{name}-{}-full-detail.png", method.name()),
                _ => format!("{name}-{}.png", method.name()),
            };
            write_png(&image, &options.out_dir.join(&file))?;
            let error = match &reference {
                Some(r) => Some(compare(&image, r)?),
                None => {
                    reference = Some(image);
                    None
                }
            };
            shots.push(Shot {
                method: method.name().to_string(),
                knob,
                full_detail,
                file,
                seconds,
                error,
                notes,
            });
            if let Some(bar) = progress {
                bar.inc(1);
            }
        }
        // Static first, then blur, the hints and the reference last, as the page shows them.
        shots.rotate_left(1);
        rows.push(SceneShots {
            name,
            description: leading_comment(path),
            surfels: scene.surfel_count(),
            size: (scene.camera.width, scene.camera.height),
            path_px: plan.longest_path_px(),
            own_style: own.map(|s| s.name()),
            shots,
        });
    }
    let page = options.out_dir.join("index.html");
    let html = index_html(&rows, &options.styles, options.samples);
    write_whole(&page, |out| out.write_all(html.as_bytes())).map_err(|e| Error::io(&page, e))?;
    Ok(rows)
}

/// A file name as a relative URL: every byte but unreserved ones percent-encoded, so that `#`,
/// `?`, `%` or a space in a scene's name do not break the image's address.
fn url_path(file: &str) -> String {
    file.bytes()
        .map(|b| {
            if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
                char::from(b).to_string()
            } else {
                format!("%{b:02X}")
            }
        })
        .collect()
}

/// Text made safe for HTML.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A figure with its caption: what it is, its time and its error.
fn figure(shot: &Shot, static_seconds: f64, class: &str) -> String {
    let title = if shot.method == "hint" {
        format!("hint · {}", shot.knob)
    } else if shot.full_detail {
        format!("{} {} · full detail", shot.method, shot.knob)
    } else {
        format!("{} {}", shot.method, shot.knob)
    };
    let error = match &shot.error {
        Some(e) => format!("RMSE {:.4} · ꟻLIP {:.3} vs reference", e.rmse, e.flip),
        None => "the reference".to_string(),
    };
    let notes: String = (shot.notes.iter())
        .map(|note| format!("<br>note: {}", escape(note)))
        .collect();
    format!(
        "<figure class=\"{class}\"><img src=\"{file}\" alt=\"{alt}\" loading=\"lazy\">\
         <figcaption><b>{title}</b><br>{seconds:.3} s · {ratio:.1}× static<br>{error}{notes}</figcaption></figure>\n",
        file = url_path(&shot.file),
        alt = escape(&title),
        title = escape(&title),
        seconds = shot.seconds,
        ratio = shot.seconds / static_seconds.max(1e-9),
    )
}

/// The gallery page.
fn index_html(rows: &[SceneShots], styles: &[Arc<Style>], samples: usize) -> String {
    let mut html = String::from(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n\
         <title>streak gallery: motion hints and motion blur</title>\n<style>\n\
         body{font:14px/1.4 system-ui,sans-serif;margin:24px;background:#f4f3f0;color:#222}\n\
         h1{margin:0 0 4px}h2{margin:32px 0 4px}p.meta{color:#555;margin:0 0 12px}\n\
         .pair,.styles{display:flex;flex-wrap:wrap;gap:12px;align-items:flex-start}\n\
         figure{margin:0;background:#fff;padding:6px;border-radius:6px;box-shadow:0 1px 3px #0002}\n\
         figure.big img{width:360px}figure.small img{width:200px}figcaption{font-size:12px;color:#444;margin-top:4px;max-width:360px}\n\
         figure.small figcaption{max-width:200px}h3{margin:14px 0 6px;font-size:14px;color:#444}\n\
         table{border-collapse:collapse;margin-top:8px}td,th{padding:3px 8px;border-bottom:1px solid #ddd;text-align:left;vertical-align:top}\n\
         </style></head><body>\n<h1>streak gallery</h1>\n",
    );
    let _ = writeln!(
        html,
        "<p class=\"meta\">Each scene drawn as a motion hint (the object sharp at the flash, a styled trail) beside the \
         physically based blur (exact streaks, τ = {DEFAULT_TOLERANCE_PX} px) and the reference (the shutter-weighted \
         average of {samples} frames, at full detail). Times are plan + render on this machine, and as ratios to a sharp \
         <code>static</code> render of the same scene. Errors are RMSE of linear colour and mean ꟻLIP against the \
         reference; a hint is an illustration, so its error measures how far it departs from the photograph.</p>"
    );
    for row in rows {
        let static_seconds = row
            .shots
            .iter()
            .find(|s| s.method == "static")
            .map_or(1.0, |s| s.seconds);
        let _ = writeln!(
            html,
            "<section id=\"{id}\"><h2>{id}</h2>\n<p class=\"meta\">{desc}<br>{surfels} surfels · {w}×{h} px · \
             longest screen path {path:.0} px</p>",
            id = escape(&row.name),
            desc = escape(&row.description),
            surfels = row.surfels,
            w = row.size.0,
            h = row.size.1,
            path = row.path_px,
        );
        let first_hint = row
            .shots
            .iter()
            .find(|s| s.method == "hint" && Some(&s.knob) == row.own_style.as_ref())
            .or_else(|| row.shots.iter().find(|s| s.method == "hint"));
        html.push_str("<div class=\"pair\">\n");
        let physical = |s: &&Shot| matches!(s.method.as_str(), "blur" | "analytic" | "reference");
        for shot in first_hint
            .into_iter()
            .chain(row.shots.iter().filter(physical).filter(|s| !s.full_detail))
        {
            html.push_str(&figure(shot, static_seconds, "big"));
        }
        html.push_str("</div>\n");
        if row.shots.iter().any(|s| s.full_detail) {
            html.push_str(
                "<h3>The moving meshes simplified for their screen speed (the default), and at full detail</h3>\n\
                 <div class=\"pair\">\n",
            );
            for method in ["blur", "analytic"] {
                for shot in row.shots.iter().filter(|s| s.method == method) {
                    html.push_str(&figure(shot, static_seconds, "big"));
                }
            }
            html.push_str("</div>\n");
        }
        html.push_str("<h3>Every style, and the sharp instant</h3>\n<div class=\"styles\">\n");
        for shot in row
            .shots
            .iter()
            .filter(|s| s.method == "hint" || s.method == "static")
        {
            html.push_str(&figure(shot, static_seconds, "small"));
        }
        html.push_str("</div></section>\n");
    }
    html.push_str("<h2>Styles</h2>\n<table><tr><th>style</th><th>what it does</th></tr>\n");
    for style in styles {
        let _ = writeln!(
            html,
            "<tr><td><code>{}</code></td><td>{}</td></tr>",
            escape(&style.name()),
            escape(&style.description)
        );
    }
    html.push_str("</table>\n</body></html>\n");
    html
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn styles_of_one_name_are_refused_before_their_images_overwrite_each_other() {
        // `--styles styles mine`, where mine/comet.toml is the user's variant of the preset.
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let options = GalleryOptions {
            scenes: vec![root.join("tests/data/turning-square.toml")],
            styles: crate::style::two_comets(),
            samples: 2,
            out_dir: std::env::temp_dir().join("streak-gallery-never-written"),
            size: None,
            spatial_samples: None,
            budget: Budget::default(),
        };
        match run(&options, None) {
            Err(Error::Usage(message)) => assert!(message.contains("mine/comet.toml"), "{message}"),
            other => panic!(
                "two `comet` styles were not refused: {:?}",
                other.map(|_| ())
            ),
        }
        assert!(!options.out_dir.exists());
    }

    #[test]
    fn file_names_are_usable_as_image_addresses() {
        // A scene file `take #2.toml`: `#` starts a fragment in a URL, so the image is not found.
        let row = SceneShots {
            name: "take #2".into(),
            description: String::new(),
            surfels: 1,
            size: (8, 8),
            path_px: 1.0,
            own_style: None,
            shots: vec![Shot {
                method: "static".into(),
                knob: "t=mid".into(),
                full_detail: false,
                file: "take #2-static.png".into(),
                seconds: 0.1,
                error: None,
                notes: Vec::new(),
            }],
        };
        let html = index_html(&[row], &[], 4);
        assert!(html.contains("src=\"take%20%232-static.png\""), "{html}");
    }

    #[test]
    fn the_page_shows_hint_and_blur_side_by_side_with_time_and_error() {
        let error = ImageError {
            rmse: 0.0123,
            psnr_db: 38.0,
            ssim: 0.99,
            flip: 0.045,
        };
        let shot = |method: &str, knob: &str, seconds: f64, error: Option<ImageError>| Shot {
            method: method.into(),
            knob: knob.into(),
            full_detail: false,
            file: format!("s-{method}-{knob}.png"),
            seconds,
            error,
            notes: Vec::new(),
        };
        let row = SceneShots {
            name: "rod <spin>".into(),
            description: "A rod & a spin".into(),
            surfels: 1000,
            size: (64, 48),
            path_px: 80.0,
            own_style: Some("comet".into()),
            shots: vec![
                shot("static", "t=mid", 0.5, Some(error)),
                shot("blur", "τ=1px", 5.0, Some(error)),
                shot("hint", "heat", 1.0, Some(error)),
                Shot {
                    notes: vec!["3 of 10 speed lines drawn: <budget>".into()],
                    ..shot("hint", "comet", 1.5, Some(error))
                },
                shot("reference", "N=256", 50.0, None),
            ],
        };
        let html = index_html(&[row], &[], 256);
        // Names are escaped; the pair row holds the scene's own style first, then blur.
        assert!(html.contains("rod &lt;spin&gt;") && html.contains("A rod &amp; a spin"));
        let pair =
            &html[html.find("class=\"pair\"").unwrap()..html.find("class=\"styles\"").unwrap()];
        let (comet, blur) = (
            pair.find("hint · comet").unwrap(),
            pair.find("blur τ=1px").unwrap(),
        );
        assert!(comet < blur && !pair.contains("hint · heat"));
        // Times as seconds and ratios to static, errors to 4 digits.
        assert!(pair.contains("1.500 s · 3.0× static") && pair.contains("RMSE 0.0123"));
        assert!(pair.contains("50.000 s · 100.0× static<br>the reference"));
        // Where a render departed from its scene, its caption says so.
        assert!(pair.contains("RMSE 0.0123 · ꟻLIP 0.045 vs reference<br>note: 3 of 10 speed lines drawn: &lt;budget&gt;</figcaption>"));
        // A scene without full-detail shots has no level-of-detail row.
        assert!(!html.contains("simplified for their screen speed"));
    }

    #[test]
    fn full_detail_is_shown_beside_the_simplified_render_not_in_the_pair() {
        let error = ImageError {
            rmse: 0.01,
            psnr_db: 40.0,
            ssim: 0.99,
            flip: 0.03,
        };
        let shot = |method: &str, seconds: f64, full_detail: bool| Shot {
            method: method.into(),
            knob: "τ=1px".into(),
            full_detail,
            file: format!("s-{method}-{full_detail}.png"),
            seconds,
            error: Some(error),
            notes: Vec::new(),
        };
        let row = SceneShots {
            name: "armadillo".into(),
            description: String::new(),
            surfels: 1000,
            size: (64, 48),
            path_px: 90.0,
            own_style: None,
            shots: vec![
                shot("static", 0.1, false),
                shot("blur", 0.2, false),
                shot("analytic", 0.3, false),
                shot("blur", 2.0, true),
                shot("analytic", 6.0, true),
            ],
        };
        let html = index_html(&[row], &[], 64);
        let pair = &html[html.find("class=\"pair\"").unwrap()
            ..html.find("simplified for their screen speed").unwrap()];
        assert!(pair.contains("blur τ=1px") && !pair.contains("full detail<"));
        let lod = &html[html.find("simplified for their screen speed").unwrap()
            ..html.find("class=\"styles\"").unwrap()];
        // Blur simplified, blur full detail, then the same for analytic, each with its time.
        let at = |needle: &str| {
            lod.find(needle)
                .unwrap_or_else(|| panic!("{needle} in {lod}"))
        };
        assert!(at("s-blur-false.png") < at("s-blur-true.png"));
        assert!(at("s-blur-true.png") < at("s-analytic-false.png"));
        assert!(at("s-analytic-false.png") < at("s-analytic-true.png"));
        assert!(lod.contains("<b>blur τ=1px · full detail</b><br>2.000 s · 20.0× static"));
    }
}
