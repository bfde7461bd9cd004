"""napari reader: tissuefit tissue files (.vtp/.vtk) and run or fit folders, as Surface layers."""

from __future__ import annotations

import os
from typing import Any, Callable

from ._layers import CELL_ID, surface_layer_data, tissue_files


def get_reader(path: Any) -> Callable[[Any], list] | None:
    """npe2 reader hook: a reader function when ``path`` holds a tissuefit tissue, else None."""
    if isinstance(path, (list, tuple)):
        if not path or not all(tissue_files(os.fspath(p)) for p in path):
            return None
    elif not tissue_files(os.fspath(path)):
        return None
    return read_tissue_layers


def read_tissue_layers(path: Any) -> list:
    """One Surface layer per tissue file (all cells, vertex values = cell id, coordinates in µm)."""
    import tissuefit

    paths = list(path) if isinstance(path, (list, tuple)) else [path]
    layers = []
    for p in paths:
        for file, name in tissue_files(os.fspath(p)):
            tissue = tissuefit.read_tissue(file)
            data, kwargs, kind = surface_layer_data(tissue, name=name, color_by=CELL_ID)
            kwargs["metadata"]["tissuefit_path"] = file
            layers.append((data, kwargs, kind))
    return layers
