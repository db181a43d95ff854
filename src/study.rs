//! Error against run time: every method across its quality knob, timed, and measured against a
//! converged reference of the same scene (docs/architecture.md, "Error against run time").
//!
//! The reference is the accumulation buffer at `reference_samples` frames (1024 by default),
//! drawn at full detail (no level of detail), cached as linear EXR keyed by the scene text, image
//! size, spatial samples per pixel and frame count. Where triangles are drawn, `analytic` is also
//! studied across its spatial samples per pixel, against a reference at the most a camera takes
//! ([`SPATIAL_REFERENCE_SAMPLES`]). Each render is timed as the median of `repeats` runs of
//! plan + render (scene loading and surfel sampling excluded, as they are shared by every
//! method), after one untimed render. Times are only comparable within one run.

use crate::error::{Error, Result};
use crate::framebuffer::Framebuffer;
use crate::io::image::{read_exr, write_exr, write_png};
use crate::lod::{Lod, FULL_DETAIL_LABEL};
use crate::metrics::{compare, ImageError};
use crate::plan::Plan;
use crate::plot::StudyPoint;
use crate::render::{
    Method, Receivers, Render, Subframes, Visibility, ANALYTIC_TOLERANCE_PX, DEFAULT_TOLERANCE_PX,
    MAX_SAMPLES,
};
use crate::scene::{Geometry, Scene};
use crate::style::Style;
use indicatif::ProgressBar;
use std::borrow::Cow;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Blur tolerances studied, px (the plan's chord-deviation tolerance).
pub const BLUR_TOLERANCES_PX: [f64; 6] = [8.0, 4.0, 2.0, 1.0, 0.5, 0.25];

/// Sub-segment tolerances `analytic` is studied at, px, on scenes with triangle objects (at the
/// scene's spatial samples per pixel, which the converged reference shares).
pub const ANALYTIC_TOLERANCES_PX: [f64; 4] = [1.0, 0.3, 0.1, 0.03];

/// Spatial samples per pixel `analytic` is studied at on scenes with triangle objects (the
/// n × n grids up to 4 × 4), at its default tolerance.
pub const ANALYTIC_SPATIAL_SAMPLES: [u32; 4] = [1, 4, 9, 16];

/// Spatial samples per pixel of the reference that [`ANALYTIC_SPATIAL_SAMPLES`] are measured
/// against: the most a camera takes (8 × 8). It is drawn with as many samples per pixel in all as
/// the converged reference (with the default 1024 frames at 4 samples, 64 frames at 64), so it
/// costs about as much.
pub const SPATIAL_REFERENCE_SAMPLES: u32 = 64;

/// After the series name of `analytic` across its spatial samples (the knob `S=` gives them): what
/// it is measured against, the reference at [`SPATIAL_REFERENCE_SAMPLES`], since the plot's axis
/// names the converged one. Short enough for the plot's legend. Equal-error lines leave the
/// series out.
pub const SPATIAL_LABEL: &str = " vs 64 samples/px";

/// Sub-frame counts and visibility modes of `kernel3d` studied.
pub const KERNEL_SETTINGS: [(usize, Visibility); 7] = [
    (1, Visibility::Exact),
    (2, Visibility::Exact),
    (4, Visibility::Exact),
    (8, Visibility::Exact),
    (1, Visibility::Approximate),
    (4, Visibility::Approximate),
    (8, Visibility::Approximate),
];

/// What a study measures.
#[derive(Clone, Debug)]
pub struct StudyOptions {
    /// Frames in the converged reference.
    pub reference_samples: usize,
    /// Largest reference sample count studied (1, 2, 4, … up to this).
    pub max_samples: usize,
    /// Timed runs per setting; the median is reported.
    pub repeats: usize,
    /// Where rendered images and the cached reference go.
    pub out_dir: PathBuf,
    /// Styles `hint` is timed with (the default style when empty). A hint is not meant to match
    /// the reference; its error is reported to show how far it departs from it.
    pub styles: Vec<Arc<Style>>,
}

/// The `blur` tolerance also studied at full detail (`--lod off`), to show what the level of
/// detail buys.
pub const FULL_DETAIL_BLUR_PX: f64 = DEFAULT_TOLERANCE_PX;

/// The `kernel3d` sub-frame counts also studied at full detail.
pub const FULL_DETAIL_SUBFRAMES: [usize; 2] = [4, 8];

/// One setting to study.
#[derive(Clone, Debug)]
struct Setting {
    method: Method,
    lod: Lod,
    /// Spatial samples per pixel in place of the scene's, measured against the reference at
    /// [`SPATIAL_REFERENCE_SAMPLES`].
    spatial_samples: Option<u32>,
}

impl Setting {
    /// `method` with the level of detail the plan chooses.
    fn auto(method: Method) -> Setting {
        Setting {
            method,
            lod: Lod::Auto,
            spatial_samples: None,
        }
    }

    /// `method` at full detail (`--lod off`).
    fn full_detail(method: Method) -> Setting {
        Setting {
            lod: Lod::Off,
            ..Setting::auto(method)
        }
    }

    /// `label` of this setting, with `full_detail` after it at `--lod off`.
    fn with_lod(&self, label: String, full_detail: &str) -> String {
        match self.lod {
            Lod::Off => label + full_detail,
            _ => label,
        }
    }

    /// `label` of this setting, after its spatial samples (`prefix`, then the count) if it sets
    /// them.
    fn with_spatial(&self, label: String, prefix: &str, separator: &str) -> String {
        match self.spatial_samples {
            Some(samples) => format!("{prefix}{samples}{separator}{label}"),
            None => label,
        }
    }

    fn knob(&self) -> String {
        let knob = match &self.method {
            Method::Static { .. } => "t=mid".to_string(),
            Method::Blur { tolerance_px } => format!("τ={tolerance_px}px"),
            Method::Reference { samples } => format!("N={samples}"),
            Method::Hint { style, .. } => format!("style={}", style.name()),
            Method::Kernel3d { .. } => self.kernel_label("F=", ""),
            Method::Analytic {
                tolerance_px,
                receivers,
            } => format!("τ={tolerance_px}px{}", traced(*receivers, " traced")),
        };
        self.with_spatial(self.with_lod(knob, " lod=off"), "S=", " ")
    }

    /// `kernel3d`'s sub-frames (or `plan`) after `prefix`, and `approximate` in the GPU mode.
    fn kernel_label(&self, prefix: &str, approximate: &str) -> String {
        let Method::Kernel3d {
            subframes,
            visibility,
        } = &self.method
        else {
            return String::new();
        };
        let subframes = match subframes {
            Subframes::Equal(n) => format!("{prefix}{n}"),
            Subframes::Planned { .. } => "plan".to_string(),
        };
        match visibility {
            Visibility::Exact => subframes,
            Visibility::Approximate => subframes + approximate,
        }
    }

    /// The plotted series: the method, with `kernel3d`'s GPU approximation a series of its own.
    fn series(&self) -> String {
        let series = match &self.method {
            Method::Kernel3d {
                visibility: Visibility::Approximate,
                ..
            } => format!("{} approx", self.method.name()),
            method => method.name().to_string(),
        };
        let series = self.with_lod(series, FULL_DETAIL_LABEL);
        match self.spatial_samples {
            Some(_) => series + SPATIAL_LABEL,
            None => series,
        }
    }

    fn file_stem(&self) -> String {
        let stem = match &self.method {
            Method::Static { .. } => "static".to_string(),
            Method::Blur { tolerance_px } => format!("blur-tol{tolerance_px}"),
            Method::Reference { samples } => format!("reference-n{samples}"),
            Method::Hint { style, .. } => format!("hint-{}", style.name()),
            Method::Kernel3d { .. } => format!("kernel3d-{}", self.kernel_label("f", "-approx")),
            Method::Analytic {
                tolerance_px,
                receivers,
            } => format!(
                "analytic-tol{tolerance_px}{}",
                traced(*receivers, "-traced")
            ),
        };
        self.with_spatial(self.with_lod(stem, "-lod-off"), "spp", "-")
    }
}

/// `mark` for `analytic` with traced receivers, nothing for the default sampled ones.
fn traced(receivers: Receivers, mark: &str) -> &str {
    match receivers {
        Receivers::Sampled => "",
        Receivers::Traced => mark,
    }
}

/// Plan and render once, returning the image, the elapsed seconds and where the render departed
/// from the scene.
fn timed(scene: &Scene, setting: &Setting) -> Result<(Render, f64, Vec<String>)> {
    let start = Instant::now();
    let plan = Plan::with_lod(scene, &setting.method, setting.lod)?;
    let out = plan.render(None);
    let seconds = start.elapsed().as_secs_f64();
    let notes = plan.departures_of(&out);
    Ok((out, seconds, notes))
}

/// The median: the middle value, or the mean of the two middle values of an even count.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let middle = v.len() / 2;
    if v.len().is_multiple_of(2) {
        (v[middle - 1] + v[middle]) / 2.0
    } else {
        v[middle]
    }
}

