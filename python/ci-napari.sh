#!/usr/bin/env bash
# Tests of the napari plugin, headless: python/ci-napari.sh WHEEL
# (`python/ci-napari.sh --system-packages-only` only installs the Debian packages: .ci/prefetch.sh)
#
# Makes a venv, installs WHEEL with its napari extra plus napari's Qt backend (PyQt5) and the test
# tools, installs the Debian packages a headless Qt + OpenGL needs when missing (Xvfb, the xcb libraries
# of Qt's xcb platform plugin, Mesa's software GL), and runs python/tests/test_napari.py under Xvfb.
# Run from anywhere; it uses the repository this script is in. Env: PYTHON (default python3),
# VENV (default a new temporary folder, removed at the end), PYTEST_ARGS (extra pytest arguments).
set -euo pipefail

SYSTEM_ONLY=0
if [ "${1:-}" = --system-packages-only ]; then
    SYSTEM_ONLY=1
elif [ $# -ne 1 ] || [ ! -f "$1" ]; then
    echo "usage: $0 path/to/tissuefit-*.whl   (or --system-packages-only)" >&2
    exit 2
else
    WHEEL=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
fi
REPO=$(cd "$(dirname "$0")/.." && pwd)
PYTHON=${PYTHON:-python3}

say() { echo "ci-napari: $*"; }

# --- Debian packages: Xvfb, Qt's xcb platform plugin's libraries, Mesa (software OpenGL)
PKGS="xvfb xauth libgl1 libegl1 libgl1-mesa-dri libglib2.0-0 libfontconfig1 libdbus-1-3 \
libxkbcommon-x11-0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1 libxcb-randr0 libxcb-render-util0 \
libxcb-xinerama0 libxcb-xfixes0 libxcb-shape0 libxcb-cursor0 libxcb-xkb1"
if ! "$PYTHON" -c "import ensurepip, venv" 2>/dev/null; then
    PKGS="$PKGS python3-venv"   # Debian's python3 has venv's pip only from this package
fi
MISSING=""
for p in $PKGS; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        MISSING="$MISSING $p"
    fi
done
if [ -n "$MISSING" ]; then
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
    say "installing Debian packages:$MISSING"
    $SUDO apt-get update -q
    # shellcheck disable=SC2086
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q $MISSING
else
    say "Debian packages present: $PKGS"
fi
if [ "$SYSTEM_ONLY" = 1 ]; then
    exit 0
fi

# --- venv with the wheel, napari and the test tools
if [ -n "${VENV:-}" ]; then
    KEEP_VENV=1
else
    VENV=$(mktemp -d -t tissuefit-napari-venv.XXXXXX)
    KEEP_VENV=0
fi
cleanup() { if [ "$KEEP_VENV" = 0 ]; then rm -rf "$VENV"; fi; }
trap cleanup EXIT
say "venv $VENV ($($PYTHON --version))"
"$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --upgrade pip
say "installing $WHEEL[napari] pyqt5 pytest pytest-qt"
"$VENV/bin/python" -m pip install -q "$WHEEL[napari]" "napari[pyqt5]>=0.5" pytest pytest-qt
"$VENV/bin/python" -m pip list 2>/dev/null | grep -i -E '^(tissuefit|napari|npe2|pyqt5|vispy|magicgui|pytest|pytest-qt) ' || true

# --- the tests, under Xvfb (a GL context for the screenshot), from outside the source tree so that
# the installed package is the one imported
say "running python/tests/test_napari.py under xvfb-run"
cd "$(mktemp -d)"
set +e
# shellcheck disable=SC2086
QT_API=pyqt5 xvfb-run -a -s "-screen 0 1280x1024x24" \
    "$VENV/bin/python" -m pytest "$REPO/python/tests/test_napari.py" -v -s -p no:cacheprovider \
    --rootdir "$REPO/python" --disable-warnings ${PYTEST_ARGS:-}
rc=$?
set -e
say "pytest exit status $rc"
exit $rc
