#!/usr/bin/env bash
# Regenerates the fixed-mesh repair table of docs/src/guide/simulation.md: a 64-cell generated
# spheroid (l_min = 1.4 µm, derived simulate defaults: no scheduled remeshing) relaxed for 3,000
# steps on 2 threads with simulation.remesh_below_edge_fraction = 0 (no repair), at its default
# (edges below 0.02·l_min collapsed and slivers flipped as they appear), and at its default with
# simulation.normal_relaxation = true; prints how each run ended.
#   docs/src/generated/fixed-mesh-repair.md   the table
# Usage: docs/scripts/fixed-mesh-repair.sh [BINARY (default target/release/tissuefit)]. About 2 minutes.
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${1:-target/release/tissuefit}
[ "$bin" != target/release/tissuefit ] || cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$bin" generate mesh --kind spheroid --cells 64 --min-edge-length 1.4e-6 --out "$work/spheroid.vtk" -q
printf '[simulation]\nremesh_below_edge_fraction = 0.0\n' > "$work/off.toml"
printf '[simulation]\nnormal_relaxation = true\n' > "$work/normal.toml"
{
    echo "| remesh_below_edge_fraction | exit status | how the run ended | collapses | flips | wall s | CPU s |"
    echo "|---|---|---|---|---|---|---|"
    for which in off on normal; do
        status=0
        config=()
        [ "$which" = off ] && config=(--config "$work/off.toml")
        [ "$which" = normal ] && config=(--config "$work/normal.toml")
        /usr/bin/time -f "%e %U %S" -o "$work/time" "$bin" --threads 2 simulate "$work/spheroid.vtk" \
            "${config[@]}" --max-steps 3000 --out "$work/$which" -q 2> "$work/err" || status=$?
        read -r wall user sys < <(tail -n 1 "$work/time")
        cpu=$(python3 -c "print(round($user + $sys, 1))")
        if [ -f "$work/$which/summary.json" ]; then
            ended=$(python3 -c "import json; s = json.load(open('$work/$which/summary.json')); \
stalled = '; FIRE stalled' if 'FIRE stalled' in (s.get('stop_reason') or '') else ''; \
print(f\"{s['steps']} steps, {'converged' if s['converged'] else 'not converged'}, residual {s['residual']:.2f}{stalled}\")")
            read -r collapses flips < <(python3 -c "import json; t = json.load(open('$work/$which/summary.json'))['topology']; \
print(t['collapses'], t['flips'])")
        else
            # The error line names the step and the cause.
            ended=$(grep -o 'step [0-9]*, cell [0-9]*: [^(]*' "$work/err" | head -n 1 | sed 's/ *$//')
            collapses=0
            flips=0
        fi
        fraction=0
        [ "$which" = on ] && fraction="0.02 (default)"
        [ "$which" = normal ] && fraction="0.02, normal_relaxation = true"
        echo "| $fraction | $status | $ended | $collapses | $flips | $wall | $cpu |"
    done
} | tee docs/src/generated/fixed-mesh-repair.md
