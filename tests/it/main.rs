//! lancer's integration tests, in one test binary: one link instead of one
//! per file, and one process whose tests share the Mesa shader cache's
//! warm entries and run side by side on every core (`scripts/test.sh` runs
//! them with cargo-nextest, a process per test, two at a time on two
//! cores). Each module is one subject; run one with
//! `cargo test --release --test it MODULE::` (for example `layers::`).
//!
//! `tests/texture_memory.rs` stays a binary of its own: it measures the
//! peak of its process's allocator, which no other test may share.
//! Helpers shared by the modules are in `common`.

mod common;

mod accuracy;
mod adaptive;
mod analytic;
mod bench;
mod bvh_gpu;
mod camera;
mod chi2;
mod ci;
mod cli;
mod examples;
mod faults;
mod features;
mod files;
mod fuzz_replay;
mod geometry;
mod large_geometry;
mod large_textures;
mod layers;
mod library;
mod materials;
mod mitsuba;
mod numerics;
mod realscenes;
mod reference;
mod robust_scenes;
mod sampler;
mod schedules;
mod speed;
mod split;
mod sync_validation;
mod tiles;
