//! The wavefront renderer: device buffers sized by the wave, five kernels,
//! and the render loop.
//!
//! Per wave of paths, one command buffer holds
//! `generate -> { intersect -> shade -> shadow } x depth -> accumulate`,
//! with every pass after generate dispatched indirectly from the queue
//! counters the previous pass wrote. Nothing is read back between bounces.

use anyhow::Result;
use bytemuck::{bytes_of, Zeroable};

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::ops::Range;

use anyhow::Context as _;
use glam::Vec4;

use crate::features::{Features, Integrator};
use crate::gpu::{GpuFilmPixel, GpuFrame, GpuHit, GpuPush, GpuQueueHeader, GpuScene};
use crate::pass::Pass;
use crate::scene::Scene;
use crate::shader_interface::*;
use crate::stats::{PassRecord, RenderStats};
use crate::tiles::{bands, rows_per_tile, Tile, Wave};
use crate::vk::{
    BindingKind, Bindings, Buffer, ComputePipeline, Context, MemoryKind, Recorder, VkError,
};

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
    /// Most rows of the image whose film the device holds at once; `None`:
    /// as many as one storage binding holds. The image does not depend on
    /// it, bit for bit; lowering it lowers device memory.
    pub tile_rows: Option<u32>,
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
            tile_rows: None,
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
/// the film by the band of `film_pixels` pixels it holds at once.
fn buffer_table<'a>(
    packed: &'a GpuScene,
    frame: &'a GpuFrame,
    schedule: Schedule,
    film_pixels: u64,
) -> Result<Vec<BufferRow<'a>>> {
    let wave = match schedule {
        Schedule::Wavefront => frame.wave_capacity as u64,
        Schedule::Megakernel => 1,
    };
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
        sized::<GpuFilmPixel>(BINDING_FILM, "accumulate.film", film_pixels)?,
        sized::<GpuFilmPixel>(BINDING_FILM_SQ, "accumulate.film_sq", film_pixels)?,
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

