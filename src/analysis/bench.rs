//! `lancer bench`: a fixed suite of scenes rendered with every variant of
//! the render options (the schedules), one table of figures, JSON to keep,
//! and the change against an earlier JSON; and `lancer bench --scale`, the
//! figures of a million triangles (load, BVH build, memory, per-sample cost
//! against a thousand triangles of the same shape, image size).
//!
//! A suite entry is a [`Case`] (a scene and its settings) rendered with each
//! [`Variant`] (a named change to [`RenderOptions`]). Each run loads the
//! scene, builds the renderer, renders one warm-up sample per pixel (some
//! drivers compile a kernel at its first dispatch), then the measured
//! samples. Figures are wall-clock and GPU-timestamp measurements; nothing
//! here asserts a speed.

pub mod scale;
pub mod scenes;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result};
use serde::{Deserialize, Serialize};

use crate::render::kernels::Pass;
use crate::render::stats::render_table;
use crate::render::{RenderOptions, Renderer};
use crate::scene::{self, Scene};
use crate::vk::Context;

/// Version of the JSON layout [`BenchReport`] writes; a baseline of another
/// version is refused.
pub const FORMAT_VERSION: u32 = 1;

/// A named change to the render options: each case of the suite runs once
/// per variant.
pub struct Variant {
    /// Name in the table and the JSON.
    pub name: &'static str,
    /// What the variant changes.
    pub apply: fn(&mut RenderOptions),
}

/// The variants of the suite, in table order. A schedule (or any other
/// render option worth comparing) is one more entry here.
pub const VARIANTS: &[Variant] = &[
    Variant {
        name: "wavefront",
        apply: |o| o.schedule = crate::render::kernels::Schedule::Wavefront,
    },
    Variant {
        name: "megakernel",
        apply: |o| o.schedule = crate::render::kernels::Schedule::Megakernel,
    },
];

/// Where a case's scene comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneSource {
    /// `scenes/cornell.toml`, as built into the binary.
    Cornell,
    /// `scenes/glass.toml`, as built into the binary.
    Glass,
    /// The generated bumpy sphere in the Cornell box, with this many quads
    /// per cube-face edge ([`scenes::bumpy_sphere_scene`]).
    BumpySphere(u32),
}

/// One scene of the suite and the settings it renders at.
#[derive(Clone, Debug)]
pub struct Case {
    /// Name in the table and the JSON.
    pub name: &'static str,
    /// The scene.
    pub source: SceneSource,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Measured samples per pixel (after one warm-up sample).
    pub spp: u32,
}

/// The fixed suite: sized so that it finishes in under two minutes on
/// lavapipe on two cores, with every variant.
pub const SUITE: &[Case] = &[
    Case {
        name: "cornell",
        source: SceneSource::Cornell,
        width: 256,
        height: 256,
        spp: 16,
    },
    Case {
        name: "glass",
        source: SceneSource::Glass,
        width: 256,
        height: 256,
        spp: 16,
    },
    Case {
        name: "bumpy-1k",
        source: SceneSource::BumpySphere(scenes::THOUSAND_SUBDIVISIONS),
        width: 256,
        height: 256,
        spp: 16,
    },
    Case {
        name: "bumpy-1m",
        source: SceneSource::BumpySphere(scenes::MILLION_SUBDIVISIONS),
        width: 256,
        height: 256,
        spp: 16,
    },
];

/// One pass's figures in one run.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
pub struct PassFigures {
    /// Pass name (`generate`, `intersect`, ...).
    pub pass: String,
    /// GPU milliseconds, summed over dispatches.
    pub ms: f64,
    /// Rays (or paths) handled.
    pub rays: u64,
    /// Millions of rays per GPU second.
    pub mrays_per_s: f64,
}

