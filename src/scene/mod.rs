//! Scene files: loading, validation and flattening (see `docs/scene-format.md`).
//!
//! [`load`] reads a TOML scene file (or, by the extension `.xml`, a Mitsuba 3
//! scene in the subset of `docs/mitsuba.md`), checks every key against the format,
//! loads the OBJ meshes it names (with their `.mtl` materials), applies the
//! object transforms and returns a flat [`Scene`]: materials, spheres and
//! world-space triangles. Texture files are only resolved and checked here;
//! their pixels are loaded by the renderer.
//!
//! Every error names the file, the key (a dotted path such as
//! `materials.glass.ior` or `objects[2].radius`, where `objects[i]` counts
//! from 0) and, where TOML gives one, the 1-based line.
//!
//! [`SceneBuilder`] builds the same [`Scene`] in code, with the same checks.

mod builder;
mod conductors;
pub mod filter;
pub(crate) mod limits;
pub(crate) mod mesh;
mod mitsuba;
pub(crate) mod obj;
pub(crate) mod obj_fast;
mod parse;
mod ply;
mod serialized;
mod spectrum;
mod spectrum_tables;
#[cfg(test)]
mod tests;
mod types;
mod write;

pub use builder::{SceneBuilder, BUILT_SOURCE};
pub use conductors::{conductor_preset, conductor_preset_names};
pub use limits::{
    image_pixels, CameraBasis, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_PLY_ELEMENTS, MAX_RADIANCE,
    MAX_SERIALIZED_ELEMENTS, MAX_TEXTURE_TEXELS,
};
pub use spectrum::{mitsuba_constant_value, mitsuba_luminance};
pub use types::*;
pub use write::to_toml;

use std::path::{Path, PathBuf};

/// Why a scene could not be loaded. `Display` gives one line that names the
/// file, the key and (where known) the line, and says what to change.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file itself could not be read.
    #[error(
        "{}: cannot read scene file: {source}",
        crate::util::text::cut_path(path)
    )]
    Read {
        /// The scene file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file is not valid TOML (or XML, for a Mitsuba scene).
    #[error("{}: invalid {}: {message}", location(path, *line), if is_mitsuba(path) { "XML" } else { "TOML" })]
    Syntax {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the error, if the parser gave one.
        line: Option<usize>,
        /// The parser's message.
        message: String,
    },
    /// A key is unknown, missing, of the wrong type or has a bad value; or a
    /// file it names (OBJ, `.mtl`, texture) cannot be used.
    #[error("{}: {key}: {reason}", location(path, *line))]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the key or value, where TOML gives one.
        line: Option<usize>,
        /// Dotted path of the key, e.g. `objects[2].radius`.
        key: String,
        /// What is wrong and what to change.
        reason: String,
    },
}

impl SceneError {
    /// The 1-based line the error points at, if any.
    pub fn line(&self) -> Option<usize> {
        match self {
            SceneError::Read { .. } => None,
            SceneError::Syntax { line, .. } | SceneError::Invalid { line, .. } => *line,
        }
    }

    /// The dotted key the error is about, if any.
    pub fn key(&self) -> Option<&str> {
        match self {
            SceneError::Read { .. } | SceneError::Syntax { .. } => None,
            SceneError::Invalid { key, .. } => Some(key),
        }
    }
}

/// The error for a render setting at fault that an override gave: it
/// names the setting and no line of the file.
fn overridden(path: &Path, key: &str, reason: String) -> SceneError {
    SceneError::Invalid {
        path: path.to_path_buf(),
        line: None,
        key: format!("render.{key}"),
        reason: format!("{reason} (the value of RenderOverrides::{key})"),
    }
}

/// `file:line` or just `file`.
fn location(path: &Path, line: Option<usize>) -> String {
    match line {
        Some(line) => format!("{}:{line}", crate::util::text::cut_path(path)),
        None => crate::util::text::cut_path(path),
    }
}

/// Loads, validates and flattens a scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with(path, &RenderOverrides::default())
}

/// Same as [`load`], with render settings that replace the file's: they
/// are applied as the file's own are read, before anything is derived from
/// them (a Mitsuba sensor's field of view from the image size) and before
/// the settings are checked, once ([`RenderSettings::check`]). An error
/// about an overridden setting names its key and no line of the file.
pub fn load_with(path: &Path, overrides: &RenderOverrides) -> Result<Scene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    load_str_with(&text, path, overrides)
}

/// Same as [`load`], from a string (`path` is used for messages, to
/// resolve relative files and, by its extension, to tell Mitsuba XML from
/// TOML).
pub fn load_str(text: &str, path: &Path) -> Result<Scene, SceneError> {
    load_str_with(text, path, &RenderOverrides::default())
}

/// Same as [`load_with`], from a string (see [`load_str`]).
pub fn load_str_with(
    text: &str,
    path: &Path,
    overrides: &RenderOverrides,
) -> Result<Scene, SceneError> {
    if is_mitsuba(path) {
        mitsuba::parse_xml(text, path, overrides)
    } else {
        parse::parse_scene(text, path, overrides)
    }
}

/// Whether `path` names a Mitsuba 3 XML scene (extension `.xml`, any case).
pub fn is_mitsuba(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("xml"))
}
