# Helpers the benchmark scripts source: the lock, the build, the median.
# Environment: LANCER_BENCH_LOCK, a lock file each timed run holds (flock)
# on shared machines; CARGO_TARGET_DIR as usual.

# Run a command, inside the lock when one is named
locked() {
    if [ -n "${LANCER_BENCH_LOCK:-}" ]; then
        flock "$LANCER_BENCH_LOCK" "$@"
    else
        "$@"
    fi
}

# Build the release binary of the crate at $1 and set $lancer to it
build_lancer() {
    export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/lancer/target}"
    locked cargo build --release --quiet --manifest-path "$1/Cargo.toml"
    lancer="$CARGO_TARGET_DIR/release/lancer"
}

# Print the median of the arguments
median() { printf '%s\n' "$@" | sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
