#!/usr/bin/env bash
# Regenerates the table of FIRE's measured masses on SimuCell3D's doublet and triplet
# (docs/src/design/young-dupre.md, "Why SimuCell3D's doublet does not converge"): each run is
# `tissuefit simulate FILE` with the mesh-derived defaults and the face quadrature, with or without
# simulation.normal_relaxation and simulation.fire_measured_masses, at most 20,000 steps; and the
# stiffest mode (examples/stiff_modes.rs) of the run without the masses, where it ends.
#   docs/src/generated/measured-masses.md   the table and the stiffest mode
# Needs ../shared/data/real. Usage: docs/scripts/measured-masses.sh. About 5 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/../.."
real=../shared/data/real
[ -d "$real" ] || { echo "measured-masses.sh: $real is missing" >&2; exit 1; }
cargo build --release --bin tissuefit --example stiff_modes
bin=target/release/tissuefit
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
out=docs/src/generated/measured-masses.md

# name | file | quadrature | normal_relaxation | fire_measured_masses | threads
runs=(
    "doublet|simucell3d__cell_doublet.vtk|faces|true|true|2"
    "triplet|simucell3d__cell_triplet.vtk|faces|true|true|2"
    "doublet, without the masses|simucell3d__cell_doublet.vtk|faces|true|false|2"
    "doublet, masses with the full forces|simucell3d__cell_doublet.vtk|faces|false|true|2"
    "doublet, masses, full forces, vertex quadrature|simucell3d__cell_doublet.vtk|vertices|false|true|2"
)
{
    echo "| run | quadrature | normal relaxation | measured masses | converged | steps | wall / CPU s (threads) | residual | out-of-turn repairs | bending energy (J) | far-field angles (°) |"
    echo "|---|---|---|---|---|---|---|---|---|---|---|"
    for i in "${!runs[@]}"; do
        IFS='|' read -r name file quadrature normal measured threads <<< "${runs[$i]}"
        printf '[numerics]\ncontact_quadrature = "%s"\n[simulation]\nnormal_relaxation = %s\nfire_measured_masses = %s\n' \
            "$quadrature" "$normal" "$measured" > "$work/$i.toml"
        /usr/bin/time -f "%e %U %S" -o "$work/time" "$bin" --threads "$threads" simulate "$real/$file" \
            --config "$work/$i.toml" --max-steps 20000 --out "$work/$i" -q 2> "$work/err" || true
        read -r wall user sys < <(tail -n 1 "$work/time")
        python3 - "$work/$i" "$name" "$quadrature" "$normal" "$measured" "$wall" "$user" "$sys" "$threads" <<'EOF'
import csv, json, sys
run, name, quadrature, normal, measured, wall, user, sys_, threads = sys.argv[1:]
s = json.load(open(f"{run}/summary.json"))
angles = []
with open(f"{run}/contacts.csv") as f:
    for row in csv.DictReader(f):
        a = row.get("far_field_angle_deg") or ""
        angles.append(f"{float(a):.1f}" if a else "none fitted")
print(f"| {name} | {quadrature} | {normal} | {measured} | {'yes' if s['converged'] else 'no'} | {s['steps']:,} | "
      f"{float(wall):.1f} / {float(user) + float(sys_):.1f} ({threads}) | {s['residual']:.2e} | "
      f"{s['topology']['need_passes']} | {s['energy']['bending']:.2e} | {', '.join(angles)} |")
EOF
    done
    d=$(python3 -c "import json; s = json.load(open('$work/2/summary.json')); \
print(next(x['value'] for x in s['mesh_defaults']['derived'] if x['key'] == 'numerics.contact_cutoff'))")
    python3 -c "import math; r = 1e9 * $d ** 2 / (4 * 1e-3); \
print(f'\nYoung–Dupré for the doublet: w/(2γ) = ωc²/(4γ) = {r:.3f} (c = {$d * 1e6:.3f} µm), θ = {2 * math.degrees(math.acos(1 - r)):.1f}°.')"
    echo
    echo "The stiffest mode where the run without the masses ends (\`cargo run --release --example stiff_modes -- final.vtk config.toml\`):"
    echo
    echo '```text'
    target/release/examples/stiff_modes "$work/2/final.vtk" "$work/2/config.toml"
    echo '```'
} > "$out"
echo "wrote $out"
