//! Storage buffers and host transfers.

use std::fmt;
use std::ptr::NonNull;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::context::{lock, Context, Inner};
use super::error::{VkError, VkResult};
use super::memory::memory_type_for;

/// Most bytes a staging or readback buffer holds: a transfer larger than
/// this (a film band of an 8K image is 1 GiB on a GPU that binds it whole)
/// goes through one such buffer in chunks, so that reading or writing a
/// buffer never needs device memory for a second copy of it.
pub const STAGING_CHUNK_BYTES: u64 = 64 << 20;

/// Where a buffer's memory lives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MemoryKind {
    /// Device-local memory: fastest for shaders; maybe not host visible.
    Device,
    /// Host-visible memory the host writes and the device reads.
    Upload,
    /// Host-visible, cached memory the device writes and the host reads.
    Readback,
}

impl MemoryKind {
    fn location(self) -> MemoryLocation {
        match self {
            MemoryKind::Device => MemoryLocation::GpuOnly,
            MemoryKind::Upload => MemoryLocation::CpuToGpu,
            MemoryKind::Readback => MemoryLocation::GpuToCpu,
        }
    }
}

/// The buffer proper; shared by the [`Buffer`], the [`super::Bindings`] that
/// bind it and the recorders that use it, so it outlives all their GPU use.
pub(crate) struct BufferShared {
    pub(crate) inner: Arc<Inner>,
    pub(crate) handle: vk::Buffer,
    allocation: Option<Allocation>,
    pub(crate) size: u64,
    pub(crate) label: String,
    kind: MemoryKind,
    /// The memory heap the allocation comes from (its budget is charged).
    heap: usize,
}

impl BufferShared {
    /// The host address of the buffer's memory, when it is mapped and coherent.
    fn mapped(&self) -> Option<NonNull<u8>> {
        let a = self.allocation.as_ref()?;
        if !a
            .memory_properties()
            .contains(vk::MemoryPropertyFlags::HOST_COHERENT)
        {
            return None;
        }
        a.mapped_ptr().map(|p| p.cast::<u8>())
    }
}

impl Drop for BufferShared {
    fn drop(&mut self) {
        // SAFETY: the buffer belongs to inner's device, which is alive (we hold
        // an Arc). No GPU work uses it: every submit waits for completion and
        // recorders/bindings keep this object alive while they reference it.
        unsafe { self.inner.device().destroy_buffer(self.handle, None) };
        if let Some(a) = self.allocation.take() {
            let _ = self.inner.allocator().free(a);
            self.inner.memory_used[self.heap].fetch_sub(self.size, Ordering::Relaxed);
        }
    }
}

/// A storage buffer (usage STORAGE | TRANSFER_SRC | TRANSFER_DST | INDIRECT)
/// with its memory. Freed on drop; [`super::Bindings`] that bind it keep it
/// alive until they are dropped too.
pub struct Buffer {
    pub(crate) shared: Arc<BufferShared>,
}

impl Buffer {
    /// Size in bytes (a requested size of 0 becomes 16).
    pub fn size(&self) -> u64 {
        self.shared.size
    }

    /// The label given at creation.
    pub fn label(&self) -> &str {
        &self.shared.label
    }

    /// Where the memory lives.
    pub fn memory_kind(&self) -> MemoryKind {
        self.shared.kind
    }
}

impl fmt::Debug for Buffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Buffer")
            .field("label", &self.shared.label)
            .field("size", &self.shared.size)
            .field("kind", &self.shared.kind)
            .finish()
    }
}

/// Checks `offset..offset+len` lies in `buf`.
pub(crate) fn check_range(what: &str, buf: &BufferShared, offset: u64, len: u64) -> VkResult<()> {
    match offset.checked_add(len) {
        Some(end) if end <= buf.size => Ok(()),
        _ => Err(VkError::Usage(format!(
            "{what}: range {offset}..+{len} is outside buffer {:?} of {} bytes",
            buf.label, buf.size
        ))),
    }
}

