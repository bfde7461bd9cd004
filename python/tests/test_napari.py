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


# Screenshots are rendered at this fixed size: the canvas itself can change height between two shots
# (the dock widget's result text wraps onto more lines), and two shots of different shapes cannot be
# compared pixel by pixel.
SHOT_SIZE = (400, 400)


def screenshot(viewer) -> np.ndarray:
    return viewer.screenshot(size=SHOT_SIZE, canvas_only=True, flash=False)


def differing_pixels(a: np.ndarray, b: np.ndarray) -> int:
    assert a.shape == b.shape, (a.shape, b.shape)
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
    assert widgets == {"Mesh labels", "Fit tissue mechanics", "Tension map (direct estimate)"}


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
    with_surface = screenshot(viewer)
    layer.visible = False
    qtbot.wait(50)
    without = screenshot(viewer)
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


# ----------------------------------------------------------------------------- tension map
class _FakeMap:
    """A TensionMap with chosen values on a real tissue (for the NaN paths the demo never takes)."""

    def __init__(self, tmap, face_tension, pressure):
        self.tissue, self.summary, self.out = tmap.tissue, tmap.summary, None
        self.interfaces, self.cells = tmap.interfaces, tmap.cells
        self.face_tension, self.pressure = face_tension, np.asarray(pressure, float)


@pytest.fixture(scope="module")
def demo_tensions(demo):
    return tissuefit.tensions(demo[0], demo[1])


def test_face_surface_unshared_vertices(demo_tensions):
    tm = demo_tensions
    tissue = tm.tissue
    n_faces = sum(len(c.faces) for c in tissue.cells)
    verts, faces, values = _layers.face_surface_data(tissue, tm.face_tension)
    assert verts.shape == (3 * n_faces, 3) and values.shape == (3 * n_faces,)
    np.testing.assert_array_equal(faces, np.arange(3 * n_faces).reshape(-1, 3))
    # each face's three vertices carry the face's value, and sit where the cell's face does (z, y, x)
    face_values = np.concatenate([np.asarray(f, float) for f in tm.face_tension])
    np.testing.assert_array_equal(values[faces], np.repeat(face_values[:, None], 3, axis=1))
    expected = np.concatenate(
        [np.asarray(c.vertices)[np.asarray(c.faces)].reshape(-1, 3)[:, ::-1] for c in tissue.cells]
    )
    np.testing.assert_allclose(verts, expected)
    # the demo's three interfaces are all determined: one coloured layer, no grey one
    layers = _layers.tension_layer_data(tm, "t")
    assert len(layers) == 1
    (data, kwargs, kind), = layers
    assert kind == "surface" and np.all(np.isfinite(data[2])) and len(data[1]) == n_faces
    lo, hi = kwargs["contrast_limits"]
    assert lo < hi and lo >= np.nanmin(face_values) and hi <= np.nanmax(face_values)
    with pytest.raises(ValueError, match="face values"):
        _layers.face_surface_data(tissue, [f[:-1] for f in tm.face_tension])


def test_tension_layers_nan_are_grey(demo_tensions):
    tm = demo_tensions
    tissue = tm.tissue
    ft = [np.array(f, float) for f in tm.face_tension]
    ft[0][:100] = np.nan  # 100 undetermined faces on the first cell
    fake = _FakeMap(tm, ft, [np.nan, 1.5])  # and the first cell's pressure undetermined
    n_faces = sum(len(c.faces) for c in tissue.cells)

    coloured, grey = _layers.tension_layer_data(fake, "t", translate=(1.0, 2.0, 3.0))
    assert len(coloured[0][1]) == n_faces - 100 and len(grey[0][1]) == 100
    assert len(coloured[0][0]) == 3 * (n_faces - 100) and len(grey[0][0]) == 300
    assert np.all(np.isfinite(coloured[0][2]))
    assert grey[1]["name"] == "t: undetermined" and grey[1]["colormap"] == "gray"
    assert grey[1]["translate"] == (1.0, 2.0, 3.0) == coloured[1]["translate"]
    # the grey layer draws one colour, UNDETERMINED_RGB, through napari's own colormap
    layer = Surface(grey[0], **grey[1])
    rgba = layer.colormap.map(
        (np.unique(layer.vertex_values) - layer.contrast_limits[0])
        / (layer.contrast_limits[1] - layer.contrast_limits[0])
    )
    assert rgba.shape[0] == 1
    np.testing.assert_allclose(rgba[0, :3], _layers.UNDETERMINED_RGB, atol=0.01)
    # NaN faces are not in the coloured layer's contrast limits either
    lo, hi = coloured[1]["contrast_limits"]
    assert np.isfinite(lo) and np.isfinite(hi) and lo < hi

    # per-cell pressure: shared vertices, the determined cell coloured, the other grey
    coloured, grey = _layers.tension_layer_data(fake, "p", color_by=_layers.PRESSURE)
    assert len(coloured[0][0]) == len(tissue.cells[1].vertices)
    assert set(np.unique(coloured[0][2])) == {1.5}
    assert len(grey[0][0]) == len(tissue.cells[0].vertices)
    # all undetermined: an empty coloured layer, everything grey
    none = _FakeMap(tm, [np.full(len(f), np.nan) for f in ft], [np.nan, np.nan])
    coloured, grey = _layers.tension_layer_data(none, "n")
    assert len(coloured[0][1]) == 0 and len(grey[0][1]) == n_faces
    assert coloured[1]["contrast_limits"] == (0.0, 1.0)
    assert len(Surface(coloured[0], **coloured[1]).faces) == 0  # napari takes the empty layer
    assert _layers.robust_limits([np.nan, 2.0, np.nan]) == (1.5, 2.5)


