//! The device buffers of a render, from the device interface table
//! ([`crate::gpu::bindings`]): scene data uploaded, path state and queues
//! sized by the wave, the film by the band of rows it holds, and the advice
//! a user gets when the device runs out of memory, by what grows.

use anyhow::{Context as _, Result};
use bytemuck::{bytes_of, cast_slice};

use super::kernels::Schedule;
use super::{RenderOptions, BOUNCES_PER_SUBMIT};
use crate::gpu::bindings::*;
use crate::gpu::{Access, BufferDecl, GpuFrame, GpuScene, Grows};
use crate::interface::*;
use crate::scene::Scene;
use crate::vk::{BindingKind, Buffer, Context, MemoryKind, VkError};

/// What a device buffer starts with.
enum Contents<'a> {
    /// These bytes, uploaded once.
    Upload(&'a [u8]),
    /// This many bytes, written by the passes.
    Size(u64),
}

/// One buffer to allocate: its row of the device interface and its contents.
pub(super) struct BufferRow<'a> {
    decl: &'static BufferDecl,
    contents: Contents<'a>,
}

/// The bytes packing gives the buffer at `binding`, one that grows with the
/// scene or its textures.
fn scene_bytes<'a>(packed: &'a GpuScene, frame: &'a GpuFrame, binding: u32) -> Result<&'a [u8]> {
    Ok(match binding {
        BINDING_FRAME => bytes_of(frame),
        BINDING_BVH_NODES => cast_slice(&packed.bvh),
        BINDING_PRIMITIVES => cast_slice(&packed.primitives),
        BINDING_TRI_SHADING => cast_slice(&packed.tri_shading),
        BINDING_MATERIALS => cast_slice(&packed.material_texels),
        BINDING_EMITTERS => cast_slice(&packed.emitter_texels),
        BINDING_TEXELS => cast_slice(&packed.textures.words),
        BINDING_ENVMAP => cast_slice(&packed.environment.words),
        other => anyhow::bail!("binding {other} is scene data that packing does not give"),
    })
}

/// Every device buffer the kernels bind, once, in the order of the device
/// interface table. Scene data is uploaded; path state and queues are sized
/// by the wave (one item under the megakernel, which keeps path state in
/// registers and binds them only because both schedules share one
/// descriptor layout), the film by the band of `film_pixels` pixels it
/// holds at once. The pixel list, which only kernels built with
/// `pixel_list` (an adaptive render) read, is one item otherwise.
pub(super) fn buffer_table<'a>(
    packed: &'a GpuScene,
    frame: &'a GpuFrame,
    schedule: Schedule,
    film_pixels: u64,
    pixel_list: bool,
) -> Result<Vec<BufferRow<'a>>> {
    let wave = match schedule {
        Schedule::Wavefront => frame.wave_capacity as u64,
        Schedule::Megakernel => 1,
    };
    BUFFERS
        .iter()
        .map(|decl| {
            let items = match decl.grows {
                Grows::Scene | Grows::Textures => {
                    let bytes = scene_bytes(packed, frame, decl.binding)?;
                    return Ok(BufferRow {
                        decl,
                        contents: Contents::Upload(bytes),
                    });
                }
                Grows::Wave(per_path) => per_path.checked_mul(wave),
                Grows::Film if decl.binding == BINDING_PIXEL_LIST && !pixel_list => Some(1),
                Grows::Film => Some(film_pixels),
                Grows::Fixed(n) => Some(n),
            };
            let bytes = items
                .and_then(|n| n.checked_mul(decl.item_bytes))
                .with_context(|| format!("{}: its size overflows a buffer size", decl.label))?;
            Ok(BufferRow {
                decl,
                contents: Contents::Size(bytes),
            })
        })
        .collect()
}

/// Bytes per path of the buffers that grow with the wave: the widest one
/// (`widest`) or all of them together.
const fn path_bytes(widest: bool) -> u64 {
    let (mut max, mut sum) = (0, 0);
    let mut i = 0;
    while i < BUFFERS.len() {
        if let Grows::Wave(per_path) = BUFFERS[i].grows {
            let bytes = BUFFERS[i].item_bytes * per_path;
            sum += bytes;
            if bytes > max {
                max = bytes;
            }
        }
        i += 1;
    }
    if widest {
        max
    } else {
        sum
    }
}

/// Bytes per path of the widest buffer that grows with the wave: one
/// binding of it must hold a whole wave.
const WIDEST_PATH_ITEM: u64 = path_bytes(true);

/// Bytes per path of every buffer that grows with the wave (the
/// wavefront's path state and queues): what a wave of n paths holds, n
/// times this, besides the scene and the film.
pub(super) const PATH_BYTES: u64 = path_bytes(false);

