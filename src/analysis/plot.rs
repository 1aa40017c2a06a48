//! Log-log line charts, drawn with `plotters` as PNG and SVG.
//!
//! A [`LogLogChart`] holds one [`Series`] per curve: a measured line through
//! the mean of each point, a shaded band of ±1 standard deviation, faint
//! marks for the samples the means came from, and a dashed predicted line
//! in the same colour. A [`Guide`] line of a given slope (slope -1 for
//! error ∝ 1/spp) runs across the whole chart.
//!
//! A log axis has no 0, and an error of exactly 0 is a result (a white
//! furnace against its analytic image), not a failure. When some y is 0,
//! the y axis gets one more decade at its bottom, whose bottom line is
//! labelled `0`: values of 0 are drawn on that line, the axis label says
//! so, and the decade above it starts the logarithmic scale as usual.
//!
//! Text in the PNG is drawn with DejaVu Sans, which the `dejavu` crate embeds
//! (plotters' `ab_glyph` renderer), so no system font library or installed
//! font is needed. The SVG names the family `sans-serif` and leaves the font
//! to the viewer.

use std::path::Path;
use std::sync::OnceLock;

use anyhow::{anyhow, ensure, Context, Result};
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::io::image_file;

/// The font family the charts use, registered with plotters on first use.
const FONT: &str = "sans-serif";

/// Series colours: the `tab10` palette (matplotlib's default cycle).
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The colour of the `i`-th series (the palette repeats after 10).
pub fn series_color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Registers DejaVu Sans as [`FONT`] with plotters, once per process.
fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok()
    });
    ensure!(ok, "the embedded DejaVu Sans font could not be loaded");
    Ok(())
}

/// One point of a measured curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Position on the x axis (> 0).
    pub x: f64,
    /// Mean on the y axis (> 0).
    pub y: f64,
    /// Standard deviation of `y`; the band spans y ± y_std (0: no band).
    pub y_std: f64,
}

/// One curve of a [`LogLogChart`].
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend entry of the measured curve.
    pub name: String,
    /// The measured curve, in the order to join the points.
    pub points: Vec<Point>,
    /// The predicted curve, drawn dashed in the same colour (may be empty).
    pub predicted: Vec<(f64, f64)>,
    /// Individual samples behind the means, drawn as faint dots (may be
    /// empty).
    pub samples: Vec<(f64, f64)>,
}

/// A straight reference line in log-log space: y = y0 · (x / x0)^slope.
#[derive(Clone, Debug, PartialEq)]
pub struct Guide {
    /// Legend entry.
    pub label: String,
    /// A point `(x0, y0)` the line passes through.
    pub through: (f64, f64),
    /// The slope in log-log space.
    pub slope: f64,
}

/// A chart with logarithmic x and y axes.
#[derive(Clone, Debug, PartialEq)]
pub struct LogLogChart {
    /// Title above the chart.
    pub title: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// The reference line, if any.
    pub guide: Option<Guide>,
}

