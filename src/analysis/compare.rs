//! Image comparison: the error figures, the FLIP metric and a statistical
//! per-pixel test, shared by the command line and the test suite.
//!
//! Images are flat `f32` slices of interleaved, linear RGB: a pixel is 3
//! consecutive values, rows top first.
//!
//! - Error figures of a test image against a reference: [`rmse`],
//!   [`rel_mse`], [`mean_bias`], [`max_abs_diff`], [`flip`], and
//!   [`predicted_rel_mse`], the relMSE a film's own variance predicts.
//!   [`Metrics`] gathers them.
//! - [`z_test`] asks, as Mitsuba 3's render tests do, whether a test image
//!   and a reference differ by more than their noise explains: each has a
//!   per-channel mean and the variance of that mean (the sample variance
//!   divided by the sample count).
//! - [`compare_files`] and [`run_compare`] compare two image files, write a
//!   FLIP heat map and a JSON report, and give a pass/fail verdict against
//!   thresholds ([`CompareReport`]).

use std::fmt;
use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context, Result};
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};
use serde::Serialize;

use crate::io::image_file;
use crate::util::metrics::*;

/// Complementary error function, erfc(x) = 1 - erf(x).
///
/// Uses the Chebyshev fit from Numerical Recipes (`erfcc`), whose fractional
/// error is below 1.2e-7 everywhere. NaN gives NaN.
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let ans = t * poly.exp();
    if x >= 0.0 {
        ans
    } else {
        2.0 - ans
    }
}

/// Two-sided p-value of a standard normal score: P(|Z| >= |z|).
fn p_two_sided(z: f64) -> f64 {
    erfc(z.abs() / std::f64::consts::SQRT_2).min(1.0)
}

/// Result of [`z_test`].
#[derive(Clone, Debug, PartialEq)]
pub struct ZTest {
    /// Pixels compared.
    pub pixels: usize,
    /// Pixels whose p-value is at least `alpha_per_pixel`.
    pub passed: usize,
    /// `passed / pixels` (1 for an empty image).
    pub pass_fraction: f64,
    /// Šidák-corrected per-pixel threshold: `1 - (1 - alpha)^(1 / pixels)`.
    pub alpha_per_pixel: f64,
    /// Mean of the test image over all channels of its finite pixels.
    pub mean_test: f64,
    /// Mean of the reference over the same pixels.
    pub mean_ref: f64,
    /// `(mean_test - mean_ref) / |mean_ref|` (0 when both are 0).
    pub mean_rel_diff: f64,
    /// The (up to) 10 pixels with the lowest p-values, as
    /// `(pixel index, p)`, lowest first. Pixel index = `y * width + x`.
    pub worst: Vec<(usize, f64)>,
    /// Pixels with a NaN or infinity in any of the four inputs; they fail
    /// with p = 0 and are left out of the means.
    pub nonfinite: usize,
}

impl ZTest {
    /// Whether every pixel passed: the image-level verdict at level `alpha`,
    /// as the Šidák correction intends.
    pub fn all_passed(&self) -> bool {
        self.passed == self.pixels
    }
}

impl fmt::Display for ZTest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "z-test: {}/{} pixels pass ({:.3}%), per-pixel alpha {:.3e}",
            self.passed,
            self.pixels,
            100.0 * self.pass_fraction,
            self.alpha_per_pixel
        )?;
        writeln!(
            f,
            "mean: test {:.6}, reference {:.6}, relative difference {:+.4}%",
            self.mean_test,
            self.mean_ref,
            100.0 * self.mean_rel_diff
        )?;
        if self.nonfinite > 0 {
            writeln!(f, "non-finite pixels: {}", self.nonfinite)?;
        }
        write!(f, "worst pixels (index: p):")?;
        for (i, p) in &self.worst {
            write!(f, " {i}: {p:.3e}")?;
        }
        Ok(())
    }
}

