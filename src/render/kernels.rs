//! The kernel set: one home for which kernels exist, which a scene calls
//! for, how they are specialised and scheduled, and their SPIR-V.
//!
//! - [`Pass`]: one kernel of the wavefront, named with a verb, or the
//!   megakernel. Its name is its kernel's file stem (`shaders/NAME.comp`),
//!   the renderer method that records it, and its dispatch label (reused for
//!   timestamps, debug-utils regions and allocation names, the rows of the
//!   stats table, the trace and `lancer info`).
//! - [`Schedule`]: the wavefront or the megakernel.
//! - [`Sampler`]: where the random numbers of a path come from.
//! - [`Features`]: what a scene calls for; kernels receive it as
//!   specialisation constants, so the driver compiler drops code for effects
//!   the scene does not use, and passes with nothing to do are not recorded.
//! - The SPIR-V of every kernel and variant, compiled by `build.rs` from
//!   `shaders/*.comp` (empty without the `kernels` feature; the renderer then
//!   refuses to run). A kernel listed in [`FILM_F32_KERNELS`] is compiled
//!   twice from its one source: with `FILM_FP64 = 1` (f64 film sums, devices
//!   with `shaderFloat64`) and with `FILM_FP64 = 0` (compensated f32 sums).
//!
//! A new kernel is one `shaders/NAME.comp` and one [`Pass`] (or, for a test
//! kernel, one call of [`spirv`]).

use std::collections::BTreeMap;
use std::fmt;

use anyhow::{Context as _, Result};

use super::specialise::{specialise, words_of};
use crate::gpu::GpuPush;
use crate::interface::*;
use crate::scene::{ColorSource, MaterialKind, Scene, Sides};
use crate::vk::{Bindings, ComputePipeline, Context};

/// How the kernels of a wave are scheduled. Both give the same image, bit
/// for bit: they run the same path functions (`shaders/common/path.glsl`)
/// and fold paths into the film in the same order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Schedule {
    /// One kernel per pass (generate, then intersect, shade and shadow per
    /// bounce, then accumulate), path state in buffers, rays in queues.
    #[default]
    Wavefront,
    /// One kernel per wave: each thread follows its pixel's paths from the
    /// camera to the film, path state in registers ("Megakernels
    /// considered harmful", Laine, Karras and Aila 2013, is the comparison).
    Megakernel,
}

impl Schedule {
    /// Every schedule, the default first.
    pub const ALL: [Schedule; 2] = [Schedule::Wavefront, Schedule::Megakernel];

    /// The schedule's name, as `--schedule` takes it.
    pub const fn name(self) -> &'static str {
        match self {
            Schedule::Wavefront => "wavefront",
            Schedule::Megakernel => "megakernel",
        }
    }
}

impl std::fmt::Display for Schedule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Schedule {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Schedule> {
        Schedule::ALL
            .into_iter()
            .find(|x| x.name() == s)
            .with_context(|| format!("unknown schedule {s:?}: use wavefront or megakernel"))
    }
}

/// Where the numbers of every dimension of a path sample (camera jitter,
/// lens, and per bounce the light sample (one pair: the first number picks
/// the emitter and is reused for the point on it), BSDF direction, lobe and
/// roulette) come from. Either is a pure function of (seed, pixel, sample
/// index, dimension): split renders and both schedules give the same image.
/// The kernels receive it as a specialisation constant (`SPEC_SAMPLER`), so
/// each compiles only the sampler it uses (`shaders/common/sampler.glsl`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Sampler {
    /// Independent uniform numbers, a hash of (seed, pixel, sample,
    /// dimension); the camera jitter is stratified N x N when the scene's spp
    /// is a square and the render is not progressive.
    Independent,
    /// Shuffled, Owen-scrambled Sobol points in every dimension (Burley
    /// 2020, "Practical Hash-based Owen Scrambling"; Cycles' Sobol-Burley):
    /// each 2D pair and each 1D dimension is stratified within a pixel at
    /// every power of two of samples, whatever the spp, progressive renders
    /// included (which draw each pixel's even and odd samples as two
    /// sequences, for the error estimate). See [`crate::render::sobol`].
    /// The default: at equal time its error is lower (docs/accuracy.md).
    #[default]
    Sobol,
}

