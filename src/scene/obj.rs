//! OBJ meshes and their `.mtl` materials.
//!
//! Faces are loaded with tobj (triangulated), transformed to world space and
//! cleaned: triangles with a non-finite vertex or zero area are dropped and
//! counted, and non-finite normals or texture coordinates fall back to none
//! for that triangle. `.mtl` files are read by a small parser of our own so
//! that their errors can name the line, and so that `Tf` is read as well.

pub(crate) use super::mesh::{make_triangle, LoadedMesh, Made, MtlMaterial, Transform};
use super::types::{ColorSource, MaterialKind, Rgb};
use crate::util::text::{cut, cut_path};
use glam::{DAffine3, DMat3, DVec3, Vec3};
use std::cell::RefCell;
use std::collections::HashMap;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

/// One material of a `.mtl` file, as written.
#[derive(Debug, Clone, Default)]
pub(crate) struct MtlEntry {
    /// Name after `newmtl`.
    pub name: String,
    /// Line of `newmtl`.
    pub line: usize,
    kd: Option<(Vec3, usize)>,
    ks: Option<(Vec3, usize)>,
    ke: Option<(Vec3, usize)>,
    tf: Option<(Vec3, usize)>,
    ns: Option<(f32, usize)>,
    ni: Option<(f32, usize)>,
    illum: Option<(u32, usize)>,
    map_kd: Option<(String, usize)>,
}

/// A byte slice read line by line, remembering how far tobj got, so that a
/// parse error can name the line.
struct CountingReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl CountingReader<'_> {
    /// 1-based line of the last line handed out.
    fn current_line(&self) -> usize {
        let consumed = &self.data[..self.pos.min(self.data.len())];
        let newlines = consumed.iter().filter(|&&b| b == b'\n').count();
        if consumed.last() == Some(&b'\n') {
            newlines
        } else {
            newlines + 1
        }
    }
}

impl Read for CountingReader<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let rest = self.data.get(self.pos..).unwrap_or(&[]);
        let n = rest.len().min(buf.len());
        buf[..n].copy_from_slice(&rest[..n]);
        self.pos += n;
        Ok(n)
    }
}

impl BufRead for CountingReader<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(self.data.get(self.pos..).unwrap_or(&[]))
    }

    fn consume(&mut self, amt: usize) {
        self.pos = (self.pos + amt).min(self.data.len());
    }
}

/// Libraries and materials read through tobj's material callback.
#[derive(Default)]
struct MtlState {
    /// Every material tobj was handed, in tobj's order:
    /// (index into `libs`, entry).
    entries: Vec<(usize, MtlEntry)>,
    /// (path on disk, path shown, `mtllib` argument) per library read.
    libs: Vec<(PathBuf, PathBuf, String)>,
    /// The first `.mtl` error.
    error: Option<String>,
}

/// Loads an OBJ file, transforms it and converts the `.mtl` materials its
/// faces use (when `fixed_material` is `None`).
///
/// With `smooth_normals`, a file without any `vn` gets smooth vertex normals
/// as Mitsuba 3 computes them ([`smooth_obj_normals`]); a file with `vn`
/// keeps its own.
///
/// With a fixed material, a plain file (the shape large meshes come in) is
/// read on every core by [`super::obj_fast`], which gives the same mesh;
/// any other file goes to the general loader.
///
/// `shown` is the path used in messages. Errors are a reason, to be prefixed
/// with the scene file, key and line by the caller.
pub(crate) fn load_mesh(
    path: &Path,
    shown: &Path,
    transform: &DAffine3,
    fixed_material: Option<u32>,
    smooth_normals: bool,
) -> Result<LoadedMesh, String> {
    let raw = super::ply::read_bounded(path)
        .map_err(|e| format!("cannot read OBJ file {}: {e}", cut_path(shown)))?;
    if let Some(material) = fixed_material {
        let mut mesh = LoadedMesh {
            files: vec![path.to_path_buf()],
            ..Default::default()
        };
        let chunk = super::obj_fast::CHUNK_BYTES;
        if super::obj_fast::load_plain(&raw, chunk, transform, material, smooth_normals, &mut mesh)
        {
            return Ok(mesh);
        }
    }
    load_obj_bytes(&raw, path, shown, transform, fixed_material, smooth_normals)
}

