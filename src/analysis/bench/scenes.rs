//! The benchmark's scenes: the example scenes as built into the binary, and
//! a generated bumpy sphere in the Cornell box at any triangle count (a
//! million for the scale figures, about a thousand for the same shape at
//! low resolution).
//!
//! The sphere is a cube sphere: each face of a cube is split into n × n
//! quads (two triangles each, so 12·n² triangles), its points pushed onto
//! the sphere through the tangent warp (even spacing) and displaced along
//! the radius by a fixed sum of sines. The OBJ and its scene file are
//! written on demand into a cache folder, atomically, and reused while their
//! first line (generator version and size) matches: nothing is downloaded
//! and nothing large is committed. The same `n` always gives the same bytes.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};
use glam::DVec3;

use crate::io::image_file::write_atomically;

/// Quads per cube-face edge of the million-triangle sphere: 12 · 289² =
/// 1,002,252 triangles.
pub const MILLION_SUBDIVISIONS: u32 = 289;

/// Quads per cube-face edge of the same shape at about a thousand
/// triangles: 12 · 9² = 972.
pub const THOUSAND_SUBDIVISIONS: u32 = 9;

/// Bump the first line of every generated file when the output changes, so
/// that stale cache files are rewritten.
const GENERATOR_VERSION: u32 = 1;

/// Centre of the sphere in the Cornell box (y up, floor at 0).
const CENTER: DVec3 = DVec3::new(0.0, 0.62, 0.0);

/// Radius of the undisplaced sphere.
const RADIUS: f64 = 0.48;

/// Largest displacement, as a fraction of the radius.
const BUMP: f64 = 0.12;

/// Triangles of a bumpy sphere with `n` quads per cube-face edge.
pub fn sphere_triangles(n: u32) -> u64 {
    12 * u64::from(n) * u64::from(n)
}

/// Radius at unit direction `d`: a fixed sum of sines, at most `BUMP` of
/// the radius either way.
fn radius_at(d: DVec3) -> f64 {
    let low = (5.0 * d.x + 1.3).sin() * (6.0 * d.y + 0.7).sin() * (7.0 * d.z + 2.1).sin();
    let high = (17.0 * d.x - 0.4).sin() * (19.0 * d.y + 1.9).sin() * (23.0 * d.z + 0.3).sin();
    RADIUS * (1.0 + BUMP * (0.7 * low + 0.3 * high))
}

/// Point `(i, j)` of the `n × n` grid on cube face `face` (0..6), on the
/// displaced sphere.
fn grid_point(face: usize, i: u32, j: u32, n: u32) -> DVec3 {
    use std::f64::consts::FRAC_PI_4;
    // Tangent warp: even angular spacing across the face; the ends are
    // exactly -1 and 1, so that faces meet at bit-identical points
    let warp = |k: u32| match k {
        0 => -1.0,
        k if k == n => 1.0,
        k => ((2.0 * f64::from(k) / f64::from(n) - 1.0) * FRAC_PI_4).tan(),
    };
    let (a, b) = (warp(i), warp(j));
    // Each face: (normal, u axis, v axis) with u × v = normal, so the
    // triangles below wind outwards
    let (normal, u, v) = match face {
        0 => (DVec3::X, DVec3::Y, DVec3::Z),
        1 => (DVec3::NEG_X, DVec3::Z, DVec3::Y),
        2 => (DVec3::Y, DVec3::Z, DVec3::X),
        3 => (DVec3::NEG_Y, DVec3::X, DVec3::Z),
        4 => (DVec3::Z, DVec3::X, DVec3::Y),
        _ => (DVec3::NEG_Z, DVec3::Y, DVec3::X),
    };
    let d = (normal + a * u + b * v).normalize();
    CENTER + d * radius_at(d)
}

/// Writes the OBJ of a bumpy sphere with `n` quads per cube-face edge:
/// vertices to 6 decimals, then faces, no normals (shaded flat).
fn write_sphere_obj(w: &mut (impl std::io::Write + ?Sized), n: u32) -> std::io::Result<()> {
    writeln!(w, "{}", header_line(n))?;
    let side = n + 1;
    for face in 0..6 {
        for i in 0..side {
            for j in 0..side {
                let p = grid_point(face, i, j, n);
                writeln!(w, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z)?;
            }
        }
    }
    let per_face = side * side;
    for face in 0..6u32 {
        // OBJ indices count from 1
        let at = |i: u32, j: u32| 1 + face * per_face + i * side + j;
        for i in 0..n {
            for j in 0..n {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                writeln!(w, "f {a} {b} {c}")?;
                writeln!(w, "f {a} {c} {d}")?;
            }
        }
    }
    Ok(())
}

