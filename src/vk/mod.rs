//! The Vulkan layer: the only module with `unsafe` code.
//!
//! [`Context`] owns the instance, device, compute queue, memory allocator and
//! pipeline cache. [`Buffer`], [`Bindings`] and [`ComputePipeline`] each hold
//! a reference-counted handle to the device state, so they may be dropped in
//! any order, before or after the context, and the device is destroyed only
//! when the last of them is gone. [`Recorder`] records one command buffer of
//! dispatches, barriers and transfers; [`Context::submit`] runs it, waits, and
//! returns per-dispatch GPU times ([`Timings`]).
#![allow(unsafe_code)]

mod buffer;
mod commands;
mod context;
mod disk_cache;
mod error;
mod memory;
mod pipeline;

pub use buffer::{Buffer, MemoryKind, STAGING_CHUNK_BYTES};
pub use commands::{DispatchTiming, Recorder, Timings, MAX_TIMED_DISPATCHES};
pub use context::{list_devices, Context, ContextOptions, DeviceInfo, DeviceKind};
pub(crate) use disk_cache::Fnv;
pub use disk_cache::PipelineCacheStats;
pub use error::{VkError, VkResult, INSTALL_HINT, VALIDATION_HINT};
pub use memory::{
    heap_budgets, BudgetSource, HeapBudget, MemoryHeap, ReportedBudget, BUDGET_ENV,
    HEAP_SIZE_BUDGET_PERCENT,
};
pub use pipeline::{BindingKind, Bindings, ComputePipeline, TEXEL_BYTES};
