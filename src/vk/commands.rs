//! Command recording, submission and GPU timestamps.

use std::any::Any;
use std::sync::Arc;

use ash::vk;

use super::buffer::{check_range, Buffer};
use super::context::{cstring, lock, Context, Inner};
use super::error::{VkError, VkResult};
use super::pipeline::{Bindings, ComputePipeline};

/// Largest `max_timed_dispatches` accepted by [`Context::begin`].
pub const MAX_TIMED_DISPATCHES: u32 = 1 << 20;

/// A reusable command pool + command buffer + fence + timestamp query pool.
/// Each recorder takes one, so recorders never share a command pool.
pub(crate) struct Frame {
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    query_pool: vk::QueryPool,
    query_capacity: u32,
}

impl Frame {
    fn new(ctx: &Context) -> VkResult<Frame> {
        let device = ctx.inner.device();
        let pool_info = vk::CommandPoolCreateInfo::default()
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER)
            .queue_family_index(ctx.queue_family);
        // SAFETY: valid create info on a live device.
        let pool = unsafe { device.create_command_pool(&pool_info, None) }
            .map_err(VkError::call("vkCreateCommandPool"))?;
        // `frame` owns what exists so far; dropping it on error would leak, so
        // errors below destroy it explicitly.
        let mut frame = Frame {
            pool,
            cmd: vk::CommandBuffer::null(),
            fence: vk::Fence::null(),
            query_pool: vk::QueryPool::null(),
            query_capacity: 0,
        };
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool is live and externally synchronised (owned here).
        match unsafe { device.allocate_command_buffers(&alloc) } {
            Ok(cmds) => frame.cmd = cmds[0],
            Err(r) => {
                frame.destroy(device);
                return Err(VkError::call("vkAllocateCommandBuffers")(r));
            }
        }
        // SAFETY: valid create info on a live device.
        match unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => frame.fence = f,
            Err(r) => {
                frame.destroy(device);
                return Err(VkError::call("vkCreateFence")(r));
            }
        }
        Ok(frame)
    }

    /// Destroys the frame's objects. None may be in use by the GPU.
    pub(crate) fn destroy(self, device: &ash::Device) {
        // SAFETY: all objects belong to `device` and are idle (callers wait for
        // the device or never submitted); null handles are ignored by Vulkan.
        unsafe {
            device.destroy_query_pool(self.query_pool, None);
            device.destroy_fence(self.fence, None);
            device.destroy_command_pool(self.pool, None);
        }
    }
}

/// GPU time of one timed dispatch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DispatchTiming {
    /// The pass name given to [`Recorder::dispatch`], e.g. `"intersect"`.
    pub label: &'static str,
    /// The step of a repeated dispatch given with it (the caller's loop index), if any.
    pub step: Option<u32>,
    /// Nanoseconds between the timestamps around the dispatch (0 when
    /// timestamps are unsupported).
    pub gpu_ns: u64,
    /// When the dispatch started, on the device's timestamp clock, in
    /// nanoseconds (0 when timestamps are not supported). Only differences
    /// between values of one device are meaningful.
    pub start_ns: u64,
}

/// GPU times of the timed dispatches of one submission, in recording order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Timings {
    /// One entry per timed dispatch (the first `max_timed_dispatches`).
    pub dispatches: Vec<DispatchTiming>,
    /// Whether the queue supports timestamps; if not, every `gpu_ns` is 0.
    pub supported: bool,
    /// Dispatches recorded past `max_timed_dispatches`, which were not timed.
    pub untimed: u32,
}

/// Records one command buffer; get one from [`Context::begin`], hand it to
/// [`Context::submit`].
///
/// Recording never fails on the spot: a misuse (out-of-range copy, wrong
/// push-constant size, resources of another context, ...) is remembered, the
/// rest of the recording is skipped, and `submit` returns the error without
/// submitting. Resources used are kept alive until the recorder is gone, so
/// dropping a buffer after recording it is safe.
pub struct Recorder<'a> {
    ctx: &'a Context,
    frame: Option<Frame>,
    max_timed: u32,
    queries: u32,
    timed: Vec<(&'static str, Option<u32>)>,
    untimed: u32,
    keep: Vec<Arc<dyn Any + Send + Sync>>,
    error: Option<VkError>,
}

/// What a dispatch launches.
enum Launch<'b> {
    Direct([u32; 3]),
    Indirect(&'b Buffer, u64),
}