/// First line of a generated OBJ: what made it, so a stale file is noticed.
fn header_line(n: u32) -> String {
    format!(
        "# lancer bumpy sphere v{GENERATOR_VERSION}, {n} quads per cube-face edge, {} triangles",
        sphere_triangles(n)
    )
}

/// The scene file around a generated sphere: the Cornell box of
/// `scenes/cornell.toml` (walls and light) with the sphere in it.
fn sphere_scene_toml(obj_name: &str, n: u32) -> String {
    let walls = cornell_walls();
    format!(
        "{header}\n# Written by `lancer bench`: the Cornell box's walls and light around a\n\
         # bumpy sphere of {tris} triangles ({obj_name}).\n\n\
         [render]\nwidth = 256\nheight = 256\nspp = 64\nmax_depth = 8\nseed = 0\n\n\
         [camera]\neye = [0.0, 1.0, 3.9]\nlook_at = [0.0, 1.0, 0.0]\nup = [0.0, 1.0, 0.0]\nvfov = 40.0\n\n\
         [materials.sphere]\ntype = \"lambert\"\nalbedo = [0.6, 0.6, 0.55]\n\n\
         {walls}\n\
         [[objects]]\ntype = \"mesh\"\nfile = \"{obj_name}\"\nmaterial = \"sphere\"\n",
        header = header_line(n),
        tris = sphere_triangles(n),
    )
}

/// The materials, walls and light of `scenes/cornell.toml`, as TOML: its
/// text from `# ---- materials` up to its blocks.
fn cornell_walls() -> String {
    let text = CORNELL_TOML;
    let start = text.find("[materials.white]").unwrap_or(0);
    // Up to the comment line that heads the blocks
    let end = text
        .find(" blocks\n")
        .and_then(|e| text[..e].rfind('\n'))
        .unwrap_or(text.len());
    text[start..end].to_string()
}

/// `scenes/cornell.toml` as built into the binary.
const CORNELL_TOML: &str = include_str!("../../../scenes/cornell.toml");
/// `scenes/glass.toml` as built into the binary.
const GLASS_TOML: &str = include_str!("../../../scenes/glass.toml");
/// `scenes/meshes/cube.obj`, which both name.
const CUBE_OBJ: &str = include_str!("../../../scenes/meshes/cube.obj");