def test_interface_rows_and_units(demo, demo_tensions):
    tm = demo_tensions
    rows = _layers.interface_rows(tm)
    assert {(r[0], r[1]) for r in rows} == {("1", "medium"), ("1", "2"), ("2", "medium")}
    assert all(r[3] == "yes" and " ± " in r[2] for r in rows)
    for r, t, sd, area in zip(
        rows, tm.interfaces["tension"], tm.interfaces["tension_sd"], tm.interfaces["area_um2"]
    ):
        assert r[2] == f"{t:.4g} ± {sd:.2g}" and r[4] == f"{area:.4g}"
    assert _layers.interface_headers(tm.summary)[2] == "tension (gauge)"
    assert "tensions in gauge, pressures in gauge/um" in _layers.tension_status(tm.summary)
    si = tissuefit.tensions(demo[0], demo[1], gauge_tension=0.5)
    assert _layers.interface_headers(si.summary)[2] == "tension (mN/m)"
    assert "pressures in kPa" in _layers.tension_status(si.summary)
    # an undetermined interface shows no number
    cols = dict(tm.interfaces)
    cols["determined"] = np.array([False, True, True])
    cols["tension"] = np.array([np.nan, 1.0, 1.0])

    class M:
        interfaces, summary = cols, tm.summary

    assert _layers.interface_rows(M)[0][2:4] == ("–", "no")


def test_tension_widget_doublet(make_napari_viewer, qtbot, demo, notes):
    viewer = make_napari_viewer(show=True)
    labels, voxel = demo
    labels_layer = viewer.add_labels(labels, scale=voxel, name="doublet", translate=(0.5, 1.0, 1.5))
    w = dock(viewer, _widgets.TensionWidget)
    assert w.layer_combo.currentText() == "doublet"
    viewer.dims.ndisplay = 3
    labels_layer.visible = False
    viewer.reset_view()
    qtbot.wait(50)
    empty = screenshot(viewer)

    w.run()
    assert w.running  # in a worker thread, not blocking the GUI
    wait_run(qtbot, w)
    assert w.last_error is None, w.last_error
    assert isinstance(w.tension_map, tissuefit.TensionMap)
    surfaces = [l for l in viewer.layers if isinstance(l, Surface)]
    assert surfaces == [w.surface_layer] and w.undetermined_layer is None  # all determined
    layer = w.surface_layer
    assert layer.name == "doublet tensions (gauge)"
    n_faces = sum(len(c.faces) for c in w.tension_map.tissue.cells)
    assert len(layer.faces) == n_faces and len(layer.vertices) == 3 * n_faces
    assert np.all(np.isfinite(layer.vertex_values))
    lo, hi = layer.contrast_limits
    assert lo < hi and layer.colormap.name == "turbo"
    np.testing.assert_allclose(layer.translate, labels_layer.translate)
    # the table: the three interfaces 1-0, 1-2, 2-0
    assert w.table.rowCount() == 3
    pairs = {(w.table.item(i, 0).text(), w.table.item(i, 1).text()) for i in range(3)}
    assert pairs == {("1", "medium"), ("1", "2"), ("2", "medium")}
    assert w.table.horizontalHeaderItem(2).text() == "tension (gauge)"
    assert "3/3 interface tensions, 2/2 pressures determined" in w.result_label.text()
    assert notes and notes[-1][0] == "info"

    # drawn: the 3-D canvas differs from the empty one
    viewer.reset_view()
    qtbot.wait(50)
    shot = screenshot(viewer)
    changed = differing_pixels(shot, empty)
    assert changed > 0.01 * shot.shape[0] * shot.shape[1], changed

    # colour by pressure: one value per cell, the cells' pressures
    w.color_combo.setCurrentText(_layers.PRESSURE)
    assert [l for l in viewer.layers if isinstance(l, Surface)] == [w.surface_layer]
    assert w.surface_layer.name == "doublet pressures (gauge/um)"
    np.testing.assert_allclose(
        np.unique(w.surface_layer.vertex_values), np.sort(w.tension_map.pressure)
    )
    w.color_combo.setCurrentText(_layers.TENSION)

    # with a gauge tension: mN/m and kPa
    w.gauge_edit.setText("0.5")
    w.one_medium_check.setChecked(True)
    w.run()
    wait_run(qtbot, w)
    assert w.last_error is None, w.last_error
    assert w.tension_map.summary["tension_unit"] == "mN/m"
    assert w.tension_map.summary["one_medium_tension"] is True
    assert w.surface_layer.name == "doublet tensions (mN/m)"
    assert w.table.horizontalHeaderItem(2).text() == "tension (mN/m)"
    assert "tensions in mN/m, pressures in kPa" in w.result_label.text()
    # a new run adds its layer; the first run's stays
    assert [l.name for l in viewer.layers if isinstance(l, Surface)] == [
        "doublet tensions (gauge)",
        "doublet tensions (mN/m)",
    ]
    w.color_combo.setCurrentText(_layers.PRESSURE)  # redraws the last run's layer only
    assert [l.name for l in viewer.layers if isinstance(l, Surface)] == [
        "doublet tensions (gauge)",
        "doublet pressures (kPa)",
    ]
    assert not any(level == "error" for level, _ in notes)
    print(f"tension map in the widget: {w.last_run_seconds:.2f} s; {changed} surface pixels")


