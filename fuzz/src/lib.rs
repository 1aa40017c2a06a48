//! The fuzz harness: one function per kind of input lancer reads from a
//! user, each feeding raw bytes through lancer's own loaders (never a copy of
//! them). The AFL binary (`src/main.rs`) runs them under `afl::fuzz!`; the
//! test suite (`tests/it/fuzz_replay.rs`, which includes this file) replays every
//! committed corpus and regression input through the same functions.
//!
//! A target passes when lancer returns, with the input loaded or refused; a
//! panic, an abort, a hang or running out of memory is a finding.

use lancer::internal::gpu::{pack_textures, GpuScene, PackOptions};
use lancer::io::film::{self, FilmPart};
use lancer::scene;
use std::path::{Path, PathBuf};

/// One kind of input; its name is the AFL binary's argument and the folder
/// of its seeds under `fuzz/corpus/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// A TOML scene file, through `scene::load`, then packed for the device
    /// (BVH build, textures) as `lancer render` does.
    SceneToml,
    /// A Mitsuba 3 XML scene file, the same way.
    SceneXml,
    /// An OBJ file, as the mesh of a fixed TOML scene, loaded and packed:
    /// alone, with a fixed material; followed by a NUL byte and a `.mtl`
    /// file, with no `material` key, so that faces take their `.mtl`
    /// materials (`mtllib fuzz.mtl` names it).
    ObjMtl,
    /// A texture file: the first byte picks the extension
    /// ([`TEXTURE_EXTENSIONS`], modulo their count), the rest is the file,
    /// loaded by the renderer's texture packer.
    Texture,
    /// A film file of `lancer render --film-out`, read and merged as
    /// `lancer merge` does (`FilmPart::read`, then `film::merge`): as
    /// given, then again with its checksum made right, so that mutations
    /// reach the checks behind it.
    Film,
    /// A PLY file, as the mesh of a fixed Mitsuba scene (`face_normals`
    /// true), loaded and packed as `lancer render` does.
    Ply,
    /// A Mitsuba `serialized` mesh file, as the mesh of a fixed Mitsuba
    /// scene, loaded and packed: the first byte picks the scene (value
    /// modulo 8: `shape_index` its value modulo 4, `face_normals` true
    /// from 4 on; ASCII `'0'` is shape_index 0 with smooth normals), the
    /// rest is the file.
    Serialized,
}

impl Target {
    /// Every target.
    pub const ALL: [Target; 7] = [
        Target::SceneToml,
        Target::SceneXml,
        Target::ObjMtl,
        Target::Texture,
        Target::Film,
        Target::Ply,
        Target::Serialized,
    ];

    /// The target's name: `scene_toml`, `scene_xml`, `obj_mtl`, `texture`,
    /// `film`, `ply` or `serialized`.
    pub fn name(self) -> &'static str {
        match self {
            Target::SceneToml => "scene_toml",
            Target::SceneXml => "scene_xml",
            Target::ObjMtl => "obj_mtl",
            Target::Texture => "texture",
            Target::Film => "film",
            Target::Ply => "ply",
            Target::Serialized => "serialized",
        }
    }

    /// The target of a name, if there is one.
    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// The texture binding's size the targets pack into: lavapipe's
/// `maxStorageBufferRange` (128 MiB), so that textures larger than it take
/// the shrinking path as they do on lavapipe.
pub const FUZZ_TEXTURE_BYTES: u64 = 1 << 27;

/// The texture file extensions the [`Target::Texture`] input's first byte
/// chooses from (byte value modulo their count; ASCII `'0'` is `png`).
pub const TEXTURE_EXTENSIONS: [&str; 6] = ["png", "jpg", "exr", "hdr", "bmp", "tga"];

/// The head of every fixed scene: render settings and a camera.
const SCENE_HEAD: &str = r#"[render]
width = 8
height = 8
spp = 1

[camera]
eye = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
vfov = 40.0
"#;

/// The mesh of [`Target::ObjMtl`]'s scenes, `fuzz.obj`, with no `material`
/// key: its faces take their `.mtl` materials.
const MESH: &str = "\n[[objects]]\ntype = \"mesh\"\nfile = \"fuzz.obj\"\n";

