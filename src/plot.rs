//! Error-against-time plots (SVG) and tables (CSV) of a study: every method at several settings
//! of its quality knob, measured against a converged reference.

use crate::error::{Error, Result};
use crate::io::write::write_whole;
use crate::metrics::ImageError;
use plotters::coord::combinators::{LogCoord, WithKeyPoints};
use plotters::coord::Shift;
use plotters::element::DynElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::fmt::Write as _;
use std::io::Write as _;
use std::ops::Range;
use std::path::Path;

/// One measured point of a study: a method at one setting of its quality knob.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StudyPoint {
    /// Name of the method, e.g. "reference"; points with the same name form one series.
    pub method: String,
    /// The knob setting as it should be printed, e.g. "N=16" or "τ=1px".
    pub knob: String,
    /// Median render time in seconds.
    pub seconds: f64,
    /// Error of the render against the converged reference.
    pub error: ImageError,
    /// Where the render departed from what the scene asked ([`crate::plan::Plan::departures_of`]).
    pub notes: Vec<String>,
}

/// Write an SVG plot of error against run time on log–log axes: x = seconds (median render time), y = RMSE.
///
/// Each method is one series in its own colour and marker shape, listed in a legend beside the
/// plot in order of first appearance. A series' points are sorted by time (stable, so equal
/// times keep their knob order) and joined by a line; each marker is labelled with its knob.
/// Axes get a margin around the data, span at least one decade and carry at least three
/// labelled ticks, so a single point and spans of many decades both plot sensibly.
///
/// Points with non-positive or non-finite RMSE or time cannot go on log axes: they are left out,
/// and their number is returned. Errors with [`Error::Usage`] when no point is left to plot, and
/// with [`Error::Io`] when the file cannot be written.
pub fn write_error_vs_time_svg(points: &[StudyPoint], title: &str, path: &Path) -> Result<usize> {
    let plottable: Vec<&StudyPoint> = points
        .iter()
        .filter(|point| is_positive_finite(point.seconds) && is_positive_finite(point.error.rmse))
        .collect();
    let left_out = points.len() - plottable.len();
    if plottable.is_empty() {
        return Err(Error::Usage(format!(
            "{}: nothing to plot: none of the {} points has a positive, finite time and RMSE",
            path.display(),
            points.len()
        )));
    }

    let svg = render_svg(&series_by_method(&plottable), title).map_err(|e| {
        Error::io(
            path,
            std::io::Error::other(format!("drawing the plot: {e}")),
        )
    })?;
    write_whole(path, |out| out.write_all(svg.as_bytes())).map_err(|e| Error::io(path, e))?;
    Ok(left_out)
}

/// Write the same data as CSV with header method,knob,seconds,rmse,psnr_db,ssim,flip.
///
/// Precision is fixed: `seconds` and `rmse` in scientific notation with 7 significant digits
/// (e.g. `1.234568e-3`), `psnr_db` with 4 decimals (`inf` for a perfect match), `ssim` and `flip`
/// with 6 decimals. Text fields holding a comma, quote or line break are quoted as in RFC 4180.
pub fn write_study_csv(points: &[StudyPoint], path: &Path) -> Result<()> {
    let mut csv = String::from("method,knob,seconds,rmse,psnr_db,ssim,flip\n");
    for point in points {
        let error = &point.error;
        // Writing to a String cannot fail.
        let _ = writeln!(
            csv,
            "{},{},{:.6e},{:.6e},{:.4},{:.6},{:.6}",
            csv_field(&point.method),
            csv_field(&point.knob),
            point.seconds,
            error.rmse,
            error.psnr_db,
            error.ssim,
            error.flip
        );
    }
    write_whole(path, |out| out.write_all(csv.as_bytes())).map_err(|e| Error::io(path, e))
}

fn is_positive_finite(value: f64) -> bool {
    value.is_finite() && value > 0.0
}

fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}

/// One plotted series: a method's points, sorted by time.
struct Series<'a> {
    method: &'a str,
    points: Vec<&'a StudyPoint>,
}

/// Groups points by method in order of first appearance, each group sorted by time.
fn series_by_method<'a>(points: &[&'a StudyPoint]) -> Vec<Series<'a>> {
    let mut all_series: Vec<Series<'a>> = Vec::new();
    for &point in points {
        match all_series.iter_mut().find(|s| s.method == point.method) {
            Some(series) => series.points.push(point),
            None => all_series.push(Series {
                method: &point.method,
                points: vec![point],
            }),
        }
    }
    for series in &mut all_series {
        series
            .points
            .sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
    }
    all_series
}

const CANVAS_SIZE: (u32, u32) = (960, 600);
const FONT: &str = "sans-serif";
/// Nominal font sizes; plotters' SVG backend writes them as `font-size` = nominal / 1.24 px.
const TITLE_FONT_SIZE: f64 = 24.0;
const AXIS_NAME_FONT_SIZE: f64 = 18.0;
const TICK_FONT_SIZE: f64 = 16.0;
const LEGEND_FONT_SIZE: f64 = 17.0;
const KNOB_FONT_SIZE: f64 = 15.0;
const SVG_FONT_SCALE: f64 = 1.0 / 1.24;
/// Okabe–Ito colours (distinguishable with colour-blindness), without yellow, which is unreadable on white.
const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
];
const MARKER_SIZE: i32 = 4;
/// Margins of the axes beyond the data, in decades: more on the right for the knob labels.
const X_MARGIN_DECADES: (f64, f64) = (0.15, 0.35);
const Y_MARGIN_DECADES: (f64, f64) = (0.2, 0.2);

/// Drawing into a string cannot fail for I/O reasons; any error here is plotters' own.
type DrawResult<T> = std::result::Result<T, Box<dyn std::error::Error>>;
type LogLogChart<'a, DB> =
    ChartContext<'a, DB, Cartesian2d<WithKeyPoints<LogCoord<f64>>, WithKeyPoints<LogCoord<f64>>>>;

fn render_svg(all_series: &[Series], title: &str) -> DrawResult<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, CANVAS_SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        let (plot_area, legend_area) =
            root.split_horizontally(CANVAS_SIZE.0 as i32 - legend_width(all_series));

        let all_points = || all_series.iter().flat_map(|series| &series.points);
        let x_axis = log_axis(all_points().map(|p| p.seconds), X_MARGIN_DECADES);
        let y_axis = log_axis(all_points().map(|p| p.error.rmse), Y_MARGIN_DECADES);
        let mut chart = ChartBuilder::on(&plot_area)
            .caption(title, (FONT, TITLE_FONT_SIZE))
            .margin(12)
            .x_label_area_size(56)
            .y_label_area_size(88)
            .build_cartesian_2d(x_axis.into_coordinates(), y_axis.into_coordinates())?;
        chart
            .configure_mesh()
            .x_desc("render time (s)")
            .y_desc("RMSE vs converged reference")
            .x_label_formatter(&|value| tick_label(*value))
            .y_label_formatter(&|value| tick_label(*value))
            .label_style((FONT, TICK_FONT_SIZE))
            .axis_desc_style((FONT, AXIS_NAME_FONT_SIZE))
            .bold_line_style(BLACK.mix(0.2))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;

        for (index, series) in all_series.iter().enumerate() {
            let coordinates = series.points.iter().map(|p| (p.seconds, p.error.rmse));
            // A line joins one method across its quality knob; hints in different styles are
            // different pictures, not steps of a knob, so their points stand alone.
            if series.method != "hint" {
                chart.draw_series(LineSeries::new(
                    coordinates.clone(),
                    series_colour(index).stroke_width(2),
                ))?;
            }
            chart
                .draw_series(coordinates.map(|at| EmptyElement::at(at) + marker(index, (0, 0))))?;
        }
        draw_knob_labels(&mut chart, all_series)?;
        draw_legend(&legend_area, all_series)?;
        root.present()?;
    }
    Ok(svg)
}

