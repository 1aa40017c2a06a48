//! Writes a [`Scene`] back as a TOML scene (`lancer convert`): the file
//! and, for its triangles, OBJ files beside it.
//!
//! Every number is written so that the TOML loader reads back the very same
//! 32-bit value, and the triangles keep their order, so the written scene
//! renders bit for bit like the one it came from. (One exception: a vertex
//! normal is normalised again on loading, which may move its last bit.)
//! Triangles go to one OBJ file per run of triangles that share a material
//! and have the same attributes (normals, texture coordinates): a mesh
//! object takes one material.

use super::types::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The files of a converted scene: (path, contents), the TOML file first.
pub type Files = Vec<(PathBuf, Vec<u8>)>;

/// A 32-bit float in the shortest form that reads back exactly through
/// TOML's 64-bit floats.
fn num(x: f32) -> String {
    let short = format!("{x:?}");
    if short.parse::<f64>().map(|y| y as f32) == Ok(x) {
        short
    } else {
        format!("{:?}", f64::from(x))
    }
}

fn vec3(v: glam::Vec3) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

/// A TOML basic string (quoted, escaped), also usable as a quoted key.
/// States a rough material's roughness textures, which the TOML format
/// has no key for, as a comment: `lancer convert` refuses them first, and
/// the comment keeps them in the scene's hash.
fn alpha_comment(t: &mut String, textures: Option<&crate::scene::AlphaTextures>) {
    if let Some(a) = textures {
        let _ = writeln!(
            t,
            "# roughness textures that the TOML format cannot state: {a:?}"
        );
    }
}

