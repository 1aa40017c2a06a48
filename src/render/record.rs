//! The recording of the two schedules: the wavefront's passes (one kernel
//! each, dispatched indirectly from the queue headers the previous pass
//! wrote) and the megakernel's one dispatch per wave, and the pass records
//! their timestamps become.

use anyhow::{Context as _, Result};
use bytemuck::bytes_of;

use super::kernels::Pass;
use super::stats::PassRecord;
use super::tiles::{Tile, Wave};
use super::{Renderer, BOUNCES_PER_SUBMIT};
use crate::gpu::bindings::*;
use crate::gpu::{GpuPush, GpuQueueHeader};
use crate::interface::*;
use crate::vk::Recorder;

impl<'c> Renderer<'c> {
    /// Renders one wave of `tile` in one kernel: each thread takes a pixel
    /// and follows its paths of the wave from the camera to the film. The
    /// wave's pixels go in runs, one command buffer each, of at most as
    /// many path segments as one wavefront command buffer records (the wave
    /// capacity times [`BOUNCES_PER_SUBMIT`]), so that a deep wave cannot
    /// keep one dispatch past a GPU watchdog. A pixel's samples stay in one
    /// thread, so the film gets the same sums in the same order.
    pub(super) fn megakernel(
        &mut self,
        tile: Tile,
        wave: Wave,
        index: u32,
    ) -> Result<Vec<PassRecord>> {
        let mut records = Vec::new();
        for run in megakernel_runs(wave, self.frame.wave_capacity, self.frame.max_depth) {
            let mut rec = self.ctx.begin("wave", 1)?;
            self.push = wave_push(tile, run);
            rec.barrier();
            self.dispatch(
                &mut rec,
                Pass::Megakernel,
                None,
                run.pixels.div_ceil(WORKGROUP_SIZE),
            );
            let timings = self.ctx.submit(rec)?;
            records.extend(self.wave_records(&timings, run.paths(), index)?);
        }
        Ok(records)
    }

    /// Records the generate pass: the camera rays of `wave`.
    pub(super) fn generate(&mut self, rec: &mut Recorder, tile: Tile, wave: Wave) {
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
    pub(super) fn intersect(&mut self, rec: &mut Recorder, bounce: u32) {
        self.push.bounce = bounce;
        let queue = ray_queue_of(bounce);
        rec.barrier();
        self.count_rays(rec, bounce, queue, 0);
        self.dispatch_queue(rec, Pass::Intersect, bounce, queue);
    }

    /// Records the shade pass: current queue in, next queue and shadow queue out.
    pub(super) fn shade(&mut self, rec: &mut Recorder, bounce: u32) {
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
    pub(super) fn shadow(&mut self, rec: &mut Recorder, bounce: u32) {
        rec.barrier();
        self.count_rays(rec, bounce, SHADOW_QUEUE, 1);
        self.dispatch_queue(rec, Pass::Shadow, bounce, SHADOW_QUEUE);
    }

    /// Records the accumulate pass: finished radiance into the film.
    pub(super) fn accumulate(&mut self, rec: &mut Recorder) {
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
    pub(super) fn dispatch(
        &self,
        rec: &mut Recorder,
        pass: Pass,
        bounce: Option<u32>,
        groups: u32,
    ) {
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
    pub(super) fn dispatch_queue(&self, rec: &mut Recorder, pass: Pass, bounce: u32, queue: u32) {
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
    pub(super) fn count_rays(&self, rec: &mut Recorder, bounce: u32, queue: u32, column: u64) {
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
    pub(super) fn wave_records(
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
                let rays = match (pass, d.step) {
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
                    bounce: d.step,
                    gpu_ns: d.gpu_ns,
                    rays,
                    start_ns: d.start_ns,
                    wave,
                })
            })
            .collect()
    }

    /// Items in queue `queue`, read back from the device.
    pub(super) fn queue_len(&self, queue: u32) -> Result<u32> {
        let headers: Vec<GpuQueueHeader> =
            self.ctx.read(self.buffers.get(BINDING_QUEUE_HEADERS))?;
        Ok(headers[queue as usize].count)
    }
}

/// The runs of `wave`'s pixels the megakernel dispatches one command buffer
/// each: at most `capacity * BOUNCES_PER_SUBMIT` path segments (paths times
/// `max_depth`) per run, and at least one pixel.
pub(super) fn megakernel_runs(wave: Wave, capacity: u32, max_depth: u32) -> Vec<Wave> {
    let segments = u64::from(capacity) * u64::from(BOUNCES_PER_SUBMIT);
    let per_pixel = u64::from(wave.samples) * u64::from(max_depth.max(1));
    let run = (segments / per_pixel.max(1)).clamp(1, u64::from(wave.pixels.max(1))) as u32;
    (0..wave.pixels)
        .step_by(run as usize)
        .map(|first| Wave {
            pixel_base: wave.pixel_base + first,
            pixels: run.min(wave.pixels - first),
            ..wave
        })
        .collect()
}

/// The push constants of `wave` of `tile`, at bounce 0.
pub(super) fn wave_push(tile: Tile, wave: Wave) -> GpuPush {
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
pub(super) fn ray_queue_of(bounce: u32) -> u32 {
    bounce % RAY_QUEUE_COUNT
}

/// Byte offset of queue header `queue`.
pub(super) fn header_offset(queue: u32) -> u64 {
    queue as u64 * std::mem::size_of::<GpuQueueHeader>() as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn megakernel_runs_cover_the_wave_within_the_bound() {
        let wave = Wave {
            pixel_base: 100,
            pixels: 4096,
            sample_base: 8,
            samples: 64,
        };
        // A shallow wave is one run, as the wavefront's one command buffer
        assert_eq!(megakernel_runs(wave, 1 << 18, 8), [wave]);
        // A deep one is split into runs of whole pixels within the bound
        let runs = megakernel_runs(wave, 1 << 18, 1000);
        let per_run = (1u64 << 18) * 16 / (64 * 1000);
        assert_eq!(runs.len() as u64, 4096u64.div_ceil(per_run));
        let mut next = wave.pixel_base;
        for r in &runs {
            assert_eq!((r.pixel_base, r.sample_base, r.samples), (next, 8, 64));
            assert!(u64::from(r.paths()) * 1000 <= (1 << 18) * 16);
            next += r.pixels;
        }
        assert_eq!(next, wave.pixel_base + wave.pixels);
        // One pixel per run at least, however deep
        assert_eq!(megakernel_runs(wave, 1, u32::MAX).len(), 4096);
    }
}