/// [`load_mesh`] by the general loader (tobj, after the passes that check
/// the encoding and the face indices) from the file's bytes `raw`.
pub(crate) fn load_obj_bytes(
    raw: &[u8],
    path: &Path,
    shown: &Path,
    transform: &DAffine3,
    fixed_material: Option<u32>,
    smooth_normals: bool,
) -> Result<LoadedMesh, String> {
    let mut face_notes = Vec::new();
    let data = prepare_obj(raw, shown, &mut face_notes)?;
    check_face_indices(&data, shown)?;
    let obj_dir = path.parent().unwrap_or(Path::new(""));
    let shown_dir = shown.parent().unwrap_or(Path::new(""));
    let state = RefCell::new(MtlState::default());
    // `..Default::default()` stays for the fields that tobj's optional
    // features add, should anything in the build turn them on.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let mut reader = CountingReader {
        data: &data,
        pos: 0,
    };
    let loader = |lib: &Path| -> tobj::MTLLoadResult {
        if fixed_material.is_some() {
            return Ok((Vec::new(), Default::default()));
        }
        let mut state = state.borrow_mut();
        let lib_path = obj_dir.join(lib);
        let lib_shown = shown_dir.join(lib);
        let text = match super::ply::read_bounded(&lib_path) {
            Ok(bytes) => match decode_lines(&bytes, &lib_shown, Syntax::Mtl) {
                Ok(text) => text,
                Err(e) => {
                    state.error.get_or_insert(e);
                    return Err(tobj::LoadError::MaterialParseError);
                }
            },
            Err(e) => {
                state.error.get_or_insert(format!(
                    "cannot read material library {} (named by `mtllib` in {}): {e}",
                    cut_path(&lib_shown),
                    cut_path(shown)
                ));
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        let entries = match parse_mtl(&text, &lib_shown) {
            Ok(entries) => entries,
            Err(e) => {
                state.error.get_or_insert(e);
                return Err(tobj::LoadError::MaterialParseError);
            }
        };
        let lib_index = state.libs.len();
        state
            .libs
            .push((lib_path, lib_shown, lib.to_string_lossy().into_owned()));
        let names = (entries.iter().enumerate())
            .map(|(i, entry)| (entry.name.clone(), i))
            .collect();
        let materials = (entries.iter())
            .map(|entry| tobj::Material {
                name: entry.name.clone(),
                ..Default::default()
            })
            .collect();
        state
            .entries
            .extend(entries.into_iter().map(|entry| (lib_index, entry)));
        Ok((materials, names))
    };
    // tobj indexes with unchecked arithmetic in places; a hostile file must
    // not take the program down, so a panic in it becomes an error.
    let loaded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut reader, &options, loader)
    }));
    let mut models = match loaded {
        Ok(Ok((models, _))) => models,
        Ok(Err(e)) => {
            let line = match e {
                tobj::LoadError::InvalidPolygon
                | tobj::LoadError::FaceVertexOutOfBounds
                | tobj::LoadError::FaceTexCoordOutOfBounds
                | tobj::LoadError::FaceNormalOutOfBounds
                | tobj::LoadError::FaceColorOutOfBounds => String::new(),
                _ => format!(":{}", reader.current_line()),
            };
            if let Some(mtl_error) = state.borrow_mut().error.take() {
                return Err(mtl_error);
            }
            return Err(format!(
                "cannot load OBJ file {}{line}: {e}",
                cut_path(shown)
            ));
        }
        Err(_) => {
            return Err(format!(
                "cannot load OBJ file {}: malformed data near line {}",
                cut_path(shown),
                reader.current_line()
            ))
        }
    };
    let state = state.into_inner();
    if let Some(error) = state.error {
        return Err(error);
    }

    let files = std::iter::once(path.to_path_buf())
        .chain(state.libs.iter().map(|(lib_path, _, _)| lib_path.clone()))
        .collect();
    let mut mesh = LoadedMesh {
        notes: face_notes,
        files,
        ..Default::default()
    };
    // tobj material id -> index into `mesh.materials`.
    let mut local: HashMap<usize, u32> = HashMap::new();
    let mut normal_matrix = transform.matrix3.inverse().transpose();
    if smooth_normals && models.iter().all(|m| m.mesh.normals.is_empty()) {
        smooth_obj_normals(&mut models, &data, transform);
        // The computed normals are in world space already.
        normal_matrix = DMat3::IDENTITY;
    }
    for model in &models {
        let m = &model.mesh;
        let material = match (fixed_material, m.material_id) {
            (Some(fixed), _) => fixed,
            (None, Some(id)) => match local.get(&id) {
                Some(&index) => index,
                None => {
                    let (lib, entry) = state.entries.get(id).ok_or_else(|| {
                        format!("{}: face material index out of range", cut_path(shown))
                    })?;
                    let (lib_path, lib_shown, mtllib) = state.libs.get(*lib).ok_or_else(|| {
                        format!("{}: material library index out of range", cut_path(shown))
                    })?;
                    let converted = convert_mtl(entry, lib_path, lib_shown, &mut mesh.notes)?;
                    let index = mesh.materials.len() as u32;
                    mesh.materials.push(MtlMaterial {
                        mtl_path: lib_path.clone(),
                        mtllib: mtllib.clone(),
                        name: entry.name.clone(),
                        kind: converted.0,
                        emission: converted.1,
                    });
                    local.insert(id, index);
                    index
                }
            },
            (None, None) => {
                if m.indices.is_empty() {
                    continue;
                }
                let object = if model.name.is_empty() {
                    String::from("unnamed_object")
                } else {
                    model.name.clone()
                };
                return Err(format!(
                    "faces of object `{}` in {} have no material (no `usemtl`, or \
                     a `usemtl` naming a material that no `mtllib` defines); fix the OBJ \
                     or give the mesh a `material` key",
                    cut(&object),
                    cut_path(shown)
                ));
            }
        };
        add_mesh_triangles(&mut mesh, m, transform, &normal_matrix, material, None)?;
    }
    Ok(mesh)
}

