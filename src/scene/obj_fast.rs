//! The parallel reader of plain OBJ files: the shape in which large meshes
//! come (`v`, `vt`, `vn`, `f`, `o`, `g`, comments), read on every core.
//!
//! It gives exactly what the general loader ([`super::obj::load_mesh`]:
//! tobj behind the checks of its own passes) gives for the same file, or
//! nothing: any line outside the plain shape (a `v` with a fourth value, an
//! `l`, a face with fewer than three corners or a comment after it, an
//! index that names nothing yet, a byte that is not UTF-8 or a non-ASCII
//! character outside a comment, a mesh whose materials come from its
//! `.mtl`, one that needs smooth normals computed) sends the whole file back
//! to the general loader, which then reads it, and words its errors, as
//! before. The file is cut into line-aligned chunks of [`CHUNK_BYTES`]; the
//! chunks are parsed apart and stitched in file order, so the result does
//! not depend on the thread count.
//!
//! What the general loader does that this one must match (tobj's rules):
//! a negative index counts back from the elements defined before its line;
//! `vn` and `vt` read their first three and two numbers and ignore the
//! rest; faces are split into fans from their first corner; `o` and `g`
//! start a new model, and a model's triangles keep their normals (or their
//! texture coordinates) only when every corner of the model has one.

use super::mesh::{make_triangle, LoadedMesh, Made};
use super::types::Triangle;
use glam::{DAffine3, DMat3, DVec3};
use rayon::prelude::*;

/// Bytes per chunk (cut at the next line end).
pub(crate) const CHUNK_BYTES: usize = 1 << 20;

/// No `vt` or `vn` at this corner.
const NONE: u32 = u32::MAX;

/// Whether `b` is white space to Rust's `split_whitespace` (the ASCII part
/// of Unicode's White_Space, vertical tab included).
fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\n' | b'\x0b' | b'\x0c' | b'\r')
}

/// The white-space-separated words of an ASCII line.
fn words(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|&b| is_space(b)).filter(|w| !w.is_empty())
}

/// What a line is, as far as counting elements goes.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// `v`, `vt`, `vn`: index 0, 1, 2.
    Element(usize),
    /// `f`.
    Face,
    /// `o` or `g`: a new model.
    Model,
    /// `usemtl`.
    UseMtl,
    /// `l`: tobj reads it as a face.
    Line,
    /// Anything else (comments, `s`, `mtllib`, unknown statements).
    Other,
}

/// The line's kind and its words after the keyword; `None` when the line
/// holds a non-ASCII byte outside a comment (Unicode white space would cut
/// words differently).
fn classify(line: &[u8]) -> Option<(Kind, &[u8])> {
    let start = line
        .iter()
        .position(|&b| !is_space(b))
        .unwrap_or(line.len());
    let line = &line[start..];
    if line.first() == Some(&b'#') || line.is_empty() {
        return Some((Kind::Other, &[]));
    }
    let end = line.iter().position(|&b| is_space(b)).unwrap_or(line.len());
    let (keyword, rest) = line.split_at(end);
    if !keyword.is_ascii() {
        return None;
    }
    let kind = match keyword {
        b"v" => Kind::Element(0),
        b"vt" => Kind::Element(1),
        b"vn" => Kind::Element(2),
        b"f" => Kind::Face,
        b"o" | b"g" => Kind::Model,
        b"usemtl" => Kind::UseMtl,
        b"l" => Kind::Line,
        _ => Kind::Other,
    };
    if matches!(kind, Kind::Element(_) | Kind::Face | Kind::Line) && !rest.is_ascii() {
        return None;
    }
    Some((kind, rest))
}

/// `n` numbers from the first `n` words, read as tobj reads them.
fn floats<const N: usize>(rest: &[u8]) -> Option<[f32; N]> {
    let mut out = [0.0f32; N];
    let mut it = words(rest);
    for slot in &mut out {
        // ASCII: checked by `classify`
        *slot = std::str::from_utf8(it.next()?).ok()?.parse().ok()?;
    }
    Some(out)
}

/// The `v`, `vt` and `vn` values of the whole file, in file order.
struct Elements {
    positions: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    normals: Vec<[f32; 3]>,
}

