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
#   docs/src/generated/noise-scatter.md  what the noise does to the measured shape before any fit: the same
#                                        two masks meshed with denoise_voxels = 2 and measured, clean and
#                                        over 6 noise seeds of each kind (mean ± SD; seconds)
#   docs/src/generated/noise-roughen.md  fits of the doublet, held-out triplet and 12-cell ball at 10 voxels
#                                        per diameter with a voxel of wavy boundary noise, denoise_voxels = 2,
#                                        the simulated masks roughened by forward.roughen_voxels = "auto",
#                                        not at all, and by the true 1 voxel (about an hour; ROUGHEN="auto none"
#                                        narrows it)
#   docs/src/generated/noise-roughen-seeds.md  the doublet and held-out triplet of noise-roughen.md under
#                                        other draws of the noise (SEEDS, default "2 3"), "auto" and not
#                                        roughened (about 16 minutes)
#   docs/src/generated/evolver-spring-fits.md  the same clusters fitted as spring adhesion with the
#                                        "aggregate" preset (run_fits.py --spring: the truth is
#                                        w/(2γ) = 1 − γ_l/γ_a; doublet, triplet, tetra at 10 and 20 voxels,
#                                        about 12 minutes)
# Usage: docs/scripts/evolver.sh [relax|fits|heldout|spring|noise|noise-scatter|roughen|roughen-seeds|all]
# (default all)
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
if [ "$what" = spring ] || [ "$what" = all ]; then
    cargo build --release
    work=$(mktemp -d)
    python3 validation/evolver/run_fits.py --spring --only "${CLUSTERS:-doublet,triplet,tetra}" \
        --resolutions "${RESOLUTIONS:-10,20}" --work "$work" --markdown "$out/evolver-spring-fits.md" \
        --json "$out/evolver-spring-fits.json"
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
# wavy_masks SEED DIR CLUSTER...: each cluster's 10 voxels-per-diameter mask with 1 voxel RMS of wavy
# noise (correlation 1.5, seed SEED), with its truth, in DIR/CLUSTER.
wavy_masks() {
    local seed=$1 dir=$2 c
    shift 2
    for c in "$@"; do
        mkdir -p "$dir/$c"
        cp "validation/evolver/fixtures/$c/truth.json" "$dir/$c/"
        target/release/tissuefit generate noise "validation/evolver/fixtures/$c/labels_10.tif" --amplitude 1 \
            --correlation 1.5 --seed "$seed" --out "$dir/$c/labels_10.tif" > /dev/null
    done
}
# roughen_fits DIR ROUGH WORK PREFIX OUT: fits of DIR's masks (denoise_voxels = 2) with the simulated
# masks roughened by ROUGH (auto, none or an RMS in voxels), their table appended to OUT under a
# heading that starts with PREFIX.
roughen_fits() {
    local dir=$1 rough=$2 work=$3 prefix=$4 out_file=$5 how
    mkdir -p "$work"
    local template="$work/template.toml"
    sed "s/^target_nodes = 400 .*/&\ndenoise_voxels = 2/" validation/evolver/fit-template.toml > "$template"
    case $rough in
        none) how="not roughened" ;;
        auto) how='roughened by `forward.roughen_voxels = "auto"` (correlation 1.5)'
              sed -i 's/^accept_residual = .*/&\nroughen_voxels = "auto"\nroughen_correlation = 1.5/' "$template" ;;
        *) how="roughened by the true noise, \`forward.roughen_voxels = $rough\` (correlation 1.5)"
           sed -i "s/^accept_residual = .*/&\nroughen_voxels = $rough\nroughen_correlation = 1.5/" "$template" ;;
    esac
    grep -q "^denoise_voxels = 2" "$template"
    python3 validation/evolver/run_fits.py --clusters "$dir" --resolutions 10 \
        --template "$template" --work "$work/runs" --markdown "$work/table.md"
    { echo "**${prefix}1 voxel RMS of wavy noise (--correlation 1.5), mesh.denoise_voxels = 2, simulated masks $how**"
      echo; cat "$work/table.md"; echo; } >> "$out_file"
}
if [ "$what" = roughen ] || [ "$what" = all ]; then
    cargo build --release
    work=$(mktemp -d)
    wavy_masks 1 "$work/wavy" doublet heldout_triplet ball12
    : > "$out/noise-roughen.md"
    for rough in ${ROUGHEN:-auto none 1.0}; do
        roughen_fits "$work/wavy" "$rough" "$work/$rough" "" "$out/noise-roughen.md"
    done
