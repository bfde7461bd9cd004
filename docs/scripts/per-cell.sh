#!/usr/bin/env bash
# Regenerates the per-cell maps' tables (docs/src/guide/fitting.md, "Per-cell maps"):
#   docs/scripts/per-cell.sh            accuracy: `tissuefit fit` with mode = "per_cell" on Evolver's
#                                       hetero4 cluster at 10 and 20 voxels per diameter and on our own
#                                       model's relaxation of it, scored by validation/per_cell/score_per_cell.py
#                                       (about a minute once the release binary is built; 2 cores)
#                                       -> docs/src/generated/per-cell.md
#   docs/scripts/per-cell.sh coverage   coverage of the intervals (`tension_sd`, `pressure_sd`, a cell's
#                                       `lateral_tension_sd`): 36 Surface Evolver clusters of 4-6 cells with
#                                       random additive tensions (made first, needs Debian's evolver-nox,
#                                       numpy and scipy), each fitted at 10 and 20 voxels per diameter;
#                                       seeds 1-8 calibrate per_cell.model_error (also scored
#                                       leave-one-seed-out), seeds 9-12 are held out and scored with the
#                                       binary's defaults (validation/per_cell/coverage.py; ~45 min on 2 cores)
#                                       -> docs/src/generated/per-cell-coverage.md (+ .json)
#   docs/scripts/per-cell.sh series     `tissuefit fit-series` warm (each frame's direct estimate
#                                       times the previous frame's correction) and --cold on 6 Evolver time series of 5 cells, 4 frames,
#                                       tensions drifting by up to ±30 % (made first, ~15 min; mapped ~25 min;
#                                       validation/per_cell/series.py)
#                                       -> docs/src/generated/per-cell-series.md (+ .json)
#   docs/scripts/per-cell.sh adhesion   spring-contact adhesion maps (each cell its own adhesion) on 12 of the
#                                       coverage table's Evolver clusters (4-6 cells, seeds 1-4), at 10 and 20
#                                       voxels per diameter: interface tensions and each cell's adhesion
#                                       energy against the truth's f - a_i (validation/per_cell/adhesion.py;
#                                       truths ~10 min, fits ~15 min on 2 cores)
#                                       -> docs/src/generated/per-cell-adhesion.md (+ .json)
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
    series)
        truths=${TRUTHS:-$work/truths}
        python3 validation/per_cell/series.py target/release/tissuefit "$truths" "$work/series" \
            --markdown docs/src/generated/per-cell-series.md --json docs/src/generated/per-cell-series.json ;;
    adhesion)
        truths=${TRUTHS:-$work/truths}
        python3 validation/per_cell/adhesion.py target/release/tissuefit "$truths" "$work/adhesion" \
            --markdown docs/src/generated/per-cell-adhesion.md --json docs/src/generated/per-cell-adhesion.json ;;
    *) echo "usage: $0 [accuracy|coverage|series|adhesion]" >&2; exit 2 ;;
esac