/// Per-pixel z-test of a test image against a reference.
///
/// All four slices are interleaved RGB of the same length, a multiple of 3.
/// `*_var_of_mean` is the variance of each channel's mean (sample variance /
/// sample count). Per channel, z = (a - b) / sqrt(va + vb) and its two-sided
/// p-value comes from [`erfc`]; when va + vb = 0 the channel has p = 1 if
/// |a - b| <= 1e-5 · max(1, |b|) (a few f32 roundings) and p = 0 otherwise. A pixel's p is the
/// smallest channel p times 3 (Bonferroni over the channels), capped at 1.
/// With `n` pixels, a pixel passes iff p >= 1 - (1 - alpha)^(1/n) (Šidák), so
/// that an image without bias fails anywhere with probability about `alpha`.
/// A pixel with any non-finite input fails with p = 0.
///
/// # Panics
///
/// If the slices differ in length or the length is not a multiple of 3.
pub fn z_test(
    test_mean: &[f32],
    test_var_of_mean: &[f32],
    ref_mean: &[f32],
    ref_var_of_mean: &[f32],
    alpha: f64,
) -> ZTest {
    let n = test_mean.len();
    assert!(
        test_var_of_mean.len() == n && ref_mean.len() == n && ref_var_of_mean.len() == n,
        "z_test: slices differ in length ({n}, {}, {}, {})",
        test_var_of_mean.len(),
        ref_mean.len(),
        ref_var_of_mean.len()
    );
    assert!(
        n.is_multiple_of(3),
        "z_test: length {n} is not a multiple of 3"
    );
    let pixels = n / 3;
    let alpha_per_pixel = if pixels == 0 {
        alpha
    } else {
        // 1 - (1 - alpha)^(1/n), without cancellation for small alpha.
        -((-alpha).ln_1p() / pixels as f64).exp_m1()
    };

    let mut p_values = Vec::with_capacity(pixels);
    let mut nonfinite = 0;
    let (mut sum_test, mut sum_ref) = (0.0f64, 0.0f64);
    for px in 0..pixels {
        let ch = 3 * px..3 * px + 3;
        let finite = ch.clone().all(|i| {
            test_mean[i].is_finite()
                && test_var_of_mean[i].is_finite()
                && ref_mean[i].is_finite()
                && ref_var_of_mean[i].is_finite()
        });
        if !finite {
            nonfinite += 1;
            p_values.push(0.0);
            continue;
        }
        let mut p_min = 1.0f64;
        for i in ch {
            let a = f64::from(test_mean[i]);
            let b = f64::from(ref_mean[i]);
            sum_test += a;
            sum_ref += b;
            let var =
                f64::from(test_var_of_mean[i]).max(0.0) + f64::from(ref_var_of_mean[i]).max(0.0);
            let p = if var > 0.0 {
                p_two_sided((a - b) / var.sqrt())
            } else if (a - b).abs() <= 1e-5 * b.abs().max(1.0) {
                1.0
            } else {
                0.0
            };
            p_min = p_min.min(p);
        }
        p_values.push((3.0 * p_min).min(1.0));
    }

    let passed = p_values.iter().filter(|&&p| p >= alpha_per_pixel).count();
    let counted = 3 * (pixels - nonfinite);
    let (mean_test, mean_ref) = if counted > 0 {
        (sum_test / counted as f64, sum_ref / counted as f64)
    } else {
        (0.0, 0.0)
    };
    let mean_rel_diff = if mean_ref != 0.0 {
        (mean_test - mean_ref) / mean_ref.abs()
    } else if mean_test == 0.0 {
        0.0
    } else {
        f64::INFINITY.copysign(mean_test)
    };

    let mut order: Vec<usize> = (0..pixels).collect();
    order.sort_by(|&i, &j| p_values[i].total_cmp(&p_values[j]).then(i.cmp(&j)));
    let worst = order.iter().take(10).map(|&i| (i, p_values[i])).collect();

    ZTest {
        pixels,
        passed,
        pass_fraction: if pixels == 0 {
            1.0
        } else {
            passed as f64 / pixels as f64
        },
        alpha_per_pixel,
        mean_test,
        mean_ref,
        mean_rel_diff,
        worst,
        nonfinite,
    }
}

