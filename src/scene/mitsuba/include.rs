//! `<include filename>`: the files a scene includes, found and read before
//! the scene is, as Mitsuba 3.9's parser (`src/core/parser.cpp`) finds them.
//!
//! - A file is looked up first in the folder of the file that includes it,
//!   then in the folders its `<path>`s and those of the files that include
//!   it name (the last one first), then in the scene file's folder.
//! - Its root element needs a `version`. A `<scene>` root's children take
//!   the `<include>`'s place; any other root (a `<bsdf>`, a `<shape>`, ...)
//!   takes it whole, named by the `<include>`'s `name`.
//! - `<default>`s count in document order, the included files spliced in:
//!   the first of a name wins (a later one is ignored, with a warning), and
//!   an include's `filename` may use the ones before it.
//! - A `<path>` in an included file is relative to that file and serves the
//!   `<include>`s in it and in the files it includes. Files that shapes,
//!   textures and emitters name are found as Mitsuba finds them when it
//!   builds the plugins, after parsing: by the scene file's own `<path>`s
//!   and its folder, wherever the naming element is.
//! - Mitsuba loads 14 nested includes and stops at the 15th; lancer does
//!   too, and refuses a file that includes itself (directly or not) by
//!   name, with the chain.

use super::*;

/// The depth of include at which Mitsuba stops (`ParserConfig::max_include_depth`;
/// the scene file is at depth 0, so 14 nested includes load).
pub(super) const MAX_INCLUDE_DEPTH: usize = 15;

/// One XML file of a scene: the scene file (index 0) or an included one.
pub(super) struct Source {
    /// Where it is.
    pub path: PathBuf,
    /// Its text.
    pub text: String,
    /// The `name` of the `<include>` that names it, which names its root
    /// element when that is not a `<scene>`.
    pub include_name: Option<String>,
}

/// The scene file and every file it includes, recursively.
pub(super) struct Sources {
    /// The scene file first, then the included files in document order
    /// (a file included twice is here twice).
    pub files: Vec<Source>,
    /// (file index, byte offset of an `<include>` element in it) -> index
    /// of the file it names.
    pub includes: HashMap<(usize, usize), usize>,
    /// `<default>` values: the first of each name in document order.
    pub defaults: HashMap<String, String>,
    /// Later `<default>`s of a name, which are ignored.
    pub warnings: Vec<String>,
}

/// `node`'s description and line in a file, for an error.
fn invalid(path: &Path, node: Node, reason: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        path: path.to_path_buf(),
        line: Some(node.document().text_pos_at(node.range().start).row as usize),
        key: Loader::describe(node),
        reason: reason.into(),
    }
}

/// The folder a file is in ("" for a bare name).
fn folder_of(path: &Path) -> PathBuf {
    path.parent().unwrap_or(Path::new("")).to_path_buf()
}

impl Sources {
    /// Reads the scene file's `text` (from `path`) and, recursively, every
    /// file its `<include>`s name.
    pub(super) fn gather(text: &str, path: &Path) -> Result<Sources> {
        let mut sources = Sources {
            files: vec![Source {
                path: path.to_path_buf(),
                text: text.to_string(),
                include_name: None,
            }],
            includes: HashMap::new(),
            defaults: HashMap::new(),
            warnings: Vec::new(),
        };
        let mut chain = vec![path.canonicalize().unwrap_or_else(|_| path.to_path_buf())];
        sources.file(0, vec![folder_of(path)], &mut chain)?;
        Ok(sources)
    }

    /// Parses file `index` and reads what it includes; `resolver` is where
    /// its `<include>`s look (before its own folder and `<path>`s).
    fn file(
        &mut self,
        index: usize,
        resolver: Vec<PathBuf>,
        chain: &mut Vec<PathBuf>,
    ) -> Result<()> {
        let text = std::mem::take(&mut self.files[index].text);
        let result = self.parse_and_walk(index, &text, resolver, chain);
        self.files[index].text = text;
        result
    }

