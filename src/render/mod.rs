//! The renderer: a scene on the device, rendered a wave of paths at a time.
//!
//! Per wave (a rectangle of pixels by a chunk of samples, in a band of rows
//! of the film), the wavefront schedule records
//! `generate; for bounce { intersect; shade; shadow }; accumulate`, each pass
//! after generate dispatched indirectly from the queue header the previous
//! pass wrote. The bounces go in command buffers of at most
//! [`BOUNCES_PER_SUBMIT`]; between two, the renderer reads back how many
//! paths are left and stops recording bounces when none is. The megakernel
//! schedule runs a whole wave in one dispatch.
//!
//! - [`kernels`]: the kernel set (passes, schedules, samplers, features, SPIR-V);
//! - [`sobol`]: the Sobol sampler's direction numbers and numbers, on the CPU;
//! - `buffers`: the buffer table, one row per binding;
//! - `record`: how each pass and the megakernel are recorded;
//! - `film`: the film on the device and the host, and its resolve;
//! - [`tiles`]: bands of rows and waves; [`budget`]: time and error budgets;
//! - [`adaptive`]: renders that give each pixel the samples its noise needs;
//! - [`stats`]: per-pass records, tables, JSON and traces;
//! - `hooks`: hidden test hooks that run single kernels.

pub mod adaptive;
pub mod budget;
mod buffers;
pub mod film;
mod hooks;
pub mod kernels;
mod record;
pub mod sobol;
pub mod specialise;
pub mod stats;
pub mod tiles;

use std::ops::Range;

use anyhow::{Context as _, Result};

use self::buffers::{advise, buffer_table, max_texture_bytes, wave_capacity, DeviceBuffers};
use self::film::{BandFilm, HostFilm, Progress, Resolved};
use self::kernels::{Features, Integrator, Kernels, Sampler, Schedule};
use self::record::ray_queue_of;

use self::stats::{PassRecord, RenderStats, SceneInfo};
use self::tiles::{bands, rows_per_tile, Tile, Wave};
use crate::gpu::bindings::*;
pub use crate::gpu::LightSelection;
use crate::gpu::{GpuFilmPixel, GpuFrame, GpuPush, GpuScene, PackOptions};
use crate::interface::*;
use crate::scene::Scene;
use crate::vk::{Bindings, ComputePipeline, Context};

pub use self::buffers::MAX_TEXTURE_BYTES_ENV;
pub use self::hooks::{
    KernelBsdfEval, KernelBsdfSample, KernelHit, KernelLightSample, Probe, ProbeResult,
};

/// How to render, beyond what the scene file says.
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// How the kernels of a wave are scheduled.
    pub schedule: Schedule,
    /// Paths in flight per wave; `None`: the device's default
    /// ([`default_wave_size`]). The image does not depend on it, bit for bit.
    pub wave_size: Option<u32>,
    /// The estimator.
    pub integrator: Integrator,
    /// Where the random numbers of every path come from.
    pub sampler: Sampler,
    /// Turn every feature on, whatever the scene calls for.
    pub all_features: bool,
    /// Sum the film in compensated f32 even where the device has f64.
    pub f32_film: bool,
    /// The film will be read at sample counts not known in advance, with
    /// its error estimate (`converge`, `--time-limit`, `--target-error`):
    /// jitter every sample uniformly over its pixel instead of stratifying
    /// by the scene's spp, so that every prefix of the samples is an
    /// unbiased image, and draw the Sobol sampler's even and odd samples as
    /// two independent sequences, so that the two half films estimate the
    /// error ([`film`]). A fixed-spp render draws one Sobol sequence per
    /// pixel, with less error at equal samples.
    pub progressive: bool,
    /// Most rows of the image whose film the device holds at once; `None`:
    /// as many as one storage binding holds. The image does not depend on
    /// it, bit for bit; lowering it lowers device memory.
    pub tile_rows: Option<u32>,
    /// How next-event estimation picks a light (by power by default).
    pub light_selection: LightSelection,
    /// Build the kernels for an adaptive render ([`adaptive`]): the waves
    /// take their pixels from a list, so that a pixel that has its samples
    /// launches no more paths. Needs `progressive`.
    pub adaptive: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            schedule: Schedule::Wavefront,
            wave_size: None,
            integrator: Integrator::Nee,
            sampler: Sampler::Sobol,
            all_features: false,
            f32_film: false,
            progressive: false,
            tile_rows: None,
            light_selection: LightSelection::Power,
            adaptive: false,
        }
    }
}