/// Whether a value can go on a log axis.
fn plottable(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// Where a y value is drawn: itself when it can go on a log axis, the
/// chart's zero line (see the module documentation) when it is 0 and the
/// chart has one, else nowhere.
fn y_at(y: f64, zero: Option<f64>) -> Option<f64> {
    if plottable(y) {
        Some(y)
    } else if y == 0.0 {
        zero
    } else {
        None
    }
}

/// The y ranges of a chart.
#[derive(Clone, Copy, Debug, PartialEq)]
struct YRange {
    /// Bottom and top, whole decades (the bottom a hair lower when there
    /// is a zero line).
    lo: f64,
    hi: f64,
    /// Where values of 0 are drawn (the bottom line), when there are any.
    zero: Option<f64>,
}

/// Lower end of a ±std band on a log axis: never at or below 0.
fn band_low(p: &Point) -> f64 {
    (p.y - p.y_std).max(p.y * 1e-3)
}

/// `[lo, hi]` widened to whole decades, so that the axis has labelled
/// powers of ten at both ends.
fn decades(lo: f64, hi: f64) -> (f64, f64) {
    let lo = 10f64.powf(lo.log10().floor());
    let mut hi = 10f64.powf(hi.log10().ceil());
    if hi <= lo {
        hi = lo * 10.0;
    }
    (lo, hi)
}

/// Tick label of a log axis: powers of ten only (the lines between them
/// stay unlabelled), in plain notation from 0.001 to 10000 and as `1e-5`
/// outside.
fn tick_label(v: f64) -> String {
    let e = v.log10();
    if (e - e.round()).abs() > 1e-6 {
        return String::new();
    }
    let e = e.round() as i32;
    if (-3..=4).contains(&e) {
        format!("{:.*}", (-e).max(0) as usize, 10f64.powi(e))
    } else {
        format!("1e{e}")
    }
}

impl LogLogChart {
    /// The x and y ranges that hold every plottable value, widened to whole
    /// decades, with a zero line below them when some y is 0 (see the
    /// module documentation); an error if there is nothing to plot.
    fn ranges(&self) -> Result<((f64, f64), YRange)> {
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        let mut zeros = false;
        for s in &self.series {
            for p in &s.points {
                if plottable(p.x) && y_at(p.y, Some(0.0)).is_some() {
                    xs.push(p.x);
                    zeros |= p.y == 0.0;
                    if plottable(p.y) {
                        ys.push(p.y);
                    }
                    if plottable(p.y) && p.y_std > 0.0 && p.y_std.is_finite() {
                        ys.push(p.y + p.y_std);
                        ys.push(band_low(p));
                    }
                }
            }
            for &(x, y) in s.predicted.iter().chain(&s.samples) {
                if plottable(x) && y_at(y, Some(0.0)).is_some() {
                    xs.push(x);
                    zeros |= y == 0.0;
                    if plottable(y) {
                        ys.push(y);
                    }
                }
            }
        }
        ensure!(
            !xs.is_empty(),
            "{}: no positive, finite values (or zeros) to plot on log axes",
            self.title
        );
        let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        // Only zeros: one decade above the zero line, to show it
        let (lo, hi) = if ys.is_empty() {
            (1.0, 10.0)
        } else {
            decades(min(&ys), max(&ys))
        };
        let y = match zeros {
            // The axis starts a hair below the zero line, so that the
            // line's tick, computed by plotters as 10^k, falls inside it
            true => YRange {
                lo: lo / 10.0 * (1.0 - 1e-6),
                hi,
                zero: Some(lo / 10.0),
            },
            false => YRange { lo, hi, zero: None },
        };
        Ok((decades(min(&xs), max(&xs)), y))
    }

    /// Draws the chart on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        register_font()?;
        let ((x0, x1), y_range) = self.ranges()?;
        let (y0, y1, zero) = (y_range.lo, y_range.hi, y_range.zero);
        let at_zero = |v: f64| zero.is_some_and(|z| (v / z - 1.0).abs() < 1e-9);
        let y_label = match zero {
            Some(_) => format!("{} (0 is drawn on the bottom line)", self.y_label),
            None => self.y_label.clone(),
        };
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("drawing the chart: {e:?}");
        root.fill(&WHITE).map_err(err)?;
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FONT, 24))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&y_label)
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| {
                if at_zero(*v) {
                    "0".to_string()
                } else {
                    tick_label(*v)
                }
            })
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 18))
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(200, 200, 200))
            .draw()
            .map_err(err)?;

        for (i, s) in self.series.iter().enumerate() {
            let color = series_color(i);
            let points: Vec<Point> = (s.points.iter())
                .filter(|p| plottable(p.x))
                .filter_map(|p| {
                    Some(Point {
                        y: y_at(p.y, zero)?,
                        ..*p
                    })
                })
                .collect();
            let banded: Vec<&Point> = (s.points.iter())
                .filter(|p| plottable(p.x) && plottable(p.y))
                .filter(|p| p.y_std > 0.0 && p.y_std.is_finite())
                .collect();
            if banded.len() >= 2 {
                let mut outline: Vec<(f64, f64)> =
                    banded.iter().map(|p| (p.x, p.y + p.y_std)).collect();
                outline.extend(banded.iter().rev().map(|p| (p.x, band_low(p))));
                chart
                    .draw_series(std::iter::once(Polygon::new(
                        outline,
                        color.mix(0.18).filled(),
                    )))
                    .map_err(err)?;
            }
            let samples = (s.samples.iter())
                .filter(|(x, _)| plottable(*x))
                .filter_map(|&(x, y)| Some((x, y_at(y, zero)?)))
                .map(|(x, y)| Circle::new((x, y), 2, color.mix(0.35).filled()));
            chart.draw_series(samples).map_err(err)?;
            chart
                .draw_series(LineSeries::new(
                    points.iter().map(|p| (p.x, p.y)),
                    color.stroke_width(2),
                ))
                .map_err(err)?
                .label(s.name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(2))
                });
            chart
                .draw_series(
                    points
                        .iter()
                        .map(|p| Circle::new((p.x, p.y), 3, color.filled())),
                )
                .map_err(err)?;
            let predicted: Vec<(f64, f64)> = (s.predicted.iter())
                .filter(|(x, _)| plottable(*x))
                .filter_map(|&(x, y)| Some((x, y_at(y, zero)?)))
                .collect();
            if !predicted.is_empty() {
                chart
                    .draw_series(DashedLineSeries::new(
                        predicted,
                        7,
                        5,
                        color.stroke_width(2),
                    ))
                    .map_err(err)?
                    .label(format!("{} (predicted)", s.name))
                    .legend(move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (9, 0)], color.stroke_width(2))
                            + PathElement::new(vec![(15, 0), (24, 0)], color.stroke_width(2))
                    });
            }
        }

        if let Some(g) = &self.guide {
            if plottable(g.through.0) && plottable(g.through.1) && g.slope.is_finite() {
                let (gx, gy) = g.through;
                let at = |x: f64| gy * (x / gx).powf(g.slope);
                let n = 32;
                let line: Vec<(f64, f64)> = (0..=n)
                    .map(|i| x0 * (x1 / x0).powf(f64::from(i) / f64::from(n)))
                    .map(|x| (x, at(x)))
                    // Not into the decade of the zero line, if any
                    .filter(|&(_, y)| y >= zero.map_or(y0, |z| z * 10.0) && y <= y1)
                    .collect();
                let grey = RGBColor(90, 90, 90);
                chart
                    .draw_series(DashedLineSeries::new(line, 3, 4, grey.stroke_width(1)))
                    .map_err(err)?
                    .label(g.label.clone())
                    .legend(move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (4, 0)], grey)
                            + PathElement::new(vec![(10, 0), (14, 0)], grey)
                            + PathElement::new(vec![(20, 0), (24, 0)], grey)
                    });
            }
        }

        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT, 15))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()
            .map_err(err)?;
        root.present().map_err(err)?;
        Ok(())
    }

    /// Draws the chart as 8-bit RGB pixels (row-major, top row first).
    pub fn to_rgb8(&self, width: u32, height: u32) -> Result<Vec<u8>> {
        ensure!(width > 0 && height > 0, "empty chart size {width}x{height}");
        let mut pixels = vec![0u8; width as usize * height as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
            self.draw(&root)?;
        }
        Ok(pixels)
    }

    /// Draws the chart as an SVG document.
    pub fn to_svg(&self, width: u32, height: u32) -> Result<String> {
        ensure!(width > 0 && height > 0, "empty chart size {width}x{height}");
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
            self.draw(&root)?;
        }
        Ok(svg)
    }

    /// Writes the chart as a PNG file, atomically (see
    /// [`image_file::write_atomically`]); errors name `path`.
    pub fn write_png(&self, path: &Path, width: u32, height: u32) -> Result<()> {
        let pixels = self
            .to_rgb8(width, height)
            .with_context(|| format!("{}: cannot draw the chart", path.display()))?;
        image_file::write_atomically(path, |w| {
            PngEncoder::new(w)
                .write_image(&pixels, width, height, ExtendedColorType::Rgb8)
                .context("PNG encoding failed")
        })
    }

    /// Writes the chart as an SVG file, atomically (see
    /// [`image_file::write_atomically`]); errors name `path`.
    pub fn write_svg(&self, path: &Path, width: u32, height: u32) -> Result<()> {
        let svg = self
            .to_svg(width, height)
            .with_context(|| format!("{}: cannot draw the chart", path.display()))?;
        image_file::write_atomically(path, |w| {
            std::io::Write::write_all(w, svg.as_bytes())?;
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart() -> LogLogChart {
        let points: Vec<Point> = [1.0, 2.0, 4.0, 8.0, 16.0]
            .iter()
            .map(|&x| Point {
                x,
                y: 0.1 / x,
                y_std: 0.02 / x,
            })
            .collect();
        LogLogChart {
            title: "relMSE against spp".into(),
            x_label: "samples per pixel".into(),
            y_label: "relMSE".into(),
            series: vec![Series {
                name: "nee".into(),
                predicted: points.iter().map(|p| (p.x, 0.9 * p.y)).collect(),
                samples: points.iter().map(|p| (p.x, 1.1 * p.y)).collect(),
                points,
            }],
            guide: Some(Guide {
                label: "slope -1".into(),
                through: (1.0, 0.1),
                slope: -1.0,
            }),
        }
    }

    #[test]
    fn decades_and_tick_labels() {
        assert_eq!(decades(0.3, 2.0), (0.1, 10.0));
        assert_eq!(decades(1.0, 1.0), (1.0, 10.0));
        let (lo, hi) = decades(2e-5, 3e-3);
        assert!((lo - 1e-5).abs() < 1e-20 && (hi - 1e-2).abs() < 1e-17);
        assert_eq!(tick_label(1.0), "1");
        assert_eq!(tick_label(1000.0), "1000");
        assert_eq!(tick_label(0.01), "0.01");
        assert_eq!(tick_label(1e-5), "1e-5");
        assert_eq!(tick_label(1e6), "1e6");
        assert_eq!(tick_label(3.0), "");
    }

    #[test]
    fn draws_the_series_colour_and_text() {
        let c = chart();
        let (w, h) = (640u32, 480u32);
        let px = c.to_rgb8(w, h).unwrap();
        let count = |rgb: RGBColor| {
            px.chunks(3)
                .filter(|p| p[0] == rgb.0 && p[1] == rgb.1 && p[2] == rgb.2)
                .count()
        };
        // The curve's colour, white background, and dark text pixels.
        assert!(count(series_color(0)) > 200, "{}", count(series_color(0)));
        assert!(count(WHITE) > (w * h / 2) as usize);
        let dark = px.chunks(3).filter(|p| p.iter().all(|&v| v < 60)).count();
        assert!(dark > 500, "{dark} dark pixels: no text or axes drawn?");

        let svg = c.to_svg(w, h).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..60.min(svg.len())]);
        for text in [
            "relMSE",
            "samples per pixel",
            "nee",
            "nee (predicted)",
            "slope -1",
        ] {
            assert!(
                svg.contains(&format!(">\n{text}\n<")),
                "no text {text:?} in the SVG"
            );
        }
    }

    #[test]
    fn nothing_to_plot_is_an_error() {
        let mut c = chart();
        for s in &mut c.series {
            for p in &mut s.points {
                p.y = f64::NAN;
            }
            s.predicted.clear();
            s.samples.clear();
        }
        let msg = format!("{:#}", c.to_rgb8(100, 100).unwrap_err());
        assert!(msg.contains("no positive"), "{msg}");
    }

    /// Errors of exactly 0 are drawn on a bottom line labelled 0, one
    /// decade below the lowest positive value (or below 1 when every value
    /// is 0), and the axis label says so.
    #[test]
    fn zeros_are_drawn_on_a_zero_line() {
        let mut some = chart();
        some.series[0].points[4].y = 0.0;
        some.series[0].predicted[4].1 = 0.0;
        some.series[0].samples[4].1 = 0.0;
        let (_, y) = some.ranges().unwrap();
        // The lowest positive value is the band's low end at x = 8,
        // 0.1/8 - 0.02/8 = 0.01 (or just below): its decade is 1e-3 or 1e-2
        let zero = y.zero.unwrap();
        assert!((y.lo / zero - 1.0).abs() < 1e-5, "{y:?}");
        assert!(
            [1e-4, 1e-3].iter().any(|z| (zero / z - 1.0).abs() < 1e-9),
            "{y:?}"
        );
        assert_eq!(y.hi, 1.0);

        let mut all = chart();
        for s in &mut all.series {
            s.points
                .iter_mut()
                .for_each(|p| (p.y, p.y_std) = (0.0, 0.0));
            s.predicted.iter_mut().for_each(|p| p.1 = 0.0);
            s.samples.iter_mut().for_each(|p| p.1 = 0.0);
        }
        let (_, y) = all.ranges().unwrap();
        assert_eq!((y.hi, y.zero), (10.0, Some(0.1)));
        let (w, h) = (640u32, 480u32);
        let px = all.to_rgb8(w, h).unwrap();
        let curve = (px.chunks(3))
            .filter(|p| (p[0], p[1], p[2]) == (31, 119, 180))
            .count();
        assert!(curve > 200, "{curve} pixels of the curve's colour");
        let svg = all.to_svg(w, h).unwrap();
        for text in ["relMSE (0 is drawn on the bottom line)", "0", "1", "10"] {
            assert!(svg.contains(&format!(">\n{text}\n<")), "no text {text:?}");
        }
        // Without zeros, no zero line and no such label
        let (_, y) = chart().ranges().unwrap();
        assert_eq!(y.zero, None);
        assert!(!chart().to_svg(w, h).unwrap().contains("bottom line"));
    }
}
