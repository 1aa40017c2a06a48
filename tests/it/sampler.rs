//! The samplers: the Sobol sampler's numbers on the device are those of its
//! CPU twin (`lancer::render::sobol`), bit for bit; every dimension pair of
//! a path is uniform over many pixels and samples under either sampler;
//! each Sobol draw is stratified in every pixel at every power of two;
//! under the Sobol sampler renders stay a pure function of (seed, pixel,
//! sample, dimension) (same seed same image, whatever the waves; split
//! renders merge into the whole render; the megakernel gives the
//! wavefront's image, bit for bit on a CPU device, to rounding on a GPU);
//! and at equal samples its error on the
//! Cornell box is lower than the independent sampler's.

use crate::common;

use common::*;
use lancer::internal::interface::{
    RNG_DIMS_CAMERA, RNG_DIMS_PER_BOUNCE, RNG_DIM_BSDF, RNG_DIM_LENS, RNG_DIM_LIGHT, RNG_DIM_LOBE,
    RNG_DIM_PIXEL, RNG_DIM_ROULETTE, TEST_SAMPLER_ALONE,
};
use lancer::render::kernels::{Integrator, Pass, Sampler, Schedule};
use lancer::render::sobol::SobolSampler;
use lancer::render::{RenderOptions, RenderOutput, Renderer};
use lancer::scene::Scene;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Options with `sampler` and a wave of `wave_size` paths.
fn with(sampler: Sampler, wave_size: u32) -> RenderOptions {
    RenderOptions {
        sampler,
        ..options(wave_size)
    }
}

/// `file` at `width` x `height` and `spp`.
fn small(file: &str, width: u32, height: u32, spp: u32) -> Scene {
    let mut scene = load(file);
    scene.render.width = width;
    scene.render.height = height;
    scene.render.spp = spp;
    scene
}

/// One draw of the path code: its first dimension, whether it is a pair
/// (`sample_2d`) or a single number (`sample_1d`), and the pair draw it is
/// partnered with, if any (`sample_2d_partnered`: one 4D point with it).
#[derive(Clone, Copy, Debug)]
struct Draw {
    dim: u32,
    pair: bool,
    partner: Option<u32>,
}

impl Draw {
    /// The sampler test kernel's item for this draw of `sample` of `pixel`.
    fn item(&self, pixel: u32, sample: u32) -> [u32; 4] {
        [
            pixel,
            sample,
            self.dim,
            self.partner.unwrap_or(TEST_SAMPLER_ALONE),
        ]
    }
}

/// The draws of a path of `bounces` bounces, in the order and at the
/// dimensions `shaders/common/path.glsl` uses, for a camera with a lens or
/// without: the pixel position and the lens; then per bounce the light (a
/// pair: its first number picks the emitter and is reused for the point),
/// BSDF direction, lobe choice and roulette. The lens is partnered with
/// the pixel position, each bounce's light with the BSDF direction of the
/// bounce before, and the first light with the pixel position when there
/// is no lens.
fn path_draws(bounces: u32, lens: bool) -> Vec<Draw> {
    let pair = |dim, partner| Draw {
        dim,
        pair: true,
        partner,
    };
    let one = |dim| Draw {
        dim,
        pair: false,
        partner: None,
    };
    let mut draws = vec![pair(RNG_DIM_PIXEL, None)];
    if lens {
        draws.push(pair(RNG_DIM_LENS, Some(RNG_DIM_PIXEL)));
    }
    for b in 0..bounces {
        let d = RNG_DIMS_CAMERA + b * RNG_DIMS_PER_BOUNCE;
        let light_partner = match (b, lens) {
            (0, true) => None,
            (0, false) => Some(RNG_DIM_PIXEL),
            _ => Some(d - RNG_DIMS_PER_BOUNCE + RNG_DIM_BSDF),
        };
        draws.extend([
            pair(d + RNG_DIM_LIGHT, light_partner),
            pair(d + RNG_DIM_BSDF, None),
            one(d + RNG_DIM_LOBE),
            one(d + RNG_DIM_ROULETTE),
        ]);
    }
    draws
}