/// Bounces recorded in one command buffer. Between command buffers the
/// renderer reads how many paths are left, and stops recording bounces when
/// none is: a large `max_depth` costs only the bounces paths reach, and
/// command buffers stay short enough for a GPU watchdog.
pub const BOUNCES_PER_SUBMIT: u32 = 16;

/// Paths in flight per wave on a CPU device (lavapipe), and the fewest on
/// any device unless asked for: on llvmpipe 256 Ki, 1 Mi and 4 Mi paths
/// render in the same time (docs/performance.md), so the wave stays small.
pub const CPU_WAVE_SIZE: u32 = 1 << 18;

/// Most paths in flight per wave on a GPU by default. On an NVIDIA H200 a
/// 1024x1024 render at 256 spp took 1.12 s of render time with waves of
/// 256 Ki paths and 0.42 s with 4 Mi: a small wave leaves the GPU idle
/// between its submits and runs its late bounces on a few paths.
pub const GPU_WAVE_SIZE: u32 = 1 << 22;

/// Share of the largest device-local heap's budget that a GPU's default
/// wave may take for its path state and queues: one quarter.
const WAVE_HEAP_SHARE: u64 = 4;

/// Paths in flight per wave when the options do not say: [`CPU_WAVE_SIZE`]
/// on a CPU device; on a GPU the largest power of two up to
/// [`GPU_WAVE_SIZE`] whose path state takes at most a quarter of the
/// largest device-local heap's budget, and never below [`CPU_WAVE_SIZE`].
pub fn default_wave_size(ctx: &Context) -> u32 {
    wave_size_for(ctx.info().kind, ctx.device_local_budget())
}

/// [`default_wave_size`] for a device of `kind` whose largest device-local
/// heap has a budget of `device_local_bytes`.
fn wave_size_for(kind: crate::vk::DeviceKind, device_local_bytes: u64) -> u32 {
    if kind == crate::vk::DeviceKind::Cpu {
        return CPU_WAVE_SIZE;
    }
    let fits = device_local_bytes / WAVE_HEAP_SHARE / buffers::PATH_BYTES;
    let pow2 = fits.checked_ilog2().map_or(0, |log| 1u64 << log);
    pow2.clamp(CPU_WAVE_SIZE as u64, GPU_WAVE_SIZE as u64) as u32
}

/// The finished image and its figures.
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel rendered.
    pub spp: u32,
    /// Per-pixel mean radiance, RGB, row-major from the top-left.
    pub mean: Vec<f32>,
    /// Samples of each pixel, row-major, when they differ from pixel to
    /// pixel (an adaptive render, where `spp` is the most any pixel got);
    /// `None` when every pixel has `spp`.
    pub pixel_spp: Option<Vec<u32>>,
    /// Per-pixel variance of the mean, RGB (sample variance / spp): exact
    /// for independent samples, an overestimate for low-discrepancy ones;
    /// what the variance EXR holds and per-pixel z-tests use.
    pub var_of_mean: Vec<f32>,
    /// Per-pixel estimate of the mean's expected squared error, RGB, from
    /// the two half films (even and odd samples, [`film`]): in a
    /// progressive render unbiased under every sampler, one degree of
    /// freedom per value, so meant to be averaged over pixels: what the
    /// predicted relMSE uses. In a fixed-spp render the halves are
    /// stratified against each other and it overstates the error.
    pub error_estimate: Vec<f32>,
    /// Timings and ray counts.
    pub stats: RenderStats,
}

