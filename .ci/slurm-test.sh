#!/usr/bin/env bash
# The Slurm job-array recipe of docs/src/guide/sweeps.md ("Many samples", "On a cluster"), run under
# a real Slurm: a one-node cluster on this machine (slurmctld + slurmd + munged, loopback only, all
# state in a temporary directory), a many-samples sweep (a glob over 4 label volumes, one run each),
# the docs' array script and `--collect` job submitted with sbatch, then checked:
#   - every array task and the collect job ended COMPLETED with exit code 0 (scontrol show job);
#   - every run directory has its stages' outputs and a manifest;
#   - results.csv has one row per sample (its file in the input.labels column), each `complete`;
#   - submitting one index again skips its run (resumable).
# The job script and the collect command are taken from the docs' code blocks, not copied here, so the
# tested recipe is the documented one; only `--array` (the number of runs, as the docs say) and
# `--cpus-per-task` (half this machine's cores, at most the documented 4, so two tasks run at once) are given on the
# sbatch command line, which overrides the script's #SBATCH lines.
#
# Run from anywhere, after building the binary:
#   cargo build --release && .ci/slurm-test.sh
# `.ci/slurm-test.sh --install-only` only installs Slurm when it is missing (.ci/prefetch.sh).
# Environment:
#   TISSUEFIT_BIN               the binary (default: target/release/tissuefit in this repo)
#   TISSUEFIT_SLURM_OPTIONAL=1  exit 0 with a message (instead of failing) when Slurm is missing and
#                               cannot be installed (not root, or no apt-get)
#   TISSUEFIT_SLURM_PORT        slurmctld's port (default 16817; slurmd uses the next one)
# Slurm and munge are installed with apt-get (Debian's slurm-wlm) when sbatch/slurmctld are missing;
# nothing is installed or changed outside the temporary directory otherwise, and the daemons are
# stopped on exit. Wall time on the 2-core development machine: 13 s with Slurm installed (mostly
# Slurm's scheduling intervals: each run is ~0.2 s of work), 25 s including the apt-get install.
set -euo pipefail

repo=$(cd "$(dirname "$0")/.." && pwd)
bin=${TISSUEFIT_BIN:-$repo/target/release/tissuefit}
port=${TISSUEFIT_SLURM_PORT:-16817}
started=$SECONDS

say() { echo "slurm-test: $*" >&2; }
die() { say "FAILED: $*"; exit 1; }

# --- 1. Slurm and munge --------------------------------------------------------------------------
# Daemons live in /usr/sbin, which a non-login root shell may not have on PATH.
export PATH="$PATH:/usr/sbin:/sbin"
have_slurm() { command -v sbatch >/dev/null && command -v slurmctld >/dev/null && command -v slurmd >/dev/null \
    && command -v munged >/dev/null; }
if ! have_slurm; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        say "installing slurm-wlm and munge with apt-get"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq >/dev/null
        apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
    fi
    if ! have_slurm; then
        if [ "${TISSUEFIT_SLURM_OPTIONAL:-}" = 1 ]; then
            say "Slurm is not installed and cannot be (needs root and apt-get): skipping the Slurm test"
            exit 0
        fi
        die "Slurm (sbatch, slurmctld, slurmd, munged) is not installed and cannot be installed here (needs root and apt-get); set TISSUEFIT_SLURM_OPTIONAL=1 to skip"
    fi
fi
if [ "${1:-}" = --install-only ]; then
    exit 0
fi
if [ ! -x "$bin" ]; then
    die "no tissuefit binary at $bin (build it with \`cargo build --release\` or set TISSUEFIT_BIN)"
fi
bin=$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")
say "$(slurmd -V)"

