"""Tests of the napari plugin (tissuefit.napari), headless.

They need the real tissuefit package (built wheel), napari with a Qt backend, pytest-qt and a display:
run under Xvfb (python/ci-napari.sh does all of it), e.g.
``xvfb-run -a python -m pytest python/tests/test_napari.py``. The screenshot test needs a GL context,
which Xvfb + Mesa give and QT_QPA_PLATFORM=offscreen does not.
"""

from __future__ import annotations

import importlib.metadata
import os
import re
import time
from pathlib import Path

import numpy as np
import pytest

import tissuefit  # the real package: no test here runs without it

napari = pytest.importorskip("napari")  # noqa: E402  (CI installs it; the module is for napari only)

from napari.layers import Surface  # noqa: E402

import tissuefit.napari as tn  # noqa: E402
from tissuefit.napari import _layers, _widgets  # noqa: E402
from tissuefit.napari._reader import get_reader  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
DEMO_LABELS = REPO / "data" / "demo" / "doublet.tif"
DEMO_PIPELINE = REPO / "pipelines" / "demo.toml"
MANIFEST = Path(tn.__file__).with_name("napari.yaml")

#: seconds a widget run may take before the test gives up
RUN_TIMEOUT_MS = 180_000


# ----------------------------------------------------------------------------- fixtures and helpers
@pytest.fixture(scope="module")
def demo():
    labels, voxel = tissuefit.read_labels(str(DEMO_LABELS))
    return labels, tuple(float(v) for v in voxel)


def short_fit_config(path: Path, max_evaluations: int = 4) -> Path:
    """The demo pipeline's [fit] table as a stand-alone fit config, with a small budget, no profile."""
    text = DEMO_PIPELINE.read_text()
    start = text.index("\n[fit]")
    end = text.index("\n[demo]")
    fit = text[start:end]
    fit = fit.replace("\n[fit]", "\n", 1)
    fit = re.sub(r"^\[fit\.", "[", fit, flags=re.M)
    model = (REPO / "data" / "demo" / "doublet_truth.toml").as_posix()
    fit, n_model = re.subn(r'^model = "[^"]*"', f'model = "{model}"', fit, flags=re.M)
    fit, n_eval = re.subn(
        r"^max_evaluations = \d+", f"max_evaluations = {max_evaluations}", fit, flags=re.M
    )
    fit, n_points = re.subn(r"^points = \d+", "points = 0", fit, flags=re.M)
    assert (n_model, n_eval, n_points) == (1, 1, 1), "pipelines/demo.toml's [fit] table changed shape"
    path.write_text(fit)
    return path


@pytest.fixture
def notes(monkeypatch):
    """What the widgets showed the user through napari's notifications: [(level, message)]."""
    seen: list[tuple[str, str]] = []
    for level in ("error", "warning", "info"):
        monkeypatch.setattr(
            _widgets, f"show_{level}", lambda msg, _level=level: seen.append((_level, str(msg)))
        )
    # and what reached napari's notification manager as an error by another way (e.g. a worker's
    # relay of an exception it raised): recorded as ("error", ...) too
    from napari.utils.notifications import notification_manager

    monkeypatch.setattr(
        notification_manager,
        "receive_error",
        lambda exctype, value, tb=None, thread=None: seen.append(("error", f"napari: {value!r}")),
    )
    return seen


def add_demo(viewer, demo):
    labels, voxel = demo
    return viewer.add_labels(labels, scale=voxel, name="doublet")


def dock(viewer, widget_class):
    widget = widget_class(viewer)
    viewer.window.add_dock_widget(widget, name=widget_class.__name__)
    return widget


def wait_run(qtbot, widget, timeout=RUN_TIMEOUT_MS):
    qtbot.waitUntil(lambda: not widget.running, timeout=timeout)
    qtbot.wait(10)  # let the queued progress signals drain


def differing_pixels(a: np.ndarray, b: np.ndarray) -> int:
    return int((np.abs(a[..., :3].astype(int) - b[..., :3].astype(int)).sum(-1) > 30).sum())


