//! Profiling figures: GPU time and rays per pass and per bounce, as a
//! terminal table and as JSON.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::Serialize;
use serde_json::{json, Value};

use crate::render::kernels::Integrator;
use crate::render::kernels::Pass;
use crate::render::kernels::Sampler;

/// One timed dispatch of one pass: what a timestamp pair measured.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct PassRecord {
    /// The pass the dispatch ran.
    pub pass: Pass,
    /// Bounce the dispatch belongs to, for passes that run once per bounce;
    /// `None` for passes that run once per wave.
    pub bounce: Option<u32>,
    /// GPU time between the pass's two timestamps, in nanoseconds (0 when
    /// timestamps are not supported).
    pub gpu_ns: u64,
    /// Rays (or paths) the dispatch handled.
    pub rays: u64,
    /// Start on the device's timestamp clock, in nanoseconds.
    pub start_ns: u64,
    /// Index of the wave the dispatch belongs to.
    pub wave: u32,
}

/// Everything measured during one render.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// Vulkan device name.
    pub device: String,
    /// Driver name and version, as the device reports them.
    pub driver: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel rendered (in an adaptive render, the most any
    /// pixel got).
    pub spp: u32,
    /// Samples rendered over the whole image: width x height x spp, or in
    /// an adaptive render the sum of every pixel's count.
    pub samples: u64,
    /// The pixels got different sample counts (an adaptive render).
    pub adaptive: bool,
    /// Longest path, in segments from the camera.
    pub max_depth: u32,
    /// Russian roulette from the hit that ends this segment on.
    pub rr_depth: u32,
    /// Seed of every random number.
    pub seed: u32,
    /// The estimator.
    pub integrator: Integrator,
    /// Where the random numbers came from.
    pub sampler: Sampler,
    /// Paths in flight per wave.
    pub wave_size: u32,
    /// Number of waves dispatched.
    pub waves: u32,
    /// Bands of rows the film was rendered in, the device holding one at a
    /// time (1: the device held the whole film).
    pub tiles: u32,
    /// Rows of the tallest band.
    pub tile_rows: u32,
    /// Every timed dispatch, in submission order.
    pub records: Vec<PassRecord>,
    /// Wall-clock time of the render, in seconds.
    pub wall_seconds: f64,
    /// Samples that came out NaN or infinite (and were discarded).
    pub nonfinite_samples: u64,
    /// Whether the device supports timestamp queries; when it does not, every
    /// `gpu_ns` is 0 and the time columns mean nothing.
    pub timestamps_supported: bool,
}

/// One summary row per pass, as [`RenderStats::pass_rows`] computes it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PassRow {
    /// The pass.
    pub pass: Pass,
    /// Number of dispatches (records) of this pass.
    pub dispatches: u64,
    /// Summed GPU time of this pass, in milliseconds.
    pub total_ms: f64,
    /// Share of the GPU time summed over all passes, in percent (0 when no
    /// GPU time was measured).
    pub percent: f64,
    /// Mean GPU time per dispatch, in milliseconds.
    pub avg_ms: f64,
    /// Shortest dispatch, in milliseconds.
    pub min_ms: f64,
    /// Longest dispatch, in milliseconds.
    pub max_ms: f64,
    /// Rays handled, summed over dispatches.
    pub rays: u64,
    /// Millions of rays per GPU second: `rays / total seconds / 1e6`; 0 when
    /// there are no rays or no measured time.
    pub mrays_per_s: f64,
}

const NS_PER_MS: f64 = 1e6;

impl RenderStats {
    /// GPU time summed over every record, in nanoseconds.
    pub fn gpu_total_ns(&self) -> u64 {
        self.records.iter().map(|r| r.gpu_ns).sum()
    }

    /// Samples rendered: width × height × spp, or each pixel's count
    /// summed in an adaptive render.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Mean samples per pixel: `spp` unless the render was adaptive.
    pub fn mean_spp(&self) -> f64 {
        let pixels = u64::from(self.width) * u64::from(self.height);
        self.samples as f64 / pixels.max(1) as f64
    }

