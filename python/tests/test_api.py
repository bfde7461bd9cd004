"""The Python API against the command line: the same stages, the same numbers.

Needs the built wheel installed (python/ci.sh) and the CLI binary (TISSUEFIT_BIN, default
target/release/tissuefit) for the comparisons.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import tissuefit as tf

# The short relaxations and fits here do not converge, on purpose; the tests that check the warning
# catch it with pytest.warns.
pytestmark = pytest.mark.filterwarnings("ignore::tissuefit.NotConverged")

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "data" / "demo" / "doublet.tif"
TRUTH = ROOT / "data" / "demo" / "doublet_truth.toml"
BIN = Path(os.environ.get("TISSUEFIT_BIN", ROOT / "target" / "release" / "tissuefit"))

# The demo pipeline's fit (pipelines/demo.toml) with a smaller budget: seconds, not a minute.
FIT = f"""
model = {json.dumps(str(TRUTH))}
[observed.meshing]
target_nodes = 200
seed = 0
[model_overrides.simulation]
max_steps = 1000
[parameters.surface_tension]
value = 1e-3
[parameters.surface_tension_lateral]
bounds = [2e-4, 1e-3]
initial = 8e-4
[objective]
sphericity = 1.0
contact_fraction = 0.0
coordination = 0.0
contact_angle = 0.0
[optimizer]
method = "nelder_mead"
max_evaluations = 6
tolerance = 0.01
seed = 0
[forward]
accept_residual = 1e9
[profile]
points = 1
span = 1.3
"""


def cli(*args: str) -> str:
    if not BIN.exists():
        pytest.fail(f"{BIN}: the tissuefit binary is needed for the comparison (cargo build --release, or TISSUEFIT_BIN)")
    done = subprocess.run([str(BIN), *args], capture_output=True, text=True)
    assert done.returncode == 0, f"tissuefit {' '.join(args)} failed:\n{done.stderr}"
    return done.stdout


@pytest.fixture(scope="module")
def demo():
    labels, voxel_size = tf.read_labels(DEMO)
    return labels, voxel_size


def test_read_labels_gives_the_files_labels_and_voxel_size(demo):
    labels, voxel_size = demo
    assert labels.dtype == np.uint32 and labels.shape == (19, 19, 25)
    assert sorted(np.unique(labels)) == [0, 1, 2]
    assert voxel_size == pytest.approx((0.31, 0.31, 0.31), rel=1e-6)
    assert voxel_size.origin == pytest.approx((0.93, 0.0, -0.31), abs=1e-9)
    # A voxel size given by the caller wins over the file's.
    _, given = tf.read_labels(DEMO, voxel_size=(0.5, 0.25, 0.25))
    assert given == pytest.approx((0.5, 0.25, 0.25))


def test_mesh_is_the_cli_mesh_bit_for_bit(demo, tmp_path):
    labels, voxel_size = demo
    tissue = tf.mesh(labels, voxel_size, target_nodes=200, seed=0)
    cli("mesh", str(DEMO), "--out", str(tmp_path / "t.vtp"), "--target-nodes", "200", "--seed", "0")
    written = tf.read_tissue(tmp_path / "t.vtp")
    assert len(tissue) == len(written) == 2
    for a, b in zip(tissue.cells, written.cells):
        assert a.id == b.id and a.kind == b.kind == "epithelial"
        np.testing.assert_array_equal(a.faces, b.faces)
        np.testing.assert_array_equal(a.vertices, b.vertices)
    report = json.loads((tmp_path / "t.report.json").read_text())
    assert tissue.l_min == pytest.approx(report["l_min"] / 1e-6, rel=1e-12)
    assert [r["status"] for r in tissue.report] == ["kept", "kept"]
    # Closed surfaces: Euler characteristic 2 (V - E + F with E = 3F/2), vertices inside the volume.
    for c in tissue.cells:
        assert len(c.vertices) - len(c.faces) * 3 // 2 + len(c.faces) == 2
        assert c.volume > 0 and c.area > 0
        lo = np.array(voxel_size.origin) - 0.31
        hi = lo + 0.31 * (np.array(labels.shape[::-1]) + 1)
        assert np.all(c.vertices >= lo) and np.all(c.vertices <= hi)


def test_mesh_denoised_is_the_cli_mesh_denoised_and_a_bad_sigma_is_refused(demo, tmp_path):
    labels, voxel_size = demo
    tissue = tf.mesh(labels, voxel_size, target_nodes=200, denoise_voxels=1.5)
    cli("mesh", str(DEMO), "--out", str(tmp_path / "d.vtp"), "--target-nodes", "200", "--denoise-voxels", "1.5")
    written = tf.read_tissue(tmp_path / "d.vtp")
    plain = tf.mesh(labels, voxel_size, target_nodes=200)
    for a, b, c in zip(tissue.cells, written.cells, plain.cells):
        np.testing.assert_array_equal(a.vertices, b.vertices)
        assert a.vertices.shape != c.vertices.shape or not np.array_equal(a.vertices, c.vertices)
    with pytest.raises(Exception, match="denoise_voxels"):
        tf.mesh(labels, voxel_size, denoise_voxels=-1.0)


def test_a_saved_tissue_reads_back_the_same_in_micrometres(demo, tmp_path):
    labels, voxel_size = demo
    tissue = tf.mesh(labels, voxel_size, target_nodes=200)
    tissue.save(tmp_path / "um.vtp")
    back = tf.read_tissue(tmp_path / "um.vtp")
    for a, b in zip(tissue.cells, back.cells):
        np.testing.assert_allclose(a.vertices, b.vertices, rtol=1e-12)
    assert b'length_unit' in (tmp_path / "um.vtp").read_bytes()


def read_csv(path: Path) -> list[dict]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def test_measure_gives_the_cli_tables_in_micrometres(demo, tmp_path):
    labels, voxel_size = demo
    tissue = tf.mesh(labels, voxel_size, target_nodes=200, seed=0)
    tissue.save(tmp_path / "t.vtp", unit="m")
    cli("measure", str(tmp_path / "t.vtp"), "--out", str(tmp_path / "m"), "--output-unit", "um")
    rows = read_csv(tmp_path / "m" / "cells.csv")
    m = tf.measure(tissue)
    assert list(m.cells["cell"]) == [int(r["cell"]) for r in rows]
    for column in ("volume_um3", "area_um2", "sphericity", "contact_fraction"):
        np.testing.assert_allclose(m.cells[column], [float(r[column]) for r in rows], rtol=1e-12)
    assert len(m.contacts["area_um2"]) == 1
    # On the voxels, like `tissuefit measure LABELS`.
    cli("measure", str(DEMO), "--out", str(tmp_path / "l"), "--output-unit", "um")
    on_voxels = tf.measure(labels, voxel_size)
    rows = read_csv(tmp_path / "l" / "cells.csv")
    np.testing.assert_allclose(on_voxels.cells["volume_um3"], [float(r["volume_um3"]) for r in rows], rtol=1e-12)
    frame = m.cells_frame()
    assert list(frame["cell"]) == [1, 2] and "volume_um3" in frame.columns


def test_tensions_are_the_cli_tensions(demo, tmp_path):
    labels, voxel_size = demo
    m = tf.tensions(labels, voxel_size, out=tmp_path / "py")
    cli("tensions", str(DEMO), "--out", str(tmp_path / "cli"))
    for name in ("interfaces.csv", "cells.csv"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    # Two cells: their contact and each one's free surface.
    assert sorted(zip(m.interfaces["cell_a"], m.interfaces["cell_b"])) == [(1, 0), (1, 2), (2, 0)]
    assert m.summary["tension_unit"] == "gauge" and len(m.pressure) == len(m.tissue) == 2
    for cell, faces in zip(m.tissue.cells, m.face_tension):
        assert faces.shape == (len(cell.faces),)
    free = m.interfaces["tension"][m.interfaces["cell_b"] == 0]
    assert np.nanmean(free) == pytest.approx(1.0)  # the default gauge: mean cell–medium tension = 1
    # Each cell's pressure about the mean of the two (they reach the medium: the same centring).
    p = np.asarray(m.cells["pressure"], dtype=float)
    assert np.asarray(m.cells["pressure_relative"], dtype=float) == pytest.approx(p - p.mean(), abs=1e-9)
    assert m.summary["spectral_gap"] is None or m.summary["spectral_gap"] > 1.0
    in_mn = tf.tensions(m.tissue, gauge_tension=0.5)
    assert in_mn.summary["tension_unit"] == "mN/m" and in_mn.summary["pressure_unit"] == "kPa"
    # --far-field, as the CLI's.
    glob = tf.tensions(labels, voxel_size, out=tmp_path / "py-global", far_field="global")
    cli("tensions", str(DEMO), "--out", str(tmp_path / "cli-global"), "--far-field", "global")
    assert (tmp_path / "py-global" / "interfaces.csv").read_bytes() == (tmp_path / "cli-global" / "interfaces.csv").read_bytes()
    assert glob.summary["far_field"] == "global" and m.summary["far_field"] == "auto"
    with pytest.raises(tf.TissuefitError, match="far field is one of global, local, auto"):
        tf.tensions(m.tissue, far_field="nearby")


def _y_junction_ply(angles_deg):
    """Three flat cells around one junction at the origin, walls along ``angles_deg``, as a PLY with
    a per-face ``label``: cell k + 1 spans the walls k and k + 1 out to radius 1 µm (its rim)."""
    a = np.radians(np.asarray(angles_deg, dtype=float))
    points, faces, index = [], [], {}

    def point(key, xy):
        if key not in index:
            index[key] = len(points)
            points.append((xy[0], xy[1], 0.0))
        return index[key]

    for k in range(3):
        lo, hi = a[k], a[(k + 1) % 3] + (2 * np.pi if k == 2 else 0.0)
        ring = [point("o", (0.0, 0.0))]
        ring += [point(("w", k, r), (r * np.cos(lo), r * np.sin(lo))) for r in (0.5, 1.0)]
        ring += [point(("rim", k, m), (np.cos(lo + (hi - lo) * m / 6), np.sin(lo + (hi - lo) * m / 6))) for m in range(1, 6)]
        ring += [point(("w", (k + 1) % 3, r), (r * np.cos(hi), r * np.sin(hi))) for r in (1.0, 0.5)]
        centre = point(("c", k), (0.5 * np.cos(0.5 * (lo + hi)), 0.5 * np.sin(0.5 * (lo + hi))))
        faces += [(centre, ring[i], ring[(i + 1) % len(ring)], k + 1) for i in range(len(ring))]
    text = "ply\nformat ascii 1.0\nelement vertex %d\nproperty double x\nproperty double y\nproperty double z\n" % len(points)
    text += "element face %d\nproperty list uchar int vertex_indices\nproperty int label\nend_header\n" % len(faces)
    text += "".join("%.17g %.17g %.17g\n" % p for p in points)
    text += "".join("3 %d %d %d %d\n" % f for f in faces)
    return text


def test_a_ply_sheet_gives_the_law_of_sines_at_its_junction(tmp_path):
    # Walls at 0°, 135° and 240°: each wall's tension ∝ the sine of the angle between the other two.
    path = tmp_path / "y.ply"
    path.write_text(_y_junction_ply([0.0, 135.0, 240.0]))
    sheet = tf.read_tissue(path, length_unit="um")
    m = tf.tensions(sheet, out=tmp_path / "py")
    assert m.summary["input"] == "sheet" and m.summary["junctions"] == 1
    want = {(1, 3): np.sin(np.radians(105)), (1, 2): np.sin(np.radians(120)), (2, 3): np.sin(np.radians(135))}
    mean = sum(want.values()) / 3
    got = {(a, b): t for a, b, t in zip(m.interfaces["cell_a"], m.interfaces["cell_b"], m.interfaces["tension"])}
    for pair, value in want.items():
        assert got[pair] == pytest.approx(value / mean, rel=1e-9), pair
    cli("tensions", str(path), "--length-unit", "um", "--out", str(tmp_path / "cli"))
    assert (tmp_path / "py" / "interfaces.csv").read_bytes() == (tmp_path / "cli" / "interfaces.csv").read_bytes()
    with pytest.raises(tf.TissuefitError, match="2.5-D cell sheet"):
        tf.tensions(sheet, gauge_tension=1.0)


def test_the_demo_fit_gives_the_cli_numbers_bit_for_bit(demo, tmp_path):
    # The README's demo: pipelines/demo.toml's [fit] (with its [input] seed and [mesh] settings), on
    # the volume read here, against `tissuefit fit --config pipelines/demo.toml`.
    labels, voxel_size = demo
    result = tf.fit(labels, voxel_size, config=ROOT / "pipelines" / "demo.toml", out=tmp_path / "py")
    cli("fit", "--config", str(ROOT / "pipelines" / "demo.toml"), "--out", str(tmp_path / "cli"))
    expected = json.loads((tmp_path / "cli" / "result.json").read_text())
    assert result.parameters == expected["parameters"] and result.ratios == expected["ratios"]
    assert result.converged is True and result.ok is True
    assert result.value("surface_tension_lateral") == expected["parameters"]["surface_tension_lateral"]["si"]
    assert 0.45 < result.value("lateral_over_apical") < 0.55  # the truth is 0.5
    py_trace, cli_trace = read_csv(tmp_path / "py" / "trace.csv"), read_csv(tmp_path / "cli" / "trace.csv")
    for a, b in zip(py_trace, cli_trace, strict=True):
        for key in ("surface_tension_lateral", "objective", "sphericity", "status"):
            assert a[key] == b[key]
    assert len(result.trace["objective"]) == len(py_trace)
    assert result.tissue is not None and len(result.tissue) == 2
    for name in ("best.vtp", "residuals.csv", "fit.toml", "objective.png"):
        assert (tmp_path / "py" / name).exists(), name
    assert list(result.residuals["cell"]) == [1, 2]
    # The best tissue in the pipeline's unit (demo.toml has no [output]: metres), as the CLI writes it.
    assert (tmp_path / "py" / "best.vtp").read_bytes() == (tmp_path / "cli" / "best.vtp").read_bytes()


def test_an_unconverged_fit_warns_and_says_so(demo, tmp_path):
    labels, voxel_size = demo
    with pytest.warns(tf.NotConverged, match="not converged"):
        result = tf.fit(labels, voxel_size, config=FIT, out=tmp_path / "py")
    assert result.converged is False and result.ok is False
    assert result.result["stop_reason"].startswith("evaluation budget of 6 spent")


# One refinement iteration on a doublet (coupled contacts, faces typed by contact), two sub-voxel
# placements per measurement so that every interval has its spread.
PER_CELL_DOUBLET = """
mode = "per_cell"
[observed.meshing]
target_nodes = 200
seed = 0
[model_overrides.numerics]
contact_model = "coupling"
polarity = "contacts"
dynamics = "overdamped"
damping = 3e-9
[model_overrides.simulation]
mode = "equilibrium"
method = "fire"
max_steps = 1500
settle_steps = 500
[forward]
accept_residual = 1e9
measure_shifts = 2
[per_cell]
iterations = 1
tolerance = 0.5
free_tension = 1e-3
"""


def test_a_per_cell_fit_returns_its_map_with_intervals_and_flags_what_a_doublet_leaves_open(demo, tmp_path):
    labels, voxel_size = demo
    config = PER_CELL_DOUBLET
    result = tf.fit(labels, voxel_size, config=config, out=tmp_path / "map")
    assert result.ok and result.result["mode"] == "per_cell" and result.tissue is not None and len(result.tissue) == 2
    assert list(result.cells["cell"]) == [1, 2] and list(result.interfaces["cell_b"]) == [0, 2, 0]
    # The free tensions average to the free tension asked for; each has an interval.
    assert np.mean(result.cells["free_tension_mn_per_m"]) == pytest.approx(1.0)
    assert np.all(result.cells["free_tension_sd_mn_per_m"] > 0)
    # A doublet fixes only the sum of its two lateral tensions: flagged, no number.
    assert list(result.cells["lateral_determined"]) == [False, False]
    assert np.all(np.isnan(result.cells["lateral_tension_mn_per_m"]))
    assert np.all(result.interfaces["tension_sd_mn_per_m"] > 0)
    assert set(result.interfaces["sd_source"]) == {"placements"}
    assert result.interfaces_frame().shape[0] == 3


def test_a_series_of_arrays_keeps_each_cell_its_id_and_starts_with_the_previous_correction(demo, tmp_path):
    # Frame 1: the demo doublet one voxel on, its two labels swapped, as the next time point's
    # segmentation numbers them.
    labels, voxel_size = demo
    moved = np.roll(labels, 1, axis=2)
    assert not labels[:, :, -1].any()
    swapped = np.where(moved == 1, 2, np.where(moved == 2, 1, 0)).astype(labels.dtype)
    config = PER_CELL_DOUBLET
    series = tf.fit_series([labels, swapped], voxel_size, config=config, out=tmp_path / "series")
    assert series.succeeded and len(series.result["frames"]) == 2
    later = series.tracks["frame"] == 1
    assert dict(zip(series.tracks["label"][later], series.tracks["track"][later])) == {1: 2, 2: 1}
    assert list(series.cells["frame"]) == [0, 0, 1, 1] and list(series.cells["cell"]) == [1, 2, 1, 2]
    assert list(series.cells["start"]) == ["direct estimate"] * 2 + ["corrected by previous frame"] * 2
    assert series.result["frames"][1]["previous_frame_cells"] == 2
    second = series.frame(1)
    assert second.ok and list(second.cells["cell"]) == [1, 2]
    with pytest.raises(tf.TissuefitError, match="not a mix"):
        tf.fit_series([labels, tmp_path / "x.tif"], voxel_size, config=config)


def test_a_fit_stopped_by_its_callback_raises_cancelled_and_resumes_to_the_same_result(demo, tmp_path):
    labels, voxel_size = demo
    seen: list[tuple] = []

    def stop_after_first_evaluations(stage, done, total, message):
        seen.append((stage, done, total, message))
        return not message.startswith("objective")  # the line written after each batch of evaluations

    with pytest.raises(tf.Cancelled, match="resume"):
        tf.fit(labels, voxel_size, config=FIT, out=tmp_path / "a", progress=stop_after_first_evaluations)
    assert seen and all(s[0] == "fit" for s in seen)
    kept = read_csv(tmp_path / "a" / "trace.csv")
    assert 1 <= len(kept) < 6
    assert not (tmp_path / "a" / "result.json").exists()
    resumed = tf.fit(labels, voxel_size, config=FIT, out=tmp_path / "a", resume=True)
    whole = tf.fit(labels, voxel_size, config=FIT, out=tmp_path / "b")
    assert resumed.parameters == whole.parameters and resumed.ratios == whole.ratios


def test_an_exception_in_the_callback_stops_the_call_and_is_raised():
    labels, voxel_size = tf.read_labels(DEMO)

    def boom(*_):
        raise ValueError("from the callback")

    with pytest.raises(ValueError, match="from the callback"):
        tf.mesh(labels, voxel_size, progress=boom)


def test_long_calls_release_the_gil(demo, tmp_path):
    labels, voxel_size = demo
    ticks = 0
    running = threading.Event()

    def count():
        nonlocal ticks
        while not running.is_set():
            ticks += 1
            time.sleep(0.001)

    counter = threading.Thread(target=count)
    counter.start()
    try:
        tissue = tf.mesh(labels, voxel_size, target_nodes=200)
        before = ticks
        tf.simulate(tissue, TRUTH, overrides={"simulation": {"max_steps": 400}}, out=tmp_path / "s")
    finally:
        running.set()
        counter.join()
    assert ticks - before > 20, "the counting thread did not run while the simulation ran"


def test_simulate_runs_the_stage_into_its_folder_and_stops_on_request(demo, tmp_path):
    labels, voxel_size = demo
    tissue = tf.mesh(labels, voxel_size, target_nodes=200, seed=0)
    with pytest.warns(tf.NotConverged, match="did not converge"):
        sim = tf.simulate(tissue, TRUTH, overrides={"simulation": {"max_steps": 300}}, out=tmp_path / "s")
    assert sim.summary["steps"] == 300 and sim.summary["converged"] is False and len(sim.tissue) == 2
    for name in ("input.vtp", "final.vtp", "summary.json", "config.toml", "stats.csv"):
        assert (tmp_path / "s" / name).exists(), name
    # The same relaxation from the command line, on the folder's own input and config.
    done = subprocess.run([str(BIN), "simulate", str(tmp_path / "s" / "input.vtp"), "--config",
                           str(tmp_path / "s" / "config.toml"), "--out", str(tmp_path / "c")], capture_output=True, text=True)
    assert done.returncode == 1 and "NOT converged" in done.stderr, done.stderr
    cli_final = tf.read_tissue(tmp_path / "c" / "final.vtp")
    for a, b in zip(sim.tissue.cells, cli_final.cells):
        np.testing.assert_array_equal(a.vertices, b.vertices)
    with pytest.raises(tf.TissuefitError, match="already holds"):
        tf.simulate(tissue, TRUTH, out=tmp_path / "s")
    calls = []

    def stop(stage, done, total, message):
        calls.append(done)
        return done < 64

    with pytest.raises(tf.Cancelled, match="checkpoint"):
        tf.simulate(tissue, TRUTH, overrides={"simulation": {"max_steps": 100000}}, out=tmp_path / "x", progress=stop)
    assert (tmp_path / "x" / "checkpoint.bin").exists()


@pytest.mark.parametrize(
    "labels, voxel_size, message",
    [
        (np.zeros((4, 4), np.uint16), 1.0, "3D array"),
        (np.full((4, 4, 4), 0.5), 1.0, "integer labels"),
        (np.full((4, 4, 4), -1, np.int32), 1.0, "negative label"),
        (np.ones((4, 4, 4), np.uint16), 3.1e-7, "did you give metres"),
        (np.ones((4, 4, 4), np.uint16), (1.0, 1.0), "three"),
        (np.zeros((4, 4, 4), np.uint16), 1.0, "no labels"),
    ],
)
def test_bad_labels_raise_tissuefit_errors_that_say_why(labels, voxel_size, message):
    with pytest.raises(tf.TissuefitError, match=message):
        tf.mesh(labels, voxel_size)


def test_bad_configs_and_files_raise_tissuefit_errors_naming_them(demo, tmp_path):
    labels, voxel_size = demo
    with pytest.raises(tf.TissuefitError, match="optimiser"):
        tf.fit(labels, voxel_size, config=FIT.replace("[optimizer]", "[optimiser]"), out=tmp_path / "f")
    with pytest.raises(tf.TissuefitError, match="not a file"):
        tf.fit(labels, voxel_size, config=tmp_path / "missing.toml")
    with pytest.raises(tf.TissuefitError, match="voxel_size"):
        tf.fit(labels, None, config=FIT)
    with pytest.raises(tf.TissuefitError, match="nothing.tif"):
        tf.read_labels(tmp_path / "nothing.tif")
    (tmp_path / "bad.vtp").write_text("<VTKFile><broken")
    with pytest.raises(tf.TissuefitError, match="bad.vtp"):
        tf.read_tissue(tmp_path / "bad.vtp")
    tissue = tf.mesh(labels, voxel_size, target_nodes=200)
    with pytest.raises(tf.TissuefitError, match="max_stepz"):
        tf.simulate(tissue, overrides={"simulation": {"max_stepz": 3}}, out=tmp_path / "s")


def test_the_package_needs_no_rust_toolchain():
    # The wheel is self-contained: the extension module lies in the package.
    assert Path(tf._native.__file__).parent == Path(tf.__file__).parent
    # Typed (PEP 561) and with its napari manifest.
    assert (Path(tf.__file__).parent / "py.typed").exists()
    assert (Path(tf.__file__).parent / "napari" / "napari.yaml").exists()
    assert shutil.which("cargo") is None or os.environ.get("TISSUEFIT_ALLOW_CARGO") == "1"


ZARR = ROOT / "tests" / "data" / "python_zarr"


def test_ome_zarr_v2_and_v3_stores_read_with_their_anisotropic_scale_and_levels():
    # Fixtures written by the Python zarr/ome-zarr packages (tests/data/python_zarr/make.py).
    v2, size2 = tf.read_labels(ZARR / "cells_v2.zarr")
    v3, size3 = tf.read_labels(ZARR / "cells_v3.zarr")
    np.testing.assert_array_equal(v2, v3)
    assert v2.shape == (6, 10, 12)
    assert size2 == pytest.approx((0.8, 0.25, 0.25)) and size3 == pytest.approx((0.8, 0.25, 0.25))
    coarse, size = tf.read_labels(ZARR / "cells_v3.zarr", zarr_level=1)
    assert coarse.shape == (6, 5, 6) and size == pytest.approx((0.8, 0.5, 0.5))
    with pytest.raises(tf.TissuefitError, match="scale level 5"):
        tf.read_labels(ZARR / "cells_v3.zarr", zarr_level=5)
    with pytest.raises(tf.TissuefitError, match="OME-Zarr stores only"):
        tf.read_labels(DEMO, zarr_level=1)
    a = tf.measure(v2, size2, min_voxels=1)
    b = tf.measure(v3, size3, min_voxels=1)
    np.testing.assert_allclose(a.cells["volume_um3"], b.cells["volume_um3"], rtol=1e-12)
