"""tissuefit from Python: segmented 3D tissues to cell mechanical parameters.

The functions call tissuefit's own stages (the code behind ``tissuefit mesh``, ``measure``,
``simulate`` and ``fit``) on numpy arrays:

>>> import tissuefit as tf
>>> labels, voxel_size = tf.read_labels("data/demo/doublet.tif")   # uint32 [z, y, x], µm
>>> tissue = tf.mesh(labels, voxel_size, target_nodes=200)
>>> tf.measure(tissue).cells_frame()                                # a pandas DataFrame
>>> result = tf.fit(labels, voxel_size, config="fit.toml", out="fit_run")
>>> result.value("surface_tension_lateral"), result.converged

Units: every length given to or returned by this package is in **micrometres** (voxel sizes,
vertices, l_min; areas in µm², volumes in µm³, with the unit in the column name). Model parameters
(tensions, adhesion) are SI, as in the configuration files (N/m; 1 mN/m = 1e-3 N/m).

Coordinates: voxel ``[k, j, i]`` has its centre at ``(x, y, z) = (i·sx, j·sy, k·sz)``; a cell's
``vertices`` are ``(x, y, z)``, so ``vertices[:, ::-1]`` are napari's ``(z, y, x)`` world
coordinates of a Labels layer whose ``scale`` is the voxel size.

Long calls release the GIL. They take ``progress``: a callable ``progress(stage, done, total,
message)`` called from the working thread at most every 0.2 s (and after each fit evaluation);
returning ``False`` stops the call, which then raises :class:`Cancelled` (Ctrl-C does the same).
Errors are :class:`TissuefitError` with tissuefit's message.
"""

from __future__ import annotations

import csv
import json
import os
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Optional, Sequence, Union

import numpy as np

from . import _tissuefit as _native
from ._tissuefit import Cancelled, TissuefitError

__all__ = [
    "Cancelled",
    "Cell",
    "FitResult",
    "Measurement",
    "NotConverged",
    "SeriesResult",
    "Simulation",
    "Tissue",
    "TissuefitError",
    "VoxelSize",
    "fit",
    "fit_series",
    "mesh",
    "measure",
    "read_labels",
    "read_tissue",
    "simulate",
    "tensions",
    "TensionMap",
    "__version__",
]

__version__: str = _native.version()

class NotConverged(UserWarning):
    """Warned when a relaxation or a fit ended without meeting its criterion (the returned object
    says so too: ``Simulation.summary["converged"]``, ``FitResult.ok``)."""


Progress = Callable[[str, int, int, str], Optional[bool]]
"""``progress(stage, done, total, message)``; return ``False`` to stop the call."""

PathLike = Union[str, "os.PathLike[str]"]


class VoxelSize(tuple):
    """A voxel size (z, y, x) in µm, as :func:`read_labels` returns it: a plain tuple of floats that
    also keeps what the file says exactly, so that passing it on to :func:`mesh`, :func:`measure` or
    :func:`fit` treats the volume bit for bit as the command line treats the file (µm → m is not
    exact in floating point): ``metres`` (z, y, x) and ``origin`` (x, y, z µm, the centre of voxel
    [0, 0, 0] recorded by the file, e.g. ImageJ's origin; the cells' vertices are placed with it)."""

    metres: tuple[float, float, float]
    origin_metres: tuple[float, float, float]

    def __new__(
        cls, metres: Sequence[float], origin_metres: Sequence[float] = (0.0, 0.0, 0.0)
    ) -> "VoxelSize":
        self = super().__new__(cls, tuple(float(m) / 1e-6 for m in metres))
        self.metres = tuple(float(m) for m in metres)  # type: ignore[assignment]
        self.origin_metres = tuple(float(o) for o in origin_metres)  # type: ignore[assignment]
        return self

    @property
    def origin(self) -> tuple[float, float, float]:
        """The centre of voxel [0, 0, 0] (x, y, z) in µm."""
        return tuple(o / 1e-6 for o in self.origin_metres)  # type: ignore[return-value]


def _origin(voxel_size: Any) -> Optional[tuple[float, float, float]]:
    """The origin (x, y, z m) a voxel size from :func:`read_labels` carries; None (0) otherwise."""
    return voxel_size.origin_metres if isinstance(voxel_size, VoxelSize) else None