/// One parsed chunk of lines.
#[derive(Default)]
struct Chunk {
    /// `v`, `vt`, `vn` values, in file order.
    positions: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    normals: Vec<[f32; 3]>,
    /// Triangles (fans of the faces) as (v, vt, vn) per corner, 0-based
    /// over the whole file.
    triangles: Vec<[[u32; 3]; 3]>,
    /// Pieces of models: each `o` or `g` ends one. Per piece, its
    /// triangles and whether each corner has a `vt` and a `vn`.
    pieces: Vec<Piece>,
}

/// Triangles between two model boundaries within a chunk.
#[derive(Clone, Copy)]
struct Piece {
    /// Triangles in the piece.
    triangles: usize,
    /// Every corner has a `vt`.
    all_uv: bool,
    /// Every corner has a `vn`.
    all_normal: bool,
    /// A model boundary (`o`, `g`) ends the piece.
    ends_model: bool,
}

impl Piece {
    fn new() -> Piece {
        Piece {
            triangles: 0,
            all_uv: true,
            all_normal: true,
            ends_model: false,
        }
    }
}

/// The lines of `data` cut into chunks of about `chunk` bytes at line ends.
fn chunks(data: &[u8], chunk: usize) -> Vec<&[u8]> {
    let mut out = Vec::new();
    let mut rest = data;
    while !rest.is_empty() {
        let cut = match rest.get(chunk.max(1)..) {
            Some(tail) => match tail.iter().position(|&b| b == b'\n') {
                Some(nl) => chunk.max(1) + nl + 1,
                None => rest.len(),
            },
            None => rest.len(),
        };
        let (head, tail) = rest.split_at(cut);
        out.push(head);
        rest = tail;
    }
    out
}

/// Counts the `v`, `vt` and `vn` lines of a chunk; `None` outside the plain shape.
fn count(chunk: &[u8]) -> Option<[usize; 3]> {
    std::str::from_utf8(chunk).ok()?;
    let mut counts = [0; 3];
    for line in chunk.split(|&b| b == b'\n') {
        match classify(line)? {
            (Kind::Element(k), _) => counts[k] += 1,
            (Kind::Line, _) => return None,
            _ => {}
        }
    }
    Some(counts)
}

/// One corner `v`, `v/vt`, `v//vn` or `v/vt/vn` as 0-based indices, with
/// `seen` elements of each kind defined before its line; `None` for
/// anything else (an index of zero, out of range or not yet defined).
fn corner(word: &[u8], seen: [usize; 3]) -> Option<[u32; 3]> {
    let mut out = [NONE; 3];
    let mut parts = word.split(|&b| b == b'/');
    for (k, slot) in out.iter_mut().enumerate() {
        let Some(part) = parts.next() else { break };
        if part.is_empty() && k > 0 {
            continue;
        }
        // ASCII: checked by `classify`
        let x: isize = std::str::from_utf8(part).ok()?.parse().ok()?;
        let index = match x {
            x if x > 0 => x as usize - 1,
            x if x < 0 => seen[k].checked_sub(x.unsigned_abs())?,
            _ => return None,
        };
        if index >= seen[k] || index >= NONE as usize {
            return None;
        }
        *slot = index as u32;
    }
    if parts.next().is_some() {
        return None;
    }
    Some(out)
}

/// Parses a chunk whose first line follows `base` elements of each kind;
/// `None` outside the plain shape.
fn parse(chunk: &[u8], base: [usize; 3]) -> Option<Chunk> {
    let mut out = Chunk::default();
    let mut piece = Piece::new();
    let mut corners: Vec<[u32; 3]> = Vec::new();
    let seen = |out: &Chunk| {
        [
            base[0] + out.positions.len(),
            base[1] + out.uvs.len(),
            base[2] + out.normals.len(),
        ]
    };
    for line in chunk.split(|&b| b == b'\n') {
        let (kind, rest) = classify(line)?;
        match kind {
            Kind::Element(0) => {
                // Exactly three numbers: a fourth is tobj's w or a colour
                if words(rest).count() != 3 {
                    return None;
                }
                out.positions.push(floats::<3>(rest)?);
            }
            Kind::Element(1) => out.uvs.push(floats::<2>(rest)?),
            Kind::Element(_) => out.normals.push(floats::<3>(rest)?),
            Kind::Face => {
                let seen = seen(&out);
                corners.clear();
                for word in words(rest) {
                    corners.push(corner(word, seen)?);
                }
                if corners.len() < 3 {
                    return None;
                }
                for pair in corners[1..].windows(2) {
                    let t = [corners[0], pair[0], pair[1]];
                    piece.all_uv &= t.iter().all(|c| c[1] != NONE);
                    piece.all_normal &= t.iter().all(|c| c[2] != NONE);
                    piece.triangles += 1;
                    out.triangles.push(t);
                }
            }
            Kind::Model => {
                piece.ends_model = true;
                out.pieces.push(piece);
                piece = Piece::new();
            }
            Kind::UseMtl => {
                // With a fixed material, tobj's `usemtl` finds no material
                // and changes nothing, unless the name is empty (an error)
                let name = std::str::from_utf8(rest).ok()?;
                if name.trim().is_empty() {
                    return None;
                }
            }
            Kind::Line => return None,
            Kind::Other => {}
        }
    }
    out.pieces.push(piece);
    Some(out)
}