/// The figures of one case rendered with one variant.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
pub struct BenchResult {
    /// Case name.
    pub case: String,
    /// Variant name.
    pub variant: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Measured samples per pixel.
    pub spp: u32,
    /// Longest path.
    pub max_depth: u32,
    /// Triangles in the scene.
    pub triangles: u64,
    /// Samples per second of rendering (warm-up and readback excluded).
    pub samples_per_second: f64,
    /// Seconds of rendering the measured samples.
    pub render_seconds: f64,
    /// Seconds to read and check the scene file and its meshes.
    pub load_seconds: f64,
    /// Seconds to build the renderer: BVH, packing, upload, kernels.
    pub setup_seconds: f64,
    /// Seconds from reading the scene to the first dispatch being ready
    /// to record: `load_seconds + setup_seconds`. Drivers that compile a
    /// kernel at its first dispatch (lavapipe) add that to the first wave
    /// instead.
    pub first_dispatch_seconds: f64,
    /// Seconds of the BVH build (part of setup).
    pub bvh_seconds: f64,
    /// SAH cost of the BVH.
    pub bvh_sah_cost: f64,
    /// Device memory of every buffer, in bytes.
    pub device_bytes: u64,
    /// Per-pass figures, in pass order.
    pub passes: Vec<PassFigures>,
}

/// Everything one `lancer bench` run measured.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
pub struct BenchReport {
    /// [`FORMAT_VERSION`] of the file.
    pub format: u32,
    /// lancer's version.
    pub lancer: String,
    /// Vulkan device name.
    pub device: String,
    /// Driver name and version.
    pub driver: String,
    /// Seconds the whole suite took.
    pub total_seconds: f64,
    /// One entry per case and variant.
    pub results: Vec<BenchResult>,
}

impl BenchReport {
    /// Pretty JSON with a final newline.
    pub fn to_json(&self) -> Result<String> {
        let mut text = serde_json::to_string_pretty(self)?;
        text.push('\n');
        Ok(text)
    }

    /// Parses a report written by [`BenchReport::to_json`]; `path` names the
    /// file in errors.
    pub fn from_json(text: &str, path: &Path) -> Result<BenchReport> {
        #[derive(Deserialize)]
        struct Version {
            format: Option<u32>,
        }
        let not_bench = "not a `lancer bench --json` file";
        let version: Version = serde_json::from_str(text)
            .with_context(|| format!("{}: {not_bench}", path.display()))?;
        match version.format {
            Some(FORMAT_VERSION) => {}
            Some(v) => anyhow::bail!(
                "{}: written in bench format {v}, this lancer reads format {FORMAT_VERSION}; \
                 run `lancer bench --json FILE` again with this version to make a baseline",
                path.display()
            ),
            None => anyhow::bail!("{}: {not_bench} (it has no \"format\" key)", path.display()),
        }
        serde_json::from_str(text).with_context(|| format!("{}: {not_bench}", path.display()))
    }

    /// Writes [`BenchReport::to_json`] to `path`, atomically.
    pub fn write_json(&self, path: &Path) -> Result<()> {
        let text = self.to_json()?;
        crate::io::image_file::write_atomically(path, |w| {
            Ok(std::io::Write::write_all(w, text.as_bytes())?)
        })
    }

    /// Reads a report from a file, with errors that name it.
    pub fn read(path: &Path) -> Result<BenchReport> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read the baseline", path.display()))?;
        BenchReport::from_json(&text, path)
    }

    /// The table of figures: one row per case and variant.
    pub fn table(&self) -> String {
        let passes = pass_columns(&self.results);
        let mut header: Vec<String> = [
            "case",
            "variant",
            "triangles",
            "size",
            "samples/s",
            "first dispatch s",
            "BVH s",
            "device MiB",
        ]
        .map(String::from)
        .to_vec();
        header.extend(passes.iter().map(|p| rate_column(p)));
        let rows: Vec<Vec<String>> = self
            .results
            .iter()
            .map(|r| {
                let mut row = vec![
                    r.case.clone(),
                    r.variant.clone(),
                    r.triangles.to_string(),
                    format!("{}x{} {} spp", r.width, r.height, r.spp),
                    format!("{:.0}", r.samples_per_second),
                    format!("{:.3}", r.first_dispatch_seconds),
                    format!("{:.3}", r.bvh_seconds),
                    format!("{:.1}", mib(r.device_bytes)),
                ];
                row.extend(passes.iter().map(|p| match r.pass(p) {
                    Some(f) => format!("{:.2}", f.mrays_per_s),
                    None => "-".into(),
                }));
                row
            })
            .collect();
        format!(
            "device: {} (driver {}), lancer {}, suite {:.1} s\n{}",
            self.device,
            self.driver,
            self.lancer,
            self.total_seconds,
            render_table(&header, &rows, 2)
        )
    }
}