def _voxel_size(voxel_size: Union[float, Sequence[float]]) -> tuple[float, float, float]:
    """A voxel size given in µm (one number for isotropic voxels, or (z, y, x)) as metres (z, y, x)."""
    if isinstance(voxel_size, VoxelSize):
        return voxel_size.metres
    if np.isscalar(voxel_size):
        v = float(voxel_size)  # type: ignore[arg-type]
        values: tuple[float, ...] = (v, v, v)
    else:
        values = tuple(float(v) for v in voxel_size)  # type: ignore[union-attr]
    if len(values) != 3:
        raise TissuefitError(f"voxel_size: give one length or three (z, y, x) in µm, got {len(values)} values")
    if not all(np.isfinite(v) and v > 0 for v in values):
        raise TissuefitError(f"voxel_size: lengths must be positive and finite (µm), got {values}")
    if any(v < 1e-3 or v > 1e3 for v in values):
        raise TissuefitError(
            f"voxel_size {values} µm: lengths are in micrometres here (a voxel of 1 nm to 1 mm); did you give "
            f"metres? e.g. 0.25 for a 0.25 µm voxel"
        )
    return (values[0] * 1e-6, values[1] * 1e-6, values[2] * 1e-6)


def _labels_u32(labels: Any) -> np.ndarray:
    """A label volume as a C-contiguous uint32 [z, y, x] array, refusing what is not labels."""
    array = np.asarray(labels)
    if array.ndim != 3:
        raise TissuefitError(f"labels: a 3D array [z, y, x] is needed, got {array.ndim} dimensions {array.shape}")
    if array.dtype == np.bool_:
        array = array.astype(np.uint32)
    if array.dtype.kind not in "iu":
        raise TissuefitError(
            f"labels: integer labels are needed, got dtype {array.dtype} (a probability map or an image?); "
            "segment it first, or cast it if it holds whole numbers"
        )
    if array.size and array.dtype.kind == "i" and array.min() < 0:
        raise TissuefitError(f"labels: negative label {int(array.min())}; labels are 0 (background) or positive")
    if array.size and array.dtype.itemsize > 4 and array.max() > np.iinfo(np.uint32).max:
        raise TissuefitError(f"labels: label {int(array.max())} is beyond the largest supported label 4294967295")
    return np.ascontiguousarray(array, dtype=np.uint32)


@dataclass(frozen=True)
class Cell:
    """One cell's closed surface. ``vertices``: (n, 3) float64, (x, y, z) in µm; ``faces``: (m, 3)
    int64 indices into ``vertices``, counter-clockwise seen from outside."""

    id: int
    kind: str
    cell_type: int
    vertices: np.ndarray
    faces: np.ndarray
    volume: float
    """µm³"""
    area: float
    """µm²"""


class Tissue:
    """A tissue: one closed triangle surface per cell. Made by :func:`mesh`, :func:`read_tissue`, or
    returned by :func:`simulate` and :func:`fit`."""

    def __init__(self, native: Any):
        self._native = native
        self._cells: Optional[list[Cell]] = None

    @property
    def cells(self) -> list[Cell]:
        """The cells, in the tissue's order."""
        if self._cells is None:
            self._cells = [Cell(*row) for row in self._native.cell_arrays()]
        return self._cells

    @property
    def l_min(self) -> Optional[float]:
        """The minimum edge length (µm) the labels were meshed at; None for a tissue read from a file."""
        return self._native.l_min_um

    @property
    def report(self) -> list[dict]:
        """Per label of a meshed volume: its status (kept, static, dropped) and why (the mesh
        stage's report.json entries)."""
        return json.loads(self._native.report_json)

    def save(self, path: PathLike, unit: str = "um") -> None:
        """Writes a .vtp (lengths in ``unit``, "um" or "m", recorded in the file) or a SimuCell3D
        .vtk (metres)."""
        self._native.save(os.fspath(path), unit)

    def __len__(self) -> int:
        return len(self._native)

    def __repr__(self) -> str:
        return f"Tissue({len(self)} cells)"


def read_labels(
    path: PathLike, voxel_size: Union[float, Sequence[float], None] = None, zarr_level: Optional[int] = None
) -> tuple[np.ndarray, VoxelSize]:
    """Reads a label volume (TIFF, OME-Zarr, HDF5 ``file.h5/dataset``, .npy) as tissuefit does.

    Returns ``(labels, voxel_size)``: uint32 [z, y, x] and (z, y, x) in µm, from the file's metadata
    unless ``voxel_size`` (µm) is given. ``zarr_level``: the OME-Zarr scale level (default 0).
    What the reader warns about (e.g. a voxel size assumed) is issued as Python warnings."""
    vs = None if voxel_size is None else _voxel_size(voxel_size)
    labels, metres, origin, warnings_ = _native.read_labels(os.fspath(path), vs, zarr_level)
    if warnings_:
        for w in warnings_:
            warnings.warn(f"{path}: {w}", stacklevel=2)
    return labels, VoxelSize(metres, origin)