/// Draws the numbers of `items` (pixel, sample, dimension) on the device
/// with `sampler` and `seed`, through the sampler test kernel, as a
/// progressive render draws them when `progressive` (the Sobol sampler in
/// two halves), else as a fixed-spp render does.
fn device_numbers(
    ctx: &lancer::Context,
    sampler: Sampler,
    progressive: bool,
    seed: u32,
    items: &[[u32; 4]],
) -> Vec<[f32; 3]> {
    let mut scene = small("scenes/cornell.toml", 8, 8, 1);
    scene.render.seed = seed;
    let options = RenderOptions {
        progressive,
        ..with(sampler, 1 << 16)
    };
    let mut renderer = Renderer::new(ctx, &scene, &options).expect("renderer");
    renderer
        .sampler_numbers(items)
        .expect("sampler test kernel")
}

/// The numbers of every dimension of the paths of `samples` samples of each
/// of `pixels`, as the path code draws them (`draws`, from [`path_draws`]):
/// `[pixel][sample][dimension]`, the dimensions in the order of the draws
/// (a pair gives two).
fn path_numbers(
    ctx: &lancer::Context,
    sampler: Sampler,
    progressive: bool,
    pixels: &[u32],
    samples: u32,
    draws: &[Draw],
) -> Vec<Vec<Vec<f32>>> {
    let mut items = Vec::new();
    for &p in pixels {
        for s in 0..samples {
            items.extend(draws.iter().map(|d| d.item(p, s)));
        }
    }
    let numbers = device_numbers(ctx, sampler, progressive, 0, &items);
    let mut it = numbers.into_iter();
    pixels
        .iter()
        .map(|_| {
            (0..samples)
                .map(|_| {
                    draws
                        .iter()
                        .flat_map(|d| {
                            let [x, y, z] = it.next().unwrap();
                            if d.pair {
                                vec![x, y]
                            } else {
                                vec![z]
                            }
                        })
                        .collect()
                })
                .collect()
        })
        .collect()
}

#[test]
fn device_numbers_are_the_cpu_sobol_sampler_bit_for_bit() {
    let ctx = context();
    let pixels = [0u32, 1, 2, 63, 4095, 1 << 20, u32::MAX];
    let samples: Vec<u32> = (0..40)
        .chain([255, 256, 1000, 65535, 1 << 20, u32::MAX])
        .collect();
    let far = RNG_DIMS_CAMERA + RNG_DIMS_PER_BOUNCE * 999;
    let draws: Vec<Draw> = path_draws(3, true)
        .into_iter()
        .chain(path_draws(3, false))
        .chain([
            Draw {
                dim: far,
                pair: true,
                partner: Some(far - 4),
            },
            Draw {
                dim: u32::MAX - 1,
                pair: true,
                partner: None,
            },
        ])
        .collect();
    let mut items = Vec::new();
    for &p in &pixels {
        for &s in &samples {
            items.extend(draws.iter().map(|d| d.item(p, s)));
        }
    }
    for (seed, progressive) in [(0u32, false), (12345, false), (0, true), (12345, true)] {
        let device = device_numbers(&ctx, Sampler::Sobol, progressive, seed, &items);
        let cpu = if progressive {
            SobolSampler::in_halves(seed)
        } else {
            SobolSampler::new(seed)
        };
        let mut differ = 0;
        for (&[p, s, d, partner], got) in items.iter().zip(&device) {
            let [x, y] = if partner == TEST_SAMPLER_ALONE {
                cpu.sample_2d(p, s, d)
            } else {
                cpu.sample_2d_partnered(p, s, d, partner)
            };
            let want = [x, y, cpu.sample_1d(p, s, d)];
            if want.map(f32::to_bits) != got.map(f32::to_bits) {
                if differ == 0 {
                    println!(
                        "first difference: pixel {p} sample {s} dim {d} partner {partner}: \
                         device {got:?}, cpu {want:?}"
                    );
                }
                differ += 1;
            }
        }
        println!(
            "seed {seed}, progressive {progressive}: {} items, {differ} differ",
            items.len()
        );
        assert_eq!(
            differ, 0,
            "seed {seed}, progressive {progressive}: the device's Sobol numbers differ from \
             the CPU's"
        );
    }
    // The independent sampler draws other numbers
    let independent = device_numbers(&ctx, Sampler::Independent, false, 0, &items[..64]);
    let sobol = device_numbers(&ctx, Sampler::Sobol, false, 0, &items[..64]);
    assert_ne!(independent, sobol);
}