impl BenchResult {
    /// The figures of the pass named `name`, if it ran.
    pub fn pass(&self, name: &str) -> Option<&PassFigures> {
        self.passes.iter().find(|p| p.pass == name)
    }

    /// The figures compared against a baseline, as (column, value); higher
    /// is better for throughputs, lower for seconds and bytes.
    fn compared_figures(&self, passes: &[String]) -> Vec<(String, Option<f64>)> {
        let mut figures = vec![
            ("samples/s".to_string(), Some(self.samples_per_second)),
            (
                "first dispatch s".to_string(),
                Some(self.first_dispatch_seconds),
            ),
            ("device bytes".to_string(), Some(self.device_bytes as f64)),
        ];
        figures.extend(
            passes
                .iter()
                .map(|p| (rate_column(p), self.pass(p).map(|f| f.mrays_per_s))),
        );
        figures
    }
}

/// Pass names that appear in `results`, in pass order.
fn pass_columns(results: &[BenchResult]) -> Vec<String> {
    Pass::ALL
        .iter()
        .map(|p| p.name().to_string())
        .filter(|name| results.iter().any(|r| r.pass(name).is_some()))
        .collect()
}

/// The column of a pass's rate: millions of its items (rays, or paths for
/// the megakernel and the film) per GPU second, e.g. `intersect Mrays/s`.
fn rate_column(pass: &str) -> String {
    let items = Pass::from_label(pass).map_or("rays", Pass::items);
    format!("{pass} M{items}/s")
}

/// Bytes in MiB.
fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

/// One figure of one case and variant, now and in the baseline.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    /// Case name.
    pub case: String,
    /// Variant name.
    pub variant: String,
    /// Column name (`samples/s`, `intersect Mrays/s`, ...).
    pub figure: String,
    /// This run's value.
    pub now: f64,
    /// The baseline's value.
    pub before: f64,
}

impl Change {
    /// `now / before`: above 1 is more throughput, or more seconds or bytes.
    pub fn ratio(&self) -> f64 {
        self.now / self.before
    }
}

/// What changed from `before` to `now`: every figure of every (case,
/// variant) found in both, and the (case, variant) pairs found in only one,
/// as `"case/variant"` names (in `now` only, in `before` only).
pub fn changes(now: &BenchReport, before: &BenchReport) -> (Vec<Change>, Vec<String>, Vec<String>) {
    let key = |r: &BenchResult| (r.case.clone(), r.variant.clone());
    let name = |r: &BenchResult| format!("{}/{}", r.case, r.variant);
    let old: BTreeMap<_, _> = before.results.iter().map(|r| (key(r), r)).collect();
    let mut all = now.results.clone();
    all.extend(before.results.iter().cloned());
    let passes = pass_columns(&all);
    let mut out = Vec::new();
    let mut only_now = Vec::new();
    for r in &now.results {
        let Some(b) = old.get(&key(r)) else {
            only_now.push(name(r));
            continue;
        };
        for ((figure, n), (_, p)) in r
            .compared_figures(&passes)
            .into_iter()
            .zip(b.compared_figures(&passes))
        {
            if let (Some(now), Some(before)) = (n, p) {
                out.push(Change {
                    case: r.case.clone(),
                    variant: r.variant.clone(),
                    figure,
                    now,
                    before,
                });
            }
        }
    }
    let new: std::collections::BTreeSet<_> = now.results.iter().map(key).collect();
    let only_before = before
        .results
        .iter()
        .filter(|r| !new.contains(&key(r)))
        .map(name)
        .collect();
    (out, only_now, only_before)
}

