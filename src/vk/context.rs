//! Instance and device selection, the shared device state, and [`Context`].

use std::ffi::{c_void, CStr, CString};
use std::fmt;
use std::io::Write as _;
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use gpu_allocator::{AllocationSizes, AllocatorDebugSettings};

use super::commands::Frame;
use super::error::{VkError, VkResult};
use super::memory::{HeapBudget, MemoryHeap, MemoryType, ReportedBudget};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";
const MIB: u64 = 1024 * 1024;

/// Locks a mutex, ignoring poisoning: the data guarded here (handles, the
/// allocator) stays consistent even if a panic happened while it was held.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The kind of a physical device, as Vulkan reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DeviceKind {
    /// A discrete GPU.
    Discrete,
    /// A GPU integrated with the CPU.
    Integrated,
    /// A virtual GPU (in a VM).
    Virtual,
    /// A software implementation on the CPU, such as lavapipe.
    Cpu,
    /// Anything else.
    Other,
}

impl DeviceKind {
    fn from_vk(t: vk::PhysicalDeviceType) -> Self {
        match t {
            vk::PhysicalDeviceType::DISCRETE_GPU => DeviceKind::Discrete,
            vk::PhysicalDeviceType::INTEGRATED_GPU => DeviceKind::Integrated,
            vk::PhysicalDeviceType::VIRTUAL_GPU => DeviceKind::Virtual,
            vk::PhysicalDeviceType::CPU => DeviceKind::Cpu,
            _ => DeviceKind::Other,
        }
    }

    /// Preference when no device is named: lower is better.
    fn rank(self) -> u32 {
        match self {
            DeviceKind::Discrete => 0,
            DeviceKind::Integrated => 1,
            DeviceKind::Virtual => 2,
            DeviceKind::Cpu => 3,
            DeviceKind::Other => 4,
        }
    }
}

impl fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DeviceKind::Discrete => "discrete GPU",
            DeviceKind::Integrated => "integrated GPU",
            DeviceKind::Virtual => "virtual GPU",
            DeviceKind::Cpu => "CPU",
            DeviceKind::Other => "other",
        })
    }
}

/// What lancer needs to know about a usable physical device.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceInfo {
    /// Index in Vulkan's enumeration order (what `--device 1` selects).
    pub index: usize,
    /// The device name, e.g. `"llvmpipe (LLVM 15.0.6, 256 bits)"`.
    pub name: String,
    /// Discrete, integrated, ...
    pub kind: DeviceKind,
    /// Vulkan version the device supports (major, minor, patch).
    pub api_version: (u32, u32, u32),
    /// Driver name, e.g. `"llvmpipe"`.
    pub driver_name: String,
    /// Driver details, e.g. `"Mesa 22.3.6 (LLVM 15.0.6)"`.
    pub driver_info: String,
    /// `maxStorageBufferRange`: the largest buffer a shader can bind, in bytes.
    pub max_storage_buffer_range: u64,
    /// `maxTexelBufferElements`: the most texels a texel-buffer view holds.
    pub max_texel_buffer_elements: u64,
    /// `maxComputeWorkGroupCount`.
    pub max_compute_workgroup_count: [u32; 3],
    /// Default subgroup size.
    pub subgroup_size: u32,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f32,
    /// Whether the chosen compute queue supports timestamp queries.
    pub timestamps_supported: bool,
    /// Total size of the device-local memory heaps, in bytes.
    pub device_local_bytes: u64,
    /// Every memory heap, with `VK_EXT_memory_budget`'s figures (read when
    /// the device was enumerated) where the device has that extension.
    pub memory_heaps: Vec<MemoryHeap>,
    /// The device supports 64-bit floats in shaders (`shaderFloat64`).
    pub shader_float64: bool,
}

impl DeviceInfo {
    /// One line naming the device, as used in [`VkError::DeviceNotFound`].
    pub fn summary(&self) -> String {
        format!(
            "{}: {} ({}, {})",
            self.index, self.name, self.kind, self.driver_name
        )
    }
}