/// χ² of `points` in a grid of [0, 1)^2 of `nx` columns and `ny` rows
/// against the uniform distribution, and its p-value.
fn chi2_uniform(points: impl Iterator<Item = (f32, f32)>, nx: usize, ny: usize) -> (f64, f64) {
    let mut counts = vec![0u64; nx * ny];
    let mut total = 0u64;
    for (x, y) in points {
        assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
        let (i, j) = ((x * nx as f32) as usize, (y * ny as f32) as usize);
        counts[j * nx + i] += 1;
        total += 1;
    }
    let cells = counts.len();
    let expected = total as f64 / cells as f64;
    let chi2: f64 = counts
        .iter()
        .map(|&c| (c as f64 - expected).powi(2) / expected)
        .sum();
    let p = ChiSquared::new((cells - 1) as f64).unwrap().sf(chi2);
    (chi2, p)
}

/// Every dimension and every pair of dimensions of a path's first three
/// bounces (22 dimensions and 231 pairs with a lens, 20 and 190 without)
/// is uniform: a χ² test on an 8 x 8 grid (64 bins for single dimensions)
/// over 64 pixels x 256 samples, with Šidák's correction to 1% in all,
/// under each sampler. The Sobol sampler's pairs within one draw are far
/// more even than chance (a tiny χ²); the test is one-sided, as uniformity
/// asks.
#[test]
fn every_dimension_pair_of_a_path_is_uniform() {
    let ctx = context();
    let pixels: Vec<u32> = (0..64).map(|i| i * 131 + 7).collect();
    let samples = 256;
    // Both samplers as a fixed-spp render draws them, and the Sobol
    // sampler's two halves of a progressive render
    let modes = [
        (Sampler::Independent, false),
        (Sampler::Sobol, false),
        (Sampler::Sobol, true),
    ];
    for ((sampler, progressive), lens) in modes.into_iter().flat_map(|m| [(m, true), (m, false)]) {
        let numbers = path_numbers(
            &ctx,
            sampler,
            progressive,
            &pixels,
            samples,
            &path_draws(3, lens),
        );
        let dims = numbers[0][0].len();
        assert_eq!(dims, if lens { 22 } else { 20 });
        let values = |d: usize| numbers.iter().flatten().map(move |v| v[d]);
        let tests = dims + dims * (dims - 1) / 2;
        let alpha = 1.0 - 0.99f64.powf(1.0 / tests as f64);
        let mut worst = (f64::INFINITY, String::new());
        let mut check = |what: String, (chi2, p): (f64, f64)| {
            if p < worst.0 {
                worst = (p, format!("{what}: chi2 {chi2:.1}"));
            }
            assert!(
                p >= alpha,
                "{sampler} (progressive {progressive}): {what} is not uniform: chi2 {chi2:.1}, \
                 p {p:.2e}"
            );
        };
        for d in 0..dims {
            check(
                format!("dimension {d}"),
                chi2_uniform(values(d).zip(std::iter::repeat(0.0)), 64, 1),
            );
            for e in d + 1..dims {
                check(
                    format!("dimensions {d}, {e}"),
                    chi2_uniform(values(d).zip(values(e)), 8, 8),
                );
            }
        }
        println!(
            "{sampler}, lens {lens}: {tests} tests at alpha {alpha:.1e} pass; \
             the lowest p is {:.3} ({})",
            worst.0, worst.1
        );
    }
}

/// Tells whether `points` (2^k of them) are a (t, k, 2)-net: 2^t points in
/// each elementary interval 2^-a x 2^-(k-t-a) of [0, 1)^2, for every a
/// (with t = 0, one point in each interval of area 2^-k).
fn is_net(points: &[(f32, f32)], k: u32, t: u32) -> bool {
    let m = k.saturating_sub(t);
    (0..=m).all(|a| {
        let mut count = vec![0u32; 1 << m];
        for &(x, y) in points {
            let col = (x * (1u32 << a) as f32) as usize;
            let row = (y * (1u32 << (m - a)) as f32) as usize;
            count[(row << a) | col] += 1;
        }
        count.iter().all(|&c| c == 1 << (k - m))
    })
}

