//! Command-line arguments → validated jobs → library calls. Nothing here renders.

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;
use streak::gallery::{self, toml_files, GalleryOptions};
use streak::io::image as output;
use streak::io::obj::write_mesh;
use streak::io::write::write_whole;
use streak::lod::Lod;
use streak::metrics;
use streak::plot::{write_error_vs_time_svg, write_study_csv};
use streak::render::{
    Receivers, Subframes, Visibility, ANALYTIC_TOLERANCE_PX, DEFAULT_TOLERANCE_PX, MAX_SAMPLES,
    MAX_SUBFRAMES,
};
use streak::scene::camera::check_image_size;
use streak::simplify::{simplify, Options as SimplifyOptions, Weighting, MAX_VALENCE};
use streak::study::{self, StudyOptions};
use streak::style::Style;
use streak::surfels::Budget;
use streak::{Error, Method, Plan, Result, Scene};

/// Motion blur and motion hints for point-based geometry.
#[derive(Parser)]
#[command(name = "streak", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render one scene to an image.
    Render(RenderArgs),
    /// Measure every method's error against a converged reference, against its run time.
    Study(StudyArgs),
    /// Render every scene of a gallery folder with each method and style, and write a page that
    /// compares them.
    Gallery(GalleryArgs),
    /// Simplify a triangle mesh by quadric edge collapse, optionally weighted by a motion
    /// direction (Zhang et al. 2014), and write it as OBJ or PLY.
    Simplify(SimplifyArgs),
    /// Compare an image with a reference: RMSE, PSNR, SSIM and ꟻLIP as `study` measures them,
    /// and where they differ most.
    Compare(CompareArgs),
}

#[derive(Args)]
struct CompareArgs {
    /// The image measured (.exr linear, or .png sRGB).
    test: PathBuf,
    /// The image it is measured against, of the same size.
    reference: PathBuf,
    /// Also write |test − reference| × --gain per channel to this image (.png or .exr).
    #[arg(long)]
    diff: Option<PathBuf>,
    /// Factor the difference image is multiplied by, so that small differences show.
    #[arg(
        long,
        default_value_t = 10.0,
        requires = "diff",
        allow_hyphen_values = true
    )]
    gain: f32,
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("amount").required(true).args(["faces", "ratio"])))]
struct SimplifyArgs {
    /// The mesh to simplify (.obj or .ply, optionally .gz).
    mesh: PathBuf,
    /// Where to write the result (.obj or .ply).
    #[arg(short, long)]
    output: PathBuf,
    /// Faces to keep.
    #[arg(long)]
    faces: Option<usize>,
    /// Share of the faces to keep, in (0, 1].
    #[arg(long)]
    ratio: Option<f64>,
    /// Motion direction X,Y,Z (object space): edges across it collapse first.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        conflicts_with = "isotropic"
    )]
    direction: Option<Vec<f64>>,
    /// Plain quadric costs, no direction weighting (the default without --direction).
    #[arg(long)]
    isotropic: bool,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
}

/// The rendering methods, as the command line names them; [`method`] adds each one's settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum MethodName {
    /// Sharp EWA splatting at one instant.
    Static,
    /// Motion footprints in one pass: exact streaks (box shutter) or motion ellipses.
    Blur,
    /// Average of N static frames at stratified shutter times.
    Reference,
    /// The object sharp at the flash over a styled trail (a motion hint).
    Hint,
    /// 3D spatio-temporal kernels integrated along pixel rays, with an A-buffer.
    Kernel3d,
    /// Triangle meshes with analytic visibility in time (time-continuous triangles).
    Analytic,
}