/// The change against a baseline as a table: one row per case and
/// variant, one column per figure, each cell `now / before` as `1.23x`.
pub fn change_table(now: &BenchReport, before: &BenchReport) -> String {
    let (changes, only_now, only_before) = changes(now, before);
    let mut figures: Vec<String> = Vec::new();
    let mut rows: Vec<(String, String)> = Vec::new();
    for c in &changes {
        if !figures.contains(&c.figure) {
            figures.push(c.figure.clone());
        }
        let row = (c.case.clone(), c.variant.clone());
        if !rows.contains(&row) {
            rows.push(row);
        }
    }
    let mut header = vec!["case".to_string(), "variant".to_string()];
    header.extend(figures.iter().cloned());
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|(case, variant)| {
            let mut row = vec![case.clone(), variant.clone()];
            row.extend(figures.iter().map(|f| {
                changes
                    .iter()
                    .find(|c| &c.case == case && &c.variant == variant && &c.figure == f)
                    .map_or("-".to_string(), |c| format!("{:.2}x", c.ratio()))
            }));
            row
        })
        .collect();
    let mut out = format!(
        "change against the baseline (now / before; samples/s and Mrays/s: above 1 is faster; \
         seconds and bytes: above 1 is more)\nbaseline: device {} (driver {}), lancer {}\n",
        before.device, before.driver, before.lancer
    );
    out.push_str(&render_table(&header, &cells, 2));
    for name in only_now {
        out.push_str(&format!("{name}: not in the baseline\n"));
    }
    for name in only_before {
        out.push_str(&format!("{name}: in the baseline only\n"));
    }
    out
}

/// A case's scene, loaded, at the case's settings.
struct LoadedCase {
    scene: Scene,
    load_seconds: f64,
}

/// Writes (or finds) the scene file of `source` in `dir`.
pub fn scene_file(source: SceneSource, dir: &Path) -> Result<PathBuf> {
    match source {
        SceneSource::Cornell => Ok(scenes::example_scenes(&dir.join("examples"))?.0),
        SceneSource::Glass => Ok(scenes::example_scenes(&dir.join("examples"))?.1),
        SceneSource::BumpySphere(n) => scenes::bumpy_sphere_scene(dir, n),
    }
}

/// The files [`scene_file`] may write for `source` in `dir`.
pub fn scene_files(source: SceneSource, dir: &Path) -> Vec<PathBuf> {
    match source {
        SceneSource::Cornell | SceneSource::Glass => scenes::example_files(&dir.join("examples")),
        SceneSource::BumpySphere(n) => scenes::bumpy_sphere_files(dir, n).to_vec(),
    }
}

/// Loads a case's scene and applies its settings.
fn load_case(case: &Case, dir: &Path) -> Result<LoadedCase> {
    let path = scene_file(case.source, dir)?;
    let started = Instant::now();
    let mut scene = scene::load(&path)?;
    let load_seconds = started.elapsed().as_secs_f64();
    scene.render.width = case.width;
    scene.render.height = case.height;
    scene.render.spp = case.spp;
    Ok(LoadedCase {
        scene,
        load_seconds,
    })
}

