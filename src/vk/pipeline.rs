//! Descriptor bindings, compute pipelines and the pipeline cache.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use ash::vk;

use super::buffer::{Buffer, BufferShared};
use super::context::{lock, Context, Inner};
use super::disk_cache::{self, PipelineCacheStats};
use super::error::{VkError, VkResult};

/// How a shader reads a bound buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum BindingKind {
    /// A storage buffer (`buffer` block in GLSL), read and written.
    Storage,
    /// A read-only uniform texel buffer of RGBA32UI texels (`usamplerBuffer`
    /// and `texelFetch` in GLSL): 16 bytes per texel, the buffer's size a
    /// multiple of 16. On llvmpipe a per-lane fetch from it is a gather,
    /// where a storage-buffer load is a per-lane loop with bounds checks.
    TexelRgba32Ui,
}

impl BindingKind {
    fn descriptor_type(self) -> vk::DescriptorType {
        match self {
            BindingKind::Storage => vk::DescriptorType::STORAGE_BUFFER,
            BindingKind::TexelRgba32Ui => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
        }
    }
}

/// Bytes per texel of [`BindingKind::TexelRgba32Ui`].
pub const TEXEL_BYTES: u64 = 16;

/// Descriptor set layout, pool and set. Keeps its buffers (and their texel
/// views) alive.
pub(crate) struct BindingsShared {
    pub(crate) inner: Arc<Inner>,
    pub(crate) layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    pub(crate) set: vk::DescriptorSet,
    /// Sorted binding numbers and kinds: pipelines built on one Bindings
    /// accept any Bindings with the same ones (identically defined layouts).
    pub(crate) signature: Vec<(u32, BindingKind)>,
    pub(crate) label: String,
    views: Vec<vk::BufferView>,
    _buffers: Vec<Arc<BufferShared>>,
}

impl Drop for BindingsShared {
    fn drop(&mut self) {
        let device = self.inner.device();
        // SAFETY: pool, layout and views belong to this live device; no GPU
        // work uses the set (submits wait; recorders keep this alive while
        // referenced). Destroying the pool frees the set.
        unsafe {
            device.destroy_descriptor_pool(self.pool, None);
            device.destroy_descriptor_set_layout(self.layout, None);
            for view in &self.views {
                device.destroy_buffer_view(*view, None);
            }
        }
    }
}

/// A descriptor set of whole buffers (storage or texel, per
/// [`BindingKind`]) for the compute stage.
/// Every pipeline uses one set (set 0); see [`Context::create_bindings`].
pub struct Bindings {
    pub(crate) shared: Arc<BindingsShared>,
}

impl Bindings {
    /// The label given at creation.
    pub fn label(&self) -> &str {
        &self.shared.label
    }
}

impl fmt::Debug for Bindings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Bindings")
            .field("label", &self.shared.label)
            .field("bindings", &self.shared.signature)
            .finish()
    }
}

/// Pipeline and pipeline layout.
pub(crate) struct PipelineShared {
    pub(crate) inner: Arc<Inner>,
    pub(crate) pipeline: vk::Pipeline,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) push_constant_bytes: u32,
    pub(crate) signature: Vec<(u32, BindingKind)>,
    pub(crate) label: String,
}

impl Drop for PipelineShared {
    fn drop(&mut self) {
        let device = self.inner.device();
        // SAFETY: both belong to this live device; no GPU work uses them
        // (submits wait; recorders keep this alive while referenced).
        unsafe {
            device.destroy_pipeline(self.pipeline, None);
            device.destroy_pipeline_layout(self.layout, None);
        }
    }
}

/// A compute pipeline (entry point `main`) with its layout: one descriptor set
/// and an optional push-constant block.
pub struct ComputePipeline {
    pub(crate) shared: Arc<PipelineShared>,
}

impl ComputePipeline {
    /// The label given at creation.
    pub fn label(&self) -> &str {
        &self.shared.label
    }

    /// Size of the push-constant block; every dispatch passes exactly this many bytes.
    pub fn push_constant_bytes(&self) -> u32 {
        self.shared.push_constant_bytes
    }
}

