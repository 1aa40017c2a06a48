//! The `[materials]` tables of a TOML scene.

use super::*;

/// `albedo` / `albedo_texture` (or `diffuse` / `diffuse_texture`): exactly one.
pub(super) fn color_or_texture(s: &Section, name: &str) -> Result<ColorSource> {
    let ctx = s.ctx;
    let tex_name = format!("{name}_texture");
    match (s.get(name), s.get(&tex_name)) {
        (Some(c), Some(t)) => {
            let (first, second, second_name) = if c.span().start < t.span().start {
                (name, t, tex_name.as_str())
            } else {
                (tex_name.as_str(), c, name)
            };
            Err(ctx.bad(
                second,
                &s.key(second_name),
                format!(
                    "`{first}` is also given (line {}); a material gives a colour or a \
                     texture, not both: remove one",
                    s.line_of(first).unwrap_or(0)
                ),
            ))
        }
        (Some(c), None) => Ok(ColorSource::Constant(ctx.color(c, &s.key(name))?)),
        (None, Some(t)) => {
            let path = ctx.readable_file(t, &s.key(&tex_name), "texture")?;
            Ok(ColorSource::Texture(path))
        }
        (None, None) => Err(s.missing(
            name,
            &format!("give {name} = [r, g, b] or {tex_name} = \"file.png\""),
        )),
    }
}

pub(super) fn parse_material(parent: &Section, name: &str, v: &Val) -> Result<Material> {
    let ctx = parent.ctx;
    let mut s = parent.table(name, v)?;
    let type_key = s.key("type");
    let type_val = s.require("type", &format!("one of {}", MATERIAL_TYPES.join(", ")))?;
    let kind_name = ctx.string(type_val, &type_key)?;
    let type_line = s.line_of("type");
    let allowed: &[&str] = match kind_name {
        "lambert" => &["type", "albedo", "albedo_texture", "emission", "sides"],
        "phong" => &[
            "type",
            "diffuse",
            "diffuse_texture",
            "specular",
            "exponent",
            "emission",
            "sides",
        ],
        "mirror" => &["type", "reflectance", "emission", "sides"],
        "glossy" => &["type", "reflectance", "cone_angle", "emission", "sides"],
        "dielectric" => &["type", "ior", "tint", "emission"],
        other => {
            let mut reason = format!(
                "unknown material type `{}`; expected one of: {}",
                cut(other),
                MATERIAL_TYPES.join(", ")
            );
            if let Some(close) = closest(other, MATERIAL_TYPES) {
                reason += &format!(" (did you mean `{}`?)", cut(close));
            }
            return Err(ctx.err(type_line, &type_key, reason));
        }
    };
    s.desc = format!("{} (a {kind_name} material)", s.desc);
    s.check_keys(allowed)?;

    let colour = "a colour [r, g, b]";
    let kind = match kind_name {
        "lambert" => MaterialKind::Lambert {
            albedo: color_or_texture(&s, "albedo")?,
        },
        "phong" => {
            let diffuse = color_or_texture(&s, "diffuse")?;
            let specular = s.req("specular", colour, |v, k| ctx.color(v, k))?;
            let exponent = s.req("exponent", "a number >= 0", |v, k| {
                let x = ctx.number(v, k)?;
                if x >= 0.0 {
                    Ok(x as f32)
                } else {
                    Err(ctx.bad(v, k, format!("must be >= 0, got {}", ctx.snippet(v))))
                }
            })?;
            check_phong_energy(&s, &diffuse, specular)?;
            MaterialKind::Phong {
                diffuse,
                specular,
                exponent,
            }
        }
        "mirror" => MaterialKind::Mirror {
            reflectance: s.req("reflectance", colour, |v, k| ctx.color(v, k))?,
        },
        "glossy" => MaterialKind::Glossy {
            reflectance: s.req("reflectance", colour, |v, k| ctx.color(v, k))?,
            cone_angle_deg: s.req(
                "cone_angle",
                "a number of degrees, 0 <= cone_angle < 90",
                |v, k| {
                    let x = ctx.number(v, k)?;
                    if (0.0..90.0).contains(&x) {
                        Ok(x as f32)
                    } else {
                        Err(ctx.bad(
                            v,
                            k,
                            format!("must be >= 0 and < 90 (degrees), got {}", ctx.snippet(v)),
                        ))
                    }
                },
            )?,
        },
        _ => MaterialKind::Dielectric {
            ior: s.req("ior", "a number > 0", |v, k| {
                let x = ctx.number(v, k)?;
                if x > 0.0 {
                    Ok(x as f32)
                } else {
                    Err(ctx.bad(v, k, format!("must be > 0, got {}", ctx.snippet(v))))
                }
            })?,
            tint: s.opt("tint", |v, k| ctx.color(v, k))?.unwrap_or(Vec3::ONE),
        },
    };
    let emission = s
        .opt("emission", |v, k| ctx.radiance(v, k))?
        .unwrap_or(Vec3::ZERO);
    let sides = s
        .opt("sides", |v, k| {
            let text = ctx.string(v, k)?;
            Sides::ALL
                .into_iter()
                .find(|x| x.name() == text)
                .ok_or_else(|| {
                    ctx.bad(
                        v,
                        k,
                        format!(
                            "expected \"both\", \"shading\" or \"front\", got {}",
                            ctx.snippet(v)
                        ),
                    )
                })
        })?
        .unwrap_or_default();
    Ok(Material {
        name: name.to_string(),
        kind,
        emission,
        sides,
    })
}

/// `diffuse + specular <= 1` per channel (only `specular <= 1` with a
/// diffuse texture, whose texels are at most 1 but not known here).
pub(super) fn check_phong_energy(s: &Section, diffuse: &ColorSource, specular: Vec3) -> Result<()> {
    let d = match diffuse {
        ColorSource::Constant(d) => *d,
        ColorSource::Texture(_) => Vec3::ZERO,
    };
    for (i, channel) in ["red", "green", "blue"].iter().enumerate() {
        let sum = d[i] as f64 + specular[i] as f64;
        if sum > 1.0 + ENERGY_SLACK {
            let reason = match diffuse {
                ColorSource::Constant(_) => format!(
                    "diffuse + specular must be <= 1 in every channel (the material would \
                     create energy), got {} + {} = {} in {channel}; lower diffuse or specular",
                    d[i],
                    specular[i],
                    d[i] + specular[i]
                ),
                ColorSource::Texture(_) => format!(
                    "specular must be <= 1 in every channel, got {} in {channel}",
                    specular[i]
                ),
            };
            return Err(s.ctx.err(s.line_of("specular"), &s.key("specular"), reason));
        }
    }
    Ok(())
}