def mesh(
    labels: Any,
    voxel_size: Union[float, Sequence[float]],
    *,
    seed: int = 0,
    target_nodes: Optional[int] = None,
    l_min: Optional[float] = None,
    border: str = "keep",
    min_voxels: Optional[int] = None,
    denoise_voxels: Optional[float] = None,
    progress: Optional[Progress] = None,
) -> Tissue:
    """Meshes every label into a closed cell surface, as ``tissuefit mesh`` does.

    ``labels``: an integer array [z, y, x] (0 = background); ``voxel_size``: µm, one number or
    (z, y, x). ``target_nodes``: nodes per median cell (sets l_min; default the CLI's);
    ``l_min``: the minimum edge length in µm instead; ``border``: what to do with labels touching
    the volume's border, "keep", "static" or "drop"; ``min_voxels``: smaller labels are debris;
    ``denoise_voxels``: first a Gaussian-weighted label vote of that σ in voxels (about 2 for
    masks whose boundaries are off by a voxel; ``--denoise-voxels``). The per-label outcome is
    ``Tissue.report``."""
    return Tissue(
        _native.mesh(
            _labels_u32(labels),
            _voxel_size(voxel_size),
            _origin(voxel_size),
            seed=seed,
            target_nodes=target_nodes,
            l_min_um=l_min,
            border=border,
            min_voxels=min_voxels,
            denoise_voxels=denoise_voxels,
            progress=progress,
        )
    )


def read_tissue(path: PathLike, length_unit: Optional[str] = None) -> Tissue:
    """Reads a tissue file: .vtp (ours, or ParaView's), SimuCell3D legacy .vtk, multi-material
    meshes (.vtk or .ply), 2.5-D cell sheets (.ply: open cell patches of one surface, for
    :func:`tensions`). ``length_unit`` ("m", "um", "nm", "px:0.2um"...) for files that do not record theirs
    (default metres)."""
    return Tissue(_native.read_tissue(os.fspath(path), length_unit))


def _columns(rows: list[dict]) -> dict[str, np.ndarray]:
    """Rows of a table as numpy columns (None becomes NaN in numeric columns)."""
    if not rows:
        return {}
    out: dict[str, np.ndarray] = {}
    for key in rows[0]:
        values = [r.get(key) for r in rows]
        if all(isinstance(v, bool) for v in values):
            out[key] = np.asarray(values, dtype=np.bool_)
        elif all(v is None or isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            if all(isinstance(v, int) for v in values):
                out[key] = np.asarray(values, dtype=np.int64)
            else:
                out[key] = np.asarray([np.nan if v is None else v for v in values], dtype=np.float64)
        else:
            out[key] = np.asarray(values, dtype=object)
    return out


@dataclass(frozen=True)
class Measurement:
    """A morphology measurement, lengths in µm (the column names say so: ``volume_um3``).

    ``cells``: one numpy column per per-cell quantity (the columns of ``cells.csv``);
    ``contacts``: the columns of ``contacts.csv``; ``summary``: ``summary.json``'s tissue summary."""

    cells: dict[str, np.ndarray]
    contacts: dict[str, np.ndarray]
    summary: dict

    def cells_frame(self) -> Any:
        """The cells as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.cells)

    def contacts_frame(self) -> Any:
        """The contacts as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.contacts)


def measure(
    data: Union[Tissue, Any],
    voxel_size: Union[float, Sequence[float], None] = None,
    *,
    border: str = "keep",
    min_voxels: Optional[int] = None,
) -> Measurement:
    """Measures a :class:`Tissue` (its meshes) or a label volume (on its voxels, with
    ``voxel_size`` in µm), as ``tissuefit measure`` does; see :class:`Measurement`."""
    if isinstance(data, Tissue):
        if voxel_size is not None:
            raise TissuefitError("measure: voxel_size applies to a label volume, not to a Tissue")
        text = _native.measure_tissue_json(data._native)
    else:
        if voxel_size is None:
            raise TissuefitError("measure: a label volume needs its voxel_size (µm, one number or (z, y, x))")
        text = _native.measure_labels_json(
            _labels_u32(data), _voxel_size(voxel_size), _origin(voxel_size), border=border, min_voxels=min_voxels
        )
    m = json.loads(text)
    return Measurement(cells=_columns(m["cells"]), contacts=_columns(m["contacts"]), summary=m["summary"])


