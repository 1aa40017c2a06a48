//! `lancer compare`: two image files compared, with the figures of
//! [`Metrics`], the per-pixel [`z_test`] when a variance image is given, a
//! FLIP heat map and a JSON report, and a pass/fail verdict against
//! thresholds ([`CompareReport`]). Every input and output is checked before
//! anything is written ([`compare_files`]).

use std::fmt;
use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context, Result};
use serde::Serialize;

use crate::analysis::metrics::{check_png_path, Metrics};
use crate::analysis::ztest::{z_test, ZTest};
use crate::io::image_file;
use crate::io::run_files::RunFiles;

/// The default significance level of the z-test in [`compare_files`].
pub const DEFAULT_ALPHA: f64 = 0.01;

/// Where the variance image of `image` is looked for when none is named:
/// the same folder and file stem, with the extension `.var.exr`
/// (`ref.exr` -> `ref.var.exr`). It holds, per channel, the variance of the
/// pixel's mean (sample variance / sample count), as linear 32-bit EXR.
pub fn variance_path(image: &Path) -> PathBuf {
    let stem = image
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    image.with_file_name(format!("{stem}.var.exr"))
}

/// What `lancer compare IMAGE REFERENCE` was asked to do.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareOptions {
    /// The image under test (.png or .exr).
    pub image: PathBuf,
    /// The reference image (.png or .exr).
    pub reference: PathBuf,
    /// Variance of the test image's mean, per channel (`--var`, an EXR).
    /// When given, the per-pixel z-test runs.
    pub var: Option<PathBuf>,
    /// Variance of the reference's mean. When `None`, the z-test uses
    /// [`variance_path`] of the reference if that file exists, and takes the
    /// reference as exact (variance 0) otherwise; the report says which.
    pub reference_var: Option<PathBuf>,
    /// Significance level of the z-test for the whole image (Šidák-corrected
    /// per pixel, see [`z_test`]).
    pub alpha: f64,
    /// Where to write the FLIP heat map (a .png).
    pub heatmap: Option<PathBuf>,
    /// Fail when relMSE is above this.
    pub max_relmse: Option<f64>,
    /// Fail when the mean FLIP error is above this.
    pub max_flip: Option<f64>,
    /// Where to write the report as JSON.
    pub json: Option<PathBuf>,
}

impl CompareOptions {
    /// Compares `image` with `reference`: no z-test, no files written, no
    /// thresholds, alpha [`DEFAULT_ALPHA`].
    pub fn new(image: impl Into<PathBuf>, reference: impl Into<PathBuf>) -> Self {
        CompareOptions {
            image: image.into(),
            reference: reference.into(),
            var: None,
            reference_var: None,
            alpha: DEFAULT_ALPHA,
            heatmap: None,
            max_relmse: None,
            max_flip: None,
            json: None,
        }
    }
}

/// One of the `(x, y)` pixels that the z-test found least likely.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WorstPixel {
    /// Column, from the left.
    pub x: u32,
    /// Row, from the top.
    pub y: u32,
    /// The pixel's p-value (see [`z_test`]).
    pub p: f64,
}

/// The z-test part of a [`CompareReport`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ZTestSummary {
    /// The test image's variance file.
    pub variance: String,
    /// The reference's variance file; `None` when the reference was taken as
    /// exact (variance 0).
    pub reference_variance: Option<String>,
    /// Significance level for the whole image.
    pub alpha: f64,
    /// Šidák-corrected per-pixel level.
    pub alpha_per_pixel: f64,
    /// Pixels compared.
    pub pixels: usize,
    /// Pixels that passed.
    pub passed: usize,
    /// `passed / pixels`.
    pub pass_fraction: f64,
    /// `(mean test - mean reference) / |mean reference|` over finite pixels.
    pub mean_rel_diff: f64,
    /// Pixels with a non-finite mean or variance (they fail).
    pub nonfinite: usize,
    /// Up to 10 pixels with the lowest p-values, lowest first.
    pub worst: Vec<WorstPixel>,
}

impl ZTestSummary {
    /// Summarises `z`, run on an image `width` pixels wide.
    pub fn new(
        z: &ZTest,
        width: u32,
        alpha: f64,
        variance: String,
        reference_variance: Option<String>,
    ) -> Self {
        let w = width.max(1) as usize;
        ZTestSummary {
            variance,
            reference_variance,
            alpha,
            alpha_per_pixel: z.alpha_per_pixel,
            pixels: z.pixels,
            passed: z.passed,
            pass_fraction: z.pass_fraction,
            mean_rel_diff: z.mean_rel_diff,
            nonfinite: z.nonfinite,
            worst: z
                .worst
                .iter()
                .map(|&(i, p)| WorstPixel {
                    x: (i % w) as u32,
                    y: (i / w) as u32,
                    p,
                })
                .collect(),
        }
    }

