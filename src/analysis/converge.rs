//! Accuracy against time: the records of a convergence run and every report
//! made from them.
//!
//! A run renders a scene progressively, for one or more variants (settings
//! such as the integrator or the maximum depth) and seeds, and compares each
//! step with a reference. Each comparison is a [`Step`]. From the steps this
//! module computes a [`Summary`] ([`summarise`]): mean and spread over seeds,
//! the error every variant reaches at equal time, the time each takes to
//! reach an equal error, the speed-up against the first variant, and the
//! log-log slope of relMSE against spp ([`loglog_slope`]; -1 for an unbiased
//! Monte Carlo estimator). It writes them as CSV ([`write_csv`]), JSON
//! ([`write_json`]), log-log plots ([`plot`]) and a terminal table
//! ([`table`]). Every file is written atomically
//! ([`crate::io::image_file::write_atomically`]). Nothing here touches the device.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{ensure, Context, Result};
use serde::Serialize;

use crate::analysis::metrics::Metrics;
use crate::analysis::plot::{Guide, LogLogChart, Point, Series};
use crate::io::image_file;

/// The passes of the wavefront, in the order they run: the order of the
/// `ms_<pass>` columns (other pass names follow, sorted).
pub const PASS_ORDER: [&str; 5] = ["generate", "intersect", "shade", "shadow", "accumulate"];

/// One progressive step of one variant and seed, compared with the reference.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Step {
    /// Name of the setting being measured (e.g. `nee`, `bsdf`, `depth=3`).
    pub variant: String,
    /// Random seed of this render.
    pub seed: u32,
    /// Samples per pixel accumulated so far.
    pub spp: u32,
    /// Render time so far in seconds, from the start of this render, without
    /// readback and metrics.
    pub render_seconds: f64,
    /// Time spent reading the film back for this step, in seconds.
    pub readback_seconds: f64,
    /// Time spent computing this step's metrics, in seconds.
    pub metrics_seconds: f64,
    /// GPU time per pass so far, in milliseconds, keyed by pass name.
    pub pass_ms: BTreeMap<String, f64>,
    /// The error figures against the reference.
    pub metrics: Metrics,
    /// The relMSE the film's error estimate predicts (its two half films,
    /// [`crate::render::film`], plus the reference's variance;
    /// [`crate::util::metrics::predicted_rel_mse`]).
    pub predicted_rel_mse: f64,
    /// 1 / (relMSE · render seconds): see [`efficiency`].
    pub efficiency: f64,
}

/// Monte Carlo efficiency: 1 / (relMSE · seconds). Higher is better; for an
/// unbiased renderer it stays roughly constant as samples accumulate, since
/// relMSE falls as 1/time. A relMSE or time of 0 gives infinity.
pub fn efficiency(rel_mse: f64, seconds: f64) -> f64 {
    1.0 / (rel_mse * seconds)
}

/// Mean and sample standard deviation of a set of figures.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Stat {
    /// Arithmetic mean.
    pub mean: f64,
    /// Sample standard deviation (divisor n - 1); 0 for a single value.
    pub std: f64,
}

impl Stat {
    /// The mean and standard deviation of `xs`; NaN for both when `xs` is
    /// empty. A non-finite value makes both non-finite.
    pub fn of(xs: &[f64]) -> Stat {
        let n = xs.len();
        if n == 0 {
            return Stat {
                mean: f64::NAN,
                std: f64::NAN,
            };
        }
        let mean = xs.iter().sum::<f64>() / n as f64;
        let std = if n == 1 {
            0.0
        } else {
            (xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1) as f64).sqrt()
        };
        Stat { mean, std }
    }
}

/// The steps of one variant at one spp, over seeds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SppSummary {
    /// Samples per pixel.
    pub spp: u32,
    /// Steps (seeds) behind these figures.
    pub seeds: usize,
    /// Render seconds.
    pub render_seconds: Stat,
    /// RMSE.
    pub rmse: Stat,
    /// relMSE.
    pub rel_mse: Stat,
    /// Mean bias.
    pub mean_bias: Stat,
    /// Mean FLIP error.
    pub flip: Stat,
    /// Largest absolute difference.
    pub max_abs_diff: Stat,
    /// Predicted relMSE.
    pub predicted_rel_mse: Stat,
    /// Efficiency, 1 / (relMSE · seconds).
    pub efficiency: Stat,
    /// GPU milliseconds per pass (over the steps that report the pass).
    pub pass_ms: BTreeMap<String, Stat>,
}

/// Everything measured for one variant.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VariantSummary {
    /// The variant's name.
    pub variant: String,
    /// Distinct seeds rendered.
    pub seeds: usize,
    /// Per spp, ascending.
    pub steps: Vec<SppSummary>,
    /// Least-squares slope of log relMSE against log spp over every step of
    /// every seed ([`loglog_slope`]): -1 when the error falls as 1/spp.
    pub loglog_slope: f64,
    /// Mean relMSE at [`Summary::equal_time_seconds`], interpolated in
    /// log-log; `None` when that time is before this variant's first step.
    pub rel_mse_at_equal_time: Option<f64>,
    /// Render seconds until the mean relMSE first reaches
    /// [`Summary::equal_error_rel_mse`], interpolated in log-log; `None` when
    /// the first step is already below it (or there is no such error).
    pub time_to_equal_error: Option<f64>,
    /// The first variant's `time_to_equal_error` divided by this variant's:
    /// above 1 means faster than the first variant to the same error.
    pub speedup: Option<f64>,
}

