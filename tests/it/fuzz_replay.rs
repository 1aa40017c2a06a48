//! Replays the fuzz corpora (`fuzz/corpus/`) and every input the fuzzer
//! found (`fuzz/regressions/`) through the fuzz harness itself, without AFL:
//! the same `Fixture::run` the AFL binary calls. A panic fails the test; the
//! assertions pin what lancer must do with each input.

#[path = "../../fuzz/src/lib.rs"]
mod harness;

use harness::{Fixture, Target};
use std::path::{Path, PathBuf};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn fixture() -> Fixture {
    Fixture::new(&repo("tests/scenes")).unwrap_or_else(|e| panic!("{e}"))
}

/// The files of a folder, sorted by name.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

/// Seeds that lancer must refuse: the corpus keeps bad inputs as well, so
/// that the fuzzer starts from every error path. Named `bad_*`, or a
/// tests/scenes mesh that exists to be refused.
fn must_refuse(target: Target, name: &str) -> bool {
    name.starts_with("bad_")
        || (target == Target::ObjMtl
            && matches!(
                name,
                "hostile_index"
                    | "latin1_vertex"
                    | "missing_mtl"
                    | "missing_texture"
                    | "no_material"
            ))
}

#[test]
fn every_corpus_seed_is_loaded_or_refused_as_its_name_says() {
    let fixture = fixture();
    let mut wrong = Vec::new();
    for target in Target::ALL {
        let seeds = files(&repo("fuzz/corpus").join(target.name()));
        assert!(
            seeds.len() >= 3,
            "{}: {} seeds, expected at least 3",
            target.name(),
            seeds.len()
        );
        for seed in seeds {
            let data = std::fs::read(&seed).unwrap();
            let name = seed.file_name().unwrap().to_string_lossy().into_owned();
            let result = fixture.run(target, &data);
            match (must_refuse(target, &name), result) {
                (false, Err(e)) => wrong.push(format!("{}/{name}: refused: {e}", target.name())),
                (true, Ok(())) => wrong.push(format!("{}/{name}: loaded", target.name())),
                _ => {}
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn texture_seeds_cover_every_extension() {
    let seeds = files(&repo("fuzz/corpus/texture"));
    for (i, ext) in harness::TEXTURE_EXTENSIONS.iter().enumerate() {
        let count = (seeds.iter())
            .filter(|p| {
                std::fs::read(p)
                    .unwrap()
                    .first()
                    .map(|&b| b as usize % harness::TEXTURE_EXTENSIONS.len())
                    == Some(i)
            })
            .count();
        assert!(count >= 1, "no texture seed for .{ext}");
    }
}

/// Every input in `fuzz/regressions/TARGET/`: what the fuzzer found (or
/// the case it stands for), with the part of the message lancer now gives.
const REGRESSIONS: &[(&str, &str, &str)] = &[
    // A 618-byte EXR whose data window claims 8323076 x 4 pixels: decoding
    // it took 4 s and 650 MB (AFL's 1 GiB limit aborted it) before lancer
    // checked the size.
    (
        "texture",
        "exr_huge_data_window",
        "fuzz.exr is 8323076 x 4 = 33292304 texels; lancer reads textures of at most \
         16777216 texels (4096 x 4096): downscale it",
    ),
    // A 617-byte EXR of 28 x 28 pixels in tiles of 16843067 x 16843066:
    // the decoder reserved the 1.9 GB its one chunk claimed (AFL's 1 GiB
    // limit aborted it), since a chunk may hold as much as a whole tile.
    (
        "texture",
        "exr_tile_of_2e14_pixels",
        "its tile of 16843067 x 16843066 pixels with 4 channels holds",
    ),
    // A PNG header claiming 100000 x 100000: refused from the header alone.
    (
        "texture",
        "png_header_1e10_texels",
        "fuzz.png is 100000 x 100000 = 10000000000 texels; lancer reads textures of at \
         most 16777216 texels (4096 x 4096): downscale it",
    ),
];

#[test]
fn every_fuzz_finding_is_refused_with_its_message() {
    let fixture = fixture();
    let mut listed = Vec::new();
    let mut wrong = Vec::new();
    for &(target, name, expected) in REGRESSIONS {
        let target = Target::from_name(target).unwrap();
        let path = repo("fuzz/regressions").join(target.name()).join(name);
        listed.push(path.clone());
        let data = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        match fixture.run(target, &data) {
            Err(message) if message.contains(expected) => {}
            other => wrong.push(format!(
                "{}: got {other:?}\nexpected: {expected}",
                path.display()
            )),
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    // Every committed finding is listed above.
    for target in Target::ALL {
        let dir = repo("fuzz/regressions").join(target.name());
        if dir.is_dir() {
            for path in files(&dir) {
                assert!(
                    listed.contains(&path),
                    "{} is not in REGRESSIONS",
                    path.display()
                );
            }
        }
    }
}

/// The `film`, `ply` and `serialized` seeds that must be refused, each with the message
/// lancer gives (`{dir}`: the fixture's scratch folder).
const REFUSED_SEEDS: &[(&str, &str, &str)] = &[
    (
        "film",
        "bad_half_of_2spp.film",
        "samples 1..2 are missing: no part holds them (the parts must cover 0..2)",
    ),
    (
        "film",
        "bad_nan_sum.film",
        "{dir}/fuzz.film: not a usable film file: pixel (1, 0): the radiance sum of G is NaN; \
         a sum must be finite: the file is damaged; render the part again",
    ),
    (
        "film",
        "bad_negative_square.film",
        "{dir}/fuzz.film: not a usable film file: pixel (0, 1): the sum of squares of G is -1; \
         a sum of squares must be finite and >= 0: the file is damaged; render the part again",
    ),
    (
        "film",
        "bad_truncated.film",
        "{dir}/fuzz.film: not a usable film file: it is 300 bytes, but a 4x3 film is 920: \
         truncated or damaged",
    ),
    (
        "film",
        "bad_wrapping_header.film",
        "{dir}/fuzz.film: not a usable film file: its header claims a width of 1073741824 \
         pixels; a film is at most 1048576 pixels wide (lancer's image limit): the header is \
         damaged; render the part again",
    ),
    (
        "ply",
        "bad_count.ply",
        "{dir}/ply.xml:8: <string name=\"filename\">: attribute `value`: PLY file \
         {dir}/fuzz.ply: its header declares 100000000 `face` elements of at least 2 bytes \
         each, but only 8 bytes are left for them after the header and the elements before \
         them: the file is truncated, or its header is wrong",
    ),
    (
        "ply",
        "bad_index.ply",
        "{dir}/ply.xml:8: <string name=\"filename\">: attribute `value`: PLY file \
         {dir}/fuzz.ply: face 0 names vertex 7, but there are 3",
    ),
    (
        "ply",
        "bad_junk_elements.ply",
        "{dir}/ply.xml:8: <string name=\"filename\">: attribute `value`: PLY file \
         {dir}/fuzz.ply: its header declares 4000000000 `junk` elements; lancer reads at most \
         268435456 of an element (docs/mitsuba.md): remove the element, or split the mesh",
    ),
    (
        "ply",
        "bad_list_count.ply",
        "{dir}/ply.xml:8: <string name=\"filename\">: attribute `value`: PLY file \
         {dir}/fuzz.ply: `face` 0: its `vertex_indices` list claims 250 values of 4 bytes, but \
         only 101 bytes are left in the file: the file is truncated or damaged",
    ),
    (
        "ply",
        "bad_not_ply.ply",
        "{dir}/ply.xml:8: <string name=\"filename\">: attribute `value`: PLY file \
         {dir}/fuzz.ply: it does not start with a line `ply`: not a PLY file",
    ),
    (
        "serialized",
        "bad_counts.serialized",
        "{dir}/serialized_0.xml:8: <string name=\"filename\">: attribute `value`: serialized \
         file {dir}/fuzz.serialized: mesh 0: it declares 134217728 vertices and 80 triangles, \
         1610613696 bytes of data, more than the 392 compressed bytes after its header can \
         hold (at most 1032 times as many): the file is truncated, or its counts are wrong",
    ),
    (
        "serialized",
        "bad_format.serialized",
        "{dir}/serialized_0.xml:8: <string name=\"filename\">: attribute `value`: serialized \
         file {dir}/fuzz.serialized: it starts with 0x4b50, not the format id 0x041c of a \
         Mitsuba serialized mesh: not a serialized file",
    ),
    (
        "serialized",
        "bad_index.serialized",
        "{dir}/serialized_3.xml:8: <string name=\"filename\">: attribute `value`: serialized \
         file {dir}/fuzz.serialized: shape_index 3 is out of range: its end-of-file table \
         lists 3 meshes (shape_index 0 to 2)",
    ),
    (
        "serialized",
        "bad_truncated.serialized",
        "{dir}/serialized_0.xml:8: <string name=\"filename\">: attribute `value`: serialized \
         file {dir}/fuzz.serialized: mesh 0: its compressed stream ends inside its flags: the \
         file is truncated, or its counts are wrong",
    ),
    (
        "serialized",
        "bad_vertex_index.serialized",
        "{dir}/serialized_0.xml:8: <string name=\"filename\">: attribute `value`: serialized \
         file {dir}/fuzz.serialized: mesh 0: triangle 5 names vertex 99, but the mesh has 42 \
         vertices",
    ),
];

#[test]
fn film_ply_and_serialized_seeds_are_refused_with_their_messages() {
    let fixture = fixture();
    let dir = fixture.dir().display().to_string();
    let mut wrong = Vec::new();
    for &(target, name, expected) in REFUSED_SEEDS {
        let path = repo("fuzz/corpus").join(target).join(name);
        let data = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let expected = expected.replace("{dir}", &dir);
        let got = fixture.run(Target::from_name(target).unwrap(), &data);
        if got.as_ref() != Err(&expected) {
            wrong.push(format!(
                "{target}/{name}: got {got:?}\nexpected: {expected}"
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}
