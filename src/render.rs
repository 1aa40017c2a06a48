//! The wavefront renderer: device buffers sized by the wave, five kernels,
//! and the render loop.
//!
//! Per wave of paths, one command buffer holds
//! `generate -> { intersect -> shade -> shadow } x depth -> accumulate`,
//! with every pass after generate dispatched indirectly from the queue
//! counters the previous pass wrote. Nothing is read back between bounces.

use anyhow::Result;
use bytemuck::bytes_of;

use std::collections::BTreeMap;

use anyhow::Context as _;
use glam::Vec4;

use crate::features::{Features, Integrator};
use crate::gpu::{GpuFilmPixel, GpuFrame, GpuHit, GpuPush, GpuQueueHeader, GpuScene};
use crate::pass::Pass;
use crate::scene::Scene;
use crate::shader_interface::*;
use crate::stats::{PassRecord, RenderStats};
use crate::vk::{BindingKind, Bindings, Buffer, ComputePipeline, Context, MemoryKind, Recorder};

/// How the kernels of a wave are scheduled. Both give the same image, bit
/// for bit: they run the same path functions (`shaders/common/path.glsl`)
/// and fold paths into the film in the same order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Schedule {
    /// One kernel per pass (generate, then intersect, shade and shadow per
    /// bounce, then accumulate), path state in buffers, rays in queues.
    #[default]
    Wavefront,
    /// One kernel per wave: each thread follows its pixel's paths from the
    /// camera to the film, path state in registers ("Megakernels
    /// considered harmful", Laine, Karras and Aila 2013, is the comparison).
    Megakernel,
}

impl Schedule {
    /// Every schedule, the default first.
    pub const ALL: [Schedule; 2] = [Schedule::Wavefront, Schedule::Megakernel];

    /// The schedule's name, as `--schedule` takes it.
    pub const fn name(self) -> &'static str {
        match self {
            Schedule::Wavefront => "wavefront",
            Schedule::Megakernel => "megakernel",
        }
    }
}

impl std::fmt::Display for Schedule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Schedule {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Schedule> {
        Schedule::ALL
            .into_iter()
            .find(|x| x.name() == s)
            .with_context(|| format!("unknown schedule {s:?}: use wavefront or megakernel"))
    }
}

/// How to render, beyond what the scene file says.
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// How the kernels of a wave are scheduled.
    pub schedule: Schedule,
    /// Paths in flight per wave.
    pub wave_size: u32,
    /// The estimator.
    pub integrator: Integrator,
    /// Turn every feature on, whatever the scene calls for.
    pub all_features: bool,
    /// Sum the film in compensated f32 even where the device has f64.
    pub f32_film: bool,
    /// The film will be read at sample counts not known in advance
    /// (`converge`, `--time-limit`, `--target-error`): jitter every sample
    /// uniformly over its pixel instead of stratifying by the scene's spp,
    /// so that every prefix of the samples is an unbiased image.
    pub progressive: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            schedule: Schedule::Wavefront,
            wave_size: DEFAULT_WAVE_SIZE,
            integrator: Integrator::Nee,
            all_features: false,
            f32_film: false,
            progressive: false,
        }
    }
}

/// Bounces recorded in one command buffer. Between command buffers the
/// renderer reads how many paths are left, and stops recording bounces when
/// none is: a large `max_depth` costs only the bounces paths reach, and
/// command buffers stay short enough for a GPU watchdog.
pub const BOUNCES_PER_SUBMIT: u32 = 16;

/// Default number of paths in flight.
pub const DEFAULT_WAVE_SIZE: u32 = 1 << 18;

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
    /// Per-pixel variance of the mean, RGB (sample variance / spp).
    pub var_of_mean: Vec<f32>,
    /// Timings and ray counts.
    pub stats: RenderStats,
}

/// The kernels of the passes the scene calls for, specialised to its features.
struct Kernels {
    by_pass: BTreeMap<Pass, ComputePipeline>,
}