/// How far one call of [`Renderer::render_to`] (or `render`,
/// `render_samples`) has come: `done` of its `total` waves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WaveProgress {
    /// Waves rendered so far by this call.
    pub done: u64,
    /// Waves this call renders.
    pub total: u64,
}

/// Who watches a render's waves, e.g. to draw a progress bar: called with
/// `done` 0 when a call starts and after every wave (`done == total` after
/// the last). `None` watches nothing.
pub type OnWave<'a> = Option<&'a dyn Fn(WaveProgress)>;

/// The pixels one call renders samples of.
#[derive(Debug, Clone, Copy)]
enum Pixels<'a> {
    /// Every pixel of the image.
    All,
    /// These pixels (row-major indices, ascending), each with the sample
    /// its samples of the call count from.
    List(&'a [glam::UVec2]),
}

/// A scene on the device, ready to render waves of paths.
pub struct Renderer<'c> {
    ctx: &'c Context,
    features: Features,
    /// The estimator asked for (the features say whether NEE runs).
    integrator: Integrator,
    /// How the kernels of a wave are scheduled.
    schedule: Schedule,
    /// Frame constants; `frame.wave_capacity` is the paths per wave.
    frame: GpuFrame,
    kernels: Kernels,
    buffers: DeviceBuffers,
    bindings: Bindings,
    /// Primitive count, BVH nodes and depth, for `lancer info`.
    pub scene_info: SceneInfo,
    push: GpuPush,
    /// The film holds f64 sums (else compensated f32).
    film_fp64: bool,
    /// Original primitive index (spheres, then triangles) of each leaf slot.
    prim_order: Vec<u32>,
    /// The bands of rows the film is rendered in, top to bottom.
    tiles: Vec<Tile>,
    /// The whole film, when the device holds one band of several at a time
    /// and a render comes back to the bands (made on the first band kept).
    host_film: Option<HostFilm>,
    /// Where the film of an image of several bands is.
    band_film: BandFilm,
    /// What the film holds so far.
    progress: Progress,
    /// What packing the scene changed that the user should know of.
    warnings: Vec<String>,
    /// The material test kernel, built on first use by a test hook.
    test_bsdf: Option<ComputePipeline>,
}