/// A fixed Mitsuba scene around `shape`: a camera looking at the origin.
fn mitsuba_scene(shape: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
  {shape}
</scene>
"#
    )
}

/// The one shape of [`Target::Ply`]'s scene: `fuzz.ply`.
const PLY_SHAPE: &str = r#"<shape type="ply">
    <string name="filename" value="fuzz.ply"/>
    <boolean name="face_normals" value="true"/>
    <bsdf type="twosided"><bsdf type="diffuse"/></bsdf>
  </shape>"#;

/// Scenes of [`Target::Serialized`] the input's first byte picks from.
const SERIALIZED_SCENES: u8 = 8;

/// The fixed Mitsuba scene of [`Target::Serialized`] number `pick` (below
/// [`SERIALIZED_SCENES`]), whose one mesh is mesh `pick % 4` of
/// `fuzz.serialized`, with `face_normals` from 4 on.
fn serialized_scene(pick: u8) -> String {
    let shape = format!(
        r#"<shape type="serialized">
    <string name="filename" value="fuzz.serialized"/>
    <integer name="shape_index" value="{}"/>
    <boolean name="face_normals" value="{}"/>
    <transform name="to_world"><scale x="2" y="1" z="0.5"/></transform>
    <bsdf type="twosided"><bsdf type="diffuse"/></bsdf>
  </shape>"#,
        pick % 4,
        pick >= 4
    );
    mitsuba_scene(&shape)
}

/// A grey material for the mesh of an OBJ given without a `.mtl`.
const GREY: &str = "\n[materials.grey]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n";

/// A scratch folder the inputs are written into, beside links to the test
/// scenes' `meshes/` and `tex/` folders, so that relative mesh and texture
/// paths in an input resolve (or fail) as they would for a user.
pub struct Fixture {
    dir: tempfile::TempDir,
    /// One scene per texture extension, whose only material uses
    /// `fuzz.<ext>` as its albedo texture.
    texture_scenes: Vec<scene::Scene>,
}

impl Fixture {
    /// Makes the scratch folder (under `$TMPDIR`), linking `assets/meshes`
    /// and `assets/tex` into it; `assets` is the repository's `tests/scenes`.
    pub fn new(assets: &Path) -> Result<Fixture, String> {
        let dir = tempfile::tempdir().map_err(|e| format!("cannot make a scratch folder: {e}"))?;
        for sub in ["meshes", "tex"] {
            let from = assets.join(sub);
            std::os::unix::fs::symlink(&from, dir.path().join(sub))
                .map_err(|e| format!("cannot link {}: {e}", from.display()))?;
        }
        let mesh_scenes = [
            ("obj_mtl.toml", format!("{SCENE_HEAD}{MESH}")),
            (
                "obj.toml",
                format!("{SCENE_HEAD}{GREY}{MESH}material = \"grey\"\n"),
            ),
            ("ply.xml", mitsuba_scene(PLY_SHAPE)),
        ];
        let mesh_scenes = (mesh_scenes.into_iter())
            .map(|(name, text)| (name.to_string(), text))
            .chain(
                (0..SERIALIZED_SCENES)
                    .map(|k| (format!("serialized_{k}.xml"), serialized_scene(k))),
            );
        for (name, text) in mesh_scenes {
            std::fs::write(dir.path().join(&name), text)
                .map_err(|e| format!("cannot write the {name} scene: {e}"))?;
        }
        let mut texture_scenes = Vec::new();
        for ext in TEXTURE_EXTENSIONS {
            let texture = dir.path().join(format!("fuzz.{ext}"));
            // A placeholder, so that the scene loader finds the file.
            std::fs::write(&texture, b"").map_err(|e| format!("cannot write: {e}"))?;
            let text = format!(
                "{SCENE_HEAD}\n[materials.textured]\ntype = \"lambert\"\n\
                 albedo_texture = \"fuzz.{ext}\"\n\n[[objects]]\ntype = \"sphere\"\n\
                 center = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"textured\"\n"
            );
            let path = dir.path().join(format!("texture_{ext}.toml"));
            let loaded = scene::load_str(&text, &path).map_err(|e| e.to_string())?;
            texture_scenes.push(loaded);
        }
        Ok(Fixture {
            dir,
            texture_scenes,
        })
    }