/// Transforms and checks every triangle of `m` (single-indexed, already
/// triangulated) into `out`; `normal_matrix` is the inverse transpose of
/// `transform`'s linear part. Also used for PLY meshes (`super::mitsuba`).
pub(crate) fn add_mesh_triangles(
    out: &mut LoadedMesh,
    m: &tobj::Mesh,
    transform: &DAffine3,
    normal_matrix: &DMat3,
    material: u32,
    attributes: Option<&[[Vec3; 3]]>,
) -> Result<(), String> {
    let vertex_count = m.positions.len() / 3;
    let has_normals = !m.normals.is_empty() && m.normals.len() == m.positions.len();
    let has_uvs = !m.texcoords.is_empty() && m.texcoords.len() / 2 == vertex_count;
    for (k, face) in m.indices.chunks_exact(3).enumerate() {
        let kept = out.triangles.len();
        add_triangle(
            out,
            m,
            face,
            (has_normals, has_uvs),
            transform,
            normal_matrix,
            material,
        )?;
        // A kept triangle takes its attribute values along
        if let (Some(values), Some(t)) = (attributes, out.triangles.get_mut(kept)) {
            t.attribute = Some(out.attributes.len() as u32);
            out.attributes.push(values[k]);
        }
    }
    Ok(())
}

/// One corner of an OBJ face as written: the indices of its `v`, `vt` and
/// `vn` (0-based, negative ones resolved). Mitsuba 3's OBJ loader makes one
/// mesh vertex per distinct key over the whole file, whatever the `o`, `g`
/// and `usemtl` statements.
type CornerKey = (usize, Option<usize>, Option<usize>);

/// The triangles of every face of a prepared OBJ file (see [`prepare_obj`]),
/// in file order and split into fans from the first corner as tobj and
/// Mitsuba split them, as the keys of their corners. `None` when a face
/// cannot be read this way (tobj then reports it, or the caller falls back).
fn triangle_keys(data: &[u8]) -> Option<Vec<[CornerKey; 3]>> {
    let mut counts = [0usize; 3];
    let mut out = Vec::new();
    for line in data.split(|&b| b == b'\n') {
        let line = std::str::from_utf8(line).ok()?;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("f") => {
                let mut corners = Vec::new();
                for word in words.take_while(|w| !w.starts_with('#')) {
                    let mut key = [None; 3];
                    for (k, part) in word.split('/').enumerate() {
                        if k >= 3 {
                            return None;
                        }
                        if part.is_empty() {
                            continue;
                        }
                        let x = part.parse::<isize>().ok()?;
                        key[k] = Some(match x {
                            x if x > 0 => x as usize - 1,
                            x if x < 0 => counts[k].checked_sub(x.unsigned_abs())?,
                            _ => return None,
                        });
                    }
                    corners.push((key[0]?, key[1], key[2]));
                }
                for pair in corners.get(1..)?.windows(2) {
                    out.push([corners[0], pair[0], pair[1]]);
                }
            }
            _ => {}
        }
    }
    Some(out)
}

/// The angle between two unit vectors, accurate near 0 and pi (Mitsuba's
/// `unit_angle`).
fn unit_angle(a: DVec3, b: DVec3) -> f64 {
    if a.dot(b) < 0.0 {
        std::f64::consts::PI - 2.0 * ((a + b).length() / 2.0).min(1.0).asin()
    } else {
        2.0 * ((a - b).length() / 2.0).min(1.0).asin()
    }
}

/// Smooth vertex normals as Mitsuba 3 computes a mesh's missing normals
/// (`Mesh::recompute_vertex_normals`, after Thürmer and Wüthrich, "Computing
/// Vertex Normals from Polygonal Facets", JGT 1998): each vertex sums the
/// unit normals of the faces that share it, each weighted by the face's
/// angle at that vertex, and the sum is normalised. Faces of zero area or
/// with a non-finite corner add nothing; a vertex whose sum vanishes gets
/// (0, 0, 0) (its triangles then use the geometric normal).
///
/// `positions` are world-space (Mitsuba applies `to_world` first, so a
/// non-uniform scale changes the angles); an index out of range skips the face.
pub(crate) fn angle_weighted_normals(positions: &[DVec3], faces: &[[u32; 3]]) -> Vec<DVec3> {
    let mut sums = vec![DVec3::ZERO; positions.len()];
    for face in faces {
        let Some(p) = face
            .iter()
            .map(|&i| positions.get(i as usize).copied())
            .collect::<Option<Vec<DVec3>>>()
        else {
            continue;
        };
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let len2 = n.length_squared();
        if !(len2 > 0.0 && len2.is_finite()) {
            continue;
        }
        let n = n / len2.sqrt();
        for k in 0..3 {
            let to_next = (p[(k + 1) % 3] - p[k]).normalize();
            let to_prev = (p[(k + 2) % 3] - p[k]).normalize();
            sums[face[k] as usize] += n * unit_angle(to_next, to_prev);
        }
    }
    sums.into_iter()
        .map(|s| {
            let len = s.length();
            if len > 0.0 && len.is_finite() {
                s / len
            } else {
                DVec3::ZERO
            }
        })
        .collect()
}