impl VariantSummary {
    /// Mean relMSE against mean render seconds, sorted by time, leaving out
    /// points that are not finite and positive.
    fn error_curve(&self) -> Vec<(f64, f64)> {
        let mut c: Vec<(f64, f64)> = self
            .steps
            .iter()
            .map(|s| (s.render_seconds.mean, s.rel_mse.mean))
            .filter(|&(t, e)| positive(t) && positive(e))
            .collect();
        c.sort_by(|a, b| a.0.total_cmp(&b.0));
        c
    }

    /// Mean render seconds until the mean relMSE first comes down to
    /// `rel_mse`, interpolated in log-log; `None` when the run never reached
    /// it, or its first step was already below it.
    pub fn time_to_reach(&self, rel_mse: f64) -> Option<f64> {
        first_reaching(&self.error_curve(), rel_mse)
    }

    /// The first step (fewest spp) when its mean relMSE is already at or
    /// below `rel_mse` (an error of 0 is below every target), so that the
    /// time to reach it is at most that step's time: what
    /// [`VariantSummary::time_to_reach`] cannot interpolate.
    pub fn first_step_below(&self, rel_mse: f64) -> Option<&SppSummary> {
        self.steps.first().filter(|s| s.rel_mse.mean <= rel_mse)
    }
}

/// The summary of a run: per variant, and the comparisons between them.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Per variant, in the order they first appear in the steps; the first
    /// is the baseline of the speed-ups.
    pub variants: Vec<VariantSummary>,
    /// The common time: the largest mean render time every variant reached.
    pub equal_time_seconds: Option<f64>,
    /// The common error: the smallest mean relMSE every variant reached.
    pub equal_error_rel_mse: Option<f64>,
}