/// Number of values in a `width` x `height` RGB image, or an error if it
/// is empty or too large for FLIP (which counts values in 32 bits).
fn rgb_len(width: u32, height: u32) -> Result<usize> {
    ensure!(
        width > 0 && height > 0,
        "cannot compare empty images ({width}x{height})"
    );
    let n = u64::from(width) * u64::from(height) * 3;
    ensure!(
        n <= u64::from(u32::MAX),
        "{width}x{height} is too large to compare"
    );
    Ok(n as usize)
}

/// Checks that a test image and a reference both hold a `width` x `height`
/// RGB image; the error gives both lengths.
fn check_lengths(test: &[f32], reference: &[f32], width: u32, height: u32) -> Result<()> {
    let n = rgb_len(width, height)?;
    ensure!(
        test.len() == n && reference.len() == n,
        "image size mismatch: a {width}x{height} RGB image has {n} values, but the test \
         image has {} ({} pixels) and the reference {} ({} pixels)",
        test.len(),
        test.len() as f64 / 3.0,
        reference.len(),
        reference.len() as f64 / 3.0
    );
    Ok(())
}

/// The tone mapping applied before FLIP: per value, clamp to [0, 1],
/// sRGB-encode and round to 8 bits ([`image_file::to_srgb8`], the PNG encoding
/// of [`image_file::write_image`]); NaN becomes 0.
fn to_ldr8(rgb: &[f32]) -> Vec<u8> {
    rgb.iter()
        .map(|&x| crate::util::color::to_srgb8(x))
        .collect()
}

/// Result of [`flip`].
#[derive(Clone, Debug, PartialEq)]
pub struct FlipResult {
    /// Mean of the error map: the FLIP figure of the image, in [0, 1].
    pub mean: f64,
    /// Per-pixel FLIP error in [0, 1], row-major, top row first.
    pub error_map: Vec<f32>,
    /// Width of the error map in pixels.
    pub width: u32,
    /// Height of the error map in pixels.
    pub height: u32,
}

impl FlipResult {
    /// The error map as an 8-bit RGB heat map (row-major, 3 bytes a pixel),
    /// coloured with FLIP's magma colour map: black for no error, through
    /// purple and orange, to pale yellow for an error of 1.
    pub fn heatmap_rgb8(&self) -> Vec<u8> {
        let map = nv_flip::FlipImageFloat::with_data(self.width, self.height, &self.error_map);
        map.apply_color_lut(&nv_flip::magma_lut()).to_vec()
    }

    /// Writes the heat map of [`FlipResult::heatmap_rgb8`] as a PNG file,
    /// atomically (see [`image_file::write_atomically`]). `path` must end in
    /// `.png` (any case); errors name it.
    pub fn write_heatmap(&self, path: &Path) -> Result<()> {
        check_png_path(path)?;
        let bytes = self.heatmap_rgb8();
        image_file::write_atomically(path, |w| {
            PngEncoder::new(w)
                .write_image(&bytes, self.width, self.height, ExtendedColorType::Rgb8)
                .context("PNG encoding failed")
        })
    }
}

/// Checks that `path` names a PNG file.
fn check_png_path(path: &Path) -> Result<()> {
    let is_png = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    ensure!(
        is_png,
        "{}: the FLIP heat map is written as PNG; give a file name ending in .png",
        path.display()
    );
    Ok(())
}

