#!/usr/bin/env bash
# Wavefront against megakernel (`--schedule`), the same image both ways:
# each scene at 256x256, 64 spp, max depth 8, as whole processes,
# alternating A B A B. Prints every run, the medians and the megakernel's
# speed relative to the wavefront. Figures only; asserts nothing.
#
#   bench/schedules.sh [RUNS] [-- extra lancer args]
#
# RUNS defaults to 3 (pairs). Environment:
#   SCENES            scene files (default "scenes/cornell.toml scenes/glass.toml")
#   WIDTH HEIGHT SPP MAX_DEPTH   settings (default 256 256 64 8)
#   LANCER_BENCH_LOCK a lock file each run holds (flock), for shared machines
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
runs="${1:-3}"
shift || true
[ "${1:-}" = "--" ] && shift
scenes="${SCENES:-$root/scenes/cornell.toml $root/scenes/glass.toml}"
width="${WIDTH:-256}" height="${HEIGHT:-256}" spp="${SPP:-64}" depth="${MAX_DEPTH:-8}"
# shellcheck source=bench/lib.sh
. "$root/bench/lib.sh"
build_lancer "$root"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# Wall seconds of one render, whole process, timed inside the lock
render_seconds() {
    locked /usr/bin/time -f %e -o "$tmp/time" "$lancer" render "$1" --width "$width" \
        --height "$height" --spp "$spp" --max-depth "$depth" --schedule "$2" -q \
        --out "$tmp/$2.png" "${@:3}" > /dev/null
    cat "$tmp/time"
}

"$lancer" info "${scenes%% *}" 2>/dev/null | sed -n 's/^device: /device: /p'
echo "${width}x${height}, $spp spp, max depth $depth; $runs pairs per scene, whole process"
for scene in $scenes; do
    wave=() mega=()
    for i in $(seq 1 "$runs"); do
        a=$(render_seconds "$scene" wavefront "$@")
        b=$(render_seconds "$scene" megakernel "$@")
        wave+=("$a") mega+=("$b")
        printf '%s run %d: wavefront %.2f s   megakernel %.2f s\n' "$(basename "$scene")" "$i" "$a" "$b"
    done
    ma=$(median "${wave[@]}")
    mb=$(median "${mega[@]}")
    printf '%s median: wavefront %.2f s   megakernel %.2f s   megakernel speed %.2fx the wavefront\n' \
        "$(basename "$scene")" "$ma" "$mb" "$(echo "$ma / $mb" | bc -l)"
done