    /// The scratch folder.
    pub fn dir(&self) -> &Path {
        self.dir.path()
    }

    /// Runs one input through `target`: `Ok` when lancer accepted it, `Err`
    /// with lancer's message when it refused it (or the scratch file could
    /// not be written).
    pub fn run(&self, target: Target, data: &[u8]) -> Result<(), String> {
        match target {
            Target::SceneToml => self.load_and_pack(&self.write("fuzz.toml", data)?),
            Target::SceneXml => self.load_and_pack(&self.write("fuzz.xml", data)?),
            Target::ObjMtl => {
                let (obj, mtl, scene) = match data.iter().position(|&b| b == 0) {
                    Some(nul) => (&data[..nul], &data[nul + 1..], "obj_mtl.toml"),
                    None => (data, &[][..], "obj.toml"),
                };
                // The parallel reader of plain files must read the OBJ as
                // the general loader does, or leave it to it
                if let Err(e) = lancer::internal::obj::compare_readers(obj) {
                    panic!("the OBJ readers disagree: {e}");
                }
                self.write("fuzz.obj", obj)?;
                self.write("fuzz.mtl", mtl)?;
                self.load_and_pack(&self.dir().join(scene))
            }
            Target::Texture => {
                let Some((&pick, file)) = data.split_first() else {
                    return Err(String::from("empty input"));
                };
                let index = pick as usize % TEXTURE_EXTENSIONS.len();
                self.write(&format!("fuzz.{}", TEXTURE_EXTENSIONS[index]), file)?;
                pack_textures(&self.texture_scenes[index], FUZZ_TEXTURE_BYTES)
                    .map(drop)
                    .map_err(|e| format!("{e:#}"))
            }
            Target::Film => {
                let as_given = self.merge_film(data);
                if data.len() < 4 {
                    return as_given;
                }
                // The same bytes with a right checksum (film files end in
                // the CRC-32 of every byte before it).
                let (body, _) = data.split_at(data.len() - 4);
                let mut fixed = body.to_vec();
                fixed.extend_from_slice(&crc32fast::hash(body).to_le_bytes());
                self.merge_film(&fixed).and(as_given)
            }
            Target::Ply => {
                self.write("fuzz.ply", data)?;
                self.load_and_pack(&self.dir().join("ply.xml"))
            }
            Target::Serialized => {
                let Some((&pick, file)) = data.split_first() else {
                    return Err(String::from("empty input"));
                };
                self.write("fuzz.serialized", file)?;
                let scene = format!("serialized_{}.xml", pick % SERIALIZED_SCENES);
                self.load_and_pack(&self.dir().join(scene))
            }
        }
    }

    /// Reads `data` as a film file and merges it alone, as `lancer merge
    /// fuzz.film` does.
    fn merge_film(&self, data: &[u8]) -> Result<(), String> {
        let path = self.write("fuzz.film", data)?;
        let part = FilmPart::read(&path).map_err(|e| format!("{e:#}"))?;
        film::merge(&[(path, part)])
            .map(drop)
            .map_err(|e| format!("{e:#}"))
    }

    /// Writes `data` to `name` in the scratch folder.
    fn write(&self, name: &str, data: &[u8]) -> Result<PathBuf, String> {
        let path = self.dir().join(name);
        std::fs::write(&path, data).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        Ok(path)
    }

    /// Loads a scene file as `lancer render` does, then packs it for the
    /// device (BVH, materials, textures), which needs no device.
    fn load_and_pack(&self, path: &Path) -> Result<(), String> {
        let loaded = scene::load(path).map_err(|e| e.to_string())?;
        let options = PackOptions {
            max_texture_bytes: FUZZ_TEXTURE_BYTES,
            ..PackOptions::default()
        };
        GpuScene::pack(&loaded, &options)
            .map(drop)
            .map_err(|e| format!("{e:#}"))
    }
}
