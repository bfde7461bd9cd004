#!/usr/bin/env bash
# Regenerates the real-data map of docs/src/guide/tensions.md ("Real data") and the README's picture of
# it: `tissuefit tensions` on the real C. elegans 4-cell embryo of ../shared/data/real (not part of the
# repository; CShaper via foambryo), from the label volume at 400, 800 and 1,600 nodes per cell and from
# foambryo's mesh, with the default far field and with the global fit alone
# (validation/real/c_elegans_map.py). Seconds once the release binary is built.
#   docs/src/generated/real-c-elegans.md   the table
#   docs/src/img/c-elegans-map.png         the map (labels, 400 nodes per cell, default settings)
#   docs/src/generated/real-ovule.md       the PlantSeg ovule crop's map in figures
#   docs/src/img/ovule-map.png             its picture (validation/real/ovule_map.py)
#   docs/src/generated/real-c-elegans-per-cell.md   the per-cell map (`tissuefit run
#                                          pipelines/real-embryo-map.toml`, about a minute)
# Usage: docs/scripts/real-maps.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
[ -d ../shared/data/real ] || { echo "../shared/data/real not found: the real data are not part of the repository" >&2; exit 1; }
cargo build --release
python3 validation/real/c_elegans_map.py --markdown docs/src/generated/real-c-elegans.md \
    --image docs/src/img/c-elegans-map.png
python3 validation/real/ovule_map.py --markdown docs/src/generated/real-ovule.md \
    --image docs/src/img/ovule-map.png
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The per-cell fit ends with a non-zero status when it does not converge: its table says so.
status=0
target/release/tissuefit --threads 2 run pipelines/real-embryo-map.toml --out "$work/run" > "$work/printed.txt" 2>&1 || status=$?
python3 validation/real/c_elegans_map.py --per-cell "$work/run" --status "$status" \
    --markdown docs/src/generated/real-c-elegans-per-cell.md
