//! Error figures of a test image against a reference: [`Metrics`] gathers
//! the per-value figures of [`crate::util::metrics`] ([`rmse`], [`rel_mse`],
//! [`mean_bias`], [`max_abs_diff`], the non-finite counts) and NVIDIA's
//! FLIP ([`flip`]), which sees the images as their PNGs show them.
//! [`predicted_rel_mse`] is the relMSE a film's own variance predicts.
//!
//! Images are flat `f32` slices of interleaved, linear RGB: a pixel is 3
//! consecutive values, rows top first.

use std::path::Path;

use anyhow::{ensure, Context, Result};
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};
use serde::Serialize;

use crate::io::image_file;
use crate::util::metrics::*;

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

/// The per-pixel sample counts of a render (`render --spp-out`) as the
/// bytes of the file `path` names: an EXR holds each count in R, G and B; a
/// PNG is a heat map in FLIP's magma colour map, black for no sample to
/// pale yellow for the most any pixel got.
pub fn sample_count_image(path: &Path, width: u32, height: u32, counts: &[u32]) -> Result<Vec<u8>> {
    ensure!(
        counts.len() as u64 == u64::from(width) * u64::from(height),
        "{} sample counts for a {width}x{height} image",
        counts.len()
    );
    let is_png = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        let rgb: Vec<f32> = counts.iter().flat_map(|&n| [n as f32; 3]).collect();
        return image_file::encode_image(path, width, height, &rgb);
    }
    let most = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
    let heat = FlipResult {
        mean: 0.0,
        error_map: counts.iter().map(|&n| n as f32 / most).collect(),
        width,
        height,
    };
    let mut bytes = Vec::new();
    PngEncoder::new(&mut bytes)
        .write_image(&heat.heatmap_rgb8(), width, height, ExtendedColorType::Rgb8)
        .context("PNG encoding failed")?;
    Ok(bytes)
}

/// Checks that `path` names a PNG file.
pub(super) fn check_png_path(path: &Path) -> Result<()> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::test_images::*;

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
}
