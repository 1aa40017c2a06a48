//! The wavefront renderer: device buffers sized by the wave, five kernels,
//! and the render loop.
//!
//! Per wave of paths, one command buffer holds
//! `generate -> { intersect -> shade -> shadow } x depth -> accumulate`,
//! with every pass after generate dispatched indirectly from the queue
//! counters the previous pass wrote. Nothing is read back between bounces.

use anyhow::{Context as _, Result};
use bytemuck::bytes_of;

use crate::features::{Features, Integrator};
use crate::gpu::{GpuFilmPixel, GpuFrame, GpuPush, GpuQueueHeader, GpuScene};
use crate::scene::Scene;
use crate::shader_interface::*;
use crate::shaders;
use crate::stats::{PassRecord, RenderStats};
use crate::vk::{Bindings, Buffer, ComputePipeline, Context, MemoryKind, Recorder};

/// How to render, beyond what the scene file says.
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// Paths in flight per wave.
    pub wave_size: u32,
    /// The estimator.
    pub integrator: Integrator,
    /// Turn every feature on, whatever the scene calls for.
    pub all_features: bool,
    /// Sum the film in compensated f32 even where the device has f64.
    pub f32_film: bool,
    /// Run shade as one dispatch per material type present, each kernel
    /// specialised to that type, instead of one kernel for all of them.
    pub shade_per_material: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            wave_size: DEFAULT_WAVE_SIZE,
            integrator: Integrator::Nee,
            all_features: false,
            f32_film: false,
            shade_per_material: false,
        }
    }
}

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

/// The five kernels, specialised to the scene's features.
struct Kernels {
    generate: ComputePipeline,
    intersect: ComputePipeline,
    /// One shade kernel for every material, or one per material type.
    shade: Vec<ComputePipeline>,
    shadow: Option<ComputePipeline>,
    accumulate: ComputePipeline,
}

/// Device buffers: the scene, the wave's path state and queues, the film.
struct DeviceBuffers {
    queue_headers: Buffer,
    ray_queues: Buffer,
    ray_origin: Buffer,
    ray_dir: Buffer,
    hits: Buffer,
    counters: Buffer,
    film: Buffer,
    film_sq: Buffer,
    ray_counts: Buffer,
    /// Kept alive while the descriptor set refers to them.
    others: Vec<Buffer>,
}

impl DeviceBuffers {
    /// Bytes of device memory held by every buffer.
    fn bytes(&self) -> u64 {
        let named = [
            &self.queue_headers,
            &self.ray_queues,
            &self.ray_origin,
            &self.ray_dir,
            &self.hits,
            &self.counters,
            &self.film,
            &self.film_sq,
            &self.ray_counts,
        ];
        named
            .into_iter()
            .chain(&self.others)
            .map(Buffer::size)
            .sum()
    }
}

/// A scene on the device, ready to render waves of paths.
pub struct Renderer<'c> {
    ctx: &'c Context,
    features: Features,
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
}

/// The closest hit the intersect kernel found for one ray.
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
    /// Device memory the renderer allocated, in bytes.
    pub device_bytes: u64,
}

/// Size in bytes of `n` items of `T`.
fn bytes<T>(n: usize) -> u64 {
    (n * std::mem::size_of::<T>()) as u64
}