impl fmt::Debug for ComputePipeline {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ComputePipeline")
            .field("label", &self.shared.label)
            .field("push_constant_bytes", &self.shared.push_constant_bytes)
            .finish()
    }
}

/// Pipeline cache header, version one (Vulkan spec, "Pipeline Cache").
const CACHE_HEADER_BYTES: usize = 16 + vk::UUID_SIZE;

impl Context {
    /// Creates a descriptor set with one binding per entry, of the entry's
    /// kind, each bound to the whole buffer (a texel binding through an
    /// RGBA32UI view of it). The bindings keep their buffers alive.
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn create_bindings(
        &self,
        label: &str,
        buffers: &[(u32, &Buffer, BindingKind)],
    ) -> VkResult<Bindings> {
        let mut signature: Vec<(u32, BindingKind)> =
            buffers.iter().map(|(b, _, k)| (*b, *k)).collect();
        signature.sort_unstable();
        if signature.windows(2).any(|w| w[0].0 == w[1].0) {
            return Err(VkError::Usage(format!(
                "bindings {label:?}: a binding number is used twice ({signature:?})"
            )));
        }
        for (b, buf, kind) in buffers {
            if *kind == BindingKind::TexelRgba32Ui {
                let size = buf.shared.size;
                let texels = size / TEXEL_BYTES;
                if size % TEXEL_BYTES != 0 || texels > self.info.max_texel_buffer_elements {
                    return Err(VkError::Usage(format!(
                        "bindings {label:?}: binding {b} ({:?}) of {size} bytes is not a whole \
                         number of 16-byte texels within the device's {} \
                         (maxTexelBufferElements)",
                        buf.shared.label, self.info.max_texel_buffer_elements
                    )));
                }
            }
        }
        let device = self.inner.device();
        let layout_bindings: Vec<vk::DescriptorSetLayoutBinding> = buffers
            .iter()
            .map(|(b, _, k)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(*b)
                    .descriptor_type(k.descriptor_type())
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings);
        // SAFETY: valid create info on a live device.
        let layout = unsafe { device.create_descriptor_set_layout(&info, None) }
            .map_err(VkError::call("vkCreateDescriptorSetLayout"))?;
        let count =
            |kind: BindingKind| buffers.iter().filter(|(_, _, k)| *k == kind).count() as u32;
        let pool_sizes: Vec<vk::DescriptorPoolSize> =
            [BindingKind::Storage, BindingKind::TexelRgba32Ui]
                .into_iter()
                .filter(|k| count(*k) > 0)
                .map(|k| {
                    vk::DescriptorPoolSize::default()
                        .ty(k.descriptor_type())
                        .descriptor_count(count(k))
                })
                .collect();
        let fallback = [vk::DescriptorPoolSize::default()
            .ty(vk::DescriptorType::STORAGE_BUFFER)
            .descriptor_count(1)];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(if pool_sizes.is_empty() {
                &fallback
            } else {
                &pool_sizes
            });
        // SAFETY: valid create info on a live device.
        let pool = match unsafe { device.create_descriptor_pool(&pool_info, None) } {
            Ok(p) => p,
            Err(r) => {
                // SAFETY: the layout was just created and is unused.
                unsafe { device.destroy_descriptor_set_layout(layout, None) };
                return Err(VkError::call("vkCreateDescriptorPool")(r));
            }
        };
        // From here on `shared` owns layout, pool and views.
        let mut shared = BindingsShared {
            inner: self.inner.clone(),
            layout,
            pool,
            set: vk::DescriptorSet::null(),
            signature,
            label: label.to_string(),
            views: Vec::new(),
            _buffers: buffers.iter().map(|(_, b, _)| b.shared.clone()).collect(),
        };
        let layouts = [layout];
        let alloc_info = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool)
            .set_layouts(&layouts);
        // SAFETY: the pool has room for exactly this set.
        let sets = unsafe { device.allocate_descriptor_sets(&alloc_info) }
            .map_err(VkError::call("vkAllocateDescriptorSets"))?;
        shared.set = sets[0];

