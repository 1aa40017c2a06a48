//! Hidden test hooks: the intersect kernel alone on given rays, the probe
//! kernel (ray offsets and shadow segments as shade makes them), the
//! material test kernel (shade's `bsdf_sample` and `bsdf_eval`), the light
//! test kernel (shade's `sample_light` and the environment map's lookups) and the
//! sampler test kernel (the path code's `sample_2d` and `sample_1d`). The
//! test suite reaches the device code through them; they are not part of
//! the API.

use anyhow::{Context as _, Result};
use bytemuck::bytes_of;
use glam::Vec4;

use super::kernels::{spirv, Pass, Schedule};
use super::record::{header_offset, ray_queue_of};
use super::Renderer;
use crate::gpu::bindings::*;
use crate::gpu::{GpuHit, GpuPush, GpuQueueHeader};
use crate::interface::*;
use crate::vk::{ComputePipeline, Recorder};

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
    /// A was hit on its front side, as the shade kernel sees it.
    pub front: bool,
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

/// What the light test kernel (`shaders/test_light.comp`) gives for one
/// item: `sample_light`'s figures (when sampling), and the environment
/// map's at the direction. A test hook for [`Renderer::sample_lights`] and
/// [`Renderer::eval_envmap`], not part of the API.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KernelLightSample {
    /// `sample_light` returned true.
    pub ok: bool,
    /// The sampled direction (the given one when evaluating).
    pub wi: glam::Vec3,
    /// The pdf `sample_light` gave, pick probability included.
    pub pdf: f32,
    /// The radiance `sample_light` gave.
    pub le: glam::Vec3,
    /// `envmap_radiance` at the direction (zero without a map).
    pub env_radiance: glam::Vec3,
    /// `envmap_pdf` at the direction, pick probability included.
    pub env_pdf: f32,
}