impl<'c> Renderer<'c> {
    /// Packs `scene`, chooses the wave, allocates every buffer and builds
    /// the kernels.
    pub fn new(ctx: &'c Context, scene: &Scene, options: &RenderOptions) -> Result<Renderer<'c>> {
        anyhow::ensure!(
            !options.adaptive || options.progressive,
            "RenderOptions::adaptive reads the film at sample counts not known in advance: \
             set RenderOptions::progressive too"
        );
        // A scene whose integrator finds light by BSDF sampling alone
        // (Mitsuba's `direct` with `emitter_samples` 0) renders with that
        // estimator: it decides what the image is
        let scene_asks_bsdf = scene.render.bsdf_sampling_only;
        let forced;
        let options = if scene_asks_bsdf && options.integrator != Integrator::Bsdf {
            forced = RenderOptions {
                integrator: Integrator::Bsdf,
                ..options.clone()
            };
            &forced
        } else {
            options
        };
        let features = Features {
            sampler: options.sampler,
            pixel_list: options.adaptive,
            ..if options.all_features {
                Features::all(options.integrator)
            } else {
                Features::detect(scene, options.integrator)
            }
        };
        let pack = PackOptions {
            max_texture_bytes: max_texture_bytes(ctx)?,
            wave_capacity: wave_capacity(ctx, scene, options)?,
            progressive: options.progressive,
            light_selection: options.light_selection,
        };
        let packed = GpuScene::pack(scene, &pack)?;
        let frame = packed.frame;

        // Split the film into bands of rows that fit one binding
        let film_limit =
            ctx.info().max_storage_buffer_range / std::mem::size_of::<GpuFilmPixel>() as u64;
        let rows = rows_per_tile(frame.width, frame.height, film_limit, options.tile_rows);
        let tiles = bands(frame.width, frame.height, rows);
        let film_pixels = u64::from(rows) * u64::from(frame.width);
        let table = buffer_table(
            &packed,
            &frame,
            options.schedule,
            film_pixels,
            features.pixel_list,
        )?;
        let buffers = DeviceBuffers::allocate(ctx, &table, &frame)?;
        let bindings = ctx
            .create_bindings("wavefront", &buffers.bindings())
            .map_err(|e| advise(e.into(), &frame))?;

        // Specialise the kernels to the scene; the film sums in f64 where it can
        let film_fp64 = ctx.info().shader_float64 && !options.f32_film;
        let kernels = Kernels::build(ctx, &features, options.schedule, &bindings, film_fp64)
            .map_err(|e| advise(e, &frame))?;

        let scene_info = SceneInfo {
            materials: scene.materials.len(),
            spheres: scene.spheres.len(),
            triangles: scene.triangles.len(),
            emitters: packed.emitters.len(),
            bvh_nodes: packed.bvh_nodes,
            bvh_depth: packed.bvh_depth,
            bvh_sah_cost: packed.bvh_sah_cost,
            bvh_seconds: packed.bvh_seconds,
            device_bytes: buffers.bytes(),
        };
        Ok(Renderer {
            ctx,
            features,
            integrator: options.integrator,
            schedule: options.schedule,
            frame,
            kernels,
            buffers,
            prim_order: packed.prim_order,
            tiles,
            host_film: None,
            band_film: BandFilm::Empty,
            film_fp64,
            bindings,
            scene_info,
            push: GpuPush::default(),
            progress: Progress::default(),
            test_bsdf: None,
            warnings: {
                let mut w = packed.textures.warnings;
                if scene_asks_bsdf && !scene.lights.is_empty() {
                    w.push(String::from(
                        "the scene's integrator finds light by BSDF sampling alone \
                         (emitter_samples = 0), which finds no point, spot or directional \
                         light: they add nothing, as in Mitsuba",
                    ));
                } else if options.integrator == Integrator::Bsdf
                    && (!scene.lights.is_empty() || scene.render.emitter_sampling_only)
                {
                    w.push(String::from(
                        "the bsdf integrator (BSDF sampling alone) finds no point, spot or \
                         directional light, and no light at all where the scene asks for \
                         emitter sampling alone (bsdf_samples = 0): those add nothing; use nee",
                    ));
                }
                w
            },
        })
    }

    /// What packing the scene for the device changed, one line each: the
    /// textures shrunk to fit the device's texture binding.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The features the kernels were specialised for.
    pub fn features(&self) -> &Features {
        &self.features
    }

    /// How the kernels of a wave are scheduled.
    pub fn schedule(&self) -> Schedule {
        self.schedule
    }

    /// Whether the film sums in f64 (`shaderFloat64`) rather than compensated f32.
    pub fn film_fp64(&self) -> bool {
        self.film_fp64
    }

    /// Paths in flight per wave.
    pub fn wave_capacity(&self) -> u32 {
        self.frame.wave_capacity
    }

    /// Bands of rows the film is rendered in (1 when the device holds the
    /// whole film).
    pub fn tile_count(&self) -> u32 {
        self.tiles.len() as u32
    }

    /// Bytes of film the host holds: none for an image of one band, or for
    /// [`Renderer::render`], which resolves each band once its samples are
    /// done; 24 bytes per pixel and sum (of 3) once a render comes back to
    /// the bands of an image of several.
    pub fn host_film_bytes(&self) -> u64 {
        self.host_film.as_ref().map_or(0, HostFilm::bytes)
    }

    /// Rows of the tallest band: the film the device holds at once is
    /// this many rows of the image.
    pub fn tile_rows(&self) -> u32 {
        self.tiles.iter().map(|t| t.rows).max().unwrap_or(0)
    }

    /// Renders every sample of the image and reads the film back. An image
    /// of several bands is resolved a band at a time, as soon as the band's
    /// samples are done, and its film is not kept: the host holds the
    /// image's means and variances, not its sums ([`Renderer::output`] and
    /// [`Renderer::film_sums`] then need a [`Renderer::restart`] and
    /// [`Renderer::render_to`]).
    pub fn render(&mut self, progress: OnWave<'_>) -> Result<RenderOutput> {
        self.restart()?;
        if self.tiles.len() == 1 {
            self.render_to(self.frame.spp, progress)?;
            return self.output();
        }
        let mut resolved = Resolved::with_capacity(3 * self.frame.pixel_count as usize);
        let spp = self.frame.spp;
        let rendered = self.render_bands(Pixels::All, 0..spp, progress, Some(&mut resolved));
        rendered.map_err(|e| advise(e, &self.frame))?;
        self.progress.spp = spp;
        self.band_film = BandFilm::Resolved;
        self.output_of(resolved)
    }

    /// Empties the film and the figures: the next samples start a new image.
    pub fn restart(&mut self) -> Result<()> {
        self.clear_film().map_err(|e| advise(e, &self.frame))?;
        self.progress = Progress::default();
        Ok(())
    }

    /// Samples per pixel the film holds.
    pub fn spp_done(&self) -> u32 {
        self.progress.spp - self.progress.first
    }

    /// Empties the film and renders samples `first..end` of every pixel
    /// (a part of a render split across machines, see `crate::io::film`): the
    /// samples are the very ones a whole render draws, because random
    /// numbers depend only on (seed, pixel, sample, dimension) and the
    /// stratification on the scene's spp.
    pub fn render_samples(&mut self, first: u32, end: u32, progress: OnWave<'_>) -> Result<()> {
        anyhow::ensure!(
            first < end && end <= self.frame.spp,
            "samples {first}..{end}: need first < end <= the scene's spp ({})",
            self.frame.spp
        );
        self.restart()?;
        self.progress.first = first;
        self.progress.spp = first;
        self.render_to(end, progress)
    }

    /// The film's raw sums, per pixel and channel (RGB interleaved), in
    /// f64, and the count of samples dropped for a NaN or infinite radiance.
    pub fn film_sums(&self) -> Result<(film::FilmSums, u64)> {
        let sums = self.sums()?;
        let nonfinite = self.ctx.read::<u32>(self.buffers.get(BINDING_COUNTERS))?
            [COUNTER_NONFINITE as usize] as u64;
        Ok((sums, nonfinite))
    }

    /// Pixels of the image.
    pub fn pixel_count(&self) -> u32 {
        self.frame.pixel_count
    }

    /// Samples each pixel holds since [`Renderer::restart`], row-major.
    pub fn pixel_spp(&self) -> Vec<u32> {
        let done = self.progress.pixel_counts(self.frame.pixel_count as usize);
        done.into_iter()
            .map(|n| n - self.progress.first.min(n))
            .collect()
    }

    /// Wall-clock seconds spent rendering since [`Renderer::restart`]
    /// (reading the film back is not counted).
    pub fn render_seconds(&self) -> f64 {
        self.progress.seconds
    }

    /// The render seconds the film will have taken once it holds `spp`
    /// samples per pixel, at the time per sample measured so far; `None`
    /// before the first sample. Budgets use it to start only what fits.
    pub fn seconds_at(&self, spp: u32) -> Option<f64> {
        let done = self.spp_done();
        (done > 0).then(|| self.progress.seconds / done as f64 * spp as f64)
    }

    /// Whole samples per pixel that one wave holds (at least 1): the natural
    /// step of a progressive render.
    /// It depends only on the image and the wave capacity: every band
    /// chunks a pixel's samples alike (see `crate::render::tiles`).
    pub fn spp_per_wave(&self) -> u32 {
        (self.frame.wave_capacity / self.frame.pixel_count).max(1)
    }

    /// Renders samples `spp_done()..spp` of every pixel into the film, which
    /// keeps what it holds: a progressive render calls this with a growing
    /// `spp` and reads [`Renderer::output`] in between. Random numbers depend
    /// only on (seed, pixel, sample, dimension), so the image does not depend
    /// on how the samples are split into calls.
    pub fn render_to(&mut self, spp: u32, progress: OnWave<'_>) -> Result<()> {
        anyhow::ensure!(
            self.progress.pixel_spp.is_none(),
            "Renderer::render_to samples every pixel alike, and this film's pixels have \
             different counts: continue with Renderer::render_pixels"
        );
        let samples = self.progress.spp..spp.max(self.progress.spp);
        let rendered = self.render_bands(Pixels::All, samples.clone(), progress, None);
        rendered.map_err(|e| advise(e, &self.frame))?;
        self.progress.spp = samples.end;
        Ok(())
    }

    /// Renders the next `count` samples of each of the pixels `pixels`
    /// (row-major indices, ascending, each once), after the samples each
    /// holds so far: the step of an adaptive render ([`adaptive`]), which
    /// needs a renderer built with `RenderOptions::adaptive`. Stopped pixels
    /// launch no paths: the waves hold only the pixels listed, whatever
    /// samples each holds.
    pub fn render_pixels(
        &mut self,
        pixels: &[u32],
        count: u32,
        progress: OnWave<'_>,
    ) -> Result<()> {
        anyhow::ensure!(
            self.features.pixel_list,
            "Renderer::render_pixels needs kernels built for a pixel list: set \
             RenderOptions::adaptive"
        );
        let pixel_count = self.frame.pixel_count as usize;
        let mut counts = self.progress.pixel_counts(pixel_count);
        anyhow::ensure!(
            pixels.windows(2).all(|w| w[0] < w[1])
                && pixels.last().is_none_or(|&p| (p as usize) < pixel_count),
            "Renderer::render_pixels: the pixels must be ascending image indices below {pixel_count}"
        );
        if let Some(&p) = pixels
            .iter()
            .find(|&&p| counts[p as usize].checked_add(count).is_none())
        {
            anyhow::bail!("Renderer::render_pixels: pixel {p} would hold more than 2^32 samples");
        }
        let entries: Vec<glam::UVec2> = pixels
            .iter()
            .map(|&p| glam::UVec2::new(p, counts[p as usize]))
            .collect();
        let rendered = self.render_bands(Pixels::List(&entries), 0..count, progress, None);
        rendered.map_err(|e| advise(e, &self.frame))?;
        for &p in pixels {
            counts[p as usize] += count;
        }
        self.progress.set_pixel_counts(counts);
        Ok(())
    }

    /// Renders `samples` of `pixels`, band by band: of every pixel, or, for
    /// a list, samples `samples` past each entry's own first. With
    /// `resolved`, each band's film is resolved into it once the band is
    /// done instead of kept.
    fn render_bands(
        &mut self,
        pixels: Pixels<'_>,
        samples: Range<u32>,
        progress: OnWave<'_>,
        mut resolved: Option<&mut Resolved>,
    ) -> Result<()> {
        let started = std::time::Instant::now();
        let end = samples.end;
        // With kernels that read a pixel list, every pixel is a list too
        let every: Vec<glam::UVec2>;
        let (pixels, samples) = match pixels {
            Pixels::All if self.features.pixel_list => {
                let first = samples.start;
                every = (0..self.frame.pixel_count)
                    .map(|p| glam::UVec2::new(p, first))
                    .collect();
                (Pixels::List(&every), 0..samples.len() as u32)
            }
            p => (p, samples),
        };
        let per_wave = self.samples_per_wave(pixels);
        let waves: usize = self
            .tiles
            .iter()
            .map(|&tile| {
                self.waves_of(tile, pixels, samples.clone(), per_wave)
                    .1
                    .len()
            })
            .sum();
        // Called at the start and after every wave
        let mut done = 0;
        let mut on_wave = || {
            if let Some(f) = progress {
                let total = waves as u64;
                f(WaveProgress { done, total });
            }
            done += 1;
        };
        on_wave();
        // Resolving a band is reading the film back: not rendering
        let mut resolving = std::time::Duration::ZERO;
        for tile in self.tiles.clone() {
            let (list, waves) = self.waves_of(tile, pixels, samples.clone(), per_wave);
            match resolved.as_deref_mut() {
                None if waves.is_empty() => continue,
                None => {
                    self.load_tile(tile)?;
                    self.render_waves(tile, list, &waves, &mut on_wave)?;
                    self.store_tile(tile)?;
                }
                Some(out) => {
                    // The device's film holds the band before: start from zero
                    if tile.first_pixel > 0 {
                        self.clear_device_film()?;
                    }
                    self.render_waves(tile, list, &waves, &mut on_wave)?;
                    self.band_film = BandFilm::Resolved;
                    let read = std::time::Instant::now();
                    self.resolve_device_band(tile, self.progress.first, end, out)?;
                    resolving += read.elapsed();
                }
            }
        }
        self.progress.seconds += (started.elapsed() - resolving).as_secs_f64();
        Ok(())
    }

    /// Samples per pixel of one wave that renders `pixels`: as many as the
    /// wave holds for that many pixels (at least 1, at most
    /// [`MAX_WAVE_SAMPLES_PER_PIXEL`]). It depends on how many pixels the
    /// whole image renders, never on the band: every band chunks a pixel's
    /// samples alike (see `crate::render::tiles`).
    fn samples_per_wave(&self, pixels: Pixels<'_>) -> u32 {
        match pixels {
            Pixels::All => self.spp_per_wave(),
            Pixels::List(list) => (self.frame.wave_capacity / (list.len().max(1) as u32))
                .clamp(1, MAX_WAVE_SAMPLES_PER_PIXEL),
        }
    }

    /// The waves that render `samples` of `pixels` in `tile`, and, for a
    /// list, the part of it in the band: the waves' pixel bases then index
    /// that part, and their samples count from each entry's own first.
    fn waves_of<'p>(
        &self,
        tile: Tile,
        pixels: Pixels<'p>,
        samples: Range<u32>,
        per_wave: u32,
    ) -> (Option<&'p [glam::UVec2]>, Vec<Wave>) {
        let capacity = self.frame.wave_capacity;
        match pixels {
            Pixels::All => (
                None,
                tiles::waves(tile, samples, per_wave, capacity).collect(),
            ),
            Pixels::List(list) => {
                let range = tile.pixel_range();
                let lo = list.partition_point(|e| (e.x as usize) < range.start);
                let hi = list.partition_point(|e| (e.x as usize) < range.end);
                let part = &list[lo..hi];
                let entries = Tile {
                    first_pixel: 0,
                    pixels: part.len() as u32,
                    ..tile
                };
                let waves = if part.is_empty() {
                    Vec::new()
                } else {
                    tiles::waves(entries, samples, per_wave, capacity).collect()
                };
                (Some(part), waves)
            }
        }
    }

