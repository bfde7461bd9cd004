#!/usr/bin/env bash
# Regenerates the accuracy table of the per-cell maps (docs/src/guide/fitting.md, "Per-cell maps"):
# `tissuefit fit` with mode = "per_cell" on Evolver's hetero4 cluster at 10 and 20 voxels per
# diameter and on our own model's relaxation of it, scored by validation/per_cell/score_per_cell.py.
# About a minute once the release binary is built (2 cores).
#   docs/src/generated/per-cell.md   the table
# Usage: docs/scripts/per-cell.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 validation/per_cell/score_per_cell.py target/release/tissuefit "$work" --markdown docs/src/generated/per-cell.md
