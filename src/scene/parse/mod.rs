//! The TOML walker: checks every key of docs/scene-format.md with its line and
//! builds the [`Scene`].
//!
//! The document is parsed into toml's spanned tree ([`DeTable`]), so every
//! key and value carries its byte range, which becomes a 1-based line in the
//! messages. Errors are reported one at a time, the first found.

use super::builder::{quad_triangles, ENERGY_SLACK, ZERO_AREA_QUAD};
use super::limits;
use super::obj::{self, Transform};
use super::types::*;
use super::SceneError;
use super::{conductor_preset, conductor_preset_names};
use crate::util::text::{cut, cut_path};
use glam::{DVec3, Vec3};
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::de::{DeTable, DeValue};
use toml::Spanned;

pub(crate) mod lights;
mod materials;
mod objects;

use materials::parse_material;
use objects::Builder;

type Val<'i> = Spanned<DeValue<'i>>;
type Result<T> = std::result::Result<T, SceneError>;

const TOP_KEYS: &[&str] = &[
    "render",
    "camera",
    "environment",
    "materials",
    "objects",
    "lights",
];
const RENDER_KEYS: &[&str] = &[
    "width",
    "height",
    "spp",
    "max_depth",
    "seed",
    "filter",
    "rr_depth",
];
/// Pixel filter types (`render.filter`), Mitsuba's names.
const FILTER_TYPES: &[&str] = &[
    "box",
    "tent",
    "gaussian",
    "mitchell",
    "catmullrom",
    "lanczos",
];
const CAMERA_KEYS: &[&str] = &[
    "eye",
    "look_at",
    "up",
    "vfov",
    "aperture_radius",
    "focus_distance",
    "near_clip",
    "far_clip",
];
const ENVIRONMENT_KEYS: &[&str] = &["radiance"];
const MATERIAL_TYPES: &[&str] = &[
    "lambert",
    "phong",
    "mirror",
    "glossy",
    "dielectric",
    "conductor",
    "roughconductor",
];
const OBJECT_TYPES: &[&str] = &["sphere", "quad", "mesh"];

/// The scene file being read: its text, path and line table.
struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
    /// The scene file's folder, for relative paths.
    dir: PathBuf,
    /// Byte offset of the start of every line.
    line_starts: Vec<usize>,
}

impl<'a> Ctx<'a> {
    fn new(path: &'a Path, text: &'a str) -> Self {
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        Ctx {
            path,
            text,
            dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
            line_starts,
        }
    }

    /// 1-based line of a byte offset.
    fn line_of(&self, offset: usize) -> usize {
        self.line_starts
            .partition_point(|&start| start <= offset)
            .max(1)
    }

    fn line(&self, span: &Range<usize>) -> Option<usize> {
        Some(self.line_of(span.start))
    }