/// Least-squares slope of ln y against ln x.
///
/// Pairs where either value is not finite and positive are left out. Fewer
/// than two usable pairs, or usable x values that are all equal, give NaN.
///
/// # Panics
///
/// If the slices differ in length.
pub fn loglog_slope(xs: &[f64], ys: &[f64]) -> f64 {
    assert_eq!(xs.len(), ys.len(), "loglog_slope: slices differ in length");
    let pts: Vec<(f64, f64)> = xs
        .iter()
        .zip(ys)
        .filter(|(x, y)| positive(**x) && positive(**y))
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if pts.len() < 2 {
        return f64::NAN;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx == 0.0 {
        return f64::NAN;
    }
    sxy / sxx
}

/// Whether a value can be taken the logarithm of.
fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// Linear interpolation between `(x0, y0)` and `(x1, y1)` in log-log space,
/// at `x`.
fn lerp_loglog((x0, y0): (f64, f64), (x1, y1): (f64, f64), x: f64) -> f64 {
    if x0 == x1 {
        return y0;
    }
    let t = (x.ln() - x0.ln()) / (x1.ln() - x0.ln());
    (y0.ln() + t * (y1.ln() - y0.ln())).exp()
}

/// y at `x` on the polyline through `curve` (sorted by x), interpolated in
/// log-log; `None` when `x` lies outside the curve.
fn value_at(curve: &[(f64, f64)], x: f64) -> Option<f64> {
    let first = curve.first()?;
    if x == first.0 {
        return Some(first.1);
    }
    curve
        .windows(2)
        .find(|w| w[0].0 <= x && x <= w[1].0)
        .map(|w| lerp_loglog(w[0], w[1], x))
}

/// The x at which the polyline through `curve` (sorted by x) first comes
/// down to `y`, interpolated in log-log; `None` when the first point is
/// already below `y` or the curve never reaches it.
fn first_reaching(curve: &[(f64, f64)], y: f64) -> Option<f64> {
    let i = curve.iter().position(|p| p.1 <= y)?;
    if i == 0 {
        return (curve[0].1 == y).then_some(curve[0].0);
    }
    let ((x0, y0), (x1, y1)) = (curve[i - 1], curve[i]);
    // Swap the axes: x as a function of y along the segment.
    Some(lerp_loglog((y0, x0), (y1, x1), y))
}

/// Summarises [`Step`]s from any number of variants and seeds.
///
/// Per variant (in order of first appearance) and spp: mean and standard
/// deviation over seeds of every figure and of the time. Between variants,
/// on the curves of mean relMSE against mean render time:
///
/// - the equal time T is the largest time every variant reached (the
///   smallest of their final times), and each variant's relMSE at T is
///   interpolated in log-log;
/// - the equal error E is the smallest relMSE every variant reached (the
///   largest of their smallest errors), and each variant's time to first
///   reach E is interpolated in log-log;
/// - the speed-up of a variant is the first variant's time to E divided by
///   its own.
///
/// Points with a relMSE or time that is not finite and positive are left
/// out of these comparisons.
pub fn summarise(steps: &[Step]) -> Summary {
    let mut order: Vec<&str> = Vec::new();
    let mut groups: BTreeMap<&str, BTreeMap<u32, Vec<&Step>>> = BTreeMap::new();
    for s in steps {
        if !groups.contains_key(s.variant.as_str()) {
            order.push(&s.variant);
        }
        groups
            .entry(&s.variant)
            .or_default()
            .entry(s.spp)
            .or_default()
            .push(s);
    }

    let mut variants: Vec<VariantSummary> = order
        .iter()
        .map(|name| {
            let by_spp = &groups[name];
            let all: Vec<&Step> = by_spp.values().flatten().copied().collect();
            let seeds: BTreeSet<u32> = all.iter().map(|s| s.seed).collect();
            let xs: Vec<f64> = all.iter().map(|s| f64::from(s.spp)).collect();
            let ys: Vec<f64> = all.iter().map(|s| s.metrics.rel_mse).collect();
            VariantSummary {
                variant: (*name).to_string(),
                seeds: seeds.len(),
                steps: by_spp
                    .iter()
                    .map(|(&spp, group)| spp_summary(spp, group))
                    .collect(),
                loglog_slope: loglog_slope(&xs, &ys),
                rel_mse_at_equal_time: None,
                time_to_equal_error: None,
                speedup: None,
            }
        })
        .collect();

    // Mean relMSE against mean time, per variant, sorted by time.
    let curves: Vec<Vec<(f64, f64)>> = variants.iter().map(VariantSummary::error_curve).collect();
    let all_have_points = !curves.is_empty() && curves.iter().all(|c| !c.is_empty());
    let equal_time = all_have_points.then(|| {
        curves
            .iter()
            .map(|c| c.last().unwrap().0)
            .fold(f64::INFINITY, f64::min)
    });
    let equal_error = all_have_points.then(|| {
        curves
            .iter()
            .map(|c| c.iter().map(|p| p.1).fold(f64::INFINITY, f64::min))
            .fold(f64::NEG_INFINITY, f64::max)
    });
    for (v, c) in variants.iter_mut().zip(&curves) {
        v.rel_mse_at_equal_time = equal_time.and_then(|t| value_at(c, t));
        v.time_to_equal_error = equal_error.and_then(|e| first_reaching(c, e));
    }
    let base = variants.first().and_then(|v| v.time_to_equal_error);
    for v in &mut variants {
        v.speedup = match (base, v.time_to_equal_error) {
            (Some(b), Some(t)) if t > 0.0 => Some(b / t),
            _ => None,
        };
    }

    Summary {
        variants,
        equal_time_seconds: equal_time,
        equal_error_rel_mse: equal_error,
    }
}

/// Mean and spread of the steps of one variant at one spp.
fn spp_summary(spp: u32, group: &[&Step]) -> SppSummary {
    let stat = |f: &dyn Fn(&Step) -> f64| Stat::of(&group.iter().map(|s| f(s)).collect::<Vec<_>>());
    let passes: BTreeSet<&str> = group
        .iter()
        .flat_map(|s| s.pass_ms.keys().map(String::as_str))
        .collect();
    SppSummary {
        spp,
        seeds: group.len(),
        render_seconds: stat(&|s| s.render_seconds),
        rmse: stat(&|s| s.metrics.rmse),
        rel_mse: stat(&|s| s.metrics.rel_mse),
        mean_bias: stat(&|s| s.metrics.mean_bias),
        flip: stat(&|s| s.metrics.flip),
        max_abs_diff: stat(&|s| s.metrics.max_abs_diff),
        predicted_rel_mse: stat(&|s| s.predicted_rel_mse),
        efficiency: stat(&|s| s.efficiency),
        pass_ms: passes
            .into_iter()
            .map(|p| {
                let ms: Vec<f64> = group
                    .iter()
                    .filter_map(|s| s.pass_ms.get(p))
                    .copied()
                    .collect();
                (p.to_string(), Stat::of(&ms))
            })
            .collect(),
    }
}

/// Every pass name seen in `steps`, those of [`PASS_ORDER`] first in that
/// order, then the others sorted.
fn pass_names(steps: &[Step]) -> Vec<String> {
    let seen: BTreeSet<&str> = steps
        .iter()
        .flat_map(|s| s.pass_ms.keys().map(String::as_str))
        .collect();
    let mut names: Vec<String> = PASS_ORDER
        .iter()
        .filter(|p| seen.contains(*p))
        .map(|p| p.to_string())
        .collect();
    names.extend(
        seen.iter()
            .filter(|p| !PASS_ORDER.contains(*p))
            .map(|p| p.to_string()),
    );
    names
}

/// The fixed columns of [`write_csv`], before the `ms_<pass>` columns.
pub const CSV_COLUMNS: [&str; 14] = [
    "variant",
    "seed",
    "spp",
    "render_seconds",
    "readback_seconds",
    "metrics_seconds",
    "rmse",
    "rel_mse",
    "mean_bias",
    "flip",
    "max_abs_diff",
    "nonfinite",
    "predicted_rel_mse",
    "efficiency",
];

/// The CSV of [`write_csv`], as text.
///
/// # Errors
///
/// Only if the CSV writer fails, which writing to memory does not.
pub fn csv_string(steps: &[Step]) -> Result<String> {
    let passes = pass_names(steps);
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = CSV_COLUMNS.iter().map(|c| c.to_string()).collect();
    header.extend(passes.iter().map(|p| format!("ms_{p}")));
    w.write_record(&header)?;
    for s in steps {
        let m = &s.metrics;
        let mut row = vec![
            s.variant.clone(),
            s.seed.to_string(),
            s.spp.to_string(),
            s.render_seconds.to_string(),
            s.readback_seconds.to_string(),
            s.metrics_seconds.to_string(),
            m.rmse.to_string(),
            m.rel_mse.to_string(),
            m.mean_bias.to_string(),
            m.flip.to_string(),
            m.max_abs_diff.to_string(),
            m.nonfinite_test.to_string(),
            s.predicted_rel_mse.to_string(),
            s.efficiency.to_string(),
        ];
        row.extend(
            passes
                .iter()
                .map(|p| s.pass_ms.get(p).map(f64::to_string).unwrap_or_default()),
        );
        w.write_record(&row)?;
    }
    let bytes = w.into_inner().context("CSV writer failed")?;
    String::from_utf8(bytes).context("CSV is not UTF-8")
}

/// Writes one CSV row per step (variant, seed and spp), in the order given,
/// atomically.
///
/// Columns: [`CSV_COLUMNS`] (`nonfinite` counts the non-finite values of the
/// test image), then `ms_<pass>` for every pass any step reports, the
/// wavefront's passes first in [`PASS_ORDER`]; a step without that pass has
/// an empty cell. Numbers are written in Rust's shortest round-trip form
/// (`NaN` and `inf` for non-finite ones). Quoting follows RFC 4180 (the `csv`
/// crate), so variant names may hold commas and quotes.
///
/// # Errors
///
/// If the file cannot be written; the message names `path`.
pub fn write_csv(path: &Path, steps: &[Step]) -> Result<()> {
    let text = csv_string(steps)?;
    image_file::write_atomically(path, |w| {
        std::io::Write::write_all(w, text.as_bytes())?;
        Ok(())
    })
}

/// Writes the run as one JSON document, atomically:
/// `{"meta": meta, "summary": summary, "steps": [...]}`. `meta` is whatever
/// the caller records about the run (scene, reference, device). Non-finite
/// numbers become `null`.
///
/// # Errors
///
/// If the file cannot be written; the message names `path`.
pub fn write_json(
    path: &Path,
    steps: &[Step],
    summary: &Summary,
    meta: &serde_json::Value,
) -> Result<()> {
    let bytes = json_bytes(steps, summary, meta)?;
    image_file::write_atomically(path, |w| {
        std::io::Write::write_all(w, &bytes)?;
        Ok(())
    })
}

/// The JSON document of [`write_json`], as bytes.
pub fn json_bytes(steps: &[Step], summary: &Summary, meta: &serde_json::Value) -> Result<Vec<u8>> {
    #[derive(Serialize)]
    struct Doc<'a> {
        meta: &'a serde_json::Value,
        summary: &'a Summary,
        steps: &'a [Step],
    }
    let mut bytes = serde_json::to_vec_pretty(&Doc {
        meta,
        summary,
        steps,
    })
    .context("cannot encode the run as JSON")?;
    bytes.push(b'\n');
    Ok(bytes)
}