    /// Samples per wall-clock second; `None` when no wall time was measured.
    pub fn samples_per_second(&self) -> Option<f64> {
        (self.wall_seconds > 0.0).then(|| self.samples() as f64 / self.wall_seconds)
    }

    /// One row per pass, in the order each pass first appears in `records`.
    pub fn pass_rows(&self) -> Vec<PassRow> {
        let total_ns = self.gpu_total_ns();
        let mut order: Vec<Pass> = Vec::new();
        let mut groups: BTreeMap<Pass, Vec<&PassRecord>> = BTreeMap::new();
        for r in &self.records {
            let g = groups.entry(r.pass).or_default();
            if g.is_empty() {
                order.push(r.pass);
            }
            g.push(r);
        }
        order
            .into_iter()
            .map(|pass| {
                let g = &groups[&pass];
                let ns: u64 = g.iter().map(|r| r.gpu_ns).sum();
                let rays: u64 = g.iter().map(|r| r.rays).sum();
                let min = g.iter().map(|r| r.gpu_ns).min().unwrap_or(0);
                let max = g.iter().map(|r| r.gpu_ns).max().unwrap_or(0);
                let secs = ns as f64 * 1e-9;
                PassRow {
                    pass,
                    dispatches: g.len() as u64,
                    total_ms: ns as f64 / NS_PER_MS,
                    percent: if total_ns > 0 {
                        100.0 * ns as f64 / total_ns as f64
                    } else {
                        0.0
                    },
                    avg_ms: ns as f64 / NS_PER_MS / g.len() as f64,
                    min_ms: min as f64 / NS_PER_MS,
                    max_ms: max as f64 / NS_PER_MS,
                    rays,
                    mrays_per_s: if rays > 0 && secs > 0.0 {
                        rays as f64 / secs / 1e6
                    } else {
                        0.0
                    },
                }
            })
            .collect()
    }

    /// Rays per pass at each bounce, bounces ascending. Records without a
    /// bounce (per-wave passes) are left out.
    pub fn rays_per_bounce(&self) -> Vec<(u32, BTreeMap<Pass, u64>)> {
        let mut by_bounce: BTreeMap<u32, BTreeMap<Pass, u64>> = BTreeMap::new();
        for r in &self.records {
            if let Some(b) = r.bounce {
                *by_bounce.entry(b).or_default().entry(r.pass).or_default() += r.rays;
            }
        }
        by_bounce.into_iter().collect()
    }

