#!/usr/bin/env bash
# Side by side: lancer (on the Vulkan device at hand, lavapipe on a CPU-only
# machine) against Mitsuba 3's LLVM variant (tools/mitsuba_bench.py), on the
# same scene and settings, at equal work per sample: Mitsuba's Russian
# roulette starts at the same path vertex as lancer's, with the same
# survival probability (ROULETTE=same, the default; see below).
#
# Runs alternate, lancer then Mitsuba (A B A B), each inside the lock when
# LANCER_BENCH_LOCK names one. Each run is
#   A: one lancer process: whole-process wall time, and lancer's own render
#      time (--stats-json wall_seconds: the waves, without scene load, BVH
#      build, pipelines, film readback and image write)
#   B: two Mitsuba processes: one that renders once (whole-process wall
#      time; its render call, JIT included, is printed too), and one that
#      renders once untimed and times a second render with another seed,
#      its kernels compiled and cached (the render alone, as a user who
#      renders twice sees it)
# One untimed run of each comes first, so that both start with their disk
# caches warm (drjit's kernel cache, Mesa's shader cache). Prints every
# run, the medians, the render-alone ratio next to the whole-process ratio
# (Mitsuba's time / lancer's: above 1, lancer is faster), the load average
# before and after the series, the CPU time other processes took while the
# timed processes ran (/proc/stat less their own), and with REFERENCE the
# efficiency at equal time. Figures only; asserts nothing.
#
#   bench/vs_mitsuba.sh [RUNS] [-- extra lancer args]
#
# RUNS (the argument, or the variable) defaults to 5 (pairs). Environment:
#   SCENE             scene file, or a `lancer bench` case name (cornell,
#                     glass, bumpy-1k, bumpy-1m: the generated million-triangle
#                     sphere); default scenes/cornell.toml
#   WIDTH HEIGHT SPP MAX_DEPTH   settings for both (default 256 256 64 8)
#   SAMPLER           Mitsuba's sampler: independent, stratified, multijitter
#                     (default; Mitsuba's best on these scenes), orthogonal,
#                     ldsampler. One that would round SPP is refused.
#   ROULETTE          same (default): Mitsuba's rr_depth = lancer's (the
#                     scene's render.rr_depth, from lancer's --stats-json),
#                     equal work per sample;
#                     mitsuba: Mitsuba's default rr_depth 5, two vertices
#                     later than lancer, so Mitsuba does more work per sample
#   REFERENCE         a linear EXR of the scene at these WIDTH, HEIGHT and
#                     MAX_DEPTH (e.g. tests/reference/cornell.exr: 64x64,
#                     depth 8): each run's images get their relMSE against
#                     it (`lancer compare`), and the efficiency
#                     1 / (relMSE x seconds) is printed, relMSE the mean over
#                     the runs (run i renders with seed i on both sides)
#   LANCER_BIN        a lancer binary to use instead of building one
#   LANCER_BENCH_LOCK a lock file the build and each run hold (flock), for
#                     shared machines: the builds' own lock (cg uses
#                     /tmp/lancer-cargo.lock) keeps builds out of the runs
#   VK_ICD_FILENAMES  as usual, to pick a Vulkan driver (e.g. another lavapipe)
#   MITSUBA_VARIANT   Mitsuba's variant (default auto: llvm_ad_rgb where a
#                     libLLVM is found, else scalar_rgb); cuda_ad_rgb races
#                     Mitsuba's CUDA/OptiX variant on an NVIDIA GPU
# Mitsuba setup: tools/README.md (libllvm19, pip install -r tools/requirements.txt).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
runs="${RUNS:-5}"
if [ $# -gt 0 ] && [ "$1" != "--" ]; then
    runs="$1"
    shift
fi
[ "${1:-}" = "--" ] && shift
case "$runs" in
    '' | *[!0-9]* | 0) echo "RUNS=$runs: a number of runs, 1 or more" >&2; exit 1 ;;
esac
scene="${SCENE:-$root/scenes/cornell.toml}"
width="${WIDTH:-256}" height="${HEIGHT:-256}" spp="${SPP:-64}" depth="${MAX_DEPTH:-8}"
sampler="${SAMPLER:-multijitter}"
roulette="${ROULETTE:-same}"
reference="${REFERENCE:-}"
# shellcheck source=bench/lib.sh
. "$root/bench/lib.sh"

case "$roulette" in
    same | mitsuba) ;;
    *) echo "ROULETTE=$roulette: same or mitsuba" >&2; exit 1 ;;
esac

