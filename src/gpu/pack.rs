//! The one conversion from the CPU [`Scene`] to what the device reads:
//! the BVH and its primitives, materials, emitters and the frame constants.

use bytemuck::Zeroable;
use glam::{UVec4, Vec3, Vec4};

use super::envmap::GpuEnvironment;
use super::structs::*;
use super::textures::{pack_textures, GpuTextures, LAYERS, LAYER_WEIGHTS};
use crate::accel::bvh::Bvh;
use crate::accel::geometry::{plane_offset, triangle_area, Aabb};
use crate::interface::*;
use crate::scene::{
    ColorSource, DeltaLight, Material, MaterialKind, Microfacet, PixelFilter, Scene, SceneError,
    Sides,
};

/// Everything the scene contributes to the device, packed.
#[derive(Debug, Clone)]
pub struct GpuScene {
    /// Frame constants, less the wave capacity the renderer fills in.
    pub frame: GpuFrame,
    /// The device BVH: element 0 is the [`GpuBvhGrid`] header (cast), then
    /// the node pairs.
    pub bvh: Vec<GpuBvhPair>,
    /// Nodes of the BVH, for `lancer info`.
    pub bvh_nodes: usize,
    /// Primitives in BVH leaf order.
    pub primitives: Vec<GpuPrimitive>,
    /// Triangle shading data, indexed by `GpuPrimitive::meta.z`.
    pub tri_shading: Vec<GpuTriShading>,
    /// Materials: the scene's, in scene order, then the components of its
    /// blends ([`crate::scene::blend_components`]).
    pub materials: Vec<GpuMaterial>,
    /// What the material binding holds: the materials
    /// ([`MATERIAL_TEXELS`] texels each), then, in the order met, the rough
    /// plastics' coating transmittance tables ([`ROUGH_TRANSMITTANCE_RES`]
    /// floats, four to a texel), one per distinct coating, and a texel of
    /// parameters for each principled material (with three more for its
    /// weights where some are textures, `MAT_FLAG_WEIGHT_TEXTURES`); the
    /// material's `info.w` is the first texel of its table.
    pub material_texels: Vec<[u32; 4]>,
    /// Emitter table: the emissive primitives, sorted by primitive index,
    /// then the delta lights (`prim` = `DELTA_LIGHT_FLAG | light`).
    pub emitters: Vec<GpuEmitter>,
    /// Delta lights (point, spot, directional), in scene order.
    pub lights: Vec<GpuDeltaLight>,
    /// What the emitter binding holds: the table, then the delta lights
    /// (`DELTA_LIGHT_TEXELS` texels each), one texel per element.
    pub emitter_texels: Vec<[u32; 4]>,
    /// Depth of the BVH (root = 1).
    pub bvh_depth: u32,
    /// SAH cost of the BVH ([`Bvh::sah_cost`]).
    pub bvh_sah_cost: f64,
    /// Wall-clock seconds the BVH build took.
    pub bvh_seconds: f64,
    /// Original primitive index (spheres, then triangles) of each leaf slot.
    pub prim_order: Vec<u32>,
    /// Every texture, packed.
    pub textures: GpuTextures,
    /// The environment map's buffer (a zero header when there is none).
    pub environment: GpuEnvironment,
}

/// Rec. 709 luminance, used to weigh emitters by power.
fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The constant part of a colour source (white under a texture).
fn constant(c: &ColorSource) -> Vec3 {
    match c {
        ColorSource::Constant(c) => *c,
        ColorSource::Texture(_) | ColorSource::Mapped(_) | ColorSource::Attribute(_) => Vec3::ONE,
    }
}

/// The diffuse Fresnel reflectance of an interface of index ratio `eta`
/// (the fraction of uniform, cosine-weighted light reflected), by the fits
/// Mitsuba 3 uses (`fresnel_diffuse_reflectance` in its fresnel.h): Egan
/// and Hilgeman (1973) for eta < 1, d'Eon and Irving (2011) otherwise, in
/// f32 as Mitsuba computes them.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv_eta = 1.0 / eta;
    if eta < 1.0 {
        0.0636f32.mul_add(inv_eta, eta.mul_add(eta.mul_add(-1.4399, 0.7099), 0.6681))
    } else {
        // Horner's scheme in 1 / eta, highest power first
        [-1.36881f32, 4.98554, -7.80989, 6.75335, -3.4793, 0.919317]
            .iter()
            .fold(0.0f32, |acc, &c| acc.mul_add(inv_eta, c))
    }
}

/// The device id (`MICROFACET_*`) of a microfacet distribution.
fn microfacet_id(distribution: Microfacet) -> u32 {
    match distribution {
        Microfacet::Beckmann => MICROFACET_BECKMANN,
        Microfacet::Ggx => MICROFACET_GGX,
    }
}

/// The texels that follow the material table, appended as the materials
/// are packed: the rough plastics' coating tables, one per distinct
/// (distribution, alpha, eta), and the principled materials' parameters,
/// one texel each (four with textured weights). `first_texel` is the
/// texel the first starts at.
#[derive(Debug, Default)]
struct MaterialTables {
    /// The material texel the first table starts at.
    first_texel: u32,
    /// Each coating's key (the distribution id and the bits of alpha and
    /// eta), its first texel and its internal reflectance.
    coatings: Vec<((u32, u32, u32), u32, f32)>,
    /// The texels, in order.
    texels: Vec<[u32; 4]>,
}

