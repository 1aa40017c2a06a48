//! Acceleration on the CPU: the BVH builder and its reference traversal, and
//! ray/primitive intersection, which the GPU kernels mirror and the tests
//! use as their reference.

pub mod bvh;
pub mod geometry;
