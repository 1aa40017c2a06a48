#!/usr/bin/env bash
# Prepares a machine to build and run lancer. Sourced by scripts/render.sh and
# scripts/test.sh, which then call `lancer_setup`:
#
#   source scripts/setup.sh
#   lancer_setup                # system packages, Rust, shared target dir
#   lancer_setup --validation   # the same plus the Khronos validation layer
#
# LANCER_SETUP_VALIDATION=1 has the same effect as --validation. Run directly
# (`scripts/setup.sh [--validation]`) it only installs; exports then do not
# reach the calling shell.
#
# Idempotent: on a machine that has everything it installs nothing. On Debian
# (bookworm) it installs missing packages with apt-get, as root or via sudo.
# If cargo is missing, or its Rust is older than lancer needs, it installs
# rustup's minimal stable toolchain into ~/.cargo.
#
# It exports CARGO_TARGET_DIR (default ~/.cache/lancer/target) so that later
# runs on the same machine, even from a fresh clone, reuse the ~10 minute
# shaderc build.
set -euo pipefail

# Oldest Rust that builds the locked dependencies (image 0.25 needs 1.88).
LANCER_MIN_RUST_MINOR=88

lancer_log() {
    printf 'setup: %s\n' "$*"
}

# Prints the minor version of the rustc on PATH, or nothing (no rustc, or a
# rustup proxy without a toolchain). Never fails.
lancer_rust_minor() {
    local version
    version="$(rustc --version 2>/dev/null)" || return 0
    printf '%s\n' "$version" | sed -n 's/^rustc 1\.\([0-9][0-9]*\)\..*/\1/p'
}

lancer_setup() {
    local validation="${LANCER_SETUP_VALIDATION:-0}"
    local arg
    for arg in "$@"; do
        case "$arg" in
            --validation) validation=1 ;;
            *)
                lancer_log "unknown argument: $arg (expected --validation)"
                return 2
                ;;
        esac
    done

    # Rust that may already be installed under ~/.cargo but not on PATH.
    local cargo_env="${CARGO_HOME:-$HOME/.cargo}/env"
    if ! command -v cargo >/dev/null 2>&1 && [ -f "$cargo_env" ]; then
        # shellcheck disable=SC1090
        . "$cargo_env"
    fi
    local need_rustup=0
    if ! command -v cargo >/dev/null 2>&1; then
        need_rustup=1
    else
        local minor
        minor="$(lancer_rust_minor)"
        if [ -z "$minor" ] || [ "$minor" -lt "$LANCER_MIN_RUST_MINOR" ]; then
            need_rustup=1
        fi
    fi

    # System packages: the Vulkan loader and lavapipe, and what the shaderc
    # build from source needs (cmake, make, a C++ compiler, python3).
    local wanted=(mesa-vulkan-drivers libvulkan1 cmake make python3 g++ pkg-config git)
    if [ "$validation" = 1 ]; then
        wanted+=(vulkan-validationlayers)
    fi
    if [ "$need_rustup" = 1 ] && ! command -v rustup >/dev/null 2>&1; then
        wanted+=(curl ca-certificates)
    fi
    if command -v dpkg >/dev/null 2>&1; then
        local missing=() pkg status
        for pkg in "${wanted[@]}"; do
            # Captured, not piped into grep -q: with pipefail an early grep
            # exit would fail the pipeline through SIGPIPE.
            status="$(dpkg -s "$pkg" 2>/dev/null)" || status=""
            case "$status" in
                *"Status: install ok installed"*) ;;
                *) missing+=("$pkg") ;;
            esac
        done
        if [ "${#missing[@]}" -eq 0 ]; then
            lancer_log "system packages present: ${wanted[*]}"
        else
            local sudo=()
            if [ "$(id -u)" -ne 0 ]; then
                if command -v sudo >/dev/null 2>&1; then
                    sudo=(sudo)
                else
                    lancer_log "need root or sudo to install: ${missing[*]}"
                    return 1
                fi
            fi
            lancer_log "installing system packages: ${missing[*]}"
            "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
            "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive \
                apt-get install -y -q --no-install-recommends "${missing[@]}"
        fi
    else
        lancer_log "no dpkg: not a Debian system; make sure these are installed: ${wanted[*]}"
    fi

    # Rust.
    if [ "$need_rustup" = 1 ]; then
        if command -v rustup >/dev/null 2>&1; then
            lancer_log "updating Rust with rustup (need 1.$LANCER_MIN_RUST_MINOR or later)"
            rustup toolchain install stable --profile minimal --no-self-update
            rustup default stable
        else
            lancer_log "installing Rust (rustup, minimal stable) into ~/.cargo"
            curl --proto '=https' --tlsv1.2 https://sh.rustup.rs -sSf |
                sh -s -- -y --profile minimal --default-toolchain stable
        fi
        if [ -f "$cargo_env" ]; then
            # shellcheck disable=SC1090
            . "$cargo_env"
        fi
        local minor
        minor="$(lancer_rust_minor)"
        if [ -z "$minor" ] || [ "$minor" -lt "$LANCER_MIN_RUST_MINOR" ]; then
            lancer_log "rustc on PATH is still older than 1.$LANCER_MIN_RUST_MINOR: $(rustc --version 2>&1)"
            return 1
        fi
    fi
    lancer_log "using $(cargo --version) and $(rustc --version)"

    # A target folder outside the checkout, shared by every clone.
    export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/lancer/target}"
    mkdir -p "$CARGO_TARGET_DIR"
    lancer_log "CARGO_TARGET_DIR=$CARGO_TARGET_DIR"
}

# Run directly rather than sourced: just do the setup.
if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    lancer_setup "$@"
fi