python3 -c 'import mitsuba' 2> /dev/null || {
    echo "Mitsuba 3 is not installed for $(command -v python3): see tools/README.md" >&2
    exit 1
}
build_lancer "$root"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# A bench case name: the scene `lancer bench` writes (generated on first use)
if [ ! -f "$scene" ]; then
    case_name="$scene"
    scene="$("$lancer" bench --write-scenes | awk -v n="$case_name" '$1 == n { print $2 }')"
    [ -n "$scene" ] || { echo "SCENE=$case_name: no such file and no such lancer bench case" >&2; exit 1; }
fi
if [ -n "$reference" ]; then
    [ -f "$reference" ] || { echo "REFERENCE=$reference: no such file" >&2; exit 1; }
    # The reference's own record, when it has one, must match the settings
    ref_json="${reference%.exr}.json"
    if [ -f "$ref_json" ]; then
        python3 - "$ref_json" "$width" "$height" "$depth" <<'EOF'
import json, sys
info = json.load(open(sys.argv[1]))
want = dict(zip(("width", "height", "max_depth"), map(int, sys.argv[2:])))
bad = [f"{k} {info[k]} (here {v})" for k, v in want.items() if k in info and info[k] != v]
if bad:
    sys.exit(f"REFERENCE does not match these settings: {', '.join(bad)}")
EOF
    fi
fi

lancer_args=(--width "$width" --height "$height" --spp "$spp" --max-depth "$depth" -q)

# Wall seconds of one whole process, timed inside the lock (waits
# excluded); its standard error goes to $tmp/err, shown if it fails. Each
# appends "wall, its own CPU seconds, the whole machine's busy CPU seconds
# meanwhile" (/usr/bin/time, /proc/stat) to $tmp/cpu.log: what the rest of
# the machine did during the timed processes.
timed() {
    # shellcheck disable=SC2016
    if ! locked bash -c '
        busy() { awk "/^cpu / { print \$2 + \$3 + \$4 + \$7 + \$8 + \$9 }" /proc/stat; }
        b0=$(busy)
        /usr/bin/time -f "%e %U %S" -o "$0" "$@"
        rc=$?
        echo "$b0 $(busy)" > "$0.stat"
        exit $rc' "$tmp/time" "$@" > "$tmp/stdout" 2> "$tmp/err"; then
        echo "failed: $*" >&2
        cat "$tmp/err" >&2
        return 1
    fi
    local wall user sys b0 b1
    read -r wall user sys < "$tmp/time"
    read -r b0 b1 < "$tmp/time.stat"
    echo "$wall $user $sys $((b1 - b0))" >> "$tmp/cpu.log"
    echo "$wall"
}
# What other processes took of the machine during the timed processes
# since the last `: > $tmp/cpu.log`
others_report() {
    awk -v hz="$(getconf CLK_TCK)" -v cores="$(nproc)" '
        { wall += $1; own += $2 + $3; busy += $4 / hz }
        END {
            other = busy - own; if (other < 0) other = 0
            share = wall > 0 ? 100 * other / (wall * cores) : 0
            printf "during the %.1f s of timed processes, they used %.1f CPU-s; other processes %.1f CPU-s, %.1f%% of the %d cores\n", wall, own, other, share, cores
            if (share > 5) printf "WARNING: other processes took more than 5%% of the machine during the timed runs: not a quiet machine\n"
        }' "$tmp/cpu.log"
}
# A figure from a JSON file: json FILE EXPRESSION (d is the document)
json() { python3 -c 'import json, sys; d = json.load(open(sys.argv[1])); print(eval(sys.argv[2]))' "$1" "$2"; }
relmse() {
    "$lancer" compare "$1" "$reference" --json "$tmp/compare.json" > /dev/null || true
    json "$tmp/compare.json" '"%.6e" % d["metrics"]["rel_mse"]'
}

# The settings and the rule each side follows
strata=$(awk -v n="$spp" 'BEGIN { s = int(sqrt(n) + 0.5); print (s * s == n) ? s : 0 }')
echo "scene $scene, ${width}x${height}, $spp spp, max depth $depth; $runs runs (A B: lancer, then Mitsuba)"
"$lancer" info "$scene" 2>/dev/null | sed -n 's/^device: /lancer device: /p'

# Untimed warm-up of both: disk caches, and the settings checked once
timed "$lancer" render "$scene" "${lancer_args[@]}" --seed 0 --out "$tmp/warm.exr" \
    --stats-json "$tmp/stats.json" "$@" > /dev/null