def test_tension_widget_undetermined_grey(make_napari_viewer, qtbot, demo, notes, monkeypatch):
    """Undetermined faces/cells in the widget: the real estimate with 100 faces of cell 1 and its
    pressure set to NaN (the demo's estimate determines everything)."""
    import dataclasses

    real = tissuefit.tensions

    def with_nan(*args, **kwargs):
        tm = real(*args, **kwargs)
        ft = [np.array(f, float) for f in tm.face_tension]
        ft[0][:100] = np.nan
        pressure = np.array(tm.pressure, float)
        pressure[0] = np.nan
        return dataclasses.replace(tm, face_tension=ft, pressure=pressure)

    monkeypatch.setattr(tissuefit, "tensions", with_nan)
    viewer = make_napari_viewer()
    add_demo(viewer, demo)
    w = dock(viewer, _widgets.TensionWidget)
    w.run()
    wait_run(qtbot, w)
    assert w.last_error is None, w.last_error
    grey = w.undetermined_layer
    assert grey is not None and grey.name == "doublet tensions (gauge): undetermined"
    assert len(grey.faces) == 100 and len(grey.vertices) == 300
    assert np.all(np.isfinite(w.surface_layer.vertex_values))
    n_faces = sum(len(c.faces) for c in w.tension_map.tissue.cells)
    assert len(w.surface_layer.faces) == n_faces - 100
    rgba = grey.colormap.map(np.array([0.5]))  # values 0.5 of contrast limits (0, 1)
    assert tuple(grey.contrast_limits) == (0.0, 1.0) and set(np.unique(grey.vertex_values)) == {0.5}
    np.testing.assert_allclose(rgba[0, :3], _layers.UNDETERMINED_RGB, atol=0.01)
    w.color_combo.setCurrentText(_layers.PRESSURE)
    cell1 = w.tension_map.tissue.cells[0]
    assert w.undetermined_layer.name == "doublet pressures (gauge/um): undetermined"
    assert len(w.undetermined_layer.faces) == len(cell1.faces)
    assert len(w.surface_layer.faces) == len(w.tension_map.tissue.cells[1].faces)
    assert len([l for l in viewer.layers if isinstance(l, Surface)]) == 2


def test_tension_widget_errors(make_napari_viewer, qtbot, notes):
    viewer = make_napari_viewer()
    viewer.add_labels(np.ones((8, 8), np.uint16), name="flat")
    w = dock(viewer, _widgets.TensionWidget)
    w.run()
    assert not w.running
    assert notes[-1][0] == "error" and "3-D" in notes[-1][1]
    assert "3-D" in w.status_label.text()

    viewer.add_labels(np.zeros((8, 8, 8), np.uint16), scale=(0.31, 0.31, 0.31), name="empty")
    w.layer_combo.setCurrentText("empty")
    w.gauge_edit.setText("abc")
    w.run()
    assert not w.running and notes[-1][0] == "error" and "Gauge tension" in notes[-1][1]
    w.gauge_edit.setText("")
    n_errors = sum(level == "error" for level, _ in notes)
    w.run()
    wait_run(qtbot, w)
    assert isinstance(w.last_error, tissuefit.TissuefitError), w.last_error
    assert notes[-1][0] == "error" and notes[-1][1].startswith("tissuefit error: ")
    assert sum(level == "error" for level, _ in notes) == n_errors + 1  # shown once
    assert not [l for l in viewer.layers if isinstance(l, Surface)]
    assert w.run_button.isEnabled()


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