/// Writes `contents` to `path` unless the file there already starts with
/// `first_line`; atomically.
fn ensure_file(
    path: &Path,
    first_line: &str,
    contents: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<()> {
    if let Ok(file) = std::fs::File::open(path) {
        let mut line = String::new();
        let mut reader = std::io::BufReader::new(file);
        if std::io::BufRead::read_line(&mut reader, &mut line).is_ok()
            && line.trim_end() == first_line
        {
            return Ok(());
        }
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the scene folder", dir.display()))?;
    }
    write_atomically(path, |w| Ok(contents(w)?))
}

/// The file names of the bumpy sphere of `n` quads per cube-face edge:
/// its mesh and its scene.
fn bumpy_sphere_names(n: u32) -> [String; 2] {
    [
        format!("bumpy_sphere_{n}.obj"),
        format!("bumpy_sphere_{n}.toml"),
    ]
}

/// The files [`bumpy_sphere_scene`] writes in `dir`: the mesh and the scene.
pub fn bumpy_sphere_files(dir: &Path, n: u32) -> [PathBuf; 2] {
    bumpy_sphere_names(n).map(|name| dir.join(name))
}

/// Writes (or finds, when already written) the bumpy sphere of `n` quads
/// per cube-face edge and its Cornell-box scene in `dir`; returns the
/// scene file.
pub fn bumpy_sphere_scene(dir: &Path, n: u32) -> Result<PathBuf> {
    anyhow::ensure!(n >= 1, "a bumpy sphere needs at least 1 quad per face edge");
    let [obj_name, scene_name] = bumpy_sphere_names(n);
    let obj = dir.join(&obj_name);
    ensure_file(&obj, &header_line(n), |w| write_sphere_obj(w, n))?;
    let scene = dir.join(scene_name);
    let text = sphere_scene_toml(&obj_name, n);
    ensure_file(&scene, &header_line(n), |w| w.write_all(text.as_bytes()))?;
    Ok(scene)
}

/// Writes (or finds) the built-in copies of `scenes/cornell.toml` and
/// `scenes/glass.toml`, with the mesh they name, in `dir`; returns the
/// scene files (Cornell, glass). Built in, so the suite is the same
/// wherever the binary runs.
pub fn example_scenes(dir: &Path) -> Result<(PathBuf, PathBuf)> {
    let mut paths = Vec::new();
    for (name, text) in EXAMPLE_FILES {
        let path = dir.join(name);
        let first = text.lines().next().unwrap_or_default();
        ensure_file(&path, first, |w| w.write_all(text.as_bytes()))?;
        paths.push(path);
    }
    Ok((paths[1].clone(), paths[2].clone()))
}

/// The files [`example_scenes`] writes (under their folder), and their text.
const EXAMPLE_FILES: [(&str, &str); 3] = [
    ("meshes/cube.obj", CUBE_OBJ),
    ("cornell.toml", CORNELL_TOML),
    ("glass.toml", GLASS_TOML),
];

/// The files [`example_scenes`] writes in `dir`.
pub fn example_files(dir: &Path) -> Vec<PathBuf> {
    EXAMPLE_FILES
        .iter()
        .map(|(name, _)| dir.join(name))
        .collect()
}

/// The folder for generated scenes: `$LANCER_SCENE_CACHE_DIR`, else
/// `scenes` in lancer's cache folder (see [`crate::util::dirs::cache_home`]).
pub fn default_scene_dir() -> Result<PathBuf> {
    if let Some(dir) = std::env::var_os("LANCER_SCENE_CACHE_DIR").filter(|d| !d.is_empty()) {
        return Ok(PathBuf::from(dir));
    }
    crate::util::dirs::cache_home()
        .map(|d| d.join("scenes"))
        .context("no cache folder: set LANCER_SCENE_CACHE_DIR, XDG_CACHE_HOME or HOME")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_has_the_promised_triangles_and_bumps() {
        let mut bytes = Vec::new();
        write_sphere_obj(&mut bytes, 5).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        let faces = text.lines().filter(|l| l.starts_with("f ")).count();
        let verts: Vec<DVec3> = text
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                let c: Vec<f64> = l.split(' ').map(|x| x.parse().unwrap()).collect();
                DVec3::new(c[0], c[1], c[2])
            })
            .collect();
        assert_eq!(faces as u64, sphere_triangles(5));
        assert_eq!(verts.len(), 6 * 36);
        // Every point within the bumps, and the bumps are really there
        let radii: Vec<f64> = verts.iter().map(|p| (*p - CENTER).length()).collect();
        let (lo, hi) = radii
            .iter()
            .fold((f64::MAX, 0.0f64), |(lo, hi), &r| (lo.min(r), hi.max(r)));
        assert!(lo >= RADIUS * (1.0 - BUMP) - 1e-5 && hi <= RADIUS * (1.0 + BUMP) + 1e-5);
        assert!(hi - lo > RADIUS * BUMP * 0.5, "bumps {lo}..{hi}");
        // Inside the Cornell box (x, z in [-1, 1], y in [0, 2])
        assert!(verts
            .iter()
            .all(|p| p.x.abs() < 1.0 && p.z.abs() < 1.0 && p.y > 0.0 && p.y < 2.0));
    }

    #[test]
    fn sphere_is_deterministic_and_closed() {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        write_sphere_obj(&mut a, 7).unwrap();
        write_sphere_obj(&mut b, 7).unwrap();
        assert_eq!(a, b);
        // Closed: every edge (by vertex position) is shared by exactly two
        // triangles, once in each direction (consistent outward winding)
        let text = String::from_utf8(a).unwrap();
        let verts: Vec<&str> = text.lines().filter_map(|l| l.strip_prefix("v ")).collect();
        let mut edges = std::collections::HashMap::new();
        for f in text.lines().filter_map(|l| l.strip_prefix("f ")) {
            let idx: Vec<usize> = f
                .split(' ')
                .map(|x| x.parse::<usize>().unwrap() - 1)
                .collect();
            for k in 0..3 {
                let (p, q) = (verts[idx[k]], verts[idx[(k + 1) % 3]]);
                *edges.entry((p, q)).or_insert(0) += 1;
            }
        }
        for (&(p, q), &count) in &edges {
            assert_eq!(count, 1, "edge {p} -> {q} used {count} times");
            assert_eq!(edges.get(&(q, p)), Some(&1), "edge {p} -> {q} has no twin");
        }
    }
}