    /// The summary for a terminal: a header line, the per-pass table, a line
    /// with GPU total, wall time and samples per second, and a rays-per-bounce
    /// table. Numbers are right-aligned. The string has no trailing newline.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "device: {} (driver {}), {}×{}, {} spp, max depth {}, {} wave(s) of {} paths",
            self.device,
            self.driver,
            self.width,
            self.height,
            self.spp,
            self.max_depth,
            self.waves,
            self.wave_size
        );
        if self.tiles > 1 {
            let _ = writeln!(
                out,
                "film: {} bands of up to {} rows, one on the device at a time",
                self.tiles, self.tile_rows
            );
        }
        let ts = self.timestamps_supported;
        let time = |v: f64, prec: usize| {
            if ts {
                format!("{v:.prec$}")
            } else {
                "n/a".to_string()
            }
        };
        let header = [
            "pass",
            "dispatches",
            "total ms",
            "%",
            "avg ms",
            "min ms",
            "max ms",
            "rays",
            "Mrays/s",
        ];
        let rows: Vec<Vec<String>> = self
            .pass_rows()
            .into_iter()
            .map(|r| {
                vec![
                    r.pass.to_string(),
                    r.dispatches.to_string(),
                    time(r.total_ms, 3),
                    time(r.percent, 1),
                    time(r.avg_ms, 3),
                    time(r.min_ms, 3),
                    time(r.max_ms, 3),
                    r.rays.to_string(),
                    time(r.mrays_per_s, 2),
                ]
            })
            .collect();
        out.push_str(&render_table(&header, &rows, 1));
        let path_rows: Vec<&str> = self
            .pass_rows()
            .iter()
            .filter(|r| r.pass.items() == "paths")
            .map(|r| r.pass.name())
            .collect();
        if !path_rows.is_empty() {
            let _ = writeln!(
                out,
                "({} count paths in the rays columns, not rays)",
                path_rows.join(" and ")
            );
        }

        let gpu_ms = self.gpu_total_ns() as f64 / NS_PER_MS;
        let sps = match self.samples_per_second() {
            Some(s) => format!("{s:.0}"),
            None => "n/a".to_string(),
        };
        let _ = writeln!(
            out,
            "GPU total: {} ms, wall: {:.3} s, {} samples/s ({}×{}×{} / {:.3} s)",
            time(gpu_ms, 3),
            self.wall_seconds,
            sps,
            self.width,
            self.height,
            self.spp,
            self.wall_seconds
        );
        if !ts {
            out.push_str(
                "GPU timestamps are not supported by this device: times are not measured\n",
            );
        }
        if self.nonfinite_samples > 0 {
            let _ = writeln!(
                out,
                "warning: {} non-finite samples (NaN or infinity) were discarded",
                self.nonfinite_samples
            );
        }

        let per_bounce = self.rays_per_bounce();
        if !per_bounce.is_empty() {
            // Columns: passes that have a bounce, in first-appearance order.
            let mut passes: Vec<Pass> = Vec::new();
            for r in &self.records {
                if r.bounce.is_some() && !passes.contains(&r.pass) {
                    passes.push(r.pass);
                }
            }
            let mut header = vec!["bounce"];
            header.extend(passes.iter().map(|p| p.name()));
            let rows: Vec<Vec<String>> = per_bounce
                .iter()
                .map(|(b, m)| {
                    let mut row = vec![b.to_string()];
                    row.extend(
                        passes
                            .iter()
                            .map(|p| m.get(p).copied().unwrap_or(0).to_string()),
                    );
                    row
                })
                .collect();
            out.push_str("rays per bounce:\n");
            out.push_str(&render_table(&header, &rows, 0));
        }
        // No trailing newline, so that `println!("{}", stats.table())` fits.
        while out.ends_with('\n') {
            out.pop();
        }
        out
    }

    /// Everything above as JSON: run settings, device and driver, totals,
    /// the per-pass rows, rays per bounce and the raw records.
    pub fn to_json(&self) -> Value {
        let per_bounce: Vec<Value> = self
            .rays_per_bounce()
            .into_iter()
            .map(|(b, m)| json!({ "bounce": b, "rays": m }))
            .collect();
        json!({
            "device": self.device,
            "driver": self.driver,
            "width": self.width,
            "height": self.height,
            "spp": self.spp,
            "adaptive": self.adaptive,
            "mean_spp": self.mean_spp(),
            "max_depth": self.max_depth,
            "rr_depth": self.rr_depth,
            "seed": self.seed,
            "integrator": self.integrator,
            "sampler": self.sampler,
            "wave_size": self.wave_size,
            "waves": self.waves,
            "tiles": self.tiles,
            "tile_rows": self.tile_rows,
            "samples": self.samples(),
            "wall_seconds": self.wall_seconds,
            "samples_per_second": self.samples_per_second(),
            "gpu_total_ms": self.gpu_total_ns() as f64 / NS_PER_MS,
            "timestamps_supported": self.timestamps_supported,
            "nonfinite_samples": self.nonfinite_samples,
            "passes": self.pass_rows(),
            "rays_per_bounce": per_bounce,
            "records": self.records,
        })
    }

    /// The dispatches as Chrome trace events (the trace-event format that
    /// Perfetto and chrome://tracing open): one complete event per timed
    /// dispatch, on the device's own clock, starting at 0.
    pub fn to_trace(&self) -> Value {
        let t0 = self.records.iter().map(|r| r.start_ns).min().unwrap_or(0);
        let events: Vec<Value> = self
            .records
            .iter()
            .map(|r| {
                let name = match r.bounce {
                    Some(b) => format!("{}[{b}]", r.pass),
                    None => r.pass.to_string(),
                };
                json!({
                    "name": name,
                    "cat": r.pass,
                    "ph": "X",
                    "ts": (r.start_ns - t0) as f64 / 1000.0,
                    "dur": r.gpu_ns as f64 / 1000.0,
                    "pid": 1,
                    "tid": 1,
                    "args": { "wave": r.wave, "bounce": r.bounce, "rays": r.rays },
                })
            })
            .collect();
        json!({
            "traceEvents": events,
            "displayTimeUnit": "ms",
            "otherData": { "device": self.device, "driver": self.driver },
        })
    }
}

