//! Scene files: loading, validation and flattening (see `SCENE_FORMAT.md`).
//!
//! [`load`] reads a TOML scene file, checks every key against the format,
//! loads the OBJ meshes it names (with their `.mtl` materials), applies the
//! object transforms and returns a flat [`Scene`]: materials, spheres and
//! world-space triangles. Texture files are only resolved and checked here;
//! their pixels are loaded by the renderer.
//!
//! Every error names the file, the key (a dotted path such as
//! `materials.glass.ior` or `objects[2].radius`, where `objects[i]` counts
//! from 0) and, where TOML gives one, the 1-based line.

mod obj;
mod parse;
#[cfg(test)]
mod tests;
mod types;

pub use types::*;

use std::path::{Path, PathBuf};

/// Which optional effects this build renders (one place to flip them on).
///
/// A scene that uses an effect whose flag is `false` is still parsed and
/// validated in full, then rejected with a "not supported yet" error that
/// names the key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Supported {
    /// `type = "phong"` materials (and `.mtl` materials with a non-zero `Ks`).
    pub phong: bool,
    /// `type = "mirror"` materials (and `.mtl` materials with `illum 5`).
    pub mirror: bool,
    /// `type = "glossy"` materials.
    pub glossy: bool,
    /// `type = "dielectric"` materials (and `.mtl` `illum` 4, 6 or 7 with `Ni`).
    pub dielectric: bool,
    /// `albedo_texture`, `diffuse_texture` and `.mtl` `map_Kd`.
    pub textures: bool,
    /// `camera.aperture_radius > 0` (depth of field).
    pub thin_lens: bool,
}

impl Supported {
    /// What this build renders today: every effect of the format.
    pub const CURRENT: Supported = Supported::ALL;

    /// None of the optional effects: plain Lambertian scenes seen through a
    /// pinhole. For tools (and tests) that must reject the other effects.
    pub const NONE: Supported = Supported {
        phong: false,
        mirror: false,
        glossy: false,
        dielectric: false,
        textures: false,
        thin_lens: false,
    };

    /// Every effect of the format.
    pub const ALL: Supported = Supported {
        phong: true,
        mirror: true,
        glossy: true,
        dielectric: true,
        textures: true,
        thin_lens: true,
    };
}

impl Default for Supported {
    /// [`Supported::CURRENT`].
    fn default() -> Self {
        Supported::CURRENT
    }
}

/// Why a scene could not be loaded. `Display` gives one line that names the
/// file, the key and (where known) the line, and says what to change.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file itself could not be read.
    #[error("{}: cannot read scene file: {source}", path.display())]
    Read {
        /// The scene file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file is not valid TOML.
    #[error("{}: invalid TOML: {message}", location(path, *line))]
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
    /// The scene is valid but uses an effect this build does not render.
    #[error("{}: {key}: not supported yet ({what}); {hint}", location(path, *line))]
    Unsupported {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the key, where TOML gives one.
        line: Option<usize>,
        /// Dotted path of the key that asks for the effect.
        key: String,
        /// The effect, e.g. `phong materials`.
        what: String,
        /// What to change so the scene loads.
        hint: String,
    },
}

impl SceneError {
    /// The 1-based line the error points at, if any.
    pub fn line(&self) -> Option<usize> {
        match self {
            SceneError::Read { .. } => None,
            SceneError::Syntax { line, .. }
            | SceneError::Invalid { line, .. }
            | SceneError::Unsupported { line, .. } => *line,
        }
    }

    /// The dotted key the error is about, if any.
    pub fn key(&self) -> Option<&str> {
        match self {
            SceneError::Read { .. } | SceneError::Syntax { .. } => None,
            SceneError::Invalid { key, .. } | SceneError::Unsupported { key, .. } => Some(key),
        }
    }
}

/// `file:line` or just `file`.
fn location(path: &Path, line: Option<usize>) -> String {
    match line {
        Some(line) => format!("{}:{line}", path.display()),
        None => path.display().to_string(),
    }
}

/// Loads, validates and flattens a scene file, accepting only the effects in
/// [`Supported::CURRENT`].
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with(path, &Supported::CURRENT)
}

/// Same as [`load`], from a string (`path` is used for messages and to
/// resolve relative files).
pub fn load_str(text: &str, path: &Path) -> Result<Scene, SceneError> {
    load_str_with(text, path, &Supported::CURRENT)
}

/// Loads, validates and flattens a scene file, accepting the effects in
/// `supported`.
pub fn load_with(path: &Path, supported: &Supported) -> Result<Scene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    load_str_with(&text, path, supported)
}

/// Same as [`load_with`], from a string (`path` is used for messages and to
/// resolve relative files).
pub fn load_str_with(text: &str, path: &Path, supported: &Supported) -> Result<Scene, SceneError> {
    parse::parse_scene(text, path, supported)
}
