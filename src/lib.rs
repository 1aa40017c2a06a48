//! lancer: a wavefront path tracer on Vulkan compute, without ray-tracing
//! extensions. Each stage of a path is its own GLSL compute kernel
//! (generate, intersect, shade, shadow, accumulate); see `render`.
//!
//! All `unsafe` code lives in [`vk`]; the rest of the crate denies it.
#![deny(unsafe_code)]

pub mod bench;
pub mod budget;
pub mod bvh;
pub mod compare;
pub mod converge;
pub mod features;
pub mod geometry;
pub mod gpu;
pub mod interrupt;
pub mod output;
pub mod pass;
pub mod plot;
pub mod render;
pub mod scene;
pub mod shader_interface;
pub mod shaders;
pub mod stats;
pub mod study;
pub mod vk;
