"""Pure conversions between tissuefit objects and napari layer data.

Nothing here touches Qt or a viewer, so it can be tested without a display.

Coordinates: tissuefit gives cell vertices in (x, y, z) micrometres, with voxel [k, j, i] centred at
(i·sx, j·sy, k·sz); napari's world order is (z, y, x), so a vertex is ``vertices[:, ::-1]`` there and it
lies on a Labels layer whose ``scale`` is the voxel size (z, y, x) in micrometres.
"""

from __future__ import annotations

import csv
import math
import os
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

#: The colour-by choice that colours each cell by its label (cell id).
CELL_ID = "cell id"

#: Colormap for continuous per-cell quantities and for cell ids.
COLORMAP = "turbo"


def voxel_size_um(layer: Any) -> tuple[float, float, float]:
    """The voxel size (z, y, x) in µm of a napari Labels layer, from its ``scale``.

    ``scale`` is taken as micrometres when the layer's ``units`` are napari's default ("pixel") or
    absent; a layer with length units (e.g. nm) is converted to µm.
    """
    scale = [float(s) for s in layer.scale]
    if len(scale) < 3:
        raise ValueError(
            f"layer {layer.name!r} is {len(scale)}-D; tissuefit needs a 3-D label volume (z, y, x)"
        )
    scale = scale[-3:]
    factors = um_per_layer_unit(layer)
    size = tuple(s * f for s, f in zip(scale, factors))
    if not all(math.isfinite(s) and s > 0 for s in size):
        raise ValueError(f"layer {layer.name!r} has a non-positive voxel size (scale) {size}")
    return size  # type: ignore[return-value]


def um_per_layer_unit(layer: Any) -> tuple[float, float, float]:
    """How many µm one unit of the layer's last three axes is (1 for 'pixel' or no units)."""
    units = getattr(layer, "units", None)
    if units is None:
        return (1.0, 1.0, 1.0)
    out = []
    for u in list(units)[-3:]:
        name = str(u)
        if name in ("pixel", "px", "", "dimensionless"):
            out.append(1.0)
            continue
        try:
            out.append(float((1 * u).to("micrometer").magnitude))
        except Exception:  # not a length unit: treat the scale as µm, as for 'pixel'
            out.append(1.0)
    return tuple(out)  # type: ignore[return-value]


def labels_volume(layer: Any) -> np.ndarray:
    """The label volume (z, y, x) of a Labels layer as a numpy array (level 0 if multiscale)."""
    data = layer.data
    if getattr(layer, "multiscale", False):
        data = data[0]
    arr = np.asarray(data)
    if arr.ndim != 3:
        raise ValueError(
            f"layer {layer.name!r} has {arr.ndim} dimensions; tissuefit needs a 3-D label volume (z, y, x)"
        )
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"layer {layer.name!r} holds {arr.dtype} values; labels must be integers")
    return arr


def cell_ids(tissue: Any) -> list[int]:
    return [int(c.id) for c in tissue.cells]


