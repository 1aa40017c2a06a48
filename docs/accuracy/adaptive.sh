#!/bin/bash
# Adaptive sampling against uniform sampling at a target error:
# `lancer render --target-error E` with and without --adaptive, alternating
# (A B A B), RUNS seeds each, at 64x64 with the Sobol sampler, against
# Mitsuba's references (the small light against a lancer reference of
# REF_SPP spp, rendered once into $OUT). Prints each run (render seconds
# from --stats-json, whole-process seconds, mean spp, true relMSE, and the
# efficiency 1 / (relMSE x s) of each time), then per scene the medians
# and the ratios. Render alone counts the waves only; the whole process
# also counts the start, the scene's load and upload, the kernels' build,
# an adaptive render's readbacks between its rounds, and writing the image. Environment as bench/lib.sh
# (LANCER_BIN, LANCER_BENCH_LOCK), plus RUNS (default 3), OUT (default
# out/adaptive) and REF_SPP (default 16384).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
source "$root/bench/lib.sh"
build_lancer "$root"
cd "$root"
RUNS="${RUNS:-3}"
OUT="${OUT:-out/adaptive}"
REF_SPP="${REF_SPP:-16384}"
mkdir -p "$OUT"
load_report before

# The small light has no Mitsuba reference in the tree: render one
small_ref="$OUT/sphere_light_ref.exr"
if [ ! -f "$small_ref" ]; then
    locked "$lancer" render tests/scenes/sphere_light.toml --width 64 --height 64 \
        --spp "$REF_SPP" --seed 2147483648 --out "$small_ref" -q
fi

# scene file, reference, target error
cases=(
    "tests/scenes/dielectric.toml tests/reference/dielectric.exr 1e-3"
    "scenes/cornell.toml tests/reference/cornell.exr 1e-3"
    "scenes/cornell.toml tests/reference/cornell.exr 2e-4"
    "tests/scenes/dof.toml tests/reference/dof.exr 1e-4"
    "tests/scenes/sphere_light.toml $small_ref 2e-5"
)
for c in "${cases[@]}"; do
    read -r scene ref target <<<"$c"
    rows=()
    for seed in $(seq 1 "$RUNS"); do
        for mode in uniform adaptive; do
            flag=()
            [ "$mode" = adaptive ] && flag=(--adaptive)
            # Whole process in ms, timed inside the lock (a build waited for is not counted)
            whole=$(locked bash -c 't0=$(date +%s%N); "$@" || exit 1; echo $((($(date +%s%N) - t0) / 1000000))' _ \
                "$lancer" render "$scene" --width 64 --height 64 --seed "$seed" \
                --target-error "$target" --max-spp 65536 "${flag[@]}" \
                --out "$OUT/run.exr" --stats-json "$OUT/run.json" -q)
            rel=$("$lancer" compare "$OUT/run.exr" "$ref" | awk '/relMSE/ {print $2; exit}')
            row=$(python3 - "$OUT/run.json" "$rel" "$mode" "$whole" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
rel = float(sys.argv[2])
s = d["wall_seconds"]
w = float(sys.argv[4]) / 1000
print(f'{sys.argv[3]} {s:.3f} {w:.3f} {d["mean_spp"]:.1f} {rel:.4g} {1 / (rel * s):.4g} {1 / (rel * w):.4g}')
PY
)
            echo "$scene E=$target seed $seed: $row  (mode, render s, whole s, mean spp, relMSE, efficiency by render, by whole)"
            rows+=("$row")
        done
    done
    printf '%s\n' "${rows[@]}" | python3 -c "
import statistics as st, sys
rows = [l.split() for l in sys.stdin if l.strip()]
def med(mode, i):
    return st.median(float(r[i]) for r in rows if r[0] == mode)
u, a = (lambda i: med('uniform', i)), (lambda i: med('adaptive', i))
print(f'$scene E=$target medians: render {u(1):.3f} s against {a(1):.3f} s '
      f'({u(1) / a(1):.2f}x sooner), whole process {u(2):.3f} s against {a(2):.3f} s '
      f'({u(2) / a(2):.2f}x sooner), mean spp {u(3):.0f} against {a(3):.0f}, '
      f'relMSE {u(4):.3g} against {a(4):.3g}, efficiency ratio {a(5) / u(5):.2f}x by render, '
      f'{a(6) / u(6):.2f}x by whole process')
"
done
load_report after