    /// Whether every pixel passed: the verdict at level `alpha`.
    pub fn all_passed(&self) -> bool {
        self.passed == self.pixels
    }
}

/// One pass/fail check of [`CompareReport::checks`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Check {
    /// What was checked, with the figures, e.g. `relMSE 1.2e-3 <= 1e-2`.
    pub what: String,
    /// Whether it held.
    pub passed: bool,
}

/// What `lancer compare` found: the figures for two images, and the z-test
/// when a variance image was given.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CompareReport {
    /// The image under test.
    pub image: String,
    /// The reference.
    pub reference: String,
    /// Width of both images in pixels.
    pub width: u32,
    /// Height of both images in pixels.
    pub height: u32,
    /// Samples per pixel of the image, when lancer wrote it (read from
    /// its metadata).
    pub image_spp: Option<u32>,
    /// Samples per pixel of the reference, when lancer wrote it.
    pub reference_spp: Option<u32>,
    /// The error figures.
    pub metrics: Metrics,
    /// The per-pixel z-test, when a variance image was given.
    pub z_test: Option<ZTestSummary>,
}

impl CompareReport {
    /// The checks behind [`CompareReport::passes`], each with its figures:
    ///
    /// - neither image holds a NaN or an infinity;
    /// - relMSE <= `max_relmse`, when given;
    /// - mean FLIP <= `max_flip`, when given;
    /// - every pixel passes the z-test, when it ran.
    ///
    /// A NaN figure fails its threshold.
    pub fn checks(&self, max_relmse: Option<f64>, max_flip: Option<f64>) -> Vec<Check> {
        let m = &self.metrics;
        let mut checks = vec![Check {
            what: format!(
                "finite values: {} non-finite in the image, {} in the reference",
                m.nonfinite_test, m.nonfinite_reference
            ),
            passed: m.nonfinite_test == 0 && m.nonfinite_reference == 0,
        }];
        if let Some(max) = max_relmse {
            checks.push(Check {
                what: format!("relMSE {} <= {max}", sci(m.rel_mse)),
                passed: m.rel_mse <= max,
            });
        }
        if let Some(max) = max_flip {
            checks.push(Check {
                what: format!("FLIP {:.6} <= {max}", m.flip),
                passed: m.flip <= max,
            });
        }
        if let Some(z) = &self.z_test {
            checks.push(Check {
                what: format!(
                    "z-test: {}/{} pixels pass at alpha {}",
                    z.passed, z.pixels, z.alpha
                ),
                passed: z.all_passed(),
            });
        }
        checks
    }

    /// Whether the test image passes: every check of
    /// [`CompareReport::checks`] holds.
    pub fn passes(&self, max_relmse: Option<f64>, max_flip: Option<f64>) -> bool {
        self.checks(max_relmse, max_flip).iter().all(|c| c.passed)
    }

    /// What `lancer compare` prints: the report, a line per check of
    /// [`CompareReport::checks`] (`[pass]` or `[FAIL]`), and the verdict of
    /// [`CompareReport::passes`], `PASS` or `FAIL` (no final newline).
    pub fn verdict(&self, max_relmse: Option<f64>, max_flip: Option<f64>) -> String {
        let mut text = format!("{self}\n\n");
        for check in self.checks(max_relmse, max_flip) {
            let mark = if check.passed { "pass" } else { "FAIL" };
            text += &format!("  [{mark}] {}\n", check.what);
        }
        text += if self.passes(max_relmse, max_flip) {
            "PASS"
        } else {
            "FAIL"
        };
        text
    }
}

/// A figure in scientific notation with 4 significant digits.
fn sci(x: f64) -> String {
    format!("{x:.3e}")
}