impl Recorder<'_> {
    /// The command buffer, unless recording already failed.
    fn cmd(&self) -> Option<vk::CommandBuffer> {
        if self.error.is_some() {
            return None;
        }
        self.frame.as_ref().map(|f| f.cmd)
    }

    fn fail(&mut self, msg: String) {
        if self.error.is_none() {
            self.error = Some(VkError::Usage(msg));
        }
    }

    fn same_device(&mut self, inner: &Arc<Inner>, what: &str) -> bool {
        if Arc::ptr_eq(inner, &self.ctx.inner) {
            true
        } else {
            self.fail(format!("{what} belongs to another Vulkan context"));
            false
        }
    }

    /// Records a compute dispatch of `groups` workgroups, timed (if within
    /// `max_timed_dispatches`) and wrapped in a debug label `"{label}"` or
    /// `"{label}[{step}]"`. `push` must be exactly the pipeline's
    /// push-constant size.
    pub fn dispatch(
        &mut self,
        label: &'static str,
        step: Option<u32>,
        pipeline: &ComputePipeline,
        bindings: &Bindings,
        push: &[u8],
        groups: [u32; 3],
    ) {
        let launch = Launch::Direct(groups);
        self.dispatch_common(label, step, pipeline, bindings, push, launch);
    }

    /// Like [`Recorder::dispatch`], with the workgroup counts read on the GPU
    /// from three u32s at byte `offset` of `args` (`vkCmdDispatchIndirect`).
    #[allow(clippy::too_many_arguments)]
    pub fn dispatch_indirect(
        &mut self,
        label: &'static str,
        step: Option<u32>,
        pipeline: &ComputePipeline,
        bindings: &Bindings,
        push: &[u8],
        args: &Buffer,
        offset: u64,
    ) {
        let launch = Launch::Indirect(args, offset);
        self.dispatch_common(label, step, pipeline, bindings, push, launch);
    }

    fn dispatch_common(
        &mut self,
        label: &'static str,
        step: Option<u32>,
        pipeline: &ComputePipeline,
        bindings: &Bindings,
        push: &[u8],
        launch: Launch<'_>,
    ) {
        let Some(cmd) = self.cmd() else { return };
        let name = match step {
            Some(t) => format!("{label}[{t}]"),
            None => label.to_string(),
        };
        let p = &pipeline.shared;
        let b = &bindings.shared;
        if !self.same_device(&p.inner, "pipeline") || !self.same_device(&b.inner, "bindings") {
            return;
        }
        if p.signature != b.signature {
            return self.fail(format!(
                "dispatch {name}: pipeline {:?} was built for bindings {:?}, but bindings {:?} has {:?}",
                p.label, p.signature, b.label, b.signature
            ));
        }
        if push.len() != p.push_constant_bytes as usize {
            return self.fail(format!(
                "dispatch {name}: {} bytes of push constants given, pipeline {:?} takes {}",
                push.len(),
                p.label,
                p.push_constant_bytes
            ));
        }
        match launch {
            Launch::Direct(groups) => {
                let max = self.ctx.info.max_compute_workgroup_count;
                if groups.iter().zip(max).any(|(g, m)| *g > m) {
                    return self.fail(format!(
                        "dispatch {name}: {groups:?} workgroups exceed the device limit {max:?}"
                    ));
                }
            }
            Launch::Indirect(args, offset) => {
                if !self.same_device(&args.shared.inner, "indirect buffer") {
                    return;
                }
                if !offset.is_multiple_of(4) {
                    return self.fail(format!(
                        "dispatch {name}: indirect offset {offset} is not a multiple of 4"
                    ));
                }
                if let Err(e) = check_range(&format!("dispatch {name}"), &args.shared, offset, 12) {
                    self.error = Some(e);
                    return;
                }
            }
        }

        let slot = self.timed.len() as u32;
        let timed = slot < self.max_timed;
        let query_pool = self.frame.as_ref().map(|f| f.query_pool);
        let timestamp_pool = query_pool.filter(|_| timed && self.queries > 0);
        let inner = &self.ctx.inner;
        let device = inner.device();
        // SAFETY: cmd is in the recording state (begun in Context::begin and
        // only ended in submit); every handle is a live object of this device,
        // checked above and kept alive by `self.keep` until after completion.
        // Push size and ranges were checked against the pipeline and buffers.
        unsafe {
            if let Some(du) = &inner.debug_device {
                let cname = cstring(&name);
                du.cmd_begin_debug_utils_label(
                    cmd,
                    &vk::DebugUtilsLabelEXT::default().label_name(&cname),
                );
            }
            device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, p.pipeline);
            device.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                p.layout,
                0,
                &[b.set],
                &[],
            );
            if !push.is_empty() {
                device.cmd_push_constants(cmd, p.layout, vk::ShaderStageFlags::COMPUTE, 0, push);
            }
            if let Some(qp) = timestamp_pool {
                device.cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, qp, 2 * slot);
            }
            match launch {
                Launch::Direct([x, y, z]) => device.cmd_dispatch(cmd, x, y, z),
                Launch::Indirect(args, offset) => {
                    device.cmd_dispatch_indirect(cmd, args.shared.handle, offset)
                }
            }
            if let Some(qp) = timestamp_pool {
                device.cmd_write_timestamp(
                    cmd,
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    qp,
                    2 * slot + 1,
                );
            }
            if let Some(du) = &inner.debug_device {
                du.cmd_end_debug_utils_label(cmd);
            }
        }
        if timed {
            self.timed.push((label, step));
        } else {
            self.untimed += 1;
        }
        self.keep.push(pipeline.shared.clone());
        self.keep.push(bindings.shared.clone());
        if let Launch::Indirect(args, _) = launch {
            self.keep.push(args.shared.clone());
        }
    }

    /// A full memory barrier between compute, indirect and transfer work:
    /// SHADER_WRITE | TRANSFER_WRITE before it are visible to SHADER_READ |
    /// SHADER_WRITE | INDIRECT_COMMAND_READ | TRANSFER_READ | TRANSFER_WRITE after it.
    pub fn barrier(&mut self) {
        let Some(cmd) = self.cmd() else { return };
        let barrier = [vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(
                vk::AccessFlags::SHADER_READ
                    | vk::AccessFlags::SHADER_WRITE
                    | vk::AccessFlags::INDIRECT_COMMAND_READ
                    | vk::AccessFlags::TRANSFER_READ
                    | vk::AccessFlags::TRANSFER_WRITE,
            )];
        // SAFETY: cmd is recording; the barrier only names stages a compute
        // queue supports.
        unsafe {
            self.ctx.inner.device().cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COMPUTE_SHADER
                    | vk::PipelineStageFlags::DRAW_INDIRECT
                    | vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &barrier,
                &[],
                &[],
            )
        };
    }

    /// Writes `data` into `buf` at `offset` on the GPU timeline
    /// (`vkCmdUpdateBuffer`): at most 65536 bytes, offset and length multiples of 4.
    pub fn update_buffer(&mut self, buf: &Buffer, offset: u64, data: &[u8]) {
        let Some(cmd) = self.cmd() else { return };
        if !self.same_device(&buf.shared.inner, "buffer") || data.is_empty() {
            return;
        }
        if data.len() > 65536 || !data.len().is_multiple_of(4) || !offset.is_multiple_of(4) {
            return self.fail(format!(
                "update_buffer {:?}: {} bytes at offset {offset}; need at most 65536 bytes \
                 and offset and length multiples of 4",
                buf.label(),
                data.len()
            ));
        }
        if let Err(e) = check_range("update_buffer", &buf.shared, offset, data.len() as u64) {
            self.error = Some(e);
            return;
        }
        // SAFETY: cmd is recording; the range was checked; the buffer is kept alive.
        unsafe {
            self.ctx
                .inner
                .device()
                .cmd_update_buffer(cmd, buf.shared.handle, offset, data)
        };
        self.keep.push(buf.shared.clone());
    }

    /// Fills `size` bytes of `buf` from `offset` with the u32 `value`
    /// (`vkCmdFillBuffer`); `size` may be `ash::vk::WHOLE_SIZE` for the rest of the buffer.
    pub fn fill_buffer(&mut self, buf: &Buffer, offset: u64, size: u64, value: u32) {
        let Some(cmd) = self.cmd() else { return };
        if !self.same_device(&buf.shared.inner, "buffer") || size == 0 {
            return;
        }
        let checked = if size == vk::WHOLE_SIZE {
            buf.size().saturating_sub(offset)
        } else {
            size
        };
        if !offset.is_multiple_of(4)
            || (size != vk::WHOLE_SIZE && !size.is_multiple_of(4))
            || checked < 4
        {
            return self.fail(format!(
                "fill_buffer {:?}: offset {offset} and size {size} must be multiples of 4 \
                 covering at least 4 bytes",
                buf.label()
            ));
        }
        if let Err(e) = check_range("fill_buffer", &buf.shared, offset, checked) {
            self.error = Some(e);
            return;
        }
        // SAFETY: cmd is recording; the range was checked; the buffer is kept alive.
        unsafe {
            self.ctx
                .inner
                .device()
                .cmd_fill_buffer(cmd, buf.shared.handle, offset, size, value)
        };
        self.keep.push(buf.shared.clone());
    }

    /// Copies `size` bytes from `src` at `src_offset` to `dst` at `dst_offset`.
    /// Ranges in the same buffer must not overlap.
    pub fn copy_buffer(
        &mut self,
        src: &Buffer,
        src_offset: u64,
        dst: &Buffer,
        dst_offset: u64,
        size: u64,
    ) {
        let Some(cmd) = self.cmd() else { return };
        if !self.same_device(&src.shared.inner, "buffer")
            || !self.same_device(&dst.shared.inner, "buffer")
            || size == 0
        {
            return;
        }
        for (what, buf, off) in [
            ("copy source", src, src_offset),
            ("copy target", dst, dst_offset),
        ] {
            if let Err(e) = check_range(what, &buf.shared, off, size) {
                self.error = Some(e);
                return;
            }
        }
        if Arc::ptr_eq(&src.shared, &dst.shared)
            && src_offset < dst_offset + size
            && dst_offset < src_offset + size
        {
            return self.fail(format!(
                "copy_buffer {:?}: overlapping ranges {src_offset}..+{size} and {dst_offset}..+{size}",
                src.label()
            ));
        }
        let region = [vk::BufferCopy {
            src_offset,
            dst_offset,
            size,
        }];
        // SAFETY: cmd is recording; ranges were checked; buffers are kept alive.
        unsafe {
            self.ctx.inner.device().cmd_copy_buffer(
                cmd,
                src.shared.handle,
                dst.shared.handle,
                &region,
            )
        };
        self.keep.push(src.shared.clone());
        self.keep.push(dst.shared.clone());
    }
}