fi
if [ "$what" = roughen-seeds ] || [ "$what" = all ]; then
    # The doublet and held-out triplet of noise-roughen.md under other draws of the same noise
    # (SEEDS, default "2 3"), roughened "auto" and not at all: how much one draw moves a few-cell fit.
    cargo build --release
    work=$(mktemp -d)
    : > "$out/noise-roughen-seeds.md"
    for seed in ${SEEDS:-2 3}; do
        wavy_masks "$seed" "$work/wavy-$seed" doublet heldout_triplet
        for rough in auto none; do
            roughen_fits "$work/wavy-$seed" "$rough" "$work/$seed-$rough" "Noise seed $seed: " "$out/noise-roughen-seeds.md"
        done
    done
fi
if [ "$what" = noise-scatter ] || [ "$what" = all ]; then
    cargo build --release
    work=$(mktemp -d)
    fixtures=validation/evolver/fixtures
    seeds="1 2 3 4 5 6"
    # One mask: meshed as the fit template meshes the observed volume (400 nodes per cell), with the
    # documented denoise_voxels = 2, and measured; prints the cells' mean sphericity, mean contact
    # fraction and total volume (µm³).
    shape() {
        target/release/tissuefit -q mesh "$1" --target-nodes 400 --denoise-voxels 2 --out "$1.vtp" > /dev/null
        target/release/tissuefit -q measure "$1.vtp" --out "$1.measured" > /dev/null
        python3 -c 'import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
mean = lambda k: sum(float(r[k]) for r in rows) / len(rows)
print(mean("sphericity"), mean("contact_fraction"), sum(float(r["volume"]) for r in rows) * 1e18)' "$1.measured/cells.csv"
    }
    for c in doublet heldout_triplet; do
        cp "$fixtures/$c/labels_10.tif" "$work/$c-clean.tif"
        echo "$c clean $(shape "$work/$c-clean.tif")" >> "$work/shapes.txt"
        for noise in 0 1.5; do
            for seed in $seeds; do
                target/release/tissuefit -q generate noise "$fixtures/$c/labels_10.tif" --amplitude 1 \
                    --correlation "$noise" --seed "$seed" --out "$work/$c-$noise-$seed.tif" > /dev/null
                echo "$c $noise $(shape "$work/$c-$noise-$seed.tif")" >> "$work/shapes.txt"
            done
        done
    done
    python3 - "$work/shapes.txt" > "$out/noise-scatter.md" <<'PY'
import collections, statistics, sys
rows = collections.defaultdict(list)
for line in open(sys.argv[1]):
    cluster, noise, psi, phi, volume = line.split()
    rows[cluster, noise].append((float(psi), float(phi), float(volume)))
names = {"clean": "clean", "0": "salt-and-pepper (correlation 0)", "1.5": "wavy (correlation 1.5)"}
print("| cluster | mask (1 voxel RMS) | masks | mean sphericity | mean contact fraction | total volume vs clean |")
print("|---|---|---|---|---|---|")
for (cluster, noise), values in rows.items():
    clean_volume = rows[cluster, "clean"][0][2]
    def cell(i, digits, relative=False):
        xs = [v[i] / clean_volume * 100 - 100 if relative else v[i] for v in values]
        sign = "+" if relative else ""
        if len(xs) == 1:
            return "—" if relative else f"{xs[0]:.{digits}f}"
        return f"{statistics.mean(xs):{sign}.{digits}f} ± {statistics.stdev(xs):.{digits}f}" + (" %" if relative else "")
    print(f"| {cluster} | {names[noise]} | {len(values)} | {cell(0, 3)} | {cell(1, 3)} | {cell(2, 1, True)} |")
PY
fi
