#!/usr/bin/env bash
# Does specialising shade per material type pay? Renders bench/materials.toml
# (five material types) with one shade kernel for all materials, then with
# one shade dispatch per material type, alternating, and prints the shade
# pass's GPU time and the wall time of each. Prints figures; asserts nothing.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/lancer/target}"
cargo build --release --quiet --manifest-path "$root/Cargo.toml"
lancer="$CARGO_TARGET_DIR/release/lancer"
out="$(mktemp -d)"
for run in 1 2 3; do
    for mode in single per-material; do
        flag=()
        [ "$mode" = per-material ] && flag=(--shade-per-material)
        "$lancer" render "$root/bench/materials.toml" --out "$out/m.png" "${flag[@]}" \
            --stats-json "$out/s.json" -q
        python3 - "$out/s.json" "$mode" "$run" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
rows = {r["pass"]: r for r in s["passes"]}
print(f"run {sys.argv[3]} {sys.argv[2]:>12}: shade {rows['shade']['total_ms']:8.1f} ms "
      f"({rows['shade']['dispatches']} dispatches), GPU total {s['gpu_total_ms']:8.1f} ms, wall {s['wall_seconds']:.2f} s")
PY
    done
done
