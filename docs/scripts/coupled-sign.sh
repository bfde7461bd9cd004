#!/usr/bin/env bash
# Regenerates the comparison of docs/src/design/performance.md, "The side of a coupled node": the
# contact stage of SimuCell3D's 16-cell embryo_5 (../shared/data/real/simucell3d__embryo_5.vtk,
# 27,970 nodes) with coupling contacts, `tissuefit --threads 1 bench contacts-tissue FILE
# --contact-model coupling --repeat 100`, by two builds alternately, REPEAT times each (wall time of
# the whole command and its CPU time, and the bench's own per-node-step figures); then a 1,500-step
# coupled relaxation of the SimuCell3D triplet by both, whose final states must be byte-identical.
#   docs/src/generated/coupled-sign.md   the table
# Usage: docs/scripts/coupled-sign.sh OLD_BINARY [NEW_BINARY (default target/release/tissuefit)] [REPEAT (3)]
# OLD_BINARY is a release build of an earlier commit (e.g. `git worktree add /tmp/old 1b2c0e6 &&
# cargo build --release --manifest-path /tmp/old/Cargo.toml`). About 15 s per run.
set -euo pipefail
cd "$(dirname "$0")/../.."
old=${1:?usage: docs/scripts/coupled-sign.sh OLD_BINARY [NEW_BINARY] [REPEAT]}
new=${2:-target/release/tissuefit}
repeat=${3:-3}
real=../shared/data/real
[ -x "$old" ] || { echo "$old: not an executable" >&2; exit 1; }
[ -d "$real" ] || { echo "$real: the shared real data are needed" >&2; exit 1; }
[ "$new" != target/release/tissuefit ] || cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
printf '[numerics]\ncontact_model = "coupling"\n' > "$work/coupling.toml"
{
    echo "| build | run | wall s | CPU s | µs per node-step | of which narrow phase |"
    echo "|---|---|---|---|---|---|"
    for k in $(seq "$repeat"); do
        for which in old new; do
            bin=$old
            [ "$which" = new ] && bin=$new
            /usr/bin/time -f "%e %U %S" -o "$work/time" "$bin" --threads 1 bench contacts-tissue \
                "$real/simucell3d__embryo_5.vtk" --contact-model coupling --repeat 100 > "$work/bench.json" 2> /dev/null
            read -r wall user sys < <(tail -n 1 "$work/time")
            python3 - "$work/bench.json" "$which" "$k" "$wall" "$user" "$sys" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))["breakdown_seconds_per_node_step"]
which, k, wall, user, system = sys.argv[2:]
print(f"| {which} | {k} | {float(wall):.2f} | {float(user) + float(system):.2f} | "
      f"{d['seconds_per_node_step'] * 1e6:.3f} | {d['narrow_phase'] * 1e6:.3f} |")
PY
        done
    done
    for which in old new; do
        bin=$old
        [ "$which" = new ] && bin=$new
        # Exit status 1: not converged in 1,500 steps; anything else is a failure.
        "$bin" -q --threads 1 simulate "$real/simucell3d__cell_triplet.vtk" --config "$work/coupling.toml" \
            --max-steps 1500 --out "$work/$which" || [ $? -eq 1 ]
    done
    echo
    if cmp -s "$work/old/final.vtk" "$work/new/final.vtk"; then
        echo "Final states of the coupled triplet (1,500 steps, \`final.vtk\`): byte-identical."
    else
        echo "Final states of the coupled triplet (1,500 steps, \`final.vtk\`): **different**."
    fi
} | tee docs/src/generated/coupled-sign.md
