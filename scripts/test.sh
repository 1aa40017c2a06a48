#!/usr/bin/env bash
# Sets the machine up with the Khronos validation layer and cargo-nextest
# (scripts/setup.sh) and runs the whole test suite in release mode under the
# layer (LANCER_VALIDATION=1) with cargo-nextest: every test in a process of
# its own, as many at once as there are cores, the slow ones reported
# (.config/nextest.toml). Then it checks that the API documentation builds
# with no warning and runs a short pass of each fuzz target
# (fuzz/run.sh smoke). docs/testing.md has the time each part takes.
# The exit status is non-zero when any part failed; the last line totals
# every check. Extra arguments go to `cargo nextest run` (and skip the
# documentation and fuzz checks), e.g.
#
#   scripts/test.sh --lib output          # unit tests whose name has "output"
#   scripts/test.sh schedules::           # the tests of tests/it/schedules.rs
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=scripts/setup.sh
. "$root/scripts/setup.sh"
lancer_setup --validation

export LANCER_VALIDATION=1
cd "$root"
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
status=0
cargo nextest run --release --locked --no-fail-fast "$@" 2>&1 | tee "$log" || status=$?
# The API documentation builds with no warning (missing docs and broken
# links are denied in src/lib.rs; -D warnings catches the rest). Release
# profile, so the shaderc build is reused; counted as one more check.
if [ "$#" -eq 0 ]; then
    if cargo rustdoc --release --locked --lib -- -D warnings 2>&1 | tee -a "$log"; then
        echo "test result: ok. 1 passed; 0 failed (cargo rustdoc, no warnings)" | tee -a "$log"
    else
        echo "test result: FAILED. 0 passed; 1 failed (cargo rustdoc reported warnings)" | tee -a "$log"
        status=1
    fi
fi
# A short pass of each fuzz target under AFL (fuzz/run.sh; the corpora are
# also replayed without AFL by tests/it/fuzz_replay.rs): one check per target,
# failed by any crash or hang. LANCER_FUZZ_SECONDS sets the time per target.
if [ "$#" -eq 0 ]; then
    if ! cargo afl --version >/dev/null 2>&1; then
        echo "test result: FAILED. 0 passed; 1 failed (fuzz smoke: no cargo-afl; scripts/setup.sh --validation installs it)" | tee -a "$log"
        status=1
    elif ! fuzz/run.sh build 2>&1 | tee -a "$log"; then
        echo "test result: FAILED. 0 passed; 1 failed (fuzz smoke: the fuzz targets did not build)" | tee -a "$log"
        status=1
    elif ! fuzz/run.sh smoke "${LANCER_FUZZ_SECONDS:-20}" 2>&1 | tee -a "$log"; then
        status=1
    fi
fi
# One closing line for the whole suite: nextest's summary ("Summary [ 1s]
# 12 tests run: 11 passed, 1 failed, 0 skipped"; a test that timed out is
# a failure) plus the documentation and fuzz checks ("test result: ...").
awk '/^test result:|^ *Summary \[/ {
         for (i = 1; i <= NF; i++) {
             if ($(i+1) ~ /^passed/) p += $i
             if ($(i+1) ~ /^failed/ || $(i+1) ~ /^timed/) f += $i
         }
     }
     END { printf "%d passed, %d failed\n", p, f }' "$log"
exit "$status"