    fn err(&self, line: Option<usize>, key: &str, reason: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            line,
            key: key.to_string(),
            reason: reason.into(),
        }
    }

    /// Error about a value, at its line.
    fn bad(&self, v: &Val, key: &str, reason: impl Into<String>) -> SceneError {
        self.err(self.line(&v.span()), key, reason)
    }

    /// The value as written, on one line, shortened if long.
    fn snippet(&self, v: &Val) -> String {
        let raw = self.text.get(v.span()).unwrap_or("");
        let mut s = raw.split_whitespace().collect::<Vec<_>>().join(" ");
        s = s.replace("[ ", "[").replace(" ]", "]");
        if s.chars().count() > 60 {
            s = s.chars().take(57).collect::<String>() + "...";
        }
        s
    }

    /// "a string \"abc\"", "integer 5", ...: what a value is, for messages.
    fn describe(&self, v: &Val) -> String {
        let kind = match v.get_ref() {
            DeValue::String(_) => "a string",
            DeValue::Integer(_) => "an integer",
            DeValue::Float(_) => "a float",
            DeValue::Boolean(_) => "a boolean",
            DeValue::Datetime(_) => "a date-time",
            DeValue::Array(_) => "an array",
            DeValue::Table(_) => return String::from("a table"),
        };
        format!("{kind} {}", self.snippet(v))
    }

    fn wrong_type(&self, v: &Val, key: &str, expected: &str) -> SceneError {
        self.bad(
            v,
            key,
            format!("expected {expected}, got {}", self.describe(v)),
        )
    }

    /// A number (integer or float), finite and within f32's range.
    fn number(&self, v: &Val, key: &str) -> Result<f64> {
        let x = match v.get_ref() {
            DeValue::Integer(i) => match i64::from_str_radix(i.as_str(), i.radix()) {
                Ok(x) => x as f64,
                Err(_) => i.as_str().parse::<f64>().unwrap_or(f64::INFINITY),
            },
            DeValue::Float(f) => f.as_str().parse::<f64>().unwrap_or(f64::NAN),
            _ => return Err(self.wrong_type(v, key, "a number")),
        };
        if !x.is_finite() {
            return Err(self.bad(
                v,
                key,
                format!("must be a finite number, got {}", self.snippet(v)),
            ));
        }
        if x.abs() > f32::MAX as f64 {
            return Err(self.bad(
                v,
                key,
                format!("is too large for a 32-bit float, got {}", self.snippet(v)),
            ));
        }
        Ok(x)
    }

    /// A boolean (`true` or `false`).
    fn boolean(&self, v: &Val, key: &str) -> Result<bool> {
        match v.get_ref() {
            DeValue::Boolean(b) => Ok(*b),
            _ => Err(self.wrong_type(v, key, "true or false")),
        }
    }

    /// An integer in `min..=u32::MAX`.
    fn uint(&self, v: &Val, key: &str, min: u32) -> Result<u32> {
        let DeValue::Integer(i) = v.get_ref() else {
            return Err(self.wrong_type(v, key, "an integer"));
        };
        let x = i128::from_str_radix(i.as_str(), i.radix()).unwrap_or(i128::MAX);
        if x < min as i128 {
            return Err(self.bad(v, key, format!("must be >= {min}, got {}", self.snippet(v))));
        }
        u32::try_from(x).map_err(|_| {
            self.bad(
                v,
                key,
                format!("must be <= {}, got {}", u32::MAX, self.snippet(v)),
            )
        })
    }

    fn string<'v>(&self, v: &'v Val, key: &str) -> Result<&'v str> {
        match v.get_ref() {
            DeValue::String(s) => Ok(s.as_ref()),
            _ => Err(self.wrong_type(v, key, "a string")),
        }
    }

    /// `[x, y, z]`: three finite numbers.
    fn vec3(&self, v: &Val, key: &str) -> Result<DVec3> {
        let DeValue::Array(a) = v.get_ref() else {
            return Err(self.wrong_type(v, key, "an array of 3 numbers [x, y, z]"));
        };
        if a.len() != 3 {
            return Err(self.bad(
                v,
                key,
                format!(
                    "expected 3 numbers [x, y, z], got {} values {}",
                    a.len(),
                    self.snippet(v)
                ),
            ));
        }
        let mut out = [0.0; 3];
        for (i, e) in a.iter().enumerate() {
            out[i] = self.number(e, &format!("{key}[{i}]"))?;
        }
        Ok(DVec3::from_array(out))
    }

    /// `[r, g, b]`: three finite numbers >= 0.
    fn color(&self, v: &Val, key: &str) -> Result<Vec3> {
        let DeValue::Array(_) = v.get_ref() else {
            return Err(self.wrong_type(v, key, "a colour [r, g, b]"));
        };
        let c = self.vec3(v, key)?;
        if c.min_element() < 0.0 {
            return Err(self.bad(
                v,
                key,
                format!("colour components must be >= 0, got {}", self.snippet(v)),
            ));
        }
        Ok(c.as_vec3())
    }

    /// A radiance colour (emission, environment): a colour whose
    /// components are at most [`MAX_RADIANCE`](super::limits::MAX_RADIANCE).
    fn radiance(&self, v: &Val, key: &str) -> Result<Vec3> {
        let c = self.color(v, key)?;
        let limit = super::limits::MAX_RADIANCE;
        if c.max_element() as f64 > limit {
            return Err(self.bad(
                v,
                key,
                format!(
                    "radiance components must be <= {limit:e} (sums of radiance and its \
                     square over many samples must stay inside 32-bit floats), got {}; \
                     scale every emission and the environment down by the same factor",
                    self.snippet(v)
                ),
            ));
        }
        Ok(c)
    }

    /// A path relative to the scene's folder, checked to be readable.
    fn readable_file(&self, v: &Val, key: &str, what: &str) -> Result<PathBuf> {
        let file = self.string(v, key)?;
        if file.is_empty() {
            return Err(self.bad(v, key, format!("expected a {what} file name, got \"\"")));
        }
        let resolved = self.dir.join(file);
        obj::check_readable(&resolved).map_err(|e| {
            self.bad(
                v,
                key,
                format!("cannot read {what} file {}: {e}", cut_path(&resolved)),
            )
        })?;
        Ok(resolved)
    }
}