/// Labels every marker with its knob, each where it collides least (see [`place_labels`]).
fn draw_knob_labels<DB: DrawingBackend>(
    chart: &mut LogLogChart<'_, DB>,
    all_series: &[Series],
) -> DrawResult<()>
where
    DB::ErrorType: 'static,
{
    let polylines: Vec<Vec<(i32, i32)>> = all_series
        .iter()
        .map(|series| {
            let pixel = |p: &&StudyPoint| chart.backend_coord(&(p.seconds, p.error.rmse));
            series.points.iter().map(pixel).collect()
        })
        .collect();
    let knobs: Vec<Vec<&str>> = all_series
        .iter()
        .map(|series| series.points.iter().map(|p| p.knob.as_str()).collect())
        .collect();
    let (x_pixels, y_pixels) = chart.plotting_area().get_pixel_range();
    let plot_box = PixelBox {
        left: x_pixels.start,
        top: y_pixels.start,
        right: x_pixels.end,
        bottom: y_pixels.end,
    };
    let spots = place_labels(&polylines, &knobs, plot_box);

    for (index, (series, series_spots)) in all_series.iter().zip(&spots).enumerate() {
        let font = (FONT, KNOB_FONT_SIZE)
            .into_font()
            .color(&series_colour(index));
        chart.draw_series(series.points.iter().zip(series_spots).map(|(point, spot)| {
            EmptyElement::at((point.seconds, point.error.rmse))
                + Text::new(
                    point.knob.clone(),
                    (spot.dx, spot.dy),
                    font.pos(Pos::new(spot.h_pos, spot.v_pos)),
                )
        }))?;
    }
    Ok(())
}

fn series_colour(index: usize) -> RGBColor {
    PALETTE[index % PALETTE.len()]
}

/// The marker of series `index` at pixel offset `centre`: shapes cycle independently of colours
/// so series stay distinct in greyscale too.
fn marker<DB: DrawingBackend>(
    index: usize,
    centre: (i32, i32),
) -> DynElement<'static, DB, (i32, i32)> {
    let fill = series_colour(index).filled();
    let (x, y) = centre;
    match index % 4 {
        0 => Circle::new(centre, MARKER_SIZE, fill).into_dyn(),
        1 => TriangleMarker::new(centre, MARKER_SIZE + 2, fill).into_dyn(),
        2 => Rectangle::new(
            [
                (x - MARKER_SIZE, y - MARKER_SIZE),
                (x + MARKER_SIZE, y + MARKER_SIZE),
            ],
            fill,
        )
        .into_dyn(),
        _ => Cross::new(centre, MARKER_SIZE, fill.stroke_width(2)).into_dyn(),
    }
}

/// An axis-aligned box in backend pixels.
#[derive(Clone, Copy)]
struct PixelBox {
    left: i32,
    top: i32,
    right: i32,
    bottom: i32,
}

impl PixelBox {
    fn around((x, y): (i32, i32), half_size: i32) -> Self {
        PixelBox {
            left: x - half_size,
            top: y - half_size,
            right: x + half_size,
            bottom: y + half_size,
        }
    }

    fn overlaps(&self, other: &PixelBox) -> bool {
        self.left < other.right
            && other.left < self.right
            && self.top < other.bottom
            && other.top < self.bottom
    }

    fn contains(&self, other: &PixelBox) -> bool {
        self.left <= other.left
            && other.right <= self.right
            && self.top <= other.top
            && other.bottom <= self.bottom
    }

