//! `lancer convert`: a scene (e.g. Mitsuba 3 XML) written as a lancer TOML
//! scene, with its triangles in OBJ files beside it.

use std::path::PathBuf;

use anyhow::{Context as _, Result};

use lancer::io::image_file::{self, folder_of};
use lancer::io::run_files::RunFiles;
use lancer::scene;

use crate::args::{load_scene, Overrides};

#[derive(clap::Args)]
pub struct ConvertArgs {
    /// Scene file (TOML, or Mitsuba 3 XML by the extension .xml).
    scene: PathBuf,
    /// The TOML file to write; OBJ files go to the folder STEM_meshes beside it.
    #[arg(long, short)]
    out: PathBuf,
}

/// `lancer convert`: every file written together, or none.
pub fn convert(args: ConvertArgs) -> Result<()> {
    let scene = load_scene(&args.scene, &Overrides::default())?;
    if let Some(env) = &scene.envmap {
        anyhow::bail!(
            "{}: the scene has an environment map ({}), which a TOML scene cannot state \
             (SCENE_FORMAT.md has a constant [environment] only); render the XML scene itself",
            args.scene.display(),
            env.file.display()
        );
    }
    if let Some(light) = scene.lights.iter().find(|l| !l.in_toml_format()) {
        anyhow::bail!(
            "{}: the scene has a {}, which a TOML scene cannot state (SCENE_FORMAT.md's \
             [[lights]] are point, spot and directional, none of them textured); render the \
             XML scene itself",
            args.scene.display(),
            match light {
                scene::DeltaLight::Projector { .. } => "projector",
                _ => "spot light with a texture",
            }
        );
    }
    if scene.camera.orthographic.is_some() {
        anyhow::bail!(
            "{}: the sensor is orthographic, which a TOML scene cannot state (its camera is a \
             pinhole or a thin lens); render the XML scene itself",
            args.scene.display()
        );
    }
    if scene.camera.shift != [0.0; 2] {
        anyhow::bail!(
            "{}: the sensor's image is off its optical axis (a film crop window or a \
             principal_point_offset), which a TOML scene cannot state; render the XML scene itself",
            args.scene.display()
        );
    }
    if scene.render.filter_inside_film {
        anyhow::bail!(
            "{}: the film keeps its samples inside the image (Mitsuba's sample_border false, its \
             default) with a `{}` filter, which a TOML scene cannot state (its filters look past \
             the image's edge); render the XML scene itself, or add <boolean \
             name=\"sample_border\" value=\"true\"/> to its film to convert it (the pixels \
             within the filter's radius of the edge then change)",
            args.scene.display(),
            scene.render.filter.name()
        );
    }
    if let Some(m) = scene.materials.iter().find(|m| !m.kind.in_toml_format()) {
        anyhow::bail!(
            "{}: material `{}` is a Mitsuba `{}`, which the TOML scene format has no type for; \
             render the XML file itself (lancer render {0}), or give the shape another BSDF to convert it",
            args.scene.display(),
            m.name,
            m.kind.mitsuba_name().unwrap_or("material"),
        );
    }
    if let Some(m) = (scene.materials.iter()).find(|m| m.kind.alpha_textures().is_some()) {
        anyhow::bail!(
            "{}: material `{}` reads its roughness from a texture, which the TOML scene format \
             cannot state (its alpha_u and alpha_v are numbers); render the XML file itself \
             (lancer render {0})",
            args.scene.display(),
            m.name,
        );
    }
    if let Some(m) = (scene.materials.iter())
        .find(|m| matches!(m.diffuse_source(), Some(scene::ColorSource::Mapped(_))))
    {
        anyhow::bail!(
            "{}: material `{}` reads a Mitsuba texture with a `to_uv` transform, a `wrap_mode` \
             other than repeat, `filter_type` nearest, `raw` or a checkerboard, which the TOML \
             scene format cannot state; render the XML file itself (lancer render {0})",
            args.scene.display(),
            m.name,
        );
    }
    if let Some(m) = (scene.materials.iter()).find(|m| !m.mesh_attribute_reads().is_empty()) {
        anyhow::bail!(
            "{}: material `{}` reads a mesh attribute (Mitsuba's `mesh_attribute`), which the \
             TOML scene format cannot state; render the XML file itself (lancer render {0})",
            args.scene.display(),
            m.name,
        );
    }
    if let Some(m) =
        (scene.materials.iter()).find(|m| m.opacity.is_some() || m.normal_map.is_some())
    {
        anyhow::bail!(
            "{}: material `{}` is a Mitsuba `{}`, which the TOML scene format cannot state; \
             render the XML file itself (lancer render {0})",
            args.scene.display(),
            m.name,
            match (&m.opacity, &m.normal_map) {
                (Some(_), _) => "mask",
                (None, Some(n)) if n.bump_scale.is_some() => "bumpmap",
                _ => "normalmap",
            },
        );
    }
    if let Some(m) = scene.spheres.iter().find_map(|s| {
        let m = &scene.materials[s.material as usize];
        let frame = s.mitsuba_frame?;
        let turned = frame != [glam::Vec3::X, glam::Vec3::Y, glam::Vec3::Z];
        let anisotropic = m.kind.is_anisotropic();
        let textured = (m.kind.colour_sources().into_iter()).any(scene::ColorSource::is_textured);
        (textured || (turned && anisotropic)).then_some(m)
    }) {
        anyhow::bail!(
            "{}: a sphere with material `{}` takes Mitsuba's texture coordinates or tangent, \
             which the TOML scene format's spheres do not have; render the XML file itself \
             (lancer render {0}), or use a sphere mesh (obj or ply)",
            args.scene.display(),
            m.name,
        );
    }
    let written = scene::to_toml(&scene, &args.out);
    // Every file before any is written: no output names another, the scene
    // or a file it reads. A mesh folder that does not exist yet holds
    // nothing to overwrite; it is made below.
    let mut files = RunFiles::default();
    files.scene(&scene);
    for (i, (path, _)) in written.iter().enumerate() {
        if i == 0 {
            files.output(path, "--out");
        } else if folder_of(path).is_dir() {
            files.output(path, "a mesh file of --out");
        }
    }
    files.check()?;
    let mut outputs = image_file::Outputs::default();
    for (path, bytes) in written {
        std::fs::create_dir_all(folder_of(&path))
            .with_context(|| format!("{}: cannot create the folder", path.display()))?;
        outputs.add(&path, bytes);
    }
    outputs.commit()?;
    println!("wrote {}", args.out.display());
    Ok(())
}