impl Sampler {
    /// Every sampler: the independent one, then the default.
    pub const ALL: [Sampler; 2] = [Sampler::Independent, Sampler::Sobol];

    /// The sampler's name, as the command line and the render's figures write it.
    pub const fn name(self) -> &'static str {
        match self {
            Sampler::Independent => "independent",
            Sampler::Sobol => "sobol",
        }
    }

    /// The sampler's id in the kernels (`SAMPLER_*`).
    pub const fn id(self) -> u32 {
        match self {
            Sampler::Independent => SAMPLER_INDEPENDENT,
            Sampler::Sobol => SAMPLER_SOBOL,
        }
    }
}

impl fmt::Display for Sampler {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Sampler {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Sampler> {
        Sampler::ALL
            .into_iter()
            .find(|x| x.name() == s)
            .with_context(|| format!("unknown sampler {s:?}: use independent or sobol"))
    }
}

/// The estimator the shade pass uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Next-event estimation combined with BSDF sampling by MIS.
    #[default]
    Nee,
    /// BSDF sampling only: light is found only by hitting it.
    Bsdf,
}

/// The effects a scene calls for, and the sampler the renderer chose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Features {
    /// The scene has spheres.
    pub spheres: bool,
    /// The scene has triangles (quads or meshes).
    pub triangles: bool,
    /// Next-event estimation runs: there are emitters or delta lights and
    /// the integrator is `nee`.
    pub nee: bool,
    /// Some surface emits.
    pub emission: bool,
    /// The scene has delta lights (point, spot, directional).
    pub delta_lights: bool,
    /// The render sets path flags: hidden emitters (Mitsuba's
    /// `hide_emitters`) or emitter sampling alone (`direct` without BSDF
    /// samples).
    pub path_flags: bool,
    /// The environment is not black.
    pub environment: bool,
    /// The scene has an environment map (Mitsuba's `envmap`): escaped
    /// paths look it up, and next-event estimation samples it.
    pub envmap: bool,
    /// Some material uses a texture.
    pub textures: bool,
    /// Some texture has a lookup of Mitsuba's other than lancer's plain
    /// one (`to_uv`, `wrap_mode`, `filter_type`, a checkerboard):
    /// [`ColorSource::Mapped`].
    pub texture_mapping: bool,
    /// The camera has a thin lens.
    pub depth_of_field: bool,
    /// The pixel filter is not the box: film positions are drawn from it.
    pub pixel_filter: bool,
    /// The camera has near or far clip planes.
    pub clip: bool,
    /// Film positions stay inside the image (Mitsuba's `sample_border`
    /// false with a filter that reaches past its pixel): the filter is
    /// sampled cut at the image's edge.
    pub film_edge: bool,
    /// The image's centre is off the optical axis (a Mitsuba crop window
    /// or principal point offset, `Camera::shift`).
    pub camera_shift: bool,
    /// The camera is orthographic (Mitsuba's `orthographic` sensor,
    /// `Camera::orthographic`).
    pub orthographic: bool,
    /// Some material is a `mask` (`Material::opacity`): light passes
    /// through it where it is not met.
    pub mask: bool,
    /// Some material has a normal map (`Material::normal_map`).
    pub normal_map: bool,
    /// Some material reads a mesh attribute ([`ColorSource::Attribute`]).
    pub mesh_attributes: bool,
    /// Bit `1 << MAT_*` set for each material type in use.
    pub material_mask: u32,
    /// Some material in use takes its side from the shading normal
    /// (`Material::sides` other than `Both`: Mitsuba's rules).
    pub shading_sides: bool,
    /// The sampler: a choice of the renderer, not of the scene
    /// ([`Features::detect`] and [`Features::all`] give the default; the
    /// renderer sets `RenderOptions::sampler`).
    pub sampler: Sampler,
    /// The waves take their pixels from a pixel list (an adaptive render,
    /// `RenderOptions::adaptive`): a choice of the renderer, like the
    /// sampler, and off in [`Features::detect`] and [`Features::all`].
    pub pixel_list: bool,
}