/// What to change when buffer `label` of [`buffer_table`] does not fit the
/// device (one binding's limit, or the memory budget), by what the buffer
/// grows with: the scene, the image or the wave.
fn what_to_change(label: &str, frame: &GpuFrame) -> String {
    if label.starts_with("scene.texels") {
        "the scene's textures do not fit this device: use smaller texture images".to_string()
    } else if label.starts_with("scene.") {
        format!(
            "the scene's geometry ({label}) does not fit this device: use fewer triangles or \
             spheres"
        )
    } else if label.starts_with("accumulate.film") {
        format!(
            "the film of a {}x{} image does not fit this device: render a smaller image \
             (--width, --height)",
            frame.width, frame.height
        )
    } else {
        format!(
            "the state of {} paths in flight ({label}) does not fit this device: lower \
             --wave-size",
            frame.wave_capacity
        )
    }
}

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
    fn allocate(ctx: &Context, table: &[BufferRow<'_>], frame: &GpuFrame) -> Result<DeviceBuffers> {
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
            .map_err(|e| {
                let what = if e.is_out_of_memory() || matches!(e, VkError::BufferTooLarge { .. }) {
                    what_to_change(row.label, frame)
                } else {
                    format!("allocating {}", row.label)
                };
                anyhow::Error::new(e).context(what)
            })?;
            slots[row.binding as usize] = Some(buffer);
        }
        if let Some(b) = taken.iter().position(|t| !t) {
            anyhow::bail!("binding {b} has no buffer");
        }
        let ray_counts = ctx.create_buffer(
            "stats.ray_counts",
            (frame.max_depth.min(BOUNCES_PER_SUBMIT) as u64 * 2 * 4).max(16),
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
    /// The bands of rows the film is rendered in, top to bottom.
    tiles: Vec<Tile>,
    /// The whole film, when the device holds one band of several at a time.
    host_film: Option<HostFilm>,
    /// What the film holds so far.
    progress: Progress,
    /// What packing the scene changed that the user should know of.
    warnings: Vec<String>,
    /// The material test kernel, built on first use by a test hook.
    test_bsdf: Option<ComputePipeline>,
}

/// The film of every band on the host, between the band's visits to the
/// device: the very bits of the device's film buffers, so that a band
/// continues where it stopped, as if it had stayed on the device.
struct HostFilm {
    /// Radiance sums, per pixel of the image.
    sum: Vec<GpuFilmPixel>,
    /// Sums of squared radiance, per pixel of the image.
    sum_sq: Vec<GpuFilmPixel>,
}

impl HostFilm {
    /// An empty film of `pixels` pixels, or a message with the bytes it
    /// needs when the host cannot hold it.
    fn new(pixels: usize, width: u32, height: u32) -> Result<HostFilm> {
        let zeroed = || -> Result<Vec<GpuFilmPixel>> {
            let mut v = Vec::new();
            v.try_reserve_exact(pixels).with_context(|| {
                format!(
                    "the film of a {width}x{height} image needs {} bytes of host memory \
                     ({} per pixel), which could not be allocated; render a smaller image",
                    2 * pixels as u64 * std::mem::size_of::<GpuFilmPixel>() as u64,
                    2 * std::mem::size_of::<GpuFilmPixel>()
                )
            })?;
            v.resize(pixels, GpuFilmPixel::zeroed());
            Ok(v)
        };
        Ok(HostFilm {
            sum: zeroed()?,
            sum_sq: zeroed()?,
        })
    }

    /// Empties the film.
    fn clear(&mut self) {
        for v in [&mut self.sum, &mut self.sum_sq] {
            v.fill(GpuFilmPixel::zeroed());
        }
    }
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

/// One probe for [`Renderer::probe_rays`]: a ray (origin, unit direction,
/// tmax) to a surface point A, the unit direction a new ray leaves A by, and
/// a ray to a second surface point B. A test hook, not part of the API.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// The ray that finds A.
    pub to_a: (glam::Vec3, glam::Vec3, f32),
    /// The direction the spawned ray leaves A by.
    pub leave: glam::Vec3,
    /// The ray that finds B.
    pub to_b: (glam::Vec3, glam::Vec3, f32),
}

/// What the probe kernel found for one [`Probe`]. A test hook, not part of
/// the API.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeResult {
    /// A's primitive in scene order, if the first ray hit anything.
    pub a: Option<u32>,
    /// B's primitive in scene order, if A was found and the second ray hit.
    pub b: Option<u32>,
    /// Distance at which the ray spawned from A hit A again, if it did.
    pub self_hit: Option<f32>,
    /// The shadow segment from A to B (B another primitive) hit A or B.
    pub shadow_blocked: bool,
    /// Interior nodes and primitives the trace that found A visited.
    pub visits: u32,
    /// A's position as the kernel rebuilt it (zero when none).
    pub pa: glam::Vec3,
    /// B's position as the kernel rebuilt it (zero when none).
    pub pb: glam::Vec3,
}

/// What the material test kernel (`shaders/test_bsdf.comp`) gives for one
/// direction: `bsdf_eval`'s figures. A test hook for
/// [`Renderer::eval_bsdf`], not part of the API.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KernelBsdfEval {
    /// f * cos(n, wi), per channel.
    pub f_cos: glam::Vec3,
    /// Solid-angle pdf of sampling the direction.
    pub pdf: f32,
}

/// What the material test kernel gives for one sample: `bsdf_sample`'s
/// figures, and `bsdf_eval`'s at the sampled direction. A test hook for
/// [`Renderer::sample_bsdf`], not part of the API.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KernelBsdfSample {
    /// `bsdf_sample` returned true: the path would go on.
    pub ok: bool,
    /// The direction came from a delta lobe.
    pub delta: bool,
    /// The sampled direction.
    pub wi: glam::Vec3,
    /// The pdf `bsdf_sample` gave (0 for a delta lobe).
    pub pdf: f32,
    /// The sample weight f * cos / pdf, per channel.
    pub weight: glam::Vec3,
    /// `bsdf_eval` at the sampled direction.
    pub eval: KernelBsdfEval,
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