def surface_data(
    tissue: Any, values: Mapping[int, float] | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All cells of a tissue as one napari Surface: (vertices (z,y,x) µm, faces, vertex values).

    ``values`` maps cell id -> value (every vertex of a cell gets its cell's value); None colours by cell
    id. A cell missing from ``values`` gets NaN.
    """
    verts, faces, vals = [], [], []
    offset = 0
    for cell in tissue.cells:
        v = np.asarray(cell.vertices, dtype=np.float64)
        f = np.asarray(cell.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
            continue
        verts.append(v[:, ::-1])
        faces.append(f + offset)
        value = float(cell.id) if values is None else float(values.get(int(cell.id), np.nan))
        vals.append(np.full(len(v), value))
        offset += len(v)
    if not verts:
        return (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros(0))
    return (np.concatenate(verts), np.concatenate(faces), np.concatenate(vals))


def contrast_limits(values: Iterable[float]) -> tuple[float, float]:
    """Contrast limits spanning the finite values (a unit span around a single value)."""
    arr = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=float)
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return (0.0, 1.0)
    lo, hi = float(arr.min()), float(arr.max())
    if hi <= lo:
        return (lo - 0.5, hi + 0.5)
    return (lo, hi)


def color_limits(values: Iterable[float], color_by: str) -> tuple[float, float]:
    """Contrast limits for a colour-by choice: cell ids padded by one id on each side (so that no
    cell sits on the colormap's dark ends), other quantities their exact span."""
    lo, hi = contrast_limits(values)
    if color_by == CELL_ID:
        return (lo - 1.0, hi + 1.0)
    return (lo, hi)


def surface_layer_data(
    tissue: Any,
    name: str,
    color_by: str = CELL_ID,
    values: Mapping[int, float] | None = None,
    scale: Sequence[float] | None = None,
    translate: Sequence[float] | None = None,
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], dict, str]:
    """A napari LayerData tuple (data, kwargs, 'surface') for a tissue coloured by a per-cell value."""
    data = surface_data(tissue, None if color_by == CELL_ID else values)
    kwargs: dict[str, Any] = {
        "name": name,
        "colormap": COLORMAP,
        "contrast_limits": color_limits(data[2], color_by),
        "metadata": {"tissuefit_color_by": color_by, "tissuefit_cells": cell_ids(tissue)},
    }
    if scale is not None:
        kwargs["scale"] = tuple(float(s) for s in scale)
    if translate is not None:
        kwargs["translate"] = tuple(float(t) for t in translate)
    return (data, kwargs, "surface")


def per_cell_columns(columns: Mapping[str, Any], id_column: str = "cell") -> dict[str, dict[int, float]]:
    """Per-cell numeric columns of a table ({column: array}) as {column: {cell id: value}}."""
    if id_column not in columns:
        return {}
    ids = [int(i) for i in np.asarray(columns[id_column]).ravel()]
    out: dict[str, dict[int, float]] = {}
    for key, col in columns.items():
        if key == id_column:
            continue
        arr = np.asarray(col)
        if arr.ndim != 1 or len(arr) != len(ids):
            continue
        if not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
            continue
        out[str(key)] = {i: float(v) for i, v in zip(ids, arr.astype(float))}
    return out


def read_residuals(fit_dir: str) -> dict[str, dict[int, float]]:
    """The per-cell columns of a fit's residuals.csv (observed vs simulated at the best point), if any."""
    path = os.path.join(fit_dir, "residuals.csv")
    if not os.path.isfile(path):
        return {}
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or "cell" not in rows[0]:
        return {}
    columns: dict[str, list] = {k: [] for k in rows[0]}
    for row in rows:
        for k in columns:
            columns[k].append(row.get(k, ""))
    numeric: dict[str, np.ndarray] = {}
    for k, col in columns.items():
        try:
            numeric[k] = np.array([float(x) for x in col])
        except ValueError:
            continue
    return per_cell_columns(numeric)


def color_choices(
    measured: Mapping[str, Mapping[int, float]], residuals: Mapping[str, Mapping[int, float]]
) -> dict[str, dict[int, float]]:
    """Colour-by choices: 'cell id', then the measured columns, then the fit's residual columns."""
    out: dict[str, dict[int, float]] = {CELL_ID: {}}
    for k, v in measured.items():
        out[k] = dict(v)
    for k, v in residuals.items():
        if "_m3_" in k or "_m2_" in k:  # SI duplicates of the µm³/µm² columns
            continue
        out[f"residual: {k}"] = dict(v)
    return out


def _fmt(x: Any) -> str:
    if x is None:
        return "–"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, float)):
        return f"{x:.4g}"
    if isinstance(x, (list, tuple)) and len(x) == 2:
        return f"[{_fmt(x[0])}, {_fmt(x[1])}]"
    return str(x)


#: Column headers of :func:`parameter_rows`.
PARAMETER_HEADERS = ("quantity", "value (SI)", "range", "fitted", "determined", "at bound")


def parameter_rows(result: Mapping[str, Any]) -> list[tuple[str, ...]]:
    """Rows of the results table from a fit's result.json: each parameter, then each ratio.

    Parameter values are SI (surface tensions in N/m: 1e-3 N/m = 1 mN/m); ratios are dimensionless.
    """
    rows = []
    for name, p in (result.get("parameters") or {}).items():
        p = p or {}
        rows.append(
            (
                name,
                _fmt(p.get("si", p.get("value"))),
                _fmt(p.get("range")),
                _fmt(p.get("fitted")),
                _fmt(p.get("determined")),
                _fmt(p.get("at_bound")),
            )
        )
    for name, r in (result.get("ratios") or {}).items():
        r = r or {}
        rows.append(
            (
                name,
                _fmt(r.get("value")),
                _fmt(r.get("range")),
                "ratio",
                _fmt(r.get("determined")),
                _fmt(r.get("at_bound")),
            )
        )
    return rows