/// Names of the material types, indexed by `MAT_*`.
pub const MATERIAL_NAMES: [&str; 13] = [
    "lambert",
    "phong",
    "mirror",
    "glossy",
    "dielectric",
    "conductor",
    "roughconductor",
    "roughdielectric",
    "plastic",
    "roughplastic",
    "thindielectric",
    "blendbsdf",
    "principled",
];

impl Features {
    /// Detects the features `scene` calls for.
    pub fn detect(scene: &Scene, integrator: Integrator) -> Features {
        let used = |i: u32| {
            scene.spheres.iter().any(|s| s.material == i)
                || scene.triangles.iter().any(|t| t.material == i)
        };
        let mut material_mask = 0;
        // Every colour the kernels read: textured ones need the texels
        let mut colours: Vec<&ColorSource> = Vec::new();
        let mut emission = false;
        let mut shading_sides = false;
        let mut mask = false;
        let mut normal_map = false;
        for (i, m) in scene.materials.iter().enumerate() {
            if !used(i as u32) {
                continue;
            }
            // A blend's kind, then its components'
            let kinds: Vec<&MaterialKind> = match &m.kind {
                MaterialKind::Blend { components, .. } => {
                    std::iter::once(&m.kind).chain(components.iter()).collect()
                }
                kind => vec![kind],
            };
            for kind in kinds {
                material_mask |= 1 << material_type(kind);
                colours.extend(kind.colour_sources());
            }
            emission |= m.emission.max_element() > 0.0;
            shading_sides |= m.sides != Sides::Both && !m.kind.transmits();
            mask |= m.opacity.is_some();
            normal_map |= m.normal_map.is_some();
            colours.extend(m.opacity.as_ref());
            colours.extend(m.normal_map.as_ref().map(|n| &n.texture));
        }
        // A spot's texture and a projector's image are read as a
        // material's are
        colours.extend(scene.lights.iter().filter_map(|l| l.texture()));
        let textures = colours.iter().any(|c| c.is_textured());
        let texture_mapping = colours.iter().any(|c| matches!(c, ColorSource::Mapped(_)));
        let mesh_attributes = colours
            .iter()
            .any(|c| matches!(c, ColorSource::Attribute(_)));
        let delta_lights = !scene.lights.is_empty();
        let envmap = scene.envmap.is_some();
        Features {
            spheres: !scene.spheres.is_empty(),
            triangles: !scene.triangles.is_empty(),
            nee: (emission || delta_lights || envmap) && integrator == Integrator::Nee,
            emission,
            delta_lights,
            path_flags: scene.render.hide_emitters || scene.render.emitter_sampling_only,
            environment: scene.environment.max_element() > 0.0,
            envmap,
            textures,
            texture_mapping,
            depth_of_field: scene.camera.aperture_radius > 0.0,
            pixel_filter: scene.render.filter != crate::scene::PixelFilter::Box,
            clip: scene.camera.has_clip(),
            film_edge: scene.render.filter_inside_film
                && scene.render.filter != crate::scene::PixelFilter::Box,
            camera_shift: scene.camera.shift != [0.0; 2],
            orthographic: scene.camera.orthographic.is_some(),
            mask,
            normal_map,
            mesh_attributes,
            material_mask,
            shading_sides,
            sampler: Sampler::default(),
            pixel_list: false,
        }
    }