/// Options shared by every command that renders.
#[derive(Args)]
struct ImageArgs {
    /// Image width in pixels, with --height (overrides the scene; the vertical field of view is
    /// kept).
    #[arg(long, requires = "height")]
    width: Option<u32>,
    /// Image height in pixels, with --width (overrides the scene).
    #[arg(long, requires = "width")]
    height: Option<u32>,
    /// Worker threads (default: all cores). The image is the same whatever the count.
    #[arg(long)]
    threads: Option<usize>,
    /// Most surfels a scene may have, all objects together (each is counted before it is
    /// made; default 8000000, about 3 GB at the peak of a render).
    #[arg(long)]
    max_surfels: Option<usize>,
    /// Spatial samples per pixel where triangles are drawn, an n × n grid: 1, 4, 9, …, 64
    /// (overrides the scene's `camera.spatial_samples`, default 4).
    #[arg(long)]
    spatial_samples: Option<u32>,
}

impl ImageArgs {
    /// The scene-wide surfel budget asked for.
    fn budget(&self) -> Result<Budget> {
        match self.max_surfels {
            Some(n) => Budget::new(n).map_err(as_option),
            None => Ok(Budget::default()),
        }
    }
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Rendering method.
    #[arg(short, long, value_enum, default_value = "blur")]
    method: MethodName,
    /// Output image: .png (sRGB) or .exr (linear float).
    #[arg(short, long, default_value = "out.png")]
    output: PathBuf,
    /// Also write the linear float image to this .exr file.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Frames averaged by `reference` [default: 64].
    #[arg(long, value_parser = sample_count())]
    samples: Option<usize>,
    /// Instant drawn by `static`, in normalized frame time [0, 1] (default: mid-exposure).
    #[arg(long, allow_hyphen_values = true)]
    time: Option<f64>,
    /// Screen tolerance for the linear sub-segments of curved paths, px (`blur`, `hint`,
    /// `kernel3d` without `--subframes`, and `analytic`) [default: 1; `analytic` 0.1].
    #[arg(long, allow_hyphen_values = true)]
    tolerance: Option<f64>,
    /// Style file for `hint` (default: the scene's `style`, else the built-in default style).
    #[arg(long)]
    style: Option<PathBuf>,
    /// Equal sub-frames of `kernel3d` (default: the plan's sub-segments).
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=MAX_SUBFRAMES as u64))]
    subframes: Option<usize>,
    /// `kernel3d` with the paper's GPU approximation of visibility instead of the A-buffer.
    #[arg(long)]
    approximate: bool,
    /// `analytic`: shadow receivers that sweep shadow-map texels by intersecting their path with
    /// the texel grid, instead of point-sampling it.
    #[arg(long)]
    traced: bool,
    /// Level of detail: `auto` merges surfels where the image cannot tell them apart (along the
    /// motion of what is drawn blurred, and within a pixel) and simplifies moving triangle meshes
    /// by their screen speed; `off` draws every surfel and face.
    #[arg(long, value_enum, default_value = "auto")]
    lod: LodName,
    /// Print the plan, and what was left out and why, with counts.
    #[arg(long)]
    explain: bool,
    #[command(flatten)]
    image: ImageArgs,
}

/// `--lod` as the command line names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum LodName {
    /// Merge where the image cannot show the difference.
    Auto,
    /// Full detail.
    Off,
}

#[derive(Args)]
struct StudyArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output folder for the CSV, the plot, the images and the cached reference.
    #[arg(short, long)]
    output: PathBuf,
    /// Frames in the converged reference.
    #[arg(long, default_value_t = 1024, value_parser = sample_count())]
    reference_samples: usize,
    /// Largest reference sample count studied (1, 2, 4, … up to this).
    #[arg(long, default_value_t = 256, value_parser = sample_count())]
    max_samples: usize,
    /// Timed runs per setting (the median is reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// Style files `hint` is timed with (repeatable; default: the scene's style, else the
    /// built-in default).
    #[arg(long)]
    style: Vec<PathBuf>,
    #[command(flatten)]
    image: ImageArgs,
}

