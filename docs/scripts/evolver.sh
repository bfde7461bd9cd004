#!/usr/bin/env bash
# Regenerates the Surface Evolver figures of docs/src/validation/evolver.md from the committed fixtures
# (validation/evolver/fixtures; remake them with validation/evolver/make_cluster.py, which needs Debian's
# evolver-nox and python3 with numpy and scipy):
#   docs/src/generated/evolver-relax.md  our relaxation of each Evolver equilibrium at its own tensions
#                                        (tests/slow/evolver_clusters.rs, ~2 min)
#   docs/src/generated/evolver-fits.md   `tissuefit run` fits of the label volumes (validation/evolver/
#                                        run_fits.py; minutes to an hour: RESOLUTIONS, CLUSTERS narrow it)
#   docs/src/generated/evolver-heldout.md the same for the held-out clusters (heldout_*; about 40 min)
#   docs/src/generated/noise-fits.md     fits of the doublet and held-out triplet at 10 voxels per
#                                        diameter with a voxel of boundary noise (`tissuefit generate
#                                        noise`), without and with `mesh.denoise_voxels` 1.5 and 2 (about 30 min)
# Usage: docs/scripts/evolver.sh [relax|fits|heldout|noise|all]   (default all)
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
if [ "$what" = noise ] || [ "$what" = all ]; then
    cargo build --release
    work=$(mktemp -d)
    fixtures=validation/evolver/fixtures
    for s in 1.5 2; do
        sed "s/^target_nodes = 400 .*/&\\ndenoise_voxels = $s/" validation/evolver/fit-template.toml > "$work/denoise-$s.toml"
        grep -q "^denoise_voxels = $s" "$work/denoise-$s.toml"
    done
    : > "$out/noise-fits.md"
    for noise in clean 0 1.5; do
        for c in doublet heldout_triplet; do
            mkdir -p "$work/$noise/$c"
            cp "$fixtures/$c/truth.json" "$work/$noise/$c/"
            if [ "$noise" = clean ]; then
                cp "$fixtures/$c/labels_10.tif" "$work/$noise/$c/"
            else
                target/release/tissuefit generate noise "$fixtures/$c/labels_10.tif" --amplitude 1 \
                    --correlation "$noise" --seed 1 --out "$work/$noise/$c/labels_10.tif" > /dev/null
            fi
        done
        case $noise in
            clean) what_noise="clean mask" ;;
            0) what_noise="1 voxel RMS of salt-and-pepper noise (--correlation 0)" ;;
            *) what_noise="1 voxel RMS of wavy noise (--correlation $noise)" ;;
        esac
        for meshing in default 1.5 2; do
            template=validation/evolver/fit-template.toml
            how="default meshing"
            if [ "$meshing" != default ]; then
                template="$work/denoise-$meshing.toml"
                how="mesh.denoise_voxels = $meshing"
            fi
            python3 validation/evolver/run_fits.py --clusters "$work/$noise" --resolutions 10 \
                --template "$template" --work "$work/runs-$noise-$meshing" --markdown "$work/$noise-$meshing.md"
            { echo "**$what_noise, $how**"; echo; cat "$work/$noise-$meshing.md"; echo; } >> "$out/noise-fits.md"
        done
    done
fi