# ----------------------------------------------------------------------------- pure conversions
def test_surface_data_matches_cells(demo):
    labels, voxel = demo
    tissue = tissuefit.mesh(labels, voxel, seed=0, target_nodes=200)
    verts, faces, values = _layers.surface_data(tissue)
    n = sum(len(c.vertices) for c in tissue.cells)
    assert verts.shape == (n, 3) and values.shape == (n,)
    assert faces.shape == (sum(len(c.faces) for c in tissue.cells), 3)
    assert faces.min() == 0 and faces.max() == n - 1
    # (x, y, z) µm -> napari (z, y, x), on top of the labels: every cell's vertices lie within its
    # label's bounding box (in µm, voxel centres at index·size) padded by two voxels
    offset = 0
    for cell in tissue.cells:
        v = verts[offset : offset + len(cell.vertices)]
        assert np.all(values[offset : offset + len(cell.vertices)] == cell.id)
        idx = np.argwhere(labels == cell.id)
        lo = idx.min(0) * np.array(voxel) - 2 * np.array(voxel)
        hi = idx.max(0) * np.array(voxel) + 2 * np.array(voxel)
        assert np.all(v >= lo) and np.all(v <= hi), cell.id
        offset += len(cell.vertices)
    # per-cell values
    data, kwargs, kind = _layers.surface_layer_data(
        tissue, "t", color_by="volume", values={c.id: c.volume for c in tissue.cells}
    )
    assert kind == "surface"
    assert set(np.unique(data[2])) == {c.volume for c in tissue.cells}
    assert kwargs["contrast_limits"][0] < kwargs["contrast_limits"][1]


def test_voxel_size_from_layer_units():
    from napari.layers import Labels

    layer = Labels(np.zeros((2, 3, 4), np.uint16), scale=(0.5, 0.31, 0.31), name="l")
    assert _layers.voxel_size_um(layer) == pytest.approx((0.5, 0.31, 0.31))
    if not hasattr(layer, "units"):
        pytest.skip("this napari's layers have no units (napari < 0.6)")
    layer.units = ("nm", "nm", "nm")
    layer.scale = (500, 310, 310)
    assert _layers.voxel_size_um(layer) == pytest.approx((0.5, 0.31, 0.31))
    assert _layers.um_per_layer_unit(layer) == pytest.approx((1e-3, 1e-3, 1e-3))
    with pytest.raises(ValueError, match="3-D"):
        _layers.labels_volume(Labels(np.zeros((3, 4), np.uint16), name="flat"))


def test_manifest_valid():
    import npe2

    manifest = npe2.PluginManifest.from_file(str(MANIFEST))
    assert manifest.name == "tissuefit"
    widgets = {w.display_name for w in manifest.contributions.widgets}
    assert widgets == {"Mesh labels", "Fit tissue mechanics"}


def test_manifest_entry_point_installed():
    """The installed distribution registers the manifest (pyproject's napari.manifest entry point)."""
    eps = importlib.metadata.entry_points(group="napari.manifest")
    assert any(ep.name == "tissuefit" and ep.value == "tissuefit.napari:napari.yaml" for ep in eps), [
        (ep.name, ep.value) for ep in eps
    ]


# ----------------------------------------------------------------------------- mesh widget
def test_mesh_widget_adds_surface(make_napari_viewer, qtbot, demo, notes):
    viewer = make_napari_viewer()
    layer = add_demo(viewer, demo)
    w = dock(viewer, _widgets.MeshWidget)
    assert w.layer_combo.currentText() == "doublet"
    assert w.voxel_label.text().startswith("z 0.31, y 0.31, x 0.31 µm")
    viewer.add_labels(np.zeros((2, 2, 2), np.uint16), name="other")
    layer.name = "doublet renamed"
    assert [w.layer_combo.itemText(i) for i in range(w.layer_combo.count())] == [
        "doublet renamed",
        "other",
    ]
    assert w.layer_combo.currentText() == "doublet renamed"
    layer.name = "doublet"
    w.nodes_spin.setValue(200)
    w.run()
    wait_run(qtbot, w)
    assert w.last_error is None, w.last_error
    surfaces = [l for l in viewer.layers if isinstance(l, Surface)]
    assert len(surfaces) == 1 and surfaces[0] is w.surface_layer
    expected = tissuefit.mesh(demo[0], demo[1], seed=0, target_nodes=200)
    n = sum(len(c.vertices) for c in expected.cells)
    assert len(w.surface_layer.vertices) == n
    assert sorted(np.unique(w.surface_layer.vertex_values)) == sorted(c.id for c in expected.cells)
    assert w.surface_layer.name == "doublet mesh"
    np.testing.assert_allclose(w.surface_layer.translate, layer.translate)
    assert w.progress_bar.text() == "done" or w.progress_bar.format() == "done"


def test_mesh_widget_without_labels_says_so(make_napari_viewer, notes):
    viewer = make_napari_viewer()
    w = dock(viewer, _widgets.MeshWidget)
    w.run()
    assert not w.running
    assert notes and notes[-1][0] == "error" and "Labels layer" in notes[-1][1]


def test_mesh_widget_shows_tissuefit_errors(make_napari_viewer, qtbot, notes):
    viewer = make_napari_viewer()
    viewer.add_labels(np.zeros((8, 8, 8), np.uint16), scale=(0.31, 0.31, 0.31), name="empty")
    w = dock(viewer, _widgets.MeshWidget)
    w.run()
    wait_run(qtbot, w)
    assert isinstance(w.last_error, tissuefit.TissuefitError), w.last_error
    assert notes and notes[-1][0] == "error" and notes[-1][1].startswith("tissuefit error: ")
    assert not [l for l in viewer.layers if isinstance(l, Surface)]
    assert w.run_button.isEnabled()