/// On the device, under the Sobol sampler: in every pixel of a fixed-spp
/// render, and in each of the two halves of a pixel of a progressive
/// render (the even samples and the odd ones, independent sequences),
/// every draw of a path (pairs and single numbers) is stratified over the
/// first 2^k samples for k = 0..7 and over later aligned blocks of 2^k, so
/// that a progressive render's every prefix of 2^(k+1) samples is: a pair
/// drawn alone is a (0, k, 2)-net, a partnered pair (Sobol dimensions 2
/// and 3) a (2, k, 2)-net whose two numbers are each stratified alone, and
/// a single number puts one point in each interval 2^-k. With a lens and
/// without. The independent sampler's draws are not, or the check would
/// mean nothing.
#[test]
fn sobol_draws_are_stratified_in_every_pixel_at_every_power_of_two() {
    let ctx = context();
    let pixels: Vec<u32> = (0..16).map(|i| i * 977 + 3).collect();
    let check = |sampler: Sampler, progressive: bool, draws: &[Draw]| -> usize {
        let numbers = path_numbers(&ctx, sampler, progressive, &pixels, 256, draws);
        let mut failed = 0;
        let (count, stride) = if progressive { (2, 2) } else { (1, 1) };
        let sequences = numbers.iter().flat_map(|pixel| {
            (0..count)
                .map(move |first| pixel.iter().skip(first).step_by(stride).collect::<Vec<_>>())
        });
        for pixel in sequences {
            let mut column = 0;
            for d in draws {
                for (k, block) in [
                    (0u32, 0u32),
                    (2, 0),
                    (4, 0),
                    (6, 0),
                    (7, 0),
                    (4, 7),
                    (5, 2),
                    (6, 1),
                ] {
                    let samples = &pixel[(block << k) as usize..((block + 1) << k) as usize];
                    let coordinate =
                        |c: usize| -> Vec<f32> { samples.iter().map(|v| v[column + c]).collect() };
                    // One number alone puts one point in each interval 2^-k
                    let stratified = |xs: Vec<f32>| {
                        let mut cells: Vec<u32> =
                            xs.iter().map(|x| (x * (1u32 << k) as f32) as u32).collect();
                        cells.sort_unstable();
                        cells.dedup();
                        cells.len() == 1 << k
                    };
                    let net = if !d.pair {
                        stratified(coordinate(0))
                    } else {
                        let points: Vec<(f32, f32)> =
                            coordinate(0).into_iter().zip(coordinate(1)).collect();
                        match d.partner {
                            None => is_net(&points, k, 0),
                            Some(_) => {
                                is_net(&points, k, 2)
                                    && stratified(coordinate(0))
                                    && stratified(coordinate(1))
                            }
                        }
                    };
                    failed += usize::from(!net);
                }
                column += if d.pair { 2 } else { 1 };
            }
        }
        failed
    };
    for lens in [true, false] {
        let draws = path_draws(2, lens);
        for progressive in [false, true] {
            assert_eq!(
                check(Sampler::Sobol, progressive, &draws),
                0,
                "lens {lens}, progressive {progressive}: Sobol draws that are not stratified"
            );
        }
        let independent = check(Sampler::Independent, false, &draws);
        println!("lens {lens}, independent sampler: {independent} blocks of draws not stratified");
        assert!(independent > 0);
    }
}

/// Asserts that two outputs have the same mean and variance, bit for bit.
fn assert_identical(a: &RenderOutput, b: &RenderOutput, what: &str) {
    assert_eq!(differing_bits(&a.mean, &b.mean), 0, "{what}: means differ");
    assert_eq!(
        differing_bits(&a.var_of_mean, &b.var_of_mean),
        0,
        "{what}: variances differ"
    );
}