# lancer's roulette, the scene's render.rr_depth (its own stats), and Mitsuba's
lancer_rr=$(json "$tmp/stats.json" 'd["rr_depth"]')
case "$roulette" in
    same) mi_rr="$lancer_rr" ;;
    mitsuba) mi_rr=5 ;;
esac
mi_args=(--width "$width" --height "$height" --spp "$spp" --max-depth "$depth"
    --rr-depth "$mi_rr" --sampler "$sampler" --variant "${MITSUBA_VARIANT:-auto}")
echo "lancer roulette: from the hit that ends segment $lancer_rr (camera ray = segment 1; the scene's rr_depth) on, survival min(max(throughput) * (ior^2 if the new ray goes into a dielectric, else 1), 0.95) (shaders/common/path.glsl)"
segments() { json "$1" '"%.4f" % (sum(b["rays"].get("intersect", 0) for b in d["rays_per_bounce"]) / d["samples"])'; }
lancer_segments=$(segments "$tmp/stats.json")
if [ "$(json "$tmp/stats.json" 'len(d["rays_per_bounce"])')" = 0 ]; then
    # The megakernel counts no rays. It traces the same paths as the
    # wavefront (the images are bit-identical), so count them there.
    counting=()
    drop=0
    for a in "$@"; do
        if [ "$drop" = 1 ]; then drop=0; continue; fi
        case "$a" in
            --schedule) drop=1 ;;
            --schedule=*) ;;
            *) counting+=("$a") ;;
        esac
    done
    "$lancer" render "$scene" "${lancer_args[@]}" --seed 0 --out "$tmp/count.exr" \
        --stats-json "$tmp/count.json" "${counting[@]}" --schedule wavefront > /dev/null
    lancer_segments=$(segments "$tmp/count.json")
    echo "lancer's schedule counts no rays: its path segments are counted by the wavefront schedule, which traces the same paths"
fi
lancer_sampler=$(json "$tmp/stats.json" 'd["sampler"]')
case "$lancer_sampler" in
    sobol) echo "lancer sampler: sobol (shuffled, Owen-scrambled Sobol (0,2) pairs, one sequence per pixel in a fixed-spp render, some pairs partnered as 4D points; shaders/common/sampler.glsl)" ;;
    independent)
        if [ "$strata" -gt 0 ]; then
            echo "lancer sampler: independent (hashed random numbers), the pixel position stratified on a ${strata}x${strata} grid"
        else
            echo "lancer sampler: independent (hashed random numbers), no strata ($spp spp is not a square)"
        fi ;;
    *) echo "lancer sampler: $lancer_sampler" ;;
esac
timed python3 "$root/tools/mitsuba_bench.py" "$scene" "${mi_args[@]}" --seed 0 --json "$tmp/mi.json" > /dev/null
sed -n 's/^\(llvm\|scalar\|cuda\)/mitsuba: \1/p' "$tmp/err"
if [ "$mi_rr" = "$lancer_rr" ]; then
    echo "equal work per sample: both roulettes start at the hit that ends segment $lancer_rr, with the same survival probability"
else
    echo "NOT equal work: Mitsuba's roulette starts at segment $mi_rr, lancer's at $lancer_rr; the one that starts later traces more segments per sample"
fi
# The work, counted: lancer's rays per sample (its own counters) and the
# rays a path traces under Mitsuba's stopping rules (tools/mitsuba_work.py)
work_spp=$((spp < 16 ? spp : 16))
if python3 "$root/tools/mitsuba_work.py" "$scene" --rr-depth "$mi_rr" --width "$width" --height "$height" \
    --spp "$work_spp" --max-depth "$depth" > "$tmp/work" 2> "$tmp/err"; then
    mi_segments=$(sed -n 's/.*: \([0-9.]*\) path segments per sample.*/\1/p' "$tmp/work")
    printf 'work per sample: lancer %.3f path segments (its counters, seed 0)   Mitsuba'"'"'s rules at rr_depth %s: %.3f (tools/mitsuba_work.py, %d spp)\n' \
        "$lancer_segments" "$mi_rr" "$mi_segments" "$work_spp"
    if awk -v a="$lancer_segments" -v b="$mi_segments" 'BEGIN { d = a / b - 1; exit !(d > 0.03 || d < -0.03) }'; then
        echo "WARNING: the two differ by more than 3%: not equal work per sample"
    fi
else
    printf 'work per sample: lancer %.3f path segments; Mitsuba'"'"'s not counted (tools/mitsuba_work.py failed: %s)\n' \
        "$lancer_segments" "$(tail -n1 "$tmp/err")"
fi
echo "warm-up: one untimed run of each done"