    /// Every feature on: the same image, at the cost of every code path.
    pub fn all(integrator: Integrator) -> Features {
        Features {
            spheres: true,
            triangles: true,
            nee: integrator == Integrator::Nee,
            emission: true,
            delta_lights: true,
            path_flags: true,
            environment: true,
            envmap: true,
            textures: true,
            texture_mapping: true,
            depth_of_field: true,
            pixel_filter: true,
            clip: true,
            film_edge: true,
            camera_shift: true,
            orthographic: true,
            mask: true,
            normal_map: true,
            mesh_attributes: true,
            material_mask: (1 << MATERIAL_NAMES.len()) - 1,
            shading_sides: true,
            sampler: Sampler::default(),
            pixel_list: false,
        }
    }

    /// Specialisation constants of `pass`'s kernel, as `(constant_id, value)`.
    /// Every kernel gets the scene's features and the sampler; shadow also
    /// runs the traversal in occlusion (any-hit) mode.
    pub fn spec_constants(&self, pass: Pass) -> Vec<(u32, u32)> {
        vec![
            (SPEC_HAS_SPHERES, self.spheres as u32),
            (SPEC_HAS_TRIANGLES, self.triangles as u32),
            (SPEC_NEE, self.nee as u32),
            (SPEC_HAS_ENVIRONMENT, self.environment as u32),
            (SPEC_MATERIAL_MASK, self.material_mask),
            (SPEC_HAS_TEXTURES, self.textures as u32),
            (SPEC_HAS_DOF, self.depth_of_field as u32),
            (SPEC_OCCLUSION, (pass == Pass::Shadow) as u32),
            (SPEC_HAS_EMISSION, self.emission as u32),
            (SPEC_WORKGROUP_SIZE, WORKGROUP_SIZE),
            (SPEC_SAMPLER, self.sampler.id()),
            (SPEC_HAS_FILTER, self.pixel_filter as u32),
            (SPEC_HAS_CLIP, self.clip as u32),
            (SPEC_HAS_DELTA_LIGHTS, self.delta_lights as u32),
            (SPEC_HAS_PATH_FLAGS, self.path_flags as u32),
            (SPEC_HAS_SHADING_SIDES, self.shading_sides as u32),
            (SPEC_HAS_ENVMAP, self.envmap as u32),
            (SPEC_PIXEL_LIST, self.pixel_list as u32),
            (SPEC_HAS_FILM_EDGE, self.film_edge as u32),
            (SPEC_HAS_CAM_SHIFT, self.camera_shift as u32),
            (SPEC_HAS_TEX_MAPPING, self.texture_mapping as u32),
            (SPEC_HAS_ORTHO, self.orthographic as u32),
            (SPEC_HAS_MASK, self.mask as u32),
            (SPEC_HAS_NORMAL_MAP, self.normal_map as u32),
            (SPEC_HAS_MESH_ATTRIBUTES, self.mesh_attributes as u32),
        ]
    }