# --- 2. A one-node cluster in a temporary directory ----------------------------------------------
tmp=$(mktemp -d /tmp/tissuefit-slurm.XXXXXX)
chmod 755 "$tmp"
pids=()
# Always: stop the daemons (slurmd, slurmctld, then munged) and remove the temporary directory.
cleanup() {
    local rc=$?
    for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
    for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
    if [ -f "$tmp/munge/munged.pid" ]; then kill "$(cat "$tmp/munge/munged.pid")" 2>/dev/null || true; fi
    cd /
    rm -rf "$tmp"
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

show_logs() {
    for f in "$tmp"/log/*.log "$tmp"/work/*.out; do
        [ -f "$f" ] || continue
        # A daemon's stdout repeats its log file: shown only when the log file was never opened.
        if [[ "$f" == *.stdout.log && -f "${f%.stdout.log}.log" ]]; then continue; fi
        echo "----- $f (last 40 lines)" >&2
        tail -n 40 "$f" >&2
    done
}
fail() { say "FAILED: $*"; show_logs; exit 1; }

mkdir -p "$tmp/state" "$tmp/spool" "$tmp/log" "$tmp/munge" "$tmp/work"
host=$(hostname -s)
cpus=$(nproc)
# munged with its own key and socket, so a system munged (if any) is neither needed nor disturbed.
dd if=/dev/urandom of="$tmp/munge/munge.key" bs=1024 count=1 status=none
chmod 755 "$tmp/munge"   # munged wants its socket's directory searchable by all
chmod 400 "$tmp/munge/munge.key"
munged --force --key-file="$tmp/munge/munge.key" --socket="$tmp/munge/munge.socket" \
    --pid-file="$tmp/munge/munged.pid" --log-file="$tmp/log/munged.log" --seed-file="$tmp/munge/seed"
for _ in $(seq 50); do [ -S "$tmp/munge/munge.socket" ] && break; sleep 0.1; done
[ -S "$tmp/munge/munge.socket" ] || fail "munged did not start"

cat >"$tmp/slurm.conf" <<EOF
ClusterName=tissuefit-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$tmp/munge/munge.socket
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
MinJobAge=600
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=1000 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$tmp/slurm.conf

slurmd -D -f "$SLURM_CONF" >>"$tmp/log/slurmd.stdout.log" 2>&1 &
pids+=($!)
slurmctld -D -f "$SLURM_CONF" >>"$tmp/log/slurmctld.stdout.log" 2>&1 &
pids+=($!)

state=
for _ in $(seq 60); do
    state=$(sinfo -h -N -n "$host" -o '%t' 2>/dev/null || true)
    [ "$state" = idle ] && break
    sleep 1
done
[ "$state" = idle ] || fail "the node did not become idle within 60 s (sinfo: '${state:-no answer}')"
say "one-node cluster up on $host ($cpus CPUs) after $((SECONDS - started)) s"

# --- 3. A many-samples sweep, submitted as the docs say -----------------------------------------
work=$tmp/work
cd "$work"
mkdir samples
for seed in 1 2 3 4; do
    "$bin" generate labels --kind aggregate --cells 3 --seed "$seed" --out "samples/embryo-$seed.tif" >/dev/null
done
cat >base.toml <<'EOF'
[input]
labels = "samples/embryo-1.tif"   # replaced by the sweep's glob
seed = 0
[mesh]
target_nodes = 100
[measure]
include_static = false
EOF
cat >S.toml <<'EOF'
base = "base.toml"
[grid]
"input.labels" = ["samples/*.tif"]
EOF
runs=$("$bin" sweep S.toml --list | wc -l)
[ "$runs" = 4 ] || fail "expected 4 runs in the sweep, --list printed $runs"

# The docs' recipe: the array script (its bash block with `#SBATCH --array`) and the collect command.
docs=$repo/docs/src/guide/sweeps.md
awk '/^```bash$/ { block = ""; inside = 1; next }
     /^```$/ && inside { if (block ~ /#SBATCH --array/) { printf "%s", block; exit } inside = 0; next }
     inside { block = block $0 "\n" }' "$docs" >job.sh
grep -q '^#!/bin/bash' job.sh && grep -q 'sweep S.toml --out sweep --index "$SLURM_ARRAY_TASK_ID"' job.sh \
    || fail "no job-array script with \`sweep S.toml --out sweep --index\` found in $docs"
collect=$(grep -m1 '^sbatch --dependency=afterany:<job id> --wrap ' "$docs" || true)
[[ "$collect" == *'"tissuefit sweep S.toml --out sweep --collect"' ]] \
    || fail "no \`sbatch --dependency=afterany:<job id> --wrap \"tissuefit sweep S.toml --out sweep --collect\"\` line in $docs"
say "job script from the docs:"; sed 's/^/    /' job.sh >&2

# The jobs inherit this environment (sbatch's default --export=ALL): `tissuefit` is the binary under test.
export PATH="$(dirname "$bin"):$PATH"
# Half the cores per task (at least 1, at most the documented 4), so that two tasks run at once.
per_task=$((cpus / 2))
[ "$per_task" -ge 1 ] || per_task=1
[ "$per_task" -le 4 ] || per_task=4
array=$(sbatch --parsable --array="0-$((runs - 1))" --cpus-per-task="$per_task" --output=task-%a.out job.sh)
array=${array%%;*}
# The docs' collect line with the array's job id, its output in collect.out.
collect_cmd=${collect/<job id>/$array}
collect_job=$(eval "sbatch --parsable --output=collect.out ${collect_cmd#sbatch }")
collect_job=${collect_job%%;*}
say "submitted array job $array (0-$((runs - 1)), $per_task CPU(s) per task) and collect job $collect_job"

wait_for() { # job ids…: until squeue no longer lists them
    local deadline=$((SECONDS + 300))
    while [ -n "$(squeue -h -j "$(IFS=,; echo "$*")" -o %i 2>/dev/null)" ]; do
        [ $SECONDS -lt $deadline ] || fail "jobs $* still queued or running after 300 s: $(squeue)"
        sleep 1
    done
}
# Each job (each array task) must have ended COMPLETED with exit code 0:0.
check_jobs() {
    local info
    info=$(scontrol -o show job "$1") || fail "scontrol show job $1: no such job"
    while read -r line; do
        [[ "$line" == *" JobState=COMPLETED "* && "$line" == *" ExitCode=0:0 "* ]] \
            || fail "job not completed with exit code 0: $(grep -o 'JobId=[^ ]*\|ArrayTaskId=[^ ]*\|JobState=[^ ]*\|ExitCode=[^ ]*' <<<"$line" | tr '\n' ' ')"
    done <<<"$info"
    echo "$info" | wc -l
}
wait_for "$array" "$collect_job"
tasks=$(check_jobs "$array")
[ "$tasks" = "$runs" ] || fail "the array had $tasks tasks, expected $runs"
check_jobs "$collect_job" >/dev/null

for i in $(seq 0 $((runs - 1))); do
    run=sweep/$(printf 'run-%04d' "$i")
    for f in manifest.json pipeline.toml config.resolved.toml mesh/report.json measure/summary.json measure/cells.csv; do
        [ -s "$run/$f" ] || fail "$run/$f is missing (task $i, task-$i.out)"
    done
done
[ -f sweep/results.csv ] || fail "the collect job wrote no sweep/results.csv"
python3 - sweep/results.csv "$runs" <<'PY' || fail "results.csv is not one complete row per sample"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
want = [f"samples/embryo-{i}.tif" for i in range(1, int(sys.argv[2]) + 1)]
got = [r["input.labels"] for r in rows]
assert got == want, f"input.labels column {got}, expected {want}"
bad = [(r["index"], r["status"], r["reason"]) for r in rows if r["status"] != "complete"]
assert not bad, f"runs not complete: {bad}"
cells = [r["measure/summary.json:cells"] for r in rows]
assert cells == ["3"] * len(rows), f"cells column {cells}, expected 3 per sample"
sphericity = [r["measure/summary.json:mean_sphericity"] for r in rows]
assert len(set(sphericity)) == len(rows), f"samples measured alike (each task its own sample?): {sphericity}"
PY
grep -q "results.csv ($runs rows)" collect.out || fail "collect.out does not report $runs rows"

# Resumable: the same task again skips its finished run.
again=$(sbatch --parsable --array=1 --cpus-per-task="$per_task" --output=again-%a.out job.sh)
again=${again%%;*}
wait_for "$again"
check_jobs "$again" >/dev/null
grep -q '1 run(s) in .*: 0 complete, 1 skipped, 0 failed' again-1.out \
    || fail "resubmitting task 1 did not skip its finished run: $(cat again-1.out)"

say "results.csv:"; sed 's/^/    /' sweep/results.csv >&2
say "passed: $runs array tasks, the collect job and a skipped resubmission under $(slurmd -V) in $((SECONDS - started)) s"
