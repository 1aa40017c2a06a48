//! Mitsuba's `serialized` meshes, read as Mitsuba 3.9.1 reads them
//! (`src/shapes/serialized.cpp`, the `SerializedMesh` constructor).
//!
//! A file holds one or more meshes, one after the other, each a 4-byte
//! header (the format id 0x041C and the version, 3 or 4, as little-endian
//! u16) and a zlib stream: u32 flags, in version 4 a NUL-terminated name,
//! u64 vertex and u64 triangle counts, then the positions, the vertex
//! normals, the texture coordinates and the vertex colours (each only when
//! its flag says so; f32, or f64 under flag 0x2000), then the triangles as
//! u32 indices. After the last mesh, an end-of-file table gives each mesh's
//! byte offset (u64 in version 4, u32 in version 3) and, last, the u32 mesh
//! count. As in Mitsuba, mesh 0 is read from byte 4 without the table,
//! the file's first header decides the version and the table's layout,
//! vertex colours are read past (they change nothing), the flags' face
//! normals bit (0x0010) is ignored (only the shape's `face_normals` counts),
//! indices are u32 whatever the vertex count, and texture coordinates are
//! taken as written: Mitsuba's v = 0 is an image's top row, so they become
//! lancer's v' = 1 - v, as for PLY files.
//!
//! Every size is checked before it is read: the counts against
//! [`MAX_SERIALIZED_ELEMENTS`], the bytes they need against what the
//! compressed bytes can inflate to, the end-of-file table against the
//! file. Arrays grow only as their data arrives, so a file that lies about
//! its counts costs no more memory than the data it really holds.

use super::limits::MAX_SERIALIZED_ELEMENTS;
use flate2::read::ZlibDecoder;
use std::io::Read as _;
use std::path::Path;

/// The format id at the head of every mesh of a file.
const FORMAT_ID: u16 = 0x041C;
/// Flag: the mesh has vertex normals.
const HAS_NORMALS: u32 = 0x0001;
/// Flag: the mesh has texture coordinates.
const HAS_TEXCOORDS: u32 = 0x0002;
/// Flag: the mesh has vertex colours.
const HAS_COLORS: u32 = 0x0008;
/// Flag: the file asks for face normals. Mitsuba 3.9.1 reads the bit and
/// does nothing with it; so does lancer (the caller warns).
pub(crate) const FACE_NORMALS: u32 = 0x0010;
/// Flag: values are f64 (else f32; the single-precision flag 0x1000 is not
/// consulted, by Mitsuba either).
const DOUBLE_PRECISION: u32 = 0x2000;
/// Most bytes one compressed byte can inflate to: deflate's largest ratio
/// (a 258-byte match costs at least 2 bits, about 1032 to 1).
const MAX_INFLATE_RATIO: u64 = 1032;
/// Values decoded per read of the stream.
const CHUNK_VALUES: usize = 4096;

/// One mesh of a serialized file: single-indexed triangles in lancer's
/// texture convention (v = 0 at the image's bottom row), and the flags the
/// file gave it.
pub(crate) struct SerializedMesh {
    /// Positions, normals (none when the file has none or `face_normals`
    /// skipped them), texture coordinates and triangle indices.
    pub mesh: tobj::Mesh,
    /// The mesh's flags as written (see [`FACE_NORMALS`]).
    pub flags: u32,
}

/// Reads mesh `shape_index` of a serialized file. With `face_normals`, the
/// file's vertex normals are read past, as Mitsuba does. `shown` is the
/// file as messages name it.
pub(crate) fn read_serialized(
    path: &Path,
    shown: &str,
    shape_index: u32,
    face_normals: bool,
) -> Result<SerializedMesh, String> {
    let bytes = super::ply::read_bounded(path)
        .map_err(|e| format!("cannot read serialized file {shown}: {e}"))?;
    parse(&bytes, shown, shape_index, face_normals)
}

