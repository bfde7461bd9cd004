#!/usr/bin/env bash
# Regenerates the figures of the docs book that come from running tissuefit, so that none is typed by
# hand: the demo's pictures (docs/src/img/) and printed output, and the real-data tutorial's output
# (docs/src/generated/, included by the chapters). Run from anywhere after `cargo build --release`;
# the real-data part needs ../shared/data/real next to the repository (skipped without it).
# Outputs go to runs/demo and runs/real-ovule (git-ignored). Wall times depend on the machine; the
# numbers of the tables in the Validation chapters come from the commands listed in "Reproducing the
# figures" there.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
bin=target/release/tissuefit
[ -x "$bin" ] || { echo "build first: cargo build --release" >&2; exit 2; }
gen=docs/src/generated
img=docs/src/img
mkdir -p "$gen"

"$bin" --threads 2 run pipelines/demo.toml --out runs/demo --force > "$gen/demo-run.txt"
# The README quotes the same output between its demo-run markers.
python3 - "$gen/demo-run.txt" README.md <<'PY'
import re, sys
run, readme = open(sys.argv[1]).read(), open(sys.argv[2]).read()
block = re.compile(r"(<!-- demo-run:[^\n]*-->\n)```\n.*?```\n(<!-- /demo-run -->)", re.S)
new, n = block.subn(lambda m: m.group(1) + "```\n" + run + "```\n" + m.group(2), readme)
if n != 1:
    sys.exit("README.md: no demo-run block between its markers")
open(sys.argv[2], "w").write(new)
PY
"$bin" render runs/demo/mesh/tissue.vtp --out "$img/demo-mesh.png" --view y --edges --size 420,280
"$bin" render runs/demo/simulate/final.vtk --out "$img/demo-relaxed.png" --view y --edges --size 420,280
cp runs/demo/fit/objective.png runs/demo/fit/landscape.png runs/demo/fit/profile.png "$img/"

ovule=../shared/data/real/plant-seg__sample_ovule_labels.tif
if [ -f "$ovule" ]; then
    "$bin" --threads 2 run pipelines/real-ovule.toml --out runs/real-ovule --force > "$gen/ovule-run.txt"
    "$bin" --threads 2 measure "$ovule" --border static --include-static --out runs/real-ovule/measure-labels \
        > "$gen/ovule-measure-labels.txt"
else
    echo "$ovule not found: the real-data tutorial's output is not regenerated" >&2
fi
"$bin" config presets > "$gen/presets.txt"
embryo=../shared/data/real/DERIVED_cshaper_4cells_labels_from_mesh.tif
if [ -f "$embryo" ]; then
    "$bin" --threads 2 run pipelines/own-embryo.toml --out runs/own-embryo --force > "$gen/own-embryo-run.txt"
    python3 - runs/own-embryo/fit/result.json > "$gen/own-embryo-metrics.txt" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
o, b = r["observed"], r["best_metrics"]
print(f"observed:  sphericity {o['sphericity']:.3f}, contact fraction {o['contact_fraction']:.3f}")
print(f"best fit:  sphericity {b['sphericity']:.3f}, contact fraction {b['contact_fraction']:.3f}")
print(f"objective at the best point: {r['objective']:.2f}")
PY
else
    echo "$embryo not found: the own-data tutorial's output is not regenerated" >&2
fi
echo "regenerated: $img/demo-*.png, objective.png, landscape.png, profile.png, $gen/*.txt"
