#!/usr/bin/env bash
# Prepares a machine to build and run lancer. Sourced by scripts/render.sh and
# scripts/test.sh, which then call `lancer_setup`:
#
#   source scripts/setup.sh
#   lancer_setup                # system packages, Rust, shared target dir
#   lancer_setup --validation   # the same plus what the tests need: the Khronos
#                               # validation layer, cargo-nextest (crates.io,
#                               # unless present), check-jsonschema (PyPI) and
#                               # cargo-afl with its AFL++ build (crates.io), for
#                               # the fuzz smoke pass
#
# LANCER_SETUP_VALIDATION=1 has the same effect as --validation.
# LANCER_SLURM=1 also installs Slurm and munge (slurm-wlm, munge) for the
# opt-in one-node cluster test, tests/slurm.sh. Run directly
# (`scripts/setup.sh [--validation]`) it only installs; exports then do not
# reach the calling shell.
#
# Idempotent: on a machine that has everything it installs nothing. On Debian
# (bookworm) it installs missing packages with apt-get, as root or via sudo.
# If cargo is missing, or its Rust is older than lancer needs, it installs
# rustup's minimal stable toolchain into ~/.cargo.
#
# On Debian bookworm it then installs the newer lavapipe (Mesa 25) from the
# bookworm-backports suite, which lancer runs 1.2-1.5x faster on than
# bookworm's Mesa 22.3 (README, "Speed"). The backports suite is added from the
# same mirror the machine's own apt sources use. LANCER_SYSTEM_MESA=1 keeps
# the distribution's Mesa.
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

# Runs a command as root: directly, or via sudo. Fails when neither works.
lancer_as_root() {
    if [ "$(id -u)" -eq 0 ]; then
        "$@"
    elif command -v sudo >/dev/null 2>&1; then
        sudo "$@"
    else
        lancer_log "need root or sudo to run: $*"
        return 1
    fi
}

# Prints the installed version of a Debian package, or nothing.
lancer_pkg_version() {
    dpkg-query -W -f='${Version}' "$1" 2>/dev/null || true
}

# Prints the URI of the machine's own Debian main archive (the source that
# serves the `bookworm` suite), from deb822 or one-line apt sources; nothing
# when there is none.
lancer_debian_mirror() {
    local f found
    # Captured, not piped into head: with pipefail an early exit would fail
    # the pipeline through SIGPIPE.
    found="$(for f in /etc/apt/sources.list.d/*.sources; do
        [ -f "$f" ] || continue
        # One stanza per paragraph: take the URIs of one whose Suites list bookworm.
        awk 'BEGIN { RS = ""; FS = "\n" }
             {
                 uris = ""; suites = ""; enabled = 1
                 for (i = 1; i <= NF; i++) {
                     if ($i ~ /^URIs:/) { uris = $i; sub(/^URIs:[ \t]*/, "", uris) }
                     if ($i ~ /^Suites:/) { suites = " " $i " " }
                     if ($i ~ /^Enabled:[ \t]*no/) { enabled = 0 }
                 }
                 if (enabled && suites ~ /[ \t]bookworm[ \t]/ && uris != "") {
                     split(uris, u, /[ \t]+/); print u[1]; exit
                 }
             }' "$f"
    done
    for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
        [ -f "$f" ] || continue
        # deb [options] URI bookworm components...
        sed -n 's/^[[:space:]]*deb[[:space:]]\+\(\[[^]]*\][[:space:]]\+\)\?\([^[:space:]]\+\)[[:space:]]\+bookworm[[:space:]].*/\2/p' "$f"
    done)"
    printf '%s' "${found%%$'\n'*}"
}

# On Debian bookworm, installs lavapipe from Mesa 25 (bookworm-backports)
# unless LANCER_SYSTEM_MESA=1. Idempotent; says what it did.
lancer_newer_mesa() {
    local version
    version="$(lancer_pkg_version mesa-vulkan-drivers)"
    if [ "${LANCER_SYSTEM_MESA:-0}" = 1 ]; then
        lancer_log "LANCER_SYSTEM_MESA=1: keeping the system's lavapipe (mesa-vulkan-drivers ${version:-not installed})"
        return 0
    fi
    local codename=""
    if [ -f /etc/os-release ]; then
        codename="$(. /etc/os-release && printf '%s' "${VERSION_CODENAME:-}")"
    fi
    if [ "$codename" != bookworm ] || ! command -v dpkg >/dev/null 2>&1; then
        lancer_log "not Debian bookworm: using the system's lavapipe (mesa-vulkan-drivers ${version:-?})"
        return 0
    fi
    case "$version" in
        2[5-9].* | [3-9][0-9].*)
            lancer_log "lavapipe from Mesa $version present"
            return 0
            ;;
    esac
    if ! grep -rqs '^[^#]*bookworm-backports' /etc/apt/sources.list /etc/apt/sources.list.d/; then
        local mirror
        mirror="$(lancer_debian_mirror)"
        if [ -z "$mirror" ]; then
            lancer_log "no Debian bookworm source in /etc/apt: keeping lavapipe from Mesa $version"
            return 0
        fi
        local keyring=/usr/share/keyrings/debian-archive-keyring.gpg
        local list=/etc/apt/sources.list.d/lancer-bookworm-backports.sources
        lancer_log "adding bookworm-backports from the machine's mirror $mirror ($list)"
        {
            printf 'Types: deb\nURIs: %s\nSuites: bookworm-backports\nComponents: main\n' "$mirror"
            if [ -f "$keyring" ]; then
                printf 'Signed-By: %s\n' "$keyring"
            fi
        } | lancer_as_root tee "$list" >/dev/null
    fi
    lancer_log "installing lavapipe from bookworm-backports (replacing Mesa ${version:-none}); LANCER_SYSTEM_MESA=1 opts out"
    lancer_as_root env DEBIAN_FRONTEND=noninteractive apt-get update -q
    lancer_as_root env DEBIAN_FRONTEND=noninteractive \
        apt-get install -y -q --no-install-recommends -t bookworm-backports mesa-vulkan-drivers
    lancer_log "lavapipe now from Mesa $(lancer_pkg_version mesa-vulkan-drivers)"
}