/// Reads `data`, an OBJ file, into `mesh` (which must be empty) as
/// [`super::obj::load_mesh`] would with a fixed material, on every core,
/// in chunks of about `chunk` bytes; `false` (and `mesh` untouched) when
/// the file is not plain, for the general loader to read.
pub(crate) fn load_plain(
    data: &[u8],
    chunk: usize,
    transform: &DAffine3,
    material: u32,
    smooth_normals: bool,
    mesh: &mut LoadedMesh,
) -> bool {
    let pieces = chunks(data, chunk);
    let Some(counts) = pieces
        .par_iter()
        .map(|c| count(c))
        .collect::<Option<Vec<[usize; 3]>>>()
    else {
        return false;
    };
    let mut bases = Vec::with_capacity(counts.len());
    let mut total = [0usize; 3];
    for c in &counts {
        bases.push(total);
        for k in 0..3 {
            total[k] += c[k];
        }
    }
    if total.iter().any(|&n| n >= NONE as usize) {
        return false;
    }
    let Some(parsed) = pieces
        .par_iter()
        .zip(&bases)
        .map(|(c, &base)| parse(c, base))
        .collect::<Option<Vec<Chunk>>>()
    else {
        return false;
    };
    let elements = Elements {
        positions: parsed
            .iter()
            .flat_map(|c| c.positions.iter().copied())
            .collect(),
        uvs: parsed.iter().flat_map(|c| c.uvs.iter().copied()).collect(),
        normals: parsed
            .iter()
            .flat_map(|c| c.normals.iter().copied())
            .collect(),
    };

    // Per model (pieces joined across chunks): do all its corners have a
    // vt, a vn? Each piece then takes its model's answer.
    let mut models: Vec<(bool, bool)> = vec![(true, true)];
    for piece in parsed.iter().flat_map(|c| &c.pieces) {
        let last = models.last_mut().expect("one model at least");
        last.0 &= piece.all_uv;
        last.1 &= piece.all_normal;
        if piece.ends_model {
            models.push((true, true));
        }
    }
    // tobj computes smooth normals when no model has any
    let any_normals = parsed
        .iter()
        .flat_map(|c| &c.triangles)
        .any(|t| t.iter().any(|c| c[2] != NONE));
    if smooth_normals && !any_normals {
        return false;
    }
    let mut model_of_chunk = Vec::with_capacity(parsed.len());
    let mut model = 0usize;
    for c in &parsed {
        model_of_chunk.push(model);
        model += c.pieces.iter().filter(|p| p.ends_model).count();
    }

    let normal_matrix = transform.matrix3.inverse().transpose();
    let built: Vec<(Vec<Triangle>, [usize; 4])> = parsed
        .par_iter()
        .zip(&model_of_chunk)
        .map(|(c, &first_model)| {
            let mut tris = Vec::with_capacity(c.triangles.len());
            let mut counts = [0usize; 4];
            let mut model = first_model;
            let mut t = 0;
            for piece in &c.pieces {
                let (has_uvs, has_normals) = models[model];
                for corners in &c.triangles[t..t + piece.triangles] {
                    let made = plain_triangle(
                        corners,
                        &elements,
                        (has_normals, has_uvs),
                        transform,
                        &normal_matrix,
                        material,
                    );
                    match made {
                        Made::NonFinite => counts[0] += 1,
                        Made::Degenerate => counts[1] += 1,
                        Made::Kept(tri, bad_normals, bad_uvs) => {
                            counts[2] += usize::from(bad_normals);
                            counts[3] += usize::from(bad_uvs);
                            tris.push(tri);
                        }
                    }
                }
                t += piece.triangles;
                model += usize::from(piece.ends_model);
            }
            (tris, counts)
        })
        .collect();
    let kept: usize = built.iter().map(|b| b.0.len()).sum();
    mesh.triangles.reserve_exact(kept);
    for (tris, counts) in built {
        mesh.triangles.extend_from_slice(&tris);
        mesh.dropped_non_finite += counts[0];
        mesh.dropped_degenerate += counts[1];
        mesh.bad_normals += counts[2];
        mesh.bad_uvs += counts[3];
    }
    true
}