#[derive(Args)]
struct GalleryArgs {
    /// Folder of scene files.
    #[arg(long, default_value = "gallery")]
    scenes: PathBuf,
    /// Output folder.
    #[arg(short, long, default_value = "gallery-out")]
    output: PathBuf,
    /// Frames averaged by `reference`.
    #[arg(long, default_value_t = 256, value_parser = sample_count())]
    samples: usize,
    /// Styles every scene is drawn with as a hint: style files, or folders of them (each scene's
    /// own `style` is drawn too).
    #[arg(long, num_args = 1.., default_value = "styles")]
    styles: Vec<PathBuf>,
    #[command(flatten)]
    image: ImageArgs,
}

/// Sample counts from 1 to [`MAX_SAMPLES`].
fn sample_count() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::new().range(1..=MAX_SAMPLES as u64)
}

/// Most worker threads per core `--threads` may ask for: a few per core can help when a core
/// waits on memory; thousands only cost time (a 0.01 s render took 30 s with 4,000).
const THREADS_PER_CORE: usize = 8;

/// Parse the command line and do the job.
pub fn run() -> Result<()> {
    let cli = Cli::parse();
    let threads = match &cli.command {
        Command::Render(a) => a.image.threads,
        Command::Study(a) => a.image.threads,
        Command::Gallery(a) => a.image.threads,
        Command::Simplify(a) => a.threads,
        Command::Compare(_) => None,
    };
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        let cores = std::thread::available_parallelism().map_or(1, usize::from);
        let most = THREADS_PER_CORE * cores;
        if !(1..=most).contains(&n) {
            return Err(Error::Usage(format!(
                "--threads {n}: use 1 to {most} ({THREADS_PER_CORE} per core of this machine's \
                 {cores}); more threads than cores only add overhead, and the image is the same \
                 whatever the count"
            )));
        }
        pool = pool.num_threads(n);
    }
    let pool = pool
        .build()
        .map_err(|e| Error::Usage(format!("cannot start worker threads: {e}")))?;
    pool.install(|| match cli.command {
        Command::Render(args) => run_render(args),
        Command::Study(args) => run_study(args),
        Command::Gallery(args) => run_gallery(args),
        Command::Simplify(args) => run_simplify(args),
        Command::Compare(args) => run_compare(args),
    })
}

/// Write `text` to standard output. A reader that has gone away (`streak … | head -1`) is not an
/// error: the rest of the text is not wanted.
fn print_quietly(text: &str) {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    if let Err(e) = stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
    {
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            eprintln!("streak: cannot write to standard output: {e}");
        }
    }
}

/// Load a scene and apply the size override.
fn load(path: &Path, image: &ImageArgs) -> Result<Scene> {
    let mut scene = Scene::load_within(path, image.budget()?)?;
    scene.camera = (scene.camera)
        .overridden(image.width.zip(image.height), image.spatial_samples)
        .map_err(as_option)?;
    Ok(scene)
}

fn bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len).with_message(what.to_string());
    if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} ({eta})") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// The method `args` ask for, with its settings; an option that the method does not read is an
