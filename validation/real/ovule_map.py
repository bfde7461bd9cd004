#!/usr/bin/env python3
"""The direct tension map of the real PlantSeg ovule crop (../shared/data/real: 44 Arabidopsis ovule
cells, every one cut by the crop, no free surface; voxel 0.235 x 0.15 x 0.15 um from the file). There
is no truth: the table shows how much of the map is determined, how spread it is (a map concentrated
on a few interfaces is the failure this guards against), how well the junctions balance, and how many
cells get a pressure relative to their neighbours.

    python3 validation/real/ovule_map.py --markdown OUT.md [--image PNG] [--tissuefit PATH] [--real DIR]

`--image` copies the map's picture (`tensions.png`).
"""

import argparse
import os
import shutil
import statistics
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "validation", "evolver"))
from score_tensions import run as run_tensions  # noqa: E402  (the same `tissuefit tensions` call)
LABELS = "plant-seg__sample_ovule_labels.tif"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tissuefit", default=os.path.join(ROOT, "target", "release", "tissuefit"))
    ap.add_argument("--real", default=os.path.join(ROOT, "..", "shared", "data", "real"))
    ap.add_argument("--markdown", required=True)
    ap.add_argument("--image")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        out = os.path.join(work, "map")
        interfaces, cells, summary = run_tensions(a.tissuefit, os.path.join(a.real, LABELS), out, [])
        if a.image:
            shutil.copy(os.path.join(out, "tensions.png"), a.image)
    determined = [r for r in interfaces if r["tension"]]
    t = sorted(float(r["tension"]) for r in determined)
    rel_sd = [float(r["tension_sd"]) / abs(float(r["tension"])) for r in determined]
    largest = max(determined, key=lambda r: float(r["tension"]))
    quantile = lambda q: t[round((len(t) - 1) * q)]
    relative = sum(1 for c in cells if c["pressure_relative"])
    absolute = sum(1 for c in cells if c["pressure"])
    poorly = any("poorly determined" in w for w in summary["warnings"])
    rows = [
        ("cells / interfaces", f"{summary['cells']} / {summary['interfaces']}"),
        ("interfaces determined", f"{len(determined)} of {len(interfaces)}"),
        ("tensions ≤ 0", f"{sum(1 for v in t if v <= 0)}"),
        ("tension median (5th–95th percentile)", f"{statistics.median(t):.2f} ({quantile(0.05):.2f}–{quantile(0.95):.2f})"),
        ("largest tension (its sd)", f"{float(largest['tension']):.1f} ({float(largest['tension_sd']):.1f}), "
         f"interface {largest['cell_a']}-{largest['cell_b']}"),
        ("median relative tension_sd", f"{100 * statistics.median(rel_sd):.0f} %"),
        ("force-balance residual rms (median)", f"{summary['residual_rms']:.3f} ({summary['residual_median']:.3f})"),
        ("spectral gap σ₂/σ₁", "exact" if summary["spectral_gap"] is None else f"{summary['spectral_gap']:.1f}"),
        ("warned as poorly determined", "yes" if poorly else "no"),
        ("pressures relative to the medium / to their group", f"{absolute} / {relative} of {len(cells)}"),
        ("wall time (s)", f"{summary['wall_seconds']:.2f} after meshing"),
    ]
    text = "| | PlantSeg ovule crop, default settings |\n|---|---|\n" + "".join(f"| {k} | {v} |\n" for k, v in rows)
    print(text)
    open(a.markdown, "w").write(text)


if __name__ == "__main__":
    main()
