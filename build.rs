//! Compiles every `shaders/*.comp` to SPIR-V with shaderc (glslang), with
//! the `kernels` feature (on by default); without it, writes empty files.
//!
//! Each constant in `src/shader_interface.rs` reaches GLSL as a macro, and
//! `#include "common/x.glsl"` resolves under `shaders/`. A GLSL error fails
//! the build with glslang's message, file and line.
//!
//! It also sets `LANCER_GIT_COMMIT` for `lancer --version`: the commit the
//! build was made from, or `unknown commit` outside a git checkout.

use std::path::{Path, PathBuf};

#[allow(dead_code)]
#[path = "src/shader_interface.rs"]
mod shader_interface;

fn main() {
    let manifest =
        PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let shader_dir = manifest.join("shaders");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo:rerun-if-changed=src/shader_interface.rs");
    println!(
        "cargo:rustc-env=LANCER_GIT_COMMIT={}",
        git_commit(&manifest)
    );
    println!("cargo:rerun-if-changed=shaders");
    compile_kernels(&shader_dir, &out_dir);
}

/// Without the `kernels` feature: an empty file per kernel, which
/// `src/shaders.rs` includes and the renderer refuses.
#[cfg(not(feature = "kernels"))]
fn compile_kernels(shader_dir: &Path, out_dir: &Path) {
    for path in kernel_sources(shader_dir) {
        let stem = path.file_stem().unwrap().to_string_lossy();
        std::fs::write(out_dir.join(format!("{stem}.spv")), b"").expect("write SPIR-V");
    }
}

/// Every `shaders/*.comp`, sorted.
fn kernel_sources(shader_dir: &Path) -> Vec<PathBuf> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(shader_dir)
        .expect("shaders/ folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "comp"))
        .collect();
    entries.sort();
    entries
}

/// Compiles each kernel to `OUT_DIR/NAME.spv`; a GLSL error fails the build.
#[cfg(feature = "kernels")]
fn compile_kernels(shader_dir: &Path, out_dir: &Path) {
    let compiler = shaderc::Compiler::new().expect("shaderc compiler");
    let mut failures = Vec::new();
    for path in &kernel_sources(shader_dir) {
        println!("cargo:rerun-if-changed={}", path.display());
        let source = std::fs::read_to_string(path).expect("read shader");
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let options = compile_options(shader_dir);
        match compiler.compile_into_spirv(
            &source,
            shaderc::ShaderKind::Compute,
            &format!("shaders/{name}"),
            "main",
            Some(&options),
        ) {
            Ok(artifact) => {
                let stem = path.file_stem().unwrap().to_string_lossy();
                std::fs::write(out_dir.join(format!("{stem}.spv")), artifact.as_binary_u8())
                    .expect("write SPIR-V");
            }
            Err(err) => failures.push(err.to_string()),
        }
    }
    if !failures.is_empty() {
        for f in &failures {
            // cargo shows build-script stderr when the build fails.
            eprintln!("{f}");
        }
        panic!("GLSL compilation failed:\n{}", failures.join("\n"));
    }
}

/// Options shared by every kernel: Vulkan 1.2, optimised, macros, includes.
#[cfg(feature = "kernels")]
fn compile_options(shader_dir: &Path) -> shaderc::CompileOptions<'static> {
    let mut options = shaderc::CompileOptions::new().expect("shaderc options");
    options.set_target_env(
        shaderc::TargetEnv::Vulkan,
        shaderc::EnvVersion::Vulkan1_2 as u32,
    );
    options.set_target_spirv(shaderc::SpirvVersion::V1_5);
    options.set_optimization_level(shaderc::OptimizationLevel::Performance);
    options.set_generate_debug_info();
    for (name, value) in shader_interface::SHADER_DEFINES {
        // Layout qualifiers need plain integer literals; only values past
        // i32::MAX need the unsigned suffix.
        let literal = if *value > i32::MAX as u32 {
            format!("{value}u")
        } else {
            value.to_string()
        };
        options.add_macro_definition(name, Some(&literal));
    }
    let root = shader_dir.to_path_buf();
    options.set_include_callback(move |requested, _kind, requester, _depth| {
        let path = root.join(requested);
        let content = std::fs::read_to_string(&path).map_err(|e| {
            format!(
                "{requester}: cannot include \"{requested}\" ({}): {e}",
                path.display()
            )
        })?;
        println!("cargo:rerun-if-changed={}", path.display());
        Ok(shaderc::ResolvedInclude {
            resolved_name: format!("shaders/{requested}"),
            content,
        })
    });
    options
}

/// `commit 1a2b3c4d5e6f` for the checkout at `dir`, or `unknown commit`
/// when it is not one (a source tarball, `cargo install` from a registry)
/// or git is missing. `LANCER_GIT_COMMIT` in the environment overrides it,
/// for packagers who build outside the checkout.
fn git_commit(dir: &Path) -> String {
    println!("cargo:rerun-if-env-changed=LANCER_GIT_COMMIT");
    if let Ok(given) = std::env::var("LANCER_GIT_COMMIT") {
        return format!("commit {given}");
    }
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .current_dir(dir)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    // Only this crate's own checkout counts, not a repository that happens
    // to hold an unpacked source tarball
    let top = git(&["rev-parse", "--show-toplevel"]).map(std::path::PathBuf::from);
    let own = top.and_then(|t| t.canonicalize().ok()) == dir.canonicalize().ok();
    let commit = git(&["rev-parse", "--short=12", "HEAD"]).filter(|_| own);
    let Some(commit) = commit else {
        return String::from("unknown commit");
    };
    // Build again when HEAD moves: HEAD itself, and the branch it names.
    // (A path that does not exist would make cargo run this every build.)
    let branch = git(&["symbolic-ref", "-q", "HEAD"]);
    for file in ["HEAD", "packed-refs"].into_iter().chain(branch.as_deref()) {
        if let Some(path) = git(&["rev-parse", "--git-path", file]) {
            let path = dir.join(path);
            if path.exists() {
                println!("cargo:rerun-if-changed={}", path.display());
            }
        }
    }
    format!("commit {commit}")
}