#[test]
fn sobol_renders_are_a_pure_function_of_the_seed() {
    let ctx = context();
    let mut scene = small("scenes/dof.toml", 32, 24, 6);
    let a = render(&ctx, &scene, &with(Sampler::Sobol, 1 << 14));
    assert_eq!(a.stats.sampler, Sampler::Sobol);
    assert!(a.mean.iter().any(|&v| v > 0.0), "a black image");
    assert_identical(
        &a,
        &render(&ctx, &scene, &with(Sampler::Sobol, 1 << 14)),
        "a second render",
    );
    // Waves of 300 paths start mid-image and split a pixel's samples
    assert_identical(
        &a,
        &render(&ctx, &scene, &with(Sampler::Sobol, 300)),
        "300-path waves",
    );
    // A progressive render draws its even and odd samples as two
    // sequences (the error estimate's halves): other numbers, the same
    // image in any steps
    let progressive = RenderOptions {
        progressive: true,
        ..with(Sampler::Sobol, 1 << 14)
    };
    let whole = render(&ctx, &scene, &progressive);
    assert!(differing_bits(&a.mean, &whole.mean) > 0);
    let mut renderer = Renderer::new(&ctx, &scene, &progressive).unwrap();
    renderer.restart().unwrap();
    for spp in [1, 2, 5, 6] {
        renderer.render_to(spp, None).unwrap();
    }
    assert_identical(&whole, &renderer.output().unwrap(), "rendered in steps");
    // Another sampler or another seed changes the image
    let independent = render(&ctx, &scene, &with(Sampler::Independent, 1 << 14));
    assert!(differing_bits(&a.mean, &independent.mean) > 0);
    assert_eq!(independent.stats.sampler, Sampler::Independent);
    scene.render.seed = 1;
    let other = render(&ctx, &scene, &with(Sampler::Sobol, 1 << 14));
    assert!(differing_bits(&a.mean, &other.mean) > 0);
}

/// Parts of a Sobol render (`render_samples`, as `--samples A..B` renders
/// them) merge into the whole render's image, as tests/it/split.rs checks for
/// the independent sampler: the same samples, summed in another grouping.
#[test]
fn sobol_split_render_merges_into_the_whole_render() {
    let ctx = context();
    let scene = small("scenes/cornell.toml", 48, 40, 16);
    let options = with(Sampler::Sobol, 1 << 14);
    let mut renderer = Renderer::new(&ctx, &scene, &options).unwrap();
    let mut parts = Vec::new();
    for (first, end) in [(13, 16), (0, 3), (8, 13), (3, 8)] {
        renderer.render_samples(first, end, None).unwrap();
        let (sums, nonfinite) = renderer.film_sums().unwrap();
        let part = lancer::io::film::FilmPart {
            scene_hash: 1,
            sampler: Sampler::Sobol,
            first,
            end,
            spp: 16,
            width: 48,
            height: 40,
            nonfinite,
            sum: sums.sum,
            sum_sq: sums.sum_sq,
            sum_odd: sums.sum_odd,
        };
        parts.push((std::path::PathBuf::from(format!("{first}..{end}")), part));
    }
    let merged = lancer::io::film::merge(&parts).unwrap().image;
    let whole = render(&ctx, &scene, &options);
    assert!(whole.mean.iter().any(|&v| v > 0.0), "a black image");
    let (ulps_mean, ulps_var) = (
        max_ulps(&merged.mean, &whole.mean),
        max_ulps(&merged.var_of_mean, &whole.var_of_mean),
    );
    println!(
        "merge vs whole: {} of {} means differ (max {ulps_mean} ulps), {} variances differ (max {ulps_var} ulps)",
        differing_bits(&merged.mean, &whole.mean),
        whole.mean.len(),
        differing_bits(&merged.var_of_mean, &whole.var_of_mean)
    );
    assert!(ulps_mean <= 1.0, "means differ by {ulps_mean} ulps");
    assert!(ulps_var <= 1.0, "variances differ by {ulps_var} ulps");
    let ulps_error = max_ulps(&merged.error, &whole.error_estimate);
    assert!(
        ulps_error <= 1.0,
        "error estimates differ by {ulps_error} ulps"
    );
    // The parts are the Sobol sampler's: the independent sampler's whole render differs
    let independent = render(&ctx, &scene, &with(Sampler::Independent, 1 << 14));
    assert!(max_ulps(&merged.mean, &independent.mean) > 1.0);
}

