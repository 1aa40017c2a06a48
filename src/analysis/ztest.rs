//! The per-pixel z-test, as Mitsuba 3's render tests run it: whether a test
//! image and a reference differ by more than their noise explains. Each has
//! a per-channel mean and the variance of that mean (the sample variance
//! divided by the sample count); [`erfc`] gives the p-values.
//!
//! Images are flat `f32` slices of interleaved, linear RGB: a pixel is 3
//! consecutive values, rows top first.

use std::fmt;

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

/// The relative standard deviation the z-test adds for the rounding of
/// each mean (about 170 units in the last place of an f32, the tolerance
/// the test has always given pixels without noise): far below any noisy
/// pixel's spread, above the ulps by which two renderers' sums of
/// identical samples differ (Mitsuba's mean of 16 passes of a constant
/// pixel differs from lancer's by up to a few 1e-6).
pub const ROUNDING: f64 = 1e-5;

/// Per-pixel z-test of a test image against a reference.
///
/// All four slices are interleaved RGB of the same length, a multiple of 3.
/// `*_var_of_mean` is the variance of each channel's mean (sample variance /
/// sample count). Per channel, z = (a - b) / sqrt(va + vb + r²) and its
/// two-sided p-value comes from [`erfc`], where r = [`ROUNDING`] · max(|a|,
/// |b|) stands for the roundings of the two means: a pixel whose
/// samples all agree (a face of constant colour under `direct`) has a
/// variance of rounding size or 0 on each side, and two renderers' sums
/// round it differently. All three are 0 only where both means are 0
/// without noise: the channel then has p = 1. A pixel's p is the
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
            let rounding = ROUNDING * a.abs().max(b.abs());
            let var = f64::from(test_var_of_mean[i]).max(0.0)
                + f64::from(ref_var_of_mean[i]).max(0.0)
                + rounding * rounding;
            // A variance of 0 leaves both means 0 and without noise: equal
            let p = if var > 0.0 {
                p_two_sided((a - b) / var.sqrt())
            } else {
                1.0
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::test_images::*;

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
    fn means_that_differ_by_rounding_pass_and_larger_differences_fail() {
        // Pixels whose samples all agree: variances of rounding size (or 0)
        // on each side, and means a few f32 ulps apart, as two renderers
        // give a face of constant colour
        let a = [0.1f32, 0.2, 0.3, 0.1, 0.2, 0.3];
        let b = [
            0.1f32 * (1.0 + 2e-7),
            0.2 * (1.0 - 3e-7),
            0.3,
            0.1 * (1.0 + 1e-4),
            0.2,
            0.3,
        ];
        let va = [1e-18f32, 0.0, 1e-17, 1e-18, 0.0, 1e-17];
        let z = z_test(&a, &va, &b, &[0.0; 6], 0.01);
        // The first pixel passes; the second, 1e-4 apart (ten standard
        // deviations of the rounding allowed), fails
        assert_eq!(z.passed, 1, "{z}");
        assert_eq!(z.worst[0].0, 1, "{:?}", z.worst);
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
}