/// error, not ignored.
fn method(args: &RenderArgs, scene: &Scene) -> Result<Method> {
    let name = args.method;
    let only = |given: bool, option: &str, methods: &[MethodName]| {
        if given && !methods.contains(&name) {
            let names: Vec<String> = methods
                .iter()
                .map(|m| format!("-m {}", method_name(*m)))
                .collect();
            Err(Error::Usage(format!(
                "{option} applies to {} only, not -m {}",
                names.join(" and "),
                method_name(name)
            )))
        } else {
            Ok(())
        }
    };
    only(args.time.is_some(), "--time", &[MethodName::Static])?;
    only(
        args.samples.is_some(),
        "--samples",
        &[MethodName::Reference],
    )?;
    only(args.style.is_some(), "--style", &[MethodName::Hint])?;
    only(
        args.subframes.is_some(),
        "--subframes",
        &[MethodName::Kernel3d],
    )?;
    only(args.approximate, "--approximate", &[MethodName::Kernel3d])?;
    only(args.traced, "--traced", &[MethodName::Analytic])?;
    // Other methods sample triangles into surfels and draw no spatial samples.
    only(
        args.image.spatial_samples.is_some(),
        "--spatial-samples",
        &[
            MethodName::Static,
            MethodName::Reference,
            MethodName::Analytic,
        ],
    )?;
    only(
        args.tolerance.is_some(),
        "--tolerance",
        &[
            MethodName::Blur,
            MethodName::Hint,
            MethodName::Kernel3d,
            MethodName::Analytic,
        ],
    )?;
    if args.tolerance.is_some() && args.subframes.is_some() {
        return Err(Error::Usage(
            "--tolerance plans kernel3d's sub-frames; with --subframes there is nothing to plan: give one of them"
                .into(),
        ));
    }
    let tolerance_px = args.tolerance.unwrap_or(DEFAULT_TOLERANCE_PX);
    Ok(match name {
        MethodName::Static => Method::Static { time: args.time },
        MethodName::Reference => Method::Reference {
            samples: args.samples.unwrap_or(64),
        },
        MethodName::Blur => Method::Blur { tolerance_px },
        MethodName::Analytic => Method::Analytic {
            tolerance_px: args.tolerance.unwrap_or(ANALYTIC_TOLERANCE_PX),
            receivers: if args.traced {
                Receivers::Traced
            } else {
                Receivers::Sampled
            },
        },
        MethodName::Hint => Method::Hint {
            style: Arc::new(match &args.style {
                Some(path) => Style::load(path)?,
                None => scene.own_style()?.unwrap_or_default(),
            }),
            tolerance_px,
        },
        MethodName::Kernel3d => Method::Kernel3d {
            subframes: match args.subframes {
                Some(n) => Subframes::Equal(n),
                None => Subframes::Planned { tolerance_px },
            },
            visibility: if args.approximate {
                Visibility::Approximate
            } else {
                Visibility::Exact
            },
        },
    })
}

/// The name the command line gives `name` (its clap value).
fn method_name(name: MethodName) -> String {
    clap::ValueEnum::to_possible_value(&name)
        .map(|value| value.get_name().to_string())
        .unwrap_or_default()
}

/// A setting's error in the command line's words: the setting `width/height` is the options
/// `--width/--height`, any other is `--` and its name in kebab case.
fn as_option(error: Error) -> Error {
    match error {
        Error::Invalid { field, message } => Error::Usage(format!(
            "--{} {message}",
            field.replace('/', "/--").replace('_', "-")
        )),
        other => other,
    }
}

