#!/usr/bin/env bash
# Builds and runs lancer's fuzz targets with cargo-afl (see fuzz/README.md).
#
#   fuzz/run.sh build                     # instrumented build of fuzz/ (lancer-fuzz)
#   fuzz/run.sh fuzz TARGET OUT [ARGS...] # afl-fuzz on TARGET, findings in OUT;
#                                         # ARGS go to afl-fuzz, e.g. -E 1000000
#   fuzz/run.sh smoke SECONDS             # every target for SECONDS each, one per core; one
#                                         # `test result:` line per target
#   fuzz/run.sh replay TARGET FILE        # one input through the instrumented binary
#
# TARGET: scene_toml, scene_xml, obj_mtl, texture, film, ply or serialized. Needs cargo-afl and its
# AFL++ runtime (scripts/setup.sh --validation installs both). Uses
# $CARGO_TARGET_DIR (default ~/.cache/lancer/target). The build names the
# host triple, so AFL's RUSTFLAGS reach only the target's crates, and its
# artifacts stay apart from the normal build's.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
targets=(scene_toml scene_xml obj_mtl texture film ply serialized)
# Limits for each run of a target: a finding is a crash (panic, abort), a
# run over the time limit, or one that needs more memory than this.
memory_mb=1024
# Milliseconds: 1 s, but 5 s for textures, where the largest texture lancer
# accepts (MAX_TEXTURE_TEXELS: 4096 x 4096, which a 618-byte EXR can claim)
# takes up to 2.2 s to decode in the instrumented build on a busy machine.
timeout_ms() {
    if [ "$1" = texture ]; then echo 5000; else echo 1000; fi
}

triple="$(rustc -vV | sed -n 's/^host: //p')"
target_dir="${CARGO_TARGET_DIR:-$HOME/.cache/lancer/target}"
binary="$target_dir/$triple/release/lancer-fuzz"

# lancer-fuzz takes lancer without its `kernels` feature, so shaderc is not
# in this build at all.
build() {
    # The folder the other commands look in, also when CARGO_TARGET_DIR is unset.
    (cd "$root" && CARGO_TARGET_DIR="$target_dir" cargo afl build --release --locked -p lancer-fuzz --target "$triple")
}

check_target() {
    local t
    for t in "${targets[@]}"; do
        [ "$t" = "$1" ] && return 0
    done
    echo "unknown target \`$1\`; one of: ${targets[*]}" >&2
    return 2
}

# fuzz TARGET OUT [ARGS...]: afl-fuzz in persistent mode from the target's corpus.
run_fuzz() {
    local target="$1" out="$2"
    shift 2
    check_target "$target"
    # No UI (logs stay readable), no CPU binding (shared machines), no
    # frequency check; a scratch folder in memory when there is one.
    local tmp="${TMPDIR:-/tmp}"
    [ -d /dev/shm ] && [ -w /dev/shm ] && tmp=/dev/shm
    TMPDIR="$tmp" AFL_NO_UI=1 AFL_NO_AFFINITY=1 AFL_SKIP_CPUFREQ=1 AFL_FAST_CAL=1 \
        AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 AFL_SUPPRESS_ANALYSIS=1 \
        cargo afl fuzz -i "$root/fuzz/corpus/$target" -o "$out" \
        -m "$memory_mb" -t "$(timeout_ms "$target")" "$@" -- "$binary" "$target"
}

# A figure from AFL's fuzzer_stats.
stat() {
    sed -n "s/^$2 *: *//p" "$1/default/fuzzer_stats"
}

# Every target for SECONDS each, as many at once as there are cores
# (LANCER_FUZZ_JOBS sets how many): afl-fuzz runs on one core.
smoke() {
    local seconds="$1" out status=0 t running=0
    local jobs="${LANCER_FUZZ_JOBS:-$(nproc)}"
    out="$(mktemp -d)"
    for t in "${targets[@]}"; do
        { run_fuzz "$t" "$out/$t" -V "$seconds" >"$out/$t.log" 2>&1 && touch "$out/$t.ran"; } &
        running=$((running + 1))
        if [ "$running" -ge "$jobs" ]; then
            wait -n || true
            running=$((running - 1))
        fi
    done
    wait || true
    for t in "${targets[@]}"; do
        if [ ! -f "$out/$t.ran" ] || [ ! -f "$out/$t/default/fuzzer_stats" ]; then
            tail -n 20 "$out/$t.log"
            echo "test result: FAILED. 0 passed; 1 failed (fuzz smoke $t: afl-fuzz did not run)"
            status=1
            continue
        fi
        local execs crashes hangs
        execs="$(stat "$out/$t" execs_done)"
        crashes="$(stat "$out/$t" saved_crashes)"
        hangs="$(stat "$out/$t" saved_hangs)"
        if [ "$crashes" = 0 ] && [ "$hangs" = 0 ] && [ "$execs" -gt 0 ]; then
            echo "test result: ok. 1 passed; 0 failed (fuzz smoke $t: $execs execs in ${seconds}s, 0 crashes, 0 hangs)"
        else
            echo "test result: FAILED. 0 passed; 1 failed (fuzz smoke $t: $execs execs, $crashes crashes, $hangs hangs; inputs kept in $out/$t/default)"
            status=1
        fi
    done
    # Keep the folder only when it holds findings.
    [ "$status" = 0 ] && rm -rf "$out"
    return "$status"
}

case "${1:-}" in
    build) build ;;
    fuzz)
        [ "$#" -ge 3 ] || { echo "usage: fuzz/run.sh fuzz TARGET OUT [AFL-ARGS...]" >&2; exit 2; }
        shift
        run_fuzz "$@"
        ;;
    smoke)
        [ "$#" -eq 2 ] || { echo "usage: fuzz/run.sh smoke SECONDS" >&2; exit 2; }
        smoke "$2"
        ;;
    replay)
        [ "$#" -eq 3 ] || { echo "usage: fuzz/run.sh replay TARGET FILE" >&2; exit 2; }
        check_target "$2"
        "$binary" "$2" <"$3"
        ;;
    *)
        sed -n '2,11p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//' >&2
        exit 2
        ;;
esac
