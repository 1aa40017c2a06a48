#!/usr/bin/env bash
# Speed benchmark: the Cornell box at 256x256, 64 spp, max depth
# 8, timed as a whole process (3 runs), with lancer's per-pass table.
# Prints figures; asserts nothing. Usage: bench/cornell.sh [extra lancer args]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/lancer/target}"
cargo build --release --quiet --manifest-path "$root/Cargo.toml"
lancer="$CARGO_TARGET_DIR/release/lancer"
out="$(mktemp -d)"
for run in 1 2 3; do
    start=$(date +%s.%N)
    "$lancer" render "$root/scenes/cornell.toml" --width 256 --height 256 --spp 64 --max-depth 8 \
        --out "$out/cornell.png" --stats-json "$out/stats$run.json" "$@" > "$out/table$run.txt"
    end=$(date +%s.%N)
    echo "run $run: $(echo "$end - $start" | bc) s whole process"
done
cat "$out/table3.txt"