    /// Whether the segment from `a` to `b` passes through the box (Liang–Barsky clipping).
    fn crosses_segment(&self, a: (i32, i32), b: (i32, i32)) -> bool {
        let (x0, y0) = (f64::from(a.0), f64::from(a.1));
        let (dx, dy) = (f64::from(b.0) - x0, f64::from(b.1) - y0);
        let (mut t_enter, mut t_exit) = (0.0_f64, 1.0_f64);
        for (direction, distance_inside) in [
            (-dx, x0 - f64::from(self.left)),
            (dx, f64::from(self.right) - x0),
            (-dy, y0 - f64::from(self.top)),
            (dy, f64::from(self.bottom) - y0),
        ] {
            if direction == 0.0 {
                if distance_inside < 0.0 {
                    return false;
                }
            } else {
                let t = distance_inside / direction;
                if direction < 0.0 {
                    t_enter = t_enter.max(t);
                } else {
                    t_exit = t_exit.min(t);
                }
            }
        }
        t_enter < t_exit
    }
}

/// Where a label goes relative to its marker: a pixel offset and which side of the text sits there.
#[derive(Clone, Copy)]
struct LabelSpot {
    dx: i32,
    dy: i32,
    h_pos: HPos,
    v_pos: VPos,
}

impl LabelSpot {
    const fn new(dx: i32, dy: i32, h_pos: HPos, v_pos: VPos) -> Self {
        LabelSpot {
            dx,
            dy,
            h_pos,
            v_pos,
        }
    }

    /// The estimated box of `text` put here next to the marker at `(x, y)`.
    fn text_box(&self, (x, y): (i32, i32), text: &str) -> PixelBox {
        let font_px = KNOB_FONT_SIZE * SVG_FONT_SCALE;
        // A viewer picks the font; 0.6 em is a typical sans-serif advance.
        let width = (0.6 * font_px * text.chars().count() as f64).ceil() as i32;
        let height = (1.2 * font_px).ceil() as i32;
        let left = x + self.dx
            - match self.h_pos {
                HPos::Left => 0,
                HPos::Center => width / 2,
                HPos::Right => width,
            };
        let top = y + self.dy
            - match self.v_pos {
                VPos::Top => 0,
                VPos::Center => height / 2,
                VPos::Bottom => height,
            };
        PixelBox {
            left,
            top,
            right: left + width,
            bottom: top + height,
        }
    }
}

const LABEL_GAP: i32 = MARKER_SIZE + 3;
/// Candidate label positions, most preferred first. Above-right and below-left come first
/// because error-against-time curves mostly fall to the right, leaving those corners free.
const LABEL_SPOTS: [LabelSpot; 8] = [
    LabelSpot::new(LABEL_GAP, -LABEL_GAP, HPos::Left, VPos::Bottom),
    LabelSpot::new(-LABEL_GAP, LABEL_GAP, HPos::Right, VPos::Top),
    LabelSpot::new(LABEL_GAP + 2, 0, HPos::Left, VPos::Center),
    LabelSpot::new(-LABEL_GAP - 2, 0, HPos::Right, VPos::Center),
    LabelSpot::new(LABEL_GAP, LABEL_GAP, HPos::Left, VPos::Top),
    LabelSpot::new(-LABEL_GAP, -LABEL_GAP, HPos::Right, VPos::Bottom),
    LabelSpot::new(0, -LABEL_GAP - 2, HPos::Center, VPos::Bottom),
    LabelSpot::new(0, LABEL_GAP + 2, HPos::Center, VPos::Top),
];