/// The converged reference, from the cache when the same scene, size and count were done before.
/// It is drawn at [`Lod::GROUND_TRUTH`], full detail.
pub fn converged_reference(
    scene: &Scene,
    samples: usize,
    cache_dir: &Path,
    progress: Option<&ProgressBar>,
) -> Result<Framebuffer> {
    // A scene built in code is not cached.
    let cached = match &scene.source {
        Some(source) => reference_key(scene, source, samples)?.map(|key| {
            cache_dir.join(format!(
                "reference-{samples}-{}spp-{key:016x}.exr",
                scene.camera.spatial_samples
            ))
        }),
        None => None,
    };
    if let Some(image) = cached.as_deref().and_then(|path| read_exr(path).ok()) {
        if (image.width, image.height) == (scene.camera.width, scene.camera.height) {
            return Ok(image);
        }
    }
    let tick = || {
        if let Some(bar) = progress {
            bar.inc(1);
        }
    };
    let image = Plan::with_lod(scene, &Method::Reference { samples }, Lod::GROUND_TRUTH)?
        .render(Some(&tick))
        .image;
    if let Some(path) = &cached {
        write_exr(&image, path)?;
    }
    Ok(image)
}

/// The key of `scene`'s converged reference of `samples` frames in the cache: the scene file's
/// text, the image size, the samples per pixel and the frames; the geometry as loaded, so that a
/// changed mesh or point cloud beside the scene file is not answered with its old image; and the
/// running program's own bytes, so that a rebuilt renderer draws its reference anew (its version
/// number stays the same across changes). `None` when the program cannot read itself: nothing is
/// cached then.
fn reference_key(scene: &Scene, source: &Path, samples: usize) -> Result<Option<u64>> {
    let text = std::fs::read_to_string(source).map_err(|e| Error::io(source, e))?;
    // Read and hashed once a process: a study keys two references.
    static PROGRAM: std::sync::OnceLock<Option<u64>> = std::sync::OnceLock::new();
    let program = PROGRAM.get_or_init(|| {
        let bytes = std::env::current_exe().and_then(std::fs::read).ok()?;
        let mut hasher = crate::cache::hasher();
        bytes.hash(&mut hasher);
        Some(hasher.finish())
    });
    let Some(program) = *program else {
        return Ok(None);
    };
    let mut hasher = crate::cache::hasher();
    (
        text,
        scene.camera.width,
        scene.camera.height,
        scene.camera.spatial_samples,
        samples,
        "full detail",
    )
        .hash(&mut hasher);
    for object in &scene.objects {
        let surfels = match &object.geometry {
            Geometry::Surfels(surfels) => surfels,
            Geometry::Triangles { mesh, surfels } => {
                hasher.write_u64(crate::simplify::speed::content_key(mesh));
                surfels
            }
        };
        crate::cache::hash_words(
            &mut hasher,
            surfels.iter().flat_map(|s| {
                let vectors = [s.position, s.normal, s.axis_u, s.axis_v];
                (vectors.into_iter().flat_map(|v| v.to_array()))
                    .chain([s.area])
                    .chain(s.colour.map(f64::from))
                    .map(f64::to_bits)
            }),
        );
    }
    hasher.write_u64(program);
    Ok(Some(hasher.finish()))
}