/// The environment variable that lowers the bytes the texture binding may
/// hold below the device's `maxStorageBufferRange`, so that tests can
/// shrink small textures as the device shrinks large ones.
pub const MAX_TEXTURE_BYTES_ENV: &str = "LANCER_MAX_TEXTURE_BYTES";

/// Bytes the one binding that holds every texel may take: the device's
/// `maxStorageBufferRange`, or less where [`MAX_TEXTURE_BYTES_ENV`] says.
fn max_texture_bytes(ctx: &Context) -> Result<u64> {
    let device = ctx.max_storage_buffer_range();
    let Some(text) = std::env::var_os(MAX_TEXTURE_BYTES_ENV) else {
        return Ok(device);
    };
    let text = text.to_string_lossy();
    match text.trim().parse::<u64>() {
        Ok(bytes) if bytes > 0 => Ok(bytes.min(device)),
        _ => anyhow::bail!(
            "{MAX_TEXTURE_BYTES_ENV}={:?} is not a number of bytes above 0; unset it to use \
             the device's limit of {device} bytes",
            crate::scene::cut(&text)
        ),
    }
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
        let packed = GpuScene::pack(scene, max_texture_bytes(ctx)?)?;
        let mut frame = packed.frame;
        frame.wave_capacity = wave_capacity(ctx, scene, options)?;
        if options.progressive {
            frame.strata = 0;
        }

        // Split the film into bands of rows that fit one binding
        let film_limit =
            ctx.info().max_storage_buffer_range / std::mem::size_of::<GpuFilmPixel>() as u64;
        let rows = rows_per_tile(frame.width, frame.height, film_limit, options.tile_rows);
        let tiles = bands(frame.width, frame.height, rows);
        let host_film = if tiles.len() > 1 {
            Some(HostFilm::new(
                frame.pixel_count as usize,
                frame.width,
                frame.height,
            )?)
        } else {
            None
        };

        let film_pixels = u64::from(rows) * u64::from(frame.width);
        let table = buffer_table(&packed, &frame, options.schedule, film_pixels)?;
        let buffers = DeviceBuffers::allocate(ctx, &table, &frame)?;
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
            tiles,
            host_film,
            film_fp64,
            bindings,
            scene_info,
            push: GpuPush::default(),
            progress: Progress::default(),
            test_bsdf: None,
            warnings: packed.textures.warnings,
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

    /// Rows of the tallest band: the film the device holds at once is
    /// this many rows of the image.
    pub fn tile_rows(&self) -> u32 {
        self.tiles.iter().map(|t| t.rows).max().unwrap_or(0)
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
        let (film, film_sq) = self.film()?;
        let nonfinite = self.ctx.read::<u32>(self.buffers.get(BINDING_COUNTERS))?
            [COUNTER_NONFINITE as usize] as u64;
        Ok((self.totals(&film), self.totals(&film_sq), nonfinite))
    }

    /// The film of every pixel: from the host when it holds the bands,
    /// else read from the device.
    #[allow(clippy::type_complexity)]
    fn film(&self) -> Result<(Cow<'_, [GpuFilmPixel]>, Cow<'_, [GpuFilmPixel]>)> {
        if let Some(host) = &self.host_film {
            return Ok((Cow::Borrowed(&host.sum), Cow::Borrowed(&host.sum_sq)));
        }
        let pixels = self.frame.pixel_count as usize;
        let read = |binding| -> Result<Cow<'_, [GpuFilmPixel]>> {
            let mut film: Vec<GpuFilmPixel> = self.ctx.read(self.buffers.get(binding))?;
            film.truncate(pixels);
            Ok(Cow::Owned(film))
        };
        Ok((read(BINDING_FILM)?, read(BINDING_FILM_SQ)?))
    }

    /// Film pixels as f64 totals, RGB interleaved.
    fn totals(&self, film: &[GpuFilmPixel]) -> Vec<f64> {
        film.iter().flat_map(|p| p.total(self.film_fp64)).collect()
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
    /// chunks a pixel's samples alike (see `crate::tiles`).
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
        let samples = self.progress.spp..spp.max(self.progress.spp);
        let waves: usize = self
            .tiles
            .iter()
            .map(|&tile| self.waves_of(tile, samples.clone()).count())
            .sum();
        let bar = progress_bar(
            progress,
            waves as u64,
            "{spinner} rendering [{bar:30}] wave {pos}/{len} {elapsed_precise} eta {eta}",
        );
        if !samples.is_empty() {
            for tile in self.tiles.clone() {
                self.render_tile(tile, samples.clone(), &bar)?;
            }
        }
        bar.finish_and_clear();
        self.progress.spp = samples.end;
        self.progress.seconds += started.elapsed().as_secs_f64();
        Ok(())
    }

    /// The waves that render `samples` of every pixel of `tile`.
    fn waves_of(&self, tile: Tile, samples: Range<u32>) -> impl Iterator<Item = Wave> {
        crate::tiles::waves(tile, samples, self.spp_per_wave(), self.frame.wave_capacity)
    }

    /// Renders `samples` of every pixel of `tile`: its film onto the device,
    /// its waves, its film back.
    fn render_tile(
        &mut self,
        tile: Tile,
        samples: Range<u32>,
        bar: &indicatif::ProgressBar,
    ) -> Result<()> {
        self.load_tile(tile)?;
        for wave in self.waves_of(tile, samples).collect::<Vec<_>>() {
            crate::interrupt::check()?;
            let index = self.progress.waves;
            let records = match self.schedule {
                Schedule::Wavefront => self.render_wave(tile, wave, index)?,
                Schedule::Megakernel => self.megakernel(tile, wave, index)?,
            };
            self.progress.records.extend(records);
            self.progress.waves += 1;
            bar.inc(1);
        }
        self.store_tile(tile)
    }

    /// Puts the film of `tile` on the device, when the host holds the bands.
    fn load_tile(&self, tile: Tile) -> Result<()> {
        let Some(host) = &self.host_film else {
            return Ok(());
        };
        for (binding, film) in [(BINDING_FILM, &host.sum), (BINDING_FILM_SQ, &host.sum_sq)] {
            self.ctx
                .write(self.buffers.get(binding), 0, &film[tile.pixel_range()])
                .with_context(|| format!("loading the film of rows {}..", tile.first_row))?;
        }
        Ok(())
    }

    /// Keeps the film of `tile` on the host, when the host holds the bands.
    fn store_tile(&mut self, tile: Tile) -> Result<()> {
        let Some(host) = &mut self.host_film else {
            return Ok(());
        };
        for (binding, film) in [
            (BINDING_FILM, &mut host.sum),
            (BINDING_FILM_SQ, &mut host.sum_sq),
        ] {
            let band: Vec<GpuFilmPixel> = self
                .ctx
                .read(self.buffers.get(binding))
                .with_context(|| format!("reading the film of rows {}..", tile.first_row))?;
            film[tile.pixel_range()].copy_from_slice(&band[..tile.pixels as usize]);
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

    /// Renders one wave of `tile` in one kernel: each thread takes a pixel
    /// and follows its paths of the wave from the camera to the film.
    fn megakernel(&mut self, tile: Tile, wave: Wave, index: u32) -> Result<Vec<PassRecord>> {
        let mut rec = self.ctx.begin("wave", 1)?;
        self.push = wave_push(tile, wave);
        rec.barrier();
        self.dispatch(
            &mut rec,
            Pass::Megakernel,
            None,
            wave.pixels.div_ceil(WORKGROUP_SIZE),
        );
        let timings = self.ctx.submit(rec)?;
        self.wave_records(&timings, wave.paths(), index)
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
        let origins: Vec<Vec4> = rays.iter().map(|r| r.0.extend(r.2)).collect();
        let dirs: Vec<Vec4> = rays.iter().map(|r| r.1.extend(0.0)).collect();
        let mut rec = self.begin_test_queue("intersect_rays", &origins, &dirs)?;
        self.intersect(&mut rec, 0);
        self.ctx.submit(rec)?;
        let hits: Vec<GpuHit> = self.ctx.read(self.buffers.get(BINDING_HITS))?;
        Ok(hits[..rays.len()]
            .iter()
            .map(|h| self.kernel_hit(h.prim, h.t))
            .collect())
    }

    /// Runs the probe kernel (`shaders/probe.comp`) on the given probes:
    /// each finds a surface point A, leaves it as the shade kernel would,
    /// and tests shade's shadow segment from A to a second surface point B.
    /// A test hook, not part of the API.
    #[doc(hidden)]
    pub fn probe_rays(&mut self, probes: &[Probe]) -> Result<Vec<ProbeResult>> {
        let origins: Vec<Vec4> = probes.iter().map(|p| p.to_a.0.extend(p.to_a.2)).collect();
        let dirs: Vec<Vec4> = probes.iter().map(|p| p.to_a.1.extend(0.0)).collect();
        let leave: Vec<Vec4> = probes.iter().map(|p| p.leave.extend(0.0)).collect();
        let b_origins: Vec<Vec4> = probes.iter().map(|p| p.to_b.0.extend(p.to_b.2)).collect();
        let b_dirs: Vec<Vec4> = probes.iter().map(|p| p.to_b.1.extend(0.0)).collect();
        for (binding, data) in [
            (BINDING_THROUGHPUT, &leave),
            (BINDING_SHADOW_ORIGIN, &b_origins),
            (BINDING_SHADOW_DIR, &b_dirs),
        ] {
            self.ctx.write(self.buffers.get(binding), 0, data)?;
        }
        let spec = self.features.spec_constants(Pass::Intersect);
        let push = std::mem::size_of::<GpuPush>() as u32;
        let kernel = self
            .ctx
            .create_pipeline("probe", crate::shaders::PROBE, &self.bindings, &spec, push)
            .context("building the probe kernel")?;
        let mut rec = self.begin_test_queue("probe_rays", &origins, &dirs)?;
        self.push.bounce = 0;
        rec.dispatch_indirect(
            "probe",
            Some(0),
            &kernel,
            &self.bindings,
            bytes_of(&self.push),
            self.buffers.get(BINDING_QUEUE_HEADERS),
            header_offset(ray_queue_of(0)),
        );
        self.ctx.submit(rec)?;
        let hits: Vec<GpuHit> = self.ctx.read(self.buffers.get(BINDING_HITS))?;
        let info: Vec<[u32; 4]> = self.ctx.read(self.buffers.get(BINDING_RADIANCE))?;
        let pa: Vec<Vec4> = self.ctx.read(self.buffers.get(BINDING_THROUGHPUT))?;
        let pb: Vec<Vec4> = self.ctx.read(self.buffers.get(BINDING_SHADOW_ORIGIN))?;
        Ok((0..probes.len())
            .map(|i| ProbeResult {
                a: self.kernel_hit(info[i][0], 0.0).map(|h| h.prim),
                b: self.kernel_hit(info[i][1], 0.0).map(|h| h.prim),
                self_hit: self.kernel_hit(hits[i].prim, hits[i].t).map(|h| h.t),
                shadow_blocked: info[i][2] & 2 != 0,
                visits: info[i][3],
                pa: pa[i].truncate(),
                pb: pb[i].truncate(),
            })
            .collect())
    }

    /// Uploads test rays (origin and tmax, direction) into the path slots
    /// of ray queue 0 and begins a command buffer whose queue header holds
    /// their count, for a test hook's kernel to run on.
    fn begin_test_queue(
        &self,
        label: &'static str,
        origins: &[Vec4],
        dirs: &[Vec4],
    ) -> Result<Recorder<'c>> {
        anyhow::ensure!(
            self.schedule == Schedule::Wavefront,
            "{label} needs the wavefront's buffers"
        );
        anyhow::ensure!(
            origins.len() <= self.frame.wave_capacity as usize,
            "more rays than the wave holds"
        );
        let slots: Vec<u32> = (0..origins.len() as u32).collect();
        self.ctx
            .write(self.buffers.get(BINDING_RAY_ORIGIN), 0, origins)?;
        self.ctx.write(self.buffers.get(BINDING_RAY_DIR), 0, dirs)?;
        self.ctx
            .write(self.buffers.get(BINDING_RAY_QUEUES), 0, &slots)?;
        let mut rec = self.ctx.begin(label, 1)?;
        let header = GpuQueueHeader::with_count(origins.len() as u32);
        rec.update_buffer(
            self.buffers.get(BINDING_QUEUE_HEADERS),
            0,
            bytes_of(&header),
        );
        rec.barrier();
        Ok(rec)
    }

    /// A kernel's hit on leaf slot `prim` (or none) in scene order.
    fn kernel_hit(&self, prim: u32, t: f32) -> Option<KernelHit> {
        (prim != NO_HIT).then(|| KernelHit {
            prim: self.prim_order[prim as usize],
            t,
        })
    }

    /// Samples material `material` (scene order) once per triple of
    /// random numbers in `u`, for light leaving along `wo` on the front
    /// (`front`) or back side of a surface at the origin whose normals are
    /// +z, with the shade kernel's `bsdf_sample`, and evaluates
    /// `bsdf_eval` at each sampled direction. A test hook, not part of the API.
    #[doc(hidden)]
    pub fn sample_bsdf(
        &mut self,
        material: u32,
        wo: glam::Vec3,
        front: bool,
        u: &[glam::Vec3],
    ) -> Result<Vec<KernelBsdfSample>> {
        let flags = if front { TEST_BSDF_FRONT } else { 0 };
        let out = self.run_test_bsdf(material, wo, flags, u)?;
        Ok(out
            .into_iter()
            .map(|[wi, weight, eval]| {
                let result = weight.w.to_bits();
                KernelBsdfSample {
                    ok: result & TEST_BSDF_OK != 0,
                    delta: result & TEST_BSDF_DELTA != 0,
                    wi: wi.truncate(),
                    pdf: wi.w,
                    weight: weight.truncate(),
                    eval: KernelBsdfEval {
                        f_cos: eval.truncate(),
                        pdf: eval.w,
                    },
                }
            })
            .collect())
    }

    /// Evaluates material `material` (scene order) with the shade kernel's
    /// `bsdf_eval` at each direction of `wi`, on the surface of
    /// [`Renderer::sample_bsdf`]. A test hook, not part of the API.
    #[doc(hidden)]
    pub fn eval_bsdf(
        &mut self,
        material: u32,
        wo: glam::Vec3,
        front: bool,
        wi: &[glam::Vec3],
    ) -> Result<Vec<KernelBsdfEval>> {
        let flags = TEST_BSDF_EVALUATE | if front { TEST_BSDF_FRONT } else { 0 };
        let out = self.run_test_bsdf(material, wo, flags, wi)?;
        Ok(out
            .into_iter()
            .map(|[_, _, eval]| KernelBsdfEval {
                f_cos: eval.truncate(),
                pdf: eval.w,
            })
            .collect())
    }

    /// Runs the material test kernel on one item per input, a wave at a
    /// time, and returns each item's three outputs (see
    /// `shaders/test_bsdf.comp`).
    fn run_test_bsdf(
        &mut self,
        material: u32,
        wo: glam::Vec3,
        flags: u32,
        inputs: &[glam::Vec3],
    ) -> Result<Vec<[Vec4; 3]>> {
        anyhow::ensure!(
            self.schedule == Schedule::Wavefront,
            "the material test kernel needs the wavefront's buffers"
        );
        let materials = self.buffers.get(BINDING_MATERIALS).size()
            / std::mem::size_of::<crate::gpu::GpuMaterial>() as u64;
        anyhow::ensure!(
            (material as u64) < materials,
            "material {material} is not in the scene, which has {materials}"
        );
        if self.test_bsdf.is_none() {
            let spec = self.features.spec_constants(Pass::Shade);
            let push_bytes = std::mem::size_of::<GpuPush>() as u32;
            let kernel = self
                .ctx
                .create_pipeline(
                    "test_bsdf",
                    crate::shaders::TEST_BSDF,
                    &self.bindings,
                    &spec,
                    push_bytes,
                )
                .context("building the material test kernel")?;
            self.test_bsdf = Some(kernel);
        }
        let kernel = self
            .test_bsdf
            .as_ref()
            .expect("the material test kernel was built above");
        let dir = wo.extend(f32::from_bits(flags));
        let mut out = Vec::with_capacity(inputs.len());
        for chunk in inputs.chunks(self.frame.wave_capacity as usize) {
            let a: Vec<Vec4> = chunk
                .iter()
                .map(|x| x.extend(f32::from_bits(material)))
                .collect();
            self.ctx
                .write(self.buffers.get(BINDING_RAY_ORIGIN), 0, &a)?;
            self.ctx.write(
                self.buffers.get(BINDING_RAY_DIR),
                0,
                &vec![dir; chunk.len()],
            )?;
            let push = GpuPush {
                path_count: chunk.len() as u32,
                ..GpuPush::default()
            };
            let mut rec = self.ctx.begin("test_bsdf", 1)?;
            rec.dispatch(
                "test_bsdf",
                None,
                kernel,
                &self.bindings,
                bytes_of(&push),
                [(chunk.len() as u32).div_ceil(WORKGROUP_SIZE), 1, 1],
            );
            self.ctx.submit(rec)?;
            let read =
                |binding| -> Result<Vec<Vec4>> { Ok(self.ctx.read(self.buffers.get(binding))?) };
            let (wi, weight, eval) = (
                read(BINDING_SHADOW_ORIGIN)?,
                read(BINDING_SHADOW_DIR)?,
                read(BINDING_SHADOW_RADIANCE)?,
            );
            out.extend((0..chunk.len()).map(|i| [wi[i], weight[i], eval[i]]));
        }
        Ok(out)
    }

    /// Zeroes the film and the counters before the first wave.
    fn clear_film(&mut self) -> Result<()> {
        let mut rec = self.ctx.begin("clear_film", 0)?;
        for binding in [BINDING_FILM, BINDING_FILM_SQ, BINDING_COUNTERS] {
            let buf = self.buffers.get(binding);
            rec.fill_buffer(buf, 0, buf.size(), 0);
        }
        self.ctx.submit(rec)?;
        if let Some(host) = &mut self.host_film {
            host.clear();
        }
        Ok(())
    }

    /// Records the generate pass: the camera rays of `wave`.
    fn generate(&mut self, rec: &mut Recorder, tile: Tile, wave: Wave) {
        self.push = wave_push(tile, wave);
        let count = wave.paths();
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
        let threads = self.push.wave_pixels;
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

    /// Reads the film and turns sums into means and variances of the mean,
    /// a band at a time so that the f64 totals of a large image are never
    /// all held at once.
    fn resolve_film(&self) -> Result<(Vec<f32>, Vec<f32>)> {
        let (film, film_sq) = self.film()?;
        let band = self.tile_rows().max(1) as usize * self.frame.width as usize;
        let mut mean = Vec::with_capacity(3 * film.len());
        let mut var_of_mean = Vec::with_capacity(3 * film.len());
        for (sum, sum_sq) in film.chunks(band).zip(film_sq.chunks(band)) {
            let (m, v) =
                crate::film::resolve(&self.totals(sum), &self.totals(sum_sq), self.spp_done());
            mean.extend(m);
            var_of_mean.extend(v);
        }
        Ok((mean, var_of_mean))
    }
}

/// The push constants of `wave` of `tile`, at bounce 0.
fn wave_push(tile: Tile, wave: Wave) -> GpuPush {
    GpuPush {
        sample_base: wave.sample_base,
        pixel_base: wave.pixel_base,
        path_count: wave.paths(),
        bounce: 0,
        wave_pixels: wave.pixels,
        film_base: tile.first_pixel,
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