/// NVIDIA's FLIP error of a test image against a reference, both linear HDR
/// RGB of `width` x `height` pixels.
///
/// Both images are tone-mapped the same way to 8-bit sRGB before LDR-FLIP:
/// each value is clamped to [0, 1], sRGB-encoded with the exact curve and
/// rounded to 8 bits, as a PNG written by [`image_file::write_image`] stores it
/// (NaN becomes 0, +inf becomes 1). So FLIP sees what the PNG shows; radiance
/// above 1 is not compared (relMSE and RMSE cover it). The viewing condition
/// is FLIP's default, 67 pixels per degree (a 0.7 m wide 4K monitor seen from
/// 0.7 m). The FLIP code is NVIDIA's C++ implementation, through `nv-flip`.
///
/// Identical tone-mapped images give exactly 0.
///
/// # Errors
///
/// If the image is empty or too large, or a slice does not hold
/// `width * height * 3` values (the message gives both lengths).
pub fn flip(test: &[f32], reference: &[f32], width: u32, height: u32) -> Result<FlipResult> {
    check_lengths(test, reference, width, height)?;
    let test8 = nv_flip::FlipImageRgb8::with_data(width, height, &to_ldr8(test));
    let ref8 = nv_flip::FlipImageRgb8::with_data(width, height, &to_ldr8(reference));
    let error_map = nv_flip::flip(ref8, test8, nv_flip::DEFAULT_PIXELS_PER_DEGREE).to_vec();
    let mean = error_map.iter().map(|&e| f64::from(e)).sum::<f64>() / error_map.len() as f64;
    Ok(FlipResult {
        mean,
        error_map,
        width,
        height,
    })
}

/// Every error figure of a test image against a reference.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// [`rmse`]: sqrt(mean((a-b)²)).
    pub rmse: f64,
    /// [`rel_mse`]: mean((a-b)² / (b² + 0.01)).
    pub rel_mse: f64,
    /// [`mean_bias`]: mean(a - b).
    pub mean_bias: f64,
    /// Mean FLIP error after tone mapping to 8-bit sRGB (see [`flip`]).
    pub flip: f64,
    /// [`max_abs_diff`]: max |a - b|.
    pub max_abs_diff: f64,
    /// Non-finite values in the test image ([`count_nonfinite`]).
    pub nonfinite_test: usize,
    /// Non-finite values in the reference.
    pub nonfinite_reference: usize,
}

impl Metrics {
    /// Computes every figure of `test` against `reference`, both linear RGB
    /// of `width` x `height` pixels. A non-finite value makes RMSE, relMSE,
    /// bias and max |a-b| non-finite (serialised as JSON `null`); the
    /// `nonfinite_*` counts say where they came from.
    ///
    /// # Errors
    ///
    /// If a slice does not hold `width * height * 3` values (the message
    /// gives both lengths), or the image is empty.
    pub fn compute(test: &[f32], reference: &[f32], width: u32, height: u32) -> Result<Metrics> {
        Ok(Self::compute_with_flip(test, reference, width, height)?.0)
    }

    /// [`Metrics::compute`], also returning the FLIP error map (for a heat
    /// map) so that FLIP runs once.
    ///
    /// # Errors
    ///
    /// As [`Metrics::compute`].
    pub fn compute_with_flip(
        test: &[f32],
        reference: &[f32],
        width: u32,
        height: u32,
    ) -> Result<(Metrics, FlipResult)> {
        check_lengths(test, reference, width, height)?;
        let flip = flip(test, reference, width, height)?;
        let metrics = Metrics {
            rmse: rmse(test, reference),
            rel_mse: rel_mse(test, reference),
            mean_bias: mean_bias(test, reference),
            flip: flip.mean,
            max_abs_diff: max_abs_diff(test, reference),
            nonfinite_test: count_nonfinite(test),
            nonfinite_reference: count_nonfinite(reference),
        };
        Ok((metrics, flip))
    }
}

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

/// Whether two paths name the same file, existing or not: compares the
/// canonical parent folders and the file names.
fn same_file(a: &Path, b: &Path) -> bool {
    let key = |p: &Path| -> Option<PathBuf> {
        let parent = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        Some(parent.canonicalize().ok()?.join(p.file_name()?))
    };
    match (key(a), key(b)) {
        (Some(x), Some(y)) => x == y,
        _ => a == b,
    }
}