/// Run the study: render every method across its knob, time it, measure it against the converged
/// reference, and write each image as PNG into `options.out_dir`. `progress` counts reference
/// frames first, then the settings studied.
pub fn run(
    scene: &Scene,
    options: &StudyOptions,
    progress: Option<&ProgressBar>,
) -> Result<Vec<StudyPoint>> {
    if !(options.reference_samples <= MAX_SAMPLES
        && options.max_samples >= 1
        && options.max_samples < options.reference_samples
        && options.repeats >= 1)
    {
        return Err(Error::Usage(format!(
            "study: need 1 ≤ max samples ({}) < reference samples ({}) ≤ {MAX_SAMPLES} and at least one repeat ({})",
            options.max_samples, options.reference_samples, options.repeats
        )));
    }
    crate::style::check_distinct_names(&options.styles)?;
    crate::io::write::output_folder(&options.out_dir)?;
    let reference = converged_reference(
        scene,
        options.reference_samples,
        &options.out_dir.join("cache"),
        progress,
    )?;
    write_png(
        &reference,
        &options
            .out_dir
            .join(format!("converged-n{}.png", options.reference_samples)),
    )?;

    let mut setups = vec![Setting::auto(Method::STATIC)];
    setups.extend(
        BLUR_TOLERANCES_PX
            .iter()
            .map(|&tolerance_px| Setting::auto(Method::Blur { tolerance_px })),
    );
    setups.push(Setting::full_detail(Method::Blur {
        tolerance_px: FULL_DETAIL_BLUR_PX,
    }));
    let styles = if options.styles.is_empty() {
        vec![Arc::new(Style::default())]
    } else {
        options.styles.clone()
    };
    setups.extend(styles.into_iter().map(|style| {
        Setting::auto(Method::Hint {
            style,
            tolerance_px: DEFAULT_TOLERANCE_PX,
        })
    }));
    // Heinzle §6: the kernels at 1–8 sub-frames, and the GPU approximation at 1, 4 and 8.
    for (subframes, visibility) in KERNEL_SETTINGS {
        setups.push(Setting::auto(Method::Kernel3d {
            subframes: Subframes::Equal(subframes),
            visibility,
        }));
    }
    for subframes in FULL_DETAIL_SUBFRAMES {
        setups.push(Setting::full_detail(Method::Kernel3d {
            subframes: Subframes::Equal(subframes),
            visibility: Visibility::Exact,
        }));
    }
    // Triangles drawn analytically, across the sub-segment tolerance (its only error in time).
    let has_meshes = scene.objects.iter().any(|o| o.mesh().is_some());
    if has_meshes {
        setups.extend(ANALYTIC_TOLERANCES_PX.iter().map(|&tolerance_px| {
            Setting::auto(Method::Analytic {
                tolerance_px,
                receivers: Receivers::Sampled,
            })
        }));
        // Receivers sweeping shadow-map texels traced instead of sampled, at the default tolerance.
        if scene.lighting.any_shadows() {
            setups.push(Setting::auto(Method::Analytic {
                tolerance_px: ANALYTIC_TOLERANCE_PX,
                receivers: Receivers::Traced,
            }));
        }
    }
    // Where the level of detail simplifies a mesh, the simplified renders level off at the
    // simplification's error against the full-detail converged reference; `analytic` and the
    // reference are then also studied at full detail, and compared with each other there.
    let triangles_full_detail =
        has_meshes && Plan::new(scene, &Method::ANALYTIC)?.simplifies_a_mesh();
    if triangles_full_detail {
        setups.extend(ANALYTIC_TOLERANCES_PX.iter().map(|&tolerance_px| {
            Setting::full_detail(Method::Analytic {
                tolerance_px,
                receivers: Receivers::Sampled,
            })
        }));
    }
    let lods: &[Lod] = if triangles_full_detail {
        &[Lod::Auto, Lod::Off]
    } else {
        &[Lod::Auto]
    };
    for &lod in lods {
        let mut n = 1;
        while n <= options.max_samples {
            setups.push(Setting {
                lod,
                ..Setting::auto(Method::Reference { samples: n })
            });
            n *= 2;
        }
    }
    // Spatial samples per pixel are `analytic`'s other knob (its only error in space): measured
    // against a reference at SPATIAL_REFERENCE_SAMPLES.
    let spatial_reference = if has_meshes {
        let spatial = at_spatial_samples(scene, SPATIAL_REFERENCE_SAMPLES)?;
        let samples_per_pixel = options.reference_samples * scene.camera.spatial_samples as usize;
        let frames = (samples_per_pixel / SPATIAL_REFERENCE_SAMPLES as usize).max(1);
        if let Some(bar) = progress {
            bar.set_length(frames as u64);
            bar.set_position(0);
            bar.set_message(format!(
                "reference at {SPATIAL_REFERENCE_SAMPLES} samples per pixel"
            ));
        }
        let image =
            converged_reference(&spatial, frames, &options.out_dir.join("cache"), progress)?;
        write_png(
            &image,
            &options.out_dir.join(format!(
                "converged-n{frames}-spp{SPATIAL_REFERENCE_SAMPLES}.png"
            )),
        )?;
        // At full detail where a mesh would be simplified, as the reference is: the series is
        // about samples, and the simplification's error would drown them.
        let lod = lods[lods.len() - 1];
        setups.extend(ANALYTIC_SPATIAL_SAMPLES.iter().map(|&samples| Setting {
            lod,
            spatial_samples: Some(samples),
            ..Setting::auto(Method::ANALYTIC)
        }));
        Some(image)
    } else {
        None
    };

    if let Some(bar) = progress {
        bar.set_length(setups.len() as u64);
        bar.set_position(0);
    }
    // The first render in a process pays for starting the thread pool and faulting in fresh
    // memory (the knot's `static` took 3.5× the reference's one frame): one untimed render of the
    // first setting (`static`) keeps that out of every ratio.
    timed(scene, &setups[0])?;
    let mut points = Vec::with_capacity(setups.len());
    for setting in &setups {
        if let Some(bar) = progress {
            bar.set_message(format!("{} {}", setting.method.name(), setting.knob()));
        }
        let (scene, reference) = match (setting.spatial_samples, &spatial_reference) {
            (Some(samples), Some(spatial)) => {
                (Cow::Owned(at_spatial_samples(scene, samples)?), spatial)
            }
            _ => (Cow::Borrowed(scene), &reference),
        };
        let (first, first_time, notes) = timed(&scene, setting)?;
        let mut times = vec![first_time];
        for _ in 1..options.repeats {
            times.push(timed(&scene, setting)?.1);
        }
        write_png(
            &first.image,
            &options.out_dir.join(format!("{}.png", setting.file_stem())),
        )?;
        points.push(StudyPoint {
            method: setting.series(),
            knob: setting.knob(),
            seconds: median(times),
            error: compare(&first.image, reference)?,
            notes,
        });
        if let Some(bar) = progress {
            bar.inc(1);
        }
    }
    Ok(points)
}