/// [`read_serialized`] of the file's bytes.
fn parse(
    bytes: &[u8],
    shown: &str,
    shape_index: u32,
    face_normals: bool,
) -> Result<SerializedMesh, String> {
    let err = |reason: String| format!("serialized file {shown}: {reason}");
    let [a, b, c, d, ..] = *bytes else {
        return Err(err(format!(
            "it has {} bytes, fewer than its 4-byte header: not a serialized file",
            bytes.len()
        )));
    };
    let format = u16::from_le_bytes([a, b]);
    if format != FORMAT_ID {
        return Err(err(format!(
            "it starts with {format:#06x}, not the format id {FORMAT_ID:#06x} of a Mitsuba \
             serialized mesh: not a serialized file"
        )));
    }
    let version = u16::from_le_bytes([c, d]);
    if version != 3 && version != 4 {
        return Err(err(format!(
            "format version {version}; Mitsuba 3 and lancer read versions 3 and 4"
        )));
    }
    let start = if shape_index == 0 {
        4
    } else {
        mesh_offset(bytes, version, shape_index).map_err(err)? + 4
    };
    Mesh {
        stream: Inflate {
            z: ZlibDecoder::new(&bytes[start..]),
        },
        compressed: (bytes.len() - start) as u64,
        version,
        face_normals,
    }
    .read()
    .map_err(|reason| err(format!("mesh {shape_index}: {reason}")))
}

/// Where mesh `index` (not 0) starts, from the end-of-file table: checked
/// to lie inside the file, before the table, and to start with the format
/// id (which Mitsuba skips unread).
fn mesh_offset(bytes: &[u8], version: u16, index: u32) -> Result<usize, String> {
    let u32_at = |at: usize| {
        let b = &bytes[at..at + 4];
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    };
    let len = bytes.len();
    // The count is the file's last 4 bytes, after the first mesh's header.
    let count_at = len.checked_sub(4).filter(|&at| at >= 4).ok_or_else(|| {
        format!(
            "shape_index {index} needs the end-of-file table of a file of several meshes, \
             but the file has only {len} bytes; use shape_index 0"
        )
    })?;
    let count = u32_at(count_at);
    if index >= count {
        return Err(match count {
            0 => format!(
                "shape_index {index} is out of range: its end-of-file table lists no meshes"
            ),
            _ => format!(
                "shape_index {index} is out of range: its end-of-file table lists {count} \
                 mesh{} (shape_index 0 to {})",
                if count == 1 { "" } else { "es" },
                count - 1
            ),
        });
    }
    let entry = if version == 4 { 8 } else { 4 };
    // At most 2^32 entries of 8 bytes: no overflow in u64.
    let back = u64::from(count - index) * entry;
    let at = (count_at as u64)
        .checked_sub(back)
        .filter(|&at| at >= 4)
        .ok_or_else(|| {
            format!(
                "its end-of-file table lists {count} meshes, whose offsets ({entry} bytes each) \
                 do not fit in the file's {len} bytes: the file is truncated, or its table is \
                 wrong"
            )
        })? as usize;
    let offset = if version == 4 {
        let b = &bytes[at..at + 8];
        u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
    } else {
        u64::from(u32_at(at))
    };
    // The mesh's header and stream come before the table.
    if offset.checked_add(4).is_none_or(|end| end > at as u64) {
        return Err(format!(
            "its end-of-file table puts mesh {index} at byte {offset}, but the table itself \
             starts by byte {at}: the table is wrong"
        ));
    }
    let offset = offset as usize;
    if bytes[offset..offset + 2] != FORMAT_ID.to_le_bytes() {
        return Err(format!(
            "its end-of-file table puts mesh {index} at byte {offset}, where no mesh header \
             (format id {FORMAT_ID:#06x}) starts: the table is wrong"
        ));
    }
    Ok(offset)
}

/// A mesh's zlib stream, read exactly.
struct Inflate<'a> {
    z: ZlibDecoder<&'a [u8]>,
}

impl Inflate<'_> {
    /// Fills `buf`; on error, why, naming `what` was being read.
    fn exact(&mut self, buf: &mut [u8], what: &str) -> Result<(), String> {
        self.z.read_exact(buf).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                format!(
                    "its compressed stream ends inside {what}: the file is truncated, or its \
                     counts are wrong"
                )
            } else {
                format!(
                    "its compressed stream is damaged inside {what} (zlib: {e}): the file is \
                     corrupt"
                )
            }
        })
    }

    fn u32(&mut self, what: &str) -> Result<u32, String> {
        let mut b = [0; 4];
        self.exact(&mut b, what)?;
        Ok(u32::from_le_bytes(b))
    }

    fn u64(&mut self, what: &str) -> Result<u64, String> {
        let mut b = [0; 8];
        self.exact(&mut b, what)?;
        Ok(u64::from_le_bytes(b))
    }

    /// Reads `count` values of `width` bytes each, in chunks, handing each
    /// value's bytes to `each` with its index; `each` may refuse one.
    fn values(
        &mut self,
        count: u64,
        width: usize,
        what: &str,
        mut each: impl FnMut(u64, &[u8]) -> Result<(), String>,
    ) -> Result<(), String> {
        let mut buf = vec![0u8; CHUNK_VALUES * width];
        let mut done = 0u64;
        while done < count {
            // At most CHUNK_VALUES: fits a usize.
            let n = (count - done).min(CHUNK_VALUES as u64) as usize;
            let chunk = &mut buf[..n * width];
            self.exact(chunk, what)?;
            for (k, value) in chunk.chunks_exact(width).enumerate() {
                each(done + k as u64, value)?;
            }
            done += n as u64;
        }
        Ok(())
    }
}