/// Gives a mesh without normals smooth world-space vertex normals
/// ([`angle_weighted_normals`]); its vertices are shared by index, as in a
/// PLY file. The caller then transforms normals by the identity.
pub(crate) fn smooth_mesh_normals(mesh: &mut tobj::Mesh, transform: &DAffine3) {
    let positions: Vec<DVec3> = mesh
        .positions
        .chunks_exact(3)
        .map(|p| world_point(transform, p))
        .collect();
    let faces: Vec<[u32; 3]> = mesh
        .indices
        .chunks_exact(3)
        .map(|f| [f[0], f[1], f[2]])
        .collect();
    mesh.normals = angle_weighted_normals(&positions, &faces)
        .into_iter()
        .flat_map(|n| n.as_vec3().to_array())
        .collect();
}

/// A local position transformed to world space, rounded to f32 as the
/// triangles store it.
fn world_point(transform: &DAffine3, p: &[f32]) -> DVec3 {
    let local = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
    transform.transform_point3(local).as_vec3().as_dvec3()
}

/// Gives the models of an OBJ file without `vn` smooth world-space vertex
/// normals, sharing them between corners as Mitsuba 3 does: corners with the
/// same `v/vt/vn` indices are one vertex over the whole file (so a seam in
/// the texture coordinates is a crease, and objects that share `v` lines are
/// smoothed together). Should the faces not read back (never for a file tobj
/// loaded), each model's own vertices are shared instead.
fn smooth_obj_normals(models: &mut [tobj::Model], data: &[u8], transform: &DAffine3) {
    let triangles: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    let keys = triangle_keys(data).filter(|k| k.len() == triangles);
    // The shared vertex of every model vertex.
    let mut ids: Vec<Vec<u32>> = models
        .iter()
        .map(|m| vec![u32::MAX; m.mesh.positions.len() / 3])
        .collect();
    let mut by_key: HashMap<CornerKey, u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut faces = Vec::with_capacity(triangles);
    let mut t = 0;
    for (model, model_ids) in models.iter().zip(ids.iter_mut()) {
        let m = &model.mesh;
        for face in m.indices.chunks_exact(3) {
            let mut shared = [0u32; 3];
            for (k, &index) in face.iter().enumerate() {
                let slot = model_ids.get_mut(index as usize);
                let Some(slot) = slot else { continue };
                let mut fresh = || {
                    let i = index as usize;
                    positions.push(world_point(transform, &m.positions[3 * i..3 * i + 3]));
                    positions.len() as u32 - 1
                };
                let id = match &keys {
                    Some(keys) => *by_key.entry(keys[t][k]).or_insert_with(&mut fresh),
                    None if *slot == u32::MAX => fresh(),
                    None => *slot,
                };
                *slot = id;
                shared[k] = id;
            }
            faces.push(shared);
            t += 1;
        }
    }
    let normals = angle_weighted_normals(&positions, &faces);
    for (model, model_ids) in models.iter_mut().zip(&ids) {
        model.mesh.normals = model_ids
            .iter()
            .flat_map(|&id| {
                normals
                    .get(id as usize)
                    .copied()
                    .unwrap_or(DVec3::ZERO)
                    .as_vec3()
                    .to_array()
            })
            .collect();
    }
}

/// Which statements of a file may hold text that is not UTF-8.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Syntax {
    /// OBJ: `o`, `g` and `usemtl` names; `v`, `vt`, `vn`, `vp`, `f`, `l`,
    /// `p` and `mtllib` must be UTF-8.
    Obj,
    /// MTL: `newmtl` names; colours, numbers and `map_Kd` must be UTF-8.
    Mtl,
}

impl Syntax {
    /// Statements whose argument is a name, read as Latin-1 when it is not
    /// UTF-8 (the same in the `.obj` and the `.mtl`, so names still match).
    fn names(self) -> &'static [&'static str] {
        match self {
            Syntax::Obj => &["o", "g", "usemtl"],
            Syntax::Mtl => &["newmtl"],
        }
    }

    /// Statements lancer reads whose every byte matters.
    fn strict(self) -> &'static [&'static str] {
        match self {
            Syntax::Obj => &["v", "vt", "vn", "vp", "f", "l", "p", "mtllib"],
            Syntax::Mtl => &["kd", "ks", "ke", "tf", "ns", "ni", "illum", "map_kd"],
        }
    }
}

