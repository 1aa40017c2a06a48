//! lancer: a wavefront path tracer on Vulkan compute, without ray-tracing
//! extensions. Each stage of a path is its own GLSL compute kernel
//! (generate, intersect, shade, shadow, accumulate), so it runs on any
//! Vulkan 1.2 device, Mesa's software driver lavapipe included; a
//! megakernel runs the same path functions in one kernel, for comparison.
//!
//! # Layers
//!
//! The modules are layers, and imports point down only (`tests/it/layers.rs`
//! checks it): [`util`] (leaf helpers) and the shader interface at the
//! bottom; the Vulkan layer (all `unsafe` code); [`scene`] (the CPU scene
//! and its loaders); the BVH; packing for the device; [`render`] (the
//! renderer, its kernel set and its loop); [`io`] (image and film files);
//! [`analysis`] (metrics, compare, converge, bench); the command line
//! (`src/bin/lancer`) on top.
//!
//! # Rendering from Rust
//!
//! 1. Get a [`Scene`]: read a scene file with [`scene::load`] (the format is
//!    `docs/scene-format.md`), or build one in code with [`SceneBuilder`].
//! 2. Open a device: [`Context::new`] (see [`list_devices`] for the choice).
//! 3. Render: [`Renderer::new`] with [`RenderOptions`], then
//!    [`Renderer::render`], which gives a [`RenderOutput`]: the image (linear
//!    RGB), the per-pixel variance of its mean and the [`RenderStats`]
//!    (GPU time per pass and per bounce, rays, wall time).
//! 4. Save it: [`io::image_file::write_image`] (PNG or EXR by the
//!    extension) or [`io::image_file::write_render`], which also records
//!    the settings in the file.
//!
//! This program (`examples/render_in_code.rs`, run it with `cargo run
//! --release --example render_in_code`) builds a scene in code, renders it
//! and writes `sphere.png`:
//!
//! ```no_run
#![doc = include_str!("../examples/render_in_code.rs")]
//! ```
//!
//! The same scene as a scene file is `tests/scenes/builder_twin.toml`; a test
//! checks that both give the same image, bit for bit.
//!
//! # Errors
//!
//! Scene mistakes are [`scene::SceneError`]s that name the file (or
//! [`scene::BUILT_SOURCE`]), the key and the line. Vulkan failures are
//! [`VkError`]s; rendering returns [`anyhow::Result`] with context.
//!
//! All `unsafe` code lives in the crate's private Vulkan layer; the rest of
//! the crate denies it.
#![deny(unsafe_code)]
#![deny(missing_docs)]
#![deny(rustdoc::broken_intra_doc_links)]

// The layers, bottom to top; a module imports only from layers below it
// (tests/it/layers.rs checks the `use` lines).
mod accel;
pub mod analysis;
mod gpu;
mod interface;
pub mod io;
pub mod render;
pub mod scene;
pub mod util;
mod vk;

pub use glam::Vec3;
pub use render::kernels::{Integrator, Schedule};
pub use render::stats::RenderStats;
pub use render::{RenderOptions, RenderOutput, Renderer};
pub use scene::{Scene, SceneBuilder};
pub use util::VERSION;
pub use vk::{
    list_devices, BudgetSource, Context, ContextOptions, DeviceInfo, DeviceKind, HeapBudget,
    MemoryHeap, PipelineCacheStats, ReportedBudget, VkError,
};

/// Not part of the API: what lancer's own command line and test suite reach
/// into (accuracy studies, the Vulkan layer, CPU geometry, shader
/// constants). Hidden from the documentation; it may change in any release.
#[doc(hidden)]
pub mod internal {
    /// The accuracy study behind `lancer converge`.
    pub mod study {
        pub use crate::analysis::study::*;
    }
    /// Convergence summaries, tables and plots of `lancer converge`.
    pub mod converge {
        pub use crate::analysis::converge::*;
    }
    /// The parallel reader of plain OBJ files, checked against the general
    /// loader (the `obj_mtl` fuzz target runs it on every input).
    pub mod obj {
        pub use crate::scene::obj::compare_readers;
    }
    /// The BVH builder and its CPU reference traversal, which the GPU
    /// intersect kernel mirrors.
    pub mod bvh {
        pub use crate::accel::bvh::*;
    }
    /// CPU ray/primitive intersection, the reference for GPU tests.
    pub mod geometry {
        pub use crate::accel::geometry::*;
    }
    /// The Vulkan layer: buffers, pipelines, command recording.
    pub mod vk {
        pub use crate::vk::*;
    }
    /// The packed structs the kernels read and write.
    pub mod gpu {
        pub use crate::gpu::*;
    }
    /// Constants shared with the kernels.
    pub mod interface {
        pub use crate::interface::*;
    }
}