impl MaterialTables {
    /// Appends `texels` and returns the first one's index.
    fn push(&mut self, texels: impl IntoIterator<Item = [u32; 4]>) -> u32 {
        let first = self.first_texel + self.texels.len() as u32;
        self.texels.extend(texels);
        first
    }

    /// Writes the texture indices of a principled material's textured
    /// weights (`layers`, from [`LAYER_WEIGHTS`]) into the weights that
    /// follow its parameter texel, each marked by [`WEIGHT_TEXTURE`].
    fn set_weight_textures(&mut self, g: &GpuMaterial, layers: &[u32; LAYERS]) {
        if g.info.x != MAT_PRINCIPLED || g.info.z & MAT_FLAG_WEIGHT_TEXTURES == 0 {
            return;
        }
        let first = (g.info.w - self.first_texel) as usize + 1;
        for (k, &index) in layers[LAYER_WEIGHTS..].iter().enumerate() {
            if index != NO_TEXTURE {
                self.texels[first + k / 4][k % 4] = WEIGHT_TEXTURE | index;
            }
        }
    }

    /// The first texel of the table of a coating, and its internal
    /// reflectance; the table is computed the first time the coating is met.
    fn coating(&mut self, distribution: Microfacet, alpha: f32, eta: f32) -> (u32, f32) {
        let key = (microfacet_id(distribution), alpha.to_bits(), eta.to_bits());
        if let Some(&(_, first, internal)) = self.coatings.iter().find(|c| c.0 == key) {
            return (first, internal);
        }
        let c = super::rough_plastic::rough_coating(distribution, alpha, eta);
        let first = self.push(
            c.transmittance
                .chunks_exact(4)
                .map(|q| [q[0], q[1], q[2], q[3]].map(f32::to_bits)),
        );
        self.coatings.push((key, first, c.internal_reflectance));
        (first, c.internal_reflectance)
    }
}

/// A blend's component as a material of its own: it scatters on both
/// sides (the blend's material decides the side) and emits nothing.
fn component_material(kind: &MaterialKind) -> Material {
    Material {
        name: String::new(),
        kind: kind.clone(),
        emission: Vec3::ZERO,
        sides: Sides::Both,
        opacity: None,
        normal_map: None,
    }
}