/// Options for [`Context::new`].
#[derive(Debug, Clone, Default)]
pub struct ContextOptions {
    /// Device to use: an index from [`list_devices`] or a case-insensitive
    /// substring of its name. `None` picks discrete > integrated > virtual > CPU.
    pub device: Option<String>,
    /// Enable the Khronos validation layer and count its errors. Also turned on
    /// by the environment variable `LANCER_VALIDATION=1`.
    pub validation: bool,
}

/// Whether `LANCER_VALIDATION` asks for validation.
fn validation_from_env() -> bool {
    match std::env::var("LANCER_VALIDATION") {
        Ok(v) => matches!(
            v.trim().to_ascii_lowercase().as_str(),
            "1" | "true" | "yes" | "on"
        ),
        Err(_) => false,
    }
}

/// Counts validation errors; the debug messenger's user data.
pub(crate) struct ValidationState {
    errors: AtomicU32,
}

/// Debug messenger callback: prints warnings and errors, counts errors.
unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the loader passes either null or a valid callback-data struct
    // whose message is a NUL-terminated string valid for this call.
    let message = unsafe {
        data.as_ref()
            .and_then(|d| d.message_as_c_str())
            .map(|m| m.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let is_error = severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR);
    if is_error {
        // SAFETY: `user` is the address of the boxed ValidationState owned by
        // the InstanceHandle, which destroys the messenger before freeing it.
        if let Some(state) = unsafe { (user as *const ValidationState).as_ref() } {
            state.errors.fetch_add(1, Ordering::Relaxed);
        }
    }
    let what = if is_error { "error" } else { "warning" };
    // Never panic across the FFI boundary: ignore a failed write to stderr.
    let _ = writeln!(std::io::stderr(), "vulkan validation {what}: {message}");
    vk::FALSE
}

/// The device-memory budget `LANCER_DEVICE_MEMORY_BUDGET` sets, in bytes;
/// `None` when it is not set.
fn memory_budget_from_env() -> VkResult<Option<u64>> {
    let value = std::env::var_os(super::memory::BUDGET_ENV);
    super::memory::budget_from_env(value.as_ref().map(|v| v.to_string_lossy()).as_deref())
}

/// The loader, the instance and (with validation) the debug messenger.
pub(crate) struct InstanceHandle {
    pub(crate) instance: ash::Instance,
    debug_instance: Option<ash::ext::debug_utils::Instance>,
    messenger: vk::DebugUtilsMessengerEXT,
    validation: Option<Box<ValidationState>>,
    // Keeps libvulkan loaded; dropped after the instance is destroyed.
    _entry: ash::Entry,
}

