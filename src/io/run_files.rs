//! The files one run reads and writes, checked together before any work:
//! every output can be written ([`check_destination`]), and no output names
//! another output or any input, whatever relative path or symbolic link
//! spells it ([`RunFiles::check`]). Every command of the command line
//! checks its files here, so that one rule holds in all of them.

use std::path::{Path, PathBuf};

use anyhow::{ensure, Result};

use crate::io::image_file::check_destination;
use crate::scene::Scene;
use crate::util::text::cut_path;

/// One file of a run and what it is to the user (`--out`, `the scene`,
/// `the texture of material "floor"`), for messages.
#[derive(Debug, Clone)]
struct Named {
    path: PathBuf,
    what: String,
}

/// The inputs and outputs of one run. Add every file, then call
/// [`RunFiles::check`] before anything is rendered or written.
#[derive(Debug, Default)]
pub struct RunFiles {
    inputs: Vec<Named>,
    /// Outputs, and what each must be.
    outputs: Vec<(Named, Kind)>,
}

/// What an output must be, by its extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// Any file.
    Any,
    /// An image lancer writes (.png or .exr).
    Image,
    /// Linear floats: an .exr.
    Exr,
    /// A file of a cache the run keeps, in a folder it makes itself when
    /// missing: not checked as a destination, only against the others.
    Cache,
}

impl RunFiles {
    /// Adds a file the run reads; `what` names it in messages.
    pub fn input(&mut self, path: &Path, what: impl Into<String>) -> &mut Self {
        self.inputs.push(Named {
            path: path.to_path_buf(),
            what: what.into(),
        });
        self
    }

    /// Adds every file `scene` was read from ([`Scene::input_files`]): the
    /// scene file, its meshes, material libraries and textures.
    pub fn scene(&mut self, scene: &Scene) -> &mut Self {
        for (path, what) in scene.input_files() {
            self.input(&path, what);
        }
        self
    }

    /// Adds a file the run writes; `what` names it in messages (the flag
    /// that gives it).
    pub fn output(&mut self, path: &Path, what: impl Into<String>) -> &mut Self {
        self.add_output(path, what.into(), Kind::Any)
    }

    /// Adds an image the run writes: as [`RunFiles::output`], and its
    /// extension must be one lancer writes.
    pub fn image_output(&mut self, path: &Path, what: impl Into<String>) -> &mut Self {
        self.add_output(path, what.into(), Kind::Image)
    }

    /// Adds an image of linear values the run writes (a variance): as
    /// [`RunFiles::image_output`], and it must be an `.exr`.
    pub fn exr_output(&mut self, path: &Path, what: impl Into<String>) -> &mut Self {
        self.add_output(path, what.into(), Kind::Exr)
    }

    /// Adds a file a cache of the run may write (a cached reference, a
    /// generated scene), in a folder the run makes when missing: no output
    /// or input may be that file, as for [`RunFiles::output`], but its
    /// folder need not exist yet.
    pub fn cache_output(&mut self, path: &Path, what: impl Into<String>) -> &mut Self {
        self.add_output(path, what.into(), Kind::Cache)
    }

    fn add_output(&mut self, path: &Path, what: String, kind: Kind) -> &mut Self {
        let named = Named {
            path: path.to_path_buf(),
            what,
        };
        self.outputs.push((named, kind));
        self
    }

    /// Checks, touching no file: each output can be written (see
    /// [`check_destination`]), no two outputs are one file, and no output is
    /// one of the inputs. Two paths are one file when they resolve to the
    /// same place: relative paths, `..` and symbolic links are resolved, and
    /// a file that does not exist yet is placed in its resolved folder.
    /// Errors name the file, both of its uses, and say what to change.
    pub fn check(&self) -> Result<()> {
        for (out, kind) in &self.outputs {
            if *kind == Kind::Cache {
                continue;
            }
            check_destination(&out.path, *kind != Kind::Any)?;
            let exr = (out.path.extension()).is_some_and(|e| e.eq_ignore_ascii_case("exr"));
            ensure!(
                *kind != Kind::Exr || exr,
                "{}: {} writes linear values and must end in .exr",
                cut_path(&out.path),
                out.what
            );
        }
        let inputs: Vec<(PathBuf, &Named)> = (self.inputs.iter())
            .map(|n| (resolve(&n.path), n))
            .collect();
        let mut outputs: Vec<(PathBuf, &Named)> = Vec::with_capacity(self.outputs.len());
        for (out, _) in &self.outputs {
            let place = resolve(&out.path);
            if let Some((_, earlier)) = outputs.iter().find(|(p, _)| *p == place) {
                anyhow::bail!(
                    "{}: given for two outputs ({} and {}){}; give each output its own file",
                    cut_path(&out.path),
                    earlier.what,
                    out.what,
                    also(&earlier.path, &out.path)
                );
            }
            if let Some((_, input)) = inputs.iter().find(|(p, _)| *p == place) {
                anyhow::bail!(
                    "{}: {} would overwrite {}, which this run reads{}; give {} another file",
                    cut_path(&out.path),
                    out.what,
                    input.what,
                    also(&input.path, &out.path),
                    out.what
                );
            }
            outputs.push((place, out));
        }
        Ok(())
    }
}