/// A TOML table being read: the keys it may hold, and how to name them.
struct Section<'a, 'i> {
    ctx: &'a Ctx<'a>,
    table: &'a DeTable<'i>,
    /// Dotted path of the table (`""` for the top level).
    prefix: String,
    /// How messages name it, e.g. `[camera]` or `objects[2] (a sphere)`.
    desc: String,
    /// Line of the table's header, for missing keys.
    line: Option<usize>,
}

impl<'a, 'i> Section<'a, 'i> {
    /// Entry `i` of the array of tables `[[array]]` as a section, and its
    /// required `type`, described as one of `types`.
    fn array_entry(
        ctx: &'a Ctx<'a>,
        array: &str,
        i: usize,
        v: &'a Val<'i>,
        types: &[&str],
    ) -> Result<(Section<'a, 'i>, &'a str)> {
        let prefix = format!("{array}[{i}]");
        let DeValue::Table(table) = v.get_ref() else {
            return Err(ctx.wrong_type(v, &prefix, &format!("a table [[{array}]]")));
        };
        let s = Section {
            ctx,
            table,
            desc: prefix.clone(),
            prefix,
            line: ctx.line(&v.span()),
        };
        let type_key = s.key("type");
        let type_val = s.require("type", &format!("one of {}", types.join(", ")))?;
        let kind = ctx.string(type_val, &type_key)?;
        Ok((s, kind))
    }

    /// The dotted key of `name` in this table, user text cut.
    fn key(&self, name: &str) -> String {
        if self.prefix.is_empty() {
            toml_key(name)
        } else {
            format!("{}.{}", self.prefix, toml_key(name))
        }
    }

    fn get(&self, name: &str) -> Option<&'a Val<'i>> {
        self.table.get(name)
    }

    /// Rejects keys not in `allowed`, the first in file order.
    fn check_keys(&self, allowed: &[&str]) -> Result<()> {
        let mut unknown: Vec<_> = self
            .table
            .keys()
            .filter(|k| !allowed.contains(&k.get_ref().as_ref()))
            .collect();
        unknown.sort_by_key(|k| k.span().start);
        if let Some(k) = unknown.first() {
            let name: &str = k.get_ref().as_ref();
            let place = if self.prefix.is_empty() {
                String::from("at the top level")
            } else {
                format!("in {}", self.desc)
            };
            let mut reason = format!(
                "unknown key `{}` {place}; expected one of: {}",
                cut(name),
                allowed.join(", ")
            );
            if let Some(close) = closest(name, allowed) {
                reason += &format!(" (did you mean `{}`?)", cut(close));
            }
            return Err(self
                .ctx
                .err(self.ctx.line(&k.span()), &self.key(name), reason));
        }
        Ok(())
    }

    fn missing(&self, name: &str, what: &str) -> SceneError {
        self.ctx.err(
            self.line,
            &self.key(name),
            format!("missing required key in {}: {what}", self.desc),
        )
    }

    fn require(&self, name: &str, what: &str) -> Result<&'a Val<'i>> {
        self.get(name).ok_or_else(|| self.missing(name, what))
    }

    /// A sub-table, e.g. `[camera]` in the top level.
    fn table(&self, name: &str, v: &'a Val<'i>) -> Result<Section<'a, 'i>> {
        let key = self.key(name);
        match v.get_ref() {
            DeValue::Table(t) => Ok(Section {
                ctx: self.ctx,
                table: t,
                desc: format!("[{key}]"),
                prefix: key,
                line: self.ctx.line(&v.span()),
            }),
            _ => Err(self.ctx.wrong_type(v, &key, &format!("a table [{key}]"))),
        }
    }