    /// Renders `waves` of `tile` into the device's film, after its part of
    /// the pixel list when the waves read one.
    fn render_waves(
        &mut self,
        tile: Tile,
        list: Option<&[glam::UVec2]>,
        waves: &[Wave],
        on_wave: &mut dyn FnMut(),
    ) -> Result<()> {
        if let Some(list) = list {
            self.ctx
                .write(self.buffers.get(BINDING_PIXEL_LIST), 0, list)
                .with_context(|| format!("loading the pixel list of rows {}..", tile.first_row))?;
        }
        for &wave in waves {
            crate::util::interrupt::check()?;
            let index = self.progress.waves;
            let records = match self.schedule {
                Schedule::Wavefront => self.render_wave(tile, wave, index)?,
                Schedule::Megakernel => self.megakernel(tile, wave, index)?,
            };
            self.progress.records.extend(records);
            self.progress.waves += 1;
            on_wave();
        }
        Ok(())
    }

    /// Renders one wave of `tile`:
    /// `generate; for depth { intersect; shade; shadow }; accumulate`, in
    /// command buffers of at most [`BOUNCES_PER_SUBMIT`] bounces. Once no
    /// path is left, no further bounce is recorded, so a huge `max_depth`
    /// costs only the bounces that paths reach.
    fn render_wave(&mut self, tile: Tile, wave: Wave, index: u32) -> Result<Vec<PassRecord>> {
        let max_dispatches = 2 + 3 * BOUNCES_PER_SUBMIT;
        let count = wave.paths();
        let mut records = Vec::new();
        let mut rec = self.ctx.begin("wave", max_dispatches)?;

        self.generate(&mut rec, tile, wave);
        let mut first = 0u32;
        loop {
            let last = first
                .saturating_add(BOUNCES_PER_SUBMIT)
                .min(self.frame.max_depth);
            for bounce in first..last {
                self.intersect(&mut rec, bounce);
                self.shade(&mut rec, bounce);
                if self.features.nee {
                    self.shadow(&mut rec, bounce);
                }
            }
            let deepest = last == self.frame.max_depth;
            if deepest {
                self.accumulate(&mut rec);
            }
            let timings = self.ctx.submit(rec)?;
            records.extend(self.wave_records(&timings, count, index)?);
            if deepest {
                return Ok(records);
            }
            rec = self.ctx.begin("wave", max_dispatches)?;
            // Stop recording bounces once no path is left
            if self.queue_len(ray_queue_of(last))? == 0 {
                self.accumulate(&mut rec);
                let timings = self.ctx.submit(rec)?;
                records.extend(self.wave_records(&timings, count, index)?);
                return Ok(records);
            }
            first = last;
        }
    }