/// `scene` with `samples` spatial samples per pixel where triangles are drawn.
fn at_spatial_samples(scene: &Scene, samples: u32) -> Result<Scene> {
    let mut scene = scene.clone();
    scene.camera = scene.camera.with_spatial_samples(samples)?;
    Ok(scene)
}

/// The first (smallest-N) point of the reference series `reference` at least as accurate as
/// `error` by `metric`, if any was studied.
#[must_use]
pub fn samples_to_match<'a>(
    points: &'a [StudyPoint],
    reference: &str,
    metric: fn(&ImageError) -> f64,
    error: &ImageError,
) -> Option<&'a StudyPoint> {
    points
        .iter()
        .find(|p| p.method == reference && metric(&p.error) <= metric(error))
}

/// The reference series a point of series `method` is compared with: at full detail where the
/// study drew the reference at full detail too, so that neither side carries the level of
/// detail's error.
fn reference_series(points: &[StudyPoint], method: &str) -> String {
    let reference = Method::Reference { samples: 1 }.name();
    let full = format!("{reference}{FULL_DETAIL_LABEL}");
    if method.ends_with(FULL_DETAIL_LABEL) && points.iter().any(|p| p.method == full) {
        full
    } else {
        reference.to_string()
    }
}

/// For each of `method`'s points, the reference sample count that first reaches its error, in
/// RMSE and in ꟻLIP, and how its time compares: Heinzle Table 1's equal-error ratio. ꟻLIP
/// weighs the reference's stroboscopic copies as the eye does, which RMSE does not. One line
/// each, Markdown.
#[must_use]
pub fn equal_error(points: &[StudyPoint], method: &str) -> String {
    let mut out = String::new();
    let matched = |p: &StudyPoint, name: &str, metric: fn(&ImageError) -> f64| {
        let reference = reference_series(points, &p.method);
        match samples_to_match(points, &reference, metric, &p.error) {
            Some(r) => format!(
                "{name} {:.5} matches the {reference} at {} ({:.3} s, {:.2}× its time)",
                metric(&p.error),
                r.knob,
                r.seconds,
                p.seconds / r.seconds
            ),
            None => format!(
                "{name} {:.5}: no studied {reference} sample count reaches it",
                metric(&p.error)
            ),
        }
    };
    let compared =
        |p: &&StudyPoint| p.method.starts_with(method) && !p.method.ends_with(SPATIAL_LABEL);
    for p in points.iter().filter(compared) {
        out.push_str(&format!(
            "- {} {} ({:.3} s): {}; {}\n",
            p.method,
            p.knob,
            p.seconds,
            matched(p, "RMSE", |e| e.rmse),
            matched(p, "ꟻLIP", |e| e.flip)
        ));
    }
    out
}