impl Context {
    /// Creates a storage (and uniform texel) buffer of `size` bytes (0 becomes 16, so empty arrays
    /// can be bound). `label` names both the allocation and the VkBuffer.
    /// Fails with [`VkError::BufferTooLarge`] above `maxStorageBufferRange`.
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn create_buffer(&self, label: &str, size: u64, location: MemoryKind) -> VkResult<Buffer> {
        let size = if size == 0 { 16 } else { size };
        let limit = self.info.max_storage_buffer_range;
        if size > limit {
            return Err(VkError::BufferTooLarge {
                label: label.to_string(),
                size,
                limit,
            });
        }
        let device = self.inner.device();
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(
                vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                    | vk::BufferUsageFlags::TRANSFER_SRC
                    | vk::BufferUsageFlags::TRANSFER_DST
                    | vk::BufferUsageFlags::INDIRECT_BUFFER,
            )
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info on a live device.
        let handle = unsafe { device.create_buffer(&info, None) }
            .map_err(VkError::call("vkCreateBuffer"))?;
        // From here on `shared` owns the handle and frees it on any error.
        let mut shared = BufferShared {
            inner: self.inner.clone(),
            handle,
            allocation: None,
            size,
            label: label.to_string(),
            kind: location,
            heap: 0,
        };
        // SAFETY: handle is a live buffer of this device.
        let requirements = unsafe { device.get_buffer_memory_requirements(handle) };
        // Charge the heap gpu-allocator will take the memory from; refuse
        // what does not fit its budget before the driver is asked.
        let memory_type = memory_type_for(
            &self.inner.memory_types,
            requirements.memory_type_bits,
            location.location(),
        );
        if let Some(t) = memory_type {
            let heap = self.inner.memory_types[t].heap as usize;
            let budget = self.inner.memory_budgets[heap];
            let used = self.inner.memory_used[heap].load(Ordering::Relaxed);
            if used.saturating_add(size) > budget.bytes {
                return Err(VkError::OverBudget {
                    label: label.to_string(),
                    size,
                    used,
                    budget,
                });
            }
            shared.heap = heap;
        }
        // The allocator lock is released at the end of this statement, before
        // `shared` can drop (and lock it again to free) on the error path.
        let allocated = self.inner.allocator().allocate(&AllocationCreateDesc {
            name: label,
            requirements,
            location: location.location(),
            linear: true,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        });
        let allocation = allocated.map_err(|source| VkError::Alloc {
            label: label.to_string(),
            source,
        })?;
        // SAFETY: the allocation was made for this buffer's requirements and
        // stays alive (owned by `shared`) as long as the buffer.
        let bound =
            unsafe { device.bind_buffer_memory(handle, allocation.memory(), allocation.offset()) };
        shared.allocation = Some(allocation);
        self.inner.memory_used[shared.heap].fetch_add(size, Ordering::Relaxed);
        let now = self.memory_in_use();
        self.inner.memory_peak.fetch_max(now, Ordering::Relaxed);
        bound.map_err(VkError::call("vkBindBufferMemory"))?;
        self.inner.set_name(handle, label);
        Ok(Buffer {
            shared: Arc::new(shared),
        })
    }