/// Renders a loaded scene with `options`: setup, one warm-up sample per
/// pixel, then the measured samples.
fn run_one(
    ctx: &Context,
    case: &str,
    variant: &str,
    loaded: &LoadedCase,
    options: &RenderOptions,
) -> Result<BenchResult> {
    let scene = &loaded.scene;
    let started = Instant::now();
    let mut renderer = Renderer::new(ctx, scene, options)?;
    let setup_seconds = started.elapsed().as_secs_f64();
    renderer.restart()?;
    renderer.render_to(1, None)?;
    let out = renderer.render(None)?;
    let stats = &out.stats;
    let info = &renderer.scene_info;
    let passes = stats
        .pass_rows()
        .into_iter()
        .map(|r| PassFigures {
            pass: r.pass.name().to_string(),
            ms: r.total_ms,
            rays: r.rays,
            mrays_per_s: r.mrays_per_s,
        })
        .collect();
    Ok(BenchResult {
        case: case.to_string(),
        variant: variant.to_string(),
        width: scene.render.width,
        height: scene.render.height,
        spp: stats.spp,
        max_depth: scene.render.max_depth,
        triangles: info.triangles as u64,
        samples_per_second: stats.samples_per_second().unwrap_or(0.0),
        render_seconds: stats.wall_seconds,
        load_seconds: loaded.load_seconds,
        setup_seconds,
        first_dispatch_seconds: loaded.load_seconds + setup_seconds,
        bvh_seconds: info.bvh_seconds,
        bvh_sah_cost: info.bvh_sah_cost,
        device_bytes: info.device_bytes,
        passes,
    })
}

/// How far [`run_suite`] has come, for a progress display: `done` of its
/// `total` steps (loading a case's scene, and each variant of it), and
/// what the next step does (empty after the last).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SuiteProgress<'a> {
    /// Steps finished.
    pub done: u64,
    /// Steps of the whole suite.
    pub total: u64,
    /// The step starting now, e.g. `cornell: loading`, `cornell wavefront`.
    pub doing: &'a str,
}

