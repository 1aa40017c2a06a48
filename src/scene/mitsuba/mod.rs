//! Mitsuba 3 XML scenes: the subset in `docs/mitsuba.md`, read with
//! roxmltree (which keeps every element's position, so each message names
//! the line) and converted to the same plain [`Scene`] the TOML loader
//! builds.
//!
//! Everything outside the subset is an error naming the element, the
//! attribute or property and the line: nothing is skipped in silence.
//! Where Mitsuba and lancer differ in a way a file cannot change (lancer's
//! surfaces shade both sides, its pixel filter is a box), the difference is
//! documented and, where the scene relies on it, reported as a warning.

use super::obj::{self, LoadedMesh};
use super::serialized;
use super::spectrum::spectrum_to_rgb;
use super::types::*;
use super::SceneError;
use super::{conductor_preset, conductor_preset_names};
use crate::util::text::cut;
use glam::{DAffine3, DMat3, DVec3, Vec2, Vec3};
use roxmltree::{Document, Node};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

mod include;
mod ior;
mod plugins;

type Result<T> = std::result::Result<T, SceneError>;

/// Mitsuba's default `int_ior` of `dielectric` (BK7 glass).
const DEFAULT_INT_IOR: f64 = 1.5046;
/// Mitsuba's default `ext_ior` of `dielectric` (air).
const DEFAULT_EXT_IOR: f64 = 1.000277;
/// Mitsuba's default `int_ior` of `plastic` (polypropylene).
const DEFAULT_PLASTIC_IOR: f64 = 1.49;
/// `max_depth` for Mitsuba's `-1` (no limit): lancer's Russian roulette ends
/// the paths long before, and a deep limit costs only the bounces reached.
const UNLIMITED_DEPTH: u32 = 1_000_000;
/// Mitsuba's default film size.
const DEFAULT_FILM: (u32, u32) = (768, 576);
/// Mitsuba's default `near_clip` of a perspective or thinlens sensor.
const DEFAULT_NEAR_CLIP: f64 = 1e-2;
/// Mitsuba's default `far_clip` (also the default `focus_distance` of thinlens).
const DEFAULT_FAR_CLIP: f64 = 1e4;
/// Mitsuba's default `sample_count`.
const DEFAULT_SAMPLE_COUNT: u32 = 4;
/// Mitsuba's default diffuse reflectance, of a shape without a BSDF (one that
/// emits gets a black one).
const DEFAULT_REFLECTANCE: f32 = 0.5;
/// How far a sensor's or sphere's `to_world` may be from rigid (relative).
const RIGID_TOLERANCE: f64 = 1e-5;

const SHAPE_TYPES: &[&str] = &[
    "sphere",
    "rectangle",
    "cube",
    "disk",
    "cylinder",
    "obj",
    "ply",
    "serialized",
    "shapegroup",
    "instance",
];
const BSDF_TYPES: &[&str] = &[
    "diffuse",
    "conductor",
    "roughconductor",
    "dielectric",
    "roughdielectric",
    "thindielectric",
    "plastic",
    "roughplastic",
    "twosided",
    "mask",
    "normalmap",
    "bumpmap",
    "blendbsdf",
    "principled",
];
/// Mitsuba's default roughness of a rough BSDF.
const DEFAULT_ALPHA: f64 = 0.1;
const SAMPLER_TYPES: &[&str] = &[
    "independent",
    "stratified",
    "multijitter",
    "orthogonal",
    "ldsampler",
];
const TOP_ELEMENTS: &[&str] = &[
    "default",
    "path",
    "texture",
    "integrator",
    "sensor",
    "sampler",
    "bsdf",
    "shape",
    "emitter",
];
/// Elements that hold one property value.
const PROPERTY_TAGS: &[&str] = &[
    "float",
    "integer",
    "string",
    "boolean",
    "rgb",
    "spectrum",
    "point",
    "vector",
    "transform",
    "texture",
];

/// The element tags a colour property may take: Mitsuba's RGB variants
/// read a `<float>` and a uniform `<spectrum>` as a grey.
const COLOR_TAGS: &[&str] = &["rgb", "float", "spectrum"];

/// The RGB that Mitsuba 3.9.1's RGB variants give an emitter's uniform
/// `<spectrum value="1">` (its parser makes an emitter's spectrum the D65
/// illuminant times the value; read back from Mitsuba's own plugin, and
/// multiplied by the value in f32 as Mitsuba does).
const D65_RGB: [f32; 3] = [1.204_793_9, 0.948_291, 0.908_916_06];

