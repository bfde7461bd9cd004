"""napari dock widgets: "Mesh labels", "Fit tissue mechanics" and "Tension map (direct estimate)".

Only napari's public API (napari.layers, napari.qt.threading, napari.utils.notifications) and qtpy.
The tissuefit calls run in a worker thread (they release the GIL); their progress callback forwards
to the GUI thread through a Qt signal and returns False once Cancel was pressed, which makes the call
raise tissuefit.Cancelled.
"""

from __future__ import annotations

import os
import tempfile
import time
from typing import Any

import numpy as np
from napari.layers import Labels, Surface
from napari.qt.threading import create_worker
from napari.utils.notifications import show_error, show_info, show_warning
from qtpy.QtCore import QObject, Qt, Signal
from qtpy.QtWidgets import (
    QAbstractItemView,
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from ._layers import (
    CELL_ID,
    PARAMETER_HEADERS,
    TENSION,
    TENSION_CHOICES,
    color_choices,
    color_limits,
    fit_config_for,
    fit_status,
    interface_headers,
    interface_rows,
    labels_volume,
    parameter_rows,
    per_cell_columns,
    read_residuals,
    surface_data,
    surface_layer_data,
    tension_layer_data,
    tension_status,
    tension_units,
    um_per_layer_unit,
    voxel_size_um,
)

NO_CONFIG_MESSAGE = (
    "No fit config selected: choose a fit TOML file (a `tissuefit fit` config, or a pipeline file "
    "with a [fit] table, e.g. pipelines/demo.toml)."
)


class _ProgressBridge(QObject):
    """Carries progress reports from the worker thread to the GUI thread (queued signal)."""

    report = Signal(str, int, int, str)


class _TissuefitWidget(QWidget):
    """Shared parts: Labels layer choice, voxel size, mesh options, progress bar, Cancel, status."""

    def __init__(self, napari_viewer: Any, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.viewer = napari_viewer
        self.worker = None
        self._cancel_requested = False
        self._started = 0.0
        #: seconds the last run took (from pressing Run to the layer being added), for tests and docs
        self.last_run_seconds: float | None = None
        #: the last error a run ended with (None after a success), for tests
        self.last_error: BaseException | None = None

        self._bridge = _ProgressBridge()
        self._bridge.report.connect(self._on_progress)

        self.layer_combo = QComboBox()
        self.layer_combo.setToolTip("The 3-D Labels layer to mesh (z, y, x); 0 is background.")
        self.layer_combo.currentIndexChanged.connect(self._update_voxel_label)
        self.voxel_label = QLabel()
        self.voxel_label.setWordWrap(True)
        self.seed_spin = QSpinBox()
        self.seed_spin.setRange(0, 2**31 - 1)
        self.seed_spin.setToolTip("Seed of the mesh's surface sampling (same seed, same mesh).")
        self.nodes_spin = QSpinBox()
        self.nodes_spin.setRange(0, 1_000_000)
        self.nodes_spin.setSpecialValueText("default")
        self.nodes_spin.setToolTip(
            "Target number of mesh nodes per cell; 'default' lets tissuefit choose from the cell size."
        )

        self.form = QFormLayout()
        self.form.addRow("Labels layer", self.layer_combo)
        self.form.addRow("Voxel size", self.voxel_label)
        self.form.addRow("Mesh seed", self.seed_spin)
        self.form.addRow("Nodes per cell", self.nodes_spin)

        self.run_button = QPushButton("Run")
        self.run_button.clicked.connect(self.run)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(self.cancel)
        buttons = QHBoxLayout()
        buttons.addWidget(self.run_button)
        buttons.addWidget(self.cancel_button)

        self.progress_bar = QProgressBar()
        self.progress_bar.setRange(0, 1)
        self.progress_bar.setValue(0)
        self.progress_bar.setFormat("idle")
        self.progress_bar.setTextVisible(True)
        self.status_label = QLabel("")
        self.status_label.setWordWrap(True)
        self.status_label.setTextInteractionFlags(Qt.TextSelectableByMouse)

        self.main_layout = QVBoxLayout(self)
        self.main_layout.addLayout(self.form)
        self.buttons_layout = buttons
        self.main_layout.addLayout(buttons)
        self.main_layout.addWidget(self.progress_bar)
        self.main_layout.addWidget(self.status_label)

        events = self.viewer.layers.events
        for name in ("inserted", "removed", "moved", "reordered"):
            emitter = getattr(events, name, None)
            if emitter is not None:
                emitter.connect(self._refresh_layers)
        self._refresh_layers()

    # ----------------------------------------------------------------- layer choice and voxel size
    def labels_layers(self) -> list[Labels]:
        return [layer for layer in self.viewer.layers if isinstance(layer, Labels)]

    def _refresh_layers(self, event: Any = None) -> None:
        current = self.layer_combo.currentText()
        layers = self.labels_layers()
        for layer in layers:  # follow renames (connecting twice is a no-op)
            layer.events.name.connect(self._refresh_layers)
        names = [layer.name for layer in layers]
        if current not in names and event is not None and getattr(event, "source", None) in layers:
            current = event.source.name  # the selected layer was renamed
        self.layer_combo.blockSignals(True)
        self.layer_combo.clear()
        self.layer_combo.addItems(names)
        if current in names:
            self.layer_combo.setCurrentIndex(names.index(current))
        self.layer_combo.blockSignals(False)
        self._update_voxel_label()

    def selected_layer(self) -> Labels | None:
        name = self.layer_combo.currentText()
        for layer in self.labels_layers():
            if layer.name == name:
                return layer
        return None

    def _update_voxel_label(self, *args: Any) -> None:
        layer = self.selected_layer()
        if layer is None:
            self.voxel_label.setText("no Labels layer")
            return
        try:
            z, y, x = voxel_size_um(layer)
        except ValueError as e:
            self.voxel_label.setText(str(e))
            return
        self.voxel_label.setText(
            f"z {z:.4g}, y {y:.4g}, x {x:.4g} µm (the layer's scale; set it in µm)"
        )

    # ----------------------------------------------------------------- running
    @property
    def running(self) -> bool:
        return self.worker is not None

    def _progress_callback(self, stage: str, done: int, total: int, message: str) -> bool:
        # worker thread: only emit (queued to the GUI thread) and answer the cancel flag
        self._bridge.report.emit(str(stage), int(done), int(total), str(message))
        return not self._cancel_requested

    def _on_progress(self, stage: str, done: int, total: int, message: str) -> None:
        if total > 0:
            self.progress_bar.setRange(0, total)
            self.progress_bar.setValue(min(done, total))
            self.progress_bar.setFormat(f"{stage} {done}/{total}")
        else:
            self.progress_bar.setRange(0, 0)  # busy
            self.progress_bar.setFormat(stage)
        if message:
            self.status_label.setText(f"{stage}: {message}")

    def cancel(self) -> None:
        """Ask the running call to stop (its progress callback returns False at the next report)."""
        if self.running:
            self._cancel_requested = True
            self.cancel_button.setEnabled(False)
            self.status_label.setText("cancelling…")

    def _inputs(self) -> dict | None:
        """Validated inputs for the run, or None after telling the user what is missing."""
        layer = self.selected_layer()
        if layer is None:
            self._fail_early("No Labels layer: open or create a 3-D Labels layer first.")
            return None
        try:
            labels = labels_volume(layer)
            voxel = voxel_size_um(layer)
        except ValueError as e:
            self._fail_early(str(e))
            return None
        return {
            "layer": layer,
            "labels": labels,
            "voxel": voxel,
            "seed": int(self.seed_spin.value()),
            "target_nodes": int(self.nodes_spin.value()) or None,
        }

    def _fail_early(self, message: str) -> None:
        self.status_label.setText(message)
        self.last_error = ValueError(message)
        show_error(message)

    def run(self) -> None:
        if self.running:
            return
        inputs = self._inputs()
        if inputs is None:
            return
        self._cancel_requested = False
        self.last_error = None
        self._started = time.perf_counter()
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.progress_bar.setRange(0, 0)
        self.progress_bar.setFormat("starting")
        self.status_label.setText("running…")
        worker = create_worker(self._guarded_work, inputs, _start_thread=False, _ignore_errors=True)
        worker.returned.connect(lambda out: self._on_done(inputs, out))
        worker.errored.connect(self._on_errored)
        worker.finished.connect(self._on_finished)
        self.worker = worker
        worker.start()

    def _guarded_work(self, inputs: dict) -> tuple[bool, Any]:
        # The worker returns errors instead of raising them: napari's workers relay a raised error
        # to its notification manager as well, which would show a cancel as an error and every
        # tissuefit error twice; _on_errored reports them once, as they are.
        try:
            return (True, self._work(inputs))
        except Exception as exc:  # noqa: BLE001 - handed to _on_errored, never swallowed
            return (False, exc)

    def _on_done(self, inputs: dict, out: tuple[bool, Any]) -> None:
        ok, value = out
        if ok:
            self._on_returned(inputs, value)
        else:
            self._on_errored(value)

    def _work(self, inputs: dict) -> Any:  # pragma: no cover - overridden
        raise NotImplementedError

    def _on_returned(self, inputs: dict, out: Any) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _on_errored(self, exc: BaseException) -> None:
        import tissuefit

        self.last_error = exc
        if isinstance(exc, tissuefit.Cancelled):
            self.status_label.setText("Cancelled.")
            self.progress_bar.setFormat("cancelled")
            show_info("tissuefit: cancelled")
        else:
            kind = "tissuefit error" if isinstance(exc, tissuefit.TissuefitError) else type(exc).__name__
            self.status_label.setText(f"{kind}: {exc}")
            self.progress_bar.setFormat("failed")
            show_error(f"{kind}: {exc}")

    def _on_finished(self) -> None:
        self.worker = None
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        if self.progress_bar.maximum() == 0:
            self.progress_bar.setRange(0, 1)
        if self.last_error is None:
            self.progress_bar.setValue(self.progress_bar.maximum())

    def _layer_placement(self, layer: Labels) -> dict:
        """scale/translate that put µm vertices on the labels layer's world coordinates."""
        factors = um_per_layer_unit(layer)
        scale = tuple(1.0 / f for f in factors)
        translate = tuple(float(t) for t in layer.translate[-3:])
        return {"scale": scale, "translate": translate}


class MeshWidget(_TissuefitWidget):
    """Mesh labels: a Labels layer → one Surface layer of the closed cell meshes, coloured by cell id."""

    def __init__(self, napari_viewer: Any, parent: QWidget | None = None) -> None:
        super().__init__(napari_viewer, parent)
        self.run_button.setText("Mesh")
        #: the Surface layer the last run added
        self.surface_layer: Surface | None = None
        #: the Tissue the last run made
        self.tissue: Any = None

    def _work(self, inputs: dict) -> Any:
        import tissuefit

        return tissuefit.mesh(
            inputs["labels"],
            inputs["voxel"],
            seed=inputs["seed"],
            target_nodes=inputs["target_nodes"],
            progress=self._progress_callback,
        )

    def _on_returned(self, inputs: dict, tissue: Any) -> None:
        self.tissue = tissue
        layer = inputs["layer"]
        data, kwargs, _ = surface_layer_data(
            tissue, name=f"{layer.name} mesh", color_by=CELL_ID, **self._layer_placement(layer)
        )
        self.surface_layer = self.viewer.add_surface(data, **kwargs)
        self.last_run_seconds = time.perf_counter() - self._started
        l_min = getattr(tissue, "l_min", None)
        extra = f", l_min {l_min:.3g} µm" if l_min else ""
        self.status_label.setText(
            f"{len(tissue)} cells, {len(data[0])} vertices{extra}; {self.last_run_seconds:.1f} s. "
            "Colours: cell id."
        )
        self.progress_bar.setFormat("done")


class FitWidget(_TissuefitWidget):
    """Fit tissue mechanics: mesh a Labels layer, fit the config's parameters, show the best tissue."""

    def __init__(self, napari_viewer: Any, parent: QWidget | None = None) -> None:
        super().__init__(napari_viewer, parent)
        self.run_button.setText("Fit")

        self.config_edit = QLineEdit()
        self.config_edit.setPlaceholderText("none selected")
        self.config_edit.setToolTip(
            "Fit configuration: a `tissuefit fit` TOML, or a pipeline file with a [fit] table "
            "(then its [mesh] target_nodes applies when Nodes per cell is 'default')."
        )
        config_browse = QPushButton("Browse…")
        config_browse.clicked.connect(self._browse_config)
        row = QHBoxLayout()
        row.addWidget(self.config_edit)
        row.addWidget(config_browse)
        self.form.addRow("Fit config", row)

        self.out_edit = QLineEdit()
        self.out_edit.setPlaceholderText("empty: a new temporary folder")
        self.out_edit.setToolTip(
            "Folder the fit writes to (result.json, trace.csv, best.vtp, residuals.csv, plots)."
        )
        out_browse = QPushButton("Browse…")
        out_browse.clicked.connect(self._browse_out)
        row = QHBoxLayout()
        row.addWidget(self.out_edit)
        row.addWidget(out_browse)
        self.form.addRow("Output folder", row)

        self.color_combo = QComboBox()
        self.color_combo.setToolTip(
            "Per-cell value the fitted tissue is coloured by: cell id, a quantity measured on the best "
            "tissue, or a column of the fit's residuals.csv (observed vs simulated)."
        )
        self.color_combo.addItem(CELL_ID)
        self.color_combo.currentTextChanged.connect(self._recolor)

        self.result_label = QLabel("")
        self.result_label.setWordWrap(True)
        self.table = QTableWidget(0, len(PARAMETER_HEADERS))
        self.table.setHorizontalHeaderLabels(list(PARAMETER_HEADERS))
        self.table.setEditTriggers(QAbstractItemView.NoEditTriggers)
        self.table.verticalHeader().setVisible(False)

        color_row = QFormLayout()
        color_row.addRow("Colour by", self.color_combo)
        self.main_layout.addWidget(self.result_label)
        self.main_layout.addLayout(color_row)
        self.main_layout.addWidget(self.table)

        self.setMinimumWidth(540)

        #: the FitResult of the last successful run
        self.result: Any = None
        #: the Surface layer of the fitted tissue
        self.surface_layer: Surface | None = None
        self._choices: dict[str, dict[int, float]] = {CELL_ID: {}}

    def _browse_config(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Fit config", "", "TOML (*.toml);;All files (*)")
        if path:
            self.config_edit.setText(path)

    def _browse_out(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Output folder")
        if path:
            self.out_edit.setText(path)

    def _inputs(self) -> dict | None:
        config = self.config_edit.text().strip()
        if not config:
            self._fail_early(NO_CONFIG_MESSAGE)
            return None
        if not os.path.isfile(config):
            self._fail_early(f"Fit config {config!r} is not a file.")
            return None
        inputs = super()._inputs()
        if inputs is None:
            return None
        try:
            fit_config = fit_config_for(config, inputs["seed"], inputs["target_nodes"])
        except (ValueError, OSError) as e:
            self._fail_early(f"Fit config {config!r}: {e}")
            return None
        except Exception as e:  # a TOML syntax error: tissuefit would report it too
            self._fail_early(f"Fit config {config!r} is not valid TOML: {e}")
            return None
        out = self.out_edit.text().strip()
        if not out:
            out = tempfile.mkdtemp(prefix="tissuefit-fit-")
            self.out_edit.setText(out)
        inputs["config"] = fit_config
        inputs["out"] = out
        return inputs

    def _work(self, inputs: dict) -> dict:
        import tissuefit

        # The Labels layer is the observed tissue as a label file is for `tissuefit fit`: meshed with
        # the config's [observed.meshing], and the simulations measured like it (on its voxels).
        result = tissuefit.fit(
            inputs["labels"],
            inputs["voxel"],
            config=inputs["config"],
            out=inputs["out"],
            progress=self._progress_callback,
        )
        measured: dict = {}
        if result.tissue is not None:
            measured = per_cell_columns(tissuefit.measure(result.tissue).cells)
        residuals = read_residuals(result.out) if result.out else {}
        return {"result": result, "measured": measured, "residuals": residuals}

    def _on_returned(self, inputs: dict, out: dict) -> None:
        result = out["result"]
        self.result = result
        raw = dict(result.result or {})
        message, level = fit_status(bool(result.converged), bool(result.poor_fit), raw)
        self._fill_table(raw)
        if result.tissue is None:
            message += "; no best tissue (best.vtp) to show"
            self.result_label.setText(message)
            self.status_label.setText(f"outputs in {result.out}")
            show_error(f"tissuefit: {message}")
            return
        self._choices = color_choices(out["measured"], out["residuals"])
        self.color_combo.blockSignals(True)
        self.color_combo.clear()
        self.color_combo.addItems(list(self._choices))
        self.color_combo.setCurrentText(CELL_ID)
        self.color_combo.blockSignals(False)

        layer = inputs["layer"]
        tag = "converged" if result.converged else "NOT converged"
        data, kwargs, _ = surface_layer_data(
            result.tissue,
            name=f"{layer.name} fitted tissue ({tag})",
            color_by=CELL_ID,
            **self._layer_placement(layer),
        )
        kwargs["metadata"]["tissuefit_fit_out"] = result.out
        self.surface_layer = self.viewer.add_surface(data, **kwargs)
        self.last_run_seconds = time.perf_counter() - self._started
        self.result_label.setText(message)
        self.result_label.setStyleSheet("" if level == "info" else "color: orange;")
        self.status_label.setText(
            f"{self.last_run_seconds:.1f} s in the widget; outputs in {result.out}"
        )
        self.progress_bar.setFormat("done" if level == "info" else "done (see warning)")
        if level == "info":
            show_info(f"tissuefit: {message}")
        else:
            show_warning(f"tissuefit: {message}")

    def _fill_table(self, raw: dict) -> None:
        rows = parameter_rows(raw)
        self.table.setRowCount(len(rows))
        for i, row in enumerate(rows):
            for j, text in enumerate(row):
                self.table.setItem(i, j, QTableWidgetItem(text))
        self.table.resizeColumnsToContents()

    def _recolor(self, choice: str) -> None:
        """Recolour the fitted tissue's Surface by the chosen per-cell value."""
        layer = self.surface_layer
        if layer is None or self.result is None or self.result.tissue is None:
            return
        if layer not in self.viewer.layers:
            return
        values = None if choice == CELL_ID else self._choices.get(choice, {})
        _, _, vals = surface_data(self.result.tissue, values)
        layer.vertex_values = vals
        layer.contrast_limits = color_limits(vals, choice)
        layer.metadata["tissuefit_color_by"] = choice


class TensionWidget(_TissuefitWidget):
    """Tension map (direct estimate): ``tissuefit.tensions`` on a Labels layer → a Surface coloured by
    each interface's tension (per face) or each cell's pressure, an interfaces table, a summary line.

    Undetermined faces / cells are not in the coloured layer: they form a second, uniform grey Surface
    layer ``"<name>: undetermined"`` (added only when there are some).
    """

    def __init__(self, napari_viewer: Any, parent: QWidget | None = None) -> None:
        super().__init__(napari_viewer, parent)
        self.run_button.setText("Run")
        # tissuefit.tensions meshes a label volume itself (seed 0) and reports no progress: no seed
        # choice, no Cancel (the call takes about a second)
        self.form.labelForField(self.seed_spin).hide()
        self.seed_spin.hide()
        self.cancel_button.hide()

        self.gauge_edit = QLineEdit()
        self.gauge_edit.setPlaceholderText("empty: relative (gauge = 1)")
        self.gauge_edit.setToolTip(
            "The gauge's tension in mN/m, when known (the gauge is the mean cell–medium tension, or the "
            "one medium tension): tensions are then in mN/m and pressures in kPa. Empty: relative to "
            "the gauge (tensions in units of the gauge, pressures in gauge/µm)."
        )
        self.form.addRow("Gauge tension (mN/m)", self.gauge_edit)
        self.one_medium_check = QCheckBox("one medium tension")
        self.one_medium_check.setToolTip("One tension for every cell–medium interface.")
        self.form.addRow("", self.one_medium_check)
        self.color_combo = QComboBox()
        self.color_combo.addItems(list(TENSION_CHOICES))
        self.color_combo.setToolTip(
            "interface tension: each face by the tension of its interface; cell pressure: each cell by "
            "its pressure (relative to the medium). Grey (a separate layer): undetermined."
        )
        self.color_combo.currentTextChanged.connect(self._recolor)
        self.form.addRow("Colour by", self.color_combo)

        self.result_label = QLabel("")
        self.result_label.setWordWrap(True)
        self.result_label.setTextInteractionFlags(Qt.TextSelectableByMouse)
        self.table = QTableWidget(0, len(interface_headers({})))
        self.table.setHorizontalHeaderLabels(list(interface_headers({})))
        self.table.setEditTriggers(QAbstractItemView.NoEditTriggers)
        self.table.verticalHeader().setVisible(False)
        self.main_layout.addWidget(self.result_label)
        self.main_layout.addWidget(self.table)
        self.setMinimumWidth(480)

        #: the TensionMap of the last successful run
        self.tension_map: Any = None
        #: the coloured Surface layer of the last run
        self.surface_layer: Surface | None = None
        #: the grey Surface layer of the undetermined faces/cells (None when all are determined)
        self.undetermined_layer: Surface | None = None
        self._source: Labels | None = None

    def gauge_tension(self) -> float | None:
        """The gauge tension in mN/m from the field (None when empty); ValueError when not a number > 0."""
        text = self.gauge_edit.text().strip().replace(",", ".")
        if not text:
            return None
        try:
            value = float(text)
        except ValueError:
            raise ValueError(
                f"Gauge tension {text!r} is not a number (mN/m), nor empty (relative)."
            ) from None
        if not (np.isfinite(value) and value > 0):
            raise ValueError(
                f"Gauge tension {text!r} must be a positive number of mN/m, or empty (relative)."
            )
        return value

    def _inputs(self) -> dict | None:
        try:
            gauge = self.gauge_tension()
        except ValueError as e:
            self._fail_early(str(e))
            return None
        inputs = super()._inputs()
        if inputs is None:
            return None
        inputs["gauge_tension"] = gauge
        inputs["one_medium_tension"] = bool(self.one_medium_check.isChecked())
        return inputs

    def _work(self, inputs: dict) -> Any:
        import tissuefit

        return tissuefit.tensions(
            inputs["labels"],
            inputs["voxel"],
            gauge_tension=inputs["gauge_tension"],
            one_medium_tension=inputs["one_medium_tension"],
            target_nodes=inputs["target_nodes"],
        )

    def _on_returned(self, inputs: dict, tmap: Any) -> None:
        self.tension_map = tmap
        self._source = inputs["layer"]
        self._fill_table(tmap)
        # a new run adds its own layers (the previous run's stay); Colour by redraws the last run's
        self.surface_layer = self.undetermined_layer = None
        self._show_layers()
        self.last_run_seconds = time.perf_counter() - self._started
        summary = tmap.summary
        message = tension_status(summary)
        warnings = [str(w) for w in (summary.get("warnings") or [])]
        if warnings:
            message += f"; {len(warnings)} warning(s): " + " | ".join(warnings)
        self.result_label.setText(message)
        self.result_label.setStyleSheet("color: orange;" if warnings else "")
        self.status_label.setText(f"{self.last_run_seconds:.1f} s in the widget; files in {tmap.out}")
        self.progress_bar.setFormat("done (see warnings)" if warnings else "done")
        for w in warnings:
            show_warning(f"tissuefit tensions: {w}")
        if not warnings:
            show_info(f"tissuefit tensions: {message}")

    def _layer_name(self, color_by: str) -> str:
        t_unit, p_unit = tension_units(self.tension_map.summary)
        base = self._source.name if self._source is not None else "labels"
        if color_by == TENSION:
            return f"{base} tensions ({t_unit})"
        return f"{base} pressures ({p_unit})"

    def _show_layers(self) -> None:
        """(Re)draws the last result for the current colour-by choice: replaces the last run's layers."""
        if self.tension_map is None or self._source is None:
            return
        for old in (self.surface_layer, self.undetermined_layer):
            if old is not None and old in self.viewer.layers:
                self.viewer.layers.remove(old)
        self.surface_layer = self.undetermined_layer = None
        color_by = self.color_combo.currentText()
        layers = tension_layer_data(
            self.tension_map,
            name=self._layer_name(color_by),
            color_by=color_by,
            **self._layer_placement(self._source),
        )
        (data, kwargs, _), rest = layers[0], layers[1:]
        if rest:
            grey_data, grey_kwargs, _ = rest[0]
            self.undetermined_layer = self.viewer.add_surface(grey_data, **grey_kwargs)
        self.surface_layer = self.viewer.add_surface(data, **kwargs)

    def _recolor(self, choice: str) -> None:
        if self.tension_map is not None and not self.running:
            self._show_layers()

    def _fill_table(self, tmap: Any) -> None:
        headers = interface_headers(tmap.summary)
        rows = interface_rows(tmap)
        self.table.setColumnCount(len(headers))
        self.table.setHorizontalHeaderLabels(list(headers))
        self.table.setRowCount(len(rows))
        for i, row in enumerate(rows):
            for j, text in enumerate(row):
                self.table.setItem(i, j, QTableWidgetItem(text))
        self.table.resizeColumnsToContents()