fn run_render(args: RenderArgs) -> Result<()> {
    // File names are checked before the render, not after it.
    output::ImageKind::of(&args.output)?;
    if let Some(exr) = &args.exr {
        if output::ImageKind::of(exr).ok() != Some(output::ImageKind::Exr) {
            return Err(Error::Usage(format!(
                "--exr {}: the linear float image is OpenEXR; give a file name ending in .exr",
                exr.display()
            )));
        }
    }
    let loading = Instant::now();
    let scene = load(&args.scene, &args.image)?;
    let load_seconds = loading.elapsed().as_secs_f64();
    let method = method(&args, &scene)?;
    method.check().map_err(as_option)?;
    let start = Instant::now();
    let lod = match args.lod {
        LodName::Auto => Lod::Auto,
        LodName::Off => Lod::Off,
    };
    let plan =
        Plan::with_lod(&scene, &method, lod).map_err(|error| error.in_file(&args.scene, ""))?;
    if matches!(method, Method::Analytic { .. }) && !plan.any_triangles() {
        eprintln!(
            "note: no object of {} is drawn as triangles (`draw = \"triangles\"` on a mesh); \
             -m analytic draws its surfels as -m blur does",
            args.scene.display()
        );
    }
    let progress = match method {
        Method::Reference { samples } => Some(bar(samples as u64, "reference frames")),
        _ => None,
    };
    let tick = || {
        if let Some(bar) = &progress {
            bar.inc(1);
        }
    };
    let out = plan.render(Some(&tick));
    if let Some(b) = progress {
        b.finish_and_clear();
    }
    let seconds = start.elapsed().as_secs_f64();
    output::write_image(&out.image, &args.output)?;
    if let Some(exr) = &args.exr {
        output::write_exr(&out.image, exr)?;
    }
    if args.explain {
        let surfel_instants = scene.surfel_count() * out.stats.frames;
        print_quietly(&format!(
            "scene: {} surfels read and sampled in {load_seconds:.3} s (files, point clouds, meshes, volume iso-surfaces)\n\
             {}{}{}\
             rendered {} footprints in {} frame(s) in {seconds:.3} s; tile lists: {} entries, longest {}\n\
             throughput: {:.3e} surfels × frames per second, {:.3e} footprints per second (plan + render)\n",
            scene.surfel_count(),
            plan.explain(Some(&out.stats.culled)),
            out.stats.method.explain(),
            out.stats.triangles.explain(),
            out.stats.footprints,
            out.stats.frames,
            out.stats.tile_entries,
            out.stats.max_per_tile,
            surfel_instants as f64 / seconds,
            out.stats.footprints as f64 / seconds
        ));
    }
    for departure in plan.departures_of(&out) {
        eprintln!("note: {departure}; --explain says more");
    }
    eprintln!(
        "wrote {} ({} {}×{}, {seconds:.3} s)",
        args.output.display(),
        method.name(),
        scene.camera.width,
        scene.camera.height
    );
    Ok(())
}

fn run_study(args: StudyArgs) -> Result<()> {
    let scene = load(&args.scene, &args.image)?;
    let styles = if args.style.is_empty() {
        scene.own_style()?.into_iter().map(Arc::new).collect()
    } else {
        args.style
            .iter()
            .map(|p| Style::load(p).map(Arc::new))
            .collect::<Result<_>>()?
    };
    let options = StudyOptions {
        reference_samples: args.reference_samples,
        max_samples: args.max_samples,
        repeats: args.repeats,
        out_dir: args.output.clone(),
        styles,
    };
    let progress = bar(args.reference_samples as u64, "converged reference");
    let points = study::run(&scene, &options, Some(&progress))?;
    progress.finish_and_clear();
    for point in &points {
        for note in &point.notes {
            eprintln!("note: {} {}: {note}", point.method, point.knob);
        }
    }
    write_study_csv(&points, &args.output.join("study.csv"))?;
    let title = format!(
        "{} ({}×{}, {} surfels)",
        args.scene.file_stem().unwrap_or_default().to_string_lossy(),
        scene.camera.width,
        scene.camera.height,
        scene.surfel_count()
    );
    // A scene where nothing moves gives every method zero error: nothing to draw on log axes,
    // and a plot left from an earlier study would stand beside a table it does not show.
    let plot = args.output.join("study.svg");
    if points.iter().all(|p| p.error.rmse == 0.0) {
        eprintln!("every method matches the reference exactly (nothing moves): no plot written");
        match std::fs::remove_file(&plot) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(Error::io(&plot, e)),
            _ => {}
        }
    } else {
        let left_out = write_error_vs_time_svg(&points, &title, &plot)?;
        if left_out > 0 {
            eprintln!(
                "{left_out} of {} points are not plotted: their RMSE or time is zero, which log \
                 axes cannot show (they are in study.csv and study.md)",
                points.len()
            );
        }
    }
    let mut report = study::table(&points);
    report
        .push_str("\nEqual error (the smallest reference sample count at least as accurate):\n\n");
    for method in ["blur", "kernel3d", "analytic"] {
        report.push_str(&study::equal_error(&points, method));
    }
    let report_path = args.output.join("study.md");
    write_whole(&report_path, |out| out.write_all(report.as_bytes()))
        .map_err(|e| Error::io(&report_path, e))?;
    print_quietly(&report);
    eprintln!("wrote {}", args.output.join("study.csv").display());
    Ok(())
}

