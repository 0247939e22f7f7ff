//! The plots a user reads to choose `tau` (paper figures 10 and 11): a histogram of handle sizes
//! and a scatter plot of Reeb-loop against cross-loop length, as SVG and PNG.

use crate::error::{Error, Result};
use crate::volume::{AtomicOutput, Compression};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Handles as plotted: those with the same lengths and kind, counted once.
#[derive(Clone, Copy, Debug)]
pub struct PlotPoint {
    /// Loop lengths in voxel edges (`None`: not found within the search limit).
    pub reeb: Option<usize>,
    /// The cross loop's length, likewise.
    pub cross: Option<usize>,
    /// Whether the handle's smaller loop encloses void (hollow marker, as in the paper).
    pub void: bool,
    /// How many handles have these lengths (a volume of noise has 100,000 handles and a few
    /// hundred distinct points).
    pub count: usize,
}

impl PlotPoint {
    fn size(&self) -> Option<usize> {
        match (self.reeb, self.cross) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
}

const FONT: &str = "sans-serif";

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            include_bytes!("../assets/DejaVuSans.ttf"),
        );
    });
}

fn plot_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::io(path, "drawing", std::io::Error::other(e.to_string()))
}

/// Writes `histogram.svg/png` and `scatter.svg/png` into `dir`; returns their paths.
pub fn write(
    dir: &Path,
    title: &str,
    points: &[PlotPoint],
    tau: Option<f64>,
) -> Result<Vec<PathBuf>> {
    register_font();
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "creating", e))?;
    let mut out = Vec::new();
    for ext in ["svg", "png"] {
        let h = dir.join(format!("histogram.{ext}"));
        let data = (title, points, tau);
        write_plot(&h, ext, Plot::Histogram, data)?;
        out.push(h);
        let s = dir.join(format!("scatter.{ext}"));
        write_plot(&s, ext, Plot::Scatter, data)?;
        out.push(s);
    }
    Ok(out)
}

const SIZE: (u32, u32) = (900, 600);

/// A log axis's label: only at 1, 2 and 5 times a power of ten (and not below `min`), so that
/// labels never crowd (90 beside 100).
fn log_label(v: f64, min: f64) -> String {
    if v < min || v <= 0.0 {
        return String::new();
    }
    let p = 10f64.powf(v.log10().floor());
    let m = v / p;
    if [1.0, 2.0, 5.0].iter().any(|&n| (m - n).abs() < 1e-6) {
        format!("{v:.0}")
    } else {
        String::new()
    }
}

/// Where simplifying with `tau` cuts an axis of integer sizes: between the largest size that
/// goes (below tau) and the smallest that stays.
fn cut_at(tau: f64) -> f64 {
    tau.ceil() - 0.5
}

/// The range of tau giving the same result as `tau` on these sizes (the paper's figure 11):
/// from just above the largest size below tau to the smallest size at or above it, as cut
/// positions (`None` above: no size at or above tau).
fn same_result(sizes: &[(usize, usize)], tau: f64) -> (f64, Option<f64>) {
    let below = sizes
        .iter()
        .map(|s| s.0)
        .filter(|&s| (s as f64) < tau)
        .max();
    let above = sizes
        .iter()
        .map(|s| s.0)
        .filter(|&s| (s as f64) >= tau)
        .min();
    (
        below.map_or(2.5, |b| b as f64 + 0.5),
        above.map(|a| a as f64 - 0.5),
    )
}

/// The two plots.
#[derive(Clone, Copy)]
enum Plot {
    Histogram,
    Scatter,
}

/// Draws `plot` in memory, as SVG or PNG by `ext`, then writes it to `path` atomically.
fn write_plot(
    path: &Path,
    ext: &str,
    plot: Plot,
    data: (&str, &[PlotPoint], Option<f64>),
) -> Result<()> {
    let bytes = if ext == "svg" {
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
            draw(&root, plot, data).map_err(|e| plot_err(path, e))?;
            root.present().map_err(|e| plot_err(path, e))?;
        }
        svg.into_bytes()
    } else {
        let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
            draw(&root, plot, data).map_err(|e| plot_err(path, e))?;
            root.present().map_err(|e| plot_err(path, e))?;
        }
        encode_png(&rgb).map_err(|e| plot_err(path, e))?
    };
    let mut out = AtomicOutput::create(path, Compression::None)?;
    out.write_all(&bytes)?;
    out.commit()
}