/// Formats a table with `|` separators: the first `left` columns are
/// left-aligned, the rest right-aligned, with a markdown alignment rule under
/// the header.
pub(crate) fn render_table<S: AsRef<str>>(
    header: &[S],
    rows: &[Vec<String>],
    left: usize,
) -> String {
    let widths: Vec<usize> = header
        .iter()
        .enumerate()
        .map(|(i, h)| {
            rows.iter()
                .map(|r| r[i].chars().count())
                .chain(std::iter::once(h.as_ref().chars().count()))
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cells: Vec<&str>| {
        let mut s = String::from("|");
        for (i, c) in cells.iter().enumerate() {
            if i < left {
                let _ = write!(s, " {:<w$} |", c, w = widths[i]);
            } else {
                let _ = write!(s, " {:>w$} |", c, w = widths[i]);
            }
        }
        s.push('\n');
        s
    };
    let mut out = line(header.iter().map(AsRef::as_ref).collect());
    out.push('|');
    for (i, w) in widths.iter().enumerate() {
        if i < left {
            let _ = write!(out, "{}|", "-".repeat(w + 2));
        } else {
            let _ = write!(out, "{}:|", "-".repeat(w + 1));
        }
    }
    out.push('\n');
    for r in rows {
        out.push_str(&line(r.iter().map(String::as_str).collect()));
    }
    out
}

/// Sizes of what the scene put on the device.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SceneInfo {
    /// Materials.
    pub materials: usize,
    /// Spheres.
    pub spheres: usize,
    /// Triangles.
    pub triangles: usize,
    /// Emissive primitives.
    pub emitters: usize,
    /// BVH nodes.
    pub bvh_nodes: usize,
    /// BVH depth (root = 1).
    pub bvh_depth: u32,
    /// SAH cost of the BVH, in primitive tests per ray that hits the scene.
    pub bvh_sah_cost: f64,
    /// Wall-clock seconds the BVH build took.
    pub bvh_seconds: f64,
    /// Device memory the renderer allocated, in bytes.
    pub device_bytes: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(pass: Pass, bounce: Option<u32>, gpu_ns: u64, rays: u64) -> PassRecord {
        PassRecord {
            pass,
            bounce,
            gpu_ns,
            rays,
            start_ns: 0,
            wave: 0,
        }
    }

    /// Two waves, two bounces each: 10 ms of GPU time in all.
    fn sample() -> RenderStats {
        let mut records = Vec::new();
        for _wave in 0..2 {
            records.push(rec(Pass::Generate, None, 500_000, 1000));
            for b in 0..2u32 {
                let alive = if b == 0 { 1000 } else { 600 };
                records.push(rec(
                    Pass::Intersect,
                    Some(b),
                    1_000_000 + 500_000 * b as u64,
                    alive,
                ));
                records.push(rec(Pass::Shade, Some(b), 750_000, alive));
                records.push(rec(Pass::Shadow, Some(b), 250_000, alive / 2));
            }
            records.push(rec(Pass::Accumulate, None, 0, 0));
        }
        RenderStats {
            device: "llvmpipe (LLVM 15.0.6, 256 bits)".into(),
            driver: "llvmpipe Mesa 22.3.6".into(),
            width: 40,
            height: 25,
            spp: 2,
            samples: 2000,
            adaptive: false,
            max_depth: 2,
            rr_depth: 3,
            seed: 0,
            integrator: Integrator::Nee,
            sampler: Sampler::Independent,
            wave_size: 1000,
            waves: 2,
            tiles: 1,
            tile_rows: 25,
            records,
            wall_seconds: 0.5,
            nonfinite_samples: 0,
            timestamps_supported: true,
        }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * b.abs().max(1.0)
    }

    #[test]
    fn pass_rows_figures() {
        let s = sample();
        assert_eq!(s.gpu_total_ns(), 10_000_000);
        let rows = s.pass_rows();
        let names: Vec<_> = rows.iter().map(|r| r.pass.name()).collect();
        assert_eq!(
            names,
            ["generate", "intersect", "shade", "shadow", "accumulate"]
        );

        let g = &rows[0];
        assert_eq!((g.dispatches, g.rays), (2, 2000));
        assert!(close(g.total_ms, 1.0) && close(g.percent, 10.0));
        assert!(close(g.avg_ms, 0.5) && close(g.min_ms, 0.5) && close(g.max_ms, 0.5));
        assert!(close(g.mrays_per_s, 2.0)); // 2000 rays in 1 ms

        let i = &rows[1];
        assert_eq!((i.dispatches, i.rays), (4, 3200));
        assert!(close(i.total_ms, 5.0) && close(i.percent, 50.0));
        assert!(close(i.avg_ms, 1.25) && close(i.min_ms, 1.0) && close(i.max_ms, 1.5));
        assert!(close(i.mrays_per_s, 3200.0 / 5e-3 / 1e6)); // 0.64

        let sh = &rows[3];
        assert_eq!((sh.dispatches, sh.rays), (4, 1600));
        assert!(close(sh.total_ms, 1.0) && close(sh.percent, 10.0));
        assert!(close(sh.mrays_per_s, 1.6));

        let sd = &rows[2];
        assert_eq!((sd.dispatches, sd.rays), (4, 3200));
        assert!(close(sd.total_ms, 3.0) && close(sd.percent, 30.0));
        assert!(close(sd.avg_ms, 0.75) && close(sd.min_ms, 0.75) && close(sd.max_ms, 0.75));

        let a = &rows[4];
        assert_eq!((a.dispatches, a.rays), (2, 0));
        assert_eq!((a.total_ms, a.percent, a.mrays_per_s), (0.0, 0.0, 0.0));

        let pct: f64 = rows.iter().map(|r| r.percent).sum();
        assert!(close(pct, 100.0));
    }

    #[test]
    fn rays_per_bounce_figures() {
        let per = sample().rays_per_bounce();
        assert_eq!(per.len(), 2);
        assert_eq!(per[0].0, 0);
        assert_eq!(per[0].1[&Pass::Intersect], 2000);
        assert_eq!(per[0].1[&Pass::Shade], 2000);
        assert_eq!(per[0].1[&Pass::Shadow], 1000);
        assert_eq!(per[1].0, 1);
        assert_eq!(per[1].1[&Pass::Intersect], 1200);
        assert_eq!(per[1].1[&Pass::Shadow], 600);
        assert!(!per[0].1.contains_key(&Pass::Generate));
    }

    #[test]
    fn table_layout_and_figures() {
        let t = sample().table();
        let lines: Vec<&str> = t.lines().collect();
        assert!(lines[0].contains("llvmpipe"), "{t}");
        // Header with the columns in order, then an alignment rule.
        let cols: Vec<&str> = lines[1]
            .split('|')
            .map(str::trim)
            .filter(|c| !c.is_empty())
            .collect();
        assert_eq!(
            cols,
            [
                "pass",
                "dispatches",
                "total ms",
                "%",
                "avg ms",
                "min ms",
                "max ms",
                "rays",
                "Mrays/s"
            ]
        );
        assert!(
            lines[2].starts_with("|---") && lines[2].ends_with(":|"),
            "{t}"
        );
        // Every table line has the same width.
        for l in &lines[1..8] {
            assert_eq!(l.chars().count(), lines[1].chars().count(), "{t}");
        }
        let intersect = lines[4];
        assert!(intersect.starts_with("| intersect "), "{t}");
        for fig in [
            "| 4 |",
            "| 5.000 |",
            "| 50.0 |",
            "| 1.250 |",
            "| 1.000 |",
            "| 1.500 |",
            "| 3200 |",
            "| 0.64 |",
        ] {
            let squeezed = intersect.split_whitespace().collect::<Vec<_>>().join(" ");
            assert!(squeezed.contains(fig), "{fig} not in {intersect}");
        }
        // Right-aligned: the number ends at the column's right edge.
        assert!(intersect.contains(" 3200 |"));
        // 40×25×2 = 2000 samples in 0.5 s.
        assert!(
            t.contains("GPU total: 10.000 ms, wall: 0.500 s, 4000 samples/s (40×25×2 / 0.500 s)"),
            "{t}"
        );
        assert!(t.contains("rays per bounce:"), "{t}");
        let squeezed: String = t.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(
            squeezed.contains("| bounce | intersect | shade | shadow |"),
            "{t}"
        );
        assert!(squeezed.contains("| 0 | 2000 | 2000 | 1000 |"), "{t}");
        assert!(squeezed.contains("| 1 | 1200 | 1200 | 600 |"), "{t}");
        assert!(!t.contains("n/a"));
        assert!(!t.ends_with('\n'));
        println!("{t}");
    }

    #[test]
    fn table_without_timestamps() {
        let mut s = sample();
        s.timestamps_supported = false;
        for r in &mut s.records {
            r.gpu_ns = 0;
        }
        s.nonfinite_samples = 3;
        let t = s.table();
        assert!(t.contains("n/a"), "{t}");
        assert!(t.contains("not supported"), "{t}");
        assert!(t.contains("3 non-finite samples"), "{t}");
        let rows = s.pass_rows();
        assert!(rows
            .iter()
            .all(|r| r.percent == 0.0 && r.mrays_per_s == 0.0));
    }

    #[test]
    fn empty_stats_do_not_panic() {
        let s = RenderStats::default();
        assert!(s.pass_rows().is_empty());
        let t = s.table();
        assert!(t.contains("GPU total"), "{t}");
        assert!(t.contains("n/a samples/s"), "{t}");
        let _ = s.to_json();
    }

    #[test]
    fn json_contents() {
        let s = sample();
        let v = s.to_json();
        assert_eq!(v["device"], "llvmpipe (LLVM 15.0.6, 256 bits)");
        assert_eq!(v["driver"], "llvmpipe Mesa 22.3.6");
        assert_eq!(v["width"], 40);
        assert_eq!(v["sampler"], "independent");
        assert_eq!(v["samples"], 2000);
        assert_eq!(v["gpu_total_ms"], 10.0);
        assert_eq!(v["samples_per_second"], 4000.0);
        assert_eq!(v["passes"].as_array().unwrap().len(), 5);
        assert_eq!(v["passes"][1]["pass"], "intersect");
        assert_eq!(v["passes"][1]["rays"], 3200);
        assert_eq!(v["passes"][1]["percent"], 50.0);
        assert_eq!(v["rays_per_bounce"][1]["bounce"], 1);
        assert_eq!(v["rays_per_bounce"][1]["rays"]["shadow"], 600);
        assert_eq!(v["records"].as_array().unwrap().len(), s.records.len());
        assert_eq!(v["records"][0]["pass"], "generate");
        assert_eq!(v["records"][0]["bounce"], Value::Null);
        assert_eq!(v["records"][1]["gpu_ns"], 1_000_000);

        let text = serde_json::to_string_pretty(&v).unwrap();
        let back: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back["passes"][1], v["passes"][1]);
    }
}