impl Kernels {
    /// Builds one pipeline per pass of `features` under `schedule`.
    fn build(
        ctx: &Context,
        features: &Features,
        schedule: Schedule,
        bindings: &Bindings,
        film_fp64: bool,
    ) -> Result<Kernels> {
        let push_bytes = std::mem::size_of::<GpuPush>() as u32;
        let mut by_pass = BTreeMap::new();
        for pass in features.passes(schedule) {
            let spirv = pass.spirv(film_fp64);
            anyhow::ensure!(
                !spirv.is_empty(),
                "this lancer was built without its GPU kernels (cargo feature `kernels`, \
                 on by default); build it with default features to render"
            );
            let spec = features.spec_constants(pass);
            let pipeline = ctx
                .create_pipeline(pass.name(), spirv, bindings, &spec, push_bytes)
                .with_context(|| format!("building the {pass} kernel"))?;
            by_pass.insert(pass, pipeline);
        }
        Ok(Kernels { by_pass })
    }

    /// The kernel of `pass`; `None` when the scene does not call for it.
    fn get(&self, pass: Pass) -> Option<&ComputePipeline> {
        self.by_pass.get(&pass)
    }
}

/// What a device buffer starts with.
enum Contents<'a> {
    /// These bytes, uploaded once.
    Upload(&'a [u8]),
    /// This many bytes, written by the passes.
    Size(u64),
}

/// One row of the buffer table: a binding of the descriptor set.
struct BufferRow<'a> {
    binding: u32,
    /// Allocation and debug name: the pass that writes it, or `scene`.
    label: &'static str,
    contents: Contents<'a>,
    /// How the kernels read it.
    kind: BindingKind,
    /// A second binding where the kernels read the same buffer as RGBA32UI
    /// texels, while they write it through the storage binding.
    read_texels: Option<u32>,
}

/// A row whose buffer holds `items` of `T`; the byte count is checked.
fn sized<T>(binding: u32, label: &'static str, items: u64) -> Result<BufferRow<'static>> {
    let bytes = items
        .checked_mul(std::mem::size_of::<T>() as u64)
        .with_context(|| format!("{label}: {items} items overflow a buffer size"))?;
    Ok(BufferRow {
        binding,
        label,
        contents: Contents::Size(bytes),
        kind: BindingKind::Storage,
        read_texels: None,
    })
}

/// Path state written through `binding` and read as texels through
/// `texels`: on llvmpipe a per-lane texel fetch is a gather, where a
/// storage-buffer load of a per-lane address is a loop over the lanes.
fn path_state<T>(
    binding: u32,
    texels: u32,
    label: &'static str,
    wave: u64,
) -> Result<BufferRow<'static>> {
    const {
        assert!(std::mem::size_of::<T>().is_multiple_of(crate::vk::TEXEL_BYTES as usize));
    }
    Ok(BufferRow {
        read_texels: Some(texels),
        ..sized::<T>(binding, label, wave)?
    })
}

/// A row whose buffer is uploaded from `data`.
fn upload<'a, T: bytemuck::Pod>(binding: u32, label: &'static str, data: &'a [T]) -> BufferRow<'a> {
    BufferRow {
        binding,
        label,
        contents: Contents::Upload(bytemuck::cast_slice(data)),
        kind: BindingKind::Storage,
        read_texels: None,
    }
}

/// A row uploaded from `data` that the kernels read as RGBA32UI texels
/// (`texelFetch`): on llvmpipe a per-lane texel fetch is a gather, where a
/// storage-buffer load of a per-lane address is a loop over the lanes.
fn upload_texels<'a, T: bytemuck::Pod>(
    binding: u32,
    label: &'static str,
    data: &'a [T],
) -> BufferRow<'a> {
    const {
        assert!(std::mem::size_of::<T>().is_multiple_of(crate::vk::TEXEL_BYTES as usize));
    }
    BufferRow {
        kind: BindingKind::TexelRgba32Ui,
        ..upload(binding, label, data)
    }
}