@dataclass(frozen=True)
class TensionMap:
    """The direct estimate of every interface's tension and every cell's pressure (``tissuefit
    tensions``): from the shapes alone (force balance at the junction lines, Young–Laplace), in
    seconds, relative to a gauge.

    ``interfaces``: the columns of ``interfaces.csv`` (``cell_a``, ``cell_b`` with 0 the medium,
    ``tension``, ``tension_sd``, ``determined``, ``area_um2``...); ``cells``: of ``cells.csv``
    (``cell``, ``pressure``, ``pressure_sd``, ``determined``, ``pressure_relative``, ``free_tension``,
    ``lateral_tension``...);
    ``summary``: ``summary.json``
    (units: ``tension_unit``, ``pressure_unit``, residuals, warnings). ``tissue``: the tissue the
    estimate was made on; ``face_tension[i]``: the tension of each face of ``tissue.cells[i]``
    (NaN where undetermined); ``pressure[i]``: that cell's pressure. ``out``: the folder with the
    files (``tensions.vtp`` for ParaView; ``cell_overrides.toml``: the map as per-cell model
    parameters, with ``gauge_tension``)."""

    interfaces: dict[str, np.ndarray]
    cells: dict[str, np.ndarray]
    summary: dict
    tissue: Tissue
    face_tension: list[np.ndarray]
    pressure: np.ndarray
    out: str

    def interfaces_frame(self) -> Any:
        """The interfaces as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.interfaces)

    def cells_frame(self) -> Any:
        """The cells as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.cells)


def tensions(
    data: Union[Tissue, Any],
    voxel_size: Union[float, Sequence[float], None] = None,
    *,
    gauge: Optional[tuple[int, int]] = None,
    gauge_tension: Optional[float] = None,
    one_medium_tension: bool = False,
    out: Optional[PathLike] = None,
    target_nodes: Optional[int] = None,
    far_field: str = "auto",
) -> TensionMap:
    """Estimates every interface's tension and every cell's pressure from the shapes of a
    :class:`Tissue` or of a label volume (meshed first as :func:`mesh` does, with ``voxel_size``
    in µm), as ``tissuefit tensions`` does. On a 2.5-D cell sheet (open cell patches of one
    surface, e.g. a PLY epidermis) it estimates the walls' line tensions at the junctions and
    in-plane pressures instead (``summary["input"] == "sheet"``; no ``gauge_tension``).

    ``gauge``: the interface (a, b) whose tension is the unit (0 = the medium; default: the mean of
    the cell–medium tensions); ``gauge_tension``: that tension in mN/m, when known (tensions are then
    in mN/m and pressures in kPa); ``one_medium_tension``: one tension for every cell–medium
    interface; ``far_field``: where each junction's interface surfaces come from, ``"global"`` (one
    sphere per interface), ``"local"`` (fitted near each junction) or ``"auto"`` (global, local where
    the global surfaces miss the junction), as ``tissuefit tensions --far-field``. ``out``: the folder
    for the four files (default: a new temporary folder)."""
    folder = os.fspath(out) if out is not None else tempfile.mkdtemp(prefix="tissuefit-tensions-")
    if isinstance(data, Tissue):
        if voxel_size is not None or target_nodes is not None:
            raise TissuefitError("tensions: voxel_size and target_nodes apply to a label volume, not to a Tissue")
        tissue, kind, rounding = data, "tissue", None
        volume = {}
    else:
        if voxel_size is None:
            raise TissuefitError("tensions: a label volume needs its voxel_size (µm, one number or (z, y, x))")
        tissue = mesh(data, voxel_size, target_nodes=target_nodes)
        # A segmentation rounds its junctions over a voxel: the estimate's scale (as the CLI does).
        kind, rounding = "labels", max(_voxel_size(voxel_size))
        # Each face's neighbour and the imaged box are read from the labels (as the CLI does).
        volume = dict(labels=_labels_u32(data), voxel_size_m=_voxel_size(voxel_size), origin_m=_origin(voxel_size))
    faces, pressure, summary = _native.tensions(
        tissue._native,
        folder,
        file="the tissue given in Python" if kind == "tissue" else "the label volume given in Python",
        kind=kind,
        gauge=None if gauge is None else (int(gauge[0]), int(gauge[1])),
        gauge_tension=gauge_tension,
        one_medium_tension=one_medium_tension,
        rounding_scale_m=rounding,
        far_field=far_field,
        **volume,
    )
    return TensionMap(
        interfaces=_read_csv_columns(Path(folder) / "interfaces.csv"),
        cells=_read_csv_columns(Path(folder) / "cells.csv"),
        summary=json.loads(summary),
        tissue=tissue,
        face_tension=list(faces),
        pressure=pressure,
        out=folder,
    )


