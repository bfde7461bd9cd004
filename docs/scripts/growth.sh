#!/usr/bin/env bash
# Regenerates docs/src/generated/growth-10k.md (issue 24's scale benchmark, docs book "The growth
# benchmark"): `tissuefit --threads 2 bench growth --cells CELLS` from one cell, the paper's Fig. 1e
# settings (pipelines/growth.toml), and a table of its milestones (wall and CPU time, nodes, cost per
# node-step since the previous milestone, peak resident memory read from /proc/self/status).
# Usage: docs/scripts/growth.sh [CELLS (10000)] [JSON]
#   JSON: format the output of an earlier `bench growth` run instead of running it (the run takes
#   about 30 minutes to 10,000 cells on 2 cores; its stderr shows progress at each milestone).
set -euo pipefail
cd "$(dirname "$0")/../.."
cells=${1:-10000}
json=${2:-}
if [ -z "$json" ]; then
    cargo build --release -q
    json=$(mktemp)
    trap 'rm -f "$json"' EXIT
    # Exit status 1 means the run stopped early; the table then says why.
    target/release/tissuefit --threads 2 bench growth --cells "$cells" > "$json" || [ $? -eq 1 ]
fi
python3 - "$json" > docs/src/generated/growth-10k.md <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
mib = lambda b: f"{b / 2**20:,.0f}" if b is not None else "n/a"
print("| cells | steps | wall s | CPU s | nodes | nodes/cell | µs per node-step since previous (wall) | peak memory MiB |")
print("|---|---|---|---|---|---|---|---|")
for m in d["milestones"]:
    if m["milestone"] < 16:
        continue
    cpu = f"{m['cpu_seconds']:.1f}" if m.get("cpu_seconds") is not None else "n/a"
    print(f"| {m['cells']:,} | {m['steps']:,} | {m['wall_seconds']:.1f} | {cpu} | {m['nodes']:,} | "
          f"{m['nodes_per_cell']:.0f} | {m['seconds_per_node_step'] * 1e6:.2f} | {mib(m.get('peak_memory_bytes'))} |")
print()
cpu = d.get("cpu_seconds")
print(f"`tissuefit --threads {d['threads']} bench growth --cells {d['target_cells']}`: {d['stop_reason']}; "
      f"{d['cells']:,} cells, {d['nodes']:,} nodes after {d['steps']:,} steps; {d['wall_seconds']:.0f} s of wall time"
      + (f" and {cpu:.0f} s of CPU time" if cpu is not None else "")
      + f" over {d['node_steps'] / 1e6:.1f} M node-steps ({d['seconds_per_node_step'] * 1e6:.2f} µs of wall time"
      + (f", {cpu / d['node_steps'] * 1e6:.2f} µs of CPU time" if cpu is not None else "")
      + f" per node-step); peak memory {mib(d.get('peak_memory_bytes'))} MiB; {d['divisions']:,} divisions, "
      f"{d['removals']:,} removals"
      + (f"; α = {d['alpha']:.2f} (T ∝ N^α from {d['alpha_from_cells']} cells)." if d.get("alpha") is not None else "."))
PY
cat docs/src/generated/growth-10k.md
