//! `lancer converge`: error against time and against samples, for one or
//! more render settings, on one reference.
//!
//! Each variant and seed renders progressively (the film keeps
//! accumulating) and at 1, 2, 4, ... samples per pixel, and at the end, the
//! film is read back and measured against the reference. Render time counts
//! only the waves; reading the film back and computing the metrics are timed
//! apart. A warm-up sample before each run keeps kernel compilation out of
//! the render time (llvmpipe compiles a kernel at its first dispatch: about
//! a second for `features=all` on Mesa 22.3). The records go to
//! [`crate::analysis::converge`] for the CSV, JSON, plots and table.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, ensure, Context as _, Result};

use crate::analysis::compare::variance_path;
use crate::analysis::converge::{efficiency, Step};
use crate::analysis::metrics::Metrics;
use crate::gpu::LightSelection;
use crate::render::adaptive::{self, Goal, ADAPTIVE_MIN_SPP};
use crate::render::kernels::{Integrator, Sampler};
use crate::render::{OnWave, RenderOptions, Renderer};
use crate::scene::Scene;
use crate::util::metrics::predicted_rel_mse;
use crate::vk::Context;

/// The keys `--vary` understands, with what each takes.
pub const VARY_KEYS: &[(&str, &str)] = &[
    ("integrator", "nee or bsdf"),
    ("max_depth", "an integer >= 1"),
    ("rr_depth", "an integer >= 1"),
    ("features", "scene or all"),
    ("wave_size", "an integer >= 1"),
    ("sampler", "independent or sobol"),
    ("light_selection", "power or uniform"),
    ("adaptive", "off or on"),
];

/// One render setting `--vary` changes.
#[derive(Debug, Clone, PartialEq)]
enum Setting {
    Integrator(Integrator),
    MaxDepth(u32),
    RrDepth(u32),
    AllFeatures(bool),
    WaveSize(u32),
    Sampler(Sampler),
    LightSelection(LightSelection),
    Adaptive(bool),
}

/// One `--vary KEY=V1,V2,...`: the key and its settings, in order.
#[derive(Debug, Clone, PartialEq)]
pub struct Vary {
    key: String,
    values: Vec<(String, Setting)>,
}

impl std::str::FromStr for Vary {
    type Err = anyhow::Error;

    /// Parses `KEY=V1,V2,...`, with a message naming the key or value that
    /// is wrong and what it takes.
    fn from_str(text: &str) -> Result<Vary> {
        let Some((key, list)) = text.split_once('=') else {
            bail!(
                "study::Vary {text:?}: expected KEY=V1,V2,... (keys: {})",
                key_list()
            );
        };
        let key = key.trim();
        let Some(&(_, takes)) = VARY_KEYS.iter().find(|(k, _)| *k == key) else {
            bail!(
                "study::Vary: unknown key {key:?}; the keys are {}",
                key_list()
            );
        };
        let mut values = Vec::new();
        for value in list.split(',').map(str::trim) {
            let bad = || anyhow::anyhow!("study::Vary {key}: {value:?} is not {takes}");
            let setting = match key {
                "integrator" => match value {
                    "nee" => Setting::Integrator(Integrator::Nee),
                    "bsdf" => Setting::Integrator(Integrator::Bsdf),
                    _ => return Err(bad()),
                },
                "features" => match value {
                    "scene" => Setting::AllFeatures(false),
                    "all" => Setting::AllFeatures(true),
                    _ => return Err(bad()),
                },
                "sampler" => Setting::Sampler(value.parse().map_err(|_| bad())?),
                "adaptive" => match value {
                    "off" => Setting::Adaptive(false),
                    "on" => Setting::Adaptive(true),
                    _ => return Err(bad()),
                },
                "light_selection" => Setting::LightSelection(value.parse().map_err(|_| bad())?),
                "max_depth" | "rr_depth" | "wave_size" => {
                    let n: u32 = value.parse().map_err(|_| bad())?;
                    ensure!(n >= 1, bad());
                    match key {
                        "max_depth" => Setting::MaxDepth(n),
                        "rr_depth" => Setting::RrDepth(n),
                        _ => Setting::WaveSize(n),
                    }
                }
                _ => unreachable!("every key of VARY_KEYS is matched"),
            };
            values.push((value.to_string(), setting));
        }
        Ok(Vary {
            key: key.to_string(),
            values,
        })
    }
}

