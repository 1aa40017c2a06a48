#!/usr/bin/env bash
# Side by side: lancer (on the Vulkan device at hand, lavapipe on a CPU-only
# machine) against Mitsuba 3's LLVM variant (tools/mitsuba_bench.py), on the
# same scene and settings, as whole processes, alternating A B A B.
# Prints every run, the medians and the throughput ratio
# (samples/s lancer / samples/s Mitsuba), for the whole process and for the
# render alone (lancer: rendering, without load, BVH build and setup;
# Mitsuba: its render call with its JIT, without imports, conversion and
# load). With REFERENCE, also the error of each image against it and the
# efficiency 1 / (relMSE x seconds). Figures only; asserts nothing.
#
#   bench/vs_mitsuba.sh [RUNS] [-- extra lancer args]
#
# RUNS defaults to 5 (pairs). Environment:
#   SCENE             scene file, or a `lancer bench` case name (cornell,
#                     glass, bumpy-1k, bumpy-1m: the generated million-triangle
#                     sphere); default scenes/cornell.toml
#   WIDTH HEIGHT SPP MAX_DEPTH   settings for both (default 256 256 64 8)
#   REFERENCE         a linear EXR of the scene at these settings (e.g.
#                     tests/reference/cornell.exr at 64x64): both write EXRs,
#                     `lancer compare` gives each one's relMSE against it
#   LANCER_BENCH_LOCK a lock file each run holds (flock), for shared machines
#   VK_ICD_FILENAMES  as usual, to pick a Vulkan driver (e.g. another lavapipe)
# Mitsuba setup: tools/README.md (libllvm19, pip install -r tools/requirements.txt).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
runs="${1:-5}"
shift || true
[ "${1:-}" = "--" ] && shift
scene="${SCENE:-$root/scenes/cornell.toml}"
width="${WIDTH:-256}" height="${HEIGHT:-256}" spp="${SPP:-64}" depth="${MAX_DEPTH:-8}"
reference="${REFERENCE:-}"
# shellcheck source=bench/lib.sh
. "$root/bench/lib.sh"
build_lancer "$root"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# A bench case name: the scene `lancer bench` writes (generated on first use)
if [ ! -f "$scene" ]; then
    case_name="$scene"
    scene="$("$lancer" bench --write-scenes | awk -v n="$case_name" '$1 == n { print $2 }')"
    [ -n "$scene" ] || { echo "SCENE=$case_name: no such file and no such lancer bench case" >&2; exit 1; }
fi
ext=png
[ -n "$reference" ] && ext=exr

# Mitsuba renders the scene at its own [render] settings: write a copy of the
# scene with ours, beside the original so relative mesh paths still resolve.
mi_scene="$(dirname "$scene")/.vs_mitsuba_$$.toml"
trap 'rm -rf "$tmp" "$mi_scene"' EXIT
python3 - "$scene" "$mi_scene" "$width" "$height" "$spp" "$depth" <<'EOF'
import sys, tomllib
src, dst, w, h, spp, depth = sys.argv[1:]
text = open(src).read()
tomllib.loads(text)  # fail early on a bad scene
out, in_render = [], False
keys = {"width": w, "height": h, "spp": spp, "max_depth": depth}
seen = set()
for line in text.splitlines():
    s = line.strip()
    if s.startswith("["):
        if in_render:
            out += [f"{k} = {v}" for k, v in keys.items() if k not in seen]
        in_render = s == "[render]"
    elif in_render and "=" in s and s.split("=")[0].strip() in keys:
        k = s.split("=")[0].strip()
        seen.add(k)
        line = f"{k} = {keys[k]}"
    out.append(line)
if in_render:
    out += [f"{k} = {v}" for k, v in keys.items() if k not in seen]
open(dst, "w").write("\n".join(out) + "\n")
EOF

# Wall seconds of one whole process, timed inside the lock (waits excluded).
timed() {
    locked /usr/bin/time -f %e -o "$tmp/time" "$@" > "$tmp/stdout"
    cat "$tmp/time"
}
samples=$((width * height * spp))
lancer_times=() mitsuba_times=() lancer_render=() mitsuba_render=()
echo "scene $scene, ${width}x${height}, $spp spp, max depth $depth; $runs pairs, whole process"
"$lancer" info "$scene" 2>/dev/null | sed -n 's/^device: /lancer device: /p'
for i in $(seq 1 "$runs"); do
    a=$(timed "$lancer" render "$scene" --width "$width" --height "$height" --spp "$spp" \
        --max-depth "$depth" -q --out "$tmp/lancer.$ext" --stats-json "$tmp/stats.json" "$@")
    b=$(timed python3 "$root/tools/mitsuba_bench.py" "$mi_scene" --out "$tmp/mitsuba.exr" 2> "$tmp/mi.log")
    ra=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["wall_seconds"])' "$tmp/stats.json")
    rb=$(sed -n 's/.*render (incl. JIT) \([0-9.]*\) s.*/\1/p' "$tmp/mi.log" | tail -n1)
    lancer_times+=("$a") mitsuba_times+=("$b") lancer_render+=("$ra") mitsuba_render+=("$rb")
    printf 'run %d: lancer %.2f s (render %.2f s)   mitsuba %.2f s   (%s)\n' "$i" "$a" "$ra" "$b" "$(tail -n1 "$tmp/mi.log")"
done

ma=$(median "${lancer_times[@]}")
mb=$(median "${mitsuba_times[@]}")
rma=$(median "${lancer_render[@]}")
rmb=$(median "${mitsuba_render[@]}")
printf 'median, whole process: lancer %.2f s (%.0f samples/s)   mitsuba %.2f s (%.0f samples/s)\n' \
    "$ma" "$(echo "$samples / $ma" | bc -l)" "$mb" "$(echo "$samples / $mb" | bc -l)"
printf 'throughput ratio lancer / mitsuba: %.2fx\n' "$(echo "$mb / $ma" | bc -l)"
printf 'median, render alone: lancer %.3f s   mitsuba %.3f s (incl. JIT)   ratio %.2fx\n' \
    "$rma" "$rmb" "$(echo "$rmb / $rma" | bc -l)"

# Efficiency at equal time: the error each renderer's image (the same seed
# every run, so the last one stands for all) leaves against the reference
if [ -n "$reference" ]; then
    relmse() {
        "$lancer" compare "$1" "$reference" --json "$tmp/compare.json" > /dev/null || true
        python3 -c 'import json, sys; print("%.12f" % json.load(open(sys.argv[1]))["metrics"]["rel_mse"])' "$tmp/compare.json"
    }
    ea=$(relmse "$tmp/lancer.exr")
    eb=$(relmse "$tmp/mitsuba.exr")
    echo "against $reference:"
    for who in lancer mitsuba; do
        if [ "$who" = lancer ]; then e=$ea t=$ma r=$rma; else e=$eb t=$mb r=$rmb; fi
        printf '  %-8s relMSE %.4e   efficiency 1/(relMSE x s): %.1f whole process, %.1f render alone\n' \
            "$who" "$e" "$(echo "1 / ($e * $t)" | bc -l)" "$(echo "1 / ($e * $r)" | bc -l)"
    done
    printf '  efficiency ratio lancer / mitsuba: %.2fx whole process, %.2fx render alone\n' \
        "$(echo "($eb * $mb) / ($ea * $ma)" | bc -l)" "$(echo "($eb * $rmb) / ($ea * $rma)" | bc -l)"
fi