    /// The GLSL name of a specialisation constant id.
    pub fn spec_constant_name(id: u32) -> &'static str {
        match id {
            SPEC_HAS_SPHERES => "HAS_SPHERES",
            SPEC_HAS_TRIANGLES => "HAS_TRIANGLES",
            SPEC_NEE => "NEE",
            SPEC_HAS_ENVIRONMENT => "HAS_ENVIRONMENT",
            SPEC_MATERIAL_MASK => "MATERIAL_MASK",
            SPEC_HAS_TEXTURES => "HAS_TEXTURES",
            SPEC_HAS_DOF => "HAS_DOF",
            SPEC_OCCLUSION => "OCCLUSION",
            SPEC_HAS_EMISSION => "HAS_EMISSION",
            SPEC_WORKGROUP_SIZE => "WORKGROUP_SIZE",
            SPEC_SAMPLER => "SAMPLER",
            SPEC_HAS_FILTER => "HAS_FILTER",
            SPEC_HAS_CLIP => "HAS_CLIP",
            SPEC_HAS_DELTA_LIGHTS => "HAS_DELTA_LIGHTS",
            SPEC_HAS_PATH_FLAGS => "HAS_PATH_FLAGS",
            SPEC_HAS_SHADING_SIDES => "HAS_SHADING_SIDES",
            SPEC_HAS_ENVMAP => "HAS_ENVMAP",
            SPEC_PIXEL_LIST => "PIXEL_LIST",
            SPEC_HAS_FILM_EDGE => "HAS_FILM_EDGE",
            SPEC_HAS_CAM_SHIFT => "HAS_CAM_SHIFT",
            SPEC_HAS_TEX_MAPPING => "HAS_TEX_MAPPING",
            SPEC_HAS_ORTHO => "HAS_ORTHO",
            SPEC_HAS_MASK => "HAS_MASK",
            SPEC_HAS_NORMAL_MAP => "HAS_NORMAL_MAP",
            SPEC_HAS_MESH_ATTRIBUTES => "HAS_MESH_ATTRIBUTES",
            _ => "?",
        }
    }

    /// The passes a wave records under `schedule`, in order: for the
    /// wavefront every pass but the megakernel, shadow only when next-event
    /// estimation runs; for the megakernel that one kernel.
    pub fn passes(&self, schedule: Schedule) -> Vec<Pass> {
        match schedule {
            Schedule::Wavefront => Pass::ALL
                .into_iter()
                .filter(|&p| p != Pass::Megakernel && (p != Pass::Shadow || self.nee))
                .collect(),
            Schedule::Megakernel => vec![Pass::Megakernel],
        }
    }

    /// Material type names present.
    pub fn material_names(&self) -> Vec<&'static str> {
        MATERIAL_NAMES
            .iter()
            .enumerate()
            .filter(|(i, _)| self.material_mask & (1 << i) != 0)
            .map(|(_, n)| *n)
            .collect()
    }
}

/// One kernel of the wavefront, in the order a wave records them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Pass {
    /// Camera rays for a wave of path slots.
    Generate,
    /// Closest hits through the BVH.
    Intersect,
    /// Emission, next-event estimation, material sampling, Russian roulette.
    Shade,
    /// Occlusion of the next-event estimation samples.
    Shadow,
    /// Finished radiance into the film.
    Accumulate,
    /// The whole wave in one kernel (the megakernel schedule): camera rays,
    /// bounces and shadow rays, and the film, from the same functions.
    Megakernel,
}

impl Pass {
    /// Every pass: the wavefront's in recording order, then the megakernel.
    pub const ALL: [Pass; 6] = [
        Pass::Generate,
        Pass::Intersect,
        Pass::Shade,
        Pass::Shadow,
        Pass::Accumulate,
        Pass::Megakernel,
    ];

    /// The pass's name: its kernel's file stem and its dispatch label.
    pub const fn name(self) -> &'static str {
        match self {
            Pass::Generate => "generate",
            Pass::Intersect => "intersect",
            Pass::Shade => "shade",
            Pass::Shadow => "shadow",
            Pass::Accumulate => "accumulate",
            Pass::Megakernel => "megakernel",
        }
    }

    /// The pass whose [`name`](Pass::name) is `label`, if any.
    pub fn from_label(label: &str) -> Option<Pass> {
        Pass::ALL.into_iter().find(|p| p.name() == label)
    }

    /// What the pass counts as the items of its rate (`rays` in
    /// [`PassRecord`](crate::render::stats::PassRecord)): rays for the passes that
    /// make or trace them, paths for the film and for the megakernel, which
    /// runs whole paths.
    pub const fn items(self) -> &'static str {
        match self {
            Pass::Accumulate | Pass::Megakernel => "paths",
            _ => "rays",
        }
    }

    /// Whether the pass runs once per bounce (else once per wave).
    pub const fn per_bounce(self) -> bool {
        matches!(self, Pass::Intersect | Pass::Shade | Pass::Shadow)
    }

    /// The kernel's SPIR-V. Accumulate and the megakernel have two
    /// encodings of the film: f64 sums where the device has `shaderFloat64`
    /// and `film_fp64` is asked for, compensated f32 sums otherwise.
    pub fn spirv(self, film_fp64: bool) -> &'static [u8] {
        if !film_fp64 && FILM_F32_KERNELS.contains(&self.name()) {
            spirv(&format!("{}_f32", self.name()))
        } else {
            spirv(self.name())
        }
    }
}

