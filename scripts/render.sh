#!/usr/bin/env bash
# Sets the machine up (scripts/setup.sh), builds lancer in release mode and
# runs it. With no arguments it renders the Cornell box:
#
#   scripts/render.sh        # = lancer render scenes/cornell.toml --out out/cornell.png
#
# Any arguments replace those and go to lancer as they are, e.g.
#
#   scripts/render.sh render my.toml --out my.exr
#   scripts/render.sh info scenes/cornell.toml
#
# Relative paths in the arguments are taken from the current folder.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=scripts/setup.sh
. "$root/scripts/setup.sh"
lancer_setup

if [ "$#" -eq 0 ]; then
    mkdir -p "$root/out"
    set -- render "$root/scenes/cornell.toml" --out "$root/out/cornell.png"
fi
exec cargo run --release --locked --manifest-path "$root/Cargo.toml" -- "$@"
