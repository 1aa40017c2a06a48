//! SPIR-V of every kernel, compiled by `build.rs` from `shaders/*.comp`
//! (empty without the `kernels` feature; the renderer then refuses to run).

/// The generate kernel: camera rays.
pub const GENERATE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/generate.spv"));
/// The intersect kernel: closest hits.
pub const INTERSECT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/intersect.spv"));
/// The shade kernel: emission, NEE, material sampling.
pub const SHADE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/shade.spv"));
/// The shadow kernel: occlusion of NEE samples.
pub const SHADOW: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/shadow.spv"));
/// The accumulate kernel: film sums in f64 (devices with `shaderFloat64`).
pub const ACCUMULATE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/accumulate.spv"));
/// The accumulate kernel: compensated f32 film sums (other devices).
pub const ACCUMULATE_F32: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/accumulate_f32.spv"));
/// The megakernel: a whole wave in one kernel, film sums in f64.
pub const MEGAKERNEL: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/megakernel.spv"));
/// The megakernel with compensated f32 film sums (other devices).
pub const MEGAKERNEL_F32: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/megakernel_f32.spv"));
/// The probe kernel: a test hook that spawns rays and shadow segments from
/// surface points as shade does (`Renderer::probe_rays`), not a pass.
pub const PROBE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/probe.spv"));
/// The BSDF test kernel: samples and evaluates materials with the shade
/// kernel's functions, for the statistical tests (not a pass).
pub const TEST_BSDF: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/test_bsdf.spv"));
