#!/usr/bin/env bash
# Regenerates the 2.5-D sheet figures of docs/src/guide/tensions.md ("2.5-D cell sheets"):
#   docs/src/generated/sheet-accuracy.md   accuracy against power diagrams (analytic truth, with
#                                          conformal images and vertex noise): the sheet_accuracy example,
#                                          about two minutes on 2 cores
#   docs/src/generated/real-sam-sheet.md   `tissuefit tensions` on the real shoot-apex L1 topomesh of
#   docs/src/img/sam-sheet-map.png         ../shared/data/real (cellcomplex, PLY), and its picture
# Usage: docs/scripts/sheet.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --examples
cargo run --release --quiet --example sheet_accuracy > docs/src/generated/sheet-accuracy.md
ply=../shared/data/real/cellcomplex__p194-t4_L1_topomesh.ply
[ -f "$ply" ] || { echo "$ply not found: the real data are not part of the repository" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
target/release/tissuefit --threads 2 tensions "$ply" --length-unit um --out "$work/map" > "$work/printed.txt" 2> "$work/log.txt"
cp "$work/map/tensions.png" docs/src/img/sam-sheet-map.png
python3 - "$work" > docs/src/generated/real-sam-sheet.md <<'PY'
import csv, json, statistics, sys
work = sys.argv[1]
s = json.load(open(f"{work}/map/summary.json"))
walls = list(csv.DictReader(open(f"{work}/map/interfaces.csv")))
t = sorted(float(w["tension"]) for w in walls if w["tension"])
rel = sorted(float(w["tension_sd"]) / abs(float(w["tension"])) for w in walls if w["tension"])
q = lambda v, f: v[round((len(v) - 1) * f)]
print("`tissuefit --threads 2 tensions ../shared/data/real/cellcomplex__p194-t4_L1_topomesh.ply --length-unit um "
      "--out map` printed:\n")
print("```text")
print(open(f"{work}/printed.txt").read().replace(f"{work}/", "").rstrip())
print("```\n")
print("| figure | value |\n|---|---|")
print(f"| cells (on the layer's rim) | {s['cells']} ({s['cells_on_rim']}) |")
print(f"| walls, determined | {s['interfaces']}, {s['determined_interfaces']} |")
print(f"| junctions with an equation | {s['junctions']} |")
print(f"| wall tension: median, 5th–95th percentile, largest | {statistics.median(t):.2f}, {q(t, 0.05):.2f}–{q(t, 0.95):.2f}, {t[-1]:.1f} |")
print(f"| walls ≤ 0 | {sum(1 for x in t if x <= 0)} |")
print(f"| median relative sd | {100 * statistics.median(rel):.0f} % |")
print(f"| force-balance residual rms (median) | {s['residual_rms']:.3f} ({s['residual_median']:.3f}) |")
print(f"| spectral gap | {s['spectral_gap']:.2f} |")
print(f"| cells with an in-plane pressure | {s['determined_pressures']} |")
print(f"| wall time (estimate only, {s['threads']} threads) | {s['wall_seconds']:.1f} s |")
print("\nWarnings:\n")
for w in s["warnings"]:
    print(f"- {w}")
PY
echo "wrote docs/src/generated/sheet-accuracy.md, real-sam-sheet.md and docs/src/img/sam-sheet-map.png"