impl InstanceHandle {
    /// Loads libvulkan and creates a Vulkan 1.2 instance.
    pub(crate) fn new(validation: bool) -> VkResult<Self> {
        // SAFETY: loading libvulkan runs its initialisers; the Vulkan loader is
        // designed to be loaded this way.
        let entry = unsafe { ash::Entry::load() }.map_err(VkError::Loader)?;
        // SAFETY: entry is a loaded Vulkan entry point table.
        let loader_version = unsafe { entry.try_enumerate_instance_version() }
            .map_err(VkError::call("vkEnumerateInstanceVersion"))?
            .unwrap_or(vk::API_VERSION_1_0);
        if loader_version < vk::API_VERSION_1_1 {
            // A 1.0 loader rejects any apiVersion above 1.0.
            return Err(VkError::NoDevice);
        }

        // SAFETY: plain enumeration through a loaded entry.
        let layers = unsafe { entry.enumerate_instance_layer_properties() }
            .map_err(VkError::call("vkEnumerateInstanceLayerProperties"))?;
        let has_validation_layer = layers
            .iter()
            .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER));
        if validation && !has_validation_layer {
            return Err(VkError::ValidationLayerMissing);
        }

        // SAFETY: plain enumeration through a loaded entry.
        let mut extensions = unsafe { entry.enumerate_instance_extension_properties(None) }
            .map_err(VkError::call("vkEnumerateInstanceExtensionProperties"))?;
        if validation {
            // SAFETY: as above; the layer is known to exist.
            let layer_ext =
                unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
                    .map_err(VkError::call("vkEnumerateInstanceExtensionProperties"))?;
            extensions.extend(layer_ext);
        }
        let has_ext = |name: &CStr| {
            extensions
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(name))
        };
        let debug_utils = has_ext(ash::ext::debug_utils::NAME);
        // With the validation layer, check synchronisation (hazards between
        // passes) as well as API usage
        let sync_validation = validation && has_ext(ash::ext::validation_features::NAME);
        let portability = has_ext(ash::khr::portability_enumeration::NAME);

        let mut ext_names = Vec::new();
        if debug_utils {
            ext_names.push(ash::ext::debug_utils::NAME.as_ptr());
        }
        if sync_validation {
            ext_names.push(ash::ext::validation_features::NAME.as_ptr());
        }
        let mut flags = vk::InstanceCreateFlags::empty();
        if portability {
            ext_names.push(ash::khr::portability_enumeration::NAME.as_ptr());
            flags |= vk::InstanceCreateFlags::ENUMERATE_PORTABILITY_KHR;
        }
        let layer_names = if validation {
            vec![VALIDATION_LAYER.as_ptr()]
        } else {
            Vec::new()
        };

        let app_info = vk::ApplicationInfo::default()
            .application_name(c"lancer")
            .application_version(vk::make_api_version(0, 0, 1, 0))
            .engine_name(c"lancer")
            .engine_version(vk::make_api_version(0, 0, 1, 0))
            .api_version(vk::API_VERSION_1_2);

        let state = (validation && debug_utils).then(|| {
            Box::new(ValidationState {
                errors: AtomicU32::new(0),
            })
        });
        let state_ptr = state.as_deref().map_or(std::ptr::null_mut(), |s| {
            s as *const ValidationState as *mut c_void
        });
        let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                    | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(debug_callback))
            .user_data(state_ptr);

        let mut create_info = vk::InstanceCreateInfo::default()
            .flags(flags)
            .application_info(&app_info)
            .enabled_layer_names(&layer_names)
            .enabled_extension_names(&ext_names);
        if state.is_some() {
            // Also catch messages from vkCreateInstance/vkDestroyInstance.
            create_info = create_info.push_next(&mut messenger_info);
        }
        let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
        if sync_validation {
            create_info = create_info.push_next(&mut features);
        }
        // SAFETY: every pointer in create_info refers to locals that outlive the call.
        let instance = unsafe { entry.create_instance(&create_info, None) }.map_err(|r| {
            if r == vk::Result::ERROR_INCOMPATIBLE_DRIVER {
                VkError::NoDevice
            } else {
                VkError::Call {
                    call: "vkCreateInstance",
                    result: r,
                }
            }
        })?;

        let mut handle = InstanceHandle {
            instance,
            debug_instance: None,
            messenger: vk::DebugUtilsMessengerEXT::null(),
            validation: state,
            _entry: entry,
        };
        if debug_utils {
            let di = ash::ext::debug_utils::Instance::new(&handle._entry, &handle.instance);
            if handle.validation.is_some() {
                let plain_info = vk::DebugUtilsMessengerCreateInfoEXT {
                    p_next: std::ptr::null(),
                    ..messenger_info
                };
                // SAFETY: the instance is live and the user-data box outlives
                // the messenger (see Drop).
                handle.messenger = unsafe { di.create_debug_utils_messenger(&plain_info, None) }
                    .map_err(VkError::call("vkCreateDebugUtilsMessengerEXT"))?;
            }
            handle.debug_instance = Some(di);
        }
        Ok(handle)
    }

    /// Number of validation errors reported so far.
    pub(crate) fn validation_errors(&self) -> u32 {
        self.validation
            .as_ref()
            .map_or(0, |s| s.errors.load(Ordering::Relaxed))
    }

    /// Whether VK_EXT_debug_utils is enabled.
    pub(crate) fn has_debug_utils(&self) -> bool {
        self.debug_instance.is_some()
    }

    /// Enumerates the usable devices: Vulkan >= 1.2 with a compute queue.
    pub(crate) fn devices(&self) -> VkResult<Vec<PhysicalDevice>> {
        // SAFETY: the instance is live.
        let physical = unsafe { self.instance.enumerate_physical_devices() }
            .map_err(VkError::call("vkEnumeratePhysicalDevices"))?;
        let mut out = Vec::new();
        for (index, &pd) in physical.iter().enumerate() {
            if let Some(d) = self.describe(index, pd) {
                out.push(d);
            }
        }
        Ok(out)
    }

    fn describe(&self, index: usize, pd: vk::PhysicalDevice) -> Option<PhysicalDevice> {
        let instance = &self.instance;
        // SAFETY: pd was enumerated from this live instance.
        let props = unsafe { instance.get_physical_device_properties(pd) };
        let v = props.api_version;
        if (vk::api_version_major(v), vk::api_version_minor(v)) < (1, 2) {
            return None;
        }
        // SAFETY: as above.
        let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
        let compute = |f: &vk::QueueFamilyProperties| {
            f.queue_flags.contains(vk::QueueFlags::COMPUTE) && f.queue_count > 0
        };
        let family = families
            .iter()
            .position(|f| compute(f) && f.timestamp_valid_bits > 0)
            .or_else(|| families.iter().position(compute))?;
        let timestamp_valid_bits = families[family].timestamp_valid_bits;

        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default()
            .push_next(&mut driver)
            .push_next(&mut subgroup);
        // SAFETY: the device supports Vulkan 1.2, where both structs are core.
        unsafe { instance.get_physical_device_properties2(pd, &mut props2) };
        // SAFETY: as above.
        let core_features = unsafe { instance.get_physical_device_features(pd) };
        let (memory_heaps, memory_types) = self.memory(pd);
        let device_local_bytes = memory_heaps
            .iter()
            .filter(|h| h.device_local)
            .map(|h| h.size)
            .sum();

        let text = |r: Result<&CStr, _>| {
            r.map(|s: &CStr| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        };
        let limits = &props.limits;
        let info = DeviceInfo {
            index,
            name: text(props.device_name_as_c_str()),
            kind: DeviceKind::from_vk(props.device_type),
            api_version: (
                vk::api_version_major(v),
                vk::api_version_minor(v),
                vk::api_version_patch(v),
            ),
            driver_name: text(driver.driver_name_as_c_str()),
            driver_info: text(driver.driver_info_as_c_str()),
            max_storage_buffer_range: u64::from(limits.max_storage_buffer_range),
            max_texel_buffer_elements: u64::from(limits.max_texel_buffer_elements),
            max_compute_workgroup_count: limits.max_compute_work_group_count,
            subgroup_size: subgroup.subgroup_size,
            timestamp_period_ns: limits.timestamp_period,
            timestamps_supported: timestamp_valid_bits > 0,
            device_local_bytes,
            memory_heaps,
            shader_float64: core_features.shader_float64 == vk::TRUE,
        };
        Some(PhysicalDevice {
            handle: pd,
            info,
            queue_family: family as u32,
            timestamp_valid_bits,
            max_push_constants_size: limits.max_push_constants_size,
            vendor_id: props.vendor_id,
            device_id: props.device_id,
            pipeline_cache_uuid: props.pipeline_cache_uuid,
            driver_version: props.driver_version,
            memory_types,
        })
    }

    /// The memory heaps of `pd`, with `VK_EXT_memory_budget`'s budget and
    /// usage when it has that extension, and its memory types.
    fn memory(&self, pd: vk::PhysicalDevice) -> (Vec<MemoryHeap>, Vec<MemoryType>) {
        let instance = &self.instance;
        // SAFETY: pd was enumerated from this live instance.
        let has_budget = unsafe { instance.enumerate_device_extension_properties(pd) }
            .unwrap_or_default()
            .iter()
            .any(|e| e.extension_name_as_c_str() == Ok(ash::ext::memory_budget::NAME));
        let mut budget = vk::PhysicalDeviceMemoryBudgetPropertiesEXT::default();
        let mut props2 = vk::PhysicalDeviceMemoryProperties2::default();
        if has_budget {
            props2 = props2.push_next(&mut budget);
        }
        // SAFETY: a Vulkan 1.2 device; the budget struct is chained only when
        // the device has VK_EXT_memory_budget, as a physical-device query of a
        // supported device extension may be.
        unsafe { instance.get_physical_device_memory_properties2(pd, &mut props2) };
        let mem = props2.memory_properties;
        let heaps = mem
            .memory_heaps_as_slice()
            .iter()
            .enumerate()
            .map(|(i, h)| MemoryHeap {
                size: h.size,
                device_local: h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL),
                reported: has_budget.then(|| ReportedBudget {
                    budget: budget.heap_budget[i],
                    usage: budget.heap_usage[i],
                }),
            })
            .collect();
        let types = mem
            .memory_types_as_slice()
            .iter()
            .map(|t| MemoryType {
                flags: t.property_flags,
                heap: t.heap_index,
            })
            .collect();
        (heaps, types)
    }
}