def _toml_text(value: Mapping[str, Any]) -> str:
    """A dict as TOML (tomli-w when installed; otherwise a small writer for tables of scalars,
    arrays and nested tables)."""
    try:
        import tomli_w  # type: ignore[import-not-found]

        return tomli_w.dumps(dict(value))
    except ImportError:
        pass

    def scalar(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, (str, os.PathLike)):
            return json.dumps(os.fspath(v))
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(scalar(x) for x in v) + "]"
        if isinstance(v, Mapping):
            return "{" + ", ".join(f"{json.dumps(str(k))} = {scalar(x)}" for k, x in v.items()) + "}"
        raise TissuefitError(f"config: cannot write {v!r} ({type(v).__name__}) as TOML")

    lines: list[str] = []

    def table(prefix: str, t: Mapping[str, Any]) -> None:
        plain = {k: v for k, v in t.items() if not isinstance(v, Mapping)}
        nested = {k: v for k, v in t.items() if isinstance(v, Mapping)}
        if prefix and plain:
            lines.append(f"[{prefix}]")
        for k, v in plain.items():
            lines.append(f"{json.dumps(str(k))} = {scalar(v)}")
        for k, v in nested.items():
            table(f"{prefix}.{json.dumps(str(k))}" if prefix else json.dumps(str(k)), v)

    table("", value)
    return "\n".join(lines) + "\n"


def _config(config: Union[PathLike, Mapping[str, Any]], what: str) -> tuple[str, str, str]:
    """(TOML text, folder its relative paths are relative to, name in errors) of a config given as
    a file path, TOML text or a dict."""
    if isinstance(config, Mapping):
        return _toml_text(config), os.getcwd(), f"the {what} dict"
    if _is_text(config):
        return os.fspath(config), os.getcwd(), f"the {what} text"
    path = Path(config)
    if not path.is_file():
        raise TissuefitError(f"{what}: {path} is not a file (give a path, TOML text or a dict)")
    return path.read_text(), str(path.resolve().parent), str(path)


def _is_text(config: Any) -> bool:
    """Whether a str config is TOML text rather than a path (it has a line break or a `=`)."""
    return isinstance(config, str) and ("\n" in config or "=" in config)


@dataclass(frozen=True)
class Simulation:
    """A finished relaxation: the final tissue, ``summary.json`` (steps, converged, residual, ...)
    and the run folder (frames, stats.csv, final.vtp, the input and config to repeat it)."""

    tissue: Tissue
    summary: dict
    out: str


def simulate(
    tissue: Tissue,
    model: Union[PathLike, Mapping[str, Any], None] = None,
    *,
    overrides: Optional[Mapping[str, Any]] = None,
    out: Optional[PathLike] = None,
    force: bool = False,
    progress: Optional[Progress] = None,
) -> Simulation:
    """Relaxes (or grows) a tissue with the SimuCell3D model, as ``tissuefit simulate`` does.

    ``model``: a simulation config file, or its keys as a dict / TOML text (applied on the built-in
    defaults); ``overrides``: single keys on top (e.g. ``{"simulation": {"max_steps": 2000}}``).
    ``out``: the run folder (default: a new temporary folder), which also receives ``input.vtp``.
    A run that stops unhealthy raises :class:`TissuefitError`; one that ends unconverged returns
    with ``summary["converged"] == False``."""
    model_path: Optional[str] = None
    layers: list[str] = []
    if isinstance(model, Mapping):
        layers.append(_toml_text(model))
    elif model is not None:
        text, _, _ = _config(model, "model")
        if _is_text(model):
            layers.append(text)
        else:
            model_path = os.fspath(model)
    if overrides:
        layers.append(_toml_text(overrides))
    folder = os.fspath(out) if out is not None else tempfile.mkdtemp(prefix="tissuefit-simulate-")
    final, summary_text = _native.simulate(
        tissue._native, folder, model=model_path, overrides=layers, force=force, progress=progress
    )
    summary = json.loads(summary_text)
    if summary.get("mode") == "equilibrium" and not summary.get("converged"):
        warnings.warn(
            f"the relaxation did not converge: {summary.get('stop_reason')} (summary['converged'] is False; "
            f"raise simulation.max_steps, see {folder})",
            NotConverged,
            stacklevel=2,
        )
    return Simulation(tissue=Tissue(final), summary=summary, out=folder)


