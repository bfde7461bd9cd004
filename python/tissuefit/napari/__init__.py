"""napari plugin of tissuefit (npe2 manifest: napari.yaml).

Widgets "Mesh labels", "Fit tissue mechanics" and "Tension map (direct estimate)", and a reader for
tissuefit tissue files (.vtp/.vtk) and run/fit folders. Needs napari (``pip install tissuefit[napari]``).
"""

__all__ = ["FitWidget", "MeshWidget", "TensionWidget", "get_reader"]


def __getattr__(name):  # lazy: importing tissuefit.napari must not import Qt
    if name in ("FitWidget", "MeshWidget", "TensionWidget"):
        from . import _widgets

        return getattr(_widgets, name)
    if name == "get_reader":
        from ._reader import get_reader

        return get_reader
    raise AttributeError(name)