impl Drop for InstanceHandle {
    fn drop(&mut self) {
        if let Some(di) = &self.debug_instance {
            if self.messenger != vk::DebugUtilsMessengerEXT::null() {
                // SAFETY: the messenger was created from this instance and is
                // destroyed exactly once, before the instance.
                unsafe { di.destroy_debug_utils_messenger(self.messenger, None) };
            }
        }
        // SAFETY: every child object (device, messenger) is destroyed by now:
        // Inner destroys the device before its InstanceHandle field drops.
        unsafe { self.instance.destroy_instance(None) };
    }
}

/// A usable physical device and what device creation needs to know about it.
pub(crate) struct PhysicalDevice {
    pub(crate) handle: vk::PhysicalDevice,
    pub(crate) info: DeviceInfo,
    pub(crate) queue_family: u32,
    pub(crate) timestamp_valid_bits: u32,
    pub(crate) max_push_constants_size: u32,
    pub(crate) vendor_id: u32,
    pub(crate) device_id: u32,
    pub(crate) pipeline_cache_uuid: [u8; vk::UUID_SIZE],
    pub(crate) driver_version: u32,
    pub(crate) memory_types: Vec<MemoryType>,
}

/// Picks a device: by index or name fragment, else by kind preference.
fn select(devices: Vec<PhysicalDevice>, query: Option<&str>) -> VkResult<PhysicalDevice> {
    if devices.is_empty() {
        return Err(VkError::NoDevice);
    }
    let best =
        |candidates: Vec<PhysicalDevice>| candidates.into_iter().min_by_key(|d| d.info.kind.rank());
    let query = match query.map(str::trim) {
        None | Some("") => return best(devices).ok_or(VkError::NoDevice),
        Some(q) => q.to_string(),
    };
    let available: Vec<String> = devices.iter().map(|d| d.info.summary()).collect();
    if let Ok(n) = query.parse::<usize>() {
        if let Some(pos) = devices.iter().position(|d| d.info.index == n) {
            return devices.into_iter().nth(pos).ok_or(VkError::NoDevice);
        }
    }
    let needle = query.to_lowercase();
    let matching: Vec<PhysicalDevice> = devices
        .into_iter()
        .filter(|d| d.info.name.to_lowercase().contains(&needle))
        .collect();
    best(matching).ok_or(VkError::DeviceNotFound { query, available })
}