fn quoted(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// The TOML text of `scene` and its OBJ files, to be written at `out`
/// (the OBJ files go to the folder `<out stem>_meshes` beside it).
pub fn to_toml(scene: &Scene, out: &Path) -> Files {
    let stem = out.file_stem().map_or_else(
        || String::from("scene"),
        |s| s.to_string_lossy().into_owned(),
    );
    let mesh_dir = format!("{stem}_meshes");
    let folder = out.parent().unwrap_or(Path::new("")).join(&mesh_dir);
    let r = &scene.render;
    let c = &scene.camera;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Converted by `lancer convert` from {}.\n",
        scene.source.display()
    );
    let filter = match r.filter {
        PixelFilter::Box => String::new(),
        PixelFilter::Tent { radius } => {
            format!("filter = {{ type = \"tent\", radius = {} }}\n", num(radius))
        }
        PixelFilter::Gaussian { stddev } => {
            format!(
                "filter = {{ type = \"gaussian\", stddev = {} }}\n",
                num(stddev)
            )
        }
        PixelFilter::Mitchell { b, c } => format!(
            "filter = {{ type = \"mitchell\", B = {}, C = {} }}\n",
            num(b),
            num(c)
        ),
        PixelFilter::Lanczos { lobes } => {
            format!("filter = {{ type = \"lanczos\", lobes = {lobes} }}\n")
        }
    };
    // The roulette start, where it is not the TOML default (a Mitsuba
    // scene's is Mitsuba's): the same noise after conversion
    let rr_depth = if r.rr_depth == DEFAULT_RR_DEPTH {
        String::new()
    } else {
        format!("rr_depth = {}\n", r.rr_depth)
    };
    let _ = writeln!(
        t,
        "[render]\nwidth = {}\nheight = {}\nspp = {}\nmax_depth = {}\nseed = {}\n{rr_depth}{filter}",
        r.width, r.height, r.spp, r.max_depth, r.seed
    );
    let _ = writeln!(
        t,
        "[camera]\neye = {}\nlook_at = {}\nup = {}\nvfov = {}\naperture_radius = {}\nfocus_distance = {}\n",
        vec3(c.eye),
        vec3(c.look_at),
        vec3(c.up),
        num(c.vfov_deg),
        num(c.aperture_radius),
        num(c.focus_distance)
    );
    if c.has_clip() {
        // Back over the blank line that ends the table
        t.pop();
        if c.near_clip > 0.0 {
            let _ = writeln!(t, "near_clip = {}", num(c.near_clip));
        }
        if c.far_clip.is_finite() {
            let _ = writeln!(t, "far_clip = {}", num(c.far_clip));
        }
        t.push('\n');
    }
    if r.hide_emitters || r.emitter_sampling_only || r.bsdf_sampling_only {
        let _ = writeln!(
            t,
            "# The source scene's integrator also had hide_emitters = {}, emitter sampling \
             only = {} and BSDF sampling only = {}, which TOML scenes do not express.\n",
            r.hide_emitters, r.emitter_sampling_only, r.bsdf_sampling_only
        );
    }
    if scene.environment != glam::Vec3::ZERO {
        let _ = writeln!(t, "[environment]\nradiance = {}\n", vec3(scene.environment));
    }
    if let Some(env) = &scene.envmap {
        // TOML scenes have no environment map (`lancer convert` refuses
        // one); the comment keeps it in the scene's hash.
        let m = env.to_local.to_cols_array().map(num);
        let _ = writeln!(
            t,
            "# The source scene also had an environment map, which TOML scenes do not \
             express: file {}, scale {}, to_local (columns) [{}].\n",
            env.file.display(),
            num(env.scale),
            m.join(", ")
        );
    }
    for m in &scene.materials {
        let _ = writeln!(t, "[materials.{}]", quoted(&m.name));
        let color = |t: &mut String, key: &str, c: &ColorSource| match c {
            ColorSource::Constant(v) => {
                let _ = writeln!(t, "{key} = {}", vec3(*v));
            }
            ColorSource::Texture(p) => {
                let p = std::path::absolute(p).unwrap_or_else(|_| p.clone());
                let _ = writeln!(t, "{key}_texture = {}", quoted(&p.to_string_lossy()));
            }
            // `lancer convert` refuses these first; the TOML format has no
            // key for them. The comment states it whole, for the scene's hash
            ColorSource::Mapped(m) => {
                let _ = writeln!(
                    t,
                    "# {key}: a Mitsuba texture that the TOML format cannot state: {m:?}"
                );
            }
            ColorSource::Attribute(a) => {
                let _ = writeln!(
                    t,
                    "# {key}: a Mitsuba mesh attribute that the TOML format cannot state: {a:?}"
                );
            }
        };
        match &m.kind {
            // `lancer convert` refuses a blend first; the TOML format has
            // no such material. The comment states it whole, for the hash
            MaterialKind::Blend { weight, components } => {
                let _ = writeln!(
                    t,
                    "type = \"blendbsdf\"\n# weight {weight:?}, components {components:?}"
                );
            }
            // Likewise for a principled material
            MaterialKind::Principled(p) => {
                let _ = writeln!(t, "type = \"principled\"\n# {p:?}");
            }
            MaterialKind::Lambert { albedo } => {
                let _ = writeln!(t, "type = \"lambert\"");
                color(&mut t, "albedo", albedo);
            }
            MaterialKind::Phong {
                diffuse,
                specular,
                exponent,
            } => {
                let _ = writeln!(t, "type = \"phong\"");
                color(&mut t, "diffuse", diffuse);
                let _ = writeln!(
                    t,
                    "specular = {}\nexponent = {}",
                    vec3(*specular),
                    num(*exponent)
                );
            }
            MaterialKind::Mirror { reflectance } => {
                let _ = writeln!(t, "type = \"mirror\"\nreflectance = {}", vec3(*reflectance));
            }
            MaterialKind::Glossy {
                reflectance,
                cone_angle_deg,
            } => {
                let _ = writeln!(
                    t,
                    "type = \"glossy\"\nreflectance = {}\ncone_angle = {}",
                    vec3(*reflectance),
                    num(*cone_angle_deg)
                );
            }
            MaterialKind::Dielectric { ior, tint } => {
                let _ = writeln!(
                    t,
                    "type = \"dielectric\"\nior = {}\ntint = {}",
                    num(*ior),
                    vec3(*tint)
                );
            }
            MaterialKind::Conductor {
                ior,
                specular_reflectance,
            } => {
                let _ = writeln!(
                    t,
                    "type = \"conductor\"\neta = {}\nk = {}\nspecular_reflectance = {}",
                    vec3(ior.eta),
                    vec3(ior.k),
                    vec3(*specular_reflectance)
                );
            }
            MaterialKind::RoughConductor {
                distribution,
                alpha_u,
                alpha_v,
                alpha_textures,
                ior,
                specular_reflectance,
            } => {
                let _ = writeln!(
                    t,
                    "type = \"roughconductor\"\ndistribution = \"{}\"\nalpha_u = {}\nalpha_v = {}\n\
                     eta = {}\nk = {}\nspecular_reflectance = {}",
                    distribution.name(),
                    num(*alpha_u),
                    num(*alpha_v),
                    vec3(ior.eta),
                    vec3(ior.k),
                    vec3(*specular_reflectance)
                );
                alpha_comment(&mut t, alpha_textures.as_deref());
            }
            // Not in the scene format: written so that the text names the
            // whole scene (`scene_hash`); `lancer convert` refuses it first
            MaterialKind::RoughDielectric {
                distribution,
                alpha_u,
                alpha_v,
                alpha_textures,
                ior,
                specular_reflectance,
                specular_transmittance,
            } => {
                let _ = writeln!(
                    t,
                    "type = \"roughdielectric\"\ndistribution = \"{}\"\nalpha_u = {}\nalpha_v = {}\n\
                     ior = {}\nspecular_reflectance = {}\nspecular_transmittance = {}",
                    distribution.name(),
                    num(*alpha_u),
                    num(*alpha_v),
                    num(*ior),
                    vec3(*specular_reflectance),
                    vec3(*specular_transmittance)
                );
                alpha_comment(&mut t, alpha_textures.as_deref());
            }
            MaterialKind::ThinDielectric {
                ior,
                specular_reflectance,
                specular_transmittance,
            } => {
                let _ = writeln!(
                    t,
                    "type = \"thindielectric\"\nior = {}\nspecular_reflectance = {}\n\
                     specular_transmittance = {}",
                    num(*ior),
                    vec3(*specular_reflectance),
                    vec3(*specular_transmittance)
                );
            }
            MaterialKind::Plastic {
                diffuse_reflectance,
                specular_reflectance,
                ior,
                nonlinear,
            } => {
                let _ = writeln!(t, "type = \"plastic\"");
                color(&mut t, "diffuse_reflectance", diffuse_reflectance);
                let _ = writeln!(
                    t,
                    "specular_reflectance = {}\nior = {}\nnonlinear = {nonlinear}",
                    vec3(*specular_reflectance),
                    num(*ior),
                );
            }
            MaterialKind::RoughPlastic {
                distribution,
                alpha,
                diffuse_reflectance,
                specular_reflectance,
                ior,
                nonlinear,
            } => {
                let _ = writeln!(
                    t,
                    "type = \"roughplastic\"\ndistribution = \"{}\"\nalpha = {}",
                    distribution.name(),
                    num(*alpha),
                );
                color(&mut t, "diffuse_reflectance", diffuse_reflectance);
                let _ = writeln!(
                    t,
                    "specular_reflectance = {}\nior = {}\nnonlinear = {nonlinear}",
                    vec3(*specular_reflectance),
                    num(*ior),
                );
            }
        }
        if m.emission != glam::Vec3::ZERO {
            let _ = writeln!(t, "emission = {}", vec3(m.emission));
        }
        if m.sides != Sides::Both && !m.kind.transmits() {
            let _ = writeln!(t, "sides = \"{}\"", m.sides.name());
        }
        if let Some(opacity) = &m.opacity {
            // `lancer convert` refuses a mask first; the comment keeps it in the scene's hash
            let _ = writeln!(
                t,
                "# a Mitsuba mask that the TOML format cannot state, opacity {opacity:?}"
            );
        }
        if let Some(map) = &m.normal_map {
            // `lancer convert` refuses a normal map first; the comment keeps it in the hash
            let _ = writeln!(
                t,
                "# a Mitsuba normalmap that the TOML format cannot state: {map:?}"
            );
        }
        t.push('\n');
    }
    for s in &scene.spheres {
        if let Some(frame) = &s.mitsuba_frame {
            // `lancer convert` refuses where it changes the image; the comment keeps it in the hash
            let _ = writeln!(
                t,
                "# Mitsuba's texture coordinates and tangent, in the frame {frame:?}"
            );
        }
        let _ = writeln!(
            t,
            "[[objects]]\ntype = \"sphere\"\ncenter = {}\nradius = {}\nmaterial = {}\n",
            vec3(s.center),
            num(s.radius),
            quoted(&scene.materials[s.material as usize].name)
        );
    }
    for light in &scene.lights {
        let _ = match *light {
            DeltaLight::Point {
                position,
                intensity,
            } => writeln!(
                t,
                "[[lights]]\ntype = \"point\"\nposition = {}\nintensity = {}\n",
                vec3(position),
                vec3(intensity)
            ),
            // `lancer convert` refuses a projector and a textured spot
            // first; the comment keeps them in the scene's hash
            DeltaLight::Projector { .. }
            | DeltaLight::Spot {
                texture: Some(_), ..
            } => writeln!(
                t,
                "# a Mitsuba light that the TOML format cannot state: {light:?}\n"
            ),
            DeltaLight::Spot {
                position,
                to_local,
                intensity,
                cutoff_deg,
                beam_width_deg,
                texture: None,
            } => writeln!(
                t,
                "[[lights]]\ntype = \"spot\"\nposition = {}\ndirection = {}\nintensity = {}\n\
                 cutoff_angle = {}\nbeam_width = {}\n",
                vec3(position),
                vec3(to_local.inverse() * glam::Vec3::Z),
                vec3(intensity),
                num(cutoff_deg),
                num(beam_width_deg)
            ),
            DeltaLight::Directional {
                direction,
                irradiance,
            } => writeln!(
                t,
                "[[lights]]\ntype = \"directional\"\ndirection = {}\nirradiance = {}\n",
                vec3(direction),
                vec3(irradiance)
            ),
        };
    }
    let mut files = Vec::new();
    let key = |tri: &Triangle| (tri.material, tri.n.is_some(), tri.uv.is_some());
    for run in scene.triangles.chunk_by(|a, b| key(a) == key(b)) {
        let name = format!("part{}.obj", files.len());
        let mut obj = String::from("# Written by `lancer convert`: world-space triangles.\n");
        for tri in run {
            for p in tri.p {
                let _ = writeln!(obj, "v {} {} {}", p.x, p.y, p.z);
            }
            for n in tri.n.iter().flatten() {
                let _ = writeln!(obj, "vn {} {} {}", n.x, n.y, n.z);
            }
            for uv in tri.uv.iter().flatten() {
                let _ = writeln!(obj, "vt {} {}", uv.x, uv.y);
            }
            // `lancer convert` refuses mesh attributes first; the comment
            // keeps their values in the scene's hash
            if let Some(a) = tri.attribute {
                let _ = writeln!(obj, "# attribute {:?}", scene.mesh_attributes[a as usize]);
            }
        }
        for (k, tri) in run.iter().enumerate() {
            let i = |j: usize| 3 * k + j + 1;
            let corner = |j: usize| match (tri.uv.is_some(), tri.n.is_some()) {
                (false, false) => format!("{}", i(j)),
                (true, false) => format!("{0}/{0}", i(j)),
                (false, true) => format!("{0}//{0}", i(j)),
                (true, true) => format!("{0}/{0}/{0}", i(j)),
            };
            let _ = writeln!(obj, "f {} {} {}", corner(0), corner(1), corner(2));
        }
        let _ = writeln!(
            t,
            "[[objects]]\ntype = \"mesh\"\nfile = {}\nmaterial = {}\n",
            quoted(&format!("{mesh_dir}/{name}")),
            quoted(&scene.materials[run[0].material as usize].name)
        );
        files.push((folder.join(name), obj.into_bytes()));
    }
    files.insert(0, (out.to_path_buf(), t.into_bytes()));
    files
}