impl fmt::Display for CompareReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = &self.metrics;
        writeln!(
            f,
            "image      {} ({}x{}{})",
            self.image,
            self.width,
            self.height,
            self.image_spp
                .map(|n| format!(", {n} spp"))
                .unwrap_or_default()
        )?;
        writeln!(
            f,
            "reference  {}{}",
            self.reference,
            self.reference_spp
                .map(|n| format!(" ({n} spp)"))
                .unwrap_or_default()
        )?;
        writeln!(f)?;
        writeln!(f, "  {:<14} {:>12}", "metric", "value")?;
        writeln!(f, "  {:<14} {:>12}", "RMSE", sci(m.rmse))?;
        writeln!(f, "  {:<14} {:>12}", "relMSE", sci(m.rel_mse))?;
        writeln!(
            f,
            "  {:<14} {:>12}",
            "mean bias",
            format!("{:+.3e}", m.mean_bias)
        )?;
        writeln!(f, "  {:<14} {:>12}", "FLIP (LDR)", format!("{:.6}", m.flip))?;
        writeln!(f, "  {:<14} {:>12}", "max |a-b|", sci(m.max_abs_diff))?;
        write!(
            f,
            "  {:<14} {:>12}",
            "non-finite",
            format!("{} / {}", m.nonfinite_test, m.nonfinite_reference)
        )?;
        write!(f, "   (image / reference)")?;
        if let Some(z) = &self.z_test {
            writeln!(f)?;
            writeln!(f)?;
            writeln!(
                f,
                "z-test: {}/{} pixels pass ({:.3}%), alpha {} (per pixel {:.3e})",
                z.passed,
                z.pixels,
                100.0 * z.pass_fraction,
                z.alpha,
                z.alpha_per_pixel
            )?;
            writeln!(
                f,
                "  variance {}; reference variance {}",
                z.variance,
                z.reference_variance
                    .as_deref()
                    .unwrap_or("none (reference taken as exact)")
            )?;
            writeln!(
                f,
                "  mean relative difference {:+.4}%",
                100.0 * z.mean_rel_diff
            )?;
            if z.nonfinite > 0 {
                writeln!(f, "  non-finite pixels: {}", z.nonfinite)?;
            }
            write!(f, "  worst pixels (x,y) p:")?;
            for w in &z.worst {
                write!(f, " ({},{}) {:.1e}", w.x, w.y, w.p)?;
            }
        }
        Ok(())
    }
}

/// Reads an image and checks that it is `width` x `height`.
fn read_sized(path: &Path, what: &str, width: u32, height: u32) -> Result<Vec<f32>> {
    let (w, h, rgb) = image_file::read_image(path)?;
    ensure!(
        (w, h) == (width, height),
        "size mismatch: the {what} {} is {w}x{h}, the image is {width}x{height}",
        path.display()
    );
    Ok(rgb)
}

/// The JSON file [`compare_files`] writes: the report, the thresholds and the
/// verdict.
#[derive(Serialize)]
struct CompareJson<'a> {
    #[serde(flatten)]
    report: &'a CompareReport,
    max_relmse: Option<f64>,
    max_flip: Option<f64>,
    checks: Vec<Check>,
    passed: bool,
}