/// The file names [`outputs`] writes in its folder: the CSV, the JSON and
/// the plots.
pub fn output_files() -> Vec<&'static str> {
    let mut names = vec!["converge.csv", "converge.json"];
    names.extend(PLOT_FILES);
    names
}

/// Every file of a run, drawn and encoded, to be written together into the
/// folder `dir` (see [`image_file::Outputs::commit`]): `converge.csv`
/// ([`write_csv`]), `converge.json` ([`write_json`]) and the plots
/// ([`plot`]). Nothing is written here, so a run that cannot draw its plots
/// leaves no CSV or JSON behind.
///
/// # Errors
///
/// If there is nothing to plot.
pub fn outputs(
    dir: &Path,
    steps: &[Step],
    summary: &Summary,
    meta: &serde_json::Value,
) -> Result<image_file::Outputs> {
    let mut out = image_file::Outputs::default();
    out.add(&dir.join("converge.csv"), csv_string(steps)?.into_bytes());
    out.add(
        &dir.join("converge.json"),
        json_bytes(steps, summary, meta)?,
    );
    for (path, bytes) in plot_files(dir, steps, summary)? {
        out.add(&path, bytes);
    }
    Ok(out)
}

/// Size of the plots in pixels (PNG) and user units (SVG).
pub const PLOT_SIZE: (u32, u32) = (960, 640);

/// The file names [`plot`] writes in its folder.
pub const PLOT_FILES: [&str; 4] = [
    "relmse_time.png",
    "relmse_time.svg",
    "relmse_spp.png",
    "relmse_spp.svg",
];

/// The two charts of [`plot`]: relMSE against render seconds, and against
/// spp.
pub fn charts(steps: &[Step], summary: &Summary) -> [LogLogChart; 2] {
    let chart = |by_time: bool| {
        let x_of = |s: &SppSummary| {
            if by_time {
                s.render_seconds.mean
            } else {
                f64::from(s.spp)
            }
        };
        let series: Vec<Series> = summary
            .variants
            .iter()
            .map(|v| Series {
                name: v.variant.clone(),
                points: v
                    .steps
                    .iter()
                    .map(|s| Point {
                        x: x_of(s),
                        y: s.rel_mse.mean,
                        y_std: s.rel_mse.std,
                    })
                    .collect(),
                predicted: v
                    .steps
                    .iter()
                    .map(|s| (x_of(s), s.predicted_rel_mse.mean))
                    .collect(),
                samples: if v.seeds > 1 {
                    steps
                        .iter()
                        .filter(|s| s.variant == v.variant)
                        .map(|s| {
                            let x = if by_time {
                                s.render_seconds
                            } else {
                                f64::from(s.spp)
                            };
                            (x, s.metrics.rel_mse)
                        })
                        .collect()
                } else {
                    Vec::new()
                },
            })
            .collect();
        // The slope -1 guide through the first variant's first point.
        let guide = series
            .first()
            .and_then(|s| s.points.iter().find(|p| positive(p.x) && positive(p.y)))
            .map(|p| Guide {
                label: "∝ 1/spp (slope -1)".into(),
                through: (p.x, p.y),
                slope: -1.0,
            });
        let (title, x_label) = if by_time {
            ("relMSE against render time", "render time (s)")
        } else {
            ("relMSE against samples per pixel", "samples per pixel")
        };
        LogLogChart {
            title: title.into(),
            x_label: x_label.into(),
            y_label: "relMSE".into(),
            series,
            guide,
        }
    };
    [chart(true), chart(false)]
}

