//! Mitsuba 3's named indices of refraction (`include/mitsuba/render/ior.h`,
//! Hecht's *Optics*, at about 589 nm), which a dielectric's `int_ior` and
//! `ext_ior` may give by name. Converted once, when the scene is read.

/// Every name Mitsuba 3.9.1 knows, lower case, and its index, in Mitsuba's
/// order.
pub(super) const IOR_PRESETS: &[(&str, f32)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

/// The index of refraction Mitsuba gives the name `name` (any case), if it
/// knows it.
pub(super) fn ior_preset(name: &str) -> Option<f32> {
    let lower = name.to_lowercase();
    IOR_PRESETS
        .iter()
        .find(|(n, _)| *n == lower)
        .map(|&(_, v)| v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_found_in_any_case_and_unknown_names_are_not() {
        assert_eq!(ior_preset("BK7"), Some(1.5046));
        assert_eq!(ior_preset("water"), Some(1.333));
        assert_eq!(ior_preset("Air"), Some(1.000277));
        assert_eq!(ior_preset("fused quartz"), Some(1.458));
        assert_eq!(ior_preset("glass"), None);
        assert_eq!(IOR_PRESETS.len(), 23);
    }
}