    fn parse_and_walk(
        &mut self,
        index: usize,
        text: &str,
        mut resolver: Vec<PathBuf>,
        chain: &mut Vec<PathBuf>,
    ) -> Result<()> {
        let path = self.files[index].path.clone();
        let doc = Document::parse(text).map_err(|e| SceneError::Syntax {
            path: path.clone(),
            line: Some(e.pos().row as usize),
            message: e.to_string(),
        })?;
        let root = doc.root_element();
        if index > 0 {
            // The scene file's own root is checked as the scene is read.
            match root.attribute("version") {
                None => {
                    return Err(invalid(
                        &path,
                        root,
                        "the root element of an included file needs a `version` attribute \
                         (Mitsuba requires it), e.g. <scene version=\"3.0.0\">",
                    ))
                }
                Some(v) if parse_version(v).is_none() => {
                    return Err(invalid(
                        &path,
                        root,
                        format!(
                            "attribute `version`: expected three numbers separated by periods \
                             (e.g. \"3.0.0\"), got \"{}\"",
                            cut(v)
                        ),
                    ))
                }
                Some(_) => {}
            }
        }
        let scene_root = root.tag_name().name() == "scene";
        self.walk(index, &path, root, scene_root, &mut resolver, chain)
    }

    /// The elements under `node` (a scene root when `scene_root`), in
    /// document order.
    fn walk(
        &mut self,
        index: usize,
        path: &Path,
        node: Node,
        scene_root: bool,
        resolver: &mut Vec<PathBuf>,
        chain: &mut Vec<PathBuf>,
    ) -> Result<()> {
        let dir = folder_of(path);
        for child in node.children().filter(|c| c.is_element()) {
            match child.tag_name().name() {
                "default" if scene_root => self.default(path, child)?,
                "path" if scene_root => {
                    // As Mitsuba: relative to this file, else where the
                    // resolver finds it; checked again for the scene file
                    // as the scene is read.
                    let Some(raw) = child.attribute("value") else {
                        return Err(invalid(path, child, "missing attribute `value`"));
                    };
                    let value = self.substitute(path, child, "value", raw)?;
                    let mut folder = dir.join(&value);
                    if !folder.is_dir() {
                        if let Some(found) = find(&value, resolver) {
                            folder = found;
                        }
                    }
                    if !folder.is_dir() {
                        return Err(SceneError::Invalid {
                            path: path.to_path_buf(),
                            line: Some(doc_line(child)),
                            key: Loader::describe(child),
                            reason: format!(
                                "attribute `value`: folder {} not found (a <path> is relative \
                                 to the {})",
                                crate::util::text::cut_path(&folder),
                                if index == 0 {
                                    "scene file"
                                } else {
                                    "included file it is in"
                                }
                            ),
                        });
                    }
                    resolver.insert(0, folder);
                }
                "include" => self.include(index, path, child, resolver, chain)?,
                _ => self.walk(index, path, child, false, resolver, chain)?,
            }
        }
        Ok(())
    }

    /// `<default name value>`: the first of a name wins, as in Mitsuba.
    fn default(&mut self, path: &Path, node: Node) -> Result<()> {
        for a in node.attributes() {
            if !["name", "value"].contains(&a.name()) || a.namespace().is_some() {
                return Err(invalid(
                    path,
                    node,
                    format!(
                        "attribute `{}`: unsupported attribute of <default>; lancer reads: name, value",
                        cut(a.name())
                    ),
                ));
            }
        }
        let name = node
            .attribute("name")
            .ok_or_else(|| invalid(path, node, "missing attribute `name`"))?;
        let value = node
            .attribute("value")
            .ok_or_else(|| invalid(path, node, "missing attribute `value`"))?;
        if name.is_empty() {
            return Err(invalid(path, node, "attribute `name`: must not be empty"));
        }
        if self.defaults.contains_key(name) {
            self.warnings.push(format!(
                "{}:{}: <default name=\"{}\">: a second <default> of this name is ignored; the \
                 first one wins, as in Mitsuba",
                crate::util::text::cut_path(path),
                doc_line(node),
                cut(name)
            ));
        } else {
            self.defaults.insert(name.to_string(), value.to_string());
        }
        Ok(())
    }

    /// `raw` (attribute `attr` of `node`) with the `<default>`s so far.
    fn substitute(&self, path: &Path, node: Node, attr: &str, raw: &str) -> Result<String> {
        substitute(raw, &self.defaults).map_err(|key| {
            invalid(
                path,
                node,
                format!(
                    "attribute `{attr}`: {} (before this element: an <include> or <path> sees \
                     the <default>s above it, as in Mitsuba)",
                    no_default(&key)
                ),
            )
        })
    }