/// Draws the log-log plots of a run into the folder `dir`, as PNG and SVG
/// (the files of [`PLOT_FILES`]): relMSE against render seconds, and relMSE
/// against spp. One curve per variant through the mean over seeds, with a
/// band of ±1 standard deviation and a dot per seed when there are several
/// seeds; the predicted relMSE dashed in the same colour; and a grey dashed
/// slope -1 guide (relMSE ∝ 1/spp) through the first variant's first point.
/// Returns the paths written.
///
/// Every file is drawn before any is written, and all are written together
/// (see [`image_file::Outputs`]).
///
/// # Errors
///
/// If `dir` is not a folder, there is nothing positive to plot, or a file
/// cannot be written.
pub fn plot(dir: &Path, steps: &[Step], summary: &Summary) -> Result<Vec<PathBuf>> {
    ensure!(
        dir.is_dir(),
        "{}: plot directory does not exist",
        dir.display()
    );
    let files = plot_files(dir, steps, summary)?;
    let written = files.iter().map(|(path, _)| path.clone()).collect();
    let mut outputs = image_file::Outputs::default();
    for (path, bytes) in files {
        outputs.add(&path, bytes);
    }
    outputs.commit()?;
    Ok(written)
}

/// The plots of [`plot`], drawn and encoded: `(path in dir, bytes)`.
fn plot_files(dir: &Path, steps: &[Step], summary: &Summary) -> Result<Vec<(PathBuf, Vec<u8>)>> {
    ensure!(!steps.is_empty(), "no steps to plot");
    let (w, h) = PLOT_SIZE;
    let [time, spp] = charts(steps, summary);
    let mut files = Vec::new();
    for (chart, stem) in [(&time, "relmse_time"), (&spp, "relmse_spp")] {
        let pixels = chart.to_rgb8(w, h)?;
        let mut png = Vec::new();
        {
            use image::ImageEncoder;
            image::codecs::png::PngEncoder::new(&mut png)
                .write_image(&pixels, w, h, image::ExtendedColorType::Rgb8)
                .context("PNG encoding failed")?;
        }
        files.push((dir.join(format!("{stem}.png")), png));
        let svg = chart.to_svg(w, h)?;
        files.push((dir.join(format!("{stem}.svg")), svg.into_bytes()));
    }
    Ok(files)
}

/// A figure in scientific notation with 3 significant digits, `-` when
/// absent or not finite.
fn sci(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.2e}"),
        Some(x) if x.is_nan() => "NaN".into(),
        Some(x) => format!("{x}"),
        None => "-".into(),
    }
}

