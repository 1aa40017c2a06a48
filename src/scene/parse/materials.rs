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
        "conductor" => &[
            "type",
            "material",
            "eta",
            "k",
            "specular_reflectance",
            "emission",
        ],
        "roughconductor" => &[
            "type",
            "material",
            "eta",
            "k",
            "specular_reflectance",
            "distribution",
            "alpha",
            "alpha_u",
            "alpha_v",
            "emission",
        ],
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
        "conductor" => MaterialKind::Conductor {
            ior: complex_ior(&s)?,
            specular_reflectance: s
                .opt("specular_reflectance", |v, k| ctx.color(v, k))?
                .unwrap_or(Vec3::ONE),
        },
        "roughconductor" => {
            let distribution = match s.opt("distribution", |v, k| {
                let name = ctx.string(v, k)?;
                match name {
                    "beckmann" => Ok(Microfacet::Beckmann),
                    "ggx" => Ok(Microfacet::Ggx),
                    _ => Err(ctx.bad(
                        v,
                        k,
                        format!("unknown distribution `{}`; use beckmann or ggx", cut(name)),
                    )),
                }
            })? {
                Some(d) => d,
                None => Microfacet::Beckmann,
            };
            let (alpha_u, alpha_v) = roughness(&s)?;
            MaterialKind::RoughConductor {
                distribution,
                alpha_u,
                alpha_v,
                alpha_textures: None,
                ior: complex_ior(&s)?,
                specular_reflectance: s
                    .opt("specular_reflectance", |v, k| ctx.color(v, k))?
                    .unwrap_or(Vec3::ONE),
            }
        }
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
        opacity: None,
        normal_map: None,
    })
}

/// A conductor's `material` preset, or its `eta` and `k` (Mitsuba's rule:
/// not both; with neither, the perfect reflector, eta 0 and k 1).
fn complex_ior(s: &Section) -> Result<ComplexIor> {
    let ctx = s.ctx;
    let preset = s.opt("material", |v, k| {
        let name = ctx.string(v, k)?;
        conductor_preset(name).ok_or_else(|| {
            let names: Vec<&str> = conductor_preset_names().collect();
            let mut reason = format!(
                "unknown conductor preset `{}`; Mitsuba's presets are: {}",
                cut(name),
                names.join(", ")
            );
            if let Some(close) = closest(name, &names) {
                reason += &format!(" (did you mean `{}`?)", cut(close));
            }
            ctx.bad(v, k, reason)
        })
    })?;
    let eta = s.opt("eta", |v, k| ctx.color(v, k))?;
    let k = s.opt("k", |v, k| ctx.color(v, k))?;
    match preset {
        Some(ior) => {
            if let Some(name) = ["eta", "k"].into_iter().find(|n| s.get(n).is_some()) {
                return Err(ctx.err(
                    s.line_of(name),
                    &s.key(name),
                    "`material` is also given: give a preset or eta and k, not both",
                ));
            }
            Ok(ior)
        }
        None => Ok(ComplexIor {
            eta: eta.unwrap_or(ComplexIor::PERFECT.eta),
            k: k.unwrap_or(ComplexIor::PERFECT.k),
        }),
    }
}

/// A rough material's `alpha` (isotropic), or its `alpha_u` and `alpha_v`
/// (both); 0.1 by default, as in Mitsuba.
fn roughness(s: &Section) -> Result<(f32, f32)> {
    let ctx = s.ctx;
    let read = |name: &str| {
        s.opt(name, |v, k| {
            let x = ctx.number(v, k)?;
            if x >= 0.0 && x.is_finite() {
                Ok(x as f32)
            } else {
                Err(ctx.bad(v, k, format!("must be >= 0, got {}", ctx.snippet(v))))
            }
        })
    };
    let (alpha, u, v) = (read("alpha")?, read("alpha_u")?, read("alpha_v")?);
    match (alpha, u, v) {
        (Some(a), None, None) => Ok((a, a)),
        (None, None, None) => Ok((DEFAULT_ALPHA, DEFAULT_ALPHA)),
        (None, Some(u), Some(v)) => Ok((u, v)),
        (Some(_), _, _) => {
            let name = if u.is_some() { "alpha_u" } else { "alpha_v" };
            Err(ctx.err(
                s.line_of(name),
                &s.key(name),
                "`alpha` is also given: give alpha (isotropic) or alpha_u and alpha_v, not both",
            ))
        }
        (None, Some(_), None) | (None, None, Some(_)) => {
            let (given, other) = if u.is_some() {
                ("alpha_u", "alpha_v")
            } else {
                ("alpha_v", "alpha_u")
            };
            Err(ctx.err(
                s.line_of(given),
                &s.key(given),
                format!(
                    "`{other}` is missing: an anisotropic roughness needs both alpha_u and alpha_v"
                ),
            ))
        }
    }
}

/// Roughness of a rough material that gives none (Mitsuba's default).
const DEFAULT_ALPHA: f32 = 0.1;

/// `diffuse + specular <= 1` per channel (only `specular <= 1` with a
/// diffuse texture, whose texels are at most 1 but not known here).
pub(super) fn check_phong_energy(s: &Section, diffuse: &ColorSource, specular: Vec3) -> Result<()> {
    let d = match diffuse {
        ColorSource::Constant(d) => *d,
        ColorSource::Texture(_) | ColorSource::Mapped(_) | ColorSource::Attribute(_) => Vec3::ZERO,
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
                ColorSource::Texture(_) | ColorSource::Mapped(_) | ColorSource::Attribute(_) => {
                    format!(
                        "specular must be <= 1 in every channel, got {} in {channel}",
                        specular[i]
                    )
                }
            };
            return Err(s.ctx.err(s.line_of("specular"), &s.key("specular"), reason));
        }
    }
    Ok(())
}
