//! Helpers shared by the GPU tests. Every GPU test needs a Vulkan device:
//! when none is found the test fails with the install hint, never skips.
#![allow(dead_code)]

pub mod brute_force;
pub mod materials;
pub mod reference;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use lancer::render::{RenderOptions, RenderOutput, Renderer};
use lancer::scene::Scene;
use lancer::{Context, ContextOptions};

/// Path of a file under the crate root.
pub fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// Opens the default device (lavapipe in CI), under validation when
/// LANCER_VALIDATION=1. Fails the test when there is no device.
pub fn context() -> Context {
    match Context::new(&ContextOptions {
        device: std::env::var("LANCER_DEVICE").ok(),
        validation: false,
    }) {
        Ok(ctx) => ctx,
        Err(e) => panic!("GPU tests need a Vulkan device: {e}"),
    }
}

/// Loads a scene from the repo.
pub fn load(path: &str) -> Scene {
    lancer::scene::load(&repo(path)).unwrap_or_else(|e| panic!("loading {path}: {e}"))
}

/// The tables a scene written in a test starts with: `[render]` of
/// `width` x `height` pixels, `spp` and `max_depth`; `[camera]` with the
/// given settings (`key = value` lines, without the last newline); and a
/// uniform `[environment]` of `radiance` (a TOML array). Materials and
/// objects follow. One setting a line, so errors name the same lines.
pub fn scene_header(
    (width, height): (u32, u32),
    spp: u32,
    max_depth: u32,
    camera: &str,
    radiance: &str,
) -> String {
    format!(
        "[render]\nwidth = {width}\nheight = {height}\nspp = {spp}\nmax_depth = {max_depth}\n\
         [camera]\n{camera}\n\
         [environment]\nradiance = {radiance}\n"
    )
}

/// Reads a scene from TOML `text` as if it were the file
/// `tests/scenes/inline.toml`: relative paths start in `tests/scenes/`, and
/// errors name `inline.toml` and the line.
pub fn load_inline(text: &str) -> Result<Scene, String> {
    lancer::scene::load_str(text, &repo("tests/scenes/inline.toml")).map_err(|e| e.to_string())
}

/// A fresh, empty folder `name` under cargo's scratch space for tests, in a
/// folder of this test binary's own.
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(env!("CARGO_CRATE_NAME"))
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

/// Renders `scene` and checks the things every render must satisfy: no
/// NaN or Inf in the output, no non-finite sample dropped, and no
/// validation error.
pub fn render(ctx: &Context, scene: &Scene, options: &RenderOptions) -> RenderOutput {
    let mut renderer = Renderer::new(ctx, scene, options).expect("renderer");
    let out = renderer.render(None).expect("render");
    check_finite(&out);
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
    out
}

/// Asserts that an output holds no NaN or Inf and dropped no sample.
pub fn check_finite(out: &RenderOutput) {
    assert_eq!(
        lancer::util::metrics::count_nonfinite(&out.mean),
        0,
        "non-finite pixels in the mean"
    );
    assert_eq!(
        lancer::util::metrics::count_nonfinite(&out.var_of_mean),
        0,
        "non-finite variances"
    );
    assert_eq!(
        out.stats.nonfinite_samples, 0,
        "samples with NaN or Inf radiance were dropped"
    );
}

/// Default options with a given wave size.
pub fn options(wave_size: u32) -> RenderOptions {
    RenderOptions {
        wave_size: Some(wave_size),
        ..RenderOptions::default()
    }
}

/// The `*.toml` files of the given repo folders, as `folder/name.toml`,
/// sorted. The folders are listed when the test runs, so a new scene is
/// covered without editing any test.
pub fn scene_files(dirs: &[&str]) -> Vec<String> {
    let mut files = Vec::new();
    for dir in dirs {
        let path = repo(dir);
        let entries =
            std::fs::read_dir(&path).unwrap_or_else(|e| panic!("listing {}: {e}", path.display()));
        for entry in entries {
            let name = entry.expect("reading a scene folder").file_name();
            let name = name.to_string_lossy();
            if name.ends_with(".toml") {
                files.push(format!("{dir}/{name}"));
            }
        }
    }
    files.sort();
    files
}

/// Every example and test scene (`scenes/` and `tests/scenes/`), checked to
/// be at least the ten there are, so a moved folder fails loudly.
pub fn example_and_test_scenes() -> Vec<String> {
    let files = scene_files(&["scenes", "tests/scenes"]);
    assert!(
        files.len() >= 10,
        "expected the example and test scenes, found {files:?}"
    );
    files
}