/// Loads a Mitsuba 3 XML scene (see `docs/mitsuba.md`): first the files
/// its `<include>`s name, recursively ([`include::Sources::gather`]), then
/// the scene, with each `<include>` replaced by what its file holds.
pub(crate) fn parse_xml(text: &str, path: &Path, overrides: &RenderOverrides) -> Result<Scene> {
    let sources = include::Sources::gather(text, path)?;
    let mut docs = Vec::with_capacity(sources.files.len());
    for source in &sources.files {
        // Each file parsed once already while gathering; it parses again.
        docs.push(
            Document::parse(&source.text).map_err(|e| SceneError::Syntax {
                path: source.path.clone(),
                line: Some(e.pos().row as usize),
                message: e.to_string(),
            })?,
        );
    }
    let mut loader = Loader {
        path,
        overrides: *overrides,
        dir: path.parent().unwrap_or(Path::new("")).to_path_buf(),
        search: Vec::new(),
        upgrade_v1: vec![false; docs.len()],
        docs: &docs,
        sources: &sources,
        defaults: sources.defaults.clone(),
        ids: HashMap::new(),
        materials: Vec::new(),
        material_index: HashMap::new(),
        spheres: Vec::new(),
        triangles: Vec::new(),
        mesh_attributes: Vec::new(),
        warnings: sources.warnings.clone(),
        dropped: Vec::new(),
        files: Vec::new(),
        groups: HashMap::new(),
        in_group: None,
    };
    loader.scene(docs[0].root_element())
}

/// `raw` with every `$name` replaced by its value in `defaults`; the name
/// without a value is the error.
fn substitute(
    raw: &str,
    defaults: &HashMap<String, String>,
) -> std::result::Result<String, String> {
    let mut out = String::new();
    let mut rest = raw;
    while let Some(at) = rest.find('$') {
        out += &rest[..at];
        let after = &rest[at + 1..];
        let len = after
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(after.len());
        let key = &after[..len];
        out += defaults.get(key).ok_or_else(|| key.to_string())?;
        rest = &after[len..];
    }
    out += rest;
    Ok(out)
}

/// The message for a `$name` without a `<default>`.
fn no_default(key: &str) -> String {
    format!(
        "`${}` has no value: add <default name=\"{}\" value=\"...\"/> at the top of the scene",
        cut(key),
        cut(key)
    )
}

/// Numbers of an attribute: separated by commas and/or white space.
fn numbers(text: &str) -> Option<Vec<f64>> {
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect()
}

/// camelCase to snake_case as Mitsuba 3 upgrades scenes older than 2.0.0:
/// an upper-case letter after a lower-case one starts a new word, and the
/// upper-case letters right after it stay in that word (`intIOR` ->
/// `int_ior`).
fn camel_to_snake(name: &str) -> String {
    let chars: Vec<char> = name.chars().collect();
    let mut out = String::with_capacity(name.len() + 4);
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if i > 0 && chars[i - 1].is_ascii_lowercase() && c.is_ascii_uppercase() {
            out.push('_');
            out.push(c.to_ascii_lowercase());
            while i + 1 < chars.len() && chars[i + 1].is_ascii_uppercase() {
                i += 1;
                out.push(chars[i].to_ascii_lowercase());
            }
        } else {
            out.push(c);
        }
        i += 1;
    }
    out
}

/// A scene's `version`: three numbers separated by periods (Mitsuba's
/// rule); `None` when it is not.
fn parse_version(text: &str) -> Option<[u32; 3]> {
    let parts: Vec<&str> = text.split([' ', '.']).filter(|t| !t.is_empty()).collect();
    match parts.as_slice() {
        [a, b, c] => Some([a.parse().ok()?, b.parse().ok()?, c.parse().ok()?]),
        _ => None,
    }
}

/// A plugin element's children, each to be used once; what is left over
/// when [`Loader::finish`] runs is an error.
struct Props<'a, 'i> {
    node: Node<'a, 'i>,
    children: Vec<(Node<'a, 'i>, bool)>,
}

/// Walks the document and builds the scene.
struct Loader<'a, 'i> {
    path: &'a Path,
    /// Render settings that replace the scene's (the command line's).
    overrides: RenderOverrides,
    /// The scene file's folder: files are looked up there last.
    dir: PathBuf,
    /// `<path value>` folders, the last one first: files are looked up in
    /// these before the scene file's folder, as Mitsuba's file resolver does.
    search: Vec<PathBuf>,
    /// Per file ([`Loader::docs`]): it is older than 2.0.0, so its property
    /// names are upgraded ([`Loader::prop_name`]).
    upgrade_v1: Vec<bool>,
    /// The scene file (index 0) and the files its `<include>`s name, parsed.
    docs: &'a [Document<'i>],
    /// Their paths, and which `<include>` names which file.
    sources: &'a include::Sources,
    /// `<default name value>` parameters, for `$name`.
    defaults: HashMap<String, String>,
    /// `<bsdf id>`s and `<texture id>`s anywhere in the scene, for `<ref id>`.
    ids: HashMap<String, Node<'a, 'i>>,
    materials: Vec<Material>,
    /// ((file, BSDF element position), emission bits) -> material index.
    material_index: HashMap<((usize, usize), [u32; 3]), u32>,
    spheres: Vec<Sphere>,
    triangles: Vec<Triangle>,
    /// [`Scene::mesh_attributes`].
    mesh_attributes: Vec<[glam::Vec3; 3]>,
    warnings: Vec<String>,
    /// Meshes that lost degenerate or non-finite triangles: where each is
    /// named in the scene, and how many it lost; one warning sums them up
    /// when there are many.
    dropped: Vec<(String, usize)>,
    /// Mesh files read ([`Scene::files`]).
    files: Vec<PathBuf>,
    /// Each `shapegroup` instanced so far, by (file, element position): its
    /// shapes in the group's own space, read once however often instanced.
    groups: HashMap<(usize, usize), GroupShapes>,
    /// The `shapegroup` whose shapes are being read, if any: Mitsuba
    /// instances no emitter.
    in_group: Option<Node<'a, 'i>>,
}