impl<'c> Renderer<'c> {
    /// Packs `scene`, allocates every buffer and builds the kernels.
    pub fn new(ctx: &'c Context, scene: &Scene, options: &RenderOptions) -> Result<Renderer<'c>> {
        let features = if options.all_features {
            Features::all(options.integrator)
        } else {
            Features::detect(scene, options.integrator)
        };
        let packed = GpuScene::pack(scene)?;
        let pixels = scene.render.width as u64 * scene.render.height as u64;
        anyhow::ensure!(options.wave_size >= 1, "--wave-size must be at least 1");
        let samples_per_wave = scene.render.spp.min(MAX_WAVE_SAMPLES_PER_PIXEL) as u64;
        // A wave must fit one dispatch (maxComputeWorkGroupCount) and its
        // widest per-path buffer (16 bytes a path) one binding.
        let info = ctx.info();
        let device_max = (info.max_compute_workgroup_count[0] as u64 * WORKGROUP_SIZE as u64)
            .min(info.max_storage_buffer_range / 16);
        let wave_capacity = (options.wave_size as u64)
            .min(pixels * samples_per_wave)
            .min(device_max) as u32;
        let wave_capacity = wave_capacity.max(1);

        let mut frame = packed.frame;
        frame.wave_capacity = wave_capacity;

        // Upload the scene
        let c = wave_capacity as usize;
        let vec4 = 16usize;
        let frame_buf = ctx.upload("scene.frame", &[frame])?;
        let nodes = ctx.upload("scene.bvh_nodes", &packed.nodes)?;
        let prims = ctx.upload("scene.primitives", &packed.primitives)?;
        let tri_shading = ctx.upload("scene.tri_shading", &packed.tri_shading)?;
        let materials = ctx.upload("scene.materials", &packed.materials)?;
        let emitters = ctx.upload("scene.emitters", &packed.emitters)?;
        let texels = if packed.textures.words.is_empty() {
            ctx.upload("scene.texels", &[0u32; 4])?
        } else {
            ctx.upload("scene.texels", &packed.textures.words)?
        };

        // Allocate the wave's path state and queues, named by the pass that writes them
        let dev = |label: &str, size: u64| ctx.create_buffer(label, size, MemoryKind::Device);
        let queue_headers = dev(
            "queues.headers",
            bytes::<GpuQueueHeader>(QUEUE_HEADER_COUNT as usize),
        )?;
        let ray_queues = dev("queues.rays", (RAY_QUEUE_COUNT as usize * c * 4) as u64)?;
        let shadow_queue = dev("queues.shadow", (c * 4) as u64)?;
        let ray_origin = dev("generate.ray_origin", (c * vec4) as u64)?;
        let ray_dir = dev("generate.ray_dir", (c * vec4) as u64)?;
        let throughput = dev("shade.throughput", (c * vec4) as u64)?;
        let radiance = dev("shade.radiance", (c * vec4) as u64)?;
        let hits = dev("intersect.hits", (c * vec4) as u64)?;
        let shadow_origin = dev("shade.shadow_origin", (c * vec4) as u64)?;
        let shadow_dir = dev("shade.shadow_dir", (c * vec4) as u64)?;
        let shadow_radiance = dev("shade.shadow_radiance", (c * vec4) as u64)?;
        let film =
            dev("accumulate.film", bytes::<GpuFilmPixel>(pixels as usize)).with_context(|| {
                format!(
                    "the film of a {}x{} image does not fit one buffer; render a smaller image",
                    scene.render.width, scene.render.height
                )
            })?;
        let film_sq = dev("accumulate.film_sq", bytes::<GpuFilmPixel>(pixels as usize))?;
        let counters = dev("accumulate.counters", (COUNTER_COUNT * 4) as u64)?;
        let ray_counts = ctx.create_buffer(
            "stats.ray_counts",
            (scene.render.max_depth as u64 * 2 * 4).max(16),
            MemoryKind::Readback,
        )?;

        let bindings = ctx.create_bindings(
            "wavefront",
            &[
                (BINDING_FRAME, &frame_buf),
                (BINDING_BVH_NODES, &nodes),
                (BINDING_PRIMITIVES, &prims),
                (BINDING_TRI_SHADING, &tri_shading),
                (BINDING_MATERIALS, &materials),
                (BINDING_EMITTERS, &emitters),
                (BINDING_QUEUE_HEADERS, &queue_headers),
                (BINDING_RAY_QUEUES, &ray_queues),
                (BINDING_SHADOW_QUEUE, &shadow_queue),
                (BINDING_RAY_ORIGIN, &ray_origin),
                (BINDING_RAY_DIR, &ray_dir),
                (BINDING_THROUGHPUT, &throughput),
                (BINDING_RADIANCE, &radiance),
                (BINDING_HITS, &hits),
                (BINDING_SHADOW_ORIGIN, &shadow_origin),
                (BINDING_SHADOW_DIR, &shadow_dir),
                (BINDING_SHADOW_RADIANCE, &shadow_radiance),
                (BINDING_FILM, &film),
                (BINDING_FILM_SQ, &film_sq),
                (BINDING_TEXELS, &texels),
                (BINDING_COUNTERS, &counters),
            ],
        )?;

        // Specialise the kernels to the scene; the film sums in f64 where it can
        let film_fp64 = ctx.info().shader_float64 && !options.f32_film;
        let push_bytes = std::mem::size_of::<GpuPush>() as u32;
        let spec = features.spec_constants(false);
        let pipeline = |label: &str, spirv: &[u8], spec: &[(u32, u32)]| {
            ctx.create_pipeline(label, spirv, &bindings, spec, push_bytes)
                .with_context(|| format!("building the {label} kernel"))
        };
        let kernels = Kernels {
            generate: pipeline("generate", shaders::GENERATE, &spec)?,
            intersect: pipeline("intersect", shaders::INTERSECT, &spec)?,
            shade: if options.shade_per_material && features.material_mask != 0 {
                features
                    .material_types()
                    .into_iter()
                    .map(|t| {
                        pipeline(
                            "shade",
                            shaders::SHADE,
                            &features.shade_spec_for_material(t),
                        )
                    })
                    .collect::<Result<Vec<_>>>()?
            } else {
                vec![pipeline("shade", shaders::SHADE, &spec)?]
            },
            shadow: if features.nee {
                Some(pipeline(
                    "shadow",
                    shaders::SHADOW,
                    &features.spec_constants(true),
                )?)
            } else {
                None
            },
            accumulate: if film_fp64 {
                pipeline("accumulate", shaders::ACCUMULATE, &spec)?
            } else {
                pipeline("accumulate", shaders::ACCUMULATE_F32, &spec)?
            },
        };

        let others = vec![
            frame_buf,
            nodes,
            prims,
            tri_shading,
            materials,
            emitters,
            texels,
            shadow_queue,
            throughput,
            radiance,
            shadow_origin,
            shadow_dir,
            shadow_radiance,
        ];
        let buffers = DeviceBuffers {
            queue_headers,
            ray_queues,
            ray_origin,
            ray_dir,
            hits,
            counters,
            film,
            film_sq,
            ray_counts,
            others,
        };
        let scene_info = SceneInfo {
            spheres: scene.spheres.len(),
            triangles: scene.triangles.len(),
            emitters: packed.emitters.len(),
            bvh_nodes: packed.nodes.len(),
            bvh_depth: packed.bvh_depth,
            device_bytes: buffers.bytes(),
        };
        Ok(Renderer {
            ctx,
            features,
            frame,
            kernels,
            buffers,
            prim_order: packed.prim_order,
            film_fp64,
            bindings,
            scene_info,
            push: GpuPush::default(),
        })
    }

    /// The features the kernels were specialised for.
    pub fn features(&self) -> &Features {
        &self.features
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
        let started = std::time::Instant::now();
        let pixels = self.frame.pixel_count as u64;
        let total_paths = pixels * self.frame.spp as u64;
        let waves = total_paths.div_ceil(self.frame.wave_capacity as u64);
        let bar = progress_bar(progress, waves);
        let mut records = Vec::new();
        let max_dispatches = 2 + (2 + self.kernels.shade.len() as u32) * self.frame.max_depth;
        self.clear_film()?;

        for wave in 0..waves {
            let start = wave * self.frame.wave_capacity as u64;
            let count = (total_paths - start).min(self.frame.wave_capacity as u64) as u32;
            let mut rec = self.ctx.begin("wave", max_dispatches)?;

            self.generate(&mut rec, start, count);
            for bounce in 0..self.frame.max_depth {
                self.intersect(&mut rec, bounce);
                self.shade(&mut rec, bounce);
                if self.features.nee {
                    self.shadow(&mut rec, bounce);
                }
            }
            self.accumulate(&mut rec);

            let timings = self.ctx.submit(rec)?;
            records.extend(self.wave_records(&timings, count, wave as u32)?);
            bar.inc(1);
        }
        bar.finish_and_clear();

        let (mean, var_of_mean) = self.resolve_film()?;
        let nonfinite =
            self.ctx.read::<u32>(&self.buffers.counters)?[COUNTER_NONFINITE as usize] as u64;
        let info = self.ctx.info();
        let stats = RenderStats {
            device: info.name.clone(),
            driver: info.driver_name.clone(),
            width: self.frame.width,
            height: self.frame.height,
            spp: self.frame.spp,
            max_depth: self.frame.max_depth,
            wave_size: self.frame.wave_capacity,
            waves: waves as u32,
            records,
            wall_seconds: started.elapsed().as_secs_f64(),
            nonfinite_samples: nonfinite,
            timestamps_supported: info.timestamps_supported,
        };
        Ok(RenderOutput {
            width: self.frame.width,
            height: self.frame.height,
            spp: self.frame.spp,
            mean,
            var_of_mean,
            stats,
        })
    }

    /// Runs the intersect kernel alone on the given rays (origin, unit
    /// direction, tmax), for testing the BVH traversal on the device.
    pub fn intersect_rays(
        &mut self,
        rays: &[(glam::Vec3, glam::Vec3, f32)],
    ) -> Result<Vec<Option<KernelHit>>> {
        anyhow::ensure!(
            rays.len() <= self.frame.wave_capacity as usize,
            "more rays than the wave holds"
        );
        let origins: Vec<glam::Vec4> = rays.iter().map(|r| r.0.extend(r.2)).collect();
        let dirs: Vec<glam::Vec4> = rays.iter().map(|r| r.1.extend(0.0)).collect();
        let slots: Vec<u32> = (0..rays.len() as u32).collect();
        self.ctx.write(&self.buffers.ray_origin, 0, &origins)?;
        self.ctx.write(&self.buffers.ray_dir, 0, &dirs)?;
        self.ctx.write(&self.buffers.ray_queues, 0, &slots)?;
        let mut rec = self.ctx.begin("intersect_rays", 1)?;
        let header = GpuQueueHeader::with_count(rays.len() as u32);
        rec.update_buffer(&self.buffers.queue_headers, 0, bytes_of(&header));
        rec.barrier();
        self.intersect(&mut rec, 0);
        self.ctx.submit(rec)?;
        let hits: Vec<[u32; 4]> = self.ctx.read(&self.buffers.hits)?;
        Ok(hits[..rays.len()]
            .iter()
            .map(|h| {
                (h[1] != NO_HIT).then(|| KernelHit {
                    prim: self.prim_order[h[1] as usize],
                    t: f32::from_bits(h[0]),
                })
            })
            .collect())
    }

    /// Zeroes the film and the counters before the first wave.
    fn clear_film(&self) -> Result<()> {
        let mut rec = self.ctx.begin("clear_film", 0)?;
        for buf in [
            &self.buffers.film,
            &self.buffers.film_sq,
            &self.buffers.counters,
        ] {
            rec.fill_buffer(buf, 0, buf.size(), 0);
        }
        self.ctx.submit(rec)?;
        Ok(())
    }

    /// Records the generate pass: camera rays for `count` paths from `start`.
    fn generate(&mut self, rec: &mut Recorder, start: u64, count: u32) {
        let pixels = self.frame.pixel_count as u64;
        self.push = GpuPush {
            sample_base: (start / pixels) as u32,
            pixel_base: (start % pixels) as u32,
            path_count: count,
            bounce: 0,
        };
        // Every camera ray is on queue 0; the other queues start empty
        let headers = [
            GpuQueueHeader::with_count(count),
            GpuQueueHeader::with_count(0),
            GpuQueueHeader::with_count(0),
        ];
        rec.update_buffer(
            &self.buffers.queue_headers,
            0,
            bytemuck::cast_slice(&headers),
        );
        rec.barrier();
        let groups = count.div_ceil(WORKGROUP_SIZE);
        rec.dispatch(
            "generate",
            None,
            &self.kernels.generate,
            &self.bindings,
            bytes_of(&self.push),
            [groups, 1, 1],
        );
    }

    /// Records the intersect pass over the current ray queue.
    fn intersect(&mut self, rec: &mut Recorder, bounce: u32) {
        self.push.bounce = bounce;
        let queue = bounce % RAY_QUEUE_COUNT;
        rec.barrier();
        self.count_rays(rec, bounce, queue, 0);
        self.dispatch_queue(
            rec,
            "intersect",
            Some(bounce),
            &self.kernels.intersect,
            queue,
        );
    }

    /// Records the shade pass: current queue in, next queue and shadow queue out.
    fn shade(&mut self, rec: &mut Recorder, bounce: u32) {
        let next = (bounce + 1) % RAY_QUEUE_COUNT;
        // Empty the queues this pass fills
        let empty = GpuQueueHeader::with_count(0);
        rec.update_buffer(
            &self.buffers.queue_headers,
            header_offset(next),
            bytes_of(&empty),
        );
        rec.update_buffer(
            &self.buffers.queue_headers,
            header_offset(SHADOW_QUEUE),
            bytes_of(&empty),
        );
        rec.barrier();
        // One dispatch, or one per material type; each path is shaded once
        for kernel in &self.kernels.shade {
            self.dispatch_queue(rec, "shade", Some(bounce), kernel, bounce % RAY_QUEUE_COUNT);
        }
    }

    /// Records the shadow pass over the shadow queue.
    fn shadow(&mut self, rec: &mut Recorder, bounce: u32) {
        let Some(kernel) = &self.kernels.shadow else {
            return;
        };
        rec.barrier();
        self.count_rays(rec, bounce, SHADOW_QUEUE, 1);
        rec.dispatch_indirect(
            "shadow",
            Some(bounce),
            kernel,
            &self.bindings,
            bytes_of(&self.push),
            &self.buffers.queue_headers,
            header_offset(SHADOW_QUEUE),
        );
    }

    /// Records the accumulate pass: finished radiance into the film.
    fn accumulate(&mut self, rec: &mut Recorder) {
        rec.barrier();
        let threads = self.push.path_count.min(self.frame.pixel_count);
        rec.dispatch(
            "accumulate",
            None,
            &self.kernels.accumulate,
            &self.bindings,
            bytes_of(&self.push),
            [threads.div_ceil(WORKGROUP_SIZE), 1, 1],
        );
    }

    /// Dispatches `kernel` indirectly over the items of ray queue `queue`.
    fn dispatch_queue(
        &self,
        rec: &mut Recorder,
        label: &'static str,
        tag: Option<u32>,
        kernel: &ComputePipeline,
        queue: u32,
    ) {
        rec.dispatch_indirect(
            label,
            tag,
            kernel,
            &self.bindings,
            bytes_of(&self.push),
            &self.buffers.queue_headers,
            header_offset(queue),
        );
    }

    /// Copies a queue's item count into the per-bounce ray counts.
    fn count_rays(&self, rec: &mut Recorder, bounce: u32, queue: u32, column: u64) {
        let count_offset =
            header_offset(queue) + std::mem::offset_of!(GpuQueueHeader, count) as u64;
        rec.copy_buffer(
            &self.buffers.queue_headers,
            count_offset,
            &self.buffers.ray_counts,
            (bounce as u64 * 2 + column) * 4,
            4,
        );
    }

    /// Turns a wave's timings and ray counts into pass records.
    fn wave_records(
        &self,
        timings: &crate::vk::Timings,
        paths: u32,
        wave: u32,
    ) -> Result<Vec<PassRecord>> {
        let counts: Vec<u32> = self.ctx.read(&self.buffers.ray_counts)?;
        // With one shade dispatch per material, the queue's rays count once
        let mut counted = std::collections::HashSet::new();
        Ok(timings
            .dispatches
            .iter()
            .map(|d| {
                let first = counted.insert((d.label, d.tag));
                let rays = match (d.label, d.tag) {
                    (_, Some(_)) if !first => 0,
                    ("intersect" | "shade", Some(b)) => counts[b as usize * 2] as u64,
                    ("shadow", Some(b)) => counts[b as usize * 2 + 1] as u64,
                    _ => paths as u64,
                };
                PassRecord {
                    pass: d.label,
                    bounce: d.tag,
                    gpu_ns: d.gpu_ns,
                    rays,
                    start_ns: d.start_ns,
                    wave,
                }
            })
            .collect())
    }

    /// Reads the film and turns sums into means and variances of the mean.
    fn resolve_film(&self) -> Result<(Vec<f32>, Vec<f32>)> {
        let film: Vec<GpuFilmPixel> = self.ctx.read(&self.buffers.film)?;
        let film_sq: Vec<GpuFilmPixel> = self.ctx.read(&self.buffers.film_sq)?;
        let n = self.frame.spp as f64;
        let mut mean = Vec::with_capacity(film.len() * 3);
        let mut var = Vec::with_capacity(film.len() * 3);
        for (s, q) in film.iter().zip(&film_sq) {
            let (s, q) = (s.total(self.film_fp64), q.total(self.film_fp64));
            for c in 0..3 {
                let m = s[c] / n;
                let sample_var = if n > 1.0 {
                    ((q[c] - n * m * m) / (n - 1.0)).max(0.0)
                } else {
                    0.0
                };
                mean.push(m as f32);
                var.push((sample_var / n) as f32);
            }
        }
        Ok((mean, var))
    }
}

/// Byte offset of queue header `queue`.
fn header_offset(queue: u32) -> u64 {
    queue as u64 * std::mem::size_of::<GpuQueueHeader>() as u64
}

/// A progress bar over waves on stderr, hidden when not wanted.
fn progress_bar(show: bool, waves: u64) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(waves),
        indicatif::ProgressDrawTarget::stderr(),
    );
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{spinner} rendering [{bar:30}] wave {pos}/{len} {elapsed_precise} eta {eta}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}