/// Turns an OBJ or MTL file into UTF-8 text, line for line (numbering kept).
///
/// Real exporters write Latin-1 in comments and names. Bytes that are not
/// UTF-8 are accepted where they do not matter: a comment (from `#`) is cut
/// off, a name (`o`, `g`, `usemtl`, `newmtl`) is read as Latin-1, and a
/// statement lancer ignores is blanked. Anywhere else the line is refused,
/// naming it and the byte.
fn decode_lines(data: &[u8], shown: &Path, syntax: Syntax) -> Result<String, String> {
    let mut out = String::with_capacity(data.len());
    for (i, line) in data.split(|&b| b == b'\n').enumerate() {
        if i > 0 {
            out.push('\n');
        }
        let bad_at = match std::str::from_utf8(line) {
            Ok(text) => {
                out.push_str(text);
                continue;
            }
            Err(e) => e.valid_up_to(),
        };
        // A comment that starts before the first bad byte: drop it.
        if let Some(hash) = line[..bad_at].iter().position(|&b| b == b'#') {
            let kept = std::str::from_utf8(&line[..hash]).unwrap_or_default();
            out.push_str(kept);
            continue;
        }
        let valid = std::str::from_utf8(&line[..bad_at]).unwrap_or_default();
        // The statement's keyword, if the bad byte comes after it.
        let trimmed = valid.trim_start();
        let keyword = trimmed
            .find(char::is_whitespace)
            .map_or("", |end| &trimmed[..end]);
        let lower = keyword.to_ascii_lowercase();
        let key = if syntax == Syntax::Obj {
            keyword
        } else {
            &lower
        };
        if syntax.names().contains(&key) {
            // Latin-1: every byte is the code point of the same value.
            out.extend(line.iter().map(|&b| b as char));
        } else if syntax.strict().contains(&key) {
            return Err(format!(
                "{}:{}: byte 0x{:02X} (column {}) is not UTF-8 text, in a `{}` statement \
                 where every byte matters; save the file as UTF-8 (other bytes are \
                 accepted only in comments and names)",
                cut_path(shown),
                i + 1,
                line[bad_at],
                valid.chars().count() + 1,
                keyword
            ));
        }
        // Else a statement lancer ignores: leave the line blank.
    }
    Ok(out)
}

/// [`decode_lines`] for an OBJ file, then drops each face with fewer than
/// three vertices (tobj would drop it silently), with a note naming the line.
///
/// Every line is also rewritten as its keyword, one space and the rest, the
/// white space at either end removed: OBJ separates tokens with any white
/// space, but tobj splits `mtllib` and `usemtl` at the first space only (a
/// tab after them gave an empty name, white space before them a wrong one).
fn prepare_obj(data: &[u8], shown: &Path, notes: &mut Vec<String>) -> Result<Vec<u8>, String> {
    let text = decode_lines(data, shown, Syntax::Obj)?;
    let mut out = String::with_capacity(text.len());
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.push('\n');
        }
        let line = line.trim();
        let normalized;
        let line = match line.split_once(char::is_whitespace) {
            Some((keyword, rest)) => {
                normalized = format!("{keyword} {}", rest.trim_start());
                normalized.as_str()
            }
            None => line,
        };
        let mut words = line.split_whitespace();
        if words.next() == Some("f") {
            let vertices = words.take_while(|w| !w.starts_with('#')).count();
            if vertices < 3 {
                notes.push(format!(
                    "{}:{}: face with {vertices} vertex(es) dropped; a face needs at least 3",
                    cut_path(shown),
                    i + 1
                ));
                continue;
            }
        }
        out.push_str(line);
    }
    Ok(out.into_bytes())
}