/// Runs the `lancer` binary from the crate root with `args` and extra
/// environment variables, and returns what it printed and its status.
pub fn lancer(args: &[&str], envs: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lancer"));
    cmd.args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    for (k, v) in envs {
        cmd.env(k, v);
    }
    cmd.output().expect("run lancer")
}

/// What a run of the binary printed on stderr.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Averages `k` x `k` pixel blocks of a `width` x `height` RGB image: the
/// block mean is the mean of its pixels, and its variance of the mean is the
/// sum of theirs over n² (the pixels' estimates are independent). Blocks cut
/// by the right or bottom edge average the pixels they have. Returns the
/// block image's size, means and variances.
pub fn block_average(
    width: usize,
    height: usize,
    mean: &[f32],
    var: &[f32],
    k: usize,
) -> (usize, usize, Vec<f32>, Vec<f32>) {
    let (bw, bh) = (width.div_ceil(k), height.div_ceil(k));
    let mut bmean = vec![0.0f64; bw * bh * 3];
    let mut bvar = vec![0.0f64; bw * bh * 3];
    let mut count = vec![0u32; bw * bh];
    for y in 0..height {
        for x in 0..width {
            let b = (y / k) * bw + x / k;
            count[b] += 1;
            for c in 0..3 {
                bmean[3 * b + c] += f64::from(mean[3 * (y * width + x) + c]);
                bvar[3 * b + c] += f64::from(var[3 * (y * width + x) + c]);
            }
        }
    }
    for (b, &n) in count.iter().enumerate() {
        let n = f64::from(n);
        for c in 0..3 {
            bmean[3 * b + c] /= n;
            bvar[3 * b + c] /= n * n;
        }
    }
    let to_f32 = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect();
    (bw, bh, to_f32(bmean), to_f32(bvar))
}

/// Largest |a - b| in units of the f32 spacing at max(|a|, |b|).
pub fn max_ulps(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let m = x.abs().max(y.abs());
            let ulp = f32::from_bits(m.to_bits() + 1) - m;
            f64::from((x - y).abs()) / f64::from(ulp)
        })
        .fold(0.0, f64::max)
}

/// How many values of two images differ in any bit (NaN payloads included).
pub fn differing_bits(a: &[f32], b: &[f32]) -> usize {
    assert_eq!(a.len(), b.len(), "images differ in length");
    a.iter()
        .zip(b)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count()
}

/// How the same render by two different kernels (the megakernel and the
/// wavefront's passes) disagrees, if it does by more than `ctx`'s device
/// allows; `None` when they agree. A CPU device (lavapipe) compiles the
/// shared GLSL alike in both, so every bit must match. A GPU's compiler
/// fuses and rounds the same expressions differently in different kernels
/// (on an NVIDIA H200, max |a - b| 3e-6 and relMSE below 1e-13 for the
/// means at 64 x 64, 16 spp, and relMSE up to 1.6e-10 for the variances,
/// which subtract sums of squares; forbidding fused multiply-adds, measured
/// there, left glass and rough dielectrics still apart), so there the two
/// must agree to rounding: relMSE (sum of squared differences over sum of
/// squares) below 1e-8, and every value within 1e-4 of the largest. A different estimator, a
/// different sample or a lost path is far outside both.
pub fn kernels_disagree(ctx: &Context, a: &[f32], b: &[f32]) -> Option<String> {
    let differ = differing_bits(a, b);
    if differ == 0 {
        return None;
    }
    let first = (0..a.len()).find(|&i| a[i].to_bits() != b[i].to_bits());
    let bits = format!(
        "{differ} of {} values differ in their bits; first (index, a, b): {:?}",
        a.len(),
        first.map(|i| (i, a[i], b[i]))
    );
    if ctx.info().kind == lancer::DeviceKind::Cpu {
        return Some(format!("{bits} (a CPU device must give the same bits)"));
    }
    let (mut diff2, mut sum2, mut max_diff, mut max_abs) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (f64::from(x), f64::from(y));
        diff2 += (x - y) * (x - y);
        sum2 += x * x;
        max_diff = max_diff.max((x - y).abs());
        max_abs = max_abs.max(x.abs()).max(y.abs());
    }
    let rel_mse = diff2 / sum2.max(f64::MIN_POSITIVE);
    let agree = rel_mse.is_finite() && rel_mse < 1e-8 && max_diff <= 1e-4 * max_abs;
    (!agree).then(|| {
        format!("{bits}; relMSE {rel_mse:.3e}, max |a - b| {max_diff:.3e} of largest {max_abs:.3e}")
    })
}