    /// `<include filename name>`: finds, reads and walks the file.
    fn include(
        &mut self,
        index: usize,
        path: &Path,
        node: Node,
        resolver: &[PathBuf],
        chain: &mut Vec<PathBuf>,
    ) -> Result<()> {
        for a in node.attributes() {
            if !["filename", "name"].contains(&a.name()) || a.namespace().is_some() {
                return Err(invalid(
                    path,
                    node,
                    format!(
                        "attribute `{}`: unsupported attribute of <include>; lancer reads: \
                         filename, name",
                        cut(a.name())
                    ),
                ));
            }
        }
        let raw = node
            .attribute("filename")
            .ok_or_else(|| invalid(path, node, "missing attribute `filename`"))?;
        let name = self.substitute(path, node, "filename", raw)?;
        let include_name = match node.attribute("name") {
            Some(n) => Some(self.substitute(path, node, "name", n)?),
            None => None,
        };
        // Mitsuba: this file's folder first, then the resolver.
        let mut search = vec![folder_of(path)];
        search.extend(resolver.iter().cloned());
        let Some(found) = find(&name, &search) else {
            let mut places: Vec<String> = Vec::new();
            for d in &search {
                let place = crate::util::text::cut_path(&d.join(&name));
                if !places.contains(&place) {
                    places.push(place);
                }
            }
            return Err(invalid(
                path,
                node,
                format!(
                    "included file \"{}\" not found (looked for {})",
                    cut(&name),
                    places.join(", ")
                ),
            ));
        };
        let canonical = found.canonicalize().unwrap_or_else(|_| found.clone());
        if let Some(first) = chain.iter().position(|p| *p == canonical) {
            let names: Vec<String> = chain[first..]
                .iter()
                .chain(std::iter::once(&canonical))
                .map(|p| crate::util::text::cut_path(p))
                .collect();
            return Err(invalid(
                path,
                node,
                format!(
                    "an include cycle: {} (Mitsuba would stop at depth {MAX_INCLUDE_DEPTH}); \
                     remove one of these <include>s",
                    names.join(" includes ")
                ),
            ));
        }
        if chain.len() >= MAX_INCLUDE_DEPTH {
            return Err(invalid(
                path,
                node,
                format!(
                    "includes nested {MAX_INCLUDE_DEPTH} deep: Mitsuba stops there \
                     (`max_include_depth`, the scene file at depth 0), and so does lancer"
                ),
            ));
        }
        let bytes = std::fs::read(&found).map_err(|e| {
            invalid(
                path,
                node,
                format!(
                    "cannot read included file {}: {e}",
                    crate::util::text::cut_path(&found)
                ),
            )
        })?;
        let text = String::from_utf8(bytes).map_err(|_| {
            invalid(
                path,
                node,
                format!(
                    "included file {} is not a text (UTF-8) file; an <include> names a \
                     Mitsuba XML file",
                    crate::util::text::cut_path(&found)
                ),
            )
        })?;
        let new = self.files.len();
        self.files.push(Source {
            path: found,
            text,
            include_name,
        });
        self.includes.insert((index, node.range().start), new);
        chain.push(canonical);
        let result = self.file(new, search, chain);
        chain.pop();
        result.map_err(|e| match e {
            // Said at the <include>, as XML whatever the file's name.
            SceneError::Syntax {
                path: p,
                line,
                message,
            } => invalid(
                path,
                node,
                format!(
                    "included file {}{} is not valid XML: {message}",
                    crate::util::text::cut_path(&p),
                    line.map_or(String::new(), |l| format!(":{l}"))
                ),
            ),
            other => other,
        })
    }
}

/// The 1-based line of `node` in its document.
fn doc_line(node: Node) -> usize {
    node.document().text_pos_at(node.range().start).row as usize
}

/// `name` as a file resolver finds it: absolute as it is, else in the
/// first of `folders` that holds it; `None` when nothing is there.
fn find(name: &str, folders: &[PathBuf]) -> Option<PathBuf> {
    let file = Path::new(name);
    if file.is_absolute() {
        return file.exists().then(|| file.to_path_buf());
    }
    folders.iter().map(|f| f.join(file)).find(|p| p.exists())
}