# The version of check-jsonschema the test suite checks the CI recipes with.
LANCER_CHECK_JSONSCHEMA_VERSION=0.39.0

# Installs check-jsonschema (PyPI; it carries GitHub's and GitLab's
# workflow schemas) into a virtual environment of its own, unless that
# version is there, and exports LANCER_CHECK_JSONSCHEMA for tests/it/ci.rs.
lancer_ci_linter() {
    local dir="${LANCER_TOOLS_DIR:-$HOME/.cache/lancer/tools}"
    local bin="$dir/bin/check-jsonschema" version
    version="$("$bin" --version 2>/dev/null)" || version=""
    if [ "$version" = "check-jsonschema, version $LANCER_CHECK_JSONSCHEMA_VERSION" ]; then
        lancer_log "check-jsonschema $LANCER_CHECK_JSONSCHEMA_VERSION present ($bin)"
    else
        lancer_log "installing check-jsonschema $LANCER_CHECK_JSONSCHEMA_VERSION from PyPI into $dir"
        # Only tests/it/ci.rs needs it: without it those tests fail and say so,
        # the rest of the suite still runs
        if ! { python3 -m venv "$dir" &&
            "$dir/bin/pip" install -q --disable-pip-version-check \
                "check-jsonschema==$LANCER_CHECK_JSONSCHEMA_VERSION"; }; then
            lancer_log "could not install check-jsonschema (no python3 venv or no PyPI?); tests/it/ci.rs will fail"
        fi
    fi
    export LANCER_CHECK_JSONSCHEMA="$bin"
}

# The cargo-nextest installed where none is on PATH (the version the suite
# was last measured with, docs/testing.md).
LANCER_NEXTEST_VERSION=0.9.143

# The cargo-afl the fuzz targets (fuzz/) are built and run with; it matches
# the `afl` crate in Cargo.lock.
LANCER_CARGO_AFL_VERSION=0.18.2

# Installs cargo-afl (crates.io) and builds its AFL++ (afl-fuzz and the
# runtime the targets link, from the source cargo-afl carries; needs make and
# a C compiler), unless both are there. Without them the fuzz smoke pass of
# scripts/test.sh fails and says so; the rest of the suite still runs.
lancer_fuzz_tools() {
    local version
    version="$(cargo afl --version 2>/dev/null)" || version=""
    case "$version" in
        "cargo-afl $LANCER_CARGO_AFL_VERSION (AFL++ version"*)
            lancer_log "$version present"
            return 0
            ;;
    esac
    if [ "${version%% (*}" != "cargo-afl $LANCER_CARGO_AFL_VERSION" ]; then
        lancer_log "installing cargo-afl $LANCER_CARGO_AFL_VERSION from crates.io"
        # Its own build folder: not the shared target folder.
        if ! env -u CARGO_TARGET_DIR cargo install --quiet --locked --force \
            --version "$LANCER_CARGO_AFL_VERSION" cargo-afl; then
            lancer_log "could not install cargo-afl; the fuzz smoke pass will fail"
            return 0
        fi
    fi
    lancer_log "building AFL++ for cargo-afl (cargo afl config --build)"
    if ! cargo afl config --build --force </dev/null; then
        lancer_log "could not build AFL++ for cargo-afl; the fuzz smoke pass will fail"
    fi
}

# Installs cargo-nextest (crates.io), the test runner scripts/test.sh runs
# the suite with, unless a cargo-nextest is on PATH (the rust machine image
# ships one). Its own build folder: not the shared target folder.
lancer_test_runner() {
    local version
    if version="$(cargo nextest --version 2>/dev/null)"; then
        lancer_log "${version%%$'\n'*} present"
        return 0
    fi
    lancer_log "installing cargo-nextest $LANCER_NEXTEST_VERSION from crates.io"
    if ! env -u CARGO_TARGET_DIR cargo install --quiet --locked \
        --version "$LANCER_NEXTEST_VERSION" cargo-nextest; then
        lancer_log "could not install cargo-nextest; scripts/test.sh cannot run the suite"
        return 1
    fi
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
        # python3-venv: for the CI-recipe linter the tests use;
        # spirv-tools: spirv-val, which checks every specialised kernel
        wanted+=(vulkan-validationlayers python3-venv spirv-tools)
    fi
    # LANCER_SLURM=1: Slurm and munge for the opt-in tests/slurm.sh.
    if [ "${LANCER_SLURM:-0}" = 1 ]; then
        wanted+=(slurm-wlm munge)
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
        lancer_newer_mesa
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

    # The test suite also lints the CI recipes (tests/it/ci.rs) and runs a
    # short pass of each fuzz target (fuzz/run.sh smoke)
    if [ "$validation" = 1 ]; then
        lancer_test_runner
        lancer_ci_linter
        lancer_fuzz_tools
    fi
}

# Run directly rather than sourced: just do the setup.
if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    lancer_setup "$@"
fi