/// The shapes of a `shapegroup`, in the group's space.
#[derive(Default)]
struct GroupShapes {
    triangles: Vec<Triangle>,
    spheres: Vec<Sphere>,
}

impl<'a, 'i> Loader<'a, 'i> {
    // ------------------------------------------------------------ messages

    /// Which of [`Loader::docs`] holds `node`.
    fn doc_index(&self, node: Node) -> usize {
        self.docs
            .iter()
            .position(|d| std::ptr::eq(d, node.document()))
            .unwrap_or(0)
    }

    /// The file that holds `node`.
    fn file_of(&self, node: Node) -> &'a Path {
        &self.sources.files[self.doc_index(node)].path
    }

    /// The 1-based line of byte `pos` of the file that holds `node`.
    fn line_at(&self, node: Node, pos: usize) -> usize {
        node.document().text_pos_at(pos).row as usize
    }

    /// The 1-based line where `node` starts.
    fn line(&self, node: Node) -> usize {
        self.line_at(node, node.range().start)
    }

    /// Where `node` is, for a message about another element: `line N` in
    /// the same file as `here`, else `FILE:N`.
    fn place(&self, node: Node, here: Node) -> String {
        if self.doc_index(node) == self.doc_index(here) {
            format!("line {}", self.line(node))
        } else {
            format!(
                "{}:{}",
                crate::util::text::cut_path(self.file_of(node)),
                self.line(node)
            )
        }
    }

    /// `<tag type="..." name="..." id="...">`, as written.
    fn describe(node: Node) -> String {
        let mut s = format!("<{}", cut(node.tag_name().name()));
        for key in ["type", "name", "id"] {
            if let Some(v) = node.attribute(key) {
                s += &format!(" {key}=\"{}\"", cut(v));
            }
        }
        s + ">"
    }

    fn err(&self, node: Node, reason: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: self.file_of(node).to_path_buf(),
            line: Some(self.line(node)),
            key: Self::describe(node),
            reason: reason.into(),
        }
    }

    fn attr_err(&self, node: Node, attr: &str, reason: impl std::fmt::Display) -> SceneError {
        let line = node
            .attribute_node(attr)
            .map_or(node.range().start, |a| a.range().start);
        SceneError::Invalid {
            path: self.file_of(node).to_path_buf(),
            line: Some(self.line_at(node, line)),
            key: Self::describe(node),
            reason: format!("attribute `{}`: {reason}", cut(attr)),
        }
    }

    /// A file named in the scene: the first `<path>` folder (the last one
    /// given first), then the scene file's folder, that holds it; else its
    /// place in the scene file's folder (whose error names that place). An
    /// absolute name is used as it is.
    fn resolve(&self, file: &str) -> PathBuf {
        let file = Path::new(file);
        if file.is_absolute() {
            return file.to_path_buf();
        }
        self.search
            .iter()
            .map(|folder| folder.join(file))
            .find(|candidate| candidate.exists())
            .unwrap_or_else(|| self.dir.join(file))
    }

    // ---------------------------------------------------------- attributes

    /// A child's `name` as Mitsuba 3 reads it: in a scene older than 2.0.0,
    /// camelCase becomes snake_case (`sampleCount` -> `sample_count`,
    /// `intIOR` -> `int_ior`), and a diffuse BSDF's `diffuse_reflectance` is
    /// its `reflectance`, as Mitsuba upgrades old scenes.
    fn prop_name(&self, child: Node) -> Option<String> {
        let doc = self.doc_index(child);
        if doc > 0 && child == self.docs[doc].root_element() {
            // The root of an included file that is not a scene: its name is
            // the `<include>`'s, as in Mitsuba.
            return self.sources.files[doc].include_name.clone();
        }
        let name = child.attribute("name")?;
        if !self.upgrade_v1[doc] {
            return Some(name.to_string());
        }
        let upgraded = camel_to_snake(name);
        let parent_diffuse = child
            .parent_element()
            .is_some_and(|p| p.attribute("type") == Some("diffuse"));
        if parent_diffuse && upgraded == "diffuse_reflectance" {
            return Some(String::from("reflectance"));
        }
        Some(upgraded)
    }

    /// Every attribute of `node` must be in `allowed`.
    fn check_attrs(&self, node: Node, allowed: &[&str]) -> Result<()> {
        // The root of an included file states its version (Mitsuba requires it).
        let included_root = node.parent().is_some_and(|p| p.is_root()) && self.doc_index(node) > 0;
        for a in node.attributes() {
            if included_root && a.name() == "version" && a.namespace().is_none() {
                continue;
            }
            if !allowed.contains(&a.name()) || a.namespace().is_some() {
                return Err(self.attr_err(
                    node,
                    a.name(),
                    format!(
                        "unsupported attribute of <{}>; lancer reads: {}",
                        cut(node.tag_name().name()),
                        if allowed.is_empty() {
                            String::from("none")
                        } else {
                            allowed.join(", ")
                        }
                    ),
                ));
            }
        }
        Ok(())
    }

    /// An attribute's value with every `$name` replaced by its `<default>`.
    fn attr(&self, node: Node, name: &str) -> Result<Option<String>> {
        let Some(raw) = node.attribute(name) else {
            return Ok(None);
        };
        substitute(raw, &self.defaults)
            .map(Some)
            .map_err(|key| self.attr_err(node, name, no_default(&key)))
    }

    fn required_attr(&self, node: Node, name: &str) -> Result<String> {
        self.attr(node, name)?
            .ok_or_else(|| self.err(node, format!("missing attribute `{name}`")))
    }

    /// The `type` attribute, which must be one of `allowed`.
    fn plugin_type(&self, node: Node, allowed: &[&str]) -> Result<String> {
        let kind = self.required_attr(node, "type")?;
        if !allowed.contains(&kind.as_str()) {
            return Err(self.attr_err(
                node,
                "type",
                format!(
                    "unsupported {} type \"{}\"; lancer reads: {}",
                    node.tag_name().name(),
                    cut(&kind),
                    allowed.join(", ")
                ),
            ));
        }
        Ok(kind)
    }

    // ---------------------------------------------------------- properties

    /// The element children of `node`; text other than white space is an
    /// error.
    fn props(&self, node: Node<'a, 'i>) -> Result<Props<'a, 'i>> {
        let children = self
            .elements(node)?
            .into_iter()
            .map(|c| (c, false))
            .collect();
        Ok(Props { node, children })
    }

    /// The element children of `node`, each `<include>` replaced by what
    /// its file holds (a `<scene>`'s children, or its one other element), as
    /// Mitsuba splices it; text other than white space is an error.
    fn elements(&self, node: Node<'a, 'i>) -> Result<Vec<Node<'a, 'i>>> {
        self.splice(node, true)
    }

    /// [`Loader::elements`]; text is an error only when `strict`.
    fn splice(&self, node: Node<'a, 'i>, strict: bool) -> Result<Vec<Node<'a, 'i>>> {
        let mut out = Vec::new();
        for child in node.children() {
            if child.is_element() {
                if child.tag_name().name() == "include" && child.tag_name().namespace().is_none() {
                    let doc = self.doc_index(child);
                    let Some(&file) = self.sources.includes.get(&(doc, child.range().start)) else {
                        return Err(self.err(child, "an <include> that was not read"));
                    };
                    let root = self.docs[file].root_element();
                    if root.tag_name().name() == "scene" {
                        out.extend(self.splice(root, strict)?);
                    } else {
                        out.push(root);
                    }
                } else {
                    out.push(child);
                }
            } else if strict && child.is_text() && !child.text().unwrap_or("").trim().is_empty() {
                return Err(self.err(node, "unexpected text inside the element"));
            }
        }
        Ok(out)
    }

    /// Every element under `node`, `<include>`s spliced in, in document order.
    fn descendants(&self, node: Node<'a, 'i>, out: &mut Vec<Node<'a, 'i>>) -> Result<()> {
        for child in self.splice(node, false)? {
            out.push(child);
            self.descendants(child, out)?;
        }
        Ok(())
    }

    /// The property element named `name` (one of `tags`), marked used.
    fn take(
        &self,
        p: &mut Props<'a, 'i>,
        tags: &[&str],
        name: &str,
    ) -> Result<Option<Node<'a, 'i>>> {
        let mut found = None;
        for (child, used) in p.children.iter_mut() {
            if PROPERTY_TAGS.contains(&child.tag_name().name())
                && self.prop_name(*child).as_deref() == Some(name)
            {
                if found.is_some() {
                    return Err(self.err(
                        *child,
                        format!("property `{name}` is given twice; give it once"),
                    ));
                }
                if !tags.contains(&child.tag_name().name()) {
                    return Err(self.err(
                        *child,
                        format!(
                            "property `{name}` of <{}> must be given as <{}>",
                            cut(p.node.tag_name().name()),
                            tags.join("> or <")
                        ),
                    ));
                }
                *used = true;
                found = Some(*child);
            }
        }
        Ok(found)
    }

    /// A `<ref name id>` child standing for the property `name` (e.g. a
    /// texture given by id), marked used.
    fn take_ref(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<Node<'a, 'i>>> {
        let mut found = None;
        for (child, used) in p.children.iter_mut() {
            if child.tag_name().name() == "ref" && self.prop_name(*child).as_deref() == Some(name) {
                if found.is_some() {
                    return Err(self.err(
                        *child,
                        format!("property `{name}` is given twice; give it once"),
                    ));
                }
                self.check_attrs(*child, &["id", "name"])?;
                *used = true;
                found = Some(*child);
            }
        }
        Ok(found)
    }

    /// Nested plugin elements with tag `tag` (e.g. `bsdf`) that no reader
    /// has taken yet, marked used.
    fn take_nested(&self, p: &mut Props<'a, 'i>, tags: &[&str]) -> Vec<Node<'a, 'i>> {
        let mut out = Vec::new();
        for (child, used) in p.children.iter_mut() {
            if !*used
                && tags.contains(&child.tag_name().name())
                && !PROPERTY_TAGS.contains(&child.tag_name().name())
            {
                *used = true;
                out.push(*child);
            }
        }
        out
    }

    /// At most one nested element of these tags.
    fn take_one(&self, p: &mut Props<'a, 'i>, tags: &[&str]) -> Result<Option<Node<'a, 'i>>> {
        let nested = self.take_nested(p, tags);
        if let Some(second) = nested.get(1) {
            return Err(self.err(
                *second,
                format!(
                    "a second <{}> in <{}>; give one",
                    cut(second.tag_name().name()),
                    cut(p.node.tag_name().name())
                ),
            ));
        }
        Ok(nested.first().copied())
    }

    /// Fails on the first child nobody used.
    fn finish(&self, p: Props) -> Result<()> {
        for (child, used) in &p.children {
            if !used {
                // A reference to nothing: say that, not that <ref> is unread
                let dangling = (child.tag_name().name() == "ref")
                    .then(|| child.attribute("id"))
                    .flatten()
                    .filter(|id| !self.ids.contains_key(*id));
                if let Some(id) = dangling {
                    return Err(self.attr_err(
                        *child,
                        "id",
                        format!(
                            "no element with id \"{}\" in the scene, which {} refers to; \
                             define it (e.g. <sampler id=\"{0}\"> for a sensor's sampler) or \
                             remove the <ref>",
                            cut(id),
                            Self::describe(p.node)
                        ),
                    ));
                }
                let what = match self.prop_name(*child).as_deref() {
                    Some(name) if PROPERTY_TAGS.contains(&child.tag_name().name()) => {
                        format!("property `{}`", cut(name))
                    }
                    _ => format!("element <{}>", cut(child.tag_name().name())),
                };
                return Err(self.err(
                    *child,
                    format!(
                        "{what} of {} is outside the subset lancer reads (docs/mitsuba.md); \
                         remove it",
                        Self::describe(p.node)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The `value` attribute of a simple property element.
    fn value(&self, node: Node) -> Result<String> {
        self.check_attrs(node, &["name", "value"])?;
        self.required_attr(node, "value")
    }

    fn float(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<f64>> {
        let Some(node) = self.take(p, &["float", "integer"], name)? else {
            return Ok(None);
        };
        let text = self.value(node)?;
        match numbers(&text).as_deref() {
            Some([x]) => Ok(Some(*x)),
            _ => Err(self.attr_err(
                node,
                "value",
                format!("expected a finite number, got \"{}\"", cut(&text)),
            )),
        }
    }

    fn integer(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<(i64, Node<'a, 'i>)>> {
        let Some(node) = self.take(p, &["integer"], name)? else {
            return Ok(None);
        };
        let text = self.value(node)?;
        let x = text.trim().parse::<i64>().map_err(|_| {
            self.attr_err(
                node,
                "value",
                format!("expected an integer, got \"{}\"", cut(&text)),
            )
        })?;
        Ok(Some((x, node)))
    }

    /// An integer in `min..=u32::MAX`.
    fn count(&self, p: &mut Props<'a, 'i>, name: &str, min: u32) -> Result<Option<u32>> {
        let Some((x, node)) = self.integer(p, name)? else {
            return Ok(None);
        };
        u32::try_from(x)
            .ok()
            .filter(|&x| x >= min)
            .map(Some)
            .ok_or_else(|| {
                self.attr_err(
                    node,
                    "value",
                    format!("must be an integer from {min} to {}, got {x}", u32::MAX),
                )
            })
    }

    fn string(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<(String, Node<'a, 'i>)>> {
        let Some(node) = self.take(p, &["string"], name)? else {
            return Ok(None);
        };
        Ok(Some((self.value(node)?, node)))
    }

    fn boolean(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<bool>> {
        let Some(node) = self.take(p, &["boolean"], name)? else {
            return Ok(None);
        };
        match self.value(node)?.trim() {
            "true" => Ok(Some(true)),
            "false" => Ok(Some(false)),
            other => Err(self.attr_err(
                node,
                "value",
                format!("expected true or false, got \"{}\"", cut(other)),
            )),
        }
    }

    /// A colour: `<rgb value="r, g, b">`, `<rgb value="x">`, `<float>` or a
    /// uniform `<spectrum value="x">` (a grey, as in Mitsuba's RGB
    /// variants); every component finite and >= 0.
    fn color(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<Rgb>> {
        let Some(node) = self.take(p, COLOR_TAGS, name)? else {
            return Ok(None);
        };
        self.color_of(node).map(Some)
    }

    /// The colour of an `<rgb>`, `<float>` or `<spectrum>` element outside
    /// an emitter: a reflectance, whose spectrum Mitsuba's RGB variants
    /// clamp to [0, 1] once it is RGB.
    fn color_of(&self, node: Node) -> Result<Rgb> {
        self.color_bounded(node, true)
    }

    /// As [`Loader::color_of`], for a value that may exceed 1 (a
    /// conductor's `eta` and `k`): a spectrum is clamped at 0 only.
    fn unbounded_color_of(&self, node: Node) -> Result<Rgb> {
        self.color_bounded(node, false)
    }

    fn color_bounded(&self, node: Node, bounded: bool) -> Result<Rgb> {
        if node.tag_name().name() == "spectrum" {
            return Ok(match self.spectrum(node)? {
                Spectrum::Uniform(x) => Vec3::splat(x as f32),
                Spectrum::Pairs(w, v) => spectrum_to_rgb(&w, &v, bounded, true).as_vec3(),
            });
        }
        let text = self.value(node)?;
        let c = match numbers(&text).as_deref() {
            Some(&[x]) => DVec3::splat(x),
            Some(&[r, g, b]) => DVec3::new(r, g, b),
            _ => {
                return Err(self.attr_err(
                    node,
                    "value",
                    format!("expected \"r, g, b\" or one number, got \"{}\"", cut(&text)),
                ))
            }
        };
        if c.min_element() < 0.0 {
            return Err(self.attr_err(
                node,
                "value",
                format!("colour components must be >= 0, got \"{}\"", cut(&text)),
            ));
        }
        Ok(c.as_vec3())
    }

    /// A `<spectrum>`: one number (>= 0), the same at every wavelength, or
    /// wavelength:value pairs (wavelengths in nm, increasing; values >= 0),
    /// which Mitsuba's RGB variants turn into RGB by the rules of
    /// [`spectrum_to_rgb`]. A spectrum given by `wavelengths` and `values`,
    /// from a file or as a plugin is refused.
    fn spectrum(&self, node: Node) -> Result<Spectrum> {
        let name = node.attribute("name").unwrap_or("...");
        let refuse = |attr: &str, what: &str| {
            self.attr_err(
                node,
                attr,
                format!(
                    "a spectrum {what} is outside the subset lancer reads; write it as \
                     wavelength:value pairs or as <rgb name=\"{}\" value=\"r, g, b\"/>",
                    cut(name)
                ),
            )
        };
        if node.attribute("filename").is_some() {
            return Err(refuse("filename", "read from a file"));
        }
        for attr in ["wavelengths", "values"] {
            if node.attribute(attr).is_some() {
                return Err(refuse(attr, "given by wavelengths and values"));
            }
        }
        if node.attribute("type").is_some() {
            return Err(refuse("type", "plugin"));
        }
        let text = self.value(node)?;
        if text.contains(':') {
            return self.spectrum_pairs(node, &text);
        }
        match numbers(&text).as_deref() {
            Some(&[x]) if x >= 0.0 => Ok(Spectrum::Uniform(x)),
            Some(&[_]) => Err(self.attr_err(
                node,
                "value",
                format!("a spectrum must be >= 0, got \"{}\"", cut(&text)),
            )),
            _ => Err(refuse("value", "of more than one number")),
        }
    }

    /// The wavelength:value pairs of a `<spectrum value>`, checked.
    fn spectrum_pairs(&self, node: Node, text: &str) -> Result<Spectrum> {
        let bad = |why: String| self.attr_err(node, "value", why);
        let (mut w, mut v) = (Vec::new(), Vec::new());
        for pair in text.split(',') {
            if w.len() == super::limits::MAX_SPECTRUM_PAIRS {
                return Err(bad(format!(
                    "a spectrum of more than {} wavelength:value pairs; resample it",
                    super::limits::MAX_SPECTRUM_PAIRS
                )));
            }
            let parsed = pair.split_once(':').and_then(|(a, b)| {
                let a: f64 = a.trim().parse().ok()?;
                let b: f64 = b.trim().parse().ok()?;
                (a.is_finite() && b.is_finite()).then_some((a, b))
            });
            let Some((nm, value)) = parsed else {
                return Err(bad(format!(
                    "expected wavelength:value pairs of finite numbers separated by commas, got \"{}\"",
                    cut(pair.trim())
                )));
            };
            if value < 0.0 {
                return Err(bad(format!(
                    "a spectrum must be >= 0, got {value} at {nm} nm"
                )));
            }
            if w.last().is_some_and(|&last| nm <= last) {
                return Err(bad(format!(
                    "the wavelengths of a spectrum must increase, got {nm} nm after {} nm",
                    w[w.len() - 1]
                )));
            }
            w.push(nm);
            v.push(value);
        }
        if w.len() < 2 {
            return Err(bad(
                "a spectrum of wavelength:value pairs needs at least two pairs".to_string(),
            ));
        }
        Ok(Spectrum::Pairs(w, v))
    }

    /// A radiance: a colour of at most `MAX_RADIANCE` per component. A
    /// uniform `<spectrum>` is the D65 illuminant times its value, as
    /// Mitsuba's RGB variants read an emitter's spectrum.
    fn radiance(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<Rgb>> {
        let Some(node) = self.take(p, COLOR_TAGS, name)? else {
            return Ok(None);
        };
        self.radiance_of(node).map(Some)
    }

    /// The radiance [`Self::radiance`] reads from a colour element.
    fn radiance_of(&self, node: Node<'a, 'i>) -> Result<Rgb> {
        let c = if node.tag_name().name() == "spectrum" {
            match self.spectrum(node)? {
                // The D65 illuminant scaled, as Mitsuba reads a uniform radiance
                Spectrum::Uniform(x) => Vec3::from(D65_RGB) * x as f32,
                // An emitter's own spectrum, not weighed by D65 nor clamped at 1
                Spectrum::Pairs(w, v) => spectrum_to_rgb(&w, &v, false, false).as_vec3(),
            }
        } else {
            self.color_of(node)?
        };
        let limit = super::limits::MAX_RADIANCE;
        if c.max_element() as f64 > limit {
            return Err(self.attr_err(
                node,
                "value",
                format!(
                    "radiance components must be <= {limit:e} (sums over many samples must \
                     stay inside 32-bit floats); scale every emitter down by the same factor"
                ),
            ));
        }
        Ok(c)
    }

    /// `<point name x y z>` or `<point name value="x, y, z">`.
    fn point(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<DVec3>> {
        let Some(node) = self.take(p, &["point", "vector"], name)? else {
            return Ok(None);
        };
        self.check_attrs(node, &["name", "value", "x", "y", "z"])?;
        self.xyz(node, 0.0).map(Some)
    }

    /// A vector from `value="x, y, z"` (or one number for all three) or the
    /// `x`, `y`, `z` attributes, each `default` when absent.
    fn xyz(&self, node: Node, default: f64) -> Result<DVec3> {
        if let Some(text) = self.attr(node, "value")? {
            for k in ["x", "y", "z"] {
                if node.attribute(k).is_some() {
                    return Err(self.attr_err(
                        node,
                        k,
                        "give either `value` or `x`, `y`, `z`, not both",
                    ));
                }
            }
            return match numbers(&text).as_deref() {
                Some(&[x]) => Ok(DVec3::splat(x)),
                Some(&[x, y, z]) => Ok(DVec3::new(x, y, z)),
                _ => Err(self.attr_err(
                    node,
                    "value",
                    format!("expected \"x, y, z\", got \"{}\"", cut(&text)),
                )),
            };
        }
        let mut out = [default; 3];
        for (k, slot) in ["x", "y", "z"].iter().zip(out.iter_mut()) {
            if let Some(text) = self.attr(node, k)? {
                *slot = match numbers(&text).as_deref() {
                    Some(&[x]) => x,
                    _ => {
                        return Err(self.attr_err(
                            node,
                            k,
                            format!("expected a finite number, got \"{}\"", cut(&text)),
                        ))
                    }
                };
            }
        }
        Ok(DVec3::from_array(out))
    }

    /// `<transform name>`: its steps applied in order (each one multiplies
    /// from the left, as in Mitsuba).
    fn transform(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<DAffine3>> {
        let Some(node) = self.take(p, &["transform"], name)? else {
            return Ok(None);
        };
        self.check_attrs(node, &["name"])?;
        let steps = self.props(node)?;
        let mut m = DAffine3::IDENTITY;
        for (step, _) in &steps.children {
            let step_m = match step.tag_name().name() {
                "translate" => {
                    self.check_attrs(*step, &["value", "x", "y", "z"])?;
                    DAffine3::from_translation(self.xyz(*step, 0.0)?)
                }
                "scale" => {
                    self.check_attrs(*step, &["value", "x", "y", "z"])?;
                    DAffine3::from_scale(self.xyz(*step, 1.0)?)
                }
                "rotate" => {
                    self.check_attrs(*step, &["value", "x", "y", "z", "angle"])?;
                    let axis = self.xyz(*step, 0.0)?;
                    let angle = self.attr(*step, "angle")?.ok_or_else(|| self.err(*step, "missing attribute `angle` (degrees)"))?;
                    let angle = match numbers(&angle).as_deref() {
                        Some(&[a]) => a,
                        _ => return Err(self.attr_err(*step, "angle", "expected a number of degrees")),
                    };
                    if axis.length_squared() == 0.0 {
                        return Err(self.err(*step, "the rotation axis is [0, 0, 0]; give x, y, z (or value) of a non-zero axis"));
                    }
                    // Mitsuba does not normalise the axis: a longer one also scales.
                    let (sin, cos) = angle.to_radians().sin_cos();
                    let k = axis;
                    let cross = DMat3::from_cols(
                        DVec3::new(0.0, k.z, -k.y),
                        DVec3::new(-k.z, 0.0, k.x),
                        DVec3::new(k.y, -k.x, 0.0),
                    );
                    let outer = DMat3::from_cols(k * k.x, k * k.y, k * k.z);
                    DAffine3::from_mat3(DMat3::from_diagonal(DVec3::splat(cos)) + cross * sin + outer * (1.0 - cos))
                }
                "matrix" => {
                    self.check_attrs(*step, &["value"])?;
                    let text = self.required_attr(*step, "value")?;
                    let v = numbers(&text).unwrap_or_default();
                    match v.len() {
                        16 => {
                            if v[12..] != [0.0, 0.0, 0.0, 1.0] {
                                return Err(self.attr_err(*step, "value", "the last row must be 0 0 0 1: lancer reads affine transforms only"));
                            }
                            DAffine3::from_mat3_translation(
                                DMat3::from_cols_array(&[v[0], v[4], v[8], v[1], v[5], v[9], v[2], v[6], v[10]]),
                                DVec3::new(v[3], v[7], v[11]),
                            )
                        }
                        9 => DAffine3::from_mat3(DMat3::from_cols_array(&[v[0], v[3], v[6], v[1], v[4], v[7], v[2], v[5], v[8]])),
                        _ => return Err(self.attr_err(*step, "value", "expected 16 (4x4, row by row) or 9 (3x3) finite numbers")),
                    }
                }
                "lookat" => {
                    self.check_attrs(*step, &["origin", "target", "up"])?;
                    let get = |k: &str| -> Result<DVec3> {
                        let text = self.attr(*step, k)?.ok_or_else(|| self.err(*step, format!("missing attribute `{k}`")))?;
                        match numbers(&text).as_deref() {
                            Some(&[x, y, z]) => Ok(DVec3::new(x, y, z)),
                            _ => Err(self.attr_err(*step, k, format!("expected \"x, y, z\", got \"{}\"", cut(&text)))),
                        }
                    };
                    let (origin, target) = (get("origin")?, get("target")?);
                    let up = if step.attribute("up").is_some() { get("up")? } else { DVec3::Y };
                    let dir = (target - origin).normalize_or_zero();
                    let left = up.cross(dir).normalize_or_zero();
                    if dir == DVec3::ZERO || left == DVec3::ZERO {
                        return Err(self.err(*step, "origin equals target, or up is parallel to target - origin; move target or change up"));
                    }
                    DAffine3::from_mat3_translation(DMat3::from_cols(left, dir.cross(left), dir), origin)
                }
                other => {
                    return Err(self.err(
                        *step,
                        format!("unsupported transform step <{}>; lancer reads: translate, rotate, scale, matrix, lookat", cut(other)),
                    ))
                }
            };
            m = step_m * m;
        }
        if !m.is_finite() {
            return Err(self.err(node, "the transform is not finite"));
        }
        Ok(Some(m))
    }

    // --------------------------------------------------------------- scene
}

/// A `<spectrum>`'s value.
enum Spectrum {
    /// The same at every wavelength.
    Uniform(f64),
    /// Wavelengths (nm, increasing) and values, linear between them.
    Pairs(Vec<f64>, Vec<f64>),
}
