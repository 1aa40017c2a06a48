//! The error type of the Vulkan layer.

use std::fmt::Write as _;
use std::path::PathBuf;

use ash::vk;

/// What to install when Vulkan itself, or any usable device, is missing.
pub const INSTALL_HINT: &str = "install libvulkan1 and mesa-vulkan-drivers \
     (Debian/Ubuntu: apt-get install libvulkan1 mesa-vulkan-drivers); \
     mesa-vulkan-drivers provides lavapipe, a software Vulkan device that needs no GPU";

/// What to install when the validation layer is requested but missing.
pub const VALIDATION_HINT: &str =
    "install vulkan-validationlayers (Debian/Ubuntu: apt-get install vulkan-validationlayers)";

/// Errors of the Vulkan layer.
#[derive(Debug, thiserror::Error)]
pub enum VkError {
    /// The Vulkan loader (libvulkan) could not be loaded.
    #[error("could not load the Vulkan loader (libvulkan): {0}; {INSTALL_HINT}")]
    Loader(#[source] ash::LoadingError),

    /// No physical device supports Vulkan 1.2 with a compute queue.
    #[error("no Vulkan 1.2 device with a compute queue was found; {INSTALL_HINT}")]
    NoDevice,

    /// `--device` matched none of the available devices.
    #[error("no Vulkan device matches ContextOptions::device {query:?}; available devices: {}", list_available(.available))]
    DeviceNotFound {
        /// The index or name fragment that was asked for.
        query: String,
        /// One line per usable device: `"index: name (kind)"`.
        available: Vec<String>,
    },

    /// Validation was requested but `VK_LAYER_KHRONOS_validation` is not installed.
    #[error("Vulkan validation was requested but VK_LAYER_KHRONOS_validation is not installed; {VALIDATION_HINT}")]
    ValidationLayerMissing,

    /// A Vulkan call failed.
    #[error("{call} failed: {result} ({result:?})")]
    Call {
        /// The Vulkan function that failed, e.g. `"vkCreateDevice"`.
        call: &'static str,
        /// What it returned.
        result: vk::Result,
    },

    /// gpu-allocator could not allocate memory for a buffer.
    #[error("allocating memory for buffer {label:?} failed: {source}")]
    Alloc {
        /// The label of the buffer being allocated.
        label: String,
        /// What gpu-allocator reported.
        #[source]
        source: gpu_allocator::AllocationError,
    },

    /// A buffer is larger than the device's `maxStorageBufferRange`.
    #[error(
        "buffer {label:?} needs {size} bytes, more than this device's maxStorageBufferRange \
         of {limit} bytes, the most one binding may hold"
    )]
    BufferTooLarge {
        /// The label of the buffer.
        label: String,
        /// The size asked for, in bytes.
        size: u64,
        /// The device's `maxStorageBufferRange`, in bytes.
        limit: u64,
    },

    /// A buffer does not fit what is left of its memory heap's budget
    /// ([`super::Context::memory_budgets`]).
    #[error(
        "buffer {label:?} needs {size} bytes, more than is left of the device-memory budget \
         of heap {}: {} bytes ({}), of which lancer's buffers hold {used}{}",
        .budget.heap, .budget.bytes, .budget.source, budget_hint(.budget.source)
    )]
    OverBudget {
        /// The label of the buffer that did not fit.
        label: String,
        /// The size asked for, in bytes.
        size: u64,
        /// Bytes already held by live buffers in the same heap.
        used: u64,
        /// The heap's budget and where it came from.
        budget: super::memory::HeapBudget,
    },

    /// The SPIR-V given to [`super::Context::create_pipeline`] is malformed.
    #[error("SPIR-V of pipeline {label:?} is invalid: {reason}")]
    InvalidSpirv {
        /// The label of the pipeline.
        label: String,
        /// Why the words were rejected.
        reason: String,
    },

    /// This layer's API was misused (out-of-range copy, oversized push constants,
    /// mismatched bindings, ...). The message says what and where.
    #[error("{0}")]
    Usage(String),

    /// Reading or writing a file (the pipeline cache) failed.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// Result type of the Vulkan layer.
pub type VkResult<T> = Result<T, VkError>;

impl VkError {
    /// Shorthand for [`VkError::Call`].
    pub(crate) fn call(call: &'static str) -> impl FnOnce(vk::Result) -> VkError {
        move |result| VkError::Call { call, result }
    }

    /// True when the device was lost (a driver reset, or a dispatch that ran
    /// past a GPU watchdog).
    pub fn is_device_lost(&self) -> bool {
        matches!(self, VkError::Call { result, .. } if *result == vk::Result::ERROR_DEVICE_LOST)
    }

    /// True when this error means memory ran out (device or host).
    pub fn is_out_of_memory(&self) -> bool {
        match self {
            VkError::Call { result, .. } => is_oom(*result),
            VkError::Alloc { source, .. } => alloc_is_oom(source),
            VkError::OverBudget { .. } => true,
            _ => false,
        }
    }
}

fn is_oom(result: vk::Result) -> bool {
    result == vk::Result::ERROR_OUT_OF_DEVICE_MEMORY
        || result == vk::Result::ERROR_OUT_OF_HOST_MEMORY
        || result == vk::Result::ERROR_OUT_OF_POOL_MEMORY
}

/// Whether gpu-allocator's error means memory ran out.
fn alloc_is_oom(source: &gpu_allocator::AllocationError) -> bool {
    match source {
        gpu_allocator::AllocationError::OutOfMemory => true,
        // gpu-allocator reports a failed vkAllocateMemory as Internal("... ERROR_OUT_OF_DEVICE_MEMORY").
        gpu_allocator::AllocationError::Internal(msg) => msg.contains("OUT_OF_"),
        _ => false,
    }
}

/// What to change about the budget itself: only a budget the user set can
/// be raised.
fn budget_hint(source: super::memory::BudgetSource) -> String {
    match source {
        super::memory::BudgetSource::Environment => format!(
            "; raise {} or unset it to use the device's budget",
            super::memory::BUDGET_ENV
        ),
        _ => String::new(),
    }
}

fn list_available(available: &[String]) -> String {
    if available.is_empty() {
        return format!("none; {INSTALL_HINT}");
    }
    let mut s = String::new();
    for (i, a) in available.iter().enumerate() {
        let sep = if i == 0 { "" } else { ", " };
        let _ = write!(s, "{sep}[{a}]");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `VK_ERROR_DEVICE_LOST` from any call reads as a lost device, names
    /// the call, and is not mistaken for running out of memory.
    #[test]
    fn device_lost_is_reported_as_such() {
        for call in ["vkQueueSubmit", "vkWaitForFences"] {
            let e = VkError::call(call)(vk::Result::ERROR_DEVICE_LOST);
            let text = e.to_string();
            println!("{text}");
            assert!(text.starts_with(&format!("{call} failed: ")), "{text}");
            assert!(text.contains("ERROR_DEVICE_LOST"), "{text}");
            assert!(e.is_device_lost());
            assert!(!e.is_out_of_memory());
        }
        let oom = VkError::call("vkAllocateMemory")(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY);
        assert!(oom.is_out_of_memory());
        assert!(!oom.is_device_lost());
    }
}