@dataclass(frozen=True)
class FitResult:
    """A finished fit (``result.json`` and the files beside it in ``out``).

    ``converged``: the optimiser met its criterion; ``poor_fit``: the best objective lies far above
    the forward model's noise; ``parameters`` / ``ratios``: ``result.json``'s entries (value in SI,
    range, whether the data determine it, at a bound...); ``tissue``: the best point relaxed
    (``best.vtp``), None when that relaxation failed (see ``result["best_relaxation"]``)."""

    converged: bool
    poor_fit: bool
    parameters: dict
    ratios: dict
    result: dict
    tissue: Optional[Tissue]
    out: str
    trace: dict[str, np.ndarray] = field(default_factory=dict)
    """``trace.csv``: every evaluation (parameters, metrics, objective, status) as numpy columns."""
    residuals: dict[str, np.ndarray] = field(default_factory=dict)
    """``residuals.csv``: per cell, the observed and simulated metrics at the best point."""
    cells: dict[str, np.ndarray] = field(default_factory=dict)
    """A per-cell fit's (``mode = "per_cell"``) ``cells.csv``: per cell, its free and lateral tension
    (mN/m, N/m) with their sd (NaN and ``lateral_determined`` False where the interfaces do not fix a
    cell's own lateral tension), the simulated pressure with its sd (``pressure_sd_pa``); with spring
    contacts also its adhesion (``adhesion_pa_per_m``, ``adhesion_energy_mj_per_m2`` with its sd,
    ``adhesion_over_tension``); empty for a global fit."""
    interfaces: dict[str, np.ndarray] = field(default_factory=dict)
    """A per-cell fit's ``interfaces.csv``: per interface (``cell_b`` 0: the medium), the refined
    ``tension_mn_per_m`` with ``tension_sd_mn_per_m`` and its parts, the direct estimate, the
    mismatch; empty for a global fit."""

    def cells_frame(self) -> Any:
        """:attr:`cells` as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.cells)

    def interfaces_frame(self) -> Any:
        """:attr:`interfaces` as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.interfaces)

    @property
    def ok(self) -> bool:
        """Converged, not a poor fit, and the best point relaxed: a result to report."""
        return self.converged and not self.poor_fit and not self.result.get("best_relaxation", {}).get("failed", True)

    def value(self, name: str) -> Optional[float]:
        """The fitted value (SI) of a parameter or ratio by name; None when it has none."""
        if name in self.parameters:
            return self.parameters[name].get("si")
        if name in self.ratios:
            return self.ratios[name].get("value")
        raise KeyError(f"{name}: not a parameter or ratio of this fit ({', '.join([*self.parameters, *self.ratios])})")