/// ` (PATH is the same file)` when `other` is spelled unlike `path`, so that
/// a user who wrote two different paths sees why they are one file.
fn also(other: &Path, path: &Path) -> String {
    if other == path {
        String::new()
    } else {
        format!(" ({} is the same file)", cut_path(other))
    }
}

/// Where `path` is: its canonical path (relative paths, `..` and symbolic
/// links resolved) when it exists; for a file that does not exist yet, the
/// canonical path of its nearest folder that exists, joined with the rest,
/// whose `.` and `..` are resolved by name (a folder that does not exist is
/// no link).
pub fn resolve(path: &Path) -> PathBuf {
    use std::path::Component;
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut rest = Vec::new();
    let mut at = absolute.clone();
    loop {
        if let Ok(found) = std::fs::canonicalize(&at) {
            return rest.iter().rev().fold(found, |mut p, name| {
                if name == ".." {
                    p.pop();
                } else if name != "." {
                    p.push(name);
                }
                p
            });
        }
        match at.components().next_back() {
            Some(c @ (Component::Normal(_) | Component::ParentDir | Component::CurDir)) => {
                rest.push(c.as_os_str().to_os_string());
            }
            _ => return absolute,
        }
        if !at.pop() {
            return absolute;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_may_not_name_each_other_or_an_input() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene.toml");
        std::fs::write(&scene, "x").unwrap();
        let out = dir.path().join("a.exr");

        let mut ok = RunFiles::default();
        ok.input(&scene, "the scene")
            .image_output(&out, "--out")
            .output(&dir.path().join("s.json"), "--stats-json");
        ok.check().unwrap();

        // Two outputs, spelled differently
        let mut two = RunFiles::default();
        two.image_output(&out, "--out")
            .image_output(&dir.path().join("sub/../a.exr"), "--var-out");
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let e = format!("{:#}", two.check().unwrap_err());
        assert!(
            e.contains("given for two outputs (--out and --var-out)")
                && e.contains("is the same file"),
            "{e}"
        );

        // An output that is the input through a symbolic link
        #[cfg(unix)]
        {
            let link = dir.path().join("link.film");
            std::os::unix::fs::symlink(&scene, &link).unwrap();
            let mut over = RunFiles::default();
            over.input(&scene, "the scene").output(&link, "--film-out");
            let e = format!("{:#}", over.check().unwrap_err());
            assert!(
                e.contains("--film-out would overwrite the scene, which this run reads"),
                "{e}"
            );
        }
        assert_eq!(std::fs::read(&scene).unwrap(), b"x");
    }

    /// A cache's file may lie in a folder the run has yet to make, and
    /// still may not be another output or an input.
    #[test]
    fn cache_files_are_outputs_in_folders_not_made_yet() {
        let dir = tempfile::tempdir().unwrap();
        let cached = dir.path().join("not/yet/ref.exr");
        let mut fine = RunFiles::default();
        fine.cache_output(&cached, "the cached reference");
        fine.check().unwrap();
        let mut both = RunFiles::default();
        both.cache_output(&cached, "the cached reference")
            .cache_output(
                &dir.path().join("not/yet/../yet/ref.exr"),
                "a generated scene",
            );
        let e = format!("{:#}", both.check().unwrap_err());
        assert!(
            e.contains("given for two outputs (the cached reference and a generated scene)"),
            "{e}"
        );
        let scene = dir.path().join("scene.toml");
        std::fs::write(&scene, "x").unwrap();
        let mut over = RunFiles::default();
        over.input(&scene, "the scene")
            .cache_output(&scene, "a generated scene");
        let e = format!("{:#}", over.check().unwrap_err());
        assert!(
            e.contains("a generated scene would overwrite the scene"),
            "{e}"
        );
    }

    #[test]
    fn a_relative_path_resolves_in_the_current_folder() {
        let here = std::fs::canonicalize(std::env::current_dir().unwrap()).unwrap();
        assert_eq!(
            resolve(Path::new("no-such-file.x")),
            here.join("no-such-file.x")
        );
        assert_eq!(
            resolve(Path::new("no/such/folder/f.x")),
            here.join("no/such/folder/f.x")
        );
    }
}