        // One RGBA32UI view per texel binding, in the order of `buffers`
        let mut views = Vec::with_capacity(buffers.len());
        for (b, buf, kind) in buffers {
            if *kind != BindingKind::TexelRgba32Ui {
                views.push(vk::BufferView::null());
                continue;
            }
            let view_info = vk::BufferViewCreateInfo::default()
                .buffer(buf.shared.handle)
                .format(vk::Format::R32G32B32A32_UINT)
                .offset(0)
                .range(vk::WHOLE_SIZE);
            // SAFETY: the buffer is live, was created with UNIFORM_TEXEL_BUFFER
            // usage, and holds a whole number of texels within
            // maxTexelBufferElements (checked above); RGBA32UI uniform texel
            // buffers are a format feature every Vulkan device has.
            let view = unsafe { device.create_buffer_view(&view_info, None) }
                .map_err(VkError::call("vkCreateBufferView"))?;
            shared.views.push(view);
            self.inner
                .set_name(view, &format!("{label} binding {b} texels"));
            views.push(view);
        }

        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = buffers
            .iter()
            .map(|(_, buf, _)| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(buf.shared.handle)
                    .offset(0)
                    .range(vk::WHOLE_SIZE)]
            })
            .collect();
        let view_slices: Vec<[vk::BufferView; 1]> = views.iter().map(|v| [*v]).collect();
        let writes: Vec<vk::WriteDescriptorSet> = buffers
            .iter()
            .zip(infos.iter().zip(&view_slices))
            .map(|((b, _, kind), (info, view))| {
                let write = vk::WriteDescriptorSet::default()
                    .dst_set(shared.set)
                    .dst_binding(*b)
                    .descriptor_type(kind.descriptor_type());
                match kind {
                    BindingKind::Storage => write.buffer_info(info),
                    BindingKind::TexelRgba32Ui => write.texel_buffer_view(view),
                }
            })
            .collect();
        // SAFETY: the set, bindings, buffers and views are live; each buffer
        // is at most maxStorageBufferRange long (checked at creation) and each
        // texel view within maxTexelBufferElements (checked above).
        unsafe { device.update_descriptor_sets(&writes, &[]) };

        self.inner.set_name(layout, &format!("{label} layout"));
        self.inner.set_name(shared.set, label);
        Ok(Bindings {
            shared: Arc::new(shared),
        })
    }

    /// Creates a compute pipeline from SPIR-V (entry point `main`) with the
    /// layout of `bindings` (set 0) and `push_constant_bytes` of push constants
    /// (0 for none). `spec` sets specialisation constants, each a 4-byte u32
    /// (GLSL `bool` and `uint` constants both take one). Uses the persistent
    /// pipeline cache when there is one (see [`Context::set_pipeline_cache_dir`]).
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn create_pipeline(
        &self,
        label: &str,
        spirv: &[u8],
        bindings: &Bindings,
        spec: &[(u32, u32)],
        push_constant_bytes: u32,
    ) -> VkResult<ComputePipeline> {
        if !push_constant_bytes.is_multiple_of(4)
            || push_constant_bytes > self.max_push_constants_size
        {
            return Err(VkError::Usage(format!(
                "pipeline {label:?}: {push_constant_bytes} bytes of push constants; \
                 need a multiple of 4 and at most {} on this device",
                self.max_push_constants_size
            )));
        }
        let mut ids: Vec<u32> = spec.iter().map(|(id, _)| *id).collect();
        ids.sort_unstable();
        if ids.windows(2).any(|w| w[0] == w[1]) {
            return Err(VkError::Usage(format!(
                "pipeline {label:?}: a specialisation constant id is set twice"
            )));
        }
        let words = ash::util::read_spv(&mut std::io::Cursor::new(spirv)).map_err(|e| {
            VkError::InvalidSpirv {
                label: label.to_string(),
                reason: e.to_string(),
            }
        })?;
        if words.first() != Some(&0x0723_0203) {
            return Err(VkError::InvalidSpirv {
                label: label.to_string(),
                reason: "missing the SPIR-V magic number (is this little-endian SPIR-V?)"
                    .to_string(),
            });
        }

        let device = self.inner.device();
        let set_layouts = [bindings.shared.layout];
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
            .offset(0)
            .size(push_constant_bytes)];
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if push_constant_bytes > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        // SAFETY: valid create info; the set layout is alive (held by bindings).
        let layout = unsafe { device.create_pipeline_layout(&layout_info, None) }
            .map_err(VkError::call("vkCreatePipelineLayout"))?;
        // From here on `shared` owns the layout (and later the pipeline).
        let mut shared = PipelineShared {
            inner: self.inner.clone(),
            pipeline: vk::Pipeline::null(),
            layout,
            push_constant_bytes,
            signature: bindings.shared.signature.clone(),
            label: label.to_string(),
        };

        let module_info = vk::ShaderModuleCreateInfo::default().code(&words);
        // SAFETY: `words` is whole SPIR-V words starting with the magic number;
        // the driver (and validation) check the rest.
        let module = unsafe { device.create_shader_module(&module_info, None) }
            .map_err(VkError::call("vkCreateShaderModule"))?;
        // Named before pipeline creation so validation messages about it say which.
        self.inner.set_name(module, label);
        self.inner.set_name(layout, &format!("{label} layout"));

        let entries: Vec<vk::SpecializationMapEntry> = spec
            .iter()
            .enumerate()
            .map(|(i, (id, _))| {
                vk::SpecializationMapEntry::default()
                    .constant_id(*id)
                    .offset((i * 4) as u32)
                    .size(4)
            })
            .collect();
        let values: Vec<u32> = spec.iter().map(|(_, v)| *v).collect();
        let spec_info = vk::SpecializationInfo::default()
            .map_entries(&entries)
            .data(bytemuck::cast_slice(&values));
        let mut stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        if !spec.is_empty() {
            stage = stage.specialization_info(&spec_info);
        }
        let create = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout)];

        // Build through this kernel's file of the persistent cache when there
        // is one, else through the context's in-memory cache
        let file = self.pipeline_cache_file(label, spirv, spec, push_constant_bytes, bindings);
        let disk = file.as_deref().map(|path| self.open_disk_cache(path));
        let result = match &disk {
            Some((cache, _)) => {
                // SAFETY: module, layout and cache are live objects of this
                // device; the cache is this call's own.
                unsafe { device.create_compute_pipelines(*cache, &create, None) }
            }
            None => {
                let cache = lock(&self.pipeline_cache);
                // SAFETY: module, layout and cache are live objects of this device;
                // the cache is locked for the call.
                unsafe { device.create_compute_pipelines(*cache, &create, None) }
            }
        };
        // SAFETY: the module is only needed during pipeline creation.
        unsafe { device.destroy_shader_module(module, None) };
        if let (Some((cache, loaded)), Some(path)) = (&disk, &file) {
            if result.is_ok() {
                if *loaded {
                    self.disk_cache_counters.loaded();
                } else {
                    self.store_disk_cache(*cache, path);
                }
            }
            // SAFETY: the cache is this call's own; the pipeline built with it
            // does not need it any more.
            unsafe { device.destroy_pipeline_cache(*cache, None) };
        }
        match result {
            Ok(p) => shared.pipeline = p[0],
            Err((pipelines, r)) => {
                for p in pipelines.into_iter().filter(|p| *p != vk::Pipeline::null()) {
                    // SAFETY: a pipeline the failed call did create; unused.
                    unsafe { device.destroy_pipeline(p, None) };
                }
                return Err(VkError::call("vkCreateComputePipelines")(r));
            }
        }
        self.inner.set_name(shared.pipeline, label);
        Ok(ComputePipeline {
            shared: Arc::new(shared),
        })
    }

    /// The directory of this device's persistent pipeline cache files, or
    /// `None` when the cache is off (see [`Context::set_pipeline_cache_dir`]).
    pub fn pipeline_cache_dir(&self) -> Option<&Path> {
        self.disk_cache_dir.as_deref()
    }

    /// Keeps the persistent pipeline cache under `dir` (a folder per device
    /// and driver is made inside it), or turns it off with `None`. The default
    /// comes from the environment: `LANCER_PIPELINE_CACHE_DIR` (`off` turns
    /// it off), else `$XDG_CACHE_HOME/lancer/pipelines`, else
    /// `~/.cache/lancer/pipelines`.
    pub fn set_pipeline_cache_dir(&mut self, dir: Option<&Path>) {
        let (vendor, device, uuid) = &self.cache_id;
        self.disk_cache_dir =
            dir.map(|d| disk_cache::device_dir(d, *vendor, *device, self.driver_version, uuid));
    }

    /// What the persistent pipeline cache did so far: files loaded, rejected
    /// (corrupt or foreign) and stored.
    pub fn pipeline_cache_stats(&self) -> PipelineCacheStats {
        self.disk_cache_counters.snapshot()
    }

    /// The cache file of one kernel: named by its label and a hash of
    /// everything that makes the pipeline (SPIR-V, specialisation, push
    /// constants, binding layout).
    fn pipeline_cache_file(
        &self,
        label: &str,
        spirv: &[u8],
        spec: &[(u32, u32)],
        push_constant_bytes: u32,
        bindings: &Bindings,
    ) -> Option<PathBuf> {
        let dir = self.disk_cache_dir.as_ref()?;
        let mut key = disk_cache::Fnv::new()
            .bytes(spirv)
            .u32(spec.len() as u32)
            .u32(push_constant_bytes);
        for (id, value) in spec {
            key = key.u32(*id).u32(*value);
        }
        for (binding, kind) in &bindings.shared.signature {
            key = key.u32(*binding).u32(*kind as u32);
        }
        let name: String = label
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        Some(dir.join(format!("{name}-{:016x}.bin", key.finish())))
    }

    /// A new pipeline cache seeded from `path` when it holds valid data for
    /// this device, and whether it was; an empty one otherwise (a corrupt or
    /// foreign file counts as rejected).
    fn open_disk_cache(&self, path: &Path) -> (vk::PipelineCache, bool) {
        let device = self.inner.device();
        match disk_cache::read(path) {
            Ok(Some(data)) if self.cache_header_matches(&data) => {
                let info = vk::PipelineCacheCreateInfo::default().initial_data(&data);
                // SAFETY: the data passed its checksum and carries this
                // device's cache header; the driver validates the rest.
                if let Ok(cache) = unsafe { device.create_pipeline_cache(&info, None) } {
                    return (cache, true);
                }
                self.disk_cache_counters.rejected();
            }
            Ok(None) => {}
            Ok(Some(_)) | Err(()) => self.disk_cache_counters.rejected(),
        }
        let info = vk::PipelineCacheCreateInfo::default();
        // SAFETY: an empty cache on a live device. Should even this fail, the
        // null handle builds the pipeline without a cache.
        let cache = unsafe { device.create_pipeline_cache(&info, None) };
        (cache.unwrap_or(vk::PipelineCache::null()), false)
    }

    /// Writes `cache`'s data to `path` (temporary file, then rename). A
    /// cache that cannot be written costs the next run its warm start, not
    /// this one its render, so errors are dropped.
    fn store_disk_cache(&self, cache: vk::PipelineCache, path: &Path) {
        if cache == vk::PipelineCache::null() {
            return;
        }
        // SAFETY: the cache is live and used by no other thread.
        let data = unsafe { self.inner.device().get_pipeline_cache_data(cache) };
        if let Ok(data) = data {
            if self.cache_header_matches(&data) && disk_cache::write(path, &data).is_ok() {
                self.disk_cache_counters.stored();
            }
        }
    }

    /// Whether `data` starts with a version-one cache header for this device.
    fn cache_header_matches(&self, data: &[u8]) -> bool {
        if data.len() < CACHE_HEADER_BYTES {
            return false;
        }
        let word = |i: usize| u32::from_ne_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
        let (vendor, device, uuid) = &self.cache_id;
        word(0) as usize >= CACHE_HEADER_BYTES
            && word(4) == vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32
            && word(8) == *vendor
            && word(12) == *device
            && data[16..CACHE_HEADER_BYTES] == uuid[..]
    }
}