/// Chooses a spot for every label (`labels[s][i]` belongs to the marker `polylines[s][i]`), one
/// label at a time, where it collides least: with labels already placed or the plot's edge worst,
/// then with markers, then with lines; ties go to the more preferred spot.
fn place_labels(
    polylines: &[Vec<(i32, i32)>],
    labels: &[Vec<&str>],
    plot_box: PixelBox,
) -> Vec<Vec<LabelSpot>> {
    let markers: Vec<PixelBox> = polylines
        .iter()
        .flatten()
        .map(|&centre| PixelBox::around(centre, MARKER_SIZE + 1))
        .collect();
    let segments: Vec<((i32, i32), (i32, i32))> = polylines
        .iter()
        .flat_map(|line| line.windows(2).map(|pair| (pair[0], pair[1])))
        .collect();
    let mut placed: Vec<PixelBox> = Vec::new();
    let collision_cost = |text_box: &PixelBox, placed: &[PixelBox]| {
        let label_hits = placed.iter().filter(|b| b.overlaps(text_box)).count();
        let outside = usize::from(!plot_box.contains(text_box));
        let marker_hits = markers.iter().filter(|b| b.overlaps(text_box)).count();
        let line_hits = segments
            .iter()
            .filter(|(a, b)| text_box.crosses_segment(*a, *b))
            .count();
        100 * (label_hits + outside) + 10 * marker_hits + line_hits
    };

    polylines
        .iter()
        .zip(labels)
        .map(|(line, texts)| {
            line.iter()
                .zip(texts)
                .map(|(&centre, text)| {
                    let best = LABEL_SPOTS
                        .iter()
                        .min_by_key(|spot| collision_cost(&spot.text_box(centre, text), &placed))
                        .copied()
                        .unwrap_or(LABEL_SPOTS[0]);
                    placed.push(best.text_box(centre, text));
                    best
                })
                .collect()
        })
        .collect()
}

const LEGEND_ROW_HEIGHT: i32 = 26;
const LEGEND_SAMPLE_WIDTH: i32 = 30;

/// Width of the legend column beside the plot: enough for the longest method name (estimated,
/// since an SVG's fonts are chosen by its viewer), within bounds.
fn legend_width(all_series: &[Series]) -> i32 {
    let longest_name = all_series
        .iter()
        .map(|series| series.method.chars().count())
        .max()
        .unwrap_or(0) as f64;
    let name_width = 0.6 * LEGEND_FONT_SIZE * SVG_FONT_SCALE * longest_name;
    (LEGEND_SAMPLE_WIDTH + 30 + name_width.ceil() as i32).clamp(120, 320)
}

/// A legend beside the plot rather than over it, so it never hides data.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    all_series: &[Series],
) -> DrawResult<()>
where
    DB::ErrorType: 'static,
{
    let top = 60;
    for (index, series) in all_series.iter().enumerate() {
        let row_start = (0, top + index as i32 * LEGEND_ROW_HEIGHT);
        let entry = EmptyElement::at(row_start)
            + PathElement::new(
                vec![(0, 0), (LEGEND_SAMPLE_WIDTH, 0)],
                series_colour(index).stroke_width(2),
            )
            + marker(index, (LEGEND_SAMPLE_WIDTH / 2, 0))
            + Text::new(
                series.method.to_owned(),
                (LEGEND_SAMPLE_WIDTH + 8, 0),
                TextStyle::from((FONT, LEGEND_FONT_SIZE).into_font())
                    .pos(Pos::new(HPos::Left, VPos::Center)),
            );
        area.draw(&entry)?;
    }
    Ok(())
}

/// A log axis: its range, its labelled ticks and its grid lines.
struct LogAxis {
    range: Range<f64>,
    ticks: Vec<f64>,
    grid: Vec<f64>,
}

impl LogAxis {
    fn into_coordinates(self) -> WithKeyPoints<LogCoord<f64>> {
        self.range
            .log_scale()
            .with_key_points(self.ticks)
            .with_light_points(self.grid)
    }
}

/// Most labelled ticks on an axis; more powers of ten than this are thinned out.
const MAX_TICKS: usize = 8;
/// Up to this many decades every 1…9 multiple gets a grid line, beyond only the powers of ten.
const MAX_FINE_GRID_DECADES: f64 = 6.0;

