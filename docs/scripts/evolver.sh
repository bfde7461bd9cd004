#!/usr/bin/env bash
# Regenerates the Surface Evolver figures of docs/src/validation/evolver.md from the committed fixtures
# (validation/evolver/fixtures; remake them with validation/evolver/make_cluster.py, which needs Debian's
# evolver-nox and python3 with numpy and scipy):
#   docs/src/generated/evolver-relax.md  our relaxation of each Evolver equilibrium at its own tensions
#                                        (tests/slow/evolver_clusters.rs, ~2 min)
#   docs/src/generated/evolver-fits.md   `tissuefit run` fits of the label volumes (validation/evolver/
#                                        run_fits.py; minutes to an hour: RESOLUTIONS, CLUSTERS narrow it)
#   docs/src/generated/evolver-heldout.md the same for the held-out clusters (heldout_*; about 40 min)
# Usage: docs/scripts/evolver.sh [relax|fits|heldout|all]   (default all)
set -euo pipefail
cd "$(dirname "$0")/../.."
what=${1:-all}
out=docs/src/generated
if [ "$what" = relax ] || [ "$what" = all ]; then
    {
        echo "| cluster, γ_l/γ_a | far-field angle | rim angle | contact area (A/V^⅔) | sphericity | residual |"
        echo "|---|---|---|---|---|---|"
        cargo test --release --test slow -- --nocapture --test-threads 1 evolver_clusters:: 2>/dev/null | grep -o '| .*|$'
    } > "$out/evolver-relax.md"
fi
if [ "$what" = fits ] || [ "$what" = all ]; then
    cargo build --release
    work=$(mktemp -d)
    python3 validation/evolver/run_fits.py --only "${CLUSTERS:-doublet,triplet,tetra,ball12}" \
        --resolutions "${RESOLUTIONS:-10,20,40}" --work "$work" --markdown "$out/evolver-fits.md" \
        --json "$out/evolver-fits.json"
fi
if [ "$what" = heldout ] || [ "$what" = all ]; then
    cargo build --release
    work=$(mktemp -d)
    python3 validation/evolver/run_fits.py --only heldout_triplet,heldout_ball8 \
        --resolutions "${RESOLUTIONS:-10,20,40}" --work "$work" --markdown "$out/evolver-heldout.md"
fi
