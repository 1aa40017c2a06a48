//! The AFL fuzz binary: `lancer-fuzz TARGET` runs one target of the harness
//! (`scene_toml`, `scene_xml`, `obj_mtl`, `texture`, `film`, `ply` or `serialized`) in
//! AFL's persistent mode. Build it with `cargo afl build`; see
//! `fuzz/README.md`.

use lancer_fuzz::{Fixture, Target};
use std::path::Path;

fn main() {
    let name = std::env::args().nth(1).unwrap_or_default();
    let Some(target) = Target::from_name(&name) else {
        let names: Vec<&str> = Target::ALL.iter().map(|t| t.name()).collect();
        eprintln!(
            "usage: lancer-fuzz TARGET (under afl-fuzz), TARGET one of: {}",
            names.join(", ")
        );
        std::process::exit(2);
    };
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/scenes");
    let fixture = match Fixture::new(&assets) {
        Ok(fixture) => fixture,
        Err(e) => {
            eprintln!("lancer-fuzz: {e}");
            std::process::exit(1);
        }
    };
    afl::fuzz!(|data: &[u8]| {
        // Refusing an input is a pass; only a panic, abort, hang or OOM counts.
        let _ = fixture.run(target, data);
    });
}