fn run_gallery(args: GalleryArgs) -> Result<()> {
    let scenes = toml_files(&args.scenes)?;
    if scenes.is_empty() {
        return Err(Error::Usage(format!(
            "{}: no .toml scene files here",
            args.scenes.display()
        )));
    }
    if let (Some(w), Some(h)) = (args.image.width, args.image.height) {
        check_image_size(w, h).map_err(as_option)?;
    }
    if let Some(samples) = args.image.spatial_samples {
        streak::scene::Camera::check_spatial_samples(samples).map_err(as_option)?;
    }
    let mut style_files = Vec::new();
    for path in &args.styles {
        if path.is_dir() {
            style_files.extend(toml_files(path)?);
        } else {
            style_files.push(path.clone());
        }
    }
    let options = GalleryOptions {
        styles: style_files
            .iter()
            .map(|p| Style::load(p).map(Arc::new))
            .collect::<Result<_>>()?,
        scenes,
        samples: args.samples,
        out_dir: args.output.clone(),
        size: args.image.width.zip(args.image.height),
        spatial_samples: args.image.spatial_samples,
        budget: args.image.budget()?,
    };
    let per_scene = gallery::images_per_scene(&options) as u64;
    let progress = bar(options.scenes.len() as u64 * per_scene, "gallery");
    let rows = gallery::run(&options, Some(&progress))?;
    progress.finish_and_clear();
    for row in &rows {
        let line: Vec<String> = row
            .shots
            .iter()
            .map(|s| {
                let detail = gallery::full_detail_mark(s.full_detail);
                format!("{} {}{detail} {:.2} s", s.method, s.knob, s.seconds)
            })
            .collect();
        eprintln!("{}: {}", row.name, line.join(", "));
        for shot in &row.shots {
            let detail = gallery::full_detail_mark(shot.full_detail);
            for note in &shot.notes {
                eprintln!(
                    "note: {} {} {}{detail}: {note}",
                    row.name, shot.method, shot.knob
                );
            }
        }
    }
    eprintln!("wrote {}", args.output.join("index.html").display());
    Ok(())
}

fn run_compare(args: CompareArgs) -> Result<()> {
    if !(args.gain.is_finite() && args.gain > 0.0) {
        return Err(Error::Usage(format!(
            "--gain {}: use a finite factor above 0 (10 shows differences of a tenth of a unit at \
             full scale)",
            args.gain
        )));
    }
    let test = output::read_image(&args.test)?;
    let reference = output::read_image(&args.reference)?;
    if (test.width, test.height) != (reference.width, reference.height) {
        return Err(Error::Usage(format!(
            "{} is {}×{} but {} is {}×{}: compare images of one size (render both with the same \
             --width and --height)",
            args.test.display(),
            test.width,
            test.height,
            args.reference.display(),
            reference.width,
            reference.height
        )));
    }
    let error = metrics::compare(&test, &reference)?;
    let mut difference = metrics::difference_image(&test, &reference)?;
    let found = metrics::Differences::of(&difference);
    let mut report = format!(
        "{} against {} ({}×{}):\n  RMSE {:.4e}, PSNR {:.2} dB, SSIM {:.6}, ꟻLIP {:.5}\n",
        args.test.display(),
        args.reference.display(),
        test.width,
        test.height,
        error.rmse,
        error.psnr_db,
        error.ssim,
        error.flip
    );
    if found.pixels == 0 {
        report += "  identical: every channel of every pixel has the same value\n";
    } else {
        let [x, y] = found.at;
        report += &format!(
            "  largest difference {:.4e} at pixel ({x}, {y}); {} of {} pixels differ\n",
            found.largest,
            found.pixels,
            test.pixels.len()
        );
    }
    if let Some(path) = &args.diff {
        for pixel in &mut difference.pixels {
            *pixel = pixel.map(|c| c * args.gain);
        }
        output::write_image(&difference, path)?;
        report += &format!(
            "wrote {} (|test − reference| × {})\n",
            path.display(),
            args.gain
        );
    }
    print_quietly(&report);
    Ok(())
}