    fn opt<T>(&self, name: &str, f: impl FnOnce(&Val, &str) -> Result<T>) -> Result<Option<T>> {
        match self.get(name) {
            Some(v) => f(v, &self.key(name)).map(Some),
            None => Ok(None),
        }
    }

    fn req<T>(&self, name: &str, what: &str, f: impl FnOnce(&Val, &str) -> Result<T>) -> Result<T> {
        let v = self.require(name, what)?;
        f(v, &self.key(name))
    }

    /// Line of a key's value, if present; else of the table.
    fn line_of(&self, name: &str) -> Option<usize> {
        match self.get(name) {
            Some(v) => self.ctx.line(&v.span()),
            None => self.line,
        }
    }
}

/// A TOML key as written in a dotted path: bare if it can be, else quoted.
///
/// User text is cut to [`cut`]'s length, so a long key cannot flood a message.
fn toml_key(name: &str) -> String {
    let bare = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if bare {
        cut(name)
    } else {
        let quoted = format!("{name:?}");
        format!("\"{}\"", cut(&quoted[1..quoted.len() - 1]))
    }
}

/// The allowed word closest to a misspelt one, if close enough: a few
/// edits away, or sharing a long prefix (`lambertian`, `rotation`).
fn closest<'s>(word: &str, candidates: &[&'s str]) -> Option<&'s str> {
    // No word near one of the candidates is this long (and the distance
    // below costs its length times theirs).
    if word.len() > 64 {
        return None;
    }
    fn distance(a: &str, b: &str) -> usize {
        let b: Vec<char> = b.chars().collect();
        let mut prev: Vec<usize> = (0..=b.len()).collect();
        for (i, ca) in a.chars().enumerate() {
            let mut cur = vec![i + 1; b.len() + 1];
            for (j, &cb) in b.iter().enumerate() {
                let cost = usize::from(ca != cb);
                cur[j + 1] = (prev[j] + cost).min(prev[j + 1] + 1).min(cur[j] + 1);
            }
            prev = cur;
        }
        prev[b.len()]
    }
    let lower = word.to_ascii_lowercase();
    candidates
        .iter()
        .filter_map(|&c| {
            let d = distance(&lower, c);
            let prefix = lower
                .chars()
                .zip(c.chars())
                .take_while(|(a, b)| a == b)
                .count();
            let close =
                d <= (c.len() / 3).max(1) || prefix >= 5 || (prefix >= 3 && prefix == c.len());
            close.then_some((d, c))
        })
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

/// Entries of a table in file order.
fn in_file_order<'a, 'i>(
    table: &'a DeTable<'i>,
) -> Vec<(&'a Spanned<std::borrow::Cow<'i, str>>, &'a Val<'i>)> {
    let mut entries: Vec<_> = table.iter().collect();
    entries.sort_by_key(|(k, _)| k.span().start);
    entries
}

