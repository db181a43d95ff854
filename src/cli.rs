//! Command-line arguments → validated jobs → library calls. Nothing here renders.

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;
use streak::gallery::{self, toml_files, GalleryOptions};
use streak::plot::{write_error_vs_time_svg, write_study_csv};
use streak::render::Visibility;
use streak::study::{self, StudyOptions, DEFAULT_TOLERANCE_PX};
use streak::style::Style;
use streak::{output, render, Error, Method, Plan, Result, Scene, Settings};

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
}

/// Options shared by every command that renders.
#[derive(Args)]
struct ImageArgs {
    /// Image width in pixels (overrides the scene; the vertical field of view is kept).
    #[arg(long, requires = "height")]
    width: Option<u32>,
    /// Image height in pixels (overrides the scene).
    #[arg(long, requires = "width")]
    height: Option<u32>,
    /// Worker threads (default: all cores). The image is the same whatever the count.
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Rendering method.
    #[arg(short, long, value_enum, default_value = "blur")]
    method: Method,
    /// Output image: .png (sRGB) or .exr (linear float).
    #[arg(short, long, default_value = "out.png")]
    output: PathBuf,
    /// Also write the linear float image to this .exr file.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Frames averaged by `reference`.
    #[arg(long, default_value_t = 64, value_parser = sample_count())]
    samples: usize,
    /// Instant drawn by `static`, in normalized frame time [0, 1] (default: mid-exposure).
    #[arg(long)]
    time: Option<f64>,
    /// Screen tolerance for the linear sub-segments of curved paths, px (`blur`, `hint`).
    #[arg(long, default_value_t = DEFAULT_TOLERANCE_PX)]
    tolerance: f64,
    /// Style file for `hint` (default: the scene's `style`, else the built-in default style).
    #[arg(long)]
    style: Option<PathBuf>,
    /// Equal sub-frames of `kernel3d` (default: the plan's sub-segments).
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=streak::render::MAX_SUBFRAMES as u64))]
    subframes: Option<usize>,
    /// `kernel3d` with the paper's GPU approximation of visibility instead of the A-buffer.
    #[arg(long)]
    approximate: bool,
    /// Print the plan, and what was left out and why, with counts.
    #[arg(long)]
    explain: bool,
    #[command(flatten)]
    image: ImageArgs,
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

/// Sample counts from 1 to [`streak::render::MAX_SAMPLES`].
fn sample_count() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::new().range(1..=streak::render::MAX_SAMPLES as u64)
}

/// Parse the command line and do the job.
pub fn run() -> Result<()> {
    let cli = Cli::parse();
    let threads = match &cli.command {
        Command::Render(a) => a.image.threads,
        Command::Study(a) => a.image.threads,
        Command::Gallery(a) => a.image.threads,
    };
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            return Err(Error::Usage("--threads must be at least 1".into()));
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
    })
}

/// Load a scene and apply the size override.
fn load(path: &Path, image: &ImageArgs) -> Result<Scene> {
    let mut scene = Scene::load(path)?;
    if let (Some(w), Some(h)) = (image.width, image.height) {
        streak::scene::check_image_size(w, h)
            .map_err(|message| Error::Usage(format!("--width/--height {message}")))?;
        scene.camera = scene.camera.resized(w, h);
    }
    Ok(scene)
}

fn bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len).with_message(what.to_string());
    if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} ({eta})") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