    /// Creates a device-local buffer holding `data`: copied through a staging
    /// buffer and a one-shot command buffer, or directly when the memory is
    /// host visible.
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn upload<T: bytemuck::Pod>(&self, label: &str, data: &[T]) -> VkResult<Buffer> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let buf = self.create_buffer(label, bytes.len() as u64, MemoryKind::Device)?;
        self.write_bytes(&buf, 0, bytes)?;
        Ok(buf)
    }

    /// Writes `data` into `buf` at byte `offset`, waiting until it is done.
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn write<T: bytemuck::Pod>(&self, buf: &Buffer, offset: u64, data: &[T]) -> VkResult<()> {
        self.write_bytes(buf, offset, bytemuck::cast_slice(data))
    }

    /// Reads the whole of `buf` as `T`s (`size / size_of::<T>()` of them).
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn read<T: bytemuck::Pod>(&self, buf: &Buffer) -> VkResult<Vec<T>> {
        let elem = std::mem::size_of::<T>() as u64;
        if elem == 0 {
            return Ok(Vec::new());
        }
        let n = buf.size() / elem;
        let len = n * elem;
        let mut out: Vec<T> = vec![<T as bytemuck::Zeroable>::zeroed(); n as usize];
        if len == 0 {
            return Ok(out);
        }
        let dst: &mut [u8] = bytemuck::cast_slice_mut(&mut out);
        if let Some(src) = self.host_mapped(&buf.shared) {
            // Holding the queue lock: no GPU work of this device is in flight.
            let _queue = lock(&self.inner.queue);
            // SAFETY: the mapping covers the buffer's `size` bytes, len <= size,
            // and the destination is a distinct Vec of len bytes.
            unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), dst.as_mut_ptr(), dst.len()) };
            return Ok(out);
        }
        // Through one readback buffer of at most STAGING_CHUNK_BYTES, a
        // chunk at a time: reading a film band does not need its size again
        let chunk = len.min(STAGING_CHUNK_BYTES);
        let staging = self.create_buffer(
            &format!("{} (readback)", buf.label()),
            chunk,
            MemoryKind::Readback,
        )?;
        let src = staging.shared.mapped().ok_or_else(|| {
            VkError::Usage(format!(
                "readback buffer for {:?} is not mapped",
                buf.label()
            ))
        })?;
        for (at, part) in (0..len)
            .step_by(chunk as usize)
            .zip(dst.chunks_mut(chunk as usize))
        {
            let mut rec = self.begin("read", 0)?;
            rec.copy_buffer(buf, at, &staging, 0, part.len() as u64);
            self.submit(rec)?;
            // SAFETY: the staging mapping holds the part.len() <= chunk bytes
            // the completed copy wrote; nothing else uses the staging buffer.
            unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), part.as_mut_ptr(), part.len()) };
        }
        Ok(out)
    }

    /// The host mapping of `buf` when direct host transfers are allowed.
    fn host_mapped(&self, buf: &BufferShared) -> Option<NonNull<u8>> {
        if self.host_mapped_transfers {
            buf.mapped()
        } else {
            None
        }
    }

    /// Writes bytes into `buf` at `offset`, waiting until it is done.
    pub(crate) fn write_bytes(&self, buf: &Buffer, offset: u64, bytes: &[u8]) -> VkResult<()> {
        let len = bytes.len() as u64;
        check_range("write", &buf.shared, offset, len)?;
        if len == 0 {
            return Ok(());
        }
        if let Some(dst) = self.host_mapped(&buf.shared) {
            // Holding the queue lock: no GPU work of this device is in flight.
            let _queue = lock(&self.inner.queue);
            // SAFETY: offset + len <= size (checked above) and the mapping
            // covers the whole buffer; `bytes` is a distinct host slice.
            unsafe {
                std::ptr::copy_nonoverlapping(
                    bytes.as_ptr(),
                    dst.as_ptr().add(offset as usize),
                    bytes.len(),
                )
            };
            return Ok(());
        }
        // Through one staging buffer of at most STAGING_CHUNK_BYTES, a chunk
        // at a time
        let chunk = len.min(STAGING_CHUNK_BYTES);
        let staging = self.create_buffer(
            &format!("{} (staging)", buf.label()),
            chunk,
            MemoryKind::Upload,
        )?;
        let dst = staging.shared.mapped().ok_or_else(|| {
            VkError::Usage(format!(
                "staging buffer for {:?} is not mapped",
                buf.label()
            ))
        })?;
        for (at, part) in (0..len)
            .step_by(chunk as usize)
            .zip(bytes.chunks(chunk as usize))
        {
            // SAFETY: the staging buffer is mapped and at least part.len()
            // bytes long, and the GPU is done with it: each copy from it
            // completes (submit waits) before the next chunk is written.
            unsafe { std::ptr::copy_nonoverlapping(part.as_ptr(), dst.as_ptr(), part.len()) };
            let mut rec = self.begin("write", 0)?;
            rec.copy_buffer(&staging, 0, buf, offset + at, part.len() as u64);
            self.submit(rec)?;
        }
        Ok(())
    }
}