def fit(
    observed: Union[Any, Tissue, PathLike, None],
    voxel_size: Union[float, Sequence[float], None] = None,
    config: Union[PathLike, Mapping[str, Any], None] = None,
    *,
    out: Optional[PathLike] = None,
    resume: bool = False,
    progress: Optional[Progress] = None,
) -> FitResult:
    """Fits the model's parameters to an observed tissue, as ``tissuefit fit`` does.

    ``observed``: a label volume (array [z, y, x], with ``voxel_size`` in µm; meshed with the
    config's ``[observed.meshing]``), a :class:`Tissue`, a label or tissue file path, or None (the
    config's own ``[observed]``). ``config``: the fit config (``tissuefit fit --config``'s schema)
    as a path, TOML text or dict; ``[observed]`` may be left out. A pipeline file (e.g.
    ``pipelines/demo.toml``) gives its ``[fit]`` with its ``[mesh]`` settings and seed, as
    ``tissuefit fit --config PIPELINE`` takes it; an observed tissue given here replaces its
    ``[input]``. ``out``: the fit folder (default
    a new temporary folder) with trace.csv, result.json, best.vtp (in µm when a pipeline's ``[output]
    length_unit`` is ``"um"``; :attr:`FitResult.tissue` is read back in metres), the plots. ``resume``: go on from
    ``out``'s trace. A fit in which no evaluation succeeded raises :class:`TissuefitError`; a fit
    that ran but did not converge returns with ``converged == False`` (check :attr:`FitResult.ok`)."""
    if config is None:
        raise TissuefitError("fit: give a config (a path, TOML text or a dict: the fit's parameters, optimiser ...)")
    text, base, config_name = _config(config, "fit config")
    folder = os.fspath(out) if out is not None else tempfile.mkdtemp(prefix="tissuefit-fit-")
    labels = tissue = None
    vs = None
    if isinstance(observed, Tissue):
        tissue = observed._native
    elif isinstance(observed, (str, os.PathLike)):
        path = Path(observed)
        key = "tissue" if path.suffix.lower() in (".vtk", ".vtp") else "labels"
        extra: dict[str, Any] = {key: str(path.resolve())}
        if voxel_size is not None:
            extra["voxel_size"] = list(_voxel_size(voxel_size))
        text = text + "\n" + _toml_text({"observed": extra})
    elif observed is not None:
        if voxel_size is None:
            raise TissuefitError("fit: a label volume needs its voxel_size (µm, one number or (z, y, x))")
        labels, vs = _labels_u32(observed), _voxel_size(voxel_size)
    result_text = _native.fit(
        text,
        base,
        config_name,
        folder,
        labels=labels,
        voxel_size_m=vs,
        origin_m=_origin(voxel_size), tissue=tissue, resume=resume, progress=progress
    )
    result = json.loads(result_text)
    problems = []
    if not result["converged"]:
        why = result.get("stop_reason") or (
            f"mismatch {result['rms_mismatch']:.4f} above per_cell.tolerance {result['tolerance']}"
            if result.get("mode") == "per_cell"
            else "see result.json"
        )
        problems.append(f"not converged ({why})")
    if result.get("poor_fit"):
        problems.append("a poor fit (the best objective lies far above the forward model's noise)")
    if result["best_relaxation"]["failed"]:
        problems.append(f"the best point's relaxation failed ({result['best_relaxation']['reason']})")
    if problems:
        warnings.warn(
            f"the fit in {folder} is {'; '.join(problems)}: its values are not a result to report (FitResult.ok "
            "is False); see result.json",
            NotConverged,
            stacklevel=2,
        )
    return _fit_result(folder, result)


def _fit_result(folder: str, result: dict) -> FitResult:
    """The :class:`FitResult` of a finished fit folder whose result.json is ``result``."""
    # A per-cell fit's relaxed tissue at its answer is relaxed.vtp.
    per_cell = result.get("mode") == "per_cell"
    best = Path(folder) / ("relaxed.vtp" if per_cell else "best.vtp")
    return FitResult(
        converged=bool(result["converged"]),
        poor_fit=bool(result.get("poor_fit", False)),
        parameters=result.get("parameters", {}),
        ratios=result.get("ratios", {}),
        result=result,
        tissue=read_tissue(best) if best.exists() else None,
        out=folder,
        trace=_read_csv_columns(Path(folder) / "trace.csv"),
        residuals=_read_csv_columns(Path(folder) / "residuals.csv"),
        cells=_read_csv_columns(Path(folder) / "cells.csv") if per_cell else {},
        interfaces=_read_csv_columns(Path(folder) / "interfaces.csv") if per_cell else {},
    )


@dataclass(frozen=True)
class SeriesResult:
    """A time series mapped by :func:`fit_series` (``series.json`` and the files beside it in ``out``).

    ``succeeded``: every frame's map converged and is no poor fit; ``result``: series.json (per
    frame: converged, iterations, the start's and the answer's mismatch, cells started with the
    previous frame's correction, tracks that begin and end); ``cells`` / ``interfaces``: every frame's
    cells.csv / interfaces.csv with ``frame`` and ``file`` columns in front (cell ids are track ids,
    one id per cell through the series); ``tracks``: each frame's labels and their tracks (``iou``
    with the cell continued, ``parent`` of a new track)."""

    succeeded: bool
    result: dict
    out: str
    cells: dict[str, np.ndarray] = field(default_factory=dict)
    interfaces: dict[str, np.ndarray] = field(default_factory=dict)
    tracks: dict[str, np.ndarray] = field(default_factory=dict)

    def frame(self, k: int) -> FitResult:
        """Frame ``k``'s per-cell fit (its folder ``tNNN``); an error for a frame whose fit failed."""
        f = self.result["frames"][k]
        if f["error"]:
            raise TissuefitError(f"frame {k} ({f['file']}) has no map: {f['error']}")
        folder = os.path.join(self.out, f["folder"])
        with open(os.path.join(folder, "result.json")) as fh:
            return _fit_result(folder, json.load(fh))

    def cells_frame(self) -> Any:
        """:attr:`cells` as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.cells)

    def interfaces_frame(self) -> Any:
        """:attr:`interfaces` as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.interfaces)