load_report "before the series"
: > "$tmp/cpu.log"
lancer_times=() lancer_render=() mitsuba_times=() mitsuba_first=() mitsuba_render=()
lancer_err=() mitsuba_err=()
samples=$((width * height * spp))
for i in $(seq 1 "$runs"); do
    a=$(timed "$lancer" render "$scene" "${lancer_args[@]}" --seed "$i" \
        --out "$tmp/lancer.exr" --stats-json "$tmp/stats.json" "$@")
    ra=$(json "$tmp/stats.json" 'd["wall_seconds"]')
    b=$(timed python3 "$root/tools/mitsuba_bench.py" "$scene" "${mi_args[@]}" --seed "$i" \
        --out "$tmp/mitsuba_once.exr" --json "$tmp/mi_once.json")
    rb1=$(json "$tmp/mi_once.json" 'd["seconds_render"]')
    timed python3 "$root/tools/mitsuba_bench.py" "$scene" "${mi_args[@]}" --seed "$i" --warm \
        --out "$tmp/mitsuba.exr" --json "$tmp/mi_warm.json" > /dev/null
    rb=$(json "$tmp/mi_warm.json" 'd["seconds_render"]')
    lancer_times+=("$a") lancer_render+=("$ra") mitsuba_times+=("$b") mitsuba_first+=("$rb1") mitsuba_render+=("$rb")
    line=$(printf 'run %d: lancer %.2f s (render %.3f s)   mitsuba %.2f s (render incl. JIT %.3f s)   mitsuba render, kernels warm %.3f s' \
        "$i" "$a" "$ra" "$b" "$rb1" "$rb")
    if [ -n "$reference" ]; then
        ea=$(relmse "$tmp/lancer.exr")
        eb=$(relmse "$tmp/mitsuba.exr")
        lancer_err+=("$ea") mitsuba_err+=("$eb")
        line="$line   relMSE lancer $ea mitsuba $eb"
    fi
    echo "$line"
done
load_report "after the series; its own renders count in it"
others_report

ma=$(median "${lancer_times[@]}") mb=$(median "${mitsuba_times[@]}")
rma=$(median "${lancer_render[@]}") rmb=$(median "${mitsuba_render[@]}")
rmb1=$(median "${mitsuba_first[@]}")
# Arithmetic on figures that may be written 1.5e-03 (bc reads no exponents)
calc() { awk "BEGIN { printf \"%.10g\", $1 }"; }
ratio() { calc "$1 / $2"; }
echo "medians of $runs runs (ratio = Mitsuba's time / lancer's: above 1, lancer is faster):"
printf '  render alone:   lancer %.3f s (%.0f samples/s)   mitsuba %.3f s, kernels warm (%.0f samples/s)   ratio %.2fx\n' \
    "$rma" "$(ratio "$samples" "$rma")" "$rmb" "$(ratio "$samples" "$rmb")" "$(ratio "$rmb" "$rma")"
printf '  whole process:  lancer %.2f s (%.0f samples/s)   mitsuba %.2f s (%.0f samples/s)   ratio %.2fx\n' \
    "$ma" "$(ratio "$samples" "$ma")" "$mb" "$(ratio "$samples" "$mb")" "$(ratio "$mb" "$ma")"
printf '  (Mitsuba'"'"'s render call in the one-render process, JIT or kernel-cache load included: %.3f s)\n' "$rmb1"

# Efficiency at equal time: 1 / (relMSE x seconds), relMSE the mean over
# the runs' images (seeds 1..RUNS on both sides)
if [ -n "$reference" ]; then
    mean() { printf '%s\n' "$@" | awk '{ s += $1 } END { printf "%.6e", s / NR }'; }
    ea=$(mean "${lancer_err[@]}") eb=$(mean "${mitsuba_err[@]}")
    echo "efficiency at equal time, 1 / (relMSE x s), against $reference (Mitsuba's sampler: $sampler):"
    printf '  lancer   relMSE %.4e (mean of %d)   %.1f render alone   %.1f whole process\n' \
        "$ea" "$runs" "$(calc "1 / ($ea * $rma)")" "$(calc "1 / ($ea * $ma)")"
    printf '  mitsuba  relMSE %.4e (mean of %d)   %.1f render alone   %.1f whole process\n' \
        "$eb" "$runs" "$(calc "1 / ($eb * $rmb)")" "$(calc "1 / ($eb * $mb)")"
    printf '  ratio lancer / mitsuba: %.2fx render alone, %.2fx whole process\n' \
        "$(calc "($eb * $rmb) / ($ea * $rma)")" "$(calc "($eb * $mb) / ($ea * $ma)")"
fi