/// The table that ends a run: per variant, its final step (largest spp) —
/// spp, seconds, relMSE ± std over seeds, FLIP, predicted relMSE, efficiency
/// and log-log slope — then relMSE at the equal time, time to the equal
/// error and the speed-up against the first variant. The first lines say
/// what the equal time and error are.
pub fn table(summary: &Summary) -> String {
    let mut out = String::new();
    if summary.variants.is_empty() {
        out.push_str("no steps\n");
        return out;
    }
    let _ = writeln!(
        out,
        "equal time: {} s (the longest every variant ran); equal error: relMSE {} (the lowest every variant reached)",
        summary
            .equal_time_seconds
            .map_or("-".into(), |t| format!("{t:.3}")),
        sci(summary.equal_error_rel_mse)
    );
    let header = [
        "variant",
        "spp",
        "seconds",
        "relMSE ± std",
        "FLIP",
        "predicted",
        "efficiency",
        "slope",
        "relMSE@T",
        "time to E",
        "speed-up",
    ];
    let rows: Vec<Vec<String>> = summary
        .variants
        .iter()
        .map(|v| {
            let last = v.steps.last();
            vec![
                v.variant.clone(),
                last.map_or("-".into(), |s| s.spp.to_string()),
                last.map_or("-".into(), |s| format!("{:.3}", s.render_seconds.mean)),
                last.map_or("-".into(), |s| {
                    format!(
                        "{} ± {}",
                        sci(Some(s.rel_mse.mean)),
                        sci(Some(s.rel_mse.std))
                    )
                }),
                last.map_or("-".into(), |s| format!("{:.4}", s.flip.mean)),
                sci(last.map(|s| s.predicted_rel_mse.mean)),
                sci(last.map(|s| s.efficiency.mean)),
                if v.loglog_slope.is_finite() {
                    format!("{:.3}", v.loglog_slope)
                } else {
                    "-".into()
                },
                sci(v.rel_mse_at_equal_time),
                v.time_to_equal_error
                    .map_or("-".into(), |t| format!("{t:.3} s")),
                v.speedup.map_or("-".into(), |s| format!("{s:.2}x")),
            ]
        })
        .collect();
    let widths: Vec<usize> = (0..header.len())
        .map(|i| {
            rows.iter()
                .map(|r| r[i].chars().count())
                .chain(std::iter::once(header[i].chars().count()))
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cells: &[String]| {
        let mut s = String::new();
        for (i, c) in cells.iter().enumerate() {
            let pad = widths[i] - c.chars().count();
            if i == 0 {
                s.push_str(c);
                s.push_str(&" ".repeat(pad));
            } else {
                s.push_str("  ");
                s.push_str(&" ".repeat(pad));
                s.push_str(c);
            }
        }
        s.trim_end().to_string()
    };
    let header: Vec<String> = header.iter().map(|h| h.to_string()).collect();
    let _ = writeln!(out, "{}", line(&header));
    let _ = writeln!(
        out,
        "{}",
        "-".repeat(widths.iter().sum::<usize>() + 2 * (widths.len() - 1))
    );
    for r in &rows {
        let _ = writeln!(out, "{}", line(r));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metrics(rel_mse: f64) -> Metrics {
        Metrics {
            rmse: rel_mse.sqrt(),
            rel_mse,
            mean_bias: 0.0,
            flip: 0.1 * rel_mse.sqrt(),
            max_abs_diff: 1.0,
            nonfinite_test: 0,
            nonfinite_reference: 0,
        }
    }

    /// Steps of a variant whose relMSE is `c / spp` and time `k · spp`,
    /// for three seeds whose relMSE is 0.9, 1 and 1.1 times that and whose
    /// time is 0.95, 1 and 1.05 times (so the means are exact).
    fn variant(name: &str, k: f64, spps: &[u32]) -> Vec<Step> {
        let c = 0.5;
        let mut steps = Vec::new();
        for seed in 0..3u32 {
            let e_scale = 0.9 + 0.1 * f64::from(seed);
            let t_scale = 0.95 + 0.05 * f64::from(seed);
            for &spp in spps {
                let rel = c / f64::from(spp) * e_scale;
                let t = k * f64::from(spp) * t_scale;
                steps.push(Step {
                    variant: name.into(),
                    seed,
                    spp,
                    render_seconds: t,
                    readback_seconds: 0.001,
                    metrics_seconds: 0.002,
                    pass_ms: [("shade", 600.0 * t), ("generate", 100.0 * t)]
                        .iter()
                        .map(|(p, ms)| (p.to_string(), *ms))
                        .collect(),
                    metrics: metrics(rel),
                    predicted_rel_mse: 0.95 * rel,
                    efficiency: efficiency(rel, t),
                });
            }
        }
        steps
    }

    fn powers(base: u32, n: u32) -> Vec<u32> {
        (0..n).map(|i| base.pow(i)).collect()
    }

    /// A: 0.01 s per spp at powers of 2 up to 1024; B: exactly twice as
    /// fast (0.005 s per spp), at powers of 3 up to 2187, so that every
    /// comparison needs interpolation.
    fn two_variants() -> Vec<Step> {
        let mut steps = variant("A", 0.01, &powers(2, 11));
        steps.extend(variant("B, fast", 0.005, &powers(3, 8)));
        steps
    }

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs()
    }

    #[test]
    fn loglog_slope_of_one_over_spp_is_minus_one() {
        let xs: Vec<f64> = powers(2, 12).iter().map(|&x| f64::from(x)).collect();
        let ys: Vec<f64> = xs.iter().map(|x| 0.37 / x).collect();
        assert!((loglog_slope(&xs, &ys) + 1.0).abs() < 1e-9);
        let ys2: Vec<f64> = xs.iter().map(|x| 3.0 * x.powf(-0.5)).collect();
        assert!((loglog_slope(&xs, &ys2) + 0.5).abs() < 1e-9);
        // Unusable pairs are skipped; too few pairs give NaN.
        let mut xs3 = xs.clone();
        let mut ys3 = ys.clone();
        xs3.push(0.0);
        ys3.push(1.0);
        xs3.push(5.0);
        ys3.push(f64::NAN);
        assert!((loglog_slope(&xs3, &ys3) + 1.0).abs() < 1e-9);
        assert!(loglog_slope(&[1.0], &[1.0]).is_nan());
        assert!(loglog_slope(&[2.0, 2.0], &[1.0, 3.0]).is_nan());
    }

    #[test]
    fn stat_mean_and_sample_std() {
        let s = Stat::of(&[0.9, 1.0, 1.1]);
        assert!(
            close(s.mean, 1.0, 1e-15) && close(s.std, 0.1, 1e-12),
            "{s:?}"
        );
        assert_eq!(
            Stat::of(&[3.0]),
            Stat {
                mean: 3.0,
                std: 0.0
            }
        );
        assert!(Stat::of(&[]).mean.is_nan());
    }

    #[test]
    fn summary_of_a_variant_twice_as_fast() {
        let steps = two_variants();
        let s = summarise(&steps);
        assert_eq!(s.variants.len(), 2);
        let (a, b) = (&s.variants[0], &s.variants[1]);
        assert_eq!((a.variant.as_str(), b.variant.as_str()), ("A", "B, fast"));
        assert_eq!((a.seeds, b.seeds), (3, 3));
        assert_eq!(a.steps.len(), 11);
        assert_eq!(b.steps.len(), 8);

        // Per spp: mean and spread over the three seeds.
        let a16 = a.steps.iter().find(|x| x.spp == 16).unwrap();
        assert_eq!(a16.seeds, 3);
        assert!(close(a16.rel_mse.mean, 0.5 / 16.0, 1e-12), "{a16:?}");
        assert!(close(a16.rel_mse.std, 0.05 / 16.0, 1e-9), "{a16:?}");
        assert!(close(a16.render_seconds.mean, 0.16, 1e-12));
        assert!(close(a16.render_seconds.std, 0.008, 1e-9));
        assert!(close(a16.predicted_rel_mse.mean, 0.95 * 0.5 / 16.0, 1e-12));
        assert!(close(a16.pass_ms["shade"].mean, 96.0, 1e-12));
        assert_eq!(a16.pass_ms.len(), 2);

        // Slopes of exact 1/spp data.
        assert!((a.loglog_slope + 1.0).abs() < 1e-9);
        assert!((b.loglog_slope + 1.0).abs() < 1e-9);

        // Equal time: A's final 10.24 s (B ran to 10.935 s). There A has
        // relMSE 0.5/1024 and B, at 2048 spp, half of it.
        let t = s.equal_time_seconds.unwrap();
        assert!(close(t, 10.24, 1e-12), "{t}");
        assert!(close(a.rel_mse_at_equal_time.unwrap(), 0.5 / 1024.0, 1e-9));
        assert!(close(b.rel_mse_at_equal_time.unwrap(), 0.5 / 2048.0, 1e-9));

        // Equal error: A's lowest, 0.5/1024, reached by A at 10.24 s and by
        // B (between 729 and 2187 spp) at 5.12 s.
        let e = s.equal_error_rel_mse.unwrap();
        assert!(close(e, 0.5 / 1024.0, 1e-12), "{e}");
        assert!(close(a.time_to_equal_error.unwrap(), 10.24, 1e-9));
        assert!(close(b.time_to_equal_error.unwrap(), 5.12, 1e-9));
        assert!((a.speedup.unwrap() - 1.0).abs() < 1e-12);
        assert!((b.speedup.unwrap() - 2.0).abs() < 1e-6, "{:?}", b.speedup);

        // Swapping the order makes B the baseline: A is then half as fast.
        let mut swapped = variant("B, fast", 0.005, &powers(3, 8));
        swapped.extend(variant("A", 0.01, &powers(2, 11)));
        let s2 = summarise(&swapped);
        assert!((s2.variants[1].speedup.unwrap() - 0.5).abs() < 1e-6);
    }

    #[test]
    fn interpolation_limits() {
        let curve = [(1.0, 1.0), (10.0, 0.1), (100.0, 0.01)];
        assert_eq!(value_at(&curve, 1.0), Some(1.0));
        assert!(close(
            value_at(&curve, 1000f64.sqrt()).unwrap(),
            0.1f64.powf(1.5),
            1e-12
        ));
        assert_eq!(value_at(&curve, 0.5), None);
        assert_eq!(value_at(&curve, 101.0), None);
        assert!(close(first_reaching(&curve, 0.05).unwrap(), 20.0, 1e-12));
        assert_eq!(first_reaching(&curve, 1.0), Some(1.0));
        assert_eq!(first_reaching(&curve, 2.0), None);
        assert_eq!(first_reaching(&curve, 0.001), None);
        // A variant that starts after the other has finished has no value
        // at the equal time.
        let mut steps = variant("quick", 0.001, &[1, 2, 4]);
        steps.extend(variant("slow", 1.0, &[1, 2, 4]));
        let s = summarise(&steps);
        assert!(close(s.equal_time_seconds.unwrap(), 0.004, 1e-12));
        assert_eq!(s.variants[1].rel_mse_at_equal_time, None);
        assert!(s.variants[0].rel_mse_at_equal_time.is_some());
        // No steps: an empty summary.
        let empty = summarise(&[]);
        assert!(empty.variants.is_empty() && empty.equal_time_seconds.is_none());
        assert_eq!(table(&empty), "no steps\n");
    }

    #[test]
    fn csv_has_the_columns_and_one_row_per_step() {
        let mut steps = two_variants();
        steps[0].pass_ms.insert("shadow".into(), 1.5);
        steps[1].pass_ms.insert("zzz_extra".into(), 2.5);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.csv");
        write_csv(&path, &steps).unwrap();
        let mut r = csv::Reader::from_path(&path).unwrap();
        let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
        let mut want: Vec<String> = CSV_COLUMNS.iter().map(|c| c.to_string()).collect();
        for p in ["generate", "shade", "shadow", "zzz_extra"] {
            want.push(format!("ms_{p}"));
        }
        assert_eq!(header, want);
        let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
        assert_eq!(rows.len(), steps.len());
        let col = |name: &str| header.iter().position(|h| h == name).unwrap();
        for (row, step) in rows.iter().zip(&steps) {
            assert_eq!(row.len(), header.len());
            assert_eq!(&row[col("variant")], step.variant);
            assert_eq!(row[col("spp")].parse::<u32>().unwrap(), step.spp);
            assert_eq!(row[col("seed")].parse::<u32>().unwrap(), step.seed);
            // Shortest round-trip form: the numbers come back exactly.
            assert_eq!(
                row[col("rel_mse")].parse::<f64>().unwrap(),
                step.metrics.rel_mse
            );
            assert_eq!(
                row[col("efficiency")].parse::<f64>().unwrap(),
                step.efficiency
            );
        }
        assert_eq!(&rows[0][col("ms_shadow")], "1.5");
        assert_eq!(&rows[1][col("ms_shadow")], "");
        assert_eq!(&rows[1][col("ms_zzz_extra")], "2.5");
        // The comma in "B, fast" is quoted in the file.
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\"B, fast\""));
        assert_eq!(text.lines().count(), steps.len() + 1);
    }

    #[test]
    fn json_holds_meta_summary_and_steps() {
        let mut steps = two_variants();
        steps[0].metrics.rel_mse = f64::NAN;
        let summary = summarise(&steps);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.json");
        let meta = serde_json::json!({"scene": "cornell.toml", "device": "llvmpipe"});
        write_json(&path, &steps, &summary, &meta).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        assert_eq!(v["meta"], meta);
        assert_eq!(v["steps"].as_array().unwrap().len(), steps.len());
        assert!(v["steps"][0]["metrics"]["rel_mse"].is_null());
        assert_eq!(v["steps"][1]["spp"].as_u64(), Some(2));
        let num = |v: &serde_json::Value| v.as_f64().unwrap();
        assert!(close(
            num(&v["steps"][1]["pass_ms"]["shade"]),
            steps[1].pass_ms["shade"],
            1e-12
        ));
        let b = &v["summary"]["variants"][1];
        assert_eq!(b["variant"], "B, fast");
        assert!((b["speedup"].as_f64().unwrap() - 2.0).abs() < 1e-6);
        assert!(close(
            num(&v["summary"]["variants"][0]["steps"][3]["rel_mse"]["std"]),
            summary.variants[0].steps[3].rel_mse.std,
            1e-12
        ));
    }

    #[test]
    fn plots_are_valid_png_and_svg() {
        let steps = two_variants();
        let summary = summarise(&steps);
        let dir = tempfile::tempdir().unwrap();
        let written = plot(dir.path(), &steps, &summary).unwrap();
        assert_eq!(written.len(), 4);
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let mut want: Vec<String> = PLOT_FILES.iter().map(|f| f.to_string()).collect();
        want.sort();
        assert_eq!(names, want);
        for stem in ["relmse_time", "relmse_spp"] {
            let png = image::open(dir.path().join(format!("{stem}.png")))
                .unwrap()
                .into_rgb8();
            assert_eq!(png.dimensions(), PLOT_SIZE);
            // Both variants' colours are on the chart.
            for i in 0..2 {
                let c = crate::analysis::plot::series_color(i);
                let n = png.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count();
                assert!(n > 100, "{stem}: colour {i} has {n} pixels");
            }

            let svg = std::fs::read_to_string(dir.path().join(format!("{stem}.svg"))).unwrap();
            assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"));
            let doc = roxmltree::Document::parse(&svg).unwrap();
            let root = doc.root_element();
            assert_eq!(root.tag_name().name(), "svg");
            assert_eq!(root.attribute("width"), Some("960"));
            let texts: Vec<&str> = doc
                .descendants()
                .filter(|n| n.has_tag_name("text"))
                .filter_map(|n| n.text())
                .map(str::trim)
                .collect();
            for want in [
                "relMSE",
                "A",
                "B, fast",
                "B, fast (predicted)",
                "∝ 1/spp (slope -1)",
            ] {
                assert!(
                    texts.contains(&want),
                    "{stem}: no text {want:?} in {texts:?}"
                );
            }
            let x_label = if stem == "relmse_time" {
                "render time (s)"
            } else {
                "samples per pixel"
            };
            assert!(texts.contains(&x_label), "{stem}: {texts:?}");
            let lines = doc
                .descendants()
                .filter(|n| n.has_tag_name("polyline") || n.has_tag_name("path"))
                .count();
            assert!(lines > 10, "{stem}: only {lines} lines");
        }

        // A missing folder is an error, and nothing is written.
        let missing = dir.path().join("nope");
        assert!(plot(&missing, &steps, &summary).is_err());
        assert!(!missing.exists());
        assert!(plot(dir.path(), &[], &summary).is_err());
    }

    #[test]
    fn table_lists_each_variant() {
        let s = summarise(&two_variants());
        let t = table(&s);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 5, "{t}");
        assert!(lines[0].contains("equal time: 10.240 s"), "{t}");
        assert!(lines[0].contains("4.88e-4"), "{t}");
        assert!(lines[1].starts_with("variant") && lines[1].contains("speed-up"));
        assert!(
            lines[3].starts_with("A ") && lines[3].contains("1.00x"),
            "{t}"
        );
        assert!(
            lines[3].contains("1024") && lines[3].contains("-1.000"),
            "{t}"
        );
        assert!(
            lines[4].starts_with("B, fast") && lines[4].contains("2.00x"),
            "{t}"
        );
        assert!(
            lines[4].contains("2187") && lines[4].contains("5.120 s"),
            "{t}"
        );
        // Columns line up: every row has the header's width or less.
        let width = lines[2].chars().count();
        assert!(lines[1..].iter().all(|l| l.chars().count() <= width));
    }

    #[test]
    fn efficiency_is_inverse_error_times_time() {
        assert_eq!(efficiency(0.01, 2.0), 50.0);
        assert_eq!(efficiency(0.0, 2.0), f64::INFINITY);
    }
}
