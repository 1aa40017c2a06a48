//! What a scene calls for, and therefore which kernels, code paths and
//! passes run. Kernels receive these as specialisation constants, so the
//! driver compiler drops code for effects the scene does not use.

use crate::pass::Pass;
use crate::render::Schedule;
use crate::scene::{ColorSource, MaterialKind, Scene};
use crate::shader_interface::*;

/// The estimator the shade pass uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Next-event estimation combined with BSDF sampling by MIS.
    #[default]
    Nee,
    /// BSDF sampling only: light is found only by hitting it.
    Bsdf,
}

/// The effects a scene calls for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Features {
    /// The scene has spheres.
    pub spheres: bool,
    /// The scene has triangles (quads or meshes).
    pub triangles: bool,
    /// Next-event estimation runs: there are emitters and the integrator is `nee`.
    pub nee: bool,
    /// Some surface emits.
    pub emission: bool,
    /// The environment is not black.
    pub environment: bool,
    /// Some material uses a texture.
    pub textures: bool,
    /// The camera has a thin lens.
    pub depth_of_field: bool,
    /// Bit `1 << MAT_*` set for each material type in use.
    pub material_mask: u32,
}

/// Names of the material types, indexed by `MAT_*`.
pub const MATERIAL_NAMES: [&str; 5] = ["lambert", "phong", "mirror", "glossy", "dielectric"];

impl Features {
    /// Detects the features `scene` calls for.
    pub fn detect(scene: &Scene, integrator: Integrator) -> Features {
        let used = |i: u32| {
            scene.spheres.iter().any(|s| s.material == i)
                || scene.triangles.iter().any(|t| t.material == i)
        };
        let mut material_mask = 0;
        let mut textures = false;
        let mut emission = false;
        for (i, m) in scene.materials.iter().enumerate() {
            if !used(i as u32) {
                continue;
            }
            let (ty, tex) = match &m.kind {
                MaterialKind::Lambert { albedo } => {
                    (MAT_LAMBERT, matches!(albedo, ColorSource::Texture(_)))
                }
                MaterialKind::Phong { diffuse, .. } => {
                    (MAT_PHONG, matches!(diffuse, ColorSource::Texture(_)))
                }
                MaterialKind::Mirror { .. } => (MAT_MIRROR, false),
                MaterialKind::Glossy { .. } => (MAT_GLOSSY, false),
                MaterialKind::Dielectric { .. } => (MAT_DIELECTRIC, false),
            };
            material_mask |= 1 << ty;
            textures |= tex;
            emission |= m.emission.max_element() > 0.0;
        }
        Features {
            spheres: !scene.spheres.is_empty(),
            triangles: !scene.triangles.is_empty(),
            nee: emission && integrator == Integrator::Nee,
            emission,
            environment: scene.environment.max_element() > 0.0,
            textures,
            depth_of_field: scene.camera.aperture_radius > 0.0,
            material_mask,
        }
    }

    /// Every feature on: the same image, at the cost of every code path.
    pub fn all(integrator: Integrator) -> Features {
        Features {
            spheres: true,
            triangles: true,
            nee: integrator == Integrator::Nee,
            emission: true,
            environment: true,
            textures: true,
            depth_of_field: true,
            material_mask: (1 << MATERIAL_NAMES.len()) - 1,
        }
    }

    /// Specialisation constants of `pass`'s kernel, as `(constant_id, value)`.
    /// Every kernel gets the scene's features; shadow also runs the
    /// traversal in occlusion (any-hit) mode.
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

#[cfg(test)]
mod tests {
    use super::*;

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
            let value = <Schedule as clap::ValueEnum>::to_possible_value(&s).unwrap();
            assert_eq!(value.get_name(), s.name());
        }
        assert_eq!(Schedule::ALL[0], Schedule::default());
        let err = "fused".parse::<Schedule>().unwrap_err().to_string();
        assert!(err.contains("wavefront or megakernel"), "{err}");
    }
}
