# Helpers the benchmark scripts source: the lock, the build, the median.
# Environment: LANCER_BENCH_LOCK, a lock file the build and each timed run
# hold (flock) on shared machines (the lock that builds take there, e.g.
# /tmp/lancer-cargo.lock, so that no build runs during a timed run);
# LANCER_BIN, a lancer binary to use instead of building one;
# CARGO_TARGET_DIR as usual.

# Run a command, inside the lock when one is named
locked() {
    if [ -n "${LANCER_BENCH_LOCK:-}" ]; then
        flock "$LANCER_BENCH_LOCK" "$@"
    else
        "$@"
    fi
}

# Build the release binary of the crate at $1 and set $lancer to it, or
# take $LANCER_BIN as it is
build_lancer() {
    if [ -n "${LANCER_BIN:-}" ]; then
        [ -x "$LANCER_BIN" ] || { echo "LANCER_BIN=$LANCER_BIN: not an executable file" >&2; exit 1; }
        lancer="$LANCER_BIN"
        return
    fi
    export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/lancer/target}"
    locked cargo build --release --quiet --manifest-path "$1/Cargo.toml"
    lancer="$CARGO_TARGET_DIR/release/lancer"
}

# Print the median of the arguments
median() { printf '%s\n' "$@" | sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

# Print "load average L1 L5 L15 on N cores (label)" from /proc/loadavg, and a
# warning when the 1-minute figure is above 0.5 per core or a compiler or
# another lancer runs
load_report() {
    local cores l1 l5 l15 busy
    cores=$(nproc)
    read -r l1 l5 l15 _ < /proc/loadavg
    echo "load average $l1 $l5 $l15 (1, 5, 15 min) on $cores cores ($1)"
    if awk -v l="$l1" -v c="$cores" 'BEGIN { exit !(l > 0.5 * c) }'; then
        echo "WARNING: load average $l1 is above 0.5 per core: the machine is busy, these times are not a quiet machine's"
    fi
    # (grep finds nothing on a quiet machine: not a failure under pipefail)
    busy=$(ps -eo comm= | { grep -xE 'rustc|rustfmt|clippy-driver|cargo|cc1|cc1plus|ld|ld.lld|clang|lancer' || true; } |
        sort | uniq -c | awk '{ printf "%s%s x%s", s, $2, $1; s = ", " }')
    if [ -n "$busy" ]; then
        echo "WARNING: compilers or other renders run: $busy"
    fi
}