/// Packs one material; a rough plastic's coating table and a principled
/// material's further parameters go to `tables`.
fn pack_material(m: &crate::scene::Material, tables: &mut MaterialTables) -> GpuMaterial {
    let mut table = 0;
    let mut params = Vec4::ZERO;
    let (ty, color, specular) = match &m.kind {
        MaterialKind::Lambert { albedo } => (MAT_LAMBERT, constant(albedo).extend(0.0), Vec4::ZERO),
        MaterialKind::Phong {
            diffuse,
            specular,
            exponent,
        } => (
            MAT_PHONG,
            constant(diffuse).extend(0.0),
            specular.extend(*exponent),
        ),
        MaterialKind::Mirror { reflectance } => (MAT_MIRROR, reflectance.extend(0.0), Vec4::ZERO),
        MaterialKind::Glossy {
            reflectance,
            cone_angle_deg,
        } => (
            MAT_GLOSSY,
            reflectance.extend(cone_angle_deg.to_radians().sin()),
            Vec4::ZERO,
        ),
        MaterialKind::Dielectric { ior, tint } => (MAT_DIELECTRIC, tint.extend(*ior), Vec4::ZERO),
        MaterialKind::Conductor {
            ior,
            specular_reflectance,
        } => {
            params = ior.k.extend(0.0);
            (
                MAT_CONDUCTOR,
                specular_reflectance.extend(0.0),
                ior.eta.extend(0.0),
            )
        }
        MaterialKind::RoughConductor {
            distribution,
            alpha_u,
            alpha_v,
            ior,
            specular_reflectance,
            ..
        } => {
            params = ior.k.extend(microfacet_id(*distribution) as f32);
            // Mitsuba clamps the roughness likewise (a smooth surface is a `conductor`)
            (
                MAT_ROUGHCONDUCTOR,
                specular_reflectance.extend(alpha_u.max(MIN_MICROFACET_ALPHA)),
                ior.eta.extend(alpha_v.max(MIN_MICROFACET_ALPHA)),
            )
        }
        MaterialKind::RoughDielectric {
            distribution,
            alpha_u,
            alpha_v,
            ior,
            specular_reflectance,
            specular_transmittance,
            ..
        } => {
            params = Vec4::new(*ior, 0.0, 0.0, microfacet_id(*distribution) as f32);
            (
                MAT_ROUGHDIELECTRIC,
                specular_transmittance.extend(alpha_u.max(MIN_MICROFACET_ALPHA)),
                specular_reflectance.extend(alpha_v.max(MIN_MICROFACET_ALPHA)),
            )
        }
        MaterialKind::ThinDielectric {
            ior,
            specular_reflectance,
            specular_transmittance,
        } => (
            MAT_THINDIELECTRIC,
            specular_transmittance.extend(*ior),
            specular_reflectance.extend(0.0),
        ),
        MaterialKind::Plastic {
            diffuse_reflectance,
            specular_reflectance,
            ior,
            nonlinear,
        } => {
            // Mitsuba's lobe choice steers by the mean colours of the two
            // layers (a texture counts as white: the choice changes the
            // noise, not the image)
            let d_mean = constant(diffuse_reflectance).element_sum() / 3.0;
            let s_mean = specular_reflectance.element_sum() / 3.0;
            let weight = s_mean / (d_mean + s_mean);
            params = Vec4::new(
                fresnel_diffuse_reflectance(1.0 / *ior),
                if *nonlinear { 1.0 } else { 0.0 },
                0.0,
                0.0,
            );
            (
                MAT_PLASTIC,
                constant(diffuse_reflectance).extend(*ior),
                specular_reflectance.extend(weight),
            )
        }
        MaterialKind::RoughPlastic {
            distribution,
            alpha,
            diffuse_reflectance,
            specular_reflectance,
            ior,
            nonlinear,
        } => {
            // Mitsuba's lobe choice steers by the mean colours of the two
            // layers (a texture counts as white: the choice changes the
            // noise, not the image)
            let d_mean = constant(diffuse_reflectance).element_sum() / 3.0;
            let s_mean = specular_reflectance.element_sum() / 3.0;
            let weight = s_mean / (d_mean + s_mean);
            let alpha = alpha.max(MIN_MICROFACET_ALPHA);
            let (first, internal) = tables.coating(*distribution, alpha, *ior);
            table = first;
            params = Vec4::new(
                internal,
                if *nonlinear { 1.0 } else { 0.0 },
                alpha,
                microfacet_id(*distribution) as f32,
            );
            (
                MAT_ROUGHPLASTIC,
                constant(diffuse_reflectance).extend(*ior),
                specular_reflectance.extend(weight),
            )
        }
        // The base colour (white under a texture) and eta; the GGX alphas,
        // metallic and the specular tint; sheen, its tint, the clearcoat
        // and its GTR1 alpha; in a texel of its own, the roughness (for
        // the retro-reflection), flatness and the lobes' probabilities
        MaterialKind::Principled(p) => {
            let (ax, ay) = p.alphas();
            let (pd, pc) = p.lobe_probabilities();
            table = tables.push([[p.roughness, p.flatness, pd, pc].map(f32::to_bits)]);
            // Where a texture gives some weight, every weight and the
            // sampling rates follow (the textures' indices are set with
            // the textures): the kernels compute the alphas and the
            // probabilities at each hit
            if p.weight_textures.is_some() {
                let words: Vec<u32> = (p.weights().into_iter().chain(p.sampling_rates))
                    .map(|x| (x + 0.0).to_bits())
                    .collect();
                tables.push(words.chunks_exact(4).map(|q| [q[0], q[1], q[2], q[3]]));
            }
            params = Vec4::new(p.sheen, p.sheen_tint, p.clearcoat, p.clearcoat_alpha());
            (
                MAT_PRINCIPLED,
                constant(&p.base_color).extend(p.eta),
                Vec4::new(ax, ay, p.metallic, p.spec_tint),
            )
        }
        // The weight's constant value (Mitsuba's `eval_1`); a texture's
        // index is set with the textures, the components' first index
        // (`info.w`) with the material table
        MaterialKind::Blend { weight, .. } => (
            MAT_BLEND,
            Vec4::new(
                crate::scene::mitsuba_constant_value(constant(weight)),
                0.0,
                0.0,
                0.0,
            ),
            Vec4::ZERO,
        ),
    };
    let emissive = m.emission.max_element() > 0.0;
    GpuMaterial {
        color,
        specular,
        emission: m.emission.extend(if emissive { 1.0 } else { 0.0 }),
        info: UVec4::new(
            ty,
            NO_TEXTURE,
            match m.sides {
                // A dielectric takes its side from the geometric normal
                _ if m.kind.transmits() => 0,
                Sides::Both => 0,
                Sides::Shading => MAT_FLAG_SHADING_SIDE,
                Sides::Front => MAT_FLAG_SHADING_SIDE | MAT_FLAG_FRONT_ONLY,
            } | if m.opacity.is_some() {
                MAT_FLAG_MASKED
            } else {
                0
            } | m.normal_map.as_ref().map_or(0, |n| {
                MAT_FLAG_NORMAL_MAP
                    | if n.wraps_two_sided {
                        MAT_FLAG_NORMAL_MAP_MIRRORED
                    } else {
                        0
                    }
                    | if n.shadowing {
                        MAT_FLAG_NORMAL_MAP_SHADOWING
                    } else {
                        0
                    }
                    | if n.bump_scale.is_some() {
                        MAT_FLAG_BUMP_MAP
                    } else {
                        0
                    }
            }) | match &m.kind {
                MaterialKind::Principled(p) if p.weight_textures.is_some() => {
                    MAT_FLAG_WEIGHT_TEXTURES
                }
                _ => 0,
            },
            table,
        ),
        params,
        // The texture indices are set with the textures
        layers: UVec4::new(
            m.opacity.as_ref().map_or(0, |c| {
                crate::scene::mitsuba_constant_value(constant(c)).to_bits()
            }),
            NO_TEXTURE,
            NO_TEXTURE,
            (m.normal_map.as_ref())
                .and_then(|n| n.bump_scale)
                .map_or(0, f32::to_bits),
        ),
    }
}