/// An RGB image of [`SIZE`] as PNG.
fn encode_png(rgb: &[u8]) -> std::result::Result<Vec<u8>, png::EncodingError> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, SIZE.0, SIZE.1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header()?.write_image_data(rgb)?;
    Ok(bytes)
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    plot: Plot,
    (title, points, tau): (&str, &[PlotPoint], Option<f64>),
) -> DrawResult<DB> {
    match plot {
        Plot::Histogram => draw_histogram(root, title, points, tau),
        Plot::Scatter => draw_scatter(root, title, points, tau),
    }
}

type DrawResult<DB> =
    std::result::Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Sizes on a logarithmic axis: one bin per voxel edge up to 20 (where noise handles are), then
/// bins growing by a quarter; the count axis is logarithmic too, since a few large handles stand
/// beside hundreds of small ones.
fn draw_histogram<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    points: &[PlotPoint],
    tau: Option<f64>,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let sizes: Vec<(usize, usize)> = points
        .iter()
        .filter_map(|p| Some((p.size()?, p.count)))
        .collect();
    let max = sizes.iter().map(|s| s.0).max().unwrap_or(10).max(10) as f64;
    let mut edges = vec![2.5f64];
    while *edges.last().unwrap() <= max {
        let e = *edges.last().unwrap();
        edges.push(if e < 20.0 {
            e + 1.0
        } else {
            (e * 1.25).round() + 0.5
        });
    }
    let mut counts = vec![0u32; edges.len() - 1];
    for &(s, n) in &sizes {
        if let Some(b) = (0..counts.len()).find(|&b| (s as f64) < edges[b + 1]) {
            counts[b] += n as u32;
        }
    }
    let top = counts.iter().copied().max().unwrap_or(1).max(1) as f64 * 2.0;
    let total: usize = points.iter().map(|p| p.count).sum();
    let not_found = total - sizes.iter().map(|s| s.1).sum::<usize>();
    let caption = format!(
        "{title}: {} handles{}",
        total,
        if not_found > 0 {
            format!(" ({not_found} beyond the search limit)")
        } else {
            String::new()
        }
    );
    let mut chart = ChartBuilder::on(root)
        .caption(caption, (FONT, 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (2.5f64..*edges.last().unwrap()).log_scale(),
            (0.8f64..top).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("handle size = shorter of Reeb and cross loop (voxel edges)")
        .y_desc("handles")
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 18))
        .x_label_formatter(&|v| log_label(*v, 3.0))
        .y_label_formatter(&|v| log_label(*v, 1.0))
        .disable_x_mesh()
        .light_line_style(WHITE)
        .draw()?;
    let tau = tau.filter(|t| t.is_finite());
    let right = *edges.last().unwrap();
    if let Some(t) = tau {
        // The band first: the bars show through it.
        let (lo, hi) = same_result(&sizes, t);
        let hi = hi.unwrap_or(right).min(right);
        let pink = RGBColor(246, 211, 211);
        if hi > lo {
            let upto = if hi == right {
                "inf".to_string()
            } else {
                format!("{}", hi + 0.5)
            };
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(lo, 0.8), (hi, top)],
                    pink.filled(),
                )))?
                .label(format!("same result for any tau in {}..{upto}", lo + 0.5))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], pink.filled()));
        }
    }
    chart.draw_series(
        counts
            .iter()
            .enumerate()
            .filter(|(_, &c)| c > 0)
            .map(|(b, &c)| {
                let (x0, x1) = (edges[b], edges[b + 1]);
                Rectangle::new(
                    [(x0 * 1.01, 0.8), (x1 / 1.01, c as f64)],
                    RGBColor(70, 110, 200).filled(),
                )
            }),
    )?;
    if let Some(t) = tau {
        let x = cut_at(t).max(2.5);
        chart
            .draw_series(LineSeries::new(
                vec![(x, 0.8), (x, top)],
                RED.stroke_width(2),
            ))?
            .label(format!("tau = {t}: handles left of the line go"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
        chart
            .configure_series_labels()
            .label_font((FONT, 16))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

/// Reeb-loop length against cross-loop length, both logarithmic; hollow markers where the
/// smaller loop encloses void, filled where it encloses material.
fn draw_scatter<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    points: &[PlotPoint],
    tau: Option<f64>,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let both: Vec<(f64, f64, bool)> = points
        .iter()
        .filter_map(|p| Some((p.reeb? as f64, p.cross? as f64, p.void)))
        .collect();
    let measured: usize = points
        .iter()
        .filter(|p| p.reeb.is_some() && p.cross.is_some())
        .map(|p| p.count)
        .sum();
    let max = both.iter().map(|p| p.0.max(p.1)).fold(10.0, f64::max) * 1.3;
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!("{title}: loop lengths of {measured} handles"),
            (FONT, 22),
        )
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        // From 2: the shortest loops (3 edges) sit inside the frame, not on its edges.
        .build_cartesian_2d((2f64..max).log_scale(), (2f64..max).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("Reeb loop (voxel edges)")
        .y_desc("cross loop (voxel edges)")
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 18))
        .x_label_formatter(&|v| log_label(*v, 2.0))
        .y_label_formatter(&|v| log_label(*v, 2.0))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    let blue = RGBColor(40, 80, 200);
    chart
        .draw_series(
            both.iter()
                .filter(|p| !p.2)
                .map(|&(x, y, _)| Circle::new((x, y), 4, blue.filled())),
        )?
        .label("smaller loop encloses material")
        .legend(move |(x, y)| Circle::new((x + 10, y), 4, blue.filled()));
    chart
        .draw_series(
            both.iter()
                .filter(|p| p.2)
                .map(|&(x, y, _)| Circle::new((x, y), 4, blue.stroke_width(1))),
        )?
        .label("smaller loop encloses void")
        .legend(move |(x, y)| Circle::new((x + 10, y), 4, blue.stroke_width(1)));
    if let Some(t) = tau.filter(|t| t.is_finite()) {
        chart
            .draw_series(LineSeries::new(
                // A handle goes when either loop is below tau: left of or below the corner.
                vec![(cut_at(t), max), (cut_at(t), cut_at(t)), (max, cut_at(t))],
                RED.stroke_width(2),
            ))?
            .label(format!(
                "tau = {t}: handles left of or below the line are removed"
            ))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 15))
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_labels_only_at_one_two_five() {
        let shown: Vec<String> = [1.0, 2.0, 3.0, 5.0, 9.0, 10.0, 20.0, 90.0, 100.0, 500.0]
            .iter()
            .map(|&v| log_label(v, 2.0))
            .collect();
        assert_eq!(shown, ["", "2", "", "5", "", "10", "20", "", "100", "500"]);
    }

    #[test]
    fn tau_cuts_between_sizes_and_the_band_spans_the_same_results() {
        // Sizes 3 (x5), 8, 19, 40: tau 20 removes 3, 8, 19; so does any tau in 20..=40.
        let sizes = [(3, 5), (8, 1), (19, 1), (40, 1)];
        assert_eq!(cut_at(20.0), 19.5);
        assert_eq!(cut_at(19.2), 19.5, "19 < 19.2: size 19 goes");
        assert_eq!(same_result(&sizes, 20.0), (19.5, Some(39.5)));
        assert_eq!(same_result(&sizes, 50.0), (40.5, None));
        assert_eq!(same_result(&sizes, 3.0), (2.5, Some(2.5)), "nothing goes");
    }

    #[test]
    fn both_plots_are_written_with_a_tau_and_without() {
        let dir = tempfile::tempdir().unwrap();
        let points = [
            PlotPoint {
                reeb: Some(3),
                cross: Some(4),
                void: false,
                count: 40,
            },
            PlotPoint {
                reeb: Some(90),
                cross: Some(100),
                void: true,
                count: 1,
            },
            PlotPoint {
                reeb: Some(12),
                cross: None,
                void: false,
                count: 2,
            },
        ];
        for tau in [Some(20.0), None] {
            let files = write(dir.path(), "t", &points, tau).unwrap();
            assert_eq!(files.len(), 4);
            let svg = std::fs::read_to_string(dir.path().join("histogram.svg")).unwrap();
            assert_eq!(
                svg.contains("same result for any tau in 13..90"),
                tau.is_some()
            );
        }
    }
}