/// Checks an output path before anything is written: its folder exists, it
/// is not a folder itself, and it is none of `inputs`.
fn check_output(path: &Path, what: &str, inputs: &[&Path]) -> Result<()> {
    image_file::check_destination(path, false).with_context(|| format!("the {what}"))?;
    for input in inputs {
        ensure!(
            !same_file(path, input),
            "{}: the {what} would overwrite the input {}",
            path.display(),
            input.display()
        );
    }
    Ok(())
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
        ("--max-relmse", opts.max_relmse),
        ("--max-flip", opts.max_flip),
    ] {
        if let Some(v) = value {
            ensure!(
                v.is_finite() && v >= 0.0,
                "{name} must be a finite number >= 0, not {v}"
            );
        }
    }
    let mut inputs: Vec<&Path> = vec![&opts.image, &opts.reference];
    inputs.extend(opts.var.as_deref());
    inputs.extend(opts.reference_var.as_deref());
    if let Some(path) = &opts.heatmap {
        check_png_path(path)?;
        check_output(path, "FLIP heat map", &inputs)?;
    }
    if let Some(path) = &opts.json {
        check_output(path, "JSON report", &inputs)?;
        if let Some(heatmap) = &opts.heatmap {
            ensure!(
                !same_file(path, heatmap),
                "{}: the JSON report and the heat map are the same file",
                path.display()
            );
        }
    }

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