/// Parses, validates and flattens a scene.
pub(crate) fn parse_scene(text: &str, path: &Path, overrides: &RenderOverrides) -> Result<Scene> {
    let ctx = Ctx::new(path, text);
    let doc = DeTable::parse(text).map_err(|e| {
        let mut message = e.message().trim().replace('\n', "; ");
        // toml names the line of a duplicate key but not the key.
        if message == "duplicate key" {
            if let Some(key) = e.span().and_then(|span| text.get(span)) {
                message = format!(
                    "duplicate key `{}`: a key may be given once per table; remove one",
                    cut(key.trim())
                );
            }
        }
        SceneError::Syntax {
            path: path.to_path_buf(),
            line: e.span().map(|s| ctx.line_of(s.start)),
            message,
        }
    })?;
    let top = Section {
        ctx: &ctx,
        table: doc.get_ref(),
        prefix: String::new(),
        desc: String::from("the top level"),
        line: None,
    };
    top.check_keys(TOP_KEYS)?;

    let render = match top.get("render") {
        Some(v) => parse_render(&top.table("render", v)?, overrides)?,
        None => {
            return Err(ctx.err(
                None,
                "render",
                "missing required table [render] (with width, height and spp)",
            ))
        }
    };
    let camera = match top.get("camera") {
        Some(v) => parse_camera(&top.table("camera", v)?, &render)?,
        None => {
            return Err(ctx.err(
                None,
                "camera",
                "missing required table [camera] (with eye, look_at and vfov)",
            ))
        }
    };
    let environment = match top.get("environment") {
        Some(v) => {
            let env = top.table("environment", v)?;
            env.check_keys(ENVIRONMENT_KEYS)?;
            env.opt("radiance", |v, k| ctx.radiance(v, k))?
                .unwrap_or(Vec3::ZERO)
        }
        None => Vec3::ZERO,
    };

    let mut materials = Vec::new();
    let mut by_name: HashMap<String, u32> = HashMap::new();
    if let Some(v) = top.get("materials") {
        let section = top.table("materials", v)?;
        for (name, value) in in_file_order(section.table) {
            let name: &str = name.get_ref().as_ref();
            let material = parse_material(&section, name, value)?;
            by_name.insert(name.to_string(), materials.len() as u32);
            materials.push(material);
        }
    }

    let mut builder = Builder {
        ctx: &ctx,
        materials,
        by_name,
        mtl_index: HashMap::new(),
        spheres: Vec::new(),
        triangles: Vec::new(),
        warnings: Vec::new(),
        files: Vec::new(),
        eye: camera.eye.as_dvec3(),
    };
    if let Some(v) = top.get("objects") {
        let DeValue::Array(objects) = v.get_ref() else {
            return Err(ctx.wrong_type(v, "objects", "an array of tables [[objects]]"));
        };
        for (i, object) in objects.iter().enumerate() {
            builder.object(i, object)?;
        }
    }

    let lights = lights::parse_lights(&top)?;

    // Refuse light that grows past the radiance limit along a path
    limits::check_path_gain(&builder.materials, environment, render.max_depth).map_err(|e| {
        let field_line = top
            .get("materials")
            .and_then(|v| top.table("materials", v).ok())
            .and_then(|section| {
                let name = &builder.materials[e.material].name;
                let table = section.table(name, section.get(name)?).ok()?;
                table.line_of(e.field)
            });
        ctx.err(field_line, &e.key(&builder.materials), e.reason)
    })?;

    Ok(Scene {
        render,
        camera,
        environment,
        envmap: None,
        materials: builder.materials,
        spheres: builder.spheres,
        triangles: builder.triangles,
        mesh_attributes: Vec::new(),
        lights,
        source: path.to_path_buf(),
        includes: Vec::new(),
        files: builder.files,
        warnings: builder.warnings,
    })
}

/// Reads `[render]`, applies `overrides`, then checks the settings once.
fn parse_render(s: &Section, overrides: &RenderOverrides) -> Result<RenderSettings> {
    let ctx = s.ctx;
    s.check_keys(RENDER_KEYS)?;
    let positive = "an integer >= 1";
    let mut render = RenderSettings {
        width: s.req("width", positive, |v, k| ctx.uint(v, k, 1))?,
        height: s.req("height", positive, |v, k| ctx.uint(v, k, 1))?,
        spp: s.req("spp", positive, |v, k| ctx.uint(v, k, 1))?,
        max_depth: s.opt("max_depth", |v, k| ctx.uint(v, k, 1))?.unwrap_or(8),
        seed: s.opt("seed", |v, k| ctx.uint(v, k, 0))?.unwrap_or(0),
        rr_depth: s
            .opt("rr_depth", |v, k| ctx.uint(v, k, 1))?
            .unwrap_or(DEFAULT_RR_DEPTH),
        filter: match s.get("filter") {
            Some(v) => parse_filter(s, v)?,
            None => PixelFilter::Box,
        },
        filter_inside_film: false,
        hide_emitters: false,
        emitter_sampling_only: false,
        bsdf_sampling_only: false,
        delta_light_gain: 1,
    };
    overrides.apply(&mut render);
    render.check().map_err(|(key, reason)| {
        if overrides.sets(key) {
            super::overridden(ctx.path, key, reason)
        } else {
            ctx.err(s.line_of(key), &s.key(key), reason)
        }
    })?;
    Ok(render)
}

