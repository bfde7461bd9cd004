#!/usr/bin/env bash
# Regenerates the candidate-list (Verlet list) comparison of docs/src/design/performance.md: a
# 32-cell generated spheroid (7,230 nodes, l_min = 1 µm, spring contacts with c = 0.5 µm) relaxed
# with FIRE for 3,000 steps on 1 thread by two builds, alternately, REPEAT times each; prints the wall
# and CPU seconds of every run and whether the two final states are byte-identical.
#   docs/src/generated/candidate-lists.md   the table
# Usage: docs/scripts/candidate-lists.sh OLD_BINARY [NEW_BINARY (default target/release/tissuefit)] [REPEAT (2)]
# OLD_BINARY is a release build of an earlier commit (e.g. `git worktree add /tmp/old e982ab8 &&
# cargo build --release --manifest-path /tmp/old/Cargo.toml`). About 1 minute per run.
set -euo pipefail
cd "$(dirname "$0")/../.."
old=${1:?usage: docs/scripts/candidate-lists.sh OLD_BINARY [NEW_BINARY] [REPEAT]}
new=${2:-target/release/tissuefit}
repeat=${3:-2}
[ -x "$old" ] || { echo "$old: not an executable" >&2; exit 1; }
[ "$new" != target/release/tissuefit ] || cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$new" generate mesh --kind spheroid --cells 32 --out "$work/spheroid.vtp" -q
cat > "$work/config.toml" <<'TOML'
[numerics]
min_edge_length = 1e-6
contact_cutoff = 5e-7
[simulation]
method = "fire"
max_steps = 3000
TOML
{
    echo "| build | run | wall s | CPU s |"
    echo "|---|---|---|---|"
    for k in $(seq "$repeat"); do
        for which in old new; do
            bin=$old
            [ "$which" = new ] && bin=$new
            rm -rf "$work/$which"
            # Exit status 1: not converged in 3,000 steps, as expected; anything else is a failure.
            /usr/bin/time -f "%e %U %S" -o "$work/time" "$bin" --threads 1 simulate "$work/spheroid.vtp" \
                --config "$work/config.toml" --out "$work/$which" -q || [ $? -eq 1 ]
            read -r wall user sys < <(tail -n 1 "$work/time")
            echo "| $which | $k | $wall | $(python3 -c "print(round($user + $sys, 2))") |"
        done
    done
    if cmp -s "$work/old/final.vtk" "$work/new/final.vtk"; then
        echo
        echo "Final states (\`final.vtk\`): byte-identical."
    else
        echo
        echo "Final states (\`final.vtk\`): **different**."
    fi
} | tee docs/src/generated/candidate-lists.md