/// `lancer compare`: [`compare_files`], then prints the report, each check
/// and the verdict to standard output. Returns whether the image passed
/// ([`CompareReport::passes`] with the options' thresholds); the command
/// maps that to exit code 0 or 1.
///
/// # Errors
///
/// As [`compare_files`]; nothing is printed then.
pub fn run_compare(opts: &CompareOptions) -> Result<bool> {
    let report = compare_files(opts)?;
    println!("{report}");
    println!();
    for check in report.checks(opts.max_relmse, opts.max_flip) {
        println!(
            "  [{}] {}",
            if check.passed { "pass" } else { "FAIL" },
            check.what
        );
    }
    let passed = report.passes(opts.max_relmse, opts.max_flip);
    println!("{}", if passed { "PASS" } else { "FAIL" });
    Ok(passed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SplitMix64 with Box–Muller normals: enough for synthetic noise.
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        /// Uniform in (0, 1].
        fn uniform(&mut self) -> f64 {
            ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(), self.uniform());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    const W: usize = 64;
    const H: usize = 48;

    /// An asymmetric ground truth: a horizontal ramp, a bright block on the
    /// left, and a channel-dependent tint.
    fn truth() -> Vec<f32> {
        let mut img = Vec::with_capacity(W * H * 3);
        for y in 0..H {
            for x in 0..W {
                let ramp = 0.1 + 0.8 * x as f32 / (W - 1) as f32;
                let block = if x < W / 4 && y > H / 3 { 0.5 } else { 0.0 };
                for c in 0..3 {
                    img.push(ramp + block + 0.05 * c as f32 + 0.02 * (y % 5) as f32);
                }
            }
        }
        img
    }

    /// A noisy estimate of `truth`: per value, noise with standard deviation
    /// `rel_sigma * value`; returns (mean, variance of mean).
    fn noisy(truth: &[f32], rel_sigma: f64, rng: &mut Rng) -> (Vec<f32>, Vec<f32>) {
        let mut mean = Vec::with_capacity(truth.len());
        let mut var = Vec::with_capacity(truth.len());
        for &t in truth {
            let s = rel_sigma * f64::from(t);
            mean.push((f64::from(t) + s * rng.normal()) as f32);
            var.push((s * s) as f32);
        }
        (mean, var)
    }

    fn mirror(img: &[f32]) -> Vec<f32> {
        let mut out = vec![0.0; img.len()];
        for y in 0..H {
            for x in 0..W {
                for c in 0..3 {
                    out[(y * W + x) * 3 + c] = img[(y * W + (W - 1 - x)) * 3 + c];
                }
            }
        }
        out
    }

    #[test]
    fn erfc_known_values() {
        // Reference values (to 16 digits) from mpmath.
        let cases = [
            (0.0, 1.0),
            (0.1, 0.887_537_083_981_715),
            (0.5, 0.479_500_122_186_953_5),
            (1.0, 0.157_299_207_050_285_1),
            (2.0, 0.004_677_734_981_047_266),
            (3.0, 2.209_049_699_858_544e-5),
            (5.0, 1.537_459_794_428_035e-12),
            (-1.0, 1.842_700_792_949_715),
            (-3.0, 1.999_977_909_503_001),
        ];
        for (x, want) in cases {
            let got = erfc(x);
            assert!(
                ((got - want) / want).abs() < 1.2e-7,
                "erfc({x}) = {got}, want {want}"
            );
        }
        assert!(erfc(f64::NAN).is_nan());
        assert_eq!(erfc(f64::INFINITY), 0.0);
        assert_eq!(erfc(f64::NEG_INFINITY), 2.0);
        // Two-sided p at the familiar quantiles.
        assert!((p_two_sided(1.959_963_984_540_054) - 0.05).abs() < 1e-8);
        assert!((p_two_sided(-2.575_829_303_548_901) - 0.01).abs() < 1e-8);
    }

    #[test]
    fn unbiased_noisy_image_passes() {
        let t = truth();
        let mut rng = Rng(1);
        let (a, va) = noisy(&t, 0.02, &mut rng);
        let (b, vb) = noisy(&t, 0.01, &mut rng);
        let z = z_test(&a, &va, &b, &vb, 0.01);
        assert_eq!(z.pixels, W * H);
        assert!(z.pass_fraction > 0.995, "{z}");
        assert!(z.all_passed(), "{z}");
        assert_eq!(z.nonfinite, 0);
        assert!(z.mean_rel_diff.abs() < 1e-3, "{z}");
        assert_eq!(z.worst.len(), 10);
        assert!(z.worst.windows(2).all(|w| w[0].1 <= w[1].1));
        // Šidák: 1 - 0.99^(1/3072).
        let want = 1.0 - 0.99f64.powf(1.0 / (W * H) as f64);
        assert!(
            (z.alpha_per_pixel - want).abs() < 1e-15,
            "{}",
            z.alpha_per_pixel
        );
    }

    #[test]
    fn scaled_mean_fails() {
        let t = truth();
        let mut rng = Rng(2);
        let (a, va) = noisy(&t, 0.005, &mut rng);
        let (b, vb) = noisy(&t, 0.005, &mut rng);
        let a: Vec<f32> = a.iter().map(|x| x * 1.05).collect();
        let z = z_test(&a, &va, &b, &vb, 0.01);
        // z ≈ 0.05 / (0.005·√2) ≈ 7 per channel: nearly every pixel fails.
        assert!(z.pass_fraction < 0.05, "{z}");
        assert!(!z.all_passed());
        assert!((z.mean_rel_diff - 0.05).abs() < 2e-3, "{z}");
    }

    #[test]
    fn mirrored_image_fails() {
        let t = truth();
        let mut rng = Rng(3);
        let (a, va) = noisy(&mirror(&t), 0.01, &mut rng);
        let (b, vb) = noisy(&t, 0.01, &mut rng);
        let z = z_test(&a, &va, &b, &vb, 0.01);
        // Mirroring keeps the mean but moves the ramp and the block.
        assert!(z.mean_rel_diff.abs() < 0.01, "{z}");
        assert!(z.pass_fraction < 0.5, "{z}");
        assert!(!z.all_passed());
    }

    #[test]
    fn zero_variance_and_nonfinite_pixels() {
        // Pixel 0: equal, zero variance -> pass. Pixel 1: differ, zero
        // variance -> fail. Pixel 2: NaN -> fail, counted. Pixel 3: z = 1
        // in one channel -> pass.
        let a = [
            1.0,
            2.0,
            3.0,
            1.0,
            1.0,
            1.1,
            f32::NAN,
            0.0,
            0.0,
            1.0,
            1.0,
            1.0,
        ];
        let b = [1.0, 2.0, 3.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0];
        let va = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5];
        let z = z_test(&a, &va, &b, &va, 0.05);
        assert_eq!((z.pixels, z.passed, z.nonfinite), (4, 2, 1));
        assert_eq!(z.worst.len(), 4);
        assert_eq!(z.worst[0], (1, 0.0));
        assert_eq!(z.worst[1], (2, 0.0));
        // Pixel 3: z = 1 in one channel -> p = 0.31731, times 3 = 0.95193.
        assert_eq!(z.worst[2].0, 3);
        assert!((z.worst[2].1 - 0.951_931_5).abs() < 1e-6, "{:?}", z.worst);
        assert_eq!(z.worst[3], (0, 1.0));
        let text = z.to_string();
        assert!(text.contains("2/4 pixels pass"), "{text}");
        assert!(text.contains("non-finite pixels: 1"), "{text}");
    }

    use crate::io::image_file::tests::dir_entries;

    #[test]
    fn five_percent_brighter_gives_the_exact_figures() {
        // 5% of each of these is a power of two, so a = 1.05 b is exact in f32.
        let b: Vec<f32> = [0.625f32, 1.25, 2.5, 5.0, 10.0, 20.0]
            .iter()
            .cycle()
            .take(6 * 4 * 3)
            .copied()
            .collect();
        let a: Vec<f32> = b.iter().map(|&x| x + x / 20.0).collect();
        for (&x, &y) in a.iter().zip(&b) {
            assert_eq!(f64::from(x), f64::from(y) * 21.0 / 20.0);
        }
        let m = Metrics::compute(&a, &b, 6, 4).unwrap();
        let n = b.len() as f64;
        // The analytic figures: a - b = b / 20 exactly.
        let want_rel: f64 = b
            .iter()
            .map(|&y| {
                let y = f64::from(y);
                (y / 20.0).powi(2) / (y * y + 0.01)
            })
            .sum::<f64>()
            / n;
        let want_bias = 0.05 * b.iter().map(|&y| f64::from(y)).sum::<f64>() / n;
        let want_rmse = 0.05 * (b.iter().map(|&y| f64::from(y).powi(2)).sum::<f64>() / n).sqrt();
        assert!((m.rel_mse - want_rel).abs() <= 1e-14 * want_rel, "{m:?}");
        assert!(
            (m.mean_bias - want_bias).abs() <= 1e-14 * want_bias,
            "{m:?}"
        );
        assert!((m.rmse - want_rmse).abs() <= 1e-14 * want_rmse, "{m:?}");
        assert_eq!(m.max_abs_diff, 1.0); // 5% of 20
                                         // relMSE of a 5% error is just under 0.0025 once b² dwarfs 0.01.
        assert!(m.rel_mse > 0.0024 && m.rel_mse < 0.0025, "{}", m.rel_mse);
        assert_eq!((m.nonfinite_test, m.nonfinite_reference), (0, 0));
    }

    #[test]
    fn image_against_itself_is_zero_everywhere() {
        let t = truth();
        let (m, f) = Metrics::compute_with_flip(&t, &t, W as u32, H as u32).unwrap();
        assert_eq!(
            m,
            Metrics {
                rmse: 0.0,
                rel_mse: 0.0,
                mean_bias: 0.0,
                flip: 0.0,
                max_abs_diff: 0.0,
                nonfinite_test: 0,
                nonfinite_reference: 0,
            }
        );
        assert_eq!(f.error_map.len(), W * H);
        assert!(f.error_map.iter().all(|&e| e == 0.0));
        assert_eq!(predicted_rel_mse(&vec![0.0; t.len()], &t), 0.0);
    }

    #[test]
    fn mirrored_image_has_large_flip() {
        let t = truth();
        let mut rng = Rng(4);
        let (noisy_t, _) = noisy(&t, 0.01, &mut rng);
        let (w, h) = (W as u32, H as u32);
        let mirrored = flip(&mirror(&t), &t, w, h).unwrap();
        let slight = flip(&noisy_t, &t, w, h).unwrap();
        // The ramp and the block move: FLIP sees a large difference, while
        // 1% noise is barely visible.
        assert!(mirrored.mean > 0.2, "mirrored FLIP {}", mirrored.mean);
        assert!(slight.mean < 0.05, "noisy FLIP {}", slight.mean);
        assert!(mirrored.mean > 10.0 * slight.mean);
        assert!(mirrored.error_map.iter().all(|e| (0.0..=1.0).contains(e)));
        // The mean is the mean of the map, and agrees with FLIP's own pool.
        let map = nv_flip::FlipImageFloat::with_data(w, h, &mirrored.error_map);
        let pool = nv_flip::FlipPool::from_image(&map);
        assert!((f64::from(pool.mean()) - mirrored.mean).abs() < 1e-5);
    }

    #[test]
    fn flip_tone_maps_like_the_png() {
        // Above 1 clamps, NaN is 0: these differ in linear values only where
        // the 8-bit sRGB encoding is equal, so FLIP is exactly 0.
        let a = [2.0, 1.0, f32::NAN, 0.5, 0.0, 0.25];
        let b = [1.0, 7.0, -1.0, 0.5, -3.0, 0.2501];
        let f = flip(&a, &b, 2, 1).unwrap();
        assert_eq!(f.mean, 0.0, "{f:?}");
        let m = Metrics::compute(&a, &b, 2, 1).unwrap();
        assert!(m.rel_mse.is_nan() && m.max_abs_diff.is_nan());
        assert_eq!((m.nonfinite_test, m.nonfinite_reference), (1, 0));
    }

    #[test]
    fn size_mismatch_is_an_error_naming_both_sizes() {
        let err = Metrics::compute(&[0.5; 12], &[0.5; 9], 2, 2).unwrap_err();
        let msg = format!("{err:#}");
        assert!(
            msg.contains("2x2") && msg.contains("12") && msg.contains("9"),
            "{msg}"
        );
        assert!(flip(&[0.5; 9], &[0.5; 9], 2, 2).is_err());
        assert!(Metrics::compute(&[], &[], 0, 3).is_err());

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

    #[test]
    fn max_abs_diff_and_predicted_rel_mse() {
        assert_eq!(max_abs_diff(&[1.0, -2.0, 3.0], &[1.5, 2.0, 3.0]), 4.0);
        assert_eq!(max_abs_diff(&[], &[]), 0.0);
        assert!(max_abs_diff(&[f32::NAN, 9.0], &[0.0, 0.0]).is_nan());
        assert_eq!(max_abs_diff(&[f32::INFINITY], &[0.0]), f64::INFINITY);

        // Per value var / (ref² + 0.01), with the f32 inputs as they are;
        // the negative variance counts as 0.
        let (v0, v1) = (f64::from(0.01f32), f64::from(0.04f32));
        let want = (v0 / 0.01 + v1 / 1.01 + 0.0) / 3.0;
        let got = predicted_rel_mse(&[0.01, 0.04, -1e-9], &[0.0, 1.0, 2.0]);
        assert!((got - want).abs() < 1e-15, "{got} {want}");

        // For an unbiased noisy image, the predicted relMSE is what relMSE
        // measures (9216 values: its relative spread is about 1.5%).
        let t = truth();
        let mut rng = Rng(5);
        let (a, va) = noisy(&t, 0.03, &mut rng);
        let measured = rel_mse(&a, &t);
        let predicted = predicted_rel_mse(&va, &t);
        assert!(
            (measured / predicted - 1.0).abs() < 0.06,
            "measured {measured}, predicted {predicted}"
        );
        // Bias shows as relMSE far above the prediction.
        let biased: Vec<f32> = a.iter().map(|x| x * 1.1).collect();
        assert!(rel_mse(&biased, &t) > 5.0 * predicted);
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
        assert!(!run_compare(&opts).unwrap());
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
        let msg = format!("{:#}", run_compare(&opts).unwrap_err());
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
                "--max-flip",
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
        assert!(run_compare(&opts).unwrap());
        assert_eq!(
            dir_entries(dir.path()),
            vec!["heat.png", "img.png", "r.json", "ref.png"]
        );
    }
}