def fit_series(
    frames: Sequence[Union[Any, PathLike]],
    voxel_size: Union[float, Sequence[float], None] = None,
    config: Union[PathLike, Mapping[str, Any], None] = None,
    *,
    out: Optional[PathLike] = None,
    cold: bool = False,
    min_iou: Optional[float] = None,
    resume: bool = False,
    progress: Optional[Progress] = None,
) -> SeriesResult:
    """Maps a time series of label volumes in order with the per-cell fit, as ``tissuefit
    fit-series`` does: each frame's cells matched to the previous frame's by overlap (one id per
    cell through the series), each frame started from its direct estimate times the correction the
    previous frame's refinement found (``cold``: the direct estimate alone).

    ``frames``: label files, or label arrays [z, y, x] on one grid with ``voxel_size`` in µm (not a
    mix). ``config``: a per-cell fit config (``mode = "per_cell"``) as a path, TOML text or dict;
    its ``[observed]`` meshing and voxel size apply to every frame and may be left out.
    ``min_iou``: the overlap at or above which a cell continues one of the previous frame (default
    0.3). ``out``: the series folder (default a new temporary folder). ``resume``: frames whose
    folder holds a finished fit are read back, not run again. A frame that did not converge or
    failed leaves ``succeeded`` False with a :class:`NotConverged` warning."""
    if config is None:
        raise TissuefitError("fit_series: give a per-cell fit config (a path, TOML text or a dict)")
    frames = list(frames)
    text, base, config_name = _config(config, "fit config")
    folder = os.fspath(out) if out is not None else tempfile.mkdtemp(prefix="tissuefit-series-")
    paths = [f for f in frames if isinstance(f, (str, os.PathLike))]
    if paths and len(paths) != len(frames):
        raise TissuefitError("fit_series: give every frame as a file or every frame as an array, not a mix")
    files = [str(Path(f).resolve()) for f in paths]
    arrays = [] if paths else [_labels_u32(f) for f in frames]
    if arrays and voxel_size is None:
        raise TissuefitError("fit_series: label arrays need their voxel_size (µm, one number or (z, y, x))")
    text_out = _native.fit_series(
        text,
        base,
        config_name,
        folder,
        files=files,
        arrays=arrays,
        voxel_size_m=_voxel_size(voxel_size) if arrays else None,
        origin_m=_origin(voxel_size) if arrays else None,
        cold=cold,
        min_iou=min_iou,
        resume=resume,
        progress=progress,
    )
    result = json.loads(text_out)
    bad = [f"frame {f['frame']}" for f in result["frames"] if not f["succeeded"]]
    if bad:
        warnings.warn(
            f"the series in {folder}: {', '.join(bad)} did not converge, are poor fits or failed "
            "(SeriesResult.succeeded is False); see series.json",
            NotConverged,
            stacklevel=2,
        )
    return SeriesResult(
        succeeded=bool(result["succeeded"]),
        result=result,
        out=folder,
        cells=_read_csv_columns(Path(folder) / "series_cells.csv"),
        interfaces=_read_csv_columns(Path(folder) / "series_interfaces.csv"),
        tracks=_read_csv_columns(Path(folder) / "tracks.csv"),
    )


def _read_csv_columns(path: Path) -> dict[str, np.ndarray]:
    """A CSV file of ours as numpy columns (numbers where every row holds one; "true"/"false" as
    booleans)."""
    if not path.exists():
        return {}
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    parsed: list[dict] = []
    for r in rows:
        row: dict[str, Any] = {}
        for k, v in r.items():
            if v in ("true", "false"):
                row[k] = v == "true"
                continue
            try:
                row[k] = int(v)
            except (TypeError, ValueError):
                try:
                    row[k] = float(v) if v != "" else None
                except (TypeError, ValueError):
                    row[k] = v
        parsed.append(row)
    return _columns(parsed)
