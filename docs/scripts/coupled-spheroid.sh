#!/usr/bin/env bash
# Regenerates docs/src/generated/coupled-spheroid.md (docs: guide, Simulation, the coupling model):
# a generated 200-cell spheroid relaxed 1,000 steps with the coupled model, its convergence, cells
# passing through each other and folded surfaces (validation/coupled/spheroid_report.py; needs numpy;
# about 3 minutes on 2 cores), with the junction groups matched afresh at every evaluation (the
# default) and with numerics.coupling_persistent_junctions = true.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
md=docs/src/generated/coupled-spheroid.md
exe=target/release/tissuefit
python3 validation/coupled/spheroid_report.py "$exe" "$work" --label "matched afresh (default)" --markdown "$md"
python3 validation/coupled/spheroid_report.py "$exe" "$work" --persistent --label "persistent" --markdown "$md" --append