/// Lists the usable devices: Vulkan >= 1.2 with a compute queue.
pub fn list_devices() -> VkResult<Vec<DeviceInfo>> {
    let instance = InstanceHandle::new(false)?;
    Ok(instance.devices()?.into_iter().map(|d| d.info).collect())
}

/// Destroys the logical device when dropped.
struct DeviceHandle {
    device: ash::Device,
}

impl Drop for DeviceHandle {
    fn drop(&mut self) {
        // SAFETY: all children of the device (buffers, pipelines, pools, the
        // allocator's memory) are destroyed before this runs: Inner drops the
        // allocator first, and every wrapper holds an Arc<Inner>.
        unsafe { self.device.destroy_device(None) };
    }
}

/// Device state shared by the Context and every resource created from it.
/// It is destroyed when the last `Arc<Inner>` goes: after the Context and all
/// its buffers, pipelines and bindings.
pub(crate) struct Inner {
    /// Memory allocator; dropped in `Drop` before the device.
    allocator: ManuallyDrop<Mutex<Allocator>>,
    /// Bytes held by live buffers, per memory heap.
    pub(crate) memory_used: Vec<std::sync::atomic::AtomicU64>,
    /// Most bytes live buffers have held at once, over all heaps.
    pub(crate) memory_peak: std::sync::atomic::AtomicU64,
    /// Most bytes live buffers may hold in each heap, to show what does not
    /// fit before the driver runs out.
    pub(crate) memory_budgets: Vec<HeapBudget>,
    /// The device's memory types, to tell which heap a buffer lands in.
    pub(crate) memory_types: Vec<MemoryType>,
    /// The single compute queue. Held across submit-and-wait, so while it is
    /// locked by someone else no GPU work of this device is in flight.
    pub(crate) queue: Mutex<vk::Queue>,
    pub(crate) debug_device: Option<ash::ext::debug_utils::Device>,
    device: DeviceHandle,
    pub(crate) instance: InstanceHandle,
}

