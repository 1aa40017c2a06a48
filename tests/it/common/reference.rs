//! Statistical comparison of a render with a stored reference made by an
//! independent renderer (Mitsuba 3: tools/mitsuba_reference.py for lancer
//! scenes, tools/mitsuba_xml_reference.py for XML scenes): a z-test with
//! Šidák correction at alpha = 0.01, as in Mitsuba 3's render tests, on 2x2
//! pixel blocks rather than single pixels, with a variance estimate for
//! lancer that is robust to heavy-tailed samples (see [`compare`]).
//!
//! When a comparison fails, [`assert_matches`] writes a per-pixel z-map PNG
//! and lancer's mean and variance EXRs into `CARGO_TARGET_TMPDIR` and prints
//! their paths.

use super::{block_average, repo};
use lancer::analysis::ztest::{z_test, ZTest};
use lancer::render::RenderOutput;

/// Share of blocks that must pass the z-test.
pub const MIN_PASS_FRACTION: f64 = 0.995;
/// Largest relative difference of the image means.
pub const MAX_MEAN_REL_DIFF: f64 = 0.01;
/// Side, in pixels, of the square blocks the z-test compares.
pub const BLOCK: usize = 2;

/// A mean image and the variance of each value of it, interleaved RGB.
#[derive(Clone)]
pub struct Estimate {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Mean, interleaved RGB.
    pub mean: Vec<f32>,
    /// Variance of each mean value, interleaved RGB.
    pub var: Vec<f32>,
}

impl Estimate {
    /// Averages `k` x `k` pixel blocks: the block mean is the mean of its
    /// pixels, and its variance is the sum of theirs over n² (the pixels'
    /// estimates are independent). Blocks cut by the right or bottom edge
    /// average the pixels they have.
    pub fn blocks(&self, k: usize) -> Estimate {
        let (width, height, mean, var) =
            block_average(self.width, self.height, &self.mean, &self.var, k);
        Estimate {
            width,
            height,
            mean,
            var,
        }
    }

    /// Raises each variance to the median of its 3 x 3 neighbourhood (the
    /// neighbours inside the image, itself included), per channel.
    pub fn variance_floored_by_neighbours(&self) -> Estimate {
        let (w, h) = (self.width as isize, self.height as isize);
        let mut var = self.var.clone();
        let mut around = Vec::with_capacity(9);
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    around.clear();
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let (nx, ny) = (x + dx, y + dy);
                            if (0..w).contains(&nx) && (0..h).contains(&ny) {
                                around.push(self.var[3 * (ny * w + nx) as usize + c]);
                            }
                        }
                    }
                    around.sort_by(f32::total_cmp);
                    let i = 3 * (y * w + x) as usize + c;
                    var[i] = var[i].max(around[around.len() / 2]);
                }
            }
        }
        Estimate {
            var,
            ..self.clone()
        }
    }

    /// The image without a frame `border` pixels wide on every side.
    pub fn cropped(&self, border: usize) -> Estimate {
        let (w, h) = (self.width - 2 * border, self.height - 2 * border);
        let crop = |img: &[f32]| -> Vec<f32> {
            (border..border + h)
                .flat_map(|y| {
                    let row = 3 * (y * self.width + border);
                    img[row..row + 3 * w].iter().copied()
                })
                .collect()
        };
        Estimate {
            width: w,
            height: h,
            mean: crop(&self.mean),
            var: crop(&self.var),
        }
    }

    /// The image mirrored left to right.
    pub fn mirrored(&self) -> Estimate {
        let flip = |img: &[f32]| -> Vec<f32> {
            img.chunks(3 * self.width)
                .flat_map(|row| row.chunks(3).rev().flatten().copied().collect::<Vec<_>>())
                .collect()
        };
        Estimate {
            mean: flip(&self.mean),
            var: flip(&self.var),
            ..self.clone()
        }
    }

    /// The image of a scene whose every emitter is `s` times brighter:
    /// radiance is linear in emission (light selection goes by relative
    /// power), so with the same seed every sample scales by `s`.
    pub fn scaled(&self, s: f32) -> Estimate {
        Estimate {
            mean: self.mean.iter().map(|v| v * s).collect(),
            var: self.var.iter().map(|v| v * s * s).collect(),
            ..self.clone()
        }
    }
}

/// Lancer's output as an [`Estimate`].
pub fn estimate(out: &RenderOutput) -> Estimate {
    Estimate {
        width: out.width as usize,
        height: out.height as usize,
        mean: out.mean.clone(),
        var: out.var_of_mean.clone(),
    }
}

/// Reads a stored reference: the mean and the variance of the mean.
pub fn reference(name: &str) -> Estimate {
    let (w, h, mean) =
        lancer::io::image_file::read_exr(&repo(&format!("tests/reference/{name}.exr")))
            .expect("reference mean");
    let (_, _, var) =
        lancer::io::image_file::read_exr(&repo(&format!("tests/reference/{name}.var.exr")))
            .expect("reference variance");
    Estimate {
        width: w as usize,
        height: h as usize,
        mean,
        var,
    }
}

