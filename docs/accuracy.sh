#!/usr/bin/env bash
# Regenerates the figures of docs/accuracy.md with lancer's own commands:
# one convergence study per example scene, and two equal-time studies on the
# Cornell box, and the samplers at equal time on three scenes. Prints
# figures; asserts nothing. Takes ~17 minutes on
# lavapipe with 2 cores. Usage: docs/accuracy.sh [OUT_DIR]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${1:-$root/docs/accuracy}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/lancer/target}"
cargo build --release --quiet --manifest-path "$root/Cargo.toml"
lancer="$CARGO_TARGET_DIR/release/lancer"
size=(--width 64 --height 64)
mkdir -p "$out"

# Error against time for every example scene: 1 to 1024 spp against an
# 8192-spp lancer reference rendered with another seed
for scene in "$root"/scenes/*.toml; do
    name="$(basename "$scene" .toml)"
    "$lancer" converge "$scene" "${size[@]}" --max-spp 1024 --reference-spp 8192 \
        --out "$out/$name" --quiet
done

# Equal-time studies on the Cornell box, three seeds each, on the reference
# rendered above
ref="$(find "$out/cornell" -name 'reference-*.exr' ! -name '*.var.exr' | head -n 1)"
"$lancer" converge "$root/scenes/cornell.toml" "${size[@]}" --max-spp 512 \
    --reference "$ref" --seeds 3 --vary integrator=nee,bsdf --out "$out/nee-vs-bsdf" --quiet
"$lancer" converge "$root/scenes/cornell.toml" "${size[@]}" --max-spp 512 \
    --reference "$ref" --seeds 3 --vary features=scene,all --out "$out/features" --quiet

# The samplers at equal time, three seeds each, against Mitsuba's references
for pair in "scenes/cornell.toml cornell" "tests/scenes/dof.toml dof" \
    "tests/scenes/dielectric.toml dielectric"; do
    read -r scene name <<<"$pair"
    "$lancer" converge "$root/$scene" "${size[@]}" --max-spp 512 \
        --reference "$root/tests/reference/$name.exr" --seeds 3 \
        --vary sampler=independent,sobol --out "$out/sampler-$name" --quiet
done