def fit_status(converged: bool, poor_fit: bool, result: Mapping[str, Any]) -> tuple[str, str]:
    """(message, level) for a finished fit; level is 'info' only for a converged, not-poor fit."""
    parts = []
    evals = result.get("evaluations")
    objective = result.get("objective")
    if converged and not poor_fit:
        head = "Fit converged"
        level = "info"
    elif converged:
        head = "Fit converged but is a POOR FIT"
        level = "warning"
    else:
        reason = result.get("stop_reason") or "optimiser did not converge"
        head = f"Fit NOT converged ({reason})"
        level = "warning"
        if poor_fit:
            head += "; POOR FIT"
    parts.append(head)
    if objective is not None:
        parts.append(f"objective {_fmt(objective)}")
    if evals is not None:
        parts.append(f"{evals} evaluations")
    if result.get("profile_evaluations") == 0 and any(
        (p or {}).get("fitted") for p in (result.get("parameters") or {}).values()
    ):
        parts.append("no profile: ranges are the bounds")
    wall = result.get("wall_seconds")
    if wall is not None:
        parts.append(f"{wall:.1f} s")
    return ("; ".join(parts), level)


def tissue_files(path: str) -> list[tuple[str, str]]:
    """The tissue files a reader opens for ``path``: [(file, layer name)], empty if none.

    A .vtp/.vtk file is itself; a fit folder gives its best.vtp; a run folder (``tissuefit run``) gives
    mesh/tissue.vtp, simulate/final.vtp and fit/best.vtp, those present.
    """
    path = os.fspath(path)
    if os.path.isfile(path):
        if path.lower().endswith((".vtp", ".vtk")):
            return [(path, os.path.splitext(os.path.basename(path))[0])]
        return []
    if not os.path.isdir(path):
        return []
    base = os.path.basename(os.path.normpath(path)) or path
    candidates = [
        ("best.vtp", "fit best"),
        ("tissue.vtp", "mesh"),
        ("final.vtp", "simulate final"),
        (os.path.join("mesh", "tissue.vtp"), "mesh"),
        (os.path.join("simulate", "final.vtp"), "simulate final"),
        (os.path.join("fit", "best.vtp"), "fit best"),
    ]
    out = []
    for rel, label in candidates:
        f = os.path.join(path, rel)
        if os.path.isfile(f):
            out.append((f, f"{base}: {label}"))
    return out


def _toml_load(path: str) -> dict | None:
    try:
        import tomllib  # Python 3.11+
    except ImportError:  # pragma: no cover - Python 3.10
        try:
            import tomli as tomllib  # type: ignore[no-redef]
        except ImportError:
            return None
    with open(path, "rb") as fh:
        return tomllib.load(fh)


def fit_config_for(path: str, seed: int, target_nodes: int | None) -> dict:
    """The config for ``tissuefit.fit(labels, voxel_size, config=...)`` from a file the user chose.

    A fit config (``tissuefit fit --config``'s schema) or a pipeline file (one with an ``[input]``
    table: its ``[fit]``, with its ``[mesh]`` as the observed meshing and its ``[input]`` seed as the
    optimiser's, as ``tissuefit fit --config PIPELINE`` takes it). ``model`` is made absolute
    (relative to the file), ``[observed]``'s files are dropped (the Labels layer is the observed
    tissue, meshed and measured like a label file), and the widget's seed and nodes per cell (when
    not "default") set ``[observed.meshing]``.
    """
    data = _toml_load(path)
    if data is None:
        raise ValueError("reading a TOML file needs Python 3.11 or the tomli package (pip install tomli)")
    if "input" in data:
        if "fit" not in data:
            raise ValueError(f"{path} is a pipeline file without a [fit] table: nothing to fit")
        fit = dict(data["fit"])
        meshing = dict(data.get("mesh") or {})
        input_seed = data["input"].get("seed") if isinstance(data["input"], dict) else None
        if input_seed is not None:
            optimizer = dict(fit.get("optimizer") or {})
            optimizer.setdefault("seed", int(input_seed))
            fit["optimizer"] = optimizer
    else:
        fit = dict(data)
        meshing = dict((fit.get("observed") or {}).get("meshing") or {})
    fit.pop("observed", None)
    model = fit.get("model")
    if isinstance(model, str) and not os.path.isabs(model):
        fit["model"] = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)), model))
    meshing["seed"] = int(seed)
    if target_nodes is not None:
        meshing["target_nodes"] = int(target_nodes)
    fit["observed"] = {"meshing": meshing}
    return fit


