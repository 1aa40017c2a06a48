//! The passes of the wavefront, one kernel each, named with a verb, and the
//! megakernel that runs them all in one.
//!
//! A [`Pass`] names its kernel everywhere: the renderer method that records
//! it, the dispatch label (reused for timestamps, debug-utils regions and
//! allocation names), the rows of the stats table, the trace events and
//! `lancer info`.

use std::fmt;

use crate::shaders;

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
    /// [`PassRecord`](crate::stats::PassRecord)): rays for the passes that
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
        match self {
            Pass::Generate => shaders::GENERATE,
            Pass::Intersect => shaders::INTERSECT,
            Pass::Shade => shaders::SHADE,
            Pass::Shadow => shaders::SHADOW,
            Pass::Accumulate if film_fp64 => shaders::ACCUMULATE,
            Pass::Accumulate => shaders::ACCUMULATE_F32,
            Pass::Megakernel if film_fp64 => shaders::MEGAKERNEL,
            Pass::Megakernel => shaders::MEGAKERNEL_F32,
        }
    }
}

impl fmt::Display for Pass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
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
}
