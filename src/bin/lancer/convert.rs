//! `lancer convert`: a scene (e.g. Mitsuba 3 XML) written as a lancer TOML
//! scene, with its triangles in OBJ files beside it.

use std::path::PathBuf;

use anyhow::{Context as _, Result};

use lancer::io::image_file;
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
    if let Some(m) = scene.materials.iter().find(|m| !m.kind.in_toml_format()) {
        anyhow::bail!(
            "{}: material `{}` is a Mitsuba `{}`, which the TOML scene format has no type for; \
             render the XML file itself (lancer render {0}), or give the shape another BSDF to convert it",
            args.scene.display(),
            m.name,
            m.kind.mitsuba_name().unwrap_or("material"),
        );
    }
    let mut outputs = image_file::Outputs::default();
    let files = scene::to_toml(&scene, &args.out);
    for (path, bytes) in files {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
        }
        outputs.add(&path, bytes);
    }
    outputs.commit()?;
    println!("wrote {}", args.out.display());
    Ok(())
}
