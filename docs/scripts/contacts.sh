#!/usr/bin/env bash
# Regenerates the multi-material contact-area table of docs/src/guide/measure.md: `tissuefit measure`
# on foambryo's 4-cell mesh (../shared/data/real) from its interface labels and by the distance rule
# (--distance-contacts), one row per contact. Seconds once the release binary is built.
#   docs/src/generated/foambryo-contacts.md   the table
# Usage: docs/scripts/contacts.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
mesh=../shared/data/real/foambryo-runner__Cshaper_4_cells_min-d-3.vtk
[ -f "$mesh" ] || { echo "$mesh not found: this table needs ../shared/data/real" >&2; exit 1; }
cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
target/release/tissuefit measure "$mesh" --out "$work/labels" -q
target/release/tissuefit measure "$mesh" --out "$work/distance" --distance-contacts -q
python3 - "$work" > docs/src/generated/foambryo-contacts.md <<'PY'
import csv, json, sys
work = sys.argv[1]
def contacts(which):
    with open(f"{work}/{which}/contacts.csv") as f:
        return {(int(r["cell_a"]), int(r["cell_b"])): r for r in csv.DictReader(f)}
def summary(which):
    with open(f"{work}/{which}/summary.json") as f:
        return json.load(f)
labels, distance = contacts("labels"), contacts("distance")
assert summary("labels")["contact_rule"] == "interface_labels", "the labels were not used"
assert summary("distance")["contact_rule"] == "distance"
delta = summary("distance")["contact_distance"]
print(f"| contact | area from labels (voxel²) | distance rule, δ = {delta:.2f} voxel (voxel²) | difference | rim angle, labels / distance |")
print("|---|---|---|---|---|")
def angle(r):
    return f"{float(r['contact_angle_deg']):.1f}°" if r and r["contact_angle_deg"] else "–"
for key in sorted(set(labels) | set(distance)):
    l, d = labels.get(key), distance.get(key)
    la = float(l["area"]) if l else None
    da = float(d["area"]) if d else None
    diff = f"{100 * (da / la - 1):+.1f} %" if la and da else "–"
    area = lambda a: f"{a:.1f}" if a is not None else "–"
    print(f"| {key[0]}–{key[1]} | {area(la)} | {area(da)} | {diff} | {angle(l)} / {angle(d)} |")
PY
echo "wrote docs/src/generated/foambryo-contacts.md"
