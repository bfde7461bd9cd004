"""Writes the Python-made fixtures read by tests/integration/label_readers.rs (python_written_stores_read_identically).

Made once with zarr-python 3.1.6 / numcodecs 0.16.6 / numpy 2.4.6 (`pip install zarr`):
    python make.py   # in tests/data/python_zarr
- cells_v3.zarr: NGFF 0.5 (Zarr v3), axes (c, z, y, x), zarr-python's default codecs (bytes + zstd),
  two levels (level 1: every second voxel in y and x), scale in micrometres.
- cells_v2.zarr: NGFF 0.4 (Zarr v2), axes (z, y, x), GZip chunks, int32 labels, scale in nanometres.
- cells_f.npy: the same labels as a Fortran-order uint16 .npy (np.save).
The labels: value(z, y, x) = ((3z + 2y + x) // 4) % 5 * (z + 1); 0 = background.
"""
import json
import shutil

import numpy as np
import zarr
from numcodecs import GZip

nz, ny, nx = 6, 10, 12
z, y, x = np.indices((nz, ny, nx))
labels = (((3 * z + 2 * y + x) // 4) % 5 * (z + 1)).astype(np.uint16)
coarse = labels[:, ::2, ::2]

shutil.rmtree("cells_v3.zarr", ignore_errors=True)
root = zarr.open_group("cells_v3.zarr", mode="w", zarr_format=3)
root.create_array("0", data=labels[np.newaxis], chunks=(1, 3, 5, 6))
root.create_array("1", data=coarse[np.newaxis], chunks=(1, 3, 5, 6))
axes = [{"name": "c", "type": "channel"}] + [{"name": a, "type": "space", "unit": "micrometer"} for a in "zyx"]
root.attrs["ome"] = {
    "version": "0.5",
    "multiscales": [{
        "axes": axes,
        "datasets": [
            {"path": "0", "coordinateTransformations": [{"type": "scale", "scale": [1, 0.8, 0.25, 0.25]}]},
            {"path": "1", "coordinateTransformations": [{"type": "scale", "scale": [1, 0.8, 0.5, 0.5]}]},
        ],
    }],
}

shutil.rmtree("cells_v2.zarr", ignore_errors=True)
root = zarr.open_group("cells_v2.zarr", mode="w", zarr_format=2)
root.create_array("0", data=labels.astype(np.int32), chunks=(4, 4, 4), compressors=GZip(level=5))
root.attrs["multiscales"] = [{
    "version": "0.4",
    "axes": [{"name": a, "type": "space", "unit": "nanometer"} for a in "zyx"],
    "datasets": [{"path": "0", "coordinateTransformations": [{"type": "scale", "scale": [800.0, 250.0, 250.0]}]}],
}]

np.save("cells_f.npy", np.asfortranarray(labels))
print(json.dumps({"labels_sum": int(labels.sum()), "nonzero": int((labels > 0).sum())}))