/// What to change when the device runs out of memory (or a buffer does not
/// fit one binding), by what grows: the buffer's row when an allocation
/// failed, `None` when the driver reported it elsewhere. The one place
/// lancer gives that advice; it names settings (`RenderOptions::wave_size`,
/// `render.width`), which the command line maps to its flags.
pub(super) fn what_to_change(decl: Option<&BufferDecl>, frame: &GpuFrame) -> String {
    let Some(decl) = decl else {
        return "the device ran out of memory; lower RenderOptions::wave_size or the image size \
                (render.width, render.height)"
            .to_string();
    };
    let label = decl.label;
    match decl.grows {
        Grows::Textures => {
            "the scene's textures do not fit this device: use smaller texture images".to_string()
        }
        Grows::Scene => format!(
            "the scene's geometry ({label}) does not fit this device: use fewer triangles or \
             spheres"
        ),
        Grows::Film => format!(
            "the film of a {}x{} image does not fit this device: render a smaller image \
             (render.width, render.height)",
            frame.width, frame.height
        ),
        Grows::Wave(_) | Grows::Fixed(_) => format!(
            "the state of {} paths in flight ({label}) does not fit this device: lower \
             RenderOptions::wave_size",
            frame.wave_capacity
        ),
    }
}

/// Adds [`what_to_change`] to an error when a Vulkan error in its chain says
/// the device ran out of memory, or was lost, and no advice is there yet.
pub(super) fn advise(e: anyhow::Error, frame: &GpuFrame) -> anyhow::Error {
    let vk = e.chain().find_map(|c| c.downcast_ref::<VkError>());
    match vk {
        Some(v) if v.is_out_of_memory() && e.downcast_ref::<Advised>().is_none() => {
            let advice = what_to_change(None, frame);
            e.context(Advised(advice))
        }
        Some(v) if v.is_device_lost() => e.context(
            "the device was lost (a dispatch may have run too long for the GPU watchdog: \
             lower RenderOptions::wave_size)",
        ),
        _ => e,
    }
}

/// Advice already attached to an error, so that it is given once.
#[derive(Debug)]
struct Advised(String);