/// A log axis around the (positive) `values`, widened by `margin_decades` below and above and
/// to at least one decade, so it always holds three or more ticks of the 1–2–5 series.
/// Ticks are powers of ten when at least three fit, otherwise 1–2–5 multiples.
fn log_axis(values: impl Iterator<Item = f64>, margin_decades: (f64, f64)) -> LogAxis {
    let (min, max) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    let mut low = min.log10() - margin_decades.0;
    let mut high = max.log10() + margin_decades.1;
    if high - low < 1.0 {
        let centre = (low + high) / 2.0;
        (low, high) = (centre - 0.5, centre + 0.5);
    }
    let range = 10f64.powf(low)..10f64.powf(high);

    let powers_of_ten = multiples_in(&range, &[1.0]);
    let ticks = if powers_of_ten.len() >= 3 {
        let stride = powers_of_ten.len().div_ceil(MAX_TICKS);
        // Keep the powers whose exponent is a multiple of the stride: 1e-6, 1e-3, 1, 1e3, …
        powers_of_ten
            .into_iter()
            .filter(|value| (value.log10().round() as i64).rem_euclid(stride as i64) == 0)
            .collect()
    } else {
        multiples_in(&range, &[1.0, 2.0, 5.0])
    };
    let grid = if high - low <= MAX_FINE_GRID_DECADES {
        multiples_in(&range, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
    } else {
        multiples_in(&range, &[1.0])
    };
    LogAxis { range, ticks, grid }
}

/// Every `mantissa × 10^k` inside `range`, ascending.
fn multiples_in(range: &Range<f64>, mantissas: &[f64]) -> Vec<f64> {
    let first_exponent = range.start.log10().floor() as i32;
    let last_exponent = range.end.log10().ceil() as i32;
    (first_exponent..=last_exponent)
        .flat_map(|exponent| mantissas.iter().map(move |m| m * 10f64.powi(exponent)))
        .filter(|value| (range.start..=range.end).contains(value))
        .collect()
}

/// A tick label for a log axis: up to 3 significant digits, plain from 0.001 to 9999 and in
/// scientific notation (e.g. "2e-5") beyond.
fn tick_label(value: f64) -> String {
    let magnitude = value.abs();
    if (1e-3..1e4).contains(&magnitude) {
        let decimals = (2 - magnitude.log10().floor() as i32).max(0) as usize;
        let plain = format!("{value:.decimals$}");
        if plain.contains('.') {
            plain.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            plain
        }
    } else {
        let scientific = format!("{value:.2e}");
        let (mantissa, exponent) = scientific.split_once('e').unwrap_or((&scientific, "0"));
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        format!("{mantissa}e{exponent}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn error_with_rmse(rmse: f64) -> ImageError {
        ImageError {
            rmse,
            psnr_db: -20.0 * rmse.log10(),
            ssim: 1.0 - rmse,
            flip: rmse.sqrt(),
        }
    }

    fn point(method: &str, knob: &str, seconds: f64, rmse: f64) -> StudyPoint {
        StudyPoint {
            method: method.to_owned(),
            knob: knob.to_owned(),
            seconds,
            error: error_with_rmse(rmse),
            notes: Vec::new(),
        }
    }

    /// Three methods × five points spanning 1e-3..10 s and RMSE 1e-4..1e-1, with crossing curves.
    fn example_study() -> Vec<StudyPoint> {
        let mut points = Vec::new();
        for (i, samples) in [1, 10, 100, 1000, 10000].into_iter().enumerate() {
            let seconds = 1e-3 * 10f64.powi(i as i32);
            let rmse = 1e-1 / (samples as f64).sqrt();
            points.push(point(
                "accumulation",
                &format!("N={samples}"),
                seconds,
                rmse,
            ));
        }
        for (i, tau) in [8.0, 4.0, 2.0, 1.0, 0.5].into_iter().enumerate() {
            let seconds = 2e-3 * 3f64.powi(i as i32);
            let rmse = 3e-2 * 0.4f64.powi(i as i32);
            points.push(point(
                "streak splatting",
                &format!("τ={tau}px"),
                seconds,
                rmse,
            ));
        }
        for (i, steps) in [2, 4, 8, 16, 32].into_iter().enumerate() {
            let seconds = 5e-3 * 2.5f64.powi(i as i32);
            let rmse = 5e-2 * 0.2f64.powi(i as i32);
            points.push(point(
                "A&B <analytic>",
                &format!("steps={steps}"),
                seconds,
                rmse,
            ));
        }
        points
    }

    /// A path in the temporary directory unique to this process and test.
    fn temp_path(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("streak-plot-{}-{name}", std::process::id()))
    }

    #[test]
    fn csv_has_a_line_per_point_and_reads_back() {
        let mut points = example_study();
        points[0].error.psnr_db = f64::INFINITY;
        let path = temp_path("study.csv");
        write_study_csv(&points, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();

        let mut lines = text.lines();
        assert_eq!(
            lines.next(),
            Some("method,knob,seconds,rmse,psnr_db,ssim,flip")
        );
        let rows: Vec<Vec<&str>> = lines.map(|line| line.split(',').collect()).collect();
        assert_eq!(rows.len(), points.len());
        let close = |printed: &str, value: f64, tolerance: f64| {
            let parsed: f64 = printed.parse().unwrap();
            parsed == value || (parsed - value).abs() <= tolerance * value.abs().max(1.0)
        };
        for (row, point) in rows.iter().zip(&points) {
            assert_eq!(row.len(), 7, "{row:?}");
            assert_eq!(
                (row[0], row[1]),
                (point.method.as_str(), point.knob.as_str())
            );
            assert!(close(row[2], point.seconds, 1e-6), "{row:?}");
            assert!(close(row[3], point.error.rmse, 1e-6), "{row:?}");
            assert!(close(row[4], point.error.psnr_db, 5e-5), "{row:?}");
            assert!(close(row[5], point.error.ssim, 5e-7), "{row:?}");
            assert!(close(row[6], point.error.flip, 5e-7), "{row:?}");
        }
        assert_eq!(rows[0][4], "inf");
    }

    #[test]
    fn csv_quotes_awkward_text() {
        assert_eq!(csv_field("plain"), "plain");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
    }

    #[test]
    fn svg_is_well_formed_and_names_every_method_and_knob() {
        let points = example_study();
        let path = temp_path("study.svg");
        let left_out = write_error_vs_time_svg(&points, "Error vs time", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();

        assert_eq!(left_out, 0);
        let document = roxmltree::Document::parse(&svg).expect("the SVG is well-formed XML");
        assert_eq!(document.root_element().tag_name().name(), "svg");
        let texts: Vec<&str> = document
            .descendants()
            .filter(|node| node.has_tag_name("text"))
            .filter_map(|node| node.text())
            .map(str::trim)
            .collect();
        for expected in points
            .iter()
            .flat_map(|p| [p.method.as_str(), p.knob.as_str()])
            .chain([
                "Error vs time",
                "render time (s)",
                "RMSE vs converged reference",
            ])
        {
            assert!(texts.contains(&expected), "no text {expected:?}");
        }
    }

    #[test]
    fn unplottable_points_are_left_out_and_counted() {
        let mut points = example_study();
        points.push(point("accumulation", "N=0", 1e-3, 0.0));
        points.push(point("accumulation", "N=nan", 1e-3, f64::NAN));
        points.push(point("accumulation", "t=0", 0.0, 1e-2));
        points.push(point("accumulation", "t=inf", f64::INFINITY, 1e-2));
        let path = temp_path("left-out.svg");
        let left_out = write_error_vs_time_svg(&points, "left out", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();

        assert_eq!(left_out, 4);
        for label in ["N=0", "N=nan", "t=0", "t=inf"] {
            assert!(!svg.contains(label), "{label} was plotted");
        }
    }

    #[test]
    fn nothing_plottable_is_a_usage_error() {
        let points = [point("accumulation", "N=1", 1.0, f64::NAN)];
        let path = temp_path("nothing.svg");
        let result = write_error_vs_time_svg(&points, "nothing", &path);
        assert!(matches!(result, Err(Error::Usage(_))));
        assert!(!path.exists());
    }

    #[test]
    fn a_single_point_plots() {
        let points = [point("accumulation", "N=1", 0.37, 0.02)];
        let path = temp_path("single.svg");
        assert_eq!(write_error_vs_time_svg(&points, "one", &path).unwrap(), 0);
        let svg = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert!(svg.contains("N=1"));
    }

    #[test]
    fn log_axes_hold_the_data_and_enough_ticks() {
        let wide = log_axis([1e-3, 10.0].into_iter(), (0.1, 0.1));
        assert!(wide.range.start < 1e-3 && wide.range.end > 10.0);
        assert_eq!(wide.ticks.len(), 5, "{:?}", wide.ticks);

        // One point: a decade around it, labelled with the 1–2–5 series.
        let single = log_axis([0.37].into_iter(), (0.1, 0.1));
        assert!((single.range.end / single.range.start - 10.0).abs() < 1e-9);
        assert!(single.range.contains(&0.37));
        assert_eq!(single.ticks.len(), 3, "{:?}", single.ticks);

        // Two decades: too few powers of ten, so 1–2–5.
        let narrow = log_axis([0.019, 1.5].into_iter(), (0.0, 0.0));
        assert_eq!(narrow.ticks.len(), 6, "{:?}", narrow.ticks);

        // Twenty decades: powers of ten, thinned to at most MAX_TICKS.
        let huge = log_axis([1e-10, 1e10].into_iter(), (0.01, 0.01));
        assert!(
            (3..=MAX_TICKS).contains(&huge.ticks.len()),
            "{:?}",
            huge.ticks
        );
        assert_eq!(huge.grid.len(), 21);
    }

    #[test]
    fn labels_avoid_each_other_and_the_plot_edge() {
        let plot_box = PixelBox {
            left: 0,
            top: 0,
            right: 400,
            bottom: 300,
        };
        // Two series with a marker on the same pixel, and one marker at the right edge.
        let polylines = vec![vec![(200, 150), (395, 150)], vec![(200, 150)]];
        let labels = vec![vec!["N=16", "N=256"], vec!["τ=1px"]];
        let spots = place_labels(&polylines, &labels, plot_box);

        let first = spots[0][0].text_box(polylines[0][0], labels[0][0]);
        let second = spots[1][0].text_box(polylines[1][0], labels[1][0]);
        assert!(!first.overlaps(&second));
        let at_edge = spots[0][1].text_box(polylines[0][1], labels[0][1]);
        assert!(plot_box.contains(&at_edge));
    }

    #[test]
    fn segments_cross_boxes_only_when_they_pass_through() {
        let unit = PixelBox::around((0, 0), 5);
        assert!(unit.crosses_segment((-20, 0), (20, 0)));
        assert!(unit.crosses_segment((-20, -20), (20, 20)));
        assert!(!unit.crosses_segment((-20, 10), (20, 10)));
        assert!(!unit.crosses_segment((10, -20), (30, 20)));
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(1.0), "1");
        assert_eq!(tick_label(10.000000000000002), "10");
        assert_eq!(tick_label(0.001), "0.001");
        assert_eq!(tick_label(0.020000000000000004), "0.02");
        assert_eq!(tick_label(0.00010000000000000002), "1e-4");
        assert_eq!(tick_label(3e-5), "3e-5");
        assert_eq!(tick_label(2.5e-6), "2.5e-6");
        assert_eq!(tick_label(1e5), "1e5");
    }
}