/// Every device buffer the kernels bind, once: binding, label, contents.
/// Scene data is uploaded; path state and queues are sized by the wave
/// (one item under the megakernel, which keeps path state in registers and
/// binds them only because both schedules share one descriptor layout),
/// film and counters by the image.
fn buffer_table<'a>(
    packed: &'a GpuScene,
    frame: &'a GpuFrame,
    schedule: Schedule,
) -> Result<Vec<BufferRow<'a>>> {
    let wave = match schedule {
        Schedule::Wavefront => frame.wave_capacity as u64,
        Schedule::Megakernel => 1,
    };
    let pixels = frame.pixel_count as u64;
    Ok(vec![
        upload(BINDING_FRAME, "scene.frame", std::slice::from_ref(frame)),
        upload_texels(BINDING_BVH_NODES, "scene.bvh", &packed.bvh),
        upload_texels(BINDING_PRIMITIVES, "scene.primitives", &packed.primitives),
        upload_texels(
            BINDING_TRI_SHADING,
            "scene.tri_shading",
            &packed.tri_shading,
        ),
        upload_texels(BINDING_MATERIALS, "scene.materials", &packed.materials),
        upload_texels(BINDING_EMITTERS, "scene.emitters", &packed.emitters),
        upload(BINDING_TEXELS, "scene.texels", &packed.textures.words),
        sized::<GpuQueueHeader>(
            BINDING_QUEUE_HEADERS,
            "queues.headers",
            QUEUE_HEADER_COUNT as u64,
        )?,
        sized::<u32>(
            BINDING_RAY_QUEUES,
            "queues.rays",
            RAY_QUEUE_COUNT as u64 * wave,
        )?,
        sized::<u32>(BINDING_SHADOW_QUEUE, "queues.shadow", wave)?,
        path_state::<Vec4>(
            BINDING_RAY_ORIGIN,
            BINDING_RAY_ORIGIN_TEXELS,
            "generate.ray_origin",
            wave,
        )?,
        path_state::<Vec4>(
            BINDING_RAY_DIR,
            BINDING_RAY_DIR_TEXELS,
            "generate.ray_dir",
            wave,
        )?,
        path_state::<Vec4>(
            BINDING_THROUGHPUT,
            BINDING_THROUGHPUT_TEXELS,
            "shade.throughput",
            wave,
        )?,
        path_state::<Vec4>(
            BINDING_RADIANCE,
            BINDING_RADIANCE_TEXELS,
            "shade.radiance",
            wave,
        )?,
        path_state::<GpuHit>(BINDING_HITS, BINDING_HITS_TEXELS, "intersect.hits", wave)?,
        path_state::<Vec4>(
            BINDING_SHADOW_ORIGIN,
            BINDING_SHADOW_ORIGIN_TEXELS,
            "shade.shadow_origin",
            wave,
        )?,
        path_state::<Vec4>(
            BINDING_SHADOW_DIR,
            BINDING_SHADOW_DIR_TEXELS,
            "shade.shadow_dir",
            wave,
        )?,
        path_state::<Vec4>(
            BINDING_SHADOW_RADIANCE,
            BINDING_SHADOW_RADIANCE_TEXELS,
            "shade.shadow_radiance",
            wave,
        )?,
        sized::<GpuFilmPixel>(BINDING_FILM, "accumulate.film", pixels)?,
        sized::<GpuFilmPixel>(BINDING_FILM_SQ, "accumulate.film_sq", pixels)?,
        sized::<u32>(
            BINDING_COUNTERS,
            "accumulate.counters",
            COUNTER_COUNT as u64,
        )?,
    ])
}

/// Bytes per path of the widest per-path buffer of [`buffer_table`]: one
/// binding of it must hold a whole wave.
const WIDEST_PATH_ITEM: u64 = {
    let (a, b) = (std::mem::size_of::<Vec4>(), std::mem::size_of::<GpuHit>());
    (if a > b { a } else { b }) as u64
};

/// Device buffers: one per binding, from [`buffer_table`], and the
/// per-bounce ray counts read back after each wave.
struct DeviceBuffers {
    /// Indexed by binding number; `None` at a binding that is a texel view
    /// of another row's buffer.
    by_binding: Vec<Option<Buffer>>,
    /// How the kernels read each binding, indexed by binding number.
    kinds: Vec<BindingKind>,
    /// `(texel binding, storage binding)` of each buffer read as texels.
    read_views: Vec<(u32, u32)>,
    ray_counts: Buffer,
}