impl Inner {
    /// The logical device.
    pub(crate) fn device(&self) -> &ash::Device {
        &self.device.device
    }

    /// The memory allocator.
    pub(crate) fn allocator(&self) -> MutexGuard<'_, Allocator> {
        lock(&self.allocator)
    }

    /// Names a Vulkan object for debuggers (RenderDoc, Nsight, validation
    /// messages) when VK_EXT_debug_utils is enabled. Failures are ignored.
    pub(crate) fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        let Some(du) = &self.debug_device else {
            return;
        };
        let name = cstring(name);
        let info = vk::DebugUtilsObjectNameInfoEXT::default()
            .object_handle(handle)
            .object_name(&name);
        // SAFETY: the handle is a live object of this device.
        let _ = unsafe { du.set_debug_utils_object_name(&info) };
    }
}

impl Drop for Inner {
    fn drop(&mut self) {
        // SAFETY: the device is live; waiting idle has no other requirement.
        let _ = unsafe { self.device().device_wait_idle() };
        // SAFETY: the allocator is dropped exactly once, here, while the device
        // it frees memory on is still alive. It is never touched afterwards.
        unsafe { ManuallyDrop::drop(&mut self.allocator) };
        // Fields then drop in order: device (destroyed), then the instance.
    }
}

/// A C string from `s`, with interior NULs replaced.
pub(crate) fn cstring(s: &str) -> CString {
    CString::new(s.replace('\0', "?")).unwrap_or_default()
}

/// The Vulkan context: instance, device, queue, allocator, pipeline cache and
/// reusable command buffers. Create one per process with [`Context::new`].
pub struct Context {
    pub(crate) inner: Arc<Inner>,
    pub(crate) info: DeviceInfo,
    pub(crate) queue_family: u32,
    pub(crate) timestamp_mask: u64,
    pub(crate) max_push_constants_size: u32,
    pub(crate) cache_id: (u32, u32, [u8; vk::UUID_SIZE]),
    pub(crate) pipeline_cache: Mutex<vk::PipelineCache>,
    /// This device's folder of the persistent pipeline cache; `None` when off.
    pub(crate) disk_cache_dir: Option<std::path::PathBuf>,
    pub(crate) disk_cache_counters: super::disk_cache::Counters,
    pub(crate) driver_version: u32,
    pub(crate) frames: Mutex<Vec<Frame>>,
    pub(crate) host_mapped_transfers: bool,
    validation: bool,
}

impl fmt::Debug for Context {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Context")
            .field("device", &self.info.name)
            .field("validation", &self.validation)
            .finish_non_exhaustive()
    }
}

