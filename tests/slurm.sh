#!/usr/bin/env bash
# Split render on a real scheduler: starts a one-node Slurm cluster on this
# machine (munged, slurmctld and slurmd with a generated slurm.conf, all
# under a temporary folder, on ports of their own), submits
# docs/slurm/render-array.sbatch as a 4-task job array, merges the parts,
# and checks the merge against one render of all samples. The daemons it
# started are stopped (by their process ids) and the folder removed on
# exit, pass or fail.
#
#   bash tests/slurm.sh [LANCER_BINARY]
#
# Needs Debian's slurm-wlm and munge (LANCER_SLURM=1 bash scripts/setup.sh
# installs them) and root (munged and slurmd run as the calling user; as
# root the test needs no Slurm user). Opt-in: not run by scripts/test.sh.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
lancer=${1:-${CARGO_TARGET_DIR:-$HOME/.cache/lancer/target}/release/lancer}
lancer=$(realpath "$lancer")
[[ -x $lancer ]] || { echo "slurm.sh: no lancer binary at $lancer (cargo build --release first, or pass its path)" >&2; exit 1; }
for tool in munged mungekey slurmctld slurmd sbatch sinfo; do
    command -v "$tool" > /dev/null || { echo "slurm.sh: $tool not found: run LANCER_SLURM=1 bash scripts/setup.sh" >&2; exit 1; }
done

tmp=$(mktemp -d /tmp/lancer-slurm.XXXXXX)
chmod 700 "$tmp"
pids=()
cleanup() {
    local status=$?
    for pid in "${pids[@]}"; do
        kill "$pid" 2> /dev/null || true
    done
    for pid in "${pids[@]}"; do
        # Wait for each daemon this script started to exit.
        for _ in $(seq 50); do kill -0 "$pid" 2> /dev/null || break; sleep 0.1; done
    done
    if [[ $status -ne 0 ]]; then
        echo "slurm.sh: failed; daemon logs:" >&2
        tail -n 20 "$tmp"/*.log >&2 2> /dev/null || true
    fi
    rm -rf "$tmp"
    exit "$status"
}
trap cleanup EXIT

# --- munge: a key and a socket of our own
mungekey --create --keyfile="$tmp/munge.key" > /dev/null
chmod 600 "$tmp/munge.key"
munged --foreground --force --key-file="$tmp/munge.key" --socket="$tmp/munge.socket" \
    --pid-file="$tmp/munged.pid" --log-file="$tmp/munged.log" --seed-file="$tmp/munged.seed" \
    > "$tmp/munged.out.log" 2>&1 &
pids+=($!)
for _ in $(seq 50); do [[ -S $tmp/munge.socket ]] && break; sleep 0.1; done
[[ -S $tmp/munge.socket ]] || { echo "slurm.sh: munged did not start" >&2; exit 1; }

# --- slurm.conf: one node (this machine), one partition
host=$(hostname -s)
cpus=$(nproc)
port=$((20000 + RANDOM % 20000))
mkdir -p "$tmp/state" "$tmp/spool"
cat > "$tmp/slurm.conf" << EOF
ClusterName=lancertest
SlurmctldHost=$host
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=$(id -un)
SlurmdUser=$(id -un)
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$tmp/munge.socket
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MpiDefault=none
NodeName=$host CPUs=$cpus State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$tmp/slurm.conf
slurmctld -D -i -f "$SLURM_CONF" > "$tmp/slurmctld.out.log" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" > "$tmp/slurmd.out.log" 2>&1 &
pids+=($!)
state=
for _ in $(seq 100); do
    state=$(sinfo -h -o %T 2> /dev/null || true)
    [[ $state == idle ]] && break
    sleep 0.2
done
[[ $state == idle ]] || { echo "slurm.sh: the node did not become idle (state: ${state:-none})" >&2; exit 1; }
echo "slurm.sh: one-node cluster up ($host, $cpus CPUs, port $port)"

# --- the split render: 4 array tasks, then the merge
work=$tmp/work
mkdir -p "$work"
args="--width 48 --height 40 --max-depth 6"
cd "$work"
SCENE=$root/scenes/cornell.toml SPP=16 OUT_DIR=$work/parts LANCER=$lancer LANCER_ARGS=$args \
    sbatch --wait --array=0-3 --output="$work/task-%a.out" "$root/docs/slurm/render-array.sbatch" > "$work/submit.out" \
    || { cat "$work"/task-*.out >&2; echo "slurm.sh: the job array failed" >&2; exit 1; }
cat "$work"/task-*.out
parts=("$work"/parts/part-*.film)
[[ ${#parts[@]} -eq 4 ]] || { echo "slurm.sh: expected 4 parts, got ${#parts[@]}" >&2; exit 1; }
"$lancer" merge "${parts[@]}" --out "$work/merged.exr"
# shellcheck disable=SC2086 # args is a list of flags
"$lancer" render "$root/scenes/cornell.toml" --spp 16 $args --out "$work/single.exr" --quiet
if cmp -s "$work/merged.exr" "$work/single.exr"; then
    echo "slurm.sh: PASS: the merge of 4 Slurm array tasks is bit-identical to the single render"
else
    # Within f32 rounding is the promise: relMSE of 1-ulp differences is ~1e-14.
    "$lancer" compare "$work/merged.exr" "$work/single.exr" --max-relmse 1e-12
    echo "slurm.sh: PASS: the merge matches the single render within f32 rounding (not bit-identical)"
fi