/// `render.filter`: a type name (`"gaussian"`, with Mitsuba's parameters)
/// or a table with `type` and the parameters Mitsuba names (`radius`,
/// `stddev`, `B`, `C`, `lobes`).
fn parse_filter<'a, 'i>(s: &Section<'a, 'i>, v: &'a Val<'i>) -> Result<PixelFilter> {
    let ctx = s.ctx;
    let key = s.key("filter");
    let unknown = |v: &Val, k: &str, name: &str| {
        ctx.bad(
            v,
            k,
            format!(
                "unknown pixel filter \"{}\"; expected one of: {}",
                cut(name),
                FILTER_TYPES.join(", ")
            ),
        )
    };
    let by_name = |name: &str| match name {
        "box" => Some(PixelFilter::Box),
        "tent" => Some(PixelFilter::Tent { radius: 1.0 }),
        "gaussian" => Some(PixelFilter::MITSUBA_DEFAULT),
        "mitchell" => Some(PixelFilter::MITCHELL),
        "catmullrom" => Some(PixelFilter::CATMULL_ROM),
        "lanczos" => Some(PixelFilter::Lanczos { lobes: 3 }),
        _ => None,
    };
    let filter = match v.get_ref() {
        DeValue::String(name) => by_name(name).ok_or_else(|| unknown(v, &key, name))?,
        DeValue::Table(_) => {
            let t = s.table("filter", v)?;
            let ty = t.req("type", "the filter's type, e.g. \"gaussian\"", |v, k| {
                ctx.string(v, k).map(str::to_string)
            })?;
            let ty = ty.as_str();
            let tv = t.require("type", "")?;
            let base = by_name(ty).ok_or_else(|| unknown(tv, &t.key("type"), ty))?;
            let params: &[&str] = match base {
                PixelFilter::Box => &["type"],
                PixelFilter::Tent { .. } => &["type", "radius"],
                PixelFilter::Gaussian { .. } => &["type", "stddev"],
                PixelFilter::Mitchell { .. } if ty == "mitchell" => &["type", "B", "C"],
                PixelFilter::Mitchell { .. } => &["type"],
                PixelFilter::Lanczos { .. } => &["type", "lobes"],
            };
            t.check_keys(params)?;
            let num = |name: &str, default: f32| -> Result<f32> {
                Ok(t.opt(name, |v, k| ctx.number(v, k))?
                    .map_or(default, |x| x as f32))
            };
            let filter = match base {
                PixelFilter::Tent { radius } => PixelFilter::Tent {
                    radius: num("radius", radius)?,
                },
                PixelFilter::Gaussian { stddev } => PixelFilter::Gaussian {
                    stddev: num("stddev", stddev)?,
                },
                PixelFilter::Mitchell { b, c } => PixelFilter::Mitchell {
                    b: num("B", b)?,
                    c: num("C", c)?,
                },
                PixelFilter::Lanczos { lobes } => PixelFilter::Lanczos {
                    lobes: t.opt("lobes", |v, k| ctx.uint(v, k, 1))?.unwrap_or(lobes),
                },
                PixelFilter::Box => PixelFilter::Box,
            };
            filter.validate().map_err(|reason| {
                let name = reason.split_whitespace().next().unwrap_or("");
                let name = if params.contains(&name) { name } else { "type" };
                ctx.err(t.line_of(name), &t.key(name), reason)
            })?;
            filter
        }
        _ => return Err(ctx.wrong_type(
            v,
            &key,
            "a filter name such as \"gaussian\" or a table { type = \"gaussian\", stddev = 0.5 }",
        )),
    };
    Ok(filter)
}