/// The power of a delta light over pi, the unit the area emitters are
/// weighed in: 4 I for a point light; for a spot, I times the solid angle
/// its falloff integrates to over 2 pi (full within beam width b, linear
/// in angle to 0 at cutoff c: 1 - (sin c - sin b) / (c - b)), times its
/// texture's mean `texture_mean` (white without one); for a projector
/// scale E times the area of its image plane at distance 1, E its
/// irradiance colour or its image's mean; for a directional light E r^2,
/// r the radius of the scene's bounding sphere (the disc of light that
/// reaches the scene, as pbrt weighs it). A texture's mean stands for its
/// integral over the light's directions: a weight for choosing lights,
/// which any positive value keeps unbiased.
fn light_power(light: &DeltaLight, texture_mean: Vec3, scene_box: Aabb) -> f32 {
    let tint = luminance(texture_mean);
    match *light {
        // pi scale E A over pi, A the image plane's area at distance 1
        DeltaLight::Projector {
            ref irradiance,
            scale,
            cot_x,
            cot_y,
            ..
        } => luminance(projector_factor(irradiance)) * tint * scale * 4.0 / (cot_x * cot_y),
        DeltaLight::Point { intensity, .. } => 4.0 * luminance(intensity),
        DeltaLight::Spot {
            intensity,
            cutoff_deg,
            beam_width_deg,
            ..
        } => {
            let (c, b) = (
                f64::from(cutoff_deg).to_radians(),
                f64::from(beam_width_deg).to_radians(),
            );
            let cone = if c - b > 1e-6 {
                1.0 - (c.sin() - b.sin()) / (c - b)
            } else {
                1.0 - c.cos()
            };
            (2.0 * cone) as f32 * luminance(intensity) * tint
        }
        DeltaLight::Directional { irradiance, .. } => {
            let r = scene_radius(scene_box);
            r * r * luminance(irradiance)
        }
    }
}

/// The radius of the scene's bounding sphere (half the box's diagonal); 0
/// for an empty scene.
fn scene_radius(scene_box: Aabb) -> f32 {
    if scene_box.min.cmple(scene_box.max).all() {
        0.5 * (scene_box.max - scene_box.min).length()
    } else {
        0.0
    }
}

/// The colour a projector's packed irradiance holds: its constant colour,
/// or 1 where an image gives it (the kernel multiplies by the image).
fn projector_factor(irradiance: &ColorSource) -> Vec3 {
    match irradiance {
        ColorSource::Constant(c) => *c,
        _ => Vec3::ONE,
    }
}

/// Packs one delta light, whose texture (a spot's, a projector's
/// irradiance image) has index `texture` (`NO_TEXTURE` for none).
fn pack_light(light: &DeltaLight, texture: u32) -> GpuDeltaLight {
    let kind = |k: u32| f32::from_bits(k);
    let extra = Vec4::new(0.0, 0.0, 0.0, f32::from_bits(texture));
    match *light {
        DeltaLight::Point {
            position,
            intensity,
        } => GpuDeltaLight {
            p: position.extend(kind(LIGHT_POINT)),
            intensity: intensity.extend(0.0),
            extra,
            ..GpuDeltaLight::zeroed()
        },
        DeltaLight::Projector {
            position,
            to_local,
            ref irradiance,
            scale,
            cot_x,
            cot_y,
        } => GpuDeltaLight {
            p: position.extend(kind(LIGHT_PROJECTOR)),
            intensity: (std::f32::consts::PI * scale * projector_factor(irradiance))
                .extend(0.5 * cot_x),
            local_x: to_local.row(0).extend(0.5 * cot_y),
            local_y: to_local.row(1).extend(0.0),
            local_z: to_local.row(2).extend(0.0),
            // Its axis, Mitsuba's to_world applied to +z
            extra: (to_local.inverse() * Vec3::Z).extend(extra.w),
        },
        DeltaLight::Spot {
            position,
            to_local,
            intensity,
            cutoff_deg,
            beam_width_deg,
            ..
        } => {
            let (c, b) = (
                f64::from(cutoff_deg).to_radians(),
                f64::from(beam_width_deg).to_radians(),
            );
            let inv_transition = if c > b { 1.0 / (c - b) } else { 0.0 };
            GpuDeltaLight {
                p: position.extend(kind(LIGHT_SPOT)),
                intensity: intensity.extend(c.cos() as f32),
                local_x: to_local.row(0).extend(b.cos() as f32),
                local_y: to_local.row(1).extend(c.sin() as f32),
                local_z: to_local.row(2).extend(inv_transition as f32),
                extra,
            }
        }
        DeltaLight::Directional {
            direction,
            irradiance,
        } => GpuDeltaLight {
            p: direction.extend(kind(LIGHT_DIRECTIONAL)),
            intensity: irradiance.extend(0.0),
            extra,
            ..GpuDeltaLight::zeroed()
        },
    }
}

/// What packing needs to know beyond the scene: the device's limits and
/// the renderer's choices, which the frame constants record.
#[derive(Debug, Clone, Copy)]
pub struct PackOptions {
    /// Bytes the one texel binding may hold; larger textures are shrunk.
    pub max_texture_bytes: u64,
    /// Paths per wave (`GpuFrame::wave_capacity`).
    pub wave_capacity: u32,
    /// Samples are read at counts not known in advance, with an error
    /// estimate: no stratification by the scene's spp (`GpuFrame::strata` is
    /// 0), and the Sobol sampler's two independent halves
    /// (`GpuFrame::halves` is 1).
    pub progressive: bool,
    /// How next-event estimation picks a light.
    pub light_selection: LightSelection,
}

/// How next-event estimation picks one light of the scene (area emitters,
/// delta lights and the environment map alike).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum LightSelection {
    /// In proportion to its power (the default).
    #[default]
    Power,
    /// Each light with the same probability.
    Uniform,
}