/// One triangle from its corners' indices, as the general loader makes it.
fn plain_triangle(
    corners: &[[u32; 3]; 3],
    elements: &Elements,
    (has_normals, has_uvs): (bool, bool),
    transform: &DAffine3,
    normal_matrix: &DMat3,
    material: u32,
) -> Made {
    let d3 = |v: [f32; 3]| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
    let e = elements;
    let p = corners.map(|c| e.positions.get(c[0] as usize).map(|&v| d3(v)));
    let n = has_normals.then(|| corners.map(|c| e.normals.get(c[2] as usize).map(|&v| d3(v))));
    let uv = has_uvs.then(|| corners.map(|c| e.uvs.get(c[1] as usize).copied()));
    // Every index was checked against the elements before its line
    make_triangle(p, n, uv, transform, normal_matrix, material).unwrap_or(Made::NonFinite)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::obj::{compare_readers, mesh_bits, test_transform};
    use std::path::{Path, PathBuf};

    /// [`compare_readers`], panicking on a difference.
    fn same_mesh(name: &str, data: &[u8]) -> bool {
        compare_readers(data).unwrap_or_else(|e| panic!("{name}: {e}"))
    }

    fn transform() -> DAffine3 {
        test_transform()
    }

    /// Plain files: the parallel reader must take each and agree.
    #[test]
    fn plain_files_read_the_same_in_parallel() {
        let cases: &[(&str, &str)] = &[
            ("triangle", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
            (
                "quad and pentagon fans, CRLF, tabs, vertical tab, comments",
                "# a comment\r\nv 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\nv -1 0.5 0.25\r\n\
                 \tf 1 2 3 4\r\nf\t1 2\x0b3 4 5\x0c\r\n",
            ),
            (
                "negative and signed indices",
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf +1 -1 2\n",
            ),
            (
                "normals and uvs, partial per model",
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nvn 0 0 0\nvn 1 2 3 4 5\n\
                 vt 0 0\nvt 1 0 0.5\nvt nan 1\n\
                 o a\nf 1/1/1 2/2/1 3/2/3\nf 1//1 3//2 4//3\n\
                 g b\nf 1/1 2/2 3/1\nf 1/2/ 2/1/ 4/2/\n\
                 o c\nf 1/3/1 2/1/1 3/1/1\nf 1/1/2 2/1/2 4/1/2\n\
                 o\no d\nusemtl anything\nmtllib none.mtl\ns 1\nf 4 3 2\n",
            ),
            (
                "non-finite and degenerate triangles",
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nv inf 1 1\nv 2 0 0\n\
                 f 1 2 3\nf 1 2 4\nf 5 1 2\nf 1 2 6\nf 1 1 2\n",
            ),
            (
                "no final newline, blank lines, unknown statements",
                "\n\n   \nvp 1 2\ncurv 1 2\nv 0 0 0\nv 1e0 0 0\nv 0 .5e1 0\nf 1 2 3",
            ),
            (
                "a comment with UTF-8 text",
                "# exporté par ünïcode ✓\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            ),
            (
                "non-ASCII names, which a fixed material makes unused",
                "v 0 0 0\nv 1 0 0\nv 0 1 0\no Körper\nf 1 2 3\ng ✓ x\nusemtl café\nf 3 2 1\n",
            ),
        ];
        for (name, text) in cases {
            assert!(same_mesh(name, text.as_bytes()), "{name}: refused");
        }
        // A real mesh of many chunks: the bench's bumpy sphere shape
        let mut big = String::new();
        let n = 60;
        for i in 0..=n {
            for j in 0..=n {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                big += &format!(
                    "v {} {} {}\nvn {u} {v} 1\nvt {u} {v}\n",
                    u.sin(),
                    v.cos(),
                    u * v
                );
            }
        }
        for i in 0..n {
            for j in 0..n {
                let a = i * (n + 1) + j + 1;
                let (b, c, d) = (a + 1, a + n + 2, a + n + 1);
                big += &format!("f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c} {d}/{d}/{d}\n");
            }
            if i % 7 == 0 {
                big += "g band\n";
            }
        }
        assert!(same_mesh("grid", big.as_bytes()));
    }

    /// Files outside the plain shape: the parallel reader must refuse each
    /// (the general loader then reads it, or words its error).
    #[test]
    fn other_files_go_to_the_general_loader() {
        let head = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        for (name, tail) in [
            ("w coordinate", "v 1 1 1 2\nf 1 2 3\n"),
            ("vertex colour", "v 1 1 1 0.5 0.5 0.5\nf 1 2 3\n"),
            ("a line", "l 1 2 3\n"),
            ("comment after a face", "f 1 2 3 # c\n"),
            ("two corners", "f 1 2\n"),
            ("forward index", "f 1 2 4\nv 0 0 1\n"),
            ("index zero", "f 0 1 2\n"),
            ("index past the end", "f 1 2 9\n"),
            ("negative past the start", "f -4 1 2\n"),
            ("four parts", "f 1/1/1/1 2 3\n"),
            ("empty position", "f /1 2 3\n"),
            ("vt not yet defined", "f 1/1 2/1 3/1\n"),
            ("Unicode space in a face", "f 1\u{2003}2 3\n"),
            ("empty usemtl", "usemtl \t\nf 1 2 3\n"),
            ("bad number", "v 1 2 x\nf 1 2 3\n"),
            ("vn too short", "vn 1 2\nf 1 2 3\n"),
        ] {
            let text = format!("{head}{tail}");
            assert!(!same_mesh(name, text.as_bytes()), "{name}: taken");
        }
        let mut latin1 = head.as_bytes().to_vec();
        latin1.extend_from_slice(b"# caf\xe9\nf 1 2 3\n");
        assert!(!same_mesh("Latin-1 comment", &latin1));
        // Smooth normals to compute: the general loader's job
        let mut mesh = LoadedMesh::default();
        let text = format!("{head}f 1 2 3\n");
        assert!(!load_plain(
            text.as_bytes(),
            64,
            &transform(),
            0,
            true,
            &mut mesh
        ));
    }

    /// The repository's meshes and the fuzz corpus, and the published
    /// scenes' OBJ files: whatever the parallel reader takes, it reads as
    /// the general loader does.
    #[test]
    fn known_meshes_read_the_same() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut files: Vec<PathBuf> = Vec::new();
        for dir in ["tests/scenes/meshes", "fuzz/corpus/obj_mtl"] {
            for entry in std::fs::read_dir(root.join(dir)).unwrap() {
                files.push(entry.unwrap().path());
            }
        }
        let real = root.join("../shared/realscenes");
        for scene in std::fs::read_dir(&real).unwrap() {
            let scene = scene.unwrap().path();
            for sub in [scene.clone(), scene.join("meshes"), scene.join("spot")] {
                for entry in std::fs::read_dir(sub).into_iter().flatten() {
                    files.push(entry.unwrap().path());
                }
            }
        }
        files.retain(|f| f.extension().is_none_or(|e| e == "obj") && f.is_file());
        files.sort();
        let mut taken = 0;
        for file in &files {
            let data = std::fs::read(file).unwrap();
            // Fuzz seeds: the OBJ part before a NUL
            let obj = data.split(|&b| b == 0).next().unwrap_or(&[]);
            taken += usize::from(same_mesh(&file.display().to_string(), obj));
        }
        println!("{taken} of {} files read in parallel", files.len());
        assert!(files.len() >= 30, "{} files", files.len());
        assert!(taken >= 15, "only {taken} files read in parallel");
    }

    /// The thread count changes nothing.
    #[test]
    fn one_thread_or_many_give_the_same_mesh() {
        let mut text = String::new();
        for k in 0..3000 {
            let x = k as f32 * 0.37;
            text += &format!("v {} {} {}\n", x.sin(), x.cos(), x * 1e-3);
            if k >= 2 {
                text += &format!("f -1 -2 {}\n", k - 1);
            }
        }
        let read = || {
            let mut mesh = LoadedMesh::default();
            assert!(load_plain(
                text.as_bytes(),
                256,
                &transform(),
                1,
                false,
                &mut mesh
            ));
            mesh_bits(&mesh)
        };
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(read);
        let four = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap()
            .install(read);
        assert!(!one.0.is_empty());
        assert!(one == four);
    }
}