/// Runs every case with every variant (variants alternate within a case,
/// so a machine that slows down slows them alike). `progress` is told of
/// each step before it starts, and once more when all are done.
pub fn run_suite(
    ctx: &Context,
    cases: &[Case],
    variants: &[Variant],
    scene_dir: &Path,
    progress: Option<&dyn Fn(SuiteProgress)>,
) -> Result<BenchReport> {
    let started = Instant::now();
    let total = (cases.len() * (variants.len() + 1)) as u64;
    let mut done = 0;
    let mut step = |doing: &str| {
        if let Some(f) = progress {
            f(SuiteProgress { done, total, doing });
        }
        done += 1;
    };
    let mut results = Vec::new();
    for case in cases {
        step(&format!("{}: loading", case.name));
        let loaded =
            load_case(case, scene_dir).with_context(|| format!("bench case {}", case.name))?;
        for variant in variants {
            crate::util::interrupt::check()?;
            step(&format!("{} {}", case.name, variant.name));
            let mut options = RenderOptions::default();
            (variant.apply)(&mut options);
            results.push(
                run_one(ctx, case.name, variant.name, &loaded, &options)
                    .with_context(|| format!("bench case {} {}", case.name, variant.name))?,
            );
        }
    }
    step("");
    let info = ctx.info();
    Ok(BenchReport {
        format: FORMAT_VERSION,
        lancer: env!("CARGO_PKG_VERSION").to_string(),
        device: info.name.clone(),
        driver: info.driver_name.clone(),
        total_seconds: started.elapsed().as_secs_f64(),
        results,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(case: &str, variant: &str, sps: f64, intersect: Option<f64>) -> BenchResult {
        let mut passes = vec![PassFigures {
            pass: "shade".into(),
            ms: 10.0,
            rays: 100,
            mrays_per_s: 4.0,
        }];
        if let Some(m) = intersect {
            passes.insert(
                0,
                PassFigures {
                    pass: "intersect".into(),
                    ms: 20.0,
                    rays: 100,
                    mrays_per_s: m,
                },
            );
        }
        BenchResult {
            case: case.into(),
            variant: variant.into(),
            width: 8,
            height: 8,
            spp: 2,
            max_depth: 8,
            triangles: 12,
            samples_per_second: sps,
            render_seconds: 1.0,
            load_seconds: 0.25,
            setup_seconds: 0.5,
            first_dispatch_seconds: 0.75,
            bvh_seconds: 0.125,
            bvh_sah_cost: 3.5,
            device_bytes: 1 << 20,
            passes,
        }
    }

    fn report(results: Vec<BenchResult>) -> BenchReport {
        BenchReport {
            format: FORMAT_VERSION,
            lancer: "0.0.0".into(),
            device: "test device".into(),
            driver: "test driver".into(),
            total_seconds: 1.5,
            results,
        }
    }

    #[test]
    fn changes_are_ratios_of_matching_entries() {
        let before = report(vec![
            result("a", "wavefront", 1000.0, Some(2.0)),
            result("b", "wavefront", 500.0, Some(1.0)),
            result("gone", "wavefront", 1.0, None),
        ]);
        let mut faster = result("a", "wavefront", 1500.0, Some(5.0));
        faster.first_dispatch_seconds = 0.375;
        faster.device_bytes = 3 << 19;
        let now = report(vec![
            faster,
            result("b", "wavefront", 250.0, None),
            result("new", "megakernel", 1.0, Some(1.0)),
        ]);
        let (changes, only_now, only_before) = changes(&now, &before);
        let get = |case: &str, figure: &str| {
            changes
                .iter()
                .find(|c| c.case == case && c.figure == figure)
                .map(Change::ratio)
        };
        assert_eq!(get("a", "samples/s"), Some(1.5));
        assert_eq!(get("a", "intersect Mrays/s"), Some(2.5));
        assert_eq!(get("a", "shade Mrays/s"), Some(1.0));
        assert_eq!(get("a", "first dispatch s"), Some(0.5));
        assert_eq!(get("a", "device bytes"), Some(1.5));
        assert_eq!(get("b", "samples/s"), Some(0.5));
        // A pass that ran on one side only has no ratio
        assert_eq!(get("b", "intersect Mrays/s"), None);
        assert_eq!(only_now, vec!["new/megakernel".to_string()]);
        assert_eq!(only_before, vec!["gone/wavefront".to_string()]);
        let table = change_table(&now, &before);
        assert!(
            table.contains("| a    | wavefront |     1.50x |"),
            "{table}"
        );
        assert!(
            table.contains("new/megakernel: not in the baseline"),
            "{table}"
        );
    }

    #[test]
    fn report_round_trips_through_json() {
        let r = report(vec![
            result("a", "wavefront", 1234.5678, Some(2.0)),
            result("b", "wavefront", 0.1, None),
        ]);
        let text = r.to_json().unwrap();
        assert_eq!(
            BenchReport::from_json(&text, Path::new("r.json")).unwrap(),
            r
        );
    }

    #[test]
    fn bad_baselines_are_refused_by_name() {
        let path = Path::new("old.json");
        let err = |text: &str| format!("{:#}", BenchReport::from_json(text, path).unwrap_err());
        let e = err("{ not json");
        assert!(
            e.starts_with("old.json: not a `lancer bench --json` file"),
            "{e}"
        );
        assert!(e.contains("line 1"), "{e}");
        let e = err(r#"{"passes": []}"#);
        assert!(
            e.contains("old.json: not a `lancer bench --json` file (it has no \"format\" key)"),
            "{e}"
        );
        let e = err(r#"{"format": 99}"#);
        assert!(e.contains("old.json: written in bench format 99"), "{e}");
        let e = err(r#"{"format": 1, "lancer": "x"}"#);
        assert!(e.contains("missing field"), "{e}");
        let missing = BenchReport::read(Path::new("/nonexistent/old.json")).unwrap_err();
        assert!(
            format!("{missing:#}").starts_with("/nonexistent/old.json: cannot read the baseline"),
            "{missing:#}"
        );
    }
}