impl LightSelection {
    /// The name `converge --vary light_selection=...` takes.
    pub fn name(self) -> &'static str {
        match self {
            LightSelection::Power => "power",
            LightSelection::Uniform => "uniform",
        }
    }
}

impl std::str::FromStr for LightSelection {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "power" => Ok(LightSelection::Power),
            "uniform" => Ok(LightSelection::Uniform),
            _ => Err(format!("light selection {s:?}: power or uniform")),
        }
    }
}

impl Default for PackOptions {
    /// No texture limit, one path per wave, stratified samples.
    fn default() -> Self {
        PackOptions {
            max_texture_bytes: u64::MAX,
            wave_capacity: 1,
            progressive: false,
            light_selection: LightSelection::Power,
        }
    }
}

impl GpuScene {
    /// Builds the BVH, loads the textures (shrunk, with a warning, where
    /// they exceed `options.max_texture_bytes`, the device's binding limit)
    /// and packs `scene` for the device. The frame constants are final:
    /// nothing changes them afterwards.
    pub fn pack(scene: &Scene, options: &PackOptions) -> anyhow::Result<GpuScene> {
        let textures = pack_textures(scene, options.max_texture_bytes)?;
        let mut environment = match &scene.envmap {
            Some(env) => GpuEnvironment::pack(env, options.max_texture_bytes)?,
            None => GpuEnvironment::none(),
        };
        let n_sph = scene.spheres.len();
        // Bound every primitive: spheres first, then triangles.
        let mut boxes: Vec<Aabb> = Vec::with_capacity(n_sph + scene.triangles.len());
        boxes.extend(
            scene
                .spheres
                .iter()
                .map(|s| Aabb::of_sphere(s.center, s.radius)),
        );
        boxes.extend(
            scene
                .triangles
                .iter()
                .map(|t| Aabb::of_triangle(t.p[0], t.p[1], t.p[2])),
        );
        let started = std::time::Instant::now();
        let mut bvh: Bvh = crate::accel::bvh::build(&boxes);
        let bvh_seconds = started.elapsed().as_secs_f64();
        let bvh_depth = bvh.depth();
        let bvh_sah_cost = bvh.sah_cost();
        if bvh.nodes.is_empty() {
            // No primitives: a placeholder root that the kernels never
            // visit, since `GpuFrame::primitive_count` is 0.
            bvh.nodes.push(crate::accel::bvh::BvhNode {
                min: Vec3::splat(1.0),
                max: Vec3::splat(-1.0),
                left_or_first: 0,
                count: 0,
            });
        }

        // The scene's materials, then the blends' components
        let components = crate::scene::blend_components(&scene.materials);
        let table_len = scene.materials.len() + components.len();
        let mut tables = MaterialTables {
            first_texel: table_len as u32 * MATERIAL_TEXELS,
            ..MaterialTables::default()
        };
        let mut next_component = scene.materials.len() as u32;
        let mut materials: Vec<GpuMaterial> = Vec::with_capacity(table_len);
        for (m, layers) in scene.materials.iter().zip(&textures.material_layers) {
            let &[tex, opacity, normals, roughness_v, ..] = layers;
            let mut g = pack_material(m, &mut tables);
            tables.set_weight_textures(&g, layers);
            g.info.y = tex;
            g.layers.y = opacity;
            g.layers.z = normals;
            match m.kind {
                MaterialKind::Blend { .. } => {
                    g.info.w = next_component;
                    next_component += 2;
                }
                MaterialKind::RoughConductor { .. } | MaterialKind::RoughDielectric { .. } => {
                    g.info.w = roughness_v;
                }
                _ => {}
            }
            materials.push(g);
        }
        for (kind, layers) in components.iter().zip(&textures.component_layers) {
            let &[tex, _, _, roughness_v, ..] = layers;
            let mut g = pack_material(&component_material(kind), &mut tables);
            tables.set_weight_textures(&g, layers);
            g.info.y = tex;
            if let MaterialKind::RoughConductor { .. } = kind {
                g.info.w = roughness_v;
            }
            materials.push(g);
        }
        let material_texels: Vec<[u32; 4]> = bytemuck::cast_slice(&materials)
            .iter()
            .copied()
            .chain(tables.texels)
            .collect();
        let tri_shading: Vec<GpuTriShading> = scene
            .triangles
            .iter()
            .map(|t| {
                let n = t.n.unwrap_or([Vec3::ZERO; 3]);
                let uv = t.uv.unwrap_or([glam::Vec2::ZERO; 3]);
                GpuTriShading {
                    n0: n[0].extend(uv[0].x),
                    n1: n[1].extend(uv[1].x),
                    n2: n[2].extend(uv[2].x),
                    v: Vec4::new(uv[0].y, uv[1].y, uv[2].y, 0.0),
                }
            })
            .collect();

        // Lay primitives out in leaf order, and weigh emitters by power.
        let mut primitives = Vec::with_capacity(bvh.prim_order.len());
        let mut emitters = Vec::new();
        for (slot, &orig) in bvh.prim_order.iter().enumerate() {
            let orig = orig as usize;
            let (prim, area, material) = if orig < n_sph {
                let s = &scene.spheres[orig];
                let (flags, b, c) = match s.mitsuba_frame {
                    Some([x, y, z]) => {
                        let handed = if x.cross(y).dot(z) < 0.0 { -1.0 } else { 1.0 };
                        (PRIM_FLAG_MITSUBA_FRAME, x.extend(handed), y.extend(0.0))
                    }
                    None => (0, Vec4::ZERO, Vec4::ZERO),
                };
                let p = GpuPrimitive {
                    a: s.center.extend(s.radius),
                    b,
                    c,
                    meta: UVec4::new(pack_prim_kind(PRIM_SPHERE, flags), s.material, 0, 0),
                };
                (
                    p,
                    4.0 * std::f32::consts::PI * s.radius * s.radius,
                    s.material,
                )
            } else {
                let ti = orig - n_sph;
                let t = &scene.triangles[ti];
                let flags = if t.n.is_some() { PRIM_FLAG_NORMALS } else { 0 }
                    | if t.uv.is_some() { PRIM_FLAG_UVS } else { 0 };
                let p = GpuPrimitive {
                    a: t.p[0].extend(plane_offset(t.p[0], t.p[1], t.p[2])),
                    b: t.p[1].extend(0.0),
                    c: t.p[2].extend(0.0),
                    meta: UVec4::new(
                        pack_prim_kind(PRIM_TRIANGLE, flags),
                        t.material,
                        ti as u32,
                        0,
                    ),
                };
                let area = triangle_area(t.p[0], t.p[1], t.p[2]);
                (p, area, t.material)
            };
            let power = luminance(scene.materials[material as usize].emission) * area;
            if power > 0.0 && power.is_finite() {
                emitters.push((slot as u32, power, area));
            }
            primitives.push(prim);
        }
        // Delta lights follow, weighed by power over pi, as the area
        // emitters are (an area emitter of radiance L sends pi L A).
        let scene_box = boxes.iter().fold(Aabb::EMPTY, |a, &b| a.union(b));
        let lights: Vec<GpuDeltaLight> = (scene.lights.iter().zip(&textures.light_textures))
            .map(|(light, &texture)| pack_light(light, texture))
            .collect();
        for (k, (light, &mean)) in scene.lights.iter().zip(&textures.light_means).enumerate() {
            let power = light_power(light, mean, scene_box);
            if power > 0.0 && power.is_finite() {
                emitters.push((DELTA_LIGHT_FLAG | k as u32, power, 0.0));
            }
        }
        // The environment map last, weighed as a directional light from
        // every direction (GpuEnvironment::power)
        if scene.envmap.is_some() {
            let power = environment.power(scene_radius(scene_box));
            if power > 0.0 && power.is_finite() {
                emitters.push((ENVMAP_EMITTER, power, 0.0));
            }
        }
        // Each light the same weight, where selection is uniform
        if options.light_selection == LightSelection::Uniform {
            for e in &mut emitters {
                e.1 = 1.0;
            }
        }
        let total: f64 = emitters.iter().map(|e| e.1 as f64).sum();
        let mut acc = 0.0f64;
        let emitters: Vec<GpuEmitter> = emitters
            .iter()
            .map(|&(prim, power, area)| {
                acc += power as f64;
                let pmf = (power as f64 / total) as f32;
                if prim == ENVMAP_EMITTER {
                    environment.set_pick_probability(pmf);
                } else if prim & DELTA_LIGHT_FLAG == 0 {
                    primitives[prim as usize].meta.w = pmf.to_bits();
                }
                GpuEmitter {
                    prim,
                    cdf: (acc / total) as f32,
                    pmf,
                    area,
                }
            })
            .collect();
        let mut emitters = emitters;
        if let Some(last) = emitters.last_mut() {
            last.cdf = 1.0;
        }

        let (grid, pairs) = if scene.spheres.is_empty() && scene.triangles.is_empty() {
            (GpuBvhGrid::zeroed(), Vec::new())
        } else {
            crate::gpu::bvh_grid::pack(&bvh)?
        };
        let gpu_bvh: Vec<GpuBvhPair> = std::iter::once(bytemuck::cast(grid)).chain(pairs).collect();

        let emitter_texels: Vec<[u32; 4]> = bytemuck::cast_slice(&emitters)
            .iter()
            .chain(bytemuck::cast_slice(&lights))
            .copied()
            .collect();
        Ok(GpuScene {
            frame: pack_frame(
                scene,
                emitters.len() as u32,
                environment.max_radiance,
                options,
            )?,
            bvh: gpu_bvh,
            bvh_nodes: bvh.nodes.len(),
            primitives,
            tri_shading,
            materials,
            material_texels,
            emitters,
            lights,
            emitter_texels,
            bvh_depth,
            bvh_sah_cost,
            bvh_seconds,
            prim_order: bvh.prim_order.clone(),
            textures,
            environment,
        })
    }
}

