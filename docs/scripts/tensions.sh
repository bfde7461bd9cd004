#!/usr/bin/env bash
# Regenerates the accuracy table of docs/src/guide/tensions.md: `tissuefit tensions` (the direct
# estimate) on every committed Surface Evolver fixture (validation/evolver/fixtures: Evolver's own mesh
# and the label volumes at 10, 20 and 40 voxels per cell diameter), scored against truth.json by
# validation/evolver/score_tensions.py. Seconds once the release binary is built.
#   docs/src/generated/direct-tensions.md    the table
#   docs/src/generated/direct-tensions.json  its rows
#   docs/src/img/tension-map.png             the README's map picture (hetero4, 20 voxels per diameter)
# Usage: docs/scripts/tensions.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release
python3 validation/evolver/score_tensions.py --markdown docs/src/generated/direct-tensions.md \
    --json docs/src/generated/direct-tensions.json
# The README's map picture: the direct estimate of hetero4 at 20 voxels per diameter, as drawn by
# `tissuefit tensions` (tensions.png).
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
target/release/tissuefit tensions validation/evolver/fixtures/hetero4/labels_20.tif --out "$work/map" -q
cp "$work/map/tensions.png" docs/src/img/tension-map.png
