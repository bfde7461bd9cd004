#!/usr/bin/env bash
# Regenerates the 64-cell relaxation profile of docs/src/design/performance.md (issue 24's scenario):
# a generated 64-cell spheroid (l_min 1.4 µm, ≈7,200 nodes, every numeric derived from the mesh as
# `simulate` derives it: spring contacts with c = l_min), relaxed with FIRE for 6,000 steps on 2
# threads as the start; then `tissuefit bench relax` runs 600 more FIRE steps from that state,
# REPEAT times on 1 thread and REPEAT times on 2, alternately, and the medians of the cost per
# node-step and of each stage go into
#   docs/src/generated/relax-profile.md
# With OLD_BINARY (a release build of an earlier commit, e.g. `git worktree add /tmp/old 28d0b5d &&
# cargo build --release --manifest-path /tmp/old/Cargo.toml`), both builds also run the same 1,500
# steps with `simulate` on 1 thread, alternately, and the script says whether their final states
# are byte-identical (a speed change must not change a result) and prints their wall and CPU seconds.
# With PERF=1, `perf record` of one 1-thread bench run and its top source lines are printed too.
# Usage: docs/scripts/profile.sh [REPEAT (3)] [OLD_BINARY]. About 1 minute per repeat, 3 for the start.
# OUT=NAME writes docs/src/generated/NAME instead (each A/B of performance.md keeps its own table).
set -euo pipefail
cd "$(dirname "$0")/../.."
repeat=${1:-3}
old=${2:-}
out=docs/src/generated/${OUT:-relax-profile.md}
new=target/release/tissuefit
cargo build --release -q
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$new" generate mesh --kind spheroid --cells 64 --min-edge-length 1.4e-6 --out "$work/sph64.vtp" -q
printf '[simulation]\nmethod = "fire"\nmax_steps = 6000\n' > "$work/start.toml"
# Exit status 1: not converged in 6,000 steps (the residual stays near 6); anything else fails.
"$new" --threads 2 simulate "$work/sph64.vtp" --config "$work/start.toml" --out "$work/start" -q 2>/dev/null ||
    [ $? -eq 1 ]
printf '[simulation]\nmethod = "fire"\n' > "$work/relax.toml"
for k in $(seq "$repeat"); do
    for t in 1 2; do
        "$new" --threads "$t" bench relax "$work/start/final.vtk" --config "$work/relax.toml" --steps 600 \
            2>/dev/null > "$work/bench-$t-$k.json"
    done
done
python3 - "$work" "$repeat" > "$out" <<'PY'
import json, statistics, sys
work, repeat = sys.argv[1], int(sys.argv[2])
stages = ["internal_forces", "contact_lists", "contact_broad", "contact_narrow", "contact_apply",
          "coupling", "remeshing", "moving_and_rest"]
print("| threads | wall µs per node-step | CPU µs per node-step | " +
      " | ".join(s.replace("_", " ") for s in stages) + " | rebuilds | updates | nodes | force evaluations |")
print("|---" * (len(stages) + 7) + "|")
for t in (1, 2):
    runs = [json.load(open(f"{work}/bench-{t}-{k}.json")) for k in range(1, repeat + 1)]
    med = lambda f: statistics.median(f(r) for r in runs) * 1e6
    cells = [f"{med(lambda r: r['seconds_per_node_step']):.2f}", f"{med(lambda r: r['cpu_seconds_per_node_step']):.2f}"]
    cells += [f"{med(lambda r, s=s: r['breakdown_seconds_per_node_step'][s]):.3f}" for s in stages]
    r0 = runs[0]
    cells += [str(r0["candidate_rebuilds"]), str(r0["candidate_updates"]), str(r0["nodes"]),
              str(r0["force_evaluations"])]
    print(f"| {t} | " + " | ".join(cells) + " |")
print()
print(f"Medians of {repeat} runs of `tissuefit --threads T bench relax` (600 FIRE steps from the 64-cell "
      "spheroid after 6,000; µs of wall time per node-step for each stage, \"contact broad\" includes "
      "\"contact lists\"; \"moving and rest\" is FIRE's update, residuals and bookkeeping).")
PY
if [ -n "$old" ]; then
    [ -x "$old" ] || { echo "$old: not an executable" >&2; exit 1; }
    printf '[simulation]\nmethod = "fire"\nmax_steps = 1500\n' > "$work/ab.toml"
    {
    echo
    echo "The same 1,500 FIRE steps with \`tissuefit --threads 1 simulate\` by the two builds, alternately:"
    echo
    echo "| build | run | wall s | CPU s |"
    echo "|---|---|---|---|"
    for k in $(seq 2); do
        for which in old new; do
            bin=$old
            [ "$which" = new ] && bin=$new
            rm -rf "$work/$which"
            /usr/bin/time -f "%e %U %S" -o "$work/time" "$bin" --threads 1 simulate "$work/start/final.vtk" \
                --config "$work/ab.toml" --out "$work/$which" -q 2>/dev/null || [ $? -eq 1 ]
            read -r wall user sys < <(tail -n 1 "$work/time")
            echo "| $which | $k | $wall | $(python3 -c "print(round($user + $sys, 2))") |"
        done
    done
    echo
    if cmp -s "$work/old/final.vtk" "$work/new/final.vtk"; then
        echo "Final states byte-identical."
    else
        echo "Final states DIFFER."
    fi
    echo
    echo "Moving tissues, 1 thread, alternately: \`bench growth --cells 128\` (coupling contacts) and"
    echo "\`bench contacts-tissue\` on the raw \`simucell3d__embryo_1.vtk\` (dynamic steps, c = 0.2 µm):"
    echo
    echo "| build | run | growth wall s | growth steps, nodes | contacts-tissue µs per node-step | its broad phase | rebuilds of 20 |"
    echo "|---|---|---|---|---|---|---|"
    embryo=../shared/data/real/simucell3d__embryo_1.vtk
    for k in $(seq 2); do
        for which in old new; do
            bin=$old
            [ "$which" = new ] && bin=$new
            g=$("$bin" --threads 1 bench growth --cells 128 2>/dev/null | python3 -c \
                "import json,sys; d=json.load(sys.stdin); print(f\"{d['wall_seconds']:.1f} | {d['steps']}, {d['nodes']}\")")
            c="(no ../shared) | |"
            if [ -f "$embryo" ]; then
                c=$("$bin" --threads 1 bench contacts-tissue "$embryo" --repeat 20 2>/dev/null | python3 -c \
                    "import json,sys; d=json.load(sys.stdin); b=d['breakdown_seconds_per_node_step']; print(f\"{d['seconds_per_node_step']*1e6:.2f} | {b['broad_phase']*1e6:.2f} | {b['candidate_rebuilds']}\")")
            fi
            echo "| $which | $k | $g | $c |"
        done
    done
    } >> "$out"
fi
cat "$out"
if [ "${PERF:-0}" = 1 ]; then
    perf record -F 999 -o "$work/perf.data" -- "$new" --threads 1 bench relax "$work/start/final.vtk" \
        --config "$work/relax.toml" --steps 600 >/dev/null 2>&1
    perf report -i "$work/perf.data" --no-children --sort srcline --percent-limit 1 --stdio 2>/dev/null |
        grep '%' | head -30
fi
