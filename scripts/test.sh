#!/usr/bin/env bash
# Sets the machine up with the Khronos validation layer (scripts/setup.sh) and
# runs the whole test suite in release mode under it (LANCER_VALIDATION=1).
# The exit status is cargo test's. Extra arguments go to `cargo test`, e.g.
#
#   scripts/test.sh --lib output
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=scripts/setup.sh
. "$root/scripts/setup.sh"
lancer_setup --validation

export LANCER_VALIDATION=1
cd "$root"
exec cargo test --release --locked "$@" 2>&1