/// `integrator, max_depth, ...` for messages.
fn key_list() -> String {
    VARY_KEYS
        .iter()
        .map(|(k, t)| format!("{k} ({t})"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// One combination of settings: its name and how it changes the render.
#[derive(Debug, Clone)]
pub struct Variant {
    /// `key=value ...`, or `scene` when nothing varies.
    pub name: String,
    settings: Vec<Setting>,
}

impl Variant {
    /// The scene and options this variant renders with.
    fn apply(&self, scene: &Scene, base: &RenderOptions) -> (Scene, RenderOptions) {
        let (mut scene, mut options) = (scene.clone(), base.clone());
        for s in &self.settings {
            match *s {
                Setting::Integrator(i) => options.integrator = i,
                Setting::MaxDepth(d) => scene.render.max_depth = d,
                Setting::RrDepth(d) => scene.render.rr_depth = d,
                Setting::AllFeatures(a) => options.all_features = a,
                Setting::WaveSize(w) => options.wave_size = Some(w),
                Setting::Sampler(x) => options.sampler = x,
                Setting::LightSelection(l) => options.light_selection = l,
                Setting::Adaptive(a) => options.adaptive = a,
            }
        }
        (scene, options)
    }
}

/// Every combination of the `--vary` lists, the first value of each first.
pub fn variants(varies: &[Vary]) -> Result<Vec<Variant>> {
    let mut seen = std::collections::HashSet::new();
    for v in varies {
        ensure!(seen.insert(&v.key), "study::Vary {} is given twice", v.key);
    }
    let mut out = vec![Variant {
        name: String::new(),
        settings: Vec::new(),
    }];
    for v in varies {
        out = out
            .into_iter()
            .flat_map(|base| {
                v.values.iter().map(move |(text, setting)| {
                    let mut next = base.clone();
                    let sep = if next.name.is_empty() { "" } else { " " };
                    next.name = format!("{}{sep}{}={text}", next.name, v.key);
                    next.settings.push(setting.clone());
                    next
                })
            })
            .collect();
    }
    for v in &mut out {
        if v.name.is_empty() {
            v.name = "scene".to_string();
        }
    }
    Ok(out)
}

/// How long each run goes on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Length {
    /// Up to this many samples per pixel.
    Spp(u32),
    /// While the next step, at the time per sample so far, fits these
    /// seconds (up to 2^20 spp).
    Seconds(f64),
}

/// A reference image and, when known, the variance of its mean.
#[derive(Debug, Clone)]
pub struct Reference {
    /// Where it came from (a file given or rendered and cached).
    pub path: PathBuf,
    /// Linear RGB.
    pub mean: Vec<f32>,
    /// Per-pixel variance of the mean, if known (zero otherwise).
    pub var: Option<Vec<f32>>,
    /// Samples per pixel, when lancer rendered it (read back from the
    /// file's metadata, see [`crate::io::image_file::Metadata`]).
    pub spp: Option<u32>,
    /// Seed, when lancer rendered it (read back as `spp`).
    pub seed: Option<u32>,
}

/// The seed of a lancer-rendered reference: far from the seeds the runs use
/// (`seed`, `seed + 1`, ..., `seed + K - 1`), so that the reference shares no
/// sample with the runs it judges.
pub fn reference_seed(scene_seed: u32) -> u32 {
    scene_seed.wrapping_add(0x8000_0000)
}

/// Reads a reference the user gives, checking its size against the scene.
/// A variance image beside it ([`variance_path`]) is used when present.
pub fn read_reference(path: &Path, width: u32, height: u32) -> Result<Reference> {
    ensure!(
        path.is_file(),
        "{}: reference image not found; give an existing EXR or render one with \
         study::rendered_reference",
        path.display()
    );
    let (w, h, mean) = crate::io::image_file::read_image(path)?;
    ensure!(
        (w, h) == (width, height),
        "{}: the reference is {w}x{h} but the scene renders {width}x{height}; give a \
         reference of the same size, or set render.width/render.height to match",
        path.display()
    );
    let var_path = variance_path(path);
    let var = if var_path.is_file() {
        let (vw, vh, var) = crate::io::image_file::read_image(&var_path)?;
        ensure!(
            (vw, vh) == (w, h),
            "{}: the variance image is {vw}x{vh}, its reference {w}x{h}",
            var_path.display()
        );
        Some(var)
    } else {
        None
    };
    // lancer records spp and seed in the images it writes
    let meta = crate::io::image_file::read_metadata(path)?;
    Ok(Reference {
        path: path.to_path_buf(),
        mean,
        var,
        spp: meta.spp,
        seed: meta.seed,
    })
}

/// The scene of the reference of `scene` at `spp`: its seed
/// [`reference_seed`].
fn reference_scene(scene: &Scene, spp: u32) -> Scene {
    let mut scene = scene.clone();
    scene.render.spp = spp;
    scene.render.seed = reference_seed(scene.render.seed);
    scene
}

/// Where [`rendered_reference`] caches the reference of `scene` at `spp`
/// in `dir` (its variance is [`variance_path`] of it): the file name holds
/// the spp, the seed and a hash of the scene and its settings.
pub fn reference_cache_path(
    scene: &Scene,
    options: &RenderOptions,
    spp: u32,
    dir: &Path,
) -> PathBuf {
    let scene = reference_scene(scene, spp);
    let mut key = format!(
        "{:?}{:?}{:?}",
        std::fs::read(&scene.source).unwrap_or_default(),
        scene.render,
        options
    );
    // The files a Mitsuba scene includes are part of it too.
    for p in &scene.includes {
        key += &format!("{:?}", std::fs::read(p).unwrap_or_default());
    }
    let hash = {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        key.hash(&mut h);
        h.finish() as u32
    };
    let seed = scene.render.seed;
    dir.join(format!("reference-spp{spp}-seed{seed}-{hash:08x}.exr"))
}

/// Renders the reference at `spp` with [`reference_seed`], or loads it from
/// `dir` where an earlier run cached it ([`reference_cache_path`]).
/// `progress` watches the render's waves.
pub fn rendered_reference(
    ctx: &Context,
    scene: &Scene,
    options: &RenderOptions,
    spp: u32,
    dir: &Path,
    progress: OnWave<'_>,
) -> Result<Reference> {
    ensure!(
        spp >= 1,
        "study::rendered_reference(spp) must be at least 1"
    );
    let path = reference_cache_path(scene, options, spp, dir);
    let scene = reference_scene(scene, spp);
    let seed = scene.render.seed;
    if path.is_file() {
        let mut r = read_reference(&path, scene.render.width, scene.render.height)?;
        r.spp = Some(spp);
        r.seed = Some(seed);
        return Ok(r);
    }
    let mut renderer = Renderer::new(ctx, &scene, options)?;
    let out = renderer.render(progress)?;
    let (w, h) = (out.width, out.height);
    let meta = crate::io::image_file::Metadata::of_stats(&out.stats);
    // Both files or neither
    let mut files = crate::io::image_file::Outputs::default();
    files.add_image(&variance_path(&path), w, h, &out.var_of_mean, &meta)?;
    files.add_image(&path, w, h, &out.mean, &meta)?;
    files.commit()?;
    Ok(Reference {
        path,
        mean: out.mean,
        var: Some(out.var_of_mean),
        spp: Some(spp),
        seed: Some(seed),
    })
}

/// The spp at which a run is measured: 1, 2, 4, ... and `max` itself.
pub fn schedule(max: u32) -> Vec<u32> {
    let mut steps: Vec<u32> = std::iter::successors(Some(1u32), |&s| s.checked_mul(2))
        .take_while(|&s| s < max)
        .collect();
    steps.push(max.max(1));
    steps
}

/// The render seconds `renderer`'s film will have taken at a mean of `spp`
/// samples per pixel, at the time per sample measured so far; `None` before
/// the first sample.
fn seconds_at(renderer: &Renderer, spp: u32) -> Option<f64> {
    let counts = renderer.pixel_spp();
    let total: u64 = counts.iter().map(|&n| u64::from(n)).sum();
    (total > 0)
        .then(|| renderer.render_seconds() / total as f64 * f64::from(spp) * counts.len() as f64)
}

/// An adaptive run's pixels may hold up to this many times the run's
/// largest mean spp.
const ADAPTIVE_PIXEL_CAP_FACTOR: u32 = 16;

/// Most samples per pixel a `Length::Seconds` run may reach.
const TIME_RUN_MAX_SPP: u32 = 1 << 20;

/// Everything a converge study measured.
#[derive(Debug, Clone)]
pub struct Study {
    /// One record per variant, seed and step.
    pub steps: Vec<Step>,
    /// Seconds spent reading films back and computing metrics (never
    /// counted as render time).
    pub measure_seconds: f64,
}

/// Runs every variant with `seeds` seeds (the scene's seed, then the next
/// ones), alternating the variants, and measures each step against
/// `reference`.
#[allow(clippy::too_many_arguments)]
pub fn run(
    ctx: &Context,
    scene: &Scene,
    base: &RenderOptions,
    variants: &[Variant],
    seeds: u32,
    length: Length,
    reference: &Reference,
    mut on_step: impl FnMut(&Step),
) -> Result<Study> {
    ensure!(seeds >= 1, "study::run(seeds) must be at least 1");
    let (w, h) = (scene.render.width, scene.render.height);
    let ref_var = reference
        .var
        .clone()
        .unwrap_or_else(|| vec![0.0; reference.mean.len()]);
    let mut steps = Vec::new();
    let mut measure_seconds = 0.0;
    // Seeds outside, variants inside: the variants alternate (A B A B), so
    // that a machine that slows down for a while slows them alike
    for k in 0..seeds {
        for variant in variants {
            let (mut scene, mut options) = variant.apply(scene, base);
            scene.render.seed = scene.render.seed.wrapping_add(k);
            let max_spp = match length {
                Length::Spp(n) => n,
                Length::Seconds(_) => TIME_RUN_MAX_SPP,
            };
            scene.render.spp = max_spp.min(crate::interface::MAX_WAVE_SAMPLES_PER_PIXEL);
            options.progressive = true;
            let mut renderer = Renderer::new(ctx, &scene, &options)
                .with_context(|| format!("variant {}", variant.name))?;
            // Some drivers (llvmpipe) compile a kernel at its first dispatch:
            // one warm-up sample, not measured, keeps that out of render time
            renderer.restart()?;
            renderer.render_to(1, None)?;
            renderer.restart()?;
            // An adaptive run is measured at equal mean spp, from the
            // samples every pixel gets first on
            let levels = schedule(max_spp)
                .into_iter()
                .filter(|&spp| !options.adaptive || spp >= ADAPTIVE_MIN_SPP.min(max_spp));
            for spp in levels {
                if let Length::Seconds(limit) = length {
                    if seconds_at(&renderer, spp).is_some_and(|t| t > limit) {
                        break;
                    }
                }
                let read;
                let out = if options.adaptive {
                    // A pixel may go past the run's last mean spp, or the
                    // last step could only be uniform
                    let cap = max_spp.saturating_mul(ADAPTIVE_PIXEL_CAP_FACTOR);
                    let goal = Goal::MeanSpp(f64::from(spp));
                    let out = adaptive::advance(&mut renderer, goal, cap, None)?;
                    // The film was read back to steer the render: that
                    // readback is part of the adaptive render's cost
                    read = Instant::now();
                    out
                } else {
                    renderer.render_to(spp, None)?;
                    read = Instant::now();
                    renderer.output()?
                };
                let seconds = renderer.render_seconds();
                let readback_seconds = read.elapsed().as_secs_f64();
                let measure = Instant::now();
                let metrics = Metrics::compute(&out.mean, &reference.mean, w, h)?;
                let var: Vec<f32> = out
                    .error_estimate
                    .iter()
                    .zip(&ref_var)
                    .map(|(a, b)| a + b)
                    .collect();
                // One sample has no second half film: nothing to predict from
                let predicted = if out.spp >= 2 {
                    predicted_rel_mse(&var, &reference.mean)
                } else {
                    f64::NAN
                };
                let metrics_seconds = measure.elapsed().as_secs_f64();
                let pass_ms: BTreeMap<String, f64> = out
                    .stats
                    .pass_rows()
                    .into_iter()
                    .map(|r| (r.pass.name().to_string(), r.total_ms))
                    .collect();
                let step = Step {
                    variant: variant.name.clone(),
                    seed: scene.render.seed,
                    // An adaptive run's step is the mean spp it aimed at
                    spp: if options.adaptive { spp } else { out.spp },
                    render_seconds: seconds,
                    readback_seconds,
                    metrics_seconds,
                    pass_ms,
                    efficiency: efficiency(metrics.rel_mse, seconds),
                    predicted_rel_mse: predicted,
                    metrics,
                };
                measure_seconds += readback_seconds + metrics_seconds;
                on_step(&step);
                steps.push(step);
            }
        }
    }
    Ok(Study {
        steps,
        measure_seconds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_doubles_and_ends_at_the_maximum() {
        assert_eq!(schedule(1), [1]);
        assert_eq!(schedule(8), [1, 2, 4, 8]);
        assert_eq!(schedule(12), [1, 2, 4, 8, 12]);
    }

    #[test]
    fn vary_parses_every_key_and_refuses_the_rest() {
        let v: Vary = "integrator=nee,bsdf".parse().unwrap();
        assert_eq!(v.values.len(), 2);
        let v: Vary = "max_depth=1, 4".parse().unwrap();
        assert_eq!(v.values[1].1, Setting::MaxDepth(4));
        let e = "colour=red".parse::<Vary>().unwrap_err().to_string();
        assert!(
            e.contains("unknown key \"colour\"") && e.contains("integrator"),
            "{e}"
        );
        let e = "max_depth=0".parse::<Vary>().unwrap_err().to_string();
        assert!(e.contains("\"0\" is not an integer >= 1"), "{e}");
        let e = "features=some".parse::<Vary>().unwrap_err().to_string();
        assert!(e.contains("scene or all"), "{e}");
        assert!("integrator".parse::<Vary>().is_err());
        let v: Vary = "sampler=independent,sobol".parse().unwrap();
        assert_eq!(v.values[1].1, Setting::Sampler(Sampler::Sobol));
        let e = "sampler=halton".parse::<Vary>().unwrap_err().to_string();
        assert!(e.contains("\"halton\" is not independent or sobol"), "{e}");
    }

    #[test]
    fn variants_are_the_product_of_the_lists() {
        let a: Vary = "integrator=nee,bsdf".parse().unwrap();
        let b: Vary = "max_depth=2,8".parse().unwrap();
        let names: Vec<String> = variants(&[a.clone(), b])
            .unwrap()
            .into_iter()
            .map(|v| v.name)
            .collect();
        assert_eq!(
            names,
            [
                "integrator=nee max_depth=2",
                "integrator=nee max_depth=8",
                "integrator=bsdf max_depth=2",
                "integrator=bsdf max_depth=8"
            ]
        );
        assert_eq!(variants(&[]).unwrap()[0].name, "scene");
        assert!(variants(&[a.clone(), a]).is_err());
    }

    #[test]
    fn the_reference_seed_differs_from_every_run_seed() {
        for seed in [0u32, 7, u32::MAX - 3] {
            let r = reference_seed(seed);
            for k in 0..1000 {
                assert_ne!(r, seed.wrapping_add(k));
            }
        }
    }
}