impl Drop for Recorder<'_> {
    fn drop(&mut self) {
        // Hand the frame back for reuse. A frame that was never submitted is
        // still recording; begin() resets it before reuse.
        if let Some(frame) = self.frame.take() {
            lock(&self.ctx.frames).push(frame);
        }
    }
}

impl Context {
    /// Starts recording a command buffer named `label`, with timestamps for up
    /// to `max_timed_dispatches` dispatches. Command buffers, fences and query
    /// pools are reused between submissions.
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn begin(&self, label: &str, max_timed_dispatches: u32) -> VkResult<Recorder<'_>> {
        if max_timed_dispatches > MAX_TIMED_DISPATCHES {
            return Err(VkError::Usage(format!(
                "begin {label:?}: max_timed_dispatches {max_timed_dispatches} exceeds \
                 {MAX_TIMED_DISPATCHES}"
            )));
        }
        let frame = lock(&self.frames).pop();
        let frame = match frame {
            Some(f) => f,
            None => Frame::new(self)?,
        };
        let queries = if self.timestamp_mask != 0 {
            2 * max_timed_dispatches
        } else {
            0
        };
        let mut rec = Recorder {
            ctx: self,
            frame: Some(frame),
            max_timed: max_timed_dispatches,
            queries,
            timed: Vec::new(),
            untimed: 0,
            keep: Vec::new(),
            error: None,
        };
        if let Some(frame) = rec.frame.as_mut() {
            // On error `rec` drops and returns the frame for reuse.
            self.prepare(frame, label, queries)?;
        }
        Ok(rec)
    }

    /// Makes `frame` ready: query pool large enough, command buffer reset and
    /// begun, queries reset, debug label opened, and a leading barrier against
    /// earlier submissions.
    fn prepare(&self, frame: &mut Frame, label: &str, queries: u32) -> VkResult<()> {
        let inner = &self.inner;
        let device = inner.device();
        if queries > frame.query_capacity {
            // SAFETY: the frame is not in use by the GPU (its submit waited);
            // destroying a null handle is a no-op.
            unsafe { device.destroy_query_pool(frame.query_pool, None) };
            frame.query_pool = vk::QueryPool::null();
            frame.query_capacity = 0;
            let info = vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::TIMESTAMP)
                .query_count(queries);
            // SAFETY: valid create info on a live device.
            frame.query_pool = unsafe { device.create_query_pool(&info, None) }
                .map_err(VkError::call("vkCreateQueryPool"))?;
            frame.query_capacity = queries;
            inner.set_name(frame.query_pool, "lancer timestamps");
        }
        inner.set_name(frame.cmd, label);
        let cmd = frame.cmd;
        // SAFETY: the command buffer is not pending (every submit waits for its
        // fence) and its pool, owned by the frame, is used by this thread only.
        unsafe {
            device
                .reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .map_err(VkError::call("vkResetCommandBuffer"))?;
            device
                .begin_command_buffer(
                    cmd,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .map_err(VkError::call("vkBeginCommandBuffer"))?;
            if queries > 0 {
                device.cmd_reset_query_pool(cmd, frame.query_pool, 0, queries);
            }
            if let Some(du) = &inner.debug_device {
                let cname = cstring(label);
                du.cmd_begin_debug_utils_label(
                    cmd,
                    &vk::DebugUtilsLabelEXT::default().label_name(&cname),
                );
            }
            // Make writes of earlier submissions visible to this one.
            let barrier = [vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::MEMORY_WRITE)
                .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE)];
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::DependencyFlags::empty(),
                &barrier,
                &[],
                &[],
            );
        }
        Ok(())
    }

    /// Ends the recording, submits it, waits for it to finish and returns the
    /// GPU times of the timed dispatches. Returns the first recording misuse,
    /// if any, without submitting.
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn submit(&self, mut rec: Recorder<'_>) -> VkResult<Timings> {
        if !std::ptr::eq(rec.ctx, self) {
            return Err(VkError::Usage(
                "submit: the recorder belongs to another Vulkan context".to_string(),
            ));
        }
        if let Some(e) = rec.error.take() {
            return Err(e);
        }
        let Some(frame) = rec.frame.as_ref() else {
            return Err(VkError::Usage(
                "submit: recorder has no command buffer".into(),
            ));
        };
        let inner = &self.inner;
        let device = inner.device();
        let cmd = frame.cmd;
        // SAFETY: cmd is recording (begun in `begin`); the barrier makes all
        // writes visible to the host once the fence has signalled.
        unsafe {
            if let Some(du) = &inner.debug_device {
                du.cmd_end_debug_utils_label(cmd);
            }
            let barrier = [vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::HOST_READ)];
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &barrier,
                &[],
                &[],
            );
            device
                .end_command_buffer(cmd)
                .map_err(VkError::call("vkEndCommandBuffer"))?;
        }
        {
            // Held until the work is done: host access to mapped memory takes
            // this lock, so it never races GPU work.
            let queue = lock(&inner.queue);
            let cmds = [cmd];
            let submits = [vk::SubmitInfo::default().command_buffers(&cmds)];
            let fences = [frame.fence];
            // SAFETY: the command buffer is executable, the fence unsignalled
            // and unused, and the queue is locked.
            unsafe {
                device
                    .queue_submit(*queue, &submits, frame.fence)
                    .map_err(VkError::call("vkQueueSubmit"))?;
                device
                    .wait_for_fences(&fences, true, u64::MAX)
                    .map_err(VkError::call("vkWaitForFences"))?;
                device
                    .reset_fences(&fences)
                    .map_err(VkError::call("vkResetFences"))?;
            }
        }

        let n = rec.timed.len();
        let mut gpu_ns = vec![0u64; n];
        let mut start_ns = vec![0u64; n];
        if rec.queries > 0 && n > 0 {
            let mut ticks = vec![0u64; 2 * n];
            // SAFETY: queries 0..2n were reset and written in this submission,
            // which has completed; 64-bit results fit the u64 slice.
            unsafe {
                device.get_query_pool_results(
                    frame.query_pool,
                    0,
                    &mut ticks,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .map_err(VkError::call("vkGetQueryPoolResults"))?;
            let period = f64::from(self.info.timestamp_period_ns);
            for (i, ns) in gpu_ns.iter_mut().enumerate() {
                let delta = ticks[2 * i + 1].wrapping_sub(ticks[2 * i]) & self.timestamp_mask;
                *ns = (delta as f64 * period).round() as u64;
                start_ns[i] = ((ticks[2 * i] & self.timestamp_mask) as f64 * period).round() as u64;
            }
        }
        let dispatches = rec
            .timed
            .iter()
            .zip(gpu_ns.into_iter().zip(start_ns))
            .map(|(&(label, step), (gpu_ns, start_ns))| DispatchTiming {
                label,
                step,
                gpu_ns,
                start_ns,
            })
            .collect();
        Ok(Timings {
            dispatches,
            supported: self.timestamp_mask != 0,
            untimed: rec.untimed,
        })
        // `rec` drops here: the frame goes back to the pool and the resources
        // it kept alive are released.
    }
}