/// One mesh being read from its stream.
struct Mesh<'a> {
    stream: Inflate<'a>,
    /// Bytes from the stream's start to the end of the file.
    compressed: u64,
    version: u16,
    face_normals: bool,
}

/// A value of the file's precision, as the f32 Mitsuba keeps.
fn float(bytes: &[u8]) -> f32 {
    match *bytes {
        [a, b, c, d] => f32::from_le_bytes([a, b, c, d]),
        [a, b, c, d, e, f, g, h] => f64::from_le_bytes([a, b, c, d, e, f, g, h]) as f32,
        // `values` hands out 4 or 8 bytes only.
        _ => f32::NAN,
    }
}

impl Mesh<'_> {
    fn read(mut self) -> Result<SerializedMesh, String> {
        let flags = self.stream.u32("its flags")?;
        if self.version == 4 {
            // The name, which lancer does not keep: read up to its NUL.
            let mut ch = [1u8];
            while ch[0] != 0 {
                self.stream.exact(&mut ch, "its name")?;
            }
        }
        let vertices = self.stream.u64("its vertex count")?;
        let triangles = self.stream.u64("its triangle count")?;
        for (n, what) in [(vertices, "vertices"), (triangles, "triangles")] {
            if n > MAX_SERIALIZED_ELEMENTS {
                return Err(format!(
                    "it declares {n} {what}; lancer reads at most {MAX_SERIALIZED_ELEMENTS} \
                     {what} of a mesh (docs/mitsuba.md): split the mesh, or the file is damaged"
                ));
            }
        }
        let width = if flags & DOUBLE_PRECISION != 0 { 8 } else { 4 };
        let has = |flag: u32| u64::from(flags & flag != 0);
        // Both counts are at most 2^28: no product below overflows, but
        // the arithmetic is checked all the same.
        let per_vertex = 3 + 3 * has(HAS_NORMALS) + 2 * has(HAS_TEXCOORDS) + 3 * has(HAS_COLORS);
        let needed = vertices
            .checked_mul(per_vertex * width as u64)
            .zip(triangles.checked_mul(12))
            .and_then(|(v, t)| v.checked_add(t));
        let most = self.compressed.saturating_mul(MAX_INFLATE_RATIO);
        if needed.is_none_or(|n| n > most) {
            return Err(format!(
                "it declares {vertices} vertices and {triangles} triangles, {} bytes of data, \
                 more than the {} compressed bytes after its header can hold (at most \
                 {MAX_INFLATE_RATIO} times as many): the file is truncated, or its counts are \
                 wrong",
                needed.map_or_else(|| String::from("more than 2^64"), |n| n.to_string()),
                self.compressed
            ));
        }
        let mut mesh = tobj::Mesh::default();
        self.stream
            .values(3 * vertices, width, "its positions", |_, b| {
                mesh.positions.push(float(b));
                Ok(())
            })?;
        if let Some(v) = mesh
            .positions
            .chunks_exact(3)
            .position(|p| !p.iter().all(|x| x.is_finite()))
        {
            let p = &mesh.positions[3 * v..3 * v + 3];
            return Err(format!(
                "vertex {v} is at [{}, {}, {}], not finite in 32-bit floats: the file is \
                 damaged",
                p[0], p[1], p[2]
            ));
        }
        if flags & HAS_NORMALS != 0 {
            let keep = !self.face_normals;
            self.stream
                .values(3 * vertices, width, "its vertex normals", |_, b| {
                    if keep {
                        mesh.normals.push(float(b));
                    }
                    Ok(())
                })?;
        }
        if flags & HAS_TEXCOORDS != 0 {
            self.stream
                .values(2 * vertices, width, "its texture coordinates", |k, b| {
                    let x = float(b);
                    // Mitsuba's v = 0 is the image's top row, lancer's the bottom.
                    mesh.texcoords.push(if k % 2 == 1 { 1.0 - x } else { x });
                    Ok(())
                })?;
        }
        if flags & HAS_COLORS != 0 {
            self.stream
                .values(3 * vertices, width, "its vertex colours", |_, _| Ok(()))?;
        }
        self.stream
            .values(3 * triangles, 4, "its triangles", |k, b| {
                let i = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                if u64::from(i) >= vertices {
                    return Err(format!(
                        "triangle {} names vertex {i}, but the mesh has {vertices} vertices",
                        k / 3
                    ));
                }
                mesh.indices.push(i);
                Ok(())
            })?;
        Ok(SerializedMesh { mesh, flags })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::write::ZlibEncoder;
    use std::io::Write as _;

    /// A mesh to encode: f64 values, written in the file's precision.
    #[derive(Clone, Default)]
    struct Plain {
        flags: u32,
        positions: Vec<[f64; 3]>,
        normals: Vec<[f64; 3]>,
        uvs: Vec<[f64; 2]>,
        colors: Vec<[f64; 3]>,
        faces: Vec<[u32; 3]>,
        /// Counts to write in place of the real ones.
        counts: Option<(u64, u64)>,
    }

    /// Two triangles of a unit quad, with normals, uvs and colours as
    /// `flags` (with HAS_* bits) asks.
    fn quad(flags: u32) -> Plain {
        Plain {
            flags,
            positions: vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
            normals: vec![[0., 0., 2.]; 4],
            uvs: vec![[0., 0.], [1., 0.], [1., 1.], [0., 0.25]],
            colors: vec![[0.5, 0.5, 0.5]; 4],
            faces: vec![[0, 1, 2], [0, 2, 3]],
            counts: None,
        }
    }

    /// The uncompressed stream of one mesh.
    fn body(m: &Plain, version: u16) -> Vec<u8> {
        let mut b = m.flags.to_le_bytes().to_vec();
        if version == 4 {
            b.extend_from_slice(b"mesh\0");
        }
        let (v, t) = m
            .counts
            .unwrap_or((m.positions.len() as u64, m.faces.len() as u64));
        b.extend(v.to_le_bytes());
        b.extend(t.to_le_bytes());
        let mut put = |x: f64| {
            if m.flags & DOUBLE_PRECISION != 0 {
                b.extend(x.to_le_bytes());
            } else {
                b.extend((x as f32).to_le_bytes());
            }
        };
        m.positions.iter().flatten().for_each(|&x| put(x));
        if m.flags & HAS_NORMALS != 0 {
            m.normals.iter().flatten().for_each(|&x| put(x));
        }
        if m.flags & HAS_TEXCOORDS != 0 {
            m.uvs.iter().flatten().for_each(|&x| put(x));
        }
        if m.flags & HAS_COLORS != 0 {
            m.colors.iter().flatten().for_each(|&x| put(x));
        }
        b.extend(m.faces.iter().flatten().flat_map(|i| i.to_le_bytes()));
        b
    }

    fn zlib(data: &[u8]) -> Vec<u8> {
        let mut z = ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(data).unwrap();
        z.finish().unwrap()
    }

    /// A whole file: each mesh's header and zlib stream, then the
    /// end-of-file table.
    fn file(meshes: &[Plain], version: u16) -> Vec<u8> {
        let mut f = Vec::new();
        let mut offsets = Vec::new();
        for m in meshes {
            offsets.push(f.len() as u64);
            f.extend(FORMAT_ID.to_le_bytes());
            f.extend(version.to_le_bytes());
            f.extend(zlib(&body(m, version)));
        }
        for o in offsets {
            if version == 4 {
                f.extend(o.to_le_bytes());
            } else {
                f.extend((o as u32).to_le_bytes());
            }
        }
        f.extend((meshes.len() as u32).to_le_bytes());
        f
    }

    fn read(bytes: &[u8], index: u32) -> Result<tobj::Mesh, String> {
        parse(bytes, "m.serialized", index, false).map(|s| s.mesh)
    }

    fn err(bytes: &[u8], index: u32) -> String {
        match read(bytes, index) {
            Ok(_) => panic!("the file was read"),
            Err(e) => e,
        }
    }

    #[test]
    fn every_version_precision_and_attribute_reads_back() {
        for version in [3, 4] {
            for precision in [0x1000, DOUBLE_PRECISION] {
                for extra in [0, HAS_NORMALS, HAS_TEXCOORDS, HAS_COLORS, 0xB] {
                    let flags = precision | extra;
                    let m = read(&file(&[quad(flags)], version), 0).unwrap();
                    let case = format!("version {version}, flags {flags:#x}");
                    assert_eq!(
                        m.positions,
                        [0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.],
                        "{case}"
                    );
                    assert_eq!(m.indices, [0, 1, 2, 0, 2, 3], "{case}");
                    let normals = if extra & HAS_NORMALS != 0 { 12 } else { 0 };
                    assert_eq!(m.normals.len(), normals, "{case}");
                    assert!(m.normals.chunks(3).all(|n| n == [0., 0., 2.]), "{case}");
                    if extra & HAS_TEXCOORDS != 0 {
                        // v flipped into lancer's convention.
                        assert_eq!(m.texcoords, [0., 1., 1., 1., 1., 0., 0., 0.75], "{case}");
                    } else {
                        assert!(m.texcoords.is_empty(), "{case}");
                    }
                }
            }
        }
    }

    #[test]
    fn double_precision_is_rounded_to_f32_as_mitsuba_does() {
        let mut m = quad(DOUBLE_PRECISION);
        m.positions[1][0] = 0.1;
        let got = read(&file(&[m], 4), 0).unwrap();
        assert_eq!(got.positions[3], 0.1f64 as f32);
    }

    #[test]
    fn shape_index_picks_each_mesh_of_a_file() {
        for version in [3, 4] {
            let mut meshes = Vec::new();
            for k in 0..3u32 {
                let mut m = quad(if k == 1 { HAS_NORMALS } else { 0 });
                m.positions[0] = [f64::from(k) + 5.0, 0., 0.];
                if k == 2 {
                    m.faces.truncate(1);
                }
                meshes.push(m);
            }
            let f = file(&meshes, version);
            for k in 0..3u32 {
                let m = read(&f, k).unwrap();
                assert_eq!(
                    m.positions[0],
                    k as f32 + 5.0,
                    "version {version}, mesh {k}"
                );
                assert_eq!(m.normals.is_empty(), k != 1);
                assert_eq!(m.indices.len(), if k == 2 { 3 } else { 6 });
            }
            assert_eq!(
                err(&f, 3),
                "serialized file m.serialized: shape_index 3 is out of range: its \
                 end-of-file table lists 3 meshes (shape_index 0 to 2)"
            );
        }
    }

    #[test]
    fn face_normals_skip_the_files_normals_and_the_flag_alone_does_nothing() {
        let f = file(&[quad(HAS_NORMALS | HAS_TEXCOORDS)], 4);
        let m = parse(&f, "m", 0, true).unwrap();
        assert!(m.mesh.normals.is_empty());
        assert_eq!(m.mesh.texcoords.len(), 8);
        let m = parse(&file(&[quad(FACE_NORMALS | HAS_NORMALS)], 4), "m", 0, false).unwrap();
        assert_eq!(m.mesh.normals.len(), 12);
        assert_eq!(m.flags & FACE_NORMALS, FACE_NORMALS);
    }

    #[test]
    fn a_single_mesh_needs_no_end_of_file_table() {
        let mut f = FORMAT_ID.to_le_bytes().to_vec();
        f.extend(4u16.to_le_bytes());
        f.extend(zlib(&body(&quad(0), 4)));
        assert_eq!(read(&f, 0).unwrap().indices.len(), 6);
    }

    #[test]
    fn bad_headers_and_tables_are_refused_by_name() {
        let good = file(&[quad(0), quad(0)], 4);
        assert_eq!(
            err(b"\x1c\x04", 0),
            "serialized file m.serialized: it has 2 bytes, fewer than its 4-byte header: not \
             a serialized file"
        );
        let mut f = good.clone();
        f[0] = 0x1d;
        assert_eq!(
            err(&f, 0),
            "serialized file m.serialized: it starts with 0x041d, not the format id 0x041c \
             of a Mitsuba serialized mesh: not a serialized file"
        );
        let mut f = good.clone();
        f[2] = 5;
        assert_eq!(
            err(&f, 0),
            "serialized file m.serialized: format version 5; Mitsuba 3 and lancer read \
             versions 3 and 4"
        );
        // A count the table cannot hold.
        let mut f = good.clone();
        let n = f.len();
        f[n - 4..].copy_from_slice(&1000u32.to_le_bytes());
        assert_eq!(
            err(&f, 1),
            format!(
                "serialized file m.serialized: its end-of-file table lists 1000 meshes, whose \
                 offsets (8 bytes each) do not fit in the file's {n} bytes: the file is \
                 truncated, or its table is wrong"
            )
        );
        // An offset past the table.
        let mut f = good.clone();
        f[n - 12..n - 4].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(err(&f, 1).contains(&format!(
            "puts mesh 1 at byte {}, but the table itself starts by byte {}: the table is wrong",
            u64::MAX,
            n - 12
        )));
        // An offset inside a mesh.
        let mut f = good.clone();
        f[n - 12..n - 4].copy_from_slice(&7u64.to_le_bytes());
        assert!(err(&f, 1).ends_with(
            "puts mesh 1 at byte 7, where no mesh header (format id 0x041c) starts: the \
             table is wrong"
        ));
        let mut f = good.clone();
        f[n - 4..].copy_from_slice(&0u32.to_le_bytes());
        assert!(err(&f, 1)
            .ends_with("shape_index 1 is out of range: its end-of-file table lists no meshes"));
        assert!(err(&good[..6], 1).ends_with(
            "shape_index 1 needs the end-of-file table of a file of several meshes, but the \
             file has only 6 bytes; use shape_index 0"
        ));
    }

    #[test]
    fn lying_streams_are_refused_by_name() {
        let prefix = "serialized file m.serialized: mesh 0: ";
        let e = |m: &Plain| err(&file(std::slice::from_ref(m), 4), 0);
        // Counts the data does not hold (but the compressed bytes could).
        let mut m = quad(0);
        m.counts = Some((40, 2));
        assert_eq!(
            e(&m),
            format!(
                "{prefix}its compressed stream ends inside its positions: the file is \
                 truncated, or its counts are wrong"
            )
        );
        // Counts no compressed stream of this size can hold.
        m.counts = Some((1 << 20, 2));
        assert!(
            e(&m).starts_with(&format!(
                "{prefix}it declares 1048576 vertices and 2 triangles, 12582936 bytes of data, \
             more than the "
            )),
            "{}",
            e(&m)
        );
        m.counts = Some((1 << 40, 2));
        assert_eq!(
            e(&m),
            format!(
                "{prefix}it declares 1099511627776 vertices; lancer reads at most 268435456 \
                 vertices of a mesh (docs/mitsuba.md): split the mesh, or the file is damaged"
            )
        );
        m.counts = Some((4, u64::MAX));
        assert!(e(&m).starts_with(&format!("{prefix}it declares {} triangles;", u64::MAX)));
        let mut m = quad(0);
        m.faces[1][2] = 4;
        assert_eq!(
            e(&m),
            format!("{prefix}triangle 1 names vertex 4, but the mesh has 4 vertices")
        );
        for bad in [f64::NAN, f64::INFINITY, 1e300] {
            let mut m = quad(DOUBLE_PRECISION);
            m.positions[2][1] = bad;
            let y = bad as f32;
            assert_eq!(
                e(&m),
                format!(
                    "{prefix}vertex 2 is at [1, {y}, 0], not finite in 32-bit floats: the \
                     file is damaged"
                )
            );
        }
        // A stream cut short, and one whose bytes are not zlib.
        let f = file(&[quad(HAS_TEXCOORDS)], 4);
        let cut = &f[..f.len() - 20];
        assert_eq!(
            err(cut, 0),
            format!(
                "{prefix}its compressed stream ends inside its triangles: the file is \
                 truncated, or its counts are wrong"
            )
        );
        let mut f = file(&[quad(0)], 4);
        f[4] = 0x12;
        assert_eq!(
            err(&f, 0),
            format!(
                "{prefix}its compressed stream is damaged inside its flags (zlib: corrupt \
                 deflate stream): the file is corrupt"
            )
        );
        let mut f = file(&[quad(0)], 3);
        f.truncate(4);
        assert_eq!(
            err(&f, 0),
            format!(
                "{prefix}its compressed stream ends inside its flags: the file is truncated, \
                 or its counts are wrong"
            )
        );
    }
}
