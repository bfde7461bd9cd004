#!/usr/bin/env bash
# The Python package in CI: build the abi3 wheel with maturin, install it into a fresh virtual
# environment, run the API tests with no Rust toolchain on PATH (the wheel must not need one), then
# the napari plugin's tests (python/ci-napari.sh). Needs target/release/tissuefit (the CLI the tests
# compare with): .ci/run calls this after the Rust tests built it.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

python3 -m venv "$work/build"
"$work/build/bin/pip" install -q "maturin>=1.9,<2"
rm -rf target/wheels
"$work/build/bin/maturin" build --release --locked -m python/Cargo.toml -o target/wheels
wheel=$(ls target/wheels/tissuefit-*.whl)
echo "built $wheel"

python3 -m venv "$work/test"
"$work/test/bin/pip" install -q "$wheel[test]"
# From outside the source tree, so that `import tissuefit` is the installed wheel.
(cd "$work" && env PATH="$work/test/bin:/usr/local/bin:/usr/bin:/bin" TISSUEFIT_BIN="$root/target/release/tissuefit" \
    "$work/test/bin/python" -m pytest -q -p no:cacheprovider "$root/python/tests/test_api.py")

if [ -x python/ci-napari.sh ]; then
    python/ci-napari.sh "$wheel"
fi
