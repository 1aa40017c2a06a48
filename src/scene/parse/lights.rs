//! The `[[lights]]` of a TOML scene: point, spot and directional lights,
//! which have no area (see [`DeltaLight`]).

use super::*;

/// Light types `[[lights]]` reads.
const LIGHT_TYPES: &[&str] = &["point", "spot", "directional"];

/// Mitsuba's default spot cutoff angle, degrees.
pub(crate) const DEFAULT_CUTOFF_DEG: f64 = 20.0;

/// Mitsuba's default spot beam width, as a fraction of the cutoff angle.
pub(crate) const DEFAULT_BEAM_FRACTION: f64 = 0.75;

/// World to light space of a light whose local +z is `axis` (unit): a
/// rotation, so its transpose; the falloff is symmetric about the axis, so
/// the choice of x and y does not matter.
pub(crate) fn frame_along(axis: DVec3) -> glam::Mat3 {
    let (x, y) = axis.any_orthonormal_pair();
    glam::DMat3::from_cols(x, y, axis).transpose().as_mat3()
}

/// Reads `[[lights]]`, if present.
pub(super) fn parse_lights(top: &Section) -> Result<Vec<DeltaLight>> {
    let ctx = top.ctx;
    let Some(v) = top.get("lights") else {
        return Ok(Vec::new());
    };
    let DeValue::Array(lights) = v.get_ref() else {
        return Err(ctx.wrong_type(v, "lights", "an array of tables [[lights]]"));
    };
    lights
        .iter()
        .enumerate()
        .map(|(i, v)| parse_light(ctx, i, v))
        .collect()
}

fn parse_light(ctx: &Ctx, i: usize, v: &Val) -> Result<DeltaLight> {
    let (mut s, kind) = Section::array_entry(ctx, "lights", i, v, LIGHT_TYPES)?;
    let allowed: &[&str] = match kind {
        "point" => &["type", "position", "intensity"],
        "spot" => &[
            "type",
            "position",
            "direction",
            "intensity",
            "cutoff_angle",
            "beam_width",
        ],
        "directional" => &["type", "direction", "irradiance"],
        other => {
            let mut reason = format!(
                "unknown light type `{}`; expected one of: {}",
                cut(other),
                LIGHT_TYPES.join(", ")
            );
            if let Some(close) = closest(other, LIGHT_TYPES) {
                reason += &format!(" (did you mean `{}`?)", cut(close));
            }
            return Err(ctx.err(s.line_of("type"), &s.key("type"), reason));
        }
    };
    s.desc = format!("{} (a {kind} light)", s.desc);
    s.check_keys(allowed)?;
    let point = "a point [x, y, z]";
    let colour = "a colour [r, g, b]";
    let direction = |s: &Section| {
        s.req("direction", "a non-zero vector [x, y, z]", |v, k| {
            let d = ctx.vec3(v, k)?;
            let n = d.normalize_or_zero();
            if n == DVec3::ZERO || !n.is_finite() {
                return Err(ctx.bad(
                    v,
                    k,
                    format!("must be a non-zero vector, got {}", ctx.snippet(v)),
                ));
            }
            Ok(n)
        })
    };
    let light = match kind {
        "point" => DeltaLight::Point {
            position: s.req("position", point, |v, k| ctx.vec3(v, k))?.as_vec3(),
            intensity: s.req("intensity", colour, |v, k| ctx.color(v, k))?,
        },
        "spot" => {
            let position = s.req("position", point, |v, k| ctx.vec3(v, k))?.as_vec3();
            let axis = direction(&s)?;
            let intensity = s.req("intensity", colour, |v, k| ctx.color(v, k))?;
            let cutoff = s
                .opt("cutoff_angle", |v, k| ctx.number(v, k))?
                .unwrap_or(DEFAULT_CUTOFF_DEG);
            let beam = s
                .opt("beam_width", |v, k| ctx.number(v, k))?
                .unwrap_or(cutoff * DEFAULT_BEAM_FRACTION);
            DeltaLight::Spot {
                position,
                to_local: frame_along(axis),
                intensity,
                cutoff_deg: cutoff as f32,
                beam_width_deg: beam as f32,
                texture: None,
            }
        }
        _ => DeltaLight::Directional {
            direction: direction(&s)?.as_vec3(),
            irradiance: s.req("irradiance", colour, |v, k| ctx.color(v, k))?,
        },
    };
    limits::check_light(&light).map_err(|(key, reason)| {
        let key = if key == "to_world" { "direction" } else { key };
        ctx.err(s.line_of(key), &s.key(key), reason)
    })?;
    Ok(light)
}
