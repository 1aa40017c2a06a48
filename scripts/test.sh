#!/usr/bin/env bash
# Sets the machine up with the Khronos validation layer (scripts/setup.sh) and
# runs the whole test suite in release mode under it (LANCER_VALIDATION=1),
# then checks that the API documentation builds with no warning and runs a
# short pass of each fuzz target (fuzz/run.sh smoke).
# The exit status is cargo test's; the last line totals every test binary. Extra arguments go to `cargo test`, e.g.
#
#   scripts/test.sh --lib output
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
cargo test --release --locked --no-fail-fast "$@" 2>&1 | tee "$log" || status=$?
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
# also replayed without AFL by tests/fuzz_replay.rs): one check per target,
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
# One closing line for the whole suite, summed over every test binary.
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i } }
     END { printf "%d passed, %d failed\n", p, f }' "$log"
exit "$status"
