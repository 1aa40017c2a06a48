//! Spectra given as wavelength:value pairs, turned into one linear sRGB
//! colour as Mitsuba 3's RGB variants turn them when they read a scene
//! (`spectrum_list_to_srgb`): the pairs, linear between them and nothing
//! outside them, are integrated against the CIE 1931 matching functions
//! (times the D65 illuminant for anything but an emitter's spectrum) at
//! 1000 evenly spaced wavelengths from 360 to 830 nm, and the XYZ colour
//! goes to sRGB. The tables are Mitsuba's own
//! ([`super::spectrum_tables`], printed by `tools/spectrum_tables.py`).

use glam::DVec3;

use super::spectrum_tables::{CIE_MAX, CIE_MIN, CIE_TABLE, CIE_Y_NORMALIZATION, XYZ_TO_SRGB};

/// Wavelengths Mitsuba's conversion sums over.
const STEPS: usize = 1000;

/// Table spacing, nm.
const TABLE_STEP: f64 = 5.0;

/// CIE 1931 x-bar, y-bar, z-bar and D65 at `nm` (within the tables),
/// linear between the table's entries.
fn cie_at(nm: f64) -> ([f64; 3], f64) {
    let s = (nm - CIE_MIN) / TABLE_STEP;
    let i = (s.floor().max(0.0) as usize).min(CIE_TABLE.len() - 2);
    let t = s - i as f64;
    let lerp =
        |k: usize| f64::from(CIE_TABLE[i][k]) * (1.0 - t) + f64::from(CIE_TABLE[i + 1][k]) * t;
    ([lerp(0), lerp(1), lerp(2)], lerp(3))
}

/// The linear sRGB colour of the spectrum through the points
/// (`wavelengths[i]`, `values[i]`), wavelengths increasing, as Mitsuba
/// computes it. `d65`: weigh by the D65 illuminant (every spectrum but an
/// emitter's); `bounded`: clamp to [0, 1] (a reflectance), else to
/// [0, inf) (a radiance, an index of refraction).
pub(crate) fn spectrum_to_rgb(
    wavelengths: &[f64],
    values: &[f64],
    bounded: bool,
    d65: bool,
) -> DVec3 {
    debug_assert!(wavelengths.len() == values.len() && wavelengths.len() >= 2);
    let (first, last) = (wavelengths[0], wavelengths[wavelengths.len() - 1]);
    let mut xyz = DVec3::ZERO;
    let mut j = 0;
    for i in 0..STEPS {
        let nm = CIE_MIN + (i as f64 / (STEPS - 1) as f64) * (CIE_MAX - CIE_MIN);
        if nm < first || nm > last {
            continue;
        }
        // The pair interval holding nm (wavelengths increase, and so does nm)
        while j + 2 < wavelengths.len() && wavelengths[j + 1] <= nm {
            j += 1;
        }
        let (x0, x1, y0, y1) = (wavelengths[j], wavelengths[j + 1], values[j], values[j + 1]);
        let mut y = (nm * y0 - x1 * y0 - nm * y1 + x0 * y1) / (x0 - x1);
        let (cmf, illuminant) = cie_at(nm);
        if d65 {
            y *= illuminant;
        }
        xyz += DVec3::from(cmf) * y;
    }
    xyz *= (CIE_MAX - CIE_MIN) / STEPS as f64 * CIE_Y_NORMALIZATION;
    let [cx, cy, cz] = XYZ_TO_SRGB.map(DVec3::from);
    let rgb = cx * xyz.x + cy * xyz.y + cz * xyz.z;
    rgb.clamp(
        DVec3::ZERO,
        DVec3::splat(if bounded { 1.0 } else { f64::INFINITY }),
    )
}

/// The luminance of a linear RGB colour as Mitsuba 3 takes it
/// (`mitsuba::luminance`, sRGB primaries): what the one-channel lookup of
/// an RGB bitmap (`eval_1`, e.g. a `mask`'s opacity) reads.
pub fn mitsuba_luminance(c: glam::Vec3) -> f32 {
    let [r, g, b] = crate::interface::MITSUBA_LUMINANCE;
    c.x * r + c.y * g + c.z * b
}

/// The one-channel value Mitsuba 3 reads from a constant colour (the
/// `eval_1` of its `srgb` spectrum in the RGB variants): the mean of its
/// channels, not its luminance.
pub fn mitsuba_constant_value(c: glam::Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spectrum_tables::MITSUBA_CASES;

    /// Every conversion Mitsuba 3.9.1 made (`tools/spectrum_tables.py`):
    /// reflectances, unbounded spectra and emitters' spectra, pairs past
    /// both ends of the tables, a jump within 1 nm and a narrow band.
    #[test]
    fn spectra_turn_into_mitsubas_rgb() {
        for (w, v, bounded, d65, expected) in MITSUBA_CASES {
            // Mitsuba sums partly in f32: agreement to 1e-5 of the colour
            let rgb = spectrum_to_rgb(w, v, *bounded, *d65);
            let scale = expected.iter().fold(1.0f64, |m, &c| m.max(f64::from(c)));
            for (got, want) in rgb.to_array().iter().zip(expected) {
                let want = f64::from(*want);
                assert!(
                    (got - want).abs() <= 1e-5 * scale,
                    "{w:?} {v:?} bounded {bounded} d65 {d65}: {rgb} against Mitsuba's {expected:?}"
                );
            }
        }
    }
}