impl DeviceBuffers {
    /// Allocates (and uploads) every row of the table, plus the ray counts
    /// of the bounces one command buffer records.
    fn allocate(ctx: &Context, table: &[BufferRow<'_>], max_depth: u32) -> Result<DeviceBuffers> {
        let mut slots: Vec<Option<Buffer>> = (0..BINDING_COUNT).map(|_| None).collect();
        let mut kinds = vec![BindingKind::Storage; BINDING_COUNT as usize];
        let mut taken = vec![false; BINDING_COUNT as usize];
        let mut read_views = Vec::new();
        for row in table {
            for b in std::iter::once(row.binding).chain(row.read_texels) {
                anyhow::ensure!(
                    !std::mem::replace(&mut taken[b as usize], true),
                    "binding {b} is in the table twice"
                );
            }
            kinds[row.binding as usize] = row.kind;
            if let Some(texels) = row.read_texels {
                kinds[texels as usize] = BindingKind::TexelRgba32Ui;
                read_views.push((texels, row.binding));
            }
            let buffer = match row.contents {
                Contents::Upload(bytes) => ctx.upload(row.label, bytes),
                Contents::Size(size) => ctx.create_buffer(row.label, size, MemoryKind::Device),
            }
            .with_context(|| format!("allocating {}", row.label))?;
            slots[row.binding as usize] = Some(buffer);
        }
        if let Some(b) = taken.iter().position(|t| !t) {
            anyhow::bail!("binding {b} has no buffer");
        }
        let ray_counts = ctx.create_buffer(
            "stats.ray_counts",
            (max_depth.min(BOUNCES_PER_SUBMIT) as u64 * 2 * 4).max(16),
            MemoryKind::Readback,
        )?;
        Ok(DeviceBuffers {
            by_binding: slots,
            kinds,
            read_views,
            ray_counts,
        })
    }

    /// The buffer bound at `binding` (for a texel view, the buffer it views).
    fn get(&self, binding: u32) -> &Buffer {
        let storage = self
            .read_views
            .iter()
            .find(|(texels, _)| *texels == binding)
            .map_or(binding, |(_, storage)| *storage);
        self.by_binding[storage as usize]
            .as_ref()
            .expect("allocate checked that every binding has a buffer")
    }

    /// `(binding, buffer, kind)` for every binding, for the descriptor set.
    fn bindings(&self) -> Vec<(u32, &Buffer, BindingKind)> {
        (0..BINDING_COUNT)
            .map(|b| (b, self.get(b), self.kinds[b as usize]))
            .collect()
    }

    /// Bytes of device memory held by every buffer.
    fn bytes(&self) -> u64 {
        self.by_binding
            .iter()
            .flatten()
            .chain([&self.ray_counts])
            .map(Buffer::size)
            .sum()
    }
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
    /// What the film holds so far.
    progress: Progress,
}

/// What the film holds since the last [`Renderer::restart`].
#[derive(Debug, Clone, Default)]
struct Progress {
    /// First sample of every pixel the film holds (0 but for
    /// [`Renderer::render_samples`]).
    first: u32,
    /// End of the samples accumulated: the film holds samples
    /// `first..spp` of every pixel.
    spp: u32,
    /// Waves rendered.
    waves: u32,
    /// Every timed dispatch.
    records: Vec<PassRecord>,
    /// Wall-clock seconds spent rendering (readbacks excluded).
    seconds: f64,
}

/// The closest hit the intersect kernel found for one ray. A test hook for
/// [`Renderer::intersect_rays`], not part of the API.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KernelHit {
    /// Primitive index in scene order: spheres first, then triangles.
    pub prim: u32,
    /// Distance along the (unit) ray direction.
    pub t: f32,
}

/// Sizes of what the scene put on the device.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SceneInfo {
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

/// Paths per wave: what the options ask for, at most every sample of the
/// image, and within one dispatch (`maxComputeWorkGroupCount`) and one
/// binding of the widest per-path buffer.
fn wave_capacity(ctx: &Context, scene: &Scene, options: &RenderOptions) -> Result<u32> {
    anyhow::ensure!(options.wave_size >= 1, "--wave-size must be at least 1");
    let pixels = scene.render.width as u64 * scene.render.height as u64;
    let samples_per_wave = scene.render.spp.min(MAX_WAVE_SAMPLES_PER_PIXEL) as u64;
    let info = ctx.info();
    let device_max = (info.max_compute_workgroup_count[0] as u64 * WORKGROUP_SIZE as u64)
        .min(info.max_storage_buffer_range / WIDEST_PATH_ITEM);
    let capacity = (options.wave_size as u64)
        .min(pixels * samples_per_wave)
        .min(device_max);
    Ok(capacity.max(1) as u32)
}