#: Colour-by choices of the "Tension map" widget.
TENSION = "interface tension"
PRESSURE = "cell pressure"
TENSION_CHOICES = (TENSION, PRESSURE)

#: Colormap of the tension / pressure layer (no grey in it: grey means undetermined).
TENSION_COLORMAP = "turbo"

#: The undetermined faces / cells are a separate Surface layer of this uniform colour (RGB).
UNDETERMINED_RGB = (0.5, 0.5, 0.5)


def face_surface_data(
    tissue: Any, face_values: Sequence[Any]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All cells as one napari Surface coloured per FACE: (vertices (z,y,x) µm, faces, vertex values).

    napari's Surface values are per vertex, so the vertices are unshared: face f of the result has
    its own three vertices ``3f, 3f+1, 3f+2``, each carrying the face's value. ``face_values[i]``
    holds one value per face of ``tissue.cells[i]`` (NaN where undetermined; NaN is kept).
    """
    verts, vals = [], []
    for cell, fv in zip(tissue.cells, face_values):
        v = np.asarray(cell.vertices, dtype=np.float64)
        f = np.asarray(cell.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0 or len(f) == 0:
            continue
        fv = np.asarray(fv, dtype=np.float64).ravel()
        if len(fv) != len(f):
            raise ValueError(f"cell {cell.id}: {len(fv)} face values for {len(f)} faces")
        verts.append(v[f.reshape(-1)][:, ::-1])  # (3·faces, 3), napari (z, y, x)
        vals.append(np.repeat(fv, 3))
    if not verts:
        return (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros(0))
    verts_all = np.concatenate(verts)
    n_faces = len(verts_all) // 3
    faces = np.arange(3 * n_faces, dtype=np.int64).reshape(n_faces, 3)
    return (verts_all, faces, np.concatenate(vals))


def split_undetermined(
    data: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Splits a Surface (vertices, faces, vertex values) into (determined, undetermined) Surfaces.

    A face is undetermined when any of its vertices' values is NaN. Each part keeps only the vertices
    its faces use (renumbered); the undetermined part's values are all 0.5 (drawn grey by
    :func:`tension_layer_data`), the determined part's are the finite values.
    """
    verts, faces, vals = data
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    vals = np.asarray(vals, dtype=np.float64)
    nan_face = ~np.isfinite(vals[faces]).all(axis=1) if len(faces) else np.zeros(0, bool)

    def part(mask: np.ndarray, values: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sel = faces[mask]
        if len(sel) == 0:
            return (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros(0))
        used, inverse = np.unique(sel.ravel(), return_inverse=True)
        new_faces = inverse.reshape(-1, 3).astype(np.int64)
        v = np.asarray(verts, dtype=np.float64)[used]
        out_vals = np.full(len(used), 0.5) if values is None else values[used]
        return (v, new_faces, out_vals)

    return part(~nan_face, vals), part(nan_face, None)


def robust_limits(values: Iterable[float], lo: float = 2.0, hi: float = 98.0) -> tuple[float, float]:
    """Contrast limits from the ``lo``–``hi`` percentiles of the finite values (NaN ignored); a unit
    span around a single value, (0, 1) when there is none."""
    arr = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=float)
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return (0.0, 1.0)
    a, b = (float(x) for x in np.percentile(arr, [lo, hi]))
    if b <= a:
        return contrast_limits(arr) if float(arr.max()) > float(arr.min()) else (a - 0.5, a + 0.5)
    return (a, b)


def tension_units(summary: Mapping[str, Any]) -> tuple[str, str]:
    """(tension unit, pressure unit) of a TensionMap's summary ('gauge', 'gauge/um'; 'mN/m', 'kPa')."""
    return (str(summary.get("tension_unit", "gauge")), str(summary.get("pressure_unit", "gauge/um")))


def tension_layer_data(
    tmap: Any,
    name: str,
    color_by: str = TENSION,
    scale: Sequence[float] | None = None,
    translate: Sequence[float] | None = None,
) -> list[tuple[tuple[np.ndarray, np.ndarray, np.ndarray], dict, str]]:
    """napari LayerData tuples for a TensionMap: the coloured Surface, then (only when some faces or
    cells are undetermined) a uniform grey Surface ``"<name>: undetermined"`` of those.

    ``color_by`` :data:`TENSION`: per face (unshared vertices, :func:`face_surface_data`), the
    tension of the face's interface; :data:`PRESSURE`: per cell (shared vertices), the cell's
    pressure. The coloured layer's contrast limits are the 2–98 percentiles of its values.
    """
    if color_by not in TENSION_CHOICES:
        raise ValueError(f"colour by {color_by!r}: choose one of {TENSION_CHOICES}")
    t_unit, p_unit = tension_units(tmap.summary)
    tissue = tmap.tissue
    if color_by == TENSION:
        full = face_surface_data(tissue, tmap.face_tension)
        unit = t_unit
    else:
        pressure = np.asarray(tmap.pressure, dtype=float)
        values = {int(c.id): float(p) for c, p in zip(tissue.cells, pressure)}
        full = surface_data(tissue, values)
        unit = p_unit
    determined, undetermined = split_undetermined(full)
    placement: dict[str, Any] = {}
    if scale is not None:
        placement["scale"] = tuple(float(s) for s in scale)
    if translate is not None:
        placement["translate"] = tuple(float(t) for t in translate)
    metadata = {
        "tissuefit_color_by": color_by,
        "tissuefit_unit": unit,
        "tissuefit_cells": cell_ids(tissue),
        "tissuefit_tensions_out": getattr(tmap, "out", None),
    }
    layers = [
        (
            determined,
            {
                "name": name,
                "colormap": TENSION_COLORMAP,
                "contrast_limits": robust_limits(determined[2]),
                "metadata": metadata,
                **placement,
            },
            "surface",
        )
    ]
    if len(undetermined[1]):
        layers.append(
            (
                undetermined,
                {
                    "name": f"{name}: undetermined",
                    "colormap": "gray",
                    "contrast_limits": (0.0, 1.0),  # values 0.5: RGB UNDETERMINED_RGB
                    "metadata": {**metadata, "tissuefit_undetermined": True},
                    **placement,
                },
                "surface",
            )
        )
    return layers


def interface_headers(summary: Mapping[str, Any]) -> tuple[str, ...]:
    """Column headers of :func:`interface_rows`, with the tension unit."""
    unit, _ = tension_units(summary)
    return ("cell a", "cell b", f"tension ({unit})", "determined", "area (µm²)")


def _num(x: Any) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def interface_rows(tmap: Any) -> list[tuple[str, ...]]:
    """Rows of the interfaces table: cell a, cell b (or "medium"), "tension ± sd" ("–" when
    undetermined), determined (yes/no), area in µm²."""
    cols = tmap.interfaces
    n = len(np.asarray(cols.get("cell_a", [])))
    rows = []
    for i in range(n):
        a = int(cols["cell_a"][i])
        b = int(cols["cell_b"][i])
        t = _num(cols["tension"][i]) if "tension" in cols else math.nan
        sd = _num(cols["tension_sd"][i]) if "tension_sd" in cols else math.nan
        det = bool(cols["determined"][i]) if "determined" in cols else math.isfinite(t)
        area = _num(cols["area_um2"][i]) if "area_um2" in cols else math.nan
        if det and math.isfinite(t):
            tension = f"{t:.4g} ± {sd:.2g}" if math.isfinite(sd) else f"{t:.4g}"
        else:
            tension = "–"
        rows.append(
            (
                str(a),
                "medium" if b == 0 else str(b),
                tension,
                "yes" if det else "no",
                f"{area:.4g}" if math.isfinite(area) else "–",
            )
        )
    return rows


def tension_status(summary: Mapping[str, Any]) -> str:
    """One line: determined counts, the force-balance residual, the gauge and units."""
    t_unit, p_unit = tension_units(summary)
    parts = [
        f"{summary.get('determined_interfaces', '?')}/{summary.get('interfaces', '?')} interface "
        f"tensions, {summary.get('determined_pressures', '?')}/{summary.get('cells', '?')} pressures "
        "determined"
    ]
    rms = summary.get("residual_rms")
    if isinstance(rms, (int, float)):
        parts.append(f"force-balance residual rms {rms:.3g} (units of the gauge)")
    gauge = summary.get("gauge")
    if gauge:
        value = summary.get("gauge_value")
        given = f" = {value:g} {t_unit}" if isinstance(value, (int, float)) else ""
        parts.append(f"gauge: {gauge}{given}")
    parts.append(f"tensions in {t_unit}, pressures in {p_unit}")
    return "; ".join(parts)