fn parse_camera(s: &Section, render: &RenderSettings) -> Result<Camera> {
    let ctx = s.ctx;
    s.check_keys(CAMERA_KEYS)?;
    let point = "a point [x, y, z]";
    let eye = s.req("eye", point, |v, k| ctx.vec3(v, k))?;
    let look_at = s.req("look_at", point, |v, k| ctx.vec3(v, k))?;
    let up = s.opt("up", |v, k| ctx.vec3(v, k))?;
    let vfov = s.req("vfov", "a number of degrees, 0 < vfov < 180", |v, k| {
        let x = ctx.number(v, k)?;
        if x > 0.0 && x < 180.0 {
            Ok(x)
        } else {
            Err(ctx.bad(
                v,
                k,
                format!("must be > 0 and < 180 (degrees), got {}", ctx.snippet(v)),
            ))
        }
    })?;
    let aperture = s
        .opt("aperture_radius", |v, k| {
            let x = ctx.number(v, k)?;
            if x >= 0.0 {
                Ok(x)
            } else {
                Err(ctx.bad(v, k, format!("must be >= 0, got {}", ctx.snippet(v))))
            }
        })?
        .unwrap_or(0.0);
    let focus = s.opt("focus_distance", |v, k| {
        let x = ctx.number(v, k)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(ctx.bad(v, k, format!("must be > 0, got {}", ctx.snippet(v))))
        }
    })?;

    let near = s.opt("near_clip", |v, k| {
        let x = ctx.number(v, k)?;
        if x >= 0.0 && (x as f32).is_finite() {
            Ok(x as f32)
        } else {
            Err(ctx.bad(
                v,
                k,
                format!("must be >= 0 and finite, got {}", ctx.snippet(v)),
            ))
        }
    })?;
    let far = s.opt("far_clip", |v, k| {
        let x = ctx.number(v, k)?;
        if x > 0.0 {
            Ok(x as f32)
        } else {
            Err(ctx.bad(v, k, format!("must be > 0, got {}", ctx.snippet(v))))
        }
    })?;
    let (near, far) = (near.unwrap_or(0.0), far.unwrap_or(f32::INFINITY));
    if far <= near {
        return Err(ctx.err(
            s.line_of("far_clip"),
            &s.key("far_clip"),
            format!("must be above near_clip ({near}), got {far}"),
        ));
    }

    let vfov32 = vfov as f32;
    if !(vfov32 > 0.0 && vfov32 < 180.0) {
        return Err(ctx.err(
            s.line_of("vfov"),
            &s.key("vfov"),
            format!(
                "must be > 0 and < 180 (degrees), got {vfov}, which is {vfov32} in 32-bit \
                 floats (what the device uses)"
            ),
        ));
    }
    let camera = Camera {
        eye: eye.as_vec3(),
        look_at: look_at.as_vec3(),
        up: up.unwrap_or(DVec3::Y).as_vec3(),
        vfov_deg: vfov32,
        aperture_radius: aperture as f32,
        focus_distance: focus.unwrap_or((look_at - eye).length()) as f32,
        near_clip: near,
        far_clip: far,
        shift: [0.0; 2],
        orthographic: None,
    };
    check_camera(s, render, &camera, (eye, look_at, up))?;
    let lens = DVec3::splat(aperture);
    super::limits::check_coordinates("the eye with its lens", [eye - lens, eye + lens])
        .map_err(|reason| ctx.err(s.line_of("eye"), &s.key("eye"), reason))?;
    Ok(camera)
}