    /// Reads the film back: the image of every sample rendered since
    /// [`Renderer::restart`], and the figures of every wave.
    pub fn output(&self) -> Result<RenderOutput> {
        self.output_of(self.resolve_film()?)
    }

    /// The figures of every wave since [`Renderer::restart`], without the
    /// image.
    pub fn stats(&self) -> Result<RenderStats> {
        Ok(self.output_of(Resolved::default())?.stats)
    }

    /// The render output of the film resolved as `resolved`.
    fn output_of(&self, resolved: Resolved) -> Result<RenderOutput> {
        let Resolved {
            mean,
            var_of_mean,
            error: error_estimate,
        } = resolved;
        let nonfinite = self.ctx.read::<u32>(self.buffers.get(BINDING_COUNTERS))?
            [COUNTER_NONFINITE as usize] as u64;
        let info = self.ctx.info();
        let pixel_spp = self.progress.pixel_spp.clone();
        let (spp, samples) = match &pixel_spp {
            Some(counts) => (
                counts.iter().copied().max().unwrap_or(0),
                counts.iter().map(|&n| u64::from(n)).sum(),
            ),
            None => {
                let spp = self.spp_done();
                (spp, u64::from(self.frame.pixel_count) * u64::from(spp))
            }
        };
        let stats = RenderStats {
            device: info.name.clone(),
            driver: info.driver_name.clone(),
            width: self.frame.width,
            height: self.frame.height,
            spp,
            samples,
            adaptive: pixel_spp.is_some(),
            max_depth: self.frame.max_depth,
            rr_depth: self.frame.rr_depth,
            seed: self.frame.seed,
            integrator: self.integrator,
            sampler: self.features.sampler,
            wave_size: self.frame.wave_capacity,
            waves: self.progress.waves,
            tiles: self.tile_count(),
            tile_rows: self.tile_rows(),
            records: self.progress.records.clone(),
            wall_seconds: self.progress.seconds,
            nonfinite_samples: nonfinite,
            timestamps_supported: info.timestamps_supported,
        };
        Ok(RenderOutput {
            width: self.frame.width,
            height: self.frame.height,
            spp,
            mean,
            pixel_spp,
            var_of_mean,
            error_estimate,
            stats,
        })
    }
}