# ----------------------------------------------------------------------------- fit widget
def test_fit_widget_needs_a_config(make_napari_viewer, demo, notes):
    viewer = make_napari_viewer()
    add_demo(viewer, demo)
    w = dock(viewer, _widgets.FitWidget)
    w.run()
    assert not w.running
    assert notes[-1] == ("error", _widgets.NO_CONFIG_MESSAGE)
    assert w.status_label.text() == _widgets.NO_CONFIG_MESSAGE


def test_fit_widget_short_fit(make_napari_viewer, qtbot, demo, notes, tmp_path):
    viewer = make_napari_viewer(show=True)
    labels_layer = add_demo(viewer, demo)
    w = dock(viewer, _widgets.FitWidget)
    w.config_edit.setText(str(short_fit_config(tmp_path / "fit.toml")))
    w.out_edit.setText(str(tmp_path / "fit"))
    w.nodes_spin.setValue(200)
    reports = []
    w._bridge.report.connect(lambda *a: reports.append(a))
    t0 = time.perf_counter()
    w.run()
    wait_run(qtbot, w)
    elapsed = time.perf_counter() - t0
    assert w.last_error is None, w.last_error
    result = w.result
    assert result is not None and result.tissue is not None
    assert reports, "the progress callback never reported"
    assert (tmp_path / "fit" / "result.json").is_file()

    # one Surface layer, named and flagged honestly
    surfaces = [l for l in viewer.layers if isinstance(l, Surface)]
    assert surfaces == [w.surface_layer]
    layer = w.surface_layer
    assert len(layer.vertices) == sum(len(c.vertices) for c in result.tissue.cells) > 0
    assert bool(result.converged) == bool(result.result["converged"])
    # 4 evaluations: the optimiser stops on its budget, and the widget says so
    assert not result.converged, "a 4-evaluation fit of the demo should stop on its budget"
    if result.converged:  # pragma: no cover - kept for when the assertion above is relaxed
        assert "NOT converged" not in layer.name
    else:
        assert "NOT converged" in layer.name
        assert "NOT converged" in w.result_label.text()
        assert notes[-1][0] == "warning" and "NOT converged" in notes[-1][1]
    # the results table: every parameter and ratio with its range
    names = [w.table.item(i, 0).text() for i in range(w.table.rowCount())]
    assert set(result.parameters) | set(result.ratios) == set(names)
    fitted = names.index("surface_tension_lateral")
    assert w.table.item(fitted, 3).text() == "yes"
    lo, hi = result.parameters["surface_tension_lateral"]["range"]
    assert w.table.item(fitted, 2).text() == f"[{lo:.4g}, {hi:.4g}]"
    value = result.value("surface_tension_lateral")
    assert w.table.item(fitted, 1).text() == f"{value:.4g}"

    # colour by a measured per-cell quantity, then back to cell id
    choices = [w.color_combo.itemText(i) for i in range(w.color_combo.count())]
    assert choices[0] == _layers.CELL_ID and len(choices) > 1
    measured = next(c for c in choices if c != _layers.CELL_ID and not c.startswith("residual"))
    w.color_combo.setCurrentText(measured)
    per_cell = w._choices[measured]
    assert set(np.unique(layer.vertex_values)) == set(per_cell.values())
    lo, hi = min(per_cell.values()), max(per_cell.values())
    if hi > lo:
        np.testing.assert_allclose(layer.contrast_limits, (lo, hi))
    w.color_combo.setCurrentText(_layers.CELL_ID)
    ids = {c.id for c in result.tissue.cells}
    assert set(np.unique(layer.vertex_values)) == ids
    np.testing.assert_allclose(layer.contrast_limits, (min(ids) - 1, max(ids) + 1))

    # the surface is drawn: a 3-D screenshot differs from one with the surface hidden
    labels_layer.visible = False
    viewer.dims.ndisplay = 3
    viewer.reset_view()
    qtbot.wait(50)
    with_surface = viewer.screenshot(canvas_only=True, flash=False)
    layer.visible = False
    qtbot.wait(50)
    without = viewer.screenshot(canvas_only=True, flash=False)
    changed = differing_pixels(with_surface, without)
    assert changed > 0.01 * with_surface.shape[0] * with_surface.shape[1], changed
    print(f"short fit (4 evaluations) in the widget: {elapsed:.1f} s; {changed} surface pixels")

    # the reader opens the fit folder's best.vtp
    reader = get_reader(result.out)
    assert reader is not None
    (data, kwargs, kind), = reader(result.out)
    assert kind == "surface" and kwargs["name"].endswith("fit best")
    assert len(data[0]) == len(layer.vertices)