/// A plain-text table of the points with times as ratios to the static render.
#[must_use]
pub fn table(points: &[StudyPoint]) -> String {
    let base = points
        .iter()
        .find(|p| p.method == Method::STATIC.name())
        .map_or(1.0, |p| p.seconds);
    let mut out = String::from("| method | knob | time (s) | × static | RMSE | PSNR (dB) | SSIM | FLIP |\n|---|---|---|---|---|---|---|---|\n");
    for p in points {
        out.push_str(&format!(
            "| {} | {} | {:.4} | {:.1} | {:.5} | {:.2} | {:.4} | {:.4} |\n",
            p.method,
            p.knob,
            p.seconds,
            p.seconds / base,
            p.error.rmse,
            p.error.psnr_db,
            p.error.ssim,
            p.error.flip
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(method: &str, knob: &str, seconds: f64, rmse: f64) -> StudyPoint {
        StudyPoint {
            method: method.to_string(),
            knob: knob.to_string(),
            seconds,
            error: ImageError {
                rmse,
                psnr_db: -20.0 * rmse.log10(),
                ssim: 1.0,
                flip: rmse,
            },
            notes: Vec::new(),
        }
    }

    #[test]
    fn a_cached_reference_is_not_handed_out_for_changed_geometry_beside_the_scene_file() {
        // The scene file's text stays the same while the mesh it names changes: the cached
        // reference was drawn from the old mesh and must not be found.
        let dir = std::env::temp_dir().join(format!("streak-study-key-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene_path = dir.join("scene.toml");
        std::fs::write(
            &scene_path,
            "[camera]\neye = [0, 0, 4]\ntarget = [0, 0, 0]\nfov_y = 30\nwidth = 16\nheight = 16\n\n\
             [[object]]\nname = \"card\"\n\
             shape = { type = \"mesh\", path = \"card.obj\", samples = 8 }\n",
        )
        .unwrap();
        let key_with = |corner: &str| {
            let obj = format!("v 0 0 0\nv 1 0 0\nv {corner} 0\nf 1 2 3\n");
            std::fs::write(dir.join("card.obj"), obj).unwrap();
            let scene = Scene::load(&scene_path).unwrap();
            reference_key(&scene, &scene_path, 16).unwrap().unwrap()
        };
        let key = key_with("0 1");
        assert_eq!(key, key_with("0 1"), "the same files give the same key");
        assert_ne!(key, key_with("0 2"), "a changed mesh gives another key");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn median_of_an_even_count_is_the_mean_of_the_middle_two() {
        // `--repeats 2`: the median of 1 s and 3 s is 2 s, not the slower run.
        assert_eq!(median(vec![1.0, 3.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![5.0]), 5.0);
    }

    #[test]
    fn styles_of_one_name_are_refused_before_their_hints_share_a_file_and_a_row() {
        // `--style styles/comet.toml --style mine/comet.toml`: both hints would be written to
        // hint-comet.png and tabled as the same knob.
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let scene = Scene::load(&root.join("tests/data/turning-square.toml")).unwrap();
        let options = StudyOptions {
            reference_samples: 4,
            max_samples: 1,
            repeats: 1,
            out_dir: std::env::temp_dir().join("streak-study-never-written"),
            styles: crate::style::two_comets(),
        };
        match run(&scene, &options, None) {
            Err(Error::Usage(message)) => assert!(message.contains("mine/comet.toml"), "{message}"),
            other => panic!(
                "two `comet` styles were not refused: {:?}",
                other.map(|_| ())
            ),
        }
        assert!(!options.out_dir.exists());
    }

    #[test]
    fn full_detail_is_matched_against_the_full_detail_reference() {
        // The simplified reference levels off at 0.001; at full detail it goes on to 0.0002.
        let points = [
            point("reference", "N=16", 1.0, 0.002),
            point("reference", "N=64", 4.0, 0.001),
            point("reference full detail", "N=16 lod=off", 2.0, 0.002),
            point("reference full detail", "N=64 lod=off", 8.0, 0.0002),
            point("analytic", "τ=0.3px", 0.5, 0.0011),
            point("analytic full detail", "τ=0.3px lod=off", 0.6, 0.0003),
        ];
        let lines = equal_error(&points, "analytic");
        let lines: Vec<&str> = lines.lines().collect();
        assert_eq!(lines.len(), 2);
        assert!(lines[0].contains("matches the reference at N=64 (4.000 s, 0.12×"));
        assert!(
            lines[1].contains("matches the reference full detail at N=64 lod=off (8.000 s, 0.07×")
        );
        // Without a full-detail reference series, full detail is matched against the reference.
        let simplified_reference = [points[0].clone(), points[1].clone(), points[5].clone()];
        let line = equal_error(&simplified_reference, "analytic");
        assert!(line.contains("RMSE 0.00030: no studied reference sample count reaches it"));
    }
}