fn run_simplify(args: SimplifyArgs) -> Result<()> {
    let mesh = streak::surfels::Mesh::read(&args.mesh)?;
    let faces_in = mesh.triangles.len();
    let target = match (args.faces, args.ratio) {
        (Some(0), _) => {
            return Err(Error::Usage(
                "--faces 0: keep at least one face (a mesh without faces cannot be read back)"
                    .to_string(),
            ))
        }
        (Some(faces), _) => faces,
        // At least one face, however small the share.
        (None, Some(ratio)) if ratio > 0.0 && ratio <= 1.0 => {
            ((ratio * faces_in as f64).round() as usize).max(1)
        }
        (None, ratio) => {
            return Err(Error::Usage(format!(
                "--ratio {}: the share of faces kept is above 0 and at most 1",
                ratio.unwrap_or(f64::NAN)
            )))
        }
    };
    let weighting = match &args.direction {
        Some(d) => {
            let direction = match d.as_slice() {
                &[x, y, z] => glam::DVec3::new(x, y, z),
                _ => glam::DVec3::NAN,
            };
            if !(direction.is_finite() && direction.length() > 0.0) {
                return Err(Error::Usage(format!(
                    "--direction {d:?}: give a motion direction as X,Y,Z, three finite numbers not all zero"
                )));
            }
            Weighting::Direction(direction)
        }
        None => Weighting::Isotropic,
    };
    let options = SimplifyOptions {
        target_faces: target,
        weighting,
        limits: None,
    };
    let progress = bar(faces_in.saturating_sub(target) as u64, "collapsing");
    let start = Instant::now();
    let result = simplify(&mesh, &options, (&[], 0), &mut |faces| {
        progress.set_position(faces_in.saturating_sub(faces) as u64);
    })?;
    progress.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let r = &result.repairs;
    if result.mesh.triangles.is_empty() {
        // A mesh of no faces is one that no reader (streak's included) takes back.
        return Err(Error::Usage(format!(
            "{}: no face is left once the mesh is repaired ({} of its {faces_in} faces had a \
             repeated corner, {} repeated another): {} not written",
            args.mesh.display(),
            r.repeated_corners,
            r.duplicate_faces,
            args.output.display()
        )));
    }
    write_mesh(&result.mesh, &args.output)?;
    let mut report = format!(
        "wrote {} ({faces_in} → {} faces, {} vertices, in {seconds:.3} s)\n",
        args.output.display(),
        result.mesh.triangles.len(),
        result.mesh.positions.len(),
    );
    if target >= faces_in {
        report += &format!(
            "  nothing to collapse: the mesh has {faces_in} faces, no more than the {target} asked for\n"
        );
    } else if result.mesh.triangles.len() + 1 == target {
        report += &format!(
            "  one below {target}: a collapse inside the surface takes two faces, and no edge on a boundary could take the last one (a closed surface always has an even count)\n"
        );
    }
    if !result.reached_target {
        report += &format!(
            "  stopped above {target} faces: every remaining collapse would fold a face, break the surface's topology or gather more than {MAX_VALENCE} faces on a vertex (refused attempts: {} folding, {} topology, {} valence)\n",
            result.stats.fold_refusals, result.stats.topology_refusals, result.stats.valence_refusals
        );
    }
    for (count, what) in [
        (r.welded, "vertices at the same position welded"),
        (r.repeated_corners, "faces with a repeated corner dropped"),
        (r.duplicate_faces, "faces repeating another dropped"),
        (
            r.non_manifold_edges,
            "edges shared by more than two faces kept in place",
        ),
        (r.isolated, "vertices no face uses left out"),
    ] {
        if count > 0 {
            report += &format!("  repaired: {count} {what}\n");
        }
    }
    print_quietly(&report);
    Ok(())
}