impl<'c> Renderer<'c> {
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
            .create_pipeline("probe", spirv("probe"), &self.bindings, &spec, push)
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
                front: info[i][2] & 4 != 0,
                pa: pa[i].truncate(),
                pb: pb[i].truncate(),
            })
            .collect())
    }

    /// Uploads test rays (origin and tmax, direction) into the path slots
    /// of ray queue 0 and begins a command buffer whose queue header holds
    /// their count, for a test hook's kernel to run on.
    pub(super) fn begin_test_queue(
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
    pub(super) fn kernel_hit(&self, prim: u32, t: f32) -> Option<KernelHit> {
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
    pub(super) fn run_test_bsdf(
        &mut self,
        material: u32,
        wo: glam::Vec3,
        flags: u32,
        inputs: &[glam::Vec3],
    ) -> Result<Vec<[Vec4; 3]>> {
        self.ensure_test_buffers("material")?;
        let materials = self.scene_info.materials;
        anyhow::ensure!(
            (material as usize) < materials,
            "material {material} is not in the scene, which has {materials}"
        );
        if self.test_bsdf.is_none() {
            self.test_bsdf = Some(self.test_kernel("test_bsdf", "material", Pass::Shade)?);
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
            self.dispatch_test("test_bsdf", kernel, &a, Some(&vec![dir; chunk.len()]))?;
            let [wi, weight, eval] = self.test_outputs()?;
            out.extend((0..chunk.len()).map(|i| [wi[i], weight[i], eval[i]]));
        }
        Ok(out)
    }

    /// Samples a light for a point at `from` once per pair of random
    /// numbers in `u` (the first picks the light and is reused), with the shade kernel's `sample_light`, and
    /// evaluates the environment map at each sampled direction. A test
    /// hook, not part of the API.
    #[doc(hidden)]
    pub fn sample_lights(
        &mut self,
        from: glam::Vec3,
        u: &[glam::Vec2],
    ) -> Result<Vec<KernelLightSample>> {
        let u: Vec<glam::Vec3> = u.iter().map(|u| u.extend(0.0)).collect();
        self.run_test_light(from, 0, &u)
    }

    /// Evaluates the environment map (`envmap_pdf`, `envmap_radiance`) at
    /// each direction of `wi`. A test hook, not part of the API.
    #[doc(hidden)]
    pub fn eval_envmap(&mut self, wi: &[glam::Vec3]) -> Result<Vec<KernelLightSample>> {
        self.run_test_light(glam::Vec3::ZERO, TEST_LIGHT_EVALUATE, wi)
    }

    /// Runs the light test kernel on one item per input, a wave at a time
    /// (see `shaders/test_light.comp`).
    fn run_test_light(
        &mut self,
        from: glam::Vec3,
        flags: u32,
        inputs: &[glam::Vec3],
    ) -> Result<Vec<KernelLightSample>> {
        self.ensure_test_buffers("light")?;
        let kernel = self.test_kernel("test_light", "light", Pass::Shade)?;
        let mut out = Vec::with_capacity(inputs.len());
        for chunk in inputs.chunks(self.frame.wave_capacity as usize) {
            let a: Vec<Vec4> = chunk
                .iter()
                .map(|x| x.extend(f32::from_bits(flags)))
                .collect();
            let dir = vec![from.extend(0.0); chunk.len()];
            self.dispatch_test("test_light", &kernel, &a, Some(&dir))?;
            let [wi, le, env] = self.test_outputs()?;
            out.extend((0..chunk.len()).map(|i| KernelLightSample {
                ok: le[i].w != 0.0,
                wi: if flags & TEST_LIGHT_EVALUATE != 0 {
                    chunk[i]
                } else {
                    wi[i].truncate()
                },
                pdf: wi[i].w,
                le: le[i].truncate(),
                env_radiance: env[i].truncate(),
                env_pdf: env[i].w,
            }));
        }
        Ok(out)
    }

    /// Draws, with the sampler the renderer was built with and the scene's
    /// seed, the numbers of each `(pixel, sample index, dimension,
    /// partner)` of `items` as the path code does: `[x, y, z]` with `(x, y)`
    /// the pair at the dimension (`sample_2d`, or `sample_2d_partnered`
    /// with the pair draw at `partner` unless it is `TEST_SAMPLER_ALONE`)
    /// and `z` the number `sample_1d` gives (`shaders/test_sampler.comp`).
    /// A test hook, not part of the API.
    #[doc(hidden)]
    pub fn sampler_numbers(&mut self, items: &[[u32; 4]]) -> Result<Vec<[f32; 3]>> {
        self.ensure_test_buffers("sampler")?;
        let kernel = self.test_kernel("test_sampler", "sampler", Pass::Generate)?;
        let mut out = Vec::with_capacity(items.len());
        for chunk in items.chunks(self.frame.wave_capacity as usize) {
            let input: Vec<Vec4> = chunk
                .iter()
                .map(|item| Vec4::from_array(item.map(f32::from_bits)))
                .collect();
            self.dispatch_test("test_sampler", &kernel, &input, None)?;
            let [numbers, _, _] = self.test_outputs()?;
            out.extend(numbers[..chunk.len()].iter().map(|v| [v.x, v.y, v.z]));
        }
        Ok(out)
    }

    /// The test kernels borrow the wavefront's path-state buffers, which
    /// the megakernel shrinks to one item: refuse them there.
    fn ensure_test_buffers(&self, what: &str) -> Result<()> {
        anyhow::ensure!(
            self.schedule == Schedule::Wavefront,
            "the {what} test kernel needs the wavefront's buffers"
        );
        Ok(())
    }

    /// Builds test kernel `name` (`shaders/<name>.comp`) with the
    /// specialisation constants of `pass`.
    fn test_kernel(&self, name: &str, what: &str, pass: Pass) -> Result<ComputePipeline> {
        let spec = self.features.spec_constants(pass);
        let push_bytes = std::mem::size_of::<GpuPush>() as u32;
        self.ctx
            .create_pipeline(name, spirv(name), &self.bindings, &spec, push_bytes)
            .with_context(|| format!("building the {what} test kernel"))
    }

    /// Runs a test kernel once over `origin` (its items, in the ray-origin
    /// buffer) and `dir` (the ray-direction buffer, where it reads one),
    /// one thread per item, and waits for it.
    fn dispatch_test(
        &self,
        name: &'static str,
        kernel: &ComputePipeline,
        origin: &[Vec4],
        dir: Option<&[Vec4]>,
    ) -> Result<()> {
        self.ctx
            .write(self.buffers.get(BINDING_RAY_ORIGIN), 0, origin)?;
        if let Some(dir) = dir {
            self.ctx.write(self.buffers.get(BINDING_RAY_DIR), 0, dir)?;
        }
        let push = GpuPush {
            path_count: origin.len() as u32,
            ..GpuPush::default()
        };
        let mut rec = self.ctx.begin(name, 1)?;
        rec.dispatch(
            name,
            None,
            kernel,
            &self.bindings,
            bytes_of(&push),
            [(origin.len() as u32).div_ceil(WORKGROUP_SIZE), 1, 1],
        );
        self.ctx.submit(rec)?;
        Ok(())
    }

    /// Reads what the test kernels write: the three shadow-ray buffers.
    fn test_outputs(&self) -> Result<[Vec<Vec4>; 3]> {
        let read = |binding| -> Result<Vec<Vec4>> { Ok(self.ctx.read(self.buffers.get(binding))?) };
        Ok([
            read(BINDING_SHADOW_ORIGIN)?,
            read(BINDING_SHADOW_DIR)?,
            read(BINDING_SHADOW_RADIANCE)?,
        ])
    }
}