impl fmt::Display for Pass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The kernels of the passes the scene calls for, specialised to its features.
pub(crate) struct Kernels {
    by_pass: BTreeMap<Pass, ComputePipeline>,
}

impl Kernels {
    /// Builds one pipeline per pass of `features` under `schedule`.
    pub(crate) fn build(
        ctx: &Context,
        features: &Features,
        schedule: Schedule,
        bindings: &Bindings,
        film_fp64: bool,
    ) -> Result<Kernels> {
        let push_bytes = std::mem::size_of::<GpuPush>() as u32;
        let mut by_pass = BTreeMap::new();
        for pass in features.passes(schedule) {
            let spirv = pass.spirv(film_fp64);
            anyhow::ensure!(
                !spirv.is_empty(),
                "this lancer was built without its GPU kernels (cargo feature `kernels`, \
                 on by default); build it with default features to render"
            );
            let spec = features.spec_constants(pass);
            let words = specialised(spirv, &spec);
            let pipeline = ctx
                .create_pipeline(
                    pass.name(),
                    bytemuck::cast_slice(&words),
                    bindings,
                    &spec,
                    push_bytes,
                )
                .with_context(|| format!("building the {pass} kernel"))?;
            by_pass.insert(pass, pipeline);
        }
        Ok(Kernels { by_pass })
    }

    /// The kernel of `pass`; `None` when the scene does not call for it.
    pub(crate) fn get(&self, pass: Pass) -> Option<&ComputePipeline> {
        self.by_pass.get(&pass)
    }
}

/// Set to `off` to hand the driver the kernels as compiled, every effect
/// behind its specialisation constant, instead of [`specialise`]d ones (the
/// same images; for measuring what specialising saves).
pub const KERNEL_SPECIALISATION_ENV: &str = "LANCER_KERNEL_SPECIALISATION";

/// The words of `spirv` specialised to `spec`, every constant but the
/// workgroup size (which sizes the dispatch and stays the driver's), unless
/// [`KERNEL_SPECIALISATION_ENV`] is `off`.
fn specialised(spirv: &[u8], spec: &[(u32, u32)]) -> Vec<u32> {
    let words = words_of(spirv);
    if std::env::var(KERNEL_SPECIALISATION_ENV).is_ok_and(|v| v == "off") {
        return words;
    }
    let fold: Vec<(u32, u32)> = spec
        .iter()
        .copied()
        .filter(|(id, _)| *id != SPEC_WORKGROUP_SIZE)
        .collect();
    specialise(&words, &fold)
}

// The generated table `SPIRV`: (file stem, SPIR-V) of every kernel and variant.
include!(concat!(env!("OUT_DIR"), "/spirv.rs"));

/// The SPIR-V of the kernel compiled to `stem` (`shaders/STEM.comp`, or
/// `STEM_f32` for the f32-film variant of a kernel in [`FILM_F32_KERNELS`]).
pub fn spirv(stem: &str) -> &'static [u8] {
    SPIRV
        .iter()
        .find(|(name, _)| *name == stem)
        .map_or(&[][..], |(_, bytes)| *bytes)
}