def test_fit_widget_demo_pipeline_timing(make_napari_viewer, qtbot, demo, notes, tmp_path):
    """The demo's own fit (pipelines/demo.toml, a pipeline file) run from the widget; times it."""
    viewer = make_napari_viewer()
    add_demo(viewer, demo)
    w = dock(viewer, _widgets.FitWidget)
    w.config_edit.setText(str(DEMO_PIPELINE))
    w.out_edit.setText(str(tmp_path / "fit"))
    w.nodes_spin.setValue(200)
    w.run()
    wait_run(qtbot, w)
    assert w.last_error is None, w.last_error
    assert w.surface_layer is not None and len(w.surface_layer.vertices) > 0
    ratio = w.result.ratios["lateral_over_apical"]["value"]
    print(
        f"demo fit in the widget: {w.last_run_seconds:.1f} s, converged {w.result.converged}, "
        f"poor_fit {w.result.poor_fit}, lateral_over_apical {ratio:.3f} (truth 0.5)"
    )
    assert ("NOT converged" in w.surface_layer.name) == (not w.result.converged)


def test_fit_widget_cancel(make_napari_viewer, qtbot, demo, notes, tmp_path):
    viewer = make_napari_viewer()
    add_demo(viewer, demo)
    w = dock(viewer, _widgets.FitWidget)
    w.config_edit.setText(str(short_fit_config(tmp_path / "fit.toml", max_evaluations=50)))
    w.out_edit.setText(str(tmp_path / "fit"))
    # press Cancel as soon as the first progress report reaches the GUI
    w._bridge.report.connect(lambda *a: w.cancel())
    w.run()
    assert w.running
    wait_run(qtbot, w)
    assert isinstance(w.last_error, tissuefit.Cancelled), w.last_error
    assert not [l for l in viewer.layers if isinstance(l, Surface)]
    assert w.run_button.isEnabled() and not w.cancel_button.isEnabled()
    assert w.status_label.text() == "Cancelled."
    # a cancel is no error: neither the widget nor napari's worker shows one
    assert not any(level == "error" for level, _ in notes)


def test_fit_widget_shows_errors(make_napari_viewer, qtbot, demo, notes, tmp_path):
    viewer = make_napari_viewer()
    add_demo(viewer, demo)
    w = dock(viewer, _widgets.FitWidget)
    bad = tmp_path / "bad.toml"
    bad.write_text('[parameters.no_such_parameter]\nbounds = [1, 2]\n')
    w.config_edit.setText(str(bad))
    w.out_edit.setText(str(tmp_path / "fit"))
    w.run()
    wait_run(qtbot, w)
    assert isinstance(w.last_error, tissuefit.TissuefitError), w.last_error
    assert notes and notes[-1][0] == "error" and notes[-1][1].startswith("tissuefit error: ")
    assert w.status_label.text().startswith("tissuefit error: ")
    assert not [l for l in viewer.layers if isinstance(l, Surface)]
    # shown once (by the widget), not a second time by napari's worker relay
    assert sum(level == "error" for level, _ in notes) == 1


# ----------------------------------------------------------------------------- reader
def test_reader_opens_vtp(make_napari_viewer, demo, tmp_path):
    import npe2

    labels, voxel = demo
    tissue = tissuefit.mesh(labels, voxel, seed=0, target_nodes=200)
    path = tmp_path / "tissue.vtp"
    tissue.save(str(path))
    assert get_reader(str(tmp_path / "nothing.tif")) is None
    assert get_reader(str(tmp_path / "empty_dir_does_not_exist")) is None

    # through napari, as File > Open does (the manifest registered if the entry point is missing)
    pm = npe2.PluginManager.instance()
    if "tissuefit" not in pm:
        pm.register(npe2.PluginManifest.from_file(str(MANIFEST)))
    viewer = make_napari_viewer()
    layers = viewer.open(str(path), plugin="tissuefit")
    assert len(layers) == 1 and isinstance(layers[0], Surface)
    surface = layers[0]
    assert len(surface.vertices) == sum(len(c.vertices) for c in tissue.cells)
    assert sorted(np.unique(surface.vertex_values)) == sorted(c.id for c in tissue.cells)
    expected, _, _ = _layers.surface_data(tissue)
    np.testing.assert_allclose(surface.vertices, expected, atol=1e-9)

    # a run folder: mesh/tissue.vtp (and simulate/final.vtp, fit/best.vtp when present)
    run = tmp_path / "run"
    (run / "mesh").mkdir(parents=True)
    tissue.save(str(run / "mesh" / "tissue.vtp"))
    layers = viewer.open(str(run), plugin="tissuefit")
    assert [l.name for l in layers] == ["run: mesh"]