fn run_render(args: RenderArgs) -> Result<()> {
    if !streak::plan::TOLERANCE_RANGE_PX.contains(&args.tolerance) {
        let (lo, hi) = (
            streak::plan::TOLERANCE_RANGE_PX.start(),
            streak::plan::TOLERANCE_RANGE_PX.end(),
        );
        return Err(Error::Usage(format!(
            "--tolerance {}: must be between {lo} and {hi} pixels",
            args.tolerance
        )));
    }
    if let Some(t) = args.time {
        if !(0.0..=1.0).contains(&t) {
            return Err(Error::Usage(format!(
                "--time {t}: frame time is normalized to [0, 1]"
            )));
        }
    }
    let loading = Instant::now();
    let scene = load(&args.scene, &args.image)?;
    let load_seconds = loading.elapsed().as_secs_f64();
    let start = Instant::now();
    let plan = Plan::new(&scene, args.tolerance);
    if args.style.is_some() && args.method != Method::Hint {
        return Err(Error::Usage(format!(
            "--style applies to -m hint only, not -m {}",
            args.method.name()
        )));
    }
    let style = match args.style.as_ref().or(scene.style.as_ref()) {
        Some(path) if args.method == Method::Hint => Some(Arc::new(Style::load(path)?)),
        _ => None,
    };
    if (args.subframes.is_some() || args.approximate) && args.method != Method::Kernel3d {
        return Err(Error::Usage(format!(
            "--subframes and --approximate apply to -m kernel3d only, not -m {}",
            args.method.name()
        )));
    }
    let settings = Settings {
        method: args.method,
        time: args.time,
        samples: args.samples,
        style,
        subframes: args.subframes,
        visibility: if args.approximate {
            Visibility::Approximate
        } else {
            Visibility::Exact
        },
    };
    let progress =
        (args.method == Method::Reference).then(|| bar(args.samples as u64, "reference frames"));
    let out = render(&scene, &plan, &settings, progress.as_ref());
    if let Some(b) = progress {
        b.finish_and_clear();
    }
    let seconds = start.elapsed().as_secs_f64();
    output::write_image(&out.image, &args.output)?;
    if let Some(exr) = &args.exr {
        output::write_exr(&out.image, exr)?;
    }
    if args.explain {
        println!(
            "scene: {} surfels read and sampled in {load_seconds:.3} s (files, point clouds, meshes, volume iso-surfaces)",
            scene.surfel_count()
        );
        print!("{}", plan.explain(Some(&out.stats.culled)));
        match args.method {
            Method::Hint => print!("{}", out.stats.hint.explain()),
            Method::Kernel3d => print!("{}", out.stats.kernel3d.explain()),
            _ => {}
        }
        println!(
            "rendered {} footprints in {} frame(s) ({} reused) in {seconds:.3} s; tile lists: {} entries, longest {}",
            out.stats.footprints,
            out.stats.frames,
            out.stats.reused_footprints,
            out.stats.tile_entries,
            out.stats.max_per_tile
        );
        let surfel_instants = scene.surfel_count() * out.stats.frames;
        println!(
            "throughput: {:.3e} surfels × frames per second, {:.3e} footprints per second (plan + render)",
            surfel_instants as f64 / seconds,
            out.stats.footprints as f64 / seconds
        );
    }
    eprintln!(
        "wrote {} ({} {}×{}, {seconds:.3} s)",
        args.output.display(),
        args.method.name(),
        scene.camera.width,
        scene.camera.height
    );
    Ok(())
}

fn run_study(args: StudyArgs) -> Result<()> {
    let scene = load(&args.scene, &args.image)?;
    let style_paths: Vec<&PathBuf> = if args.style.is_empty() {
        scene.style.iter().collect()
    } else {
        args.style.iter().collect()
    };
    let options = StudyOptions {
        reference_samples: args.reference_samples,
        max_samples: args.max_samples,
        repeats: args.repeats,
        out_dir: args.output.clone(),
        styles: style_paths
            .into_iter()
            .map(|p| Style::load(p).map(Arc::new))
            .collect::<Result<_>>()?,
    };
    let progress = bar(args.reference_samples as u64, "converged reference");
    let points = study::run(&scene, &options, Some(&progress))?;
    progress.finish_and_clear();
    write_study_csv(&points, &args.output.join("study.csv"))?;
    let title = format!(
        "{} ({}×{}, {} surfels)",
        args.scene.file_stem().unwrap_or_default().to_string_lossy(),
        scene.camera.width,
        scene.camera.height,
        scene.surfel_count()
    );
    // A scene where nothing moves gives every method zero error: nothing to draw on log axes.
    if points.iter().all(|p| p.error.rmse == 0.0) {
        eprintln!("every method matches the reference exactly (nothing moves): no plot written");
    } else {
        write_error_vs_time_svg(&points, &title, &args.output.join("study.svg"))?;
    }
    let mut report = study::table(&points);
    report
        .push_str("\nEqual error (the smallest reference sample count at least as accurate):\n\n");
    for method in [Method::Blur, Method::Kernel3d] {
        report.push_str(&study::equal_error(&points, method));
    }
    std::fs::write(args.output.join("study.md"), &report)
        .map_err(|e| Error::io(&args.output, e))?;
    print!("{report}");
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
        streak::scene::check_image_size(w, h)
            .map_err(|message| Error::Usage(format!("--width/--height {message}")))?;
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
    };
    // Per scene: reference, static, blur, and a hint per style (the scene's own style may add one).
    let per_scene = 3 + options.styles.len() as u64;
    let progress = bar(options.scenes.len() as u64 * per_scene, "gallery");
    let rows = gallery::run(&options, Some(&progress))?;
    progress.finish_and_clear();
    for row in &rows {
        let line: Vec<String> = row
            .shots
            .iter()
            .map(|s| format!("{} {} {:.2} s", s.method, s.knob, s.seconds))
            .collect();
        eprintln!("{}: {}", row.name, line.join(", "));
    }
    eprintln!("wrote {}", args.output.join("index.html").display());
    Ok(())
}
