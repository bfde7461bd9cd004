"""Writes the HDF5 fixtures read by tests/integration/label_readers.rs (hdf5_files_written_by_h5py_read_identically).

Made once with h5py 3.16.0 (HDF5 2.0.0) / numpy (`pip install h5py`):
    python make.py   # in tests/data/python_h5
- plantseg.h5: as PlantSeg writes its output: /raw (float32 image) and /segmentation (uint16, gzip,
  chunks (3, 5, 6)) with the attribute element_size_um = (0.8, 0.25, 0.25) (z, y, x in µm).
- two.h5: two integer volumes, neither with a label-like name: /a/cells (int64, shuffle + gzip, with a
  leading channel axis of 1) and /b/nuclei (uint32, LZF); no voxel size.
- probabilities.h5: /prob only (float32): no label dataset.
- doublet.h5: two half-overlapping balls of radius 7 voxels (labels 1, 2; 0.5 µm voxels) as
  /segmentation (uint16, gzip) and again as /copy (int32, contiguous), for a pipeline run.
- latest.h5: /segmentation written with libver="latest" (HDF5 2.0's data layout version 5), which
  the reader does not know yet: its error must say so.
The labels are those of tests/data/python_zarr: value(z, y, x) = ((3z + 2y + x) // 4) % 5 * (z + 1).
"""
import h5py
import numpy as np

nz, ny, nx = 6, 10, 12
z, y, x = np.indices((nz, ny, nx))
labels = (((3 * z + 2 * y + x) // 4) % 5 * (z + 1)).astype(np.uint16)

with h5py.File("plantseg.h5", "w") as f:
    f.create_dataset("raw", data=np.linspace(0, 1, labels.size, dtype=np.float32).reshape(labels.shape))
    d = f.create_dataset("segmentation", data=labels, compression="gzip", chunks=(3, 5, 6))
    d.attrs["element_size_um"] = np.array([0.8, 0.25, 0.25])

with h5py.File("two.h5", "w") as f:
    f.create_dataset("a/cells", data=labels.astype(np.int64)[np.newaxis], compression="gzip", shuffle=True,
                     chunks=(1, 2, 4, 5))
    f.create_dataset("b/nuclei", data=(labels // 2).astype(np.uint32), compression="lzf")

with h5py.File("probabilities.h5", "w") as f:
    f.create_dataset("prob", data=np.zeros(labels.shape, dtype=np.float32))

zz, yy, xx = np.indices((16, 18, 30))
ball = lambda cx: (zz - 7.5) ** 2 + (yy - 8.5) ** 2 + (xx - cx) ** 2 <= 49
doublet = np.zeros((16, 18, 30), dtype=np.uint16)
doublet[ball(8.5)] = 1
doublet[ball(20.5) & (doublet == 0)] = 2
with h5py.File("doublet.h5", "w") as f:
    d = f.create_dataset("segmentation", data=doublet, compression="gzip")
    d.attrs["element_size_um"] = np.array([0.5, 0.5, 0.5])
    f.create_dataset("copy", data=doublet.astype(np.int32))

with h5py.File("latest.h5", "w", libver="latest") as f:
    f.create_dataset("segmentation", data=labels, compression="gzip", chunks=(3, 5, 6))

print(h5py.__version__, h5py.version.hdf5_version, int(labels.sum()))