impl Context {
    /// Creates the instance (Vulkan 1.2), picks a device (see
    /// [`ContextOptions::device`]) and creates the device, its compute queue,
    /// the allocator and the pipeline cache.
    ///
    /// VK_EXT_debug_utils is enabled when available, for pass labels and
    /// object names. With validation, a debug messenger prints validation
    /// warnings and errors to stderr and counts the errors
    /// ([`Context::validation_errors`]).
    ///
    /// These device features are enabled when the device supports them, so
    /// shaders may use them: shaderInt64, shaderInt16, shaderFloat64,
    /// storageBuffer16BitAccess, storageBuffer8BitAccess, shaderInt8,
    /// shaderFloat16, scalarBlockLayout, vulkanMemoryModel (+ device scope),
    /// hostQueryReset.
    pub fn new(opts: &ContextOptions) -> VkResult<Context> {
        let validation = opts.validation || validation_from_env();
        let instance = InstanceHandle::new(validation)?;
        let pd = select(instance.devices()?, opts.device.as_deref())?;

        // Features: enable the useful ones the device has.
        let mut f11 = vk::PhysicalDeviceVulkan11Features::default();
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default()
            .push_next(&mut f11)
            .push_next(&mut f12);
        // SAFETY: pd is a Vulkan 1.2 device of this live instance.
        unsafe {
            instance
                .instance
                .get_physical_device_features2(pd.handle, &mut f2)
        };
        let have = f2.features;
        let features = vk::PhysicalDeviceFeatures::default()
            .shader_int64(have.shader_int64 == vk::TRUE)
            .shader_int16(have.shader_int16 == vk::TRUE)
            .shader_float64(have.shader_float64 == vk::TRUE);
        let mut want11 = vk::PhysicalDeviceVulkan11Features::default()
            .storage_buffer16_bit_access(f11.storage_buffer16_bit_access == vk::TRUE);
        let mut want12 = vk::PhysicalDeviceVulkan12Features::default()
            .storage_buffer8_bit_access(f12.storage_buffer8_bit_access == vk::TRUE)
            .shader_int8(f12.shader_int8 == vk::TRUE)
            .shader_float16(f12.shader_float16 == vk::TRUE)
            .scalar_block_layout(f12.scalar_block_layout == vk::TRUE)
            .vulkan_memory_model(f12.vulkan_memory_model == vk::TRUE)
            .vulkan_memory_model_device_scope(f12.vulkan_memory_model_device_scope == vk::TRUE)
            .host_query_reset(f12.host_query_reset == vk::TRUE);
        let mut want2 = vk::PhysicalDeviceFeatures2::default()
            .features(features)
            .push_next(&mut want11)
            .push_next(&mut want12);

        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(pd.queue_family)
            .queue_priorities(&priorities)];
        let device_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .push_next(&mut want2);
        // SAFETY: every pointer in device_info refers to locals alive for the call;
        // only supported features are requested.
        let device = unsafe {
            instance
                .instance
                .create_device(pd.handle, &device_info, None)
        }
        .map_err(VkError::call("vkCreateDevice"))?;
        let device = DeviceHandle { device };
        // SAFETY: the family and index 0 were requested in device_info.
        let queue = unsafe { device.device.get_device_queue(pd.queue_family, 0) };

        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.instance.clone(),
            device: device.device.clone(),
            physical_device: pd.handle,
            debug_settings: AllocatorDebugSettings::default(),
            buffer_device_address: false,
            allocation_sizes: AllocationSizes::new(64 * MIB, 64 * MIB)
                .with_max_device_memblock_size(256 * MIB)
                .with_max_host_memblock_size(256 * MIB),
        })
        .map_err(|source| VkError::Alloc {
            label: "allocator".to_string(),
            source,
        })?;

        let debug_device = instance
            .has_debug_utils()
            .then(|| ash::ext::debug_utils::Device::new(&instance.instance, &device.device));
        let inner = Arc::new(Inner {
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            memory_peak: std::sync::atomic::AtomicU64::new(0),
            memory_used: pd
                .info
                .memory_heaps
                .iter()
                .map(|_| std::sync::atomic::AtomicU64::new(0))
                .collect(),
            memory_budgets: super::memory::heap_budgets(
                &pd.info.memory_heaps,
                memory_budget_from_env()?,
            ),
            memory_types: pd.memory_types.clone(),
            queue: Mutex::new(queue),
            debug_device,
            device,
            instance,
        });
        inner.set_name(queue, "lancer compute queue");

        // SAFETY: the device is live; an empty cache needs no initial data.
        let cache = unsafe {
            inner
                .device()
                .create_pipeline_cache(&vk::PipelineCacheCreateInfo::default(), None)
        }
        .map_err(VkError::call("vkCreatePipelineCache"))?;

        let timestamp_mask = match pd.timestamp_valid_bits {
            0 => 0,
            b if b >= 64 => u64::MAX,
            b => (1u64 << b) - 1,
        };
        let mut ctx = Context {
            inner,
            info: pd.info,
            queue_family: pd.queue_family,
            timestamp_mask,
            max_push_constants_size: pd.max_push_constants_size,
            cache_id: (pd.vendor_id, pd.device_id, pd.pipeline_cache_uuid),
            pipeline_cache: Mutex::new(cache),
            disk_cache_dir: None,
            disk_cache_counters: Default::default(),
            driver_version: pd.driver_version,
            frames: Mutex::new(Vec::new()),
            host_mapped_transfers: true,
            validation,
        };
        ctx.set_pipeline_cache_dir(super::disk_cache::default_dir().as_deref());
        Ok(ctx)
    }

    /// The chosen device.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// `maxStorageBufferRange` of the device: no buffer may be larger.
    pub fn max_storage_buffer_range(&self) -> u64 {
        self.info.max_storage_buffer_range
    }

    /// Bytes of device memory held by live buffers right now, in all heaps.
    pub fn memory_in_use(&self) -> u64 {
        self.inner
            .memory_used
            .iter()
            .map(|u| u.load(std::sync::atomic::Ordering::Relaxed))
            .sum()
    }

    /// The bytes lancer's buffers may hold in each memory heap, and where
    /// each figure came from: `LANCER_DEVICE_MEMORY_BUDGET`, else
    /// `VK_EXT_memory_budget`, else a share of the heap's size.
    pub fn memory_budgets(&self) -> &[HeapBudget] {
        &self.inner.memory_budgets
    }

    /// The largest budget of a device-local heap (0 when there is none).
    pub fn device_local_budget(&self) -> u64 {
        let heaps = &self.info().memory_heaps;
        self.memory_budgets()
            .iter()
            .filter(|b| heaps.get(b.heap as usize).is_some_and(|h| h.device_local))
            .map(|b| b.bytes)
            .max()
            .unwrap_or(0)
    }

    /// Most bytes of device memory live buffers have held at once since
    /// the context was made, staging and readback buffers included.
    pub fn memory_peak(&self) -> u64 {
        self.inner
            .memory_peak
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Number of validation ERROR messages so far (0 without validation).
    pub fn validation_errors(&self) -> u32 {
        self.inner.instance.validation_errors()
    }

    /// Whether [`Context::upload`], [`Context::read`] and [`Context::write`]
    /// may copy straight through a host mapping when a buffer's memory is host
    /// visible and coherent (the default, `true`). With `false` they always go
    /// through a staging buffer and a copy command, as on a discrete GPU; this
    /// lets tests cover that path on lavapipe, where all memory is host visible.
    #[doc(hidden)] // the Vulkan layer's own call, not API
    pub fn set_host_mapped_transfers(&mut self, enabled: bool) {
        self.host_mapped_transfers = enabled;
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        let device = self.inner.device();
        // SAFETY: the device is live. Waiting first means no command buffer,
        // fence or query pool destroyed below is in use.
        let _ = unsafe { device.device_wait_idle() };
        for frame in lock(&self.frames).drain(..) {
            frame.destroy(device);
        }
        let cache = std::mem::replace(&mut *lock(&self.pipeline_cache), vk::PipelineCache::null());
        // SAFETY: the cache belongs to this device; pipelines created with it
        // do not need it any more.
        unsafe { device.destroy_pipeline_cache(cache, None) };
        // `inner` drops next; the device goes when the last resource holding
        // an Arc<Inner> is dropped.
    }
}