/// Renders `scene` with `options` under both schedules and asserts the
/// same image, bit for bit.
fn assert_schedules_agree(ctx: &lancer::Context, file: &str, label: &str, options: &RenderOptions) {
    let scene = small(file, 24, 24, 4);
    let run = |schedule| {
        let out = render(
            ctx,
            &scene,
            &RenderOptions {
                schedule,
                ..options.clone()
            },
        );
        let mega = out
            .stats
            .records
            .iter()
            .filter(|r| r.pass == Pass::Megakernel)
            .count();
        assert_eq!(mega > 0, schedule == Schedule::Megakernel);
        out
    };
    let (wave, mega) = (run(Schedule::Wavefront), run(Schedule::Megakernel));
    assert!(
        wave.mean.iter().any(|&v| v > 0.0),
        "{file} ({label}): black image"
    );
    for (what, a, b) in [
        ("mean", &wave.mean, &mega.mean),
        ("variance", &wave.var_of_mean, &mega.var_of_mean),
    ] {
        if let Some(how) = kernels_disagree(ctx, a, b) {
            panic!("{file} ({label}): the schedules' {what} values disagree: {how}");
        }
    }
    println!("{file} ({label}): agree");
}

/// The megakernel gives the wavefront's image under the Sobol sampler (bit
/// for bit on a CPU device, to rounding on a GPU), on every example and test scene, as tests/it/schedules.rs checks
/// for the default sampler.
#[test]
fn megakernel_gives_the_wavefront_image_under_sobol() {
    let ctx = context();
    for file in example_and_test_scenes() {
        assert_schedules_agree(
            &ctx,
            &file,
            "scene features",
            &with(Sampler::Sobol, 1 << 14),
        );
    }
    for file in [
        "scenes/cornell.toml",
        "scenes/glass.toml",
        "scenes/dof.toml",
    ] {
        let all = RenderOptions {
            all_features: true,
            ..with(Sampler::Sobol, 1 << 14)
        };
        assert_schedules_agree(&ctx, file, "all features", &all);
        let bsdf = RenderOptions {
            integrator: Integrator::Bsdf,
            f32_film: true,
            ..with(Sampler::Sobol, 1 << 14)
        };
        assert_schedules_agree(&ctx, file, "bsdf, f32 film", &bsdf);
        assert_schedules_agree(&ctx, file, "300-path waves", &with(Sampler::Sobol, 300));
    }
}

/// At equal samples the Sobol sampler's error on the Cornell box (64 x 64,
/// against Mitsuba 3's 65,536-spp reference) is lower than the independent
/// sampler's, at a power of two (64 spp) and at a count that is not one
/// (48 spp, rendered progressively, where the independent sampler cannot
/// stratify). The mean relMSE of 4 seeds; measured ratios are about 0.66
/// and 0.64 (two independent halves of 32 and 24 samples; see
/// render::sobol), asserted loosely (below 0.8). examples/sampler_error.rs
/// measures 256 spp and the depth-of-field scene.
#[test]
fn sobol_has_less_error_than_independent_at_equal_samples() {
    let ctx = context();
    let (w, h, reference) =
        lancer::io::image_file::read_exr(&repo("tests/reference/cornell.exr")).unwrap();
    for (spp, progressive) in [(64, false), (48, true)] {
        let mut error = [0.0f64; 2];
        for (e, sampler) in error.iter_mut().zip(Sampler::ALL) {
            for seed in 0..4 {
                let mut scene = small("scenes/cornell.toml", w, h, spp);
                scene.render.seed = seed;
                let options = RenderOptions {
                    progressive,
                    ..with(sampler, 1 << 18)
                };
                let out = render(&ctx, &scene, &options);
                *e += lancer::util::metrics::rel_mse(&out.mean, &reference) / 4.0;
            }
        }
        let ratio = error[1] / error[0];
        println!(
            "Cornell box {w}x{h}, {spp} spp{}: relMSE independent {:.3e}, sobol {:.3e}, ratio {ratio:.2}",
            if progressive { ", progressive" } else { "" },
            error[0],
            error[1]
        );
        assert!(
            ratio < 0.8,
            "{spp} spp: Sobol / independent relMSE = {ratio:.2}"
        );
    }
}