impl<'c> Renderer<'c> {
    /// Packs `scene`, chooses the wave, allocates every buffer and builds
    /// the kernels.
    pub fn new(ctx: &'c Context, scene: &Scene, options: &RenderOptions) -> Result<Renderer<'c>> {
        let features = if options.all_features {
            Features::all(options.integrator)
        } else {
            Features::detect(scene, options.integrator)
        };
        let packed = GpuScene::pack(scene)?;
        let mut frame = packed.frame;
        frame.wave_capacity = wave_capacity(ctx, scene, options)?;
        if options.progressive {
            frame.strata = 0;
        }

        let table = buffer_table(&packed, &frame, options.schedule)?;
        let buffers = DeviceBuffers::allocate(ctx, &table, frame.max_depth).with_context(|| {
            format!(
                "the buffers of a {}x{} image with {} paths in flight do not fit the \
                     device; render a smaller image or lower --wave-size",
                frame.width, frame.height, frame.wave_capacity
            )
        })?;
        let bindings = ctx.create_bindings("wavefront", &buffers.bindings())?;

        // Specialise the kernels to the scene; the film sums in f64 where it can
        let film_fp64 = ctx.info().shader_float64 && !options.f32_film;
        let kernels = Kernels::build(ctx, &features, options.schedule, &bindings, film_fp64)?;

        let scene_info = SceneInfo {
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
            film_fp64,
            bindings,
            scene_info,
            push: GpuPush::default(),
            progress: Progress::default(),
        })
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

    /// Renders every sample of the image and reads the film back.
    pub fn render(&mut self, progress: bool) -> Result<RenderOutput> {
        self.restart()?;
        self.render_to(self.frame.spp, progress)?;
        self.output()
    }

    /// Empties the film and the figures: the next samples start a new image.
    pub fn restart(&mut self) -> Result<()> {
        self.clear_film()?;
        self.progress = Progress::default();
        Ok(())
    }

    /// Samples per pixel the film holds.
    pub fn spp_done(&self) -> u32 {
        self.progress.spp - self.progress.first
    }

    /// Empties the film and renders samples `first..end` of every pixel
    /// (a part of a render split across machines, see `crate::film`): the
    /// samples are the very ones a whole render draws, because random
    /// numbers depend only on (seed, pixel, sample, dimension) and the
    /// stratification on the scene's spp.
    pub fn render_samples(&mut self, first: u32, end: u32, progress: bool) -> Result<()> {
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
    /// f64: the radiance sums, the sums of squares, and the count of
    /// samples dropped for a NaN or infinite radiance.
    pub fn film_sums(&self) -> Result<(Vec<f64>, Vec<f64>, u64)> {
        let film: Vec<GpuFilmPixel> = self.ctx.read(self.buffers.get(BINDING_FILM))?;
        let film_sq: Vec<GpuFilmPixel> = self.ctx.read(self.buffers.get(BINDING_FILM_SQ))?;
        let nonfinite = self.ctx.read::<u32>(self.buffers.get(BINDING_COUNTERS))?
            [COUNTER_NONFINITE as usize] as u64;
        let flat = |f: &[GpuFilmPixel]| -> Vec<f64> {
            f.iter().flat_map(|p| p.total(self.film_fp64)).collect()
        };
        Ok((flat(&film), flat(&film_sq), nonfinite))
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
    pub fn spp_per_wave(&self) -> u32 {
        (self.frame.wave_capacity / self.frame.pixel_count).max(1)
    }

    /// Renders samples `spp_done()..spp` of every pixel into the film, which
    /// keeps what it holds: a progressive render calls this with a growing
    /// `spp` and reads [`Renderer::output`] in between. Random numbers depend
    /// only on (seed, pixel, sample, dimension), so the image does not depend
    /// on how the samples are split into calls.
    pub fn render_to(&mut self, spp: u32, progress: bool) -> Result<()> {
        let started = std::time::Instant::now();
        let pixels = self.frame.pixel_count as u64;
        let first = self.progress.spp as u64 * pixels;
        let end = spp as u64 * pixels;
        let capacity = self.frame.wave_capacity as u64;
        let waves = end.saturating_sub(first).div_ceil(capacity);
        let bar = progress_bar(
            progress,
            waves,
            "{spinner} rendering [{bar:30}] wave {pos}/{len} {elapsed_precise} eta {eta}",
        );
        for wave in 0..waves {
            crate::interrupt::check()?;
            let start = first + wave * capacity;
            let count = (end - start).min(capacity) as u32;
            let records = match self.schedule {
                Schedule::Wavefront => self.render_wave(start, count, self.progress.waves)?,
                Schedule::Megakernel => self.megakernel(start, count, self.progress.waves)?,
            };
            self.progress.records.extend(records);
            self.progress.waves += 1;
            bar.inc(1);
        }
        bar.finish_and_clear();
        self.progress.spp = self.progress.spp.max(spp);
        self.progress.seconds += started.elapsed().as_secs_f64();
        Ok(())
    }

    /// Renders one wave of `count` paths from path index `start`:
    /// `generate; for depth { intersect; shade; shadow }; accumulate`, in
    /// command buffers of at most [`BOUNCES_PER_SUBMIT`] bounces. Once no
    /// path is left, no further bounce is recorded, so a huge `max_depth`
    /// costs only the bounces that paths reach.
    fn render_wave(&mut self, start: u64, count: u32, wave: u32) -> Result<Vec<PassRecord>> {
        let max_dispatches = 2 + 3 * BOUNCES_PER_SUBMIT;
        let mut records = Vec::new();
        let mut rec = self.ctx.begin("wave", max_dispatches)?;

        self.generate(&mut rec, start, count);
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
            records.extend(self.wave_records(&timings, count, wave)?);
            if deepest {
                return Ok(records);
            }
            rec = self.ctx.begin("wave", max_dispatches)?;
            // Stop recording bounces once no path is left
            if self.queue_len(ray_queue_of(last))? == 0 {
                self.accumulate(&mut rec);
                let timings = self.ctx.submit(rec)?;
                records.extend(self.wave_records(&timings, count, wave)?);
                return Ok(records);
            }
            first = last;
        }
    }

    /// Renders one wave of `count` paths from path index `start` in one
    /// kernel: each thread takes a pixel and follows its paths of the wave
    /// from the camera to the film.
    fn megakernel(&mut self, start: u64, count: u32, wave: u32) -> Result<Vec<PassRecord>> {
        let mut rec = self.ctx.begin("wave", 1)?;
        self.push = wave_push(start, count, self.frame.pixel_count);
        let threads = count.min(self.frame.pixel_count);
        rec.barrier();
        self.dispatch(
            &mut rec,
            Pass::Megakernel,
            None,
            threads.div_ceil(WORKGROUP_SIZE),
        );
        let timings = self.ctx.submit(rec)?;
        self.wave_records(&timings, count, wave)
    }

    /// Items in queue `queue`, read back from the device.
    fn queue_len(&self, queue: u32) -> Result<u32> {
        let headers: Vec<GpuQueueHeader> =
            self.ctx.read(self.buffers.get(BINDING_QUEUE_HEADERS))?;
        Ok(headers[queue as usize].count)
    }

    /// Reads the film back: the image of every sample rendered since
    /// [`Renderer::restart`], and the figures of every wave.
    pub fn output(&self) -> Result<RenderOutput> {
        let (mean, var_of_mean) = self.resolve_film()?;
        let nonfinite = self.ctx.read::<u32>(self.buffers.get(BINDING_COUNTERS))?
            [COUNTER_NONFINITE as usize] as u64;
        let info = self.ctx.info();
        let stats = RenderStats {
            device: info.name.clone(),
            driver: info.driver_name.clone(),
            width: self.frame.width,
            height: self.frame.height,
            spp: self.spp_done(),
            max_depth: self.frame.max_depth,
            seed: self.frame.seed,
            integrator: self.integrator,
            wave_size: self.frame.wave_capacity,
            waves: self.progress.waves,
            records: self.progress.records.clone(),
            wall_seconds: self.progress.seconds,
            nonfinite_samples: nonfinite,
            timestamps_supported: info.timestamps_supported,
        };
        Ok(RenderOutput {
            width: self.frame.width,
            height: self.frame.height,
            spp: self.spp_done(),
            mean,
            var_of_mean,
            stats,
        })
    }

    /// Runs the intersect kernel alone on the given rays (origin, unit
    /// direction, tmax), for testing the BVH traversal on the device. A
    /// test hook, not part of the API.
    #[doc(hidden)]
    pub fn intersect_rays(
        &mut self,
        rays: &[(glam::Vec3, glam::Vec3, f32)],
    ) -> Result<Vec<Option<KernelHit>>> {
        anyhow::ensure!(
            self.schedule == Schedule::Wavefront,
            "intersect_rays needs the wavefront's buffers"
        );
        anyhow::ensure!(
            rays.len() <= self.frame.wave_capacity as usize,
            "more rays than the wave holds"
        );
        let origins: Vec<glam::Vec4> = rays.iter().map(|r| r.0.extend(r.2)).collect();
        let dirs: Vec<glam::Vec4> = rays.iter().map(|r| r.1.extend(0.0)).collect();
        let slots: Vec<u32> = (0..rays.len() as u32).collect();
        self.ctx
            .write(self.buffers.get(BINDING_RAY_ORIGIN), 0, &origins)?;
        self.ctx
            .write(self.buffers.get(BINDING_RAY_DIR), 0, &dirs)?;
        self.ctx
            .write(self.buffers.get(BINDING_RAY_QUEUES), 0, &slots)?;
        let mut rec = self.ctx.begin("intersect_rays", 1)?;
        let header = GpuQueueHeader::with_count(rays.len() as u32);
        rec.update_buffer(
            self.buffers.get(BINDING_QUEUE_HEADERS),
            0,
            bytes_of(&header),
        );
        rec.barrier();
        self.intersect(&mut rec, 0);
        self.ctx.submit(rec)?;
        let hits: Vec<GpuHit> = self.ctx.read(self.buffers.get(BINDING_HITS))?;
        Ok(hits[..rays.len()]
            .iter()
            .map(|h| {
                (h.prim != NO_HIT).then(|| KernelHit {
                    prim: self.prim_order[h.prim as usize],
                    t: h.t,
                })
            })
            .collect())
    }

    /// Zeroes the film and the counters before the first wave.
    fn clear_film(&self) -> Result<()> {
        let mut rec = self.ctx.begin("clear_film", 0)?;
        for binding in [BINDING_FILM, BINDING_FILM_SQ, BINDING_COUNTERS] {
            let buf = self.buffers.get(binding);
            rec.fill_buffer(buf, 0, buf.size(), 0);
        }
        self.ctx.submit(rec)?;
        Ok(())
    }

    /// Records the generate pass: camera rays for `count` paths from `start`.
    fn generate(&mut self, rec: &mut Recorder, start: u64, count: u32) {
        self.push = wave_push(start, count, self.frame.pixel_count);
        // Every camera ray is on queue 0; the other queues start empty
        let headers = [
            GpuQueueHeader::with_count(count),
            GpuQueueHeader::with_count(0),
            GpuQueueHeader::with_count(0),
        ];
        rec.update_buffer(
            self.buffers.get(BINDING_QUEUE_HEADERS),
            0,
            bytemuck::cast_slice(&headers),
        );
        rec.barrier();
        self.dispatch(rec, Pass::Generate, None, count.div_ceil(WORKGROUP_SIZE));
    }

    /// Records the intersect pass over the current ray queue.
    fn intersect(&mut self, rec: &mut Recorder, bounce: u32) {
        self.push.bounce = bounce;
        let queue = ray_queue_of(bounce);
        rec.barrier();
        self.count_rays(rec, bounce, queue, 0);
        self.dispatch_queue(rec, Pass::Intersect, bounce, queue);
    }

    /// Records the shade pass: current queue in, next queue and shadow queue out.
    fn shade(&mut self, rec: &mut Recorder, bounce: u32) {
        // Empty the queues this pass fills, once intersect has read the headers
        let empty = GpuQueueHeader::with_count(0);
        let headers = self.buffers.get(BINDING_QUEUE_HEADERS);
        rec.barrier();
        for queue in [ray_queue_of(bounce + 1), SHADOW_QUEUE] {
            rec.update_buffer(headers, header_offset(queue), bytes_of(&empty));
        }
        rec.barrier();
        self.dispatch_queue(rec, Pass::Shade, bounce, ray_queue_of(bounce));
    }

    /// Records the shadow pass over the shadow queue.
    fn shadow(&mut self, rec: &mut Recorder, bounce: u32) {
        rec.barrier();
        self.count_rays(rec, bounce, SHADOW_QUEUE, 1);
        self.dispatch_queue(rec, Pass::Shadow, bounce, SHADOW_QUEUE);
    }

    /// Records the accumulate pass: finished radiance into the film.
    fn accumulate(&mut self, rec: &mut Recorder) {
        rec.barrier();
        let threads = self.push.path_count.min(self.frame.pixel_count);
        self.dispatch(
            rec,
            Pass::Accumulate,
            None,
            threads.div_ceil(WORKGROUP_SIZE),
        );
    }

    /// Dispatches `pass`'s kernel over `groups` workgroups, labelled by the pass.
    fn dispatch(&self, rec: &mut Recorder, pass: Pass, bounce: Option<u32>, groups: u32) {
        if let Some(kernel) = self.kernels.get(pass) {
            let push = bytes_of(&self.push);
            rec.dispatch(
                pass.name(),
                bounce,
                kernel,
                &self.bindings,
                push,
                [groups, 1, 1],
            );
        }
    }

    /// Dispatches `pass`'s kernel indirectly over the items of queue `queue`.
    fn dispatch_queue(&self, rec: &mut Recorder, pass: Pass, bounce: u32, queue: u32) {
        if let Some(kernel) = self.kernels.get(pass) {
            rec.dispatch_indirect(
                pass.name(),
                Some(bounce),
                kernel,
                &self.bindings,
                bytes_of(&self.push),
                self.buffers.get(BINDING_QUEUE_HEADERS),
                header_offset(queue),
            );
        }
    }

    /// Copies a queue's item count into the ray counts of the bounces of
    /// the current command buffer.
    fn count_rays(&self, rec: &mut Recorder, bounce: u32, queue: u32, column: u64) {
        let bounce = bounce % BOUNCES_PER_SUBMIT;
        let count_offset =
            header_offset(queue) + std::mem::offset_of!(GpuQueueHeader, count) as u64;
        rec.copy_buffer(
            self.buffers.get(BINDING_QUEUE_HEADERS),
            count_offset,
            &self.buffers.ray_counts,
            (bounce as u64 * 2 + column) * 4,
            4,
        );
    }

    /// Turns the timings and ray counts of one command buffer of a wave into
    /// pass records.
    fn wave_records(
        &self,
        timings: &crate::vk::Timings,
        paths: u32,
        wave: u32,
    ) -> Result<Vec<PassRecord>> {
        let counts: Vec<u32> = self.ctx.read(&self.buffers.ray_counts)?;
        timings
            .dispatches
            .iter()
            .map(|d| {
                let pass = Pass::from_label(d.label)
                    .with_context(|| format!("a dispatch labelled {:?} is no pass", d.label))?;
                let rays = match (pass, d.bounce) {
                    (Pass::Intersect | Pass::Shade, Some(b)) => {
                        counts[(b % BOUNCES_PER_SUBMIT) as usize * 2] as u64
                    }
                    (Pass::Shadow, Some(b)) => {
                        counts[(b % BOUNCES_PER_SUBMIT) as usize * 2 + 1] as u64
                    }
                    _ => paths as u64,
                };
                Ok(PassRecord {
                    pass,
                    bounce: d.bounce,
                    gpu_ns: d.gpu_ns,
                    rays,
                    start_ns: d.start_ns,
                    wave,
                })
            })
            .collect()
    }

    /// Reads the film and turns sums into means and variances of the mean.
    fn resolve_film(&self) -> Result<(Vec<f32>, Vec<f32>)> {
        let (sum, sum_sq, _) = self.film_sums()?;
        Ok(crate::film::resolve(&sum, &sum_sq, self.spp_done()))
    }
}

/// The push constants of a wave of `count` paths from path index `start`
/// of an image of `pixels` pixels, at bounce 0.
fn wave_push(start: u64, count: u32, pixels: u32) -> GpuPush {
    GpuPush {
        sample_base: (start / pixels as u64) as u32,
        pixel_base: (start % pixels as u64) as u32,
        path_count: count,
        bounce: 0,
    }
}

/// The ray queue that bounce `bounce` reads (`ray_queue_of` in GLSL); the
/// shade pass of that bounce fills the next one.
fn ray_queue_of(bounce: u32) -> u32 {
    bounce % RAY_QUEUE_COUNT
}

/// Byte offset of queue header `queue`.
fn header_offset(queue: u32) -> u64 {
    queue as u64 * std::mem::size_of::<GpuQueueHeader>() as u64
}

/// A progress bar of `steps` on stderr drawn with `template` (indicatif's
/// syntax), hidden when not wanted. Rendering and `lancer bench` share it.
pub(crate) fn progress_bar(show: bool, steps: u64, template: &str) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(steps),
        indicatif::ProgressDrawTarget::stderr(),
    );
    if let Ok(style) = indicatif::ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}