/// Camera basis and render settings, checked as the device will use them:
/// the basis is built in f64 ([`Camera::basis`](crate::scene::Camera::basis))
/// and the pixel count in u64, so neither can collapse or wrap. The image
/// size is checked again here because the command line may change it after
/// the scene was read.
fn pack_frame(
    scene: &Scene,
    emitter_count: u32,
    envmap_max_radiance: f32,
    options: &PackOptions,
) -> Result<GpuFrame, SceneError> {
    let cam = &scene.camera;
    let r = &scene.render;
    let invalid = |key: &str, reason: String| SceneError::Invalid {
        path: scene.source.clone(),
        line: None,
        key: key.to_string(),
        reason,
    };
    let pixel_count = r.check().map_err(|(key, reason)| {
        let keys = if key == "width" || key == "height" {
            " (render.width, render.height)"
        } else {
            ""
        };
        invalid(&format!("render.{key}"), format!("{reason}{keys}"))
    })?;
    // The environment map's brightest texel counts as the environment
    let environment = scene.environment.max(Vec3::splat(envmap_max_radiance));
    crate::scene::limits::check_path_gain(&scene.materials, environment, r.max_depth)
        .map_err(|e| invalid(&e.key(&scene.materials), e.reason))?;
    let basis = cam
        .basis()
        .map_err(|(key, reason)| invalid(&format!("camera.{key}"), reason))?;
    let tan_half = (cam.vfov_deg as f64).to_radians() * 0.5;
    let tan_half = tan_half.tan();
    let aspect = r.width as f64 / r.height as f64;
    let (tan_v, tan_u) = (tan_half as f32, (tan_half * aspect) as f32);
    if !(cam.vfov_deg > 0.0 && cam.vfov_deg < 180.0 && tan_v > 0.0 && tan_u.is_finite()) {
        return Err(invalid(
            "camera.vfov",
            format!(
                "must be > 0 and < 180 (degrees) with a finite field of view at a {} x {} \
                 image, got {}",
                r.width, r.height, cam.vfov_deg
            ),
        ));
    }
    let strata = (r.spp as f64).sqrt().round() as u64;
    let strata = if strata * strata == r.spp as u64 && !options.progressive {
        strata as u32
    } else {
        0
    };
    let primitive_count =
        u32::try_from(scene.spheres.len() + scene.triangles.len()).map_err(|_| {
            invalid(
                "objects",
                format!(
                    "{} spheres and {} triangles are more primitives than 32-bit indices \
                     address",
                    scene.spheres.len(),
                    scene.triangles.len()
                ),
            )
        })?;
    let filter = &r.filter;
    let (filter_kind, filter_params, filter_table) = pack_filter(filter);
    let filter_edge = pack_filter_edge(filter, r.filter_inside_film);
    let clip = if cam.has_clip() {
        if !(cam.near_clip >= 0.0 && cam.far_clip > cam.near_clip) {
            return Err(invalid(
                "camera.near_clip",
                format!(
                    "must be >= 0 and below camera.far_clip, got {} and {}",
                    cam.near_clip, cam.far_clip
                ),
            ));
        }
        let ortho = if cam.orthographic.is_some() { 1.0 } else { 0.0 };
        Vec4::new(cam.near_clip, cam.far_clip.min(f32::MAX), 1.0, ortho)
    } else {
        Vec4::ZERO
    };
    // An orthographic camera: the near plane's centre, its half extents
    // (as unit tangents) and the rays' direction
    let (eye, cam_u, cam_v, cam_w) = match &cam.orthographic {
        Some(o) => (
            o.origin.extend(0.0),
            o.right.extend(1.0),
            o.up.extend(1.0),
            (-o.dir).extend(cam.focus_distance),
        ),
        None => (
            cam.eye.extend(cam.aperture_radius),
            basis.u.extend(tan_u),
            basis.v.extend(tan_v),
            basis.w.extend(cam.focus_distance),
        ),
    };
    if cam.orthographic.is_some() && clip.w != 1.0 {
        return Err(invalid(
            "camera.near_clip",
            String::from("an orthographic camera needs its near and far planes"),
        ));
    }
    Ok(GpuFrame {
        eye,
        cam_u,
        cam_v,
        cam_w,
        environment: scene.environment.extend(0.0),
        width: r.width,
        height: r.height,
        spp: r.spp,
        max_depth: r.max_depth,
        seed: r.seed,
        strata,
        emitter_count,
        wave_capacity: options.wave_capacity,
        pixel_count,
        primitive_count,
        filter_kind,
        path_flags: if r.hide_emitters {
            PATH_FLAG_HIDE_EMITTERS
        } else {
            0
        } | if r.emitter_sampling_only {
            PATH_FLAG_EMITTER_SAMPLING_ONLY
        } else {
            0
        },
        delta_light_gain: r.delta_light_gain as f32,
        rr_depth: r.rr_depth,
        halves: u32::from(options.progressive),
        pad2: 0,
        filter_params,
        clip,
        filter_table,
        filter_edge,
        cam_shift: (cam.shift[0] * cam_u.w * cam_u.truncate()
            + cam.shift[1] * cam_v.w * cam_v.truncate())
        .extend(0.0),
    })
}