impl std::fmt::Display for Advised {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Advised {}

/// Device buffers: one per binding, from [`buffer_table`], and the
/// per-bounce ray counts read back after each wave.
pub(super) struct DeviceBuffers {
    /// Indexed by binding number; `None` at a binding that is a texel view
    /// of another row's buffer.
    by_binding: Vec<Option<Buffer>>,
    /// How the kernels read each binding, indexed by binding number.
    kinds: Vec<BindingKind>,
    /// `(texel binding, storage binding)` of each buffer read as texels.
    read_views: Vec<(u32, u32)>,
    /// Per-bounce ray counts, read back after each command buffer.
    pub(super) ray_counts: Buffer,
}

impl DeviceBuffers {
    /// Allocates (and uploads) every row of the table, plus the ray counts
    /// of the bounces one command buffer records.
    pub(super) fn allocate(
        ctx: &Context,
        table: &[BufferRow<'_>],
        frame: &GpuFrame,
    ) -> Result<DeviceBuffers> {
        let mut slots: Vec<Option<Buffer>> = (0..BINDING_COUNT).map(|_| None).collect();
        let mut kinds = vec![BindingKind::Storage; BINDING_COUNT as usize];
        let mut taken = vec![false; BINDING_COUNT as usize];
        let mut read_views = Vec::new();
        for row in table {
            let decl = row.decl;
            for b in std::iter::once(decl.binding).chain(decl.texels) {
                anyhow::ensure!(
                    !std::mem::replace(&mut taken[b as usize], true),
                    "binding {b} is in the table twice"
                );
            }
            kinds[decl.binding as usize] = match decl.access {
                Access::Texels => BindingKind::TexelRgba32Ui,
                Access::ReadOnly | Access::ReadWrite => BindingKind::Storage,
            };
            if let Some(texels) = decl.texels {
                kinds[texels as usize] = BindingKind::TexelRgba32Ui;
                read_views.push((texels, decl.binding));
            }
            let buffer = match row.contents {
                Contents::Upload(bytes) => ctx.upload(decl.label, bytes),
                Contents::Size(size) => ctx.create_buffer(decl.label, size, MemoryKind::Device),
            }
            .map_err(|e| {
                if e.is_out_of_memory() || matches!(e, VkError::BufferTooLarge { .. }) {
                    anyhow::Error::new(e).context(Advised(what_to_change(Some(decl), frame)))
                } else {
                    anyhow::Error::new(e).context(format!("allocating {}", decl.label))
                }
            })?;
            slots[decl.binding as usize] = Some(buffer);
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
    pub(super) fn get(&self, binding: u32) -> &Buffer {
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
    pub(super) fn bindings(&self) -> Vec<(u32, &Buffer, BindingKind)> {
        (0..BINDING_COUNT)
            .map(|b| (b, self.get(b), self.kinds[b as usize]))
            .collect()
    }

    /// Bytes of device memory held by every buffer.
    pub(super) fn bytes(&self) -> u64 {
        self.by_binding
            .iter()
            .flatten()
            .chain([&self.ray_counts])
            .map(Buffer::size)
            .sum()
    }
}

/// The environment variable that lowers the bytes the texture binding may
/// hold below the device's `maxStorageBufferRange`, so that tests can
/// shrink small textures as the device shrinks large ones.
pub const MAX_TEXTURE_BYTES_ENV: &str = "LANCER_MAX_TEXTURE_BYTES";

/// Bytes the one binding that holds every texel may take: the device's
/// `maxStorageBufferRange`, or less where [`MAX_TEXTURE_BYTES_ENV`] says.
pub(super) fn max_texture_bytes(ctx: &Context) -> Result<u64> {
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
            crate::util::text::cut(&text)
        ),
    }
}

/// Paths per wave: what the options ask for (or the device's default,
/// [`super::default_wave_size`]), at most every sample of the image, and
/// within one dispatch (`maxComputeWorkGroupCount`) and one binding of the
/// widest per-path buffer.
pub(super) fn wave_capacity(ctx: &Context, scene: &Scene, options: &RenderOptions) -> Result<u32> {
    let asked = match options.wave_size {
        Some(n) => {
            anyhow::ensure!(
                n >= 1,
                "the paths in flight (RenderOptions::wave_size) must be at least 1"
            );
            n
        }
        None => super::default_wave_size(ctx),
    };
    let pixels = scene.render.width as u64 * scene.render.height as u64;
    let samples_per_wave = scene.render.spp.min(MAX_WAVE_SAMPLES_PER_PIXEL) as u64;
    let info = ctx.info();
    let device_max = (info.max_compute_workgroup_count[0] as u64 * WORKGROUP_SIZE as u64)
        .min(info.max_storage_buffer_range / WIDEST_PATH_ITEM);
    let capacity = (asked as u64)
        .min(pixels * samples_per_wave)
        .min(device_max);
    Ok(capacity.max(1) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vk::TEXEL_BYTES;

    #[test]
    fn texel_views_hold_whole_texels_and_every_binding_is_declared_once() {
        let mut seen = vec![0; BINDING_COUNT as usize];
        for decl in BUFFERS {
            if decl.access == Access::Texels || decl.texels.is_some() {
                assert_eq!(decl.item_bytes % TEXEL_BYTES, 0, "{}", decl.label);
            }
            for b in std::iter::once(decl.binding).chain(decl.texels) {
                seen[b as usize] += 1;
            }
        }
        assert!(seen.iter().all(|&n| n == 1), "{seen:?}");
        assert_eq!(WIDEST_PATH_ITEM, 16);
    }

    /// The default wave: small on a CPU device; on a GPU a power of two
    /// whose path state stays within a quarter of the device-local budget.
    #[test]
    fn default_wave_takes_at_most_a_quarter_of_a_gpu_heap() {
        use crate::render::{wave_size_for, CPU_WAVE_SIZE, GPU_WAVE_SIZE};
        use crate::vk::DeviceKind;
        assert_eq!(wave_size_for(DeviceKind::Cpu, 1 << 40), CPU_WAVE_SIZE);
        assert_eq!(
            wave_size_for(DeviceKind::Discrete, 140 << 30),
            GPU_WAVE_SIZE
        );
        assert_eq!(wave_size_for(DeviceKind::Discrete, 0), CPU_WAVE_SIZE);
        let budget = 1u64 << 30;
        let wave = wave_size_for(DeviceKind::Integrated, budget) as u64;
        assert!(
            wave.is_power_of_two() && wave > CPU_WAVE_SIZE as u64,
            "{wave}"
        );
        assert!(wave * PATH_BYTES <= budget / 4, "{wave}");
        assert!(2 * wave * PATH_BYTES > budget / 4, "{wave}");
        // The widest buffer is one of those counted
        const { assert!(PATH_BYTES > WIDEST_PATH_ITEM) };
    }

    /// Out of memory and a lost device get their advice once, naming the
    /// setting to change, wherever the driver reported them.
    #[test]
    fn advice_is_given_once_by_what_grows() {
        let frame = GpuFrame {
            width: 64,
            height: 48,
            wave_capacity: 4096,
            ..bytemuck::Zeroable::zeroed()
        };
        let lost = advise(
            VkError::call("vkQueueSubmit")(ash::vk::Result::ERROR_DEVICE_LOST).into(),
            &frame,
        );
        let text = format!("{lost:#}");
        assert!(text.starts_with("the device was lost"), "{text}");
        assert!(text.contains("lower RenderOptions::wave_size)"), "{text}");

        let oom = || VkError::call("vkQueueSubmit")(ash::vk::Result::ERROR_OUT_OF_DEVICE_MEMORY);
        let text = format!("{:#}", advise(advise(oom().into(), &frame), &frame));
        assert_eq!(text.matches("ran out of memory").count(), 1, "{text}");
        assert!(
            text.contains("or the image size (render.width, render.height)"),
            "{text}"
        );

        let film = BUFFERS.iter().find(|d| d.binding == BINDING_FILM).unwrap();
        let allocation =
            anyhow::Error::new(oom()).context(Advised(what_to_change(Some(film), &frame)));
        let text = format!("{:#}", advise(allocation, &frame));
        assert!(
            text.starts_with("the film of a 64x48 image does not fit"),
            "{text}"
        );
        assert!(!text.contains("ran out of memory"), "{text}");
    }
}