/// Checks the camera the file asks for, in f64, and then the one the device
/// gets (f32): the basis must exist in both and agree to a quarter pixel,
/// and the thin lens must stay inside what f32 resolves.
fn check_camera(
    s: &Section,
    render: &RenderSettings,
    camera: &Camera,
    file: (DVec3, DVec3, Option<DVec3>),
) -> Result<()> {
    use super::limits::{angle, basis_f64, BasisError};
    let ctx = s.ctx;
    let (eye, look_at, up) = file;
    let up_desc = if up.is_some() {
        "camera.up"
    } else {
        "the default up [0, 1, 0]"
    };
    let up = up.unwrap_or(DVec3::Y);
    let wanted = basis_f64(eye, look_at, up).map_err(|e| match e {
        BasisError::SamePoint => ctx.err(
            s.line_of("look_at"),
            &s.key("look_at"),
            "equals camera.eye, so the camera has no direction to look in; move look_at or eye",
        ),
        BasisError::ZeroUp => ctx.err(
            s.line_of("up"),
            &s.key("up"),
            "must not be [0, 0, 0]; give the direction that should point up in the image",
        ),
        BasisError::UpParallel => ctx.err(
            s.line_of("up"),
            &s.key("up"),
            format!(
                "{up_desc} is parallel to the view direction (look_at - eye); \
                 set camera.up to a direction that is not, e.g. [0, 0, 1] or [1, 0, 0]"
            ),
        ),
        BasisError::NonFinite(key) => ctx.err(s.line_of(key), &s.key(key), "must be finite"),
    })?;
    let distance = (look_at - eye).length();
    let device = camera.basis().map_err(|(key, reason)| {
        let reason = if key == "look_at" {
            format!(
                "is {distance:e} from camera.eye: {reason} (at least a few units in the \
                 last place of eye's largest coordinate)"
            )
        } else {
            format!("{reason} (it is {})", camera.up)
        };
        ctx.err(s.line_of(key), &s.key(key), reason)
    })?;

    // How far the device's basis turns the image from the file's, in pixels.
    let (width, height) = (render.width as f64, render.height as f64);
    let tan_half = ((camera.vfov_deg as f64).to_radians() * 0.5).tan();
    let pixel_angle = 2.0 * tan_half / height;
    let got = [device.u, device.v, device.w].map(|x| x.as_dvec3());
    let turn_px = angle(wanted[2], got[2]) / pixel_angle;
    let roll = angle(wanted[0], got[0]).max(angle(wanted[1], got[1]));
    let roll_px = roll * (1.0 / pixel_angle).max(0.5 * width.hypot(height));
    const MAX_SHIFT_PX: f64 = 0.25;
    if turn_px > MAX_SHIFT_PX {
        return Err(ctx.err(
            s.line_of("look_at"),
            &s.key("look_at"),
            format!(
                "is only {distance:e} from camera.eye: in 32-bit floats (what the device \
                 uses) the view direction turns by {:.3e} degrees, {turn_px:.2} pixels; \
                 move look_at farther from eye along the same direction",
                angle(wanted[2], got[2]).to_degrees()
            ),
        ));
    }
    if roll_px > MAX_SHIFT_PX {
        let sine = wanted[2].cross(up.normalize()).length();
        return Err(ctx.err(
            s.line_of("up"),
            &s.key("up"),
            format!(
                "{up_desc} is only {:.3e} degrees from the view direction: in 32-bit \
                 floats (what the device uses) the image would turn by {:.3e} degrees, \
                 about {roll_px:.2} pixels; choose an up further from look_at - eye",
                sine.asin().to_degrees(),
                roll.to_degrees()
            ),
        ));
    }

    // The thin lens: the device aims at eye + f * dir, then subtracts the
    // lens point, so f must stand well above eye's rounding step, and the
    // ray must stay short enough to normalise in f32.
    if camera.aperture_radius > 0.0 {
        let f = camera.focus_distance as f64;
        let largest = camera.eye.abs().max_element();
        let ulp = f64::from(f32::from_bits(largest.to_bits() + 1) - largest);
        let least = (256.0 * ulp).max(1e-18);
        let key = if s.get("focus_distance").is_some() {
            "focus_distance"
        } else {
            "look_at"
        };
        if !f.is_finite() || f < least {
            return Err(ctx.err(
                s.line_of(key),
                &s.key(key),
                format!(
                    "the focus distance {:e} is below what 32-bit floats resolve at eye \
                     (largest coordinate {largest:e}): with aperture_radius > 0 it must be \
                     at least {:e}; set a larger focus_distance or move the scene nearer \
                     the origin",
                    camera.focus_distance, least as f32
                ),
            ));
        }
        let corner = (1.0 + tan_half * tan_half * (1.0 + (width / height).powi(2))).sqrt();
        let reach = f * corner + camera.aperture_radius as f64 + largest as f64;
        const MAX_REACH: f64 = 1e18;
        if reach > MAX_REACH {
            return Err(ctx.err(
                s.line_of(key),
                &s.key(key),
                format!(
                    "the thin-lens rays reach {reach:e} from the origin; 32-bit floats \
                     (what the device uses) cannot normalise rays longer than about \
                     {MAX_REACH:e}; lower focus_distance or aperture_radius"
                ),
            ));
        }
    }
    Ok(())
}