/// `Frame.filter_edge`: the filter cut at the image's edge where film
/// positions stay inside the image (`PixelFilter::edge_table`); else every
/// entry is the uncut filter's, so nothing is cut even where the kernels
/// are built to cut (`--all-features`). Zeros for the box, which stays in
/// its pixel.
fn pack_filter_edge(
    filter: &PixelFilter,
    inside_film: bool,
) -> [Vec4; FILTER_EDGE_ENTRIES as usize] {
    let mut out = [Vec4::ZERO; FILTER_EDGE_ENTRIES as usize];
    if *filter == PixelFilter::Box {
        return out;
    }
    let table = filter.edge_table(&filter.table());
    let whole = table[FILTER_EDGE_ENTRIES as usize - 1];
    for (slot, e) in out.iter_mut().zip(&table) {
        let e = if inside_film { e } else { &whole };
        *slot = Vec4::new(e[0] as f32, e[1] as f32, e[2] as f32, e[3] as f32);
    }
    out
}

/// The pixel filter for the device: its kind (`FILTER_*`), its parameters
/// (`Frame.filter_params`) and its inverse-CDF table (zeros for the box, which
/// jitters inside the pixel).
fn pack_filter(filter: &PixelFilter) -> (u32, Vec4, [Vec4; FILTER_TABLE_VEC4S as usize]) {
    let mut table = [Vec4::ZERO; FILTER_TABLE_VEC4S as usize];
    let kind = match filter {
        PixelFilter::Box => return (FILTER_BOX, Vec4::ZERO, table),
        PixelFilter::Tent { .. } => FILTER_TENT,
        PixelFilter::Gaussian { .. } => FILTER_GAUSSIAN,
        PixelFilter::Mitchell { .. } => FILTER_MITCHELL,
        PixelFilter::Lanczos { .. } => FILTER_LANCZOS,
    };
    let radius = filter.radius();
    let (y, z) = match *filter {
        PixelFilter::Tent { radius } => (1.0 / radius, 0.0),
        PixelFilter::Gaussian { stddev } => {
            let alpha = -1.0 / (2.0 * (stddev as f64).powi(2));
            (alpha as f32, (alpha * radius * radius).exp() as f32)
        }
        PixelFilter::Mitchell { b, c } => (b, c),
        _ => (0.0, 0.0),
    };
    let t = filter.table();
    for (i, x) in t.x.iter().enumerate() {
        table[i / 4][i % 4] = *x as f32;
    }
    (
        kind,
        Vec4::new(radius as f32, y, z, t.inv_integral as f32),
        table,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Light selection by power weighs a textured light by its image's
    /// mean: a projector of an EXR image and a spot of an sRGB PNG are each
    /// picked as often as the same light with the image replaced by its
    /// mean colour (read by the image reader, not the texture packer), and
    /// not as often as with a white image.
    #[test]
    fn a_textured_light_is_weighed_by_its_images_mean() {
        for file in ["projector.xml", "spot_texture.xml"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/scenes/mitsuba")
                .join(file);
            let scene = crate::scene::load(&path).expect("the test scene loads");
            let pmfs = |scene: &Scene| {
                let packed = GpuScene::pack(scene, &PackOptions::default()).expect("packs");
                packed.emitters.iter().map(|e| e.pmf).collect::<Vec<f32>>()
            };
            let k = (scene.lights.iter())
                .position(|l| l.texture().is_some_and(|t| t.file().is_some()))
                .expect("a light with an image");
            let image = scene.lights[k].texture().and_then(|t| t.file()).unwrap();
            let (w, h, rgb) = crate::io::image_file::read_image(image).expect("reads");
            let n = f64::from(w * h);
            let mean = Vec3::from_array(std::array::from_fn(|c| {
                (rgb.chunks(3).map(|p| f64::from(p[c])).sum::<f64>() / n) as f32
            }));
            assert!(
                luminance(mean) < 0.9,
                "{file}: mean {mean}, too near white to tell"
            );
            let mut flat = scene.clone();
            match &mut flat.lights[k] {
                DeltaLight::Projector { irradiance, .. } => {
                    *irradiance = ColorSource::Constant(mean)
                }
                DeltaLight::Spot {
                    texture, intensity, ..
                } => {
                    *texture = None;
                    *intensity *= mean;
                }
                other => panic!("{file}: light {other:?}"),
            }
            let (textured, constant) = (pmfs(&scene), pmfs(&flat));
            assert_eq!(textured.len(), constant.len());
            for (a, b) in textured.iter().zip(&constant) {
                assert!(
                    (a - b).abs() <= 1e-4 * b.max(1e-3),
                    "{file}: {textured:?} against {constant:?}"
                );
            }
            let mut white = scene.clone();
            if let DeltaLight::Projector { irradiance, .. } = &mut white.lights[k] {
                *irradiance = ColorSource::Constant(Vec3::ONE);
            } else if let DeltaLight::Spot { texture, .. } = &mut white.lights[k] {
                *texture = None;
            }
            assert_ne!(
                pmfs(&white),
                textured,
                "{file}: the image's mean changes nothing"
            );
        }
    }

    /// Next-event estimation picks lights in proportion to their power, or
    /// each with the same probability: the delta-light test scene's lights
    /// (an area emitter, a point, a spot and a directional light).
    #[test]
    fn lights_are_picked_by_power_or_uniformly() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/delta_lights.toml");
        let scene = crate::scene::load(&path).expect("the test scene loads");
        let pmfs = |light_selection| {
            let options = PackOptions {
                light_selection,
                ..PackOptions::default()
            };
            let packed = GpuScene::pack(&scene, &options).expect("packs");
            packed.emitters.iter().map(|e| e.pmf).collect::<Vec<f32>>()
        };
        let power = pmfs(LightSelection::Power);
        let uniform = pmfs(LightSelection::Uniform);
        assert!(power.len() >= 4, "{power:?}");
        let n = uniform.len() as f32;
        assert!(
            uniform.iter().all(|&p| (p - 1.0 / n).abs() < 1e-6),
            "{uniform:?}"
        );
        let most = power.iter().cloned().fold(0.0f32, f32::max);
        let least = power.iter().cloned().fold(1.0f32, f32::min);
        assert!(most > 2.0 * least, "the lights' powers differ: {power:?}");
        let sum: f32 = power.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5, "{power:?}");
    }
}
