#!/usr/bin/env bash
# Network-bound installs of the later CI phases, run by .ci/run in the background while the Rust
# build and tests keep the CPUs busy: `.ci/prefetch.sh system` installs the Debian packages of the
# Slurm phase and of the napari tests (the scripts of those phases install only what is missing, so
# they then find everything present) and, with VENV set, the napari tests' Python environment there
# (python/ci-napari.sh reuses a VENV it is given); `.ci/prefetch.sh mdbook` compiles mdbook for the
# docs phase. Both run at the lowest CPU priority where they compute, so that they take the cycles
# the tests leave idle. On the 2-core development machine, from a fresh machine: apt-get update 4 s,
# Slurm 10 s, napari's Debian packages 10 s, the napari venv 90 s (52 s CPU), mdbook ~90 s of compilation.
# Nothing here is required: a step that fails is reported and the phase that needs it installs it
# itself (and fails there, with its own message, if it cannot).
set -uo pipefail
cd "$(dirname "$0")/.."

case "${1:-}" in
system)
    # apt-get's lock: these two run one after the other, and .ci/run waits for this job before the
    # phases that call apt-get themselves.
    TISSUEFIT_SLURM_OPTIONAL=1 .ci/slurm-test.sh --install-only || echo "prefetch: Slurm install failed"
    python/ci-napari.sh --system-packages-only || echo "prefetch: napari's Debian packages failed"
    # The napari test environment (python/ci-napari.sh's requirements, python/pyproject.toml's napari
    # and test extras) into $VENV, which ci-napari.sh then reuses: only the wheel is left to install.
    if [ -n "${VENV:-}" ]; then
        if python3 -m venv "$VENV" && "$VENV/bin/python" -m pip install -q --upgrade pip; then
            nice -n 19 "$VENV/bin/python" -m pip install -q "napari[pyqt5]>=0.5" magicgui qtpy pytest pytest-qt \
                "pandas>=1.5" "numpy>=1.23" || echo "prefetch: pip install into $VENV failed"
        else
            echo "prefetch: no python3 venv with pip"
        fi
    fi
    ;;
mdbook)
    if ! command -v mdbook >/dev/null 2>&1; then
        nice -n 19 cargo install mdbook --locked --quiet || echo "prefetch: cargo install mdbook failed"
    fi
    ;;
*)
    echo "usage: $0 system|mdbook" >&2
    exit 2
    ;;
esac
