//! PLY meshes (ASCII, binary little- and big-endian), read into a
//! single-indexed, triangulated mesh, with the vertex and face attributes
//! Mitsuba's PLY loader finds in the file.
//!
//! The reader is lancer's own, so that every size the file declares is
//! checked before anything is allocated for it: each element count against
//! [`MAX_PLY_ELEMENTS`], and the counts together, in checked arithmetic,
//! against the bytes the file has after its header (every entry of an
//! element takes at least a known number of bytes); each list's length
//! against the bytes left. Only what lancer uses is kept: `vertex` x, y, z,
//! optional nx, ny, nz and u, v (or s, t, or texture_u, texture_v), and
//! `face` `vertex_indices` (or `vertex_index`); other elements and
//! properties are read past.
//!
//! The header and ASCII values separate their tokens with any white space
//! (spaces, tabs, CR LF line ends, white space at either end of a line).
//! ASCII entries are one a line, as the format says; blank lines are
//! skipped.

use super::limits::MAX_PLY_ELEMENTS;
use crate::util::text::cut;
use std::path::Path;

/// A scalar type of the PLY format.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// The type of a header name (both the old and the sized names).
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Bytes of one value in a binary file.
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value of `bytes` (exactly [`Scalar::size`] of them).
    fn decode(self, bytes: &[u8], big_endian: bool) -> f64 {
        let mut a = [0u8; 8];
        let n = self.size();
        a[..n].copy_from_slice(&bytes[..n]);
        if big_endian {
            a[..n].reverse();
        }
        match self {
            Scalar::I8 => f64::from(a[0] as i8),
            Scalar::U8 => f64::from(a[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([a[0], a[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([a[0], a[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Scalar::F64 => f64::from_le_bytes(a),
        }
    }

    /// The value of an ASCII token, if it is one of this type.
    fn parse_value(self, token: &str) -> Option<f64> {
        let int = |min: i64, max: i64| {
            token
                .parse::<i64>()
                .ok()
                .filter(|x| (min..=max).contains(x))
                .map(|x| x as f64)
        };
        match self {
            Scalar::I8 => int(i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => int(0, u8::MAX.into()),
            Scalar::I16 => int(i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => int(0, u16::MAX.into()),
            Scalar::I32 => int(i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => int(0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => token.parse::<f64>().ok(),
        }
    }
}

/// A property: a scalar, or a list of `item` values preceded by a count of
/// type `count`.
#[derive(Debug, Clone, PartialEq)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

impl Element {
    /// Fewest bytes one entry takes: in binary, its scalars and list
    /// counts; in ASCII, one character and one separator per value.
    fn min_bytes(&self, encoding: Encoding) -> u64 {
        match encoding {
            Encoding::Ascii => 2 * self.properties.len() as u64,
            _ => (self.properties.iter())
                .map(|p| match p.kind {
                    Kind::Scalar(s) | Kind::List { count: s, .. } => s.size() as u64,
                })
                .sum(),
        }
    }

    fn index_of(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    LittleEndian,
    BigEndian,
}

/// The header: the encoding, the elements in file order, and where the
/// data starts.
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    body: usize,
}

/// Reads a mesh file's bytes, as many as the file system says it has (so
/// that a file growing while it is read cannot exhaust memory); a device or
/// a pipe, which may never end, is refused.
pub(crate) fn read_bounded(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::io::Read as _;
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_dir() {
        return Err(std::io::Error::other("is a folder, not a file"));
    }
    if !meta.is_file() {
        return Err(std::io::Error::other(
            "not a regular file (a device or a pipe); give a mesh file",
        ));
    }
    let mut bytes = Vec::new();
    file.take(meta.len()).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Reads a PLY file into a single-indexed, triangulated mesh: `vertex` x,
/// y, z, optional nx, ny, nz and u, v (or s, t, or texture_u, texture_v),
/// turned into lancer's texture convention (v = 0 at the image's bottom
/// row, where Mitsuba reads PLY v = 0 as the top row); `face`
/// vertex_indices (or vertex_index) polygons, split into fans. `shown` is
/// the file as messages name it.
pub(crate) fn read_ply(path: &Path, shown: &str) -> Result<PlyMesh, String> {
    let bytes = read_bounded(path).map_err(|e| format!("cannot read PLY file {shown}: {e}"))?;
    Reader {
        bytes: &bytes,
        shown,
    }
    .read()
}

struct Reader<'a> {
    bytes: &'a [u8],
    shown: &'a str,
}

impl Reader<'_> {
    fn err(&self, reason: impl std::fmt::Display) -> String {
        format!("PLY file {}: {reason}", self.shown)
    }

    fn read(&self) -> Result<PlyMesh, String> {
        let header = self.header()?;
        self.check_counts(&header)?;
        let vertex = header.elements.iter().find(|e| e.name == "vertex");
        let vertex = vertex.ok_or_else(|| self.err("it has no `vertex` element"))?;
        let plan = Plan::new(vertex, header.elements.iter().find(|e| e.name == "face"))
            .map_err(|e| self.err(e))?;
        let mut mesh = PlyMesh {
            attributes: (plan.attributes.iter())
                .map(|(kind, group)| PlyAttribute {
                    name: group.name.clone(),
                    per_vertex: *kind == AttributeKind::Vertex,
                    channels: group.fields.len(),
                    integer: group.integer,
                    values: Vec::new(),
                })
                .collect(),
            ..PlyMesh::default()
        };
        // The counts are within the limit, and the file holds them.
        let vertices = vertex.count as usize;
        mesh.mesh.positions.reserve_exact(3 * vertices);
        if plan.normals.is_some() {
            mesh.mesh.normals.reserve_exact(3 * vertices);
        }
        if plan.uv.is_some() {
            mesh.mesh.texcoords.reserve_exact(2 * vertices);
        }
        match header.encoding {
            Encoding::Ascii => self.ascii_body(&header, &plan, &mut mesh)?,
            _ => self.binary_body(&header, &plan, &mut mesh)?,
        }
        Ok(mesh)
    }

    /// Parses the header: every line split on any white space.
    fn header(&self) -> Result<Header, String> {
        let mut lines = self.bytes.split_inclusive(|&b| b == b'\n');
        let mut offset = 0;
        let mut line_no = 0;
        let mut next = || {
            let line = lines.next()?;
            offset += line.len();
            line_no += 1;
            Some((line_no, String::from_utf8_lossy(line)))
        };
        let first = next().map(|(_, l)| l.split_whitespace().collect::<Vec<_>>().join(" "));
        if first.as_deref() != Some("ply") {
            return Err(self.err("it does not start with a line `ply`: not a PLY file"));
        }
        let mut encoding = None;
        let mut elements: Vec<Element> = Vec::new();
        loop {
            let Some((line, text)) = next() else {
                return Err(
                    self.err("its header has no `end_header` line: not a PLY file, or truncated")
                );
            };
            let at = |reason: String| self.err(format!("line {line}: {reason}"));
            let words: Vec<&str> = text.split_whitespace().collect();
            match words.as_slice() {
                [] | ["comment", ..] | ["obj_info", ..] => {}
                ["end_header"] => break,
                ["format", kind, version] => {
                    let kind = match *kind {
                        "ascii" => Encoding::Ascii,
                        "binary_little_endian" => Encoding::LittleEndian,
                        "binary_big_endian" => Encoding::BigEndian,
                        other => {
                            return Err(at(format!(
                                "format `{}` is not ascii, binary_little_endian or \
                                 binary_big_endian",
                                cut(other)
                            )))
                        }
                    };
                    if !version.starts_with("1.") {
                        return Err(at(format!(
                            "format version `{}`; lancer reads PLY 1.0",
                            cut(version)
                        )));
                    }
                    if encoding.replace(kind).is_some() {
                        return Err(at(String::from("a second `format` line; give one")));
                    }
                }
                ["element", name, count] => {
                    let count = count.parse::<u64>().map_err(|_| {
                        at(format!(
                            "element `{}`: the count `{}` is not a whole number",
                            cut(name),
                            cut(count)
                        ))
                    })?;
                    if elements.iter().any(|e| e.name == *name) {
                        return Err(at(format!(
                            "a second element `{}`; give each element once",
                            cut(name)
                        )));
                    }
                    elements.push(Element {
                        name: name.to_string(),
                        count,
                        properties: Vec::new(),
                    });
                }
                ["property", rest @ ..] => {
                    let scalar = |name: &str| {
                        Scalar::parse(name).ok_or_else(|| {
                            at(format!(
                                "`{}` is not a PLY type (char, uchar, short, ushort, int, \
                                 uint, float, double, or int8 ... float64)",
                                cut(name)
                            ))
                        })
                    };
                    let (kind, name) = match rest {
                        ["list", count, item, name] => {
                            let count = scalar(count)?;
                            if !count.is_integer() {
                                return Err(at(format!(
                                    "list `{}`: its count must be of an integer type",
                                    cut(name)
                                )));
                            }
                            (
                                Kind::List {
                                    count,
                                    item: scalar(item)?,
                                },
                                name,
                            )
                        }
                        [kind, name] if *kind != "list" => (Kind::Scalar(scalar(kind)?), name),
                        _ => {
                            return Err(at(String::from(
                                "expected `property TYPE NAME` or `property list COUNT_TYPE \
                                 TYPE NAME`",
                            )))
                        }
                    };
                    let Some(element) = elements.last_mut() else {
                        return Err(at(format!(
                            "property `{}` comes before any `element`",
                            cut(name)
                        )));
                    };
                    if element.index_of(name).is_some() {
                        return Err(at(format!(
                            "a second property `{}` in element `{}`",
                            cut(name),
                            cut(&element.name)
                        )));
                    }
                    element.properties.push(Property {
                        name: name.to_string(),
                        kind,
                    });
                }
                _ => {
                    return Err(at(format!(
                        "`{}` is not a PLY header line (format, element, property, comment, \
                         obj_info, end_header)",
                        cut(&words.join(" "))
                    )))
                }
            }
        }
        let encoding = encoding.ok_or_else(|| self.err("its header has no `format` line"))?;
        Ok(Header {
            encoding,
            elements,
            body: offset,
        })
    }

    /// Each element's count against [`MAX_PLY_ELEMENTS`], and all of them
    /// against the bytes after the header, in checked arithmetic.
    fn check_counts(&self, header: &Header) -> Result<(), String> {
        let available = (self.bytes.len() - header.body) as u64;
        // The last ASCII line may end without a line break.
        let slack = u64::from(header.encoding == Encoding::Ascii);
        let mut needed = 0u64;
        for e in &header.elements {
            if e.count > MAX_PLY_ELEMENTS {
                return Err(self.err(format!(
                    "its header declares {} `{}` elements; lancer reads at most \
                     {MAX_PLY_ELEMENTS} of an element (docs/mitsuba.md): remove the element, \
                     or split the mesh",
                    e.count,
                    cut(&e.name)
                )));
            }
            let each = e.min_bytes(header.encoding);
            let these = e.count.saturating_mul(each);
            let left = available.saturating_sub(needed);
            if these > left.saturating_add(slack) {
                return Err(self.err(format!(
                    "its header declares {} `{}` elements of at least {each} byte{} each, but \
                     only {left} bytes are left for them after the header and the elements \
                     before them: the file is truncated, or its header is wrong",
                    e.count,
                    cut(&e.name),
                    if each == 1 { "" } else { "s" }
                )));
            }
            needed = needed.saturating_add(these);
        }
        Ok(())
    }

    fn ascii_body(&self, header: &Header, plan: &Plan, mesh: &mut PlyMesh) -> Result<(), String> {
        let body = &self.bytes[header.body..];
        // The header's lines come first.
        let header_lines = self.bytes[..header.body]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        let mut lines = body
            .split(|&b| b == b'\n')
            .enumerate()
            .map(|(i, l)| (header_lines + i + 1, l))
            .filter(|(_, l)| l.iter().any(|b| !b.is_ascii_whitespace()));
        let mut values = Vec::new();
        for element in &header.elements {
            if element.properties.is_empty() {
                continue;
            }
            for i in 0..element.count {
                let Some((line, text)) = lines.next() else {
                    return Err(self.err(format!(
                        "the file ends after {i} of its {} `{}` elements: the file is \
                         truncated, or its header is wrong",
                        element.count,
                        cut(&element.name)
                    )));
                };
                let at = |reason: String| {
                    self.err(format!(
                        "line {line}: `{}` {i}: {reason}",
                        cut(&element.name)
                    ))
                };
                let text = String::from_utf8_lossy(text);
                let mut tokens = text.split_ascii_whitespace();
                values.clear();
                let mut lists = Vec::new();
                for p in &element.properties {
                    let mut take = |ty: Scalar, what: &str| {
                        let token = tokens.next().ok_or_else(|| {
                            at(format!("the line ends before {what} `{}`", cut(&p.name)))
                        })?;
                        ty.parse_value(token).ok_or_else(|| {
                            at(format!(
                                "`{}` is not a value of {what} `{}` ({ty:?})",
                                cut(token),
                                cut(&p.name)
                            ))
                        })
                    };
                    match p.kind {
                        Kind::Scalar(s) => values.push(take(s, "property")?),
                        Kind::List { count, item } => {
                            let n = take(count, "the count of list")?;
                            if n < 0.0 {
                                return Err(at(format!(
                                    "list `{}` has a negative count",
                                    cut(&p.name)
                                )));
                            }
                            let mut list = Vec::new();
                            for _ in 0..n as u64 {
                                list.push(take(item, "list")?);
                            }
                            values.push(f64::NAN);
                            lists.push(list);
                        }
                    }
                }
                if let Some(extra) = tokens.next() {
                    return Err(at(format!(
                        "`{}` is more than the {} value(s) the header declares",
                        cut(extra),
                        element.properties.len()
                    )));
                }
                plan.take(element, i, &values, &lists, mesh)
                    .map_err(|e| self.err(e))?;
            }
        }
        Ok(())
    }

    fn binary_body(&self, header: &Header, plan: &Plan, mesh: &mut PlyMesh) -> Result<(), String> {
        let big = header.encoding == Encoding::BigEndian;
        let mut at = header.body;
        let mut values = Vec::new();
        let mut lists = Vec::new();
        for element in &header.elements {
            let wanted = plan.wants(element);
            let fixed = (element.properties.iter()).all(|p| matches!(p.kind, Kind::Scalar(_)));
            if !wanted && fixed {
                // check_counts made sure these bytes are in the file.
                at += (element.count * element.min_bytes(header.encoding)) as usize;
                continue;
            }
            for i in 0..element.count {
                values.clear();
                lists.clear();
                for p in &element.properties {
                    let (scalar, list) = match p.kind {
                        Kind::Scalar(s) => (s, None),
                        Kind::List { count, item } => (count, Some(item)),
                    };
                    let bytes = self.bytes.get(at..at + scalar.size()).ok_or_else(|| {
                        self.err(format!(
                            "`{}` {i}: the file ends inside it: the file is truncated or \
                             damaged",
                            cut(&element.name)
                        ))
                    })?;
                    at += scalar.size();
                    let value = scalar.decode(bytes, big);
                    let Some(item) = list else {
                        values.push(value);
                        continue;
                    };
                    // An integer count: negative ones are refused.
                    let left = self.bytes.len() - at;
                    let need = (value.max(0.0) as u64).checked_mul(item.size() as u64);
                    if value < 0.0 || need.is_none_or(|n| n > left as u64) {
                        return Err(self.err(format!(
                            "`{}` {i}: its `{}` list claims {value} values of {} byte{}, but \
                             only {left} bytes are left in the file: the file is truncated or \
                             damaged",
                            cut(&element.name),
                            cut(&p.name),
                            item.size(),
                            if item.size() == 1 { "" } else { "s" }
                        )));
                    }
                    let n = value as usize;
                    let list = (0..n)
                        .map(|k| item.decode(&self.bytes[at + k * item.size()..], big))
                        .collect();
                    at += n * item.size();
                    values.push(f64::NAN);
                    lists.push(list);
                }
                if wanted {
                    plan.take(element, i, &values, &lists, mesh)
                        .map_err(|e| self.err(e))?;
                }
                lists.clear();
            }
        }
        Ok(())
    }
}

/// Which properties of `vertex` and `face` lancer takes, by index.
struct Plan {
    /// x, y, z of `vertex`.
    position: [usize; 3],
    normals: Option<[usize; 3]>,
    uv: Option<[usize; 2]>,
    /// The vertex count, which face indices must stay below.
    vertices: u64,
    /// The list index (among the element's lists) of `face`'s vertex
    /// indices.
    face_list: Option<usize>,
    /// The attributes of `vertex` and `face`, in the order of
    /// [`PlyMesh::attributes`].
    attributes: Vec<(AttributeKind, AttributeFields)>,
}

/// A mesh as a PLY file gives it: the triangles (faces split into fans),
/// and the attributes of its vertices and faces.
#[derive(Debug, Default)]
pub(crate) struct PlyMesh {
    /// Positions, normals, texture coordinates and triangles.
    pub mesh: tobj::Mesh,
    /// The attributes Mitsuba's PLY loader would find, vertex ones first.
    pub attributes: Vec<PlyAttribute>,
    /// The face each triangle of `mesh.indices` comes from.
    pub triangle_faces: Vec<u32>,
}

/// One attribute of a PLY mesh.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PlyAttribute {
    /// Mitsuba's name: `vertex_` or `face_`, then the group's prefix
    /// (`vertex_color` for `r, g, b` or `red, green, blue`; `face_weight`
    /// for `weight_0`; `vertex_foo_color` for `foo_r, foo_g, foo_b`).
    pub name: String,
    /// A value per vertex, else per face.
    pub per_vertex: bool,
    /// Values per vertex or face: 1, 3, or 4 (a colour with alpha).
    pub channels: usize,
    /// Whether the file stores its fields as integers, which Mitsuba 3.9.1
    /// reads as numbers (a `uchar` 255 is 255, not 1).
    pub integer: bool,
    /// `channels` values per vertex or face, in order.
    pub values: Vec<f32>,
}

/// Which element an attribute belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum AttributeKind {
    Vertex,
    Face,
}

/// The fields of one attribute: its name and the property indices of its
/// channels, in order.
#[derive(Debug, Clone, PartialEq)]
struct AttributeFields {
    name: String,
    fields: Vec<usize>,
    integer: bool,
}

/// The attributes among the scalar properties of `element` not in
/// `reserved`, grouped as Mitsuba 3.9.1's PLY loader groups them
/// (`find_other_fields`): `r, g, b` (or `red, green, blue`), with `a` (or
/// `alpha`) if present, make `{type}color`; then runs of properties
/// `{prefix}_{c}` whose one-letter postfixes follow one of the sequences
/// x y z w, r g b a, 0 1 2 3 or 1 2 3 4 make `{type}{prefix}` (with
/// `_color` appended for r g b a), kept when they have 1 or 3 fields.
/// Properties that fit no group are left out, as Mitsuba leaves them out
/// (with a warning there).
fn find_attributes(element: &Element, kind: &str, reserved: &[&str]) -> Vec<AttributeFields> {
    let scalar = |name: &str| {
        element
            .index_of(name)
            .filter(|&i| matches!(element.properties[i].kind, Kind::Scalar(_)))
    };
    let is_integer =
        |i: usize| matches!(element.properties[i].kind, Kind::Scalar(s) if s.is_integer());
    let mut out = Vec::new();
    let mut colour_fields: Vec<usize> = Vec::new();
    for names in [["r", "g", "b", "a"], ["red", "green", "blue", "alpha"]] {
        if let (Some(r), Some(g), Some(b)) = (scalar(names[0]), scalar(names[1]), scalar(names[2]))
        {
            colour_fields = vec![r, g, b];
            colour_fields.extend(scalar(names[3]));
            break;
        }
    }
    if !colour_fields.is_empty() {
        out.push(AttributeFields {
            name: format!("{kind}color"),
            integer: is_integer(colour_fields[0]),
            fields: colour_fields.clone(),
        });
    }
    const POSTFIXES: [&[u8; 4]; 4] = [b"xr01", b"yg12", b"zb23", b"wa34"];
    let mut seen: Vec<String> = Vec::new();
    // The group being read: prefix, postfix category, fields
    let mut current: Option<(String, usize, Vec<usize>)> = None;
    let flush = |current: &mut Option<(String, usize, Vec<usize>)>,
                 seen: &mut Vec<String>,
                 out: &mut Vec<AttributeFields>| {
        if let Some((prefix, category, fields)) = current.take() {
            if fields.len() == 1 || fields.len() == 3 {
                let colour = if category == 1 { "_color" } else { "" };
                out.push(AttributeFields {
                    name: format!("{kind}{prefix}{colour}"),
                    integer: is_integer(fields[0]),
                    fields,
                });
                seen.push(prefix);
            }
        }
    };
    let mut i = 0;
    while i < element.properties.len() {
        let p = &element.properties[i];
        let skip = !matches!(p.kind, Kind::Scalar(_))
            || reserved.contains(&p.name.as_str())
            || colour_fields.contains(&i)
            || ["r", "g", "b", "a"].contains(&p.name.as_str());
        if skip {
            i += 1;
            continue;
        }
        let Some((prefix, postfix)) = p.name.rsplit_once('_') else {
            flush(&mut current, &mut seen, &mut out);
            i += 1;
            continue;
        };
        if postfix.len() != 1 {
            flush(&mut current, &mut seen, &mut out);
            i += 1;
            continue;
        }
        let c = postfix.as_bytes()[0];
        if current.as_ref().is_some_and(|g| g.0 != prefix) {
            flush(&mut current, &mut seen, &mut out);
        }
        match &mut current {
            None => {
                if seen.iter().any(|s| s == prefix) {
                    // A prefix met before: this run is left out
                    while i < element.properties.len()
                        && element.properties[i].name.starts_with(prefix)
                    {
                        i += 1;
                    }
                    continue;
                }
                if let Some(category) = POSTFIXES[0].iter().position(|&x| x == c) {
                    current = Some((prefix.to_string(), category, vec![i]));
                }
            }
            Some((_, category, fields)) => {
                let level = fields.len();
                if level < 4 && POSTFIXES[level][*category] == c {
                    fields.push(i);
                } else {
                    // A broken sequence: the attribute and the rest of its
                    // prefix's run are left out
                    current = None;
                    while i < element.properties.len()
                        && element.properties[i].name.starts_with(prefix)
                    {
                        i += 1;
                    }
                    continue;
                }
            }
        }
        i += 1;
    }
    flush(&mut current, &mut seen, &mut out);
    out
}

impl Plan {
    fn new(vertex: &Element, face: Option<&Element>) -> Result<Plan, String> {
        let scalar = |name: &str| {
            vertex
                .index_of(name)
                .filter(|&i| matches!(vertex.properties[i].kind, Kind::Scalar(_)))
        };
        let all = |names: [&str; 3]| -> Option<[usize; 3]> {
            Some([scalar(names[0])?, scalar(names[1])?, scalar(names[2])?])
        };
        let mut position = [0; 3];
        for (slot, k) in position.iter_mut().zip(["x", "y", "z"]) {
            *slot = scalar(k)
                .ok_or_else(|| format!("its `vertex` element has no number property `{k}`"))?;
        }
        let uv = [["u", "v"], ["s", "t"], ["texture_u", "texture_v"]]
            .into_iter()
            .find_map(|[u, v]| Some([scalar(u)?, scalar(v)?]));
        let face_list = match face {
            None => None,
            Some(face) => {
                let list = ["vertex_indices", "vertex_index"].iter().find_map(|name| {
                    let i = face.index_of(name)?;
                    match face.properties[i].kind {
                        Kind::List { item, .. } if item.is_integer() => Some(i),
                        _ => None,
                    }
                });
                let list = list.ok_or_else(|| {
                    String::from(
                        "its `face` element has no integer list `vertex_indices` (or \
                         `vertex_index`)",
                    )
                })?;
                // Its place among the element's lists.
                let lists_before = face.properties[..list]
                    .iter()
                    .filter(|p| matches!(p.kind, Kind::List { .. }))
                    .count();
                Some(lists_before)
            }
        };
        // Mitsuba reserves the texture coordinates' pair that it reads
        let uv_names: &[&str] = match uv {
            Some([u, _]) => match vertex.properties[u].name.as_str() {
                "u" => &["u", "v"],
                "s" => &["s", "t"],
                _ => &["texture_u", "texture_v"],
            },
            None => &[],
        };
        let mut reserved = vec!["x", "y", "z", "nx", "ny", "nz"];
        reserved.extend(uv_names);
        let mut attributes: Vec<(AttributeKind, AttributeFields)> =
            (find_attributes(vertex, "vertex_", &reserved).into_iter())
                .map(|a| (AttributeKind::Vertex, a))
                .collect();
        if let (Some(face), Some(_)) = (face, face_list) {
            attributes.extend(
                (find_attributes(face, "face_", &[]).into_iter()).map(|a| (AttributeKind::Face, a)),
            );
        }
        Ok(Plan {
            position,
            normals: all(["nx", "ny", "nz"]),
            uv,
            vertices: vertex.count,
            face_list,
            attributes,
        })
    }

    /// Whether lancer keeps anything of `element`.
    fn wants(&self, element: &Element) -> bool {
        element.name == "vertex" || (element.name == "face" && self.face_list.is_some())
    }

    /// Keeps entry `i` of `element` (`values`: every property in order,
    /// NaN for lists; `lists`: the lists in order).
    fn take(
        &self,
        element: &Element,
        i: u64,
        values: &[f64],
        lists: &[Vec<f64>],
        mesh: &mut PlyMesh,
    ) -> Result<(), String> {
        let kind = if element.name == "vertex" {
            AttributeKind::Vertex
        } else {
            AttributeKind::Face
        };
        for ((k, group), out) in self.attributes.iter().zip(&mut mesh.attributes) {
            if *k == kind {
                out.values
                    .extend(group.fields.iter().map(|&f| values[f] as f32));
            }
        }
        let mesh_out = &mut mesh.mesh;
        if kind == AttributeKind::Vertex {
            mesh_out
                .positions
                .extend(self.position.map(|k| values[k] as f32));
            if let Some(n) = self.normals {
                mesh_out.normals.extend(n.map(|k| values[k] as f32));
            }
            if let Some([u, v]) = self.uv {
                mesh_out.texcoords.push(values[u] as f32);
                mesh_out.texcoords.push(1.0 - values[v] as f32);
            }
            return Ok(());
        }
        let Some(list) = self.face_list.and_then(|k| lists.get(k)) else {
            return Ok(());
        };
        if list.len() < 3 {
            return Err(format!(
                "face {i} has {} vertices; a face needs 3 or more",
                list.len()
            ));
        }
        let index = |x: f64| {
            // Integers of at most 32 bits: exact in f64.
            if x >= 0.0 && (x as u64) < self.vertices {
                Ok(x as u32)
            } else {
                Err(format!(
                    "face {i} names vertex {x}, but there are {}",
                    self.vertices
                ))
            }
        };
        for k in 1..list.len() - 1 {
            mesh_out
                .indices
                .extend([index(list[0])?, index(list[k])?, index(list[k + 1])?]);
            mesh.triangle_faces.push(i as u32);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(bytes: &[u8]) -> Result<tobj::Mesh, String> {
        read_with_attributes(bytes).map(|m| m.mesh)
    }

    fn read_with_attributes(bytes: &[u8]) -> Result<PlyMesh, String> {
        Reader {
            bytes,
            shown: "m.ply",
        }
        .read()
    }

    #[test]
    fn ascii_quads_split_into_fans_with_normals_and_uvs() {
        let m = read(
            b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
              property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
              property float s\nproperty float t\nelement face 1\n\
              property list uchar uint vertex_index\nend_header\n\
              0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n1 1 0 0 0 1 1 1\n0 1 0 0 0 1 0 0.25\n4 0 1 2 3\n",
        )
        .unwrap();
        assert_eq!(m.indices, [0, 1, 2, 0, 2, 3]);
        assert_eq!(m.positions.len(), 12);
        assert_eq!(m.normals[2], 1.0);
        assert_eq!(&m.texcoords[6..], [0.0, 0.75]);
    }

    #[test]
    fn big_endian_and_side_data_are_read_past() {
        let mut b = b"ply\nformat binary_big_endian 1.0\nelement junk 2\nproperty double w\n\
              property list uchar short tags\nelement vertex 3\nproperty short x\n\
              property short y\nproperty short z\nelement face 1\n\
              property list uchar int vertex_indices\nend_header\n"
            .to_vec();
        for n in [1u8, 2] {
            b.extend_from_slice(&1.5f64.to_be_bytes());
            b.push(n);
            b.extend((0..n).flat_map(|k| i16::from(k).to_be_bytes()));
        }
        for v in [[0i16, 0, 0], [1, 0, 0], [0, -1, 0]] {
            b.extend(v.iter().flat_map(|c| c.to_be_bytes()));
        }
        b.push(3);
        b.extend([0i32, 2, 1].iter().flat_map(|c| c.to_be_bytes()));
        let m = read(&b).unwrap();
        assert_eq!(m.positions, [0., 0., 0., 1., 0., 0., 0., -1., 0.]);
        assert_eq!(m.indices, [0, 2, 1]);
    }

    #[test]
    fn bad_values_and_indices_name_the_line_and_entry() {
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                    property float y\nproperty float z\nelement face 1\n\
                    property list uchar int vertex_indices\nend_header\n";
        let e = |body: &str| read(format!("{head}{body}").as_bytes()).unwrap_err();
        assert_eq!(
            e("0 0 0\n1 0 zero\n0 1 0\n3 0 1 2\n"),
            "PLY file m.ply: line 11: `vertex` 1: `zero` is not a value of property `z` (F32)"
        );
        assert_eq!(
            e("0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
            "PLY file m.ply: face 0 names vertex 3, but there are 3"
        );
        assert_eq!(
            e("0 0 0\n1 0 0\n0 1 0 7\n3 0 1 2\n"),
            "PLY file m.ply: line 12: `vertex` 2: `7` is more than the 3 value(s) the header declares"
        );
        assert_eq!(
            e("0 0 0\n1 0 0\n0 1 0\n2 0 1\n"),
            "PLY file m.ply: face 0 has 2 vertices; a face needs 3 or more"
        );
        assert_eq!(
            read(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n")
                .unwrap_err(),
            "PLY file m.ply: its `vertex` element has no number property `y`"
        );
        assert_eq!(
            read(b"ply\nformat ascii 1.0\nelemnt vertex 1\n").unwrap_err(),
            "PLY file m.ply: line 3: `elemnt vertex 1` is not a PLY header line (format, \
             element, property, comment, obj_info, end_header)"
        );
        assert_eq!(
            read(b"solid cube\n").unwrap_err(),
            "PLY file m.ply: it does not start with a line `ply`: not a PLY file"
        );
    }

    #[test]
    fn attributes_are_grouped_and_named_as_mitsubas_loader_names_them() {
        let m = read_with_attributes(
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nproperty float s\nproperty float t\nproperty uchar red\n\
              property uchar green\nproperty uchar blue\nproperty uchar alpha\n\
              property float foo_r\nproperty float foo_g\nproperty float foo_b\n\
              property float dir_x\nproperty float dir_y\nproperty float dir_z\n\
              property float w_0\nproperty float pair_1\nproperty float pair_2\n\
              property float bad_x\nproperty float bad_g\nproperty float plain\n\
              element face 1\nproperty list uchar int vertex_index\n\
              property float k_1\nproperty float k_2\nproperty float k_3\nend_header\n\
              0 0 0 0 0 1 2 3 4 0.1 0.2 0.3 1 0 0 0.5 7 8 9 9 9\n\
              1 0 0 1 0 5 6 7 8 0.4 0.5 0.6 0 1 0 0.25 7 8 9 9 9\n\
              0 1 0 0 1 9 10 11 12 0.7 0.8 0.9 0 0 1 0.125 7 8 9 9 9\n\
              3 0 1 2 0.3 0.6 0.9\n",
        )
        .unwrap();
        let named: Vec<(&str, bool, usize, bool)> = (m.attributes.iter())
            .map(|a| (a.name.as_str(), a.per_vertex, a.channels, a.integer))
            .collect();
        // red, green, blue, alpha: vertex_color of 4 (integer) channels;
        // foo_r/g/b: vertex_foo_color; dir_x/y/z: vertex_dir; w_0 alone:
        // vertex_w; pair_1, pair_2 (two fields) and bad_x, bad_g (a broken
        // sequence) and plain (no postfix) are left out; s, t are the
        // texture coordinates; face k_1/2/3: face_k
        assert_eq!(
            named,
            [
                ("vertex_color", true, 4, true),
                ("vertex_foo_color", true, 3, false),
                ("vertex_dir", true, 3, false),
                ("vertex_w", true, 1, false),
                ("face_k", false, 3, false),
            ]
        );
        assert_eq!(m.attributes[0].values[4..8], [5.0, 6.0, 7.0, 8.0]);
        assert_eq!(m.attributes[3].values, [0.5, 0.25, 0.125]);
        assert_eq!(m.attributes[4].values, [0.3, 0.6, 0.9]);
        assert_eq!(m.mesh.texcoords.len(), 6);
        assert_eq!(m.triangle_faces, [0]);
    }
}
