//! The sRGB transfer curve, shared by image files and texture loading.

/// Encodes one linear value with the exact piecewise sRGB transfer curve.
///
/// `x <= 0.0031308` maps to `12.92 x`, anything above to
/// `1.055 x^(1/2.4) - 0.055`. The input is not clamped: values below 0 stay
/// negative, values above 1 go above 1, and NaN stays NaN.
pub fn srgb_encode(x: f32) -> f32 {
    let x = f64::from(x);
    let y = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    y as f32
}

/// Decodes one sRGB-encoded value to linear with the exact piecewise curve,
/// the inverse of [`srgb_encode`].
///
/// `y <= 0.04045` maps to `y / 12.92`, anything above to
/// `((y + 0.055) / 1.055)^2.4`. The input is not clamped.
pub fn srgb_decode(y: f32) -> f32 {
    let y = f64::from(y);
    let x = if y <= 0.040_45 {
        y / 12.92
    } else {
        ((y + 0.055) / 1.055).powf(2.4)
    };
    x as f32
}

/// Converts one linear value to the 8-bit sRGB code stored in a PNG: clamp to
/// [0, 1], sRGB-encode, scale by 255 and round to nearest. NaN becomes 0.
pub fn to_srgb8(x: f32) -> u8 {
    if x.is_nan() {
        return 0;
    }
    let v = srgb_encode(x.clamp(0.0, 1.0));
    (v * 255.0).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_known_values() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        // Linear segment below the knee.
        assert!((srgb_encode(0.001) - 0.01292).abs() < 1e-7);
        // The two pieces meet at the knee (continuity to ~1e-7).
        assert!((srgb_encode(0.003_130_8) - 0.040_45).abs() < 1e-6);
        // Middle grey and 0.5, against values from the formula in f64.
        assert!((srgb_encode(0.18) - 0.461_356_1).abs() < 1e-6);
        assert!((srgb_encode(0.5) - 0.735_356_6).abs() < 1e-6);
        assert!((srgb_decode(0.5) - 0.214_041_14).abs() < 1e-6);
        assert!((srgb_decode(0.04045) - 0.003_130_8).abs() < 1e-7);
    }

    #[test]
    fn srgb_round_trips_every_8bit_level() {
        for i in 0..=255u32 {
            let y = i as f32 / 255.0;
            let back = (srgb_encode(srgb_decode(y)) * 255.0).round() as u32;
            assert_eq!(back, i);
            assert_eq!(to_srgb8(srgb_decode(y)), i as u8);
        }
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            assert!((srgb_decode(srgb_encode(x)) - x).abs() < 1e-6, "{x}");
        }
    }
}
