#!/usr/bin/env bash
# Regenerates the per-cell maps' tables (docs/src/guide/fitting.md, "Per-cell maps"):
#   docs/scripts/per-cell.sh            accuracy: `tissuefit fit` with mode = "per_cell" on Evolver's
#                                       hetero4 cluster at 10 and 20 voxels per diameter and on our own
#                                       model's relaxation of it, scored by validation/per_cell/score_per_cell.py
#                                       (about a minute once the release binary is built; 2 cores)
#                                       -> docs/src/generated/per-cell.md
#   docs/scripts/per-cell.sh coverage   coverage of the intervals (`tension_sd`): 24 Surface Evolver
#                                       clusters of 4-6 cells with random additive tensions (made first,
#                                       needs Debian's evolver-nox, numpy and scipy; ~15 min), each fitted
#                                       at 10 and 20 voxels per diameter; seeds 1-4 calibrate
#                                       per_cell.model_error, seeds 5-8 are held out and scored with the
#                                       binary's defaults (validation/per_cell/coverage.py; ~45 min)
#                                       -> docs/src/generated/per-cell-coverage.md (+ .json)
# TRUTHS=DIR keeps the Evolver clusters between runs (default: a temporary folder).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
case "${1:-accuracy}" in
    accuracy)
        python3 validation/per_cell/score_per_cell.py target/release/tissuefit "$work" --markdown docs/src/generated/per-cell.md ;;
    coverage)
        truths=${TRUTHS:-$work/truths}
        python3 validation/per_cell/coverage.py target/release/tissuefit "$truths" "$work/fits" \
            --markdown docs/src/generated/per-cell-coverage.md --json docs/src/generated/per-cell-coverage.json ;;
    *) echo "usage: $0 [accuracy|coverage]" >&2; exit 2 ;;
esac