/// Checks that every face index names an existing `v`, `vt` or `vn`
/// (positive: of the whole file; negative: counted back from that line), so
/// that tobj's index arithmetic cannot overflow, and the message has a line.
fn check_face_indices(data: &[u8], shown: &Path) -> Result<(), String> {
    const KINDS: [&str; 3] = ["v", "vt", "vn"];
    let lines = || data.split(|&b| b == b'\n').map(String::from_utf8_lossy);
    let mut totals = [0isize; 3];
    for line in lines() {
        if let Some(k) = line
            .split_whitespace()
            .next()
            .and_then(|w| KINDS.iter().position(|&kind| kind == w))
        {
            totals[k] += 1;
        }
    }
    let mut seen = [0isize; 3];
    for (i, line) in lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some(w) if KINDS.contains(&w) => {
                if let Some(k) = KINDS.iter().position(|&kind| kind == w) {
                    seen[k] += 1;
                }
            }
            Some("f") | Some("l") => {
                for vertex in words {
                    for (k, part) in vertex.split('/').take(3).enumerate() {
                        let digits = part.strip_prefix(['-', '+']).unwrap_or(part);
                        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                            continue; // empty, or tobj reports the parse error
                        }
                        // Beyond isize: as far out of range as it gets.
                        let x = part.parse::<isize>().unwrap_or(if part.starts_with('-') {
                            isize::MIN
                        } else {
                            isize::MAX
                        });
                        let ok = match x {
                            0 => false,
                            x if x > 0 => x <= totals[k],
                            x => seen[k] + x >= 0,
                        };
                        if !ok {
                            return Err(format!(
                                "{}:{}: face index `{}` refers to no `{}` ({} defined{})",
                                cut_path(shown),
                                i + 1,
                                cut(part),
                                KINDS[k],
                                if x < 0 { seen[k] } else { totals[k] },
                                if x < 0 { " before this line" } else { "" }
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Transforms and checks one triangle, adding it to `out` or counting why not.
fn add_triangle(
    out: &mut LoadedMesh,
    m: &tobj::Mesh,
    face: &[u32],
    (has_normals, has_uvs): (bool, bool),
    transform: &DAffine3,
    normal_matrix: &DMat3,
    material: u32,
) -> Result<(), String> {
    let fetch3 = |data: &[f32], i: u32| -> Option<DVec3> {
        let i = i as usize;
        let v = data.get(3 * i..3 * i + 3)?;
        Some(DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64))
    };
    let corner = |k: usize| face.get(k).copied().unwrap_or(u32::MAX);
    let p = [0, 1, 2].map(|k| fetch3(&m.positions, corner(k)));
    let n = has_normals.then(|| [0, 1, 2].map(|k| fetch3(&m.normals, corner(k))));
    let uv = has_uvs.then(|| {
        [0, 1, 2].map(|k| {
            let i = corner(k) as usize;
            (m.texcoords.get(2 * i..2 * i + 2)).map(|t| [t[0], t[1]])
        })
    });
    match make_triangle(p, n, uv, transform, normal_matrix, material)? {
        Made::NonFinite => out.dropped_non_finite += 1,
        Made::Degenerate => out.dropped_degenerate += 1,
        Made::Kept(triangle, bad_normals, bad_uvs) => {
            out.bad_normals += usize::from(bad_normals);
            out.bad_uvs += usize::from(bad_uvs);
            out.triangles.push(triangle);
        }
    }
    Ok(())
}

/// Parses the numbers after a colour keyword: `r g b`, or one value for grey.
fn parse_rgb(args: &[&str]) -> Option<Vec3> {
    let values: Option<Vec<f32>> = args.iter().map(|a| a.parse::<f32>().ok()).collect();
    match values?.as_slice() {
        [g] => Some(Vec3::splat(*g)),
        [r, g, b] => Some(Vec3::new(*r, *g, *b)),
        _ => None,
    }
}

/// Parses a `.mtl` file. Unknown statements are ignored, as MTL has many
/// that do not apply here.
pub(crate) fn parse_mtl(text: &str, shown: &Path) -> Result<Vec<MtlEntry>, String> {
    let mut entries: Vec<MtlEntry> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (keyword, rest) = match line.split_once(char::is_whitespace) {
            Some((k, r)) => (k, r.trim()),
            None => (line, ""),
        };
        let args: Vec<&str> = rest.split_whitespace().collect();
        let bad = |what: &str| {
            format!(
                "{}:{line_no}: `{}`: expected {what}, got `{}`",
                cut_path(shown),
                cut(keyword),
                cut(rest)
            )
        };
        let lower = keyword.to_ascii_lowercase();
        if lower == "newmtl" {
            if rest.is_empty() {
                return Err(bad("a material name"));
            }
            entries.push(MtlEntry {
                name: rest.to_string(),
                line: line_no,
                ..Default::default()
            });
            continue;
        }
        let known = matches!(
            lower.as_str(),
            "kd" | "ks" | "ke" | "tf" | "ns" | "ni" | "illum" | "map_kd"
        );
        if !known {
            continue;
        }
        let Some(entry) = entries.last_mut() else {
            return Err(format!(
                "{}:{line_no}: `{}` comes before any `newmtl`",
                cut_path(shown),
                cut(keyword)
            ));
        };
        match lower.as_str() {
            "kd" | "ks" | "ke" | "tf" => {
                let rgb = parse_rgb(&args).ok_or_else(|| bad("`r g b` (three numbers)"))?;
                let slot = match lower.as_str() {
                    "kd" => &mut entry.kd,
                    "ks" => &mut entry.ks,
                    "ke" => &mut entry.ke,
                    _ => &mut entry.tf,
                };
                *slot = Some((rgb, line_no));
            }
            "ns" | "ni" => {
                let value = match args.as_slice() {
                    [v] => v.parse::<f32>().ok(),
                    _ => None,
                }
                .ok_or_else(|| bad("one number"))?;
                let slot = if lower == "ns" {
                    &mut entry.ns
                } else {
                    &mut entry.ni
                };
                *slot = Some((value, line_no));
            }
            "illum" => {
                let value = match args.as_slice() {
                    [v] => v.parse::<u32>().ok(),
                    _ => None,
                }
                .ok_or_else(|| bad("an illumination model number 0..10"))?;
                entry.illum = Some((value, line_no));
            }
            _ => {
                // map_Kd [-options ...] file: with options, the file is the
                // last word; without, the whole rest (names may hold spaces).
                let file = if rest.starts_with('-') {
                    args.last().copied().unwrap_or("")
                } else {
                    rest
                };
                if file.is_empty() {
                    return Err(bad("a texture file name"));
                }
                entry.map_kd = Some((file.to_string(), line_no));
            }
        }
    }
    Ok(entries)
}

/// Maps one `.mtl` material to a scene material, per docs/scene-format.md:
/// `illum 5` -> mirror; `illum` 4/6/7 with `Ni` -> dielectric; non-zero `Ks`
/// -> phong; else lambert. Returns (kind, emission).
fn convert_mtl(
    entry: &MtlEntry,
    mtl_path: &Path,
    mtl_shown: &Path,
    notes: &mut Vec<String>,
) -> Result<(MaterialKind, Rgb), String> {
    let at = |line: usize| format!("{}:{line}", cut_path(mtl_shown));
    let colour = |slot: &Option<(Vec3, usize)>, what: &str| -> Result<Option<Vec3>, String> {
        match slot {
            Some((c, line)) if !(c.is_finite() && c.min_element() >= 0.0) => Err(format!(
                "{}: `{what}` of material `{}` must be finite and >= 0, got {} {} {}",
                at(*line),
                cut(&entry.name),
                c.x,
                c.y,
                c.z
            )),
            Some((c, _)) => Ok(Some(*c)),
            None => Ok(None),
        }
    };
    let kd = colour(&entry.kd, "Kd")?;
    let ks = colour(&entry.ks, "Ks")?;
    let ke = colour(&entry.ke, "Ke")?;
    if let (Some(ke), Some((_, line))) = (ke, entry.ke) {
        let limit = super::limits::MAX_RADIANCE;
        if ke.max_element() as f64 > limit {
            return Err(format!(
                "{}: `Ke` of material `{}` must be <= {limit:e} in every component (sums of \
                 radiance and its square over many samples must stay inside 32-bit floats), \
                 got {} {} {}; scale every emission down by the same factor",
                at(line),
                cut(&entry.name),
                ke.x,
                ke.y,
                ke.z
            ));
        }
    }
    let tf = colour(&entry.tf, "Tf")?;
    let emission = ke.unwrap_or(Vec3::ZERO);
    let illum = entry.illum.map(|(v, _)| v);

    if illum == Some(5) {
        return Ok((
            MaterialKind::Mirror {
                reflectance: ks.unwrap_or(Vec3::ONE),
            },
            emission,
        ));
    }
    if let (Some(4 | 6 | 7), Some((ior, line))) = (illum, entry.ni) {
        if !(ior.is_finite() && ior > 0.0) {
            return Err(format!(
                "{}: `Ni` of material `{}` must be > 0, got {ior}",
                at(line),
                cut(&entry.name)
            ));
        }
        return Ok((
            MaterialKind::Dielectric {
                ior,
                tint: tf.unwrap_or(Vec3::ONE),
            },
            emission,
        ));
    }
    let diffuse = match &entry.map_kd {
        Some((file, line)) => {
            let resolved = mtl_path.parent().unwrap_or(Path::new("")).join(file);
            let shown = mtl_shown.parent().unwrap_or(Path::new("")).join(file);
            if let Err(e) = check_readable(&resolved) {
                return Err(format!(
                    "{}: `map_Kd` of material `{}`: cannot read texture {}: {e}",
                    at(*line),
                    cut(&entry.name),
                    cut_path(&shown)
                ));
            }
            ColorSource::Texture(resolved)
        }
        None => ColorSource::Constant(kd.unwrap_or(Vec3::ZERO)),
    };
    match ks {
        Some(specular) if specular.max_element() > 0.0 => {
            let exponent = match entry.ns {
                Some((ns, line)) if !(ns.is_finite() && ns >= 0.0) => {
                    return Err(format!(
                        "{}: `Ns` of material `{}` must be >= 0, got {ns}",
                        at(line),
                        cut(&entry.name)
                    ))
                }
                Some((ns, _)) => ns,
                None => 0.0,
            };
            let mut specular = specular;
            let mut diffuse = diffuse;
            // Keep diffuse + specular <= 1 per channel, as the format
            // requires; exporters often write more (Kd 0.8, Ks 0.5).
            match &mut diffuse {
                ColorSource::Constant(d) => {
                    let sum = *d + specular;
                    if sum.max_element() > 1.0 {
                        let k = Vec3::ONE / sum.max(Vec3::ONE);
                        *d *= k;
                        specular *= k;
                        notes.push(format!(
                            "{}: material `{}`: Kd + Ks exceeds 1 in some channel; \
                             both scaled down so it does not create energy",
                            at(entry.line),
                            cut(&entry.name)
                        ));
                    }
                }
                ColorSource::Texture(_) | ColorSource::Mapped(_) | ColorSource::Attribute(_) => {
                    if specular.max_element() > 1.0 {
                        specular /= specular.max(Vec3::ONE);
                        notes.push(format!(
                            "{}: material `{}`: Ks exceeds 1; clamped to 1",
                            at(entry.line),
                            cut(&entry.name)
                        ));
                    }
                }
            }
            Ok((
                MaterialKind::Phong {
                    diffuse,
                    specular,
                    exponent,
                },
                emission,
            ))
        }
        _ => Ok((MaterialKind::Lambert { albedo: diffuse }, emission)),
    }
}

/// Checks that a file exists, is a file and can be opened for reading.
pub(crate) fn check_readable(path: &Path) -> std::io::Result<()> {
    let file = std::fs::File::open(path)?;
    if file.metadata()?.is_dir() {
        return Err(std::io::Error::other("is a folder, not a file"));
    }
    Ok(())
}

/// A transform with every part: rotation, non-uniform scale, translation.
pub(crate) fn test_transform() -> DAffine3 {
    Transform {
        translate: DVec3::new(0.25, -3.0, 7.5),
        rotate_deg: DVec3::new(10.0, -35.0, 80.0),
        scale: DVec3::new(1.5, 0.5, 2.0),
    }
    .affine()
}

/// Every figure of a mesh: per triangle its floats as bits (so -0.0 and
/// 0.0 differ) and its material; the counts; the notes and materials.
pub(crate) type MeshBits = (Vec<Vec<u32>>, [usize; 4], usize, usize);

/// [`MeshBits`] of a mesh.
pub(crate) fn mesh_bits(mesh: &LoadedMesh) -> MeshBits {
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| {
            let mut v: Vec<u32> =
                t.p.iter()
                    .flat_map(|p| p.to_array())
                    .map(f32::to_bits)
                    .collect();
            v.push(t.material);
            match t.n {
                Some(n) => v.extend(n.iter().flat_map(|n| n.to_array()).map(f32::to_bits)),
                None => v.push(u32::MAX),
            }
            match t.uv {
                Some(uv) => v.extend(uv.iter().flat_map(|t| t.to_array()).map(f32::to_bits)),
                None => v.push(u32::MAX),
            }
            v
        })
        .collect();
    let counts = [
        mesh.dropped_non_finite,
        mesh.dropped_degenerate,
        mesh.bad_normals,
        mesh.bad_uvs,
    ];
    (triangles, counts, mesh.notes.len(), mesh.materials.len())
}

/// Reads `data`, an OBJ file with a fixed material, with the parallel
/// reader (at chunks of 1, 7, 64 bytes and `CHUNK_BYTES` (1 MiB), with and
/// without smooth normals, under a transform with a rotation, a
/// non-uniform scale and a translation) and with the general loader.
/// `Ok(true)`: the parallel reader took the file and gave the general
/// loader's mesh, bit for bit; `Ok(false)`: it refused the file at every
/// chunk size; `Err` names the first disagreement. For the tests and the
/// `obj_mtl` fuzz target.
pub fn compare_readers(data: &[u8]) -> Result<bool, String> {
    let path = std::path::Path::new("mesh.obj");
    let t = test_transform();
    let mut taken = None;
    for smooth in [false, true] {
        let general = load_obj_bytes(data, path, path, &t, Some(3), smooth);
        for chunk in [1, 7, 64, super::obj_fast::CHUNK_BYTES] {
            let mut fast = LoadedMesh::default();
            let took = super::obj_fast::load_plain(data, chunk, &t, 3, smooth, &mut fast);
            if !took && !fast.triangles.is_empty() {
                return Err(String::from("a refused file left triangles"));
            }
            if took {
                let general = general.as_ref().map_err(|e| {
                    format!("read in parallel (chunk {chunk}), refused by the general loader: {e}")
                })?;
                if mesh_bits(&fast) != mesh_bits(general) {
                    return Err(format!(
                        "chunk {chunk}, smooth normals {smooth}: the meshes differ"
                    ));
                }
            }
            if !smooth {
                if taken.is_some_and(|t| t != took) {
                    return Err(String::from(
                        "the chunk size changed whether the file is plain",
                    ));
                }
                taken = Some(took);
            }
        }
    }
    Ok(taken.unwrap_or(false))
}