/// Compares a render with a reference.
///
/// The verdict is a z-test on 2x2 blocks, in which lancer's variance of each
/// block mean is at least the median of those of the 3x3 blocks around it.
/// Why not the plain per-pixel test: lancer's per-pixel variance is the
/// sample variance of its 512 to 1024 samples. Where the samples are heavy
/// tailed (caustics that only BSDF sampling finds, Russian roulette's 1/q
/// weights, pixels that a blurred edge reaches with a few samples in a
/// thousand), that estimate is unbiased on average but small exactly in the
/// pixels that drew none of the rare large samples, and those pixels also
/// have a low mean: they fail with large negative z although lancer agrees
/// with Mitsuba at high spp (dielectric at 16384 spp, dof at 8192 spp: every
/// pixel passes). Blocks quadruple the samples per tested value; the
/// neighbourhood median gives each block a variance that does not depend on
/// its own luck, and, being a median, does not leak the large variance of an
/// edge (a light's outline) into the blocks beside it. Raising the variance
/// can only make blocks pass, so each test also checks that a mirrored image
/// and a 5% brighter light fail.
///
/// The per-pixel test on lancer's raw variance is returned too, for
/// information.
pub fn compare(test: &Estimate, reference: &Estimate) -> (ZTest, ZTest) {
    let a = test.blocks(BLOCK).variance_floored_by_neighbours();
    let b = reference.blocks(BLOCK);
    let blocks = z_test(&a.mean, &a.var, &b.mean, &b.var, 0.01);
    let pixels = z_test(&test.mean, &test.var, &reference.mean, &reference.var, 0.01);
    (blocks, pixels)
}

/// Tells whether a comparison passes both criteria.
pub fn passes(z: &ZTest) -> bool {
    z.pass_fraction >= MIN_PASS_FRACTION && z.mean_rel_diff.abs() <= MAX_MEAN_REL_DIFF
}

/// Signed z-score of the channel with the largest |z| in each pixel:
/// (test - reference) / sqrt(var_test + var_ref).
pub fn z_scores(test: &Estimate, reference: &Estimate) -> Vec<f64> {
    test.mean
        .chunks(3)
        .zip(test.var.chunks(3))
        .zip(reference.mean.chunks(3).zip(reference.var.chunks(3)))
        .map(|((a, va), (b, vb))| {
            (0..3)
                .map(|c| {
                    let v = f64::from(va[c]).max(0.0) + f64::from(vb[c]).max(0.0);
                    let d = f64::from(a[c]) - f64::from(b[c]);
                    if v > 0.0 {
                        d / v.sqrt()
                    } else if d == 0.0 {
                        0.0
                    } else {
                        d.signum() * f64::INFINITY
                    }
                })
                .fold(0.0f64, |z, zc| {
                    if zc.abs() > z.abs() || zc.is_nan() {
                        zc
                    } else {
                        z
                    }
                })
        })
        .collect()
}

/// |z| of one channel at which a value fails the test `z` made: its p times
/// 3 (Bonferroni over the channels) falls below the per-value threshold.
pub fn z_threshold(z: &ZTest) -> f64 {
    let target = z.alpha_per_pixel / 3.0;
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if lancer::analysis::ztest::erfc(mid / std::f64::consts::SQRT_2) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Writes, for a failed comparison, the per-pixel z-map of lancer's raw
/// variance as a PNG (red: lancer brighter, blue: lancer darker, full at
/// |z| >= 8; a green tint marks the pixels beyond the per-pixel test's
/// threshold), and lancer's mean and variance of the mean as EXR, into the
/// test's temporary folder, and prints the paths.
pub fn dump_failure(name: &str, test: &Estimate, reference: &Estimate, per_pixel: &ZTest) {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let z_fail = z_threshold(per_pixel);
    let zmap: Vec<f32> = z_scores(test, reference)
        .iter()
        .flat_map(|&zv| {
            let m = (zv.abs() / 8.0).min(1.0) as f32;
            let g = if zv.abs() >= z_fail || zv.is_nan() {
                0.25
            } else {
                0.0
            };
            if zv > 0.0 {
                [m, g, 0.0]
            } else {
                [0.0, g, m]
            }
        })
        .collect();
    let (w, h) = (test.width as u32, test.height as u32);
    // A name may hold folders (`mitsuba/mask`): make them
    if let Some(parent) = dir.join(name).parent() {
        let _ = std::fs::create_dir_all(parent);
    }
    let files = [
        (dir.join(format!("{name}.zmap.png")), zmap),
        (dir.join(format!("{name}.lancer.exr")), test.mean.clone()),
        (dir.join(format!("{name}.lancer.var.exr")), test.var.clone()),
    ];
    for (path, img) in &files {
        match lancer::io::image_file::write_image(path, w, h, img) {
            Ok(()) => println!("{name}: wrote {}", path.display()),
            Err(e) => println!("{name}: could not write {}: {e:#}", path.display()),
        }
    }
    println!("{name}: per-pixel |z| threshold per channel {z_fail:.2}");
}

/// Compares lancer with the reference, prints both tests, dumps the images
/// when the verdict fails, and asserts that it passes.
pub fn assert_matches(name: &str, test: &Estimate, reference: &Estimate) {
    let (z, z_px) = compare(test, reference);
    println!("{name}: lancer vs Mitsuba 3, {BLOCK}x{BLOCK} blocks: {z}");
    println!("{name}: per pixel (information only): {z_px}");
    if !passes(&z) {
        dump_failure(name, test, reference, &z_px);
    }
    assert!(
        passes(&z),
        "{name} differs from the Mitsuba reference ({BLOCK}x{BLOCK} blocks): {z}"
    );
}

/// Asserts that a mirrored image fails, and that a 5% brighter light fails
/// the z-test on its own, without the image-mean criterion.
pub fn assert_wrong_images_fail(name: &str, test: &Estimate, reference: &Estimate) {
    let (z_mirrored, _) = compare(&test.mirrored(), reference);
    println!("{name}: mirrored: {z_mirrored}");
    assert!(
        !passes(&z_mirrored),
        "{name}: a mirrored image passed: {z_mirrored}"
    );
    let (z_bright, _) = compare(&test.scaled(1.05), reference);
    println!("{name}: 5% brighter light: {z_bright}");
    assert!(
        z_bright.pass_fraction < MIN_PASS_FRACTION,
        "{name}: a 5% brighter light passed the z-test: {z_bright}"
    );
}