/// Everything `lancer compare` does but printing: reads both images (and the
/// variance images), computes the [`Metrics`], runs the z-test when
/// `opts.var` is given, writes the FLIP heat map and the JSON report (the
/// report plus the thresholds, each check and the verdict) when asked.
///
/// Every input and output is checked before anything is written: the files
/// exist and are readable images of one size, the thresholds and alpha make
/// sense, each output's folder exists, and no output would overwrite an input
/// or another output. Each file is written atomically; if the JSON cannot be
/// written after the heat map was, the heat map is removed again, so an
/// error leaves no new file behind.
///
/// # Errors
///
/// Any of the above, with a message naming the file and the problem.
pub fn compare_files(opts: &CompareOptions) -> Result<CompareReport> {
    ensure!(
        opts.alpha > 0.0 && opts.alpha < 1.0,
        "alpha must lie strictly between 0 and 1, not {}",
        opts.alpha
    );
    for (name, value) in [
        ("CompareOptions::max_relmse", opts.max_relmse),
        ("CompareOptions::max_flip", opts.max_flip),
    ] {
        if let Some(v) = value {
            ensure!(
                v.is_finite() && v >= 0.0,
                "{name} must be a finite number >= 0, not {v}"
            );
        }
    }
    // Every file before any is read: no output names another or an input
    let mut files = RunFiles::default();
    files
        .input(&opts.image, "the image")
        .input(&opts.reference, "the reference");
    if let Some(path) = &opts.var {
        files.input(path, "the image's variance");
    }
    // The reference's variance beside it is read when it exists
    let beside = Some(variance_path(&opts.reference)).filter(|p| p.is_file());
    if let Some(path) = opts.reference_var.as_ref().or(beside.as_ref()) {
        files.input(path, "the reference's variance");
    }
    if let Some(path) = &opts.heatmap {
        check_png_path(path)?;
        files.output(path, "the FLIP heat map (CompareOptions::heatmap)");
    }
    if let Some(path) = &opts.json {
        files.output(path, "the JSON report (CompareOptions::json)");
    }
    files.check()?;

    let (width, height, test) = image_file::read_image(&opts.image)?;
    let (rw, rh, reference) = image_file::read_image(&opts.reference)?;
    if (rw, rh) != (width, height) {
        bail!(
            "size mismatch: the image {} is {width}x{height} but the reference {} is {rw}x{rh}",
            opts.image.display(),
            opts.reference.display()
        );
    }

    let z_test = match &opts.var {
        None => None,
        Some(var_path) => {
            let var = read_sized(var_path, "variance image", width, height)?;
            let ref_var_path = match &opts.reference_var {
                Some(p) => Some(p.clone()),
                None => Some(variance_path(&opts.reference)).filter(|p| p.is_file()),
            };
            let ref_var = match &ref_var_path {
                Some(p) => read_sized(p, "reference variance image", width, height)?,
                None => vec![0.0; reference.len()],
            };
            let z = z_test(&test, &var, &reference, &ref_var, opts.alpha);
            Some(ZTestSummary::new(
                &z,
                width,
                opts.alpha,
                var_path.display().to_string(),
                ref_var_path.map(|p| p.display().to_string()),
            ))
        }
    };

    let (metrics, flip) = Metrics::compute_with_flip(&test, &reference, width, height)?;
    let report = CompareReport {
        image: opts.image.display().to_string(),
        reference: opts.reference.display().to_string(),
        width,
        height,
        image_spp: image_file::read_metadata(&opts.image)?.spp,
        reference_spp: image_file::read_metadata(&opts.reference)?.spp,
        metrics,
        z_test,
    };
    let json = match &opts.json {
        Some(_) => {
            let doc = CompareJson {
                report: &report,
                max_relmse: opts.max_relmse,
                max_flip: opts.max_flip,
                checks: report.checks(opts.max_relmse, opts.max_flip),
                passed: report.passes(opts.max_relmse, opts.max_flip),
            };
            let mut bytes = serde_json::to_vec_pretty(&doc).context("cannot encode the report")?;
            bytes.push(b'\n');
            Some(bytes)
        }
        None => None,
    };

    let mut new_heatmap = None;
    if let Some(path) = &opts.heatmap {
        let existed = path.exists();
        flip.write_heatmap(path)?;
        if !existed {
            new_heatmap = Some(path);
        }
    }
    if let (Some(path), Some(bytes)) = (&opts.json, json) {
        if let Err(e) = image_file::write_atomically(path, |w| {
            std::io::Write::write_all(w, &bytes)?;
            Ok(())
        }) {
            if let Some(heatmap) = new_heatmap {
                let _ = std::fs::remove_file(heatmap);
            }
            return Err(e);
        }
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::metrics::FlipResult;
    use crate::analysis::test_images::*;
    use crate::io::image_file::tests::dir_entries;

    #[test]
    fn size_mismatch_is_an_error_naming_both_files() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.exr");
        let b = dir.path().join("b.exr");
        image_file::write_image(&a, 4, 2, &[0.5; 24]).unwrap();
        image_file::write_image(&b, 2, 4, &[0.5; 24]).unwrap();
        let mut opts = CompareOptions::new(&a, &b);
        opts.heatmap = Some(dir.path().join("heat.png"));
        opts.json = Some(dir.path().join("report.json"));
        let msg = format!("{:#}", compare_files(&opts).unwrap_err());
        assert!(msg.contains("4x2") && msg.contains("2x4"), "{msg}");
        assert!(msg.contains("a.exr") && msg.contains("b.exr"), "{msg}");
        assert_eq!(dir_entries(dir.path()), vec!["a.exr", "b.exr"]);
    }

    /// A report with the given figures, for the verdict tests.
    fn report(rel: f64, flip: f64, nonfinite: usize, z_passed: Option<bool>) -> CompareReport {
        CompareReport {
            image: "a.png".into(),
            reference: "b.exr".into(),
            width: 2,
            height: 2,
            image_spp: None,
            reference_spp: None,
            metrics: Metrics {
                rmse: 0.1,
                rel_mse: rel,
                mean_bias: 0.0,
                flip,
                max_abs_diff: 0.2,
                nonfinite_test: nonfinite,
                nonfinite_reference: 0,
            },
            z_test: z_passed.map(|ok| ZTestSummary {
                variance: "a.var.exr".into(),
                reference_variance: None,
                alpha: 0.01,
                alpha_per_pixel: 0.0025,
                pixels: 4,
                passed: if ok { 4 } else { 3 },
                pass_fraction: if ok { 1.0 } else { 0.75 },
                mean_rel_diff: 0.0,
                nonfinite: 0,
                worst: vec![],
            }),
        }
    }

    #[test]
    fn passes_follows_the_thresholds() {
        let r = report(0.002, 0.05, 0, None);
        assert!(r.passes(None, None));
        assert!(r.passes(Some(0.002), Some(0.05)));
        assert!(r.passes(Some(0.0021), None));
        assert!(!r.passes(Some(0.0019), None));
        assert!(r.passes(None, Some(0.051)));
        assert!(!r.passes(None, Some(0.049)));
        assert!(!r.passes(Some(1.0), Some(0.049)));
        assert_eq!(r.checks(Some(1.0), Some(1.0)).len(), 3);
        // Non-finite values fail whatever the thresholds; so does a NaN figure.
        assert!(!report(0.002, 0.05, 1, None).passes(None, None));
        assert!(!report(f64::NAN, 0.05, 0, None).passes(Some(1.0), None));
        assert!(report(f64::NAN, 0.05, 0, None).passes(None, None));
        // The z-test verdict counts when it ran.
        assert!(report(0.002, 0.05, 0, Some(true)).passes(None, None));
        assert!(!report(0.002, 0.05, 0, Some(false)).passes(None, None));
        let text = report(0.002, 0.05, 0, Some(false)).to_string();
        assert!(
            text.contains("relMSE") && text.contains("2.000e-3"),
            "{text}"
        );
        assert!(text.contains("3/4 pixels pass"), "{text}");
    }

    #[test]
    fn compare_files_writes_heatmap_and_json() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (W as u32, H as u32);
        let t = truth();
        let mut rng = Rng(6);
        let (a, va) = noisy(&t, 0.02, &mut rng);
        let (b, vb) = noisy(&t, 0.005, &mut rng);
        let img = dir.path().join("img.exr");
        let var = dir.path().join("img.var.exr");
        let reference = dir.path().join("ref.exr");
        image_file::write_image(&img, w, h, &a).unwrap();
        image_file::write_image(&var, w, h, &va).unwrap();
        image_file::write_image(&reference, w, h, &b).unwrap();

        let mut opts = CompareOptions::new(&img, &reference);
        opts.var = Some(var.clone());
        opts.heatmap = Some(dir.path().join("heat.png"));
        opts.json = Some(dir.path().join("report.json"));
        opts.max_relmse = Some(1e-3);
        let r = compare_files(&opts).unwrap();
        assert_eq!((r.width, r.height), (w, h));
        assert_eq!(r.metrics, Metrics::compute(&a, &b, w, h).unwrap());
        let z = r.z_test.as_ref().unwrap();
        // No ref.var.exr yet: the reference counts as exact, and its 0.5%
        // noise against the image's 2% still passes.
        assert_eq!(z.reference_variance, None);
        assert!(z.all_passed(), "{r}");
        assert!(r.passes(opts.max_relmse, None), "{r}");

        // The heat map: the image's size, magma black where FLIP is 0.
        let heat = image::open(dir.path().join("heat.png"))
            .unwrap()
            .into_rgb8();
        assert_eq!(heat.dimensions(), (w, h));
        let (_, f) = Metrics::compute_with_flip(&a, &b, w, h).unwrap();
        assert_eq!(heat.into_raw(), f.heatmap_rgb8());
        let lut = nv_flip::magma_lut().to_vec();
        let zero = FlipResult {
            mean: 0.0,
            error_map: vec![0.0, 1.0],
            width: 2,
            height: 1,
        };
        assert_eq!(zero.heatmap_rgb8(), [&lut[..3], &lut[765..768]].concat());

        // The JSON report: figures, thresholds and verdict.
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("report.json")).unwrap())
                .unwrap();
        let num = |v: &serde_json::Value| v.as_f64().unwrap();
        assert!((num(&json["metrics"]["rel_mse"]) / r.metrics.rel_mse - 1.0).abs() < 1e-12);
        assert!((num(&json["metrics"]["flip"]) / r.metrics.flip - 1.0).abs() < 1e-12);
        assert_eq!(json["max_relmse"].as_f64(), Some(1e-3));
        assert_eq!(json["passed"].as_bool(), Some(true));
        assert_eq!(json["z_test"]["pixels"].as_u64(), Some((W * H) as u64));
        assert_eq!(json["width"].as_u64(), Some(u64::from(w)));

        // The reference's variance is picked up from ref.var.exr.
        image_file::write_image(&variance_path(&reference), w, h, &vb).unwrap();
        let r = compare_files(&opts).unwrap();
        let z = r.z_test.as_ref().unwrap();
        assert_eq!(
            z.reference_variance.as_deref(),
            Some(dir.path().join("ref.var.exr").to_str().unwrap())
        );
        // A 5% brighter image fails the z-test and the relMSE threshold.
        let bright: Vec<f32> = a.iter().map(|x| x * 1.05).collect();
        image_file::write_image(&img, w, h, &bright).unwrap();
        let r = compare_files(&opts).unwrap();
        assert!(!r.z_test.as_ref().unwrap().all_passed());
        assert!(r.metrics.rel_mse > 1e-3);
        assert!(!compare_files(&opts)
            .unwrap()
            .passes(opts.max_relmse, opts.max_flip));
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("report.json")).unwrap())
                .unwrap();
        assert_eq!(json["passed"].as_bool(), Some(false));
        assert_eq!(
            dir_entries(dir.path()),
            vec![
                "heat.png",
                "img.exr",
                "img.var.exr",
                "ref.exr",
                "ref.var.exr",
                "report.json"
            ]
        );
    }

    #[test]
    fn compare_writes_nothing_on_bad_input() {
        let dir = tempfile::tempdir().unwrap();
        let reference = dir.path().join("ref.png");
        image_file::write_image(&reference, 2, 2, &[0.5; 12]).unwrap();
        let img = dir.path().join("img.png");
        let mut opts = CompareOptions::new(&img, &reference);
        opts.heatmap = Some(dir.path().join("heat.png"));
        opts.json = Some(dir.path().join("r.json"));

        // The image is missing.
        let msg = format!("{:#}", compare_files(&opts).unwrap_err());
        assert!(
            msg.contains("img.png") && msg.contains("no such file"),
            "{msg}"
        );
        assert_eq!(dir_entries(dir.path()), vec!["ref.png"]);

        image_file::write_image(&img, 2, 2, &[0.25; 12]).unwrap();
        let before = dir_entries(dir.path());
        // A missing variance image, a variance of the wrong size, a missing
        // output folder, a heat map that is not a PNG, an output over an
        // input, bad thresholds: each fails before anything is written.
        let var_small = dir.path().join("small.exr");
        image_file::write_image(&var_small, 1, 1, &[0.0; 3]).unwrap();
        let before_small = dir_entries(dir.path());
        let cases: Vec<(CompareOptions, &str)> = vec![
            (
                CompareOptions {
                    var: Some(dir.path().join("nope.exr")),
                    ..opts.clone()
                },
                "nope.exr",
            ),
            (
                CompareOptions {
                    var: Some(var_small.clone()),
                    ..opts.clone()
                },
                "1x1",
            ),
            (
                CompareOptions {
                    json: Some(dir.path().join("no/such/r.json")),
                    ..opts.clone()
                },
                "does not exist",
            ),
            (
                CompareOptions {
                    heatmap: Some(dir.path().join("heat.exr")),
                    ..opts.clone()
                },
                ".png",
            ),
            (
                CompareOptions {
                    heatmap: Some(img.clone()),
                    ..opts.clone()
                },
                "overwrite",
            ),
            (
                CompareOptions {
                    max_flip: Some(-1.0),
                    ..opts.clone()
                },
                "CompareOptions::max_flip",
            ),
            (
                CompareOptions {
                    alpha: 1.0,
                    ..opts.clone()
                },
                "alpha",
            ),
        ];
        for (case, want) in cases {
            let msg = format!("{:#}", compare_files(&case).unwrap_err());
            assert!(msg.contains(want), "{want}: {msg}");
            assert_eq!(dir_entries(dir.path()), before_small, "{want}");
        }
        std::fs::remove_file(&var_small).unwrap();
        assert_eq!(dir_entries(dir.path()), before);

        // And with good input, both files appear.
        assert!(compare_files(&opts)
            .unwrap()
            .passes(opts.max_relmse, opts.max_flip));
        assert_eq!(
            dir_entries(dir.path()),
            vec!["heat.png", "img.png", "r.json", "ref.png"]
        );
    }
}
