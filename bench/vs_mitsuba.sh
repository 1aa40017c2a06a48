#!/usr/bin/env bash
# Side by side: lancer (on the Vulkan device at hand, lavapipe on a CPU-only
# machine) against Mitsuba 3's LLVM variant (tools/mitsuba_bench.py), on the
# same scene and settings, as whole processes, alternating A B A B.
# Prints every run, the medians and the throughput ratio
# (samples/s lancer / samples/s Mitsuba). Figures only; asserts nothing.
#
#   bench/vs_mitsuba.sh [RUNS] [-- extra lancer args]
#
# RUNS defaults to 5 (pairs). Environment:
#   SCENE             scene file (default scenes/cornell.toml)
#   WIDTH HEIGHT SPP MAX_DEPTH   settings for both (default 256 256 64 8)
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
# shellcheck source=bench/lib.sh
. "$root/bench/lib.sh"
build_lancer "$root"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

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
lancer_times=() mitsuba_times=()
echo "scene $(basename "$scene"), ${width}x${height}, $spp spp, max depth $depth; $runs pairs, whole process"
"$lancer" info "$scene" 2>/dev/null | sed -n 's/^device: /lancer device: /p'
for i in $(seq 1 "$runs"); do
    a=$(timed "$lancer" render "$scene" --width "$width" --height "$height" --spp "$spp" \
        --max-depth "$depth" -q --out "$tmp/lancer.png" "$@")
    b=$(timed python3 "$root/tools/mitsuba_bench.py" "$mi_scene" 2> "$tmp/mi.log")
    lancer_times+=("$a") mitsuba_times+=("$b")
    printf 'run %d: lancer %.2f s   mitsuba %.2f s   (%s)\n' "$i" "$a" "$b" "$(tail -n1 "$tmp/mi.log")"
done

ma=$(median "${lancer_times[@]}")
mb=$(median "${mitsuba_times[@]}")
printf 'median: lancer %.2f s (%.0f samples/s)   mitsuba %.2f s (%.0f samples/s)\n' \
    "$ma" "$(echo "$samples / $ma" | bc -l)" "$mb" "$(echo "$samples / $mb" | bc -l)"
printf 'throughput ratio lancer / mitsuba: %.2fx\n' "$(echo "$mb / $ma" | bc -l)"