/// The device's type tag of a material kind (`MAT_*`).
fn material_type(kind: &MaterialKind) -> u32 {
    match kind {
        MaterialKind::Lambert { .. } => MAT_LAMBERT,
        MaterialKind::Phong { .. } => MAT_PHONG,
        MaterialKind::Mirror { .. } => MAT_MIRROR,
        MaterialKind::Glossy { .. } => MAT_GLOSSY,
        MaterialKind::Dielectric { .. } => MAT_DIELECTRIC,
        MaterialKind::Conductor { .. } => MAT_CONDUCTOR,
        MaterialKind::RoughConductor { .. } => MAT_ROUGHCONDUCTOR,
        MaterialKind::RoughDielectric { .. } => MAT_ROUGHDIELECTRIC,
        MaterialKind::ThinDielectric { .. } => MAT_THINDIELECTRIC,
        MaterialKind::Plastic { .. } => MAT_PLASTIC,
        MaterialKind::RoughPlastic { .. } => MAT_ROUGHPLASTIC,
        MaterialKind::Blend { .. } => MAT_BLEND,
        MaterialKind::Principled(_) => MAT_PRINCIPLED,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_follow_the_order() {
        for p in Pass::ALL {
            assert_eq!(Pass::from_label(p.name()), Some(p));
        }
        assert_eq!(Pass::from_label("bounce"), None);
        let mut sorted = Pass::ALL;
        sorted.sort();
        assert_eq!(sorted, Pass::ALL);
    }

    #[test]
    fn every_pass_has_its_kernel_file() {
        for p in Pass::ALL {
            let path = format!("{}/shaders/{}.comp", env!("CARGO_MANIFEST_DIR"), p.name());
            assert!(std::path::Path::new(&path).is_file(), "{path}");
        }
    }

    #[test]
    fn serialises_as_its_name() {
        for p in Pass::ALL {
            assert_eq!(serde_json::to_value(p).unwrap(), p.name());
        }
    }

    #[test]
    fn each_schedule_has_its_passes() {
        let f = Features::all(Integrator::Nee);
        assert_eq!(
            f.passes(Schedule::Wavefront),
            [
                Pass::Generate,
                Pass::Intersect,
                Pass::Shade,
                Pass::Shadow,
                Pass::Accumulate
            ]
        );
        assert_eq!(f.passes(Schedule::Megakernel), [Pass::Megakernel]);
        let bsdf = Features::all(Integrator::Bsdf);
        assert!(!bsdf.passes(Schedule::Wavefront).contains(&Pass::Shadow));
    }

    #[test]
    fn schedule_names_round_trip() {
        for s in Schedule::ALL {
            assert_eq!(s.name().parse::<Schedule>().unwrap(), s);
            assert_eq!(s.to_string(), s.name());
            #[cfg(feature = "cli")]
            {
                let value = <Schedule as clap::ValueEnum>::to_possible_value(&s).unwrap();
                assert_eq!(value.get_name(), s.name());
            }
        }
        assert_eq!(Schedule::ALL[0], Schedule::default());
        let err = "fused".parse::<Schedule>().unwrap_err().to_string();
        assert!(err.contains("wavefront or megakernel"), "{err}");
    }

    #[test]
    fn sampler_names_round_trip_and_reach_the_kernels() {
        for s in Sampler::ALL {
            assert_eq!(s.name().parse::<Sampler>().unwrap(), s);
            assert_eq!(s.to_string(), s.name());
            assert_eq!(serde_json::to_value(s).unwrap(), s.name());
            let f = Features {
                sampler: s,
                ..Features::all(Integrator::Nee)
            };
            for pass in Pass::ALL {
                assert!(f.spec_constants(pass).contains(&(SPEC_SAMPLER, s.id())));
            }
        }
        assert_eq!(Sampler::ALL[1], Sampler::default());
        assert_eq!(Sampler::default(), Sampler::Sobol);
        assert_eq!(Sampler::Independent.id(), SAMPLER_INDEPENDENT);
        assert_eq!(Sampler::Sobol.id(), SAMPLER_SOBOL);
        assert_eq!(Features::spec_constant_name(SPEC_SAMPLER), "SAMPLER");
        let err = "halton".parse::<Sampler>().unwrap_err().to_string();
        assert!(err.contains("independent or sobol"), "{err}");
    }
}
