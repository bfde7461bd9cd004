#!/usr/bin/env python3
"""Score `tissuefit tensions` (the direct estimate) against the Surface Evolver truths.

For each cluster folder (cluster.vtk + labels_{10,20,40}.tif + truth.json) this runs
`tissuefit tensions` on Evolver's own mesh and on each committed label volume, and compares:

- every cell–cell interface tension with truth.json's `interfaces[*].tension`, and every cell–medium
  tension with `gamma_a` (the truths have one medium tension, 1; the estimate's gauge is the mean of
  the cell–medium tensions, one unknown per cell);
- every cell pressure with truth.json's `pressures` converted to our units: Evolver's pressure is in
  tension per Evolver length, so p / evolver_length_to_um is in gauge tension per µm.

Relative errors: |estimate − truth| / truth. An undetermined interface counts as missing (reported).

    python3 validation/evolver/score_tensions.py --markdown docs/src/generated/direct-tensions.md

The tissuefit binary is `target/release/tissuefit` (build it first) or `--tissuefit PATH`.
"""

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def run(tissuefit, source, out, extra):
    cmd = [tissuefit, "tensions", source, "--out", out, "-q"] + extra
    subprocess.run(cmd, check=True)
    interfaces = list(csv.DictReader(open(os.path.join(out, "interfaces.csv"))))
    cells = list(csv.DictReader(open(os.path.join(out, "cells.csv"))))
    summary = json.load(open(os.path.join(out, "summary.json")))
    return interfaces, cells, summary


def score(truth, interfaces, cells):
    gamma = truth["gamma_a"]
    want = {tuple(sorted(map(int, k.split("-")))): v["tension"] for k, v in truth["interfaces"].items()}
    got, sd = {}, {}
    for row in interfaces:
        a, b = int(row["cell_a"]), int(row["cell_b"])
        key = (a, b) if b == 0 else tuple(sorted((a, b)))
        got[key] = float(row["tension"]) if row["tension"] else None
        sd[key] = float(row["tension_sd"]) if row["tension_sd"] else None
    lateral, medium, missing, within = [], [], 0, 0
    for k, t in sorted(want.items()):
        g = got.get(k)
        if g is None:
            missing += 1
        else:
            lateral.append(abs(g - t) / t)
            within += sd[k] is not None and abs(g - t) <= sd[k]
    for c in range(1, truth["cells"] + 1):
        if (c, 0) not in got:
            continue  # no free surface (a buried cell): no cell–medium interface to score
        g = got[(c, 0)]
        if g is None:
            missing += 1
        else:
            medium.append(abs(g - gamma) / gamma)
            within += sd[(c, 0)] is not None and abs(g - gamma) <= sd[(c, 0)]
    unit = truth["evolver_length_to_um"]
    pressure = []
    for row in cells:
        p_true = truth["pressures"].get(row["cell"])
        if p_true is None or not row["pressure"]:
            continue
        p_true /= unit
        pressure.append(abs(float(row["pressure"]) - p_true) / p_true)
    return lateral, medium, pressure, missing, within


def pct(values, f):
    return f"{100 * f(values):.1f}" if values else "–"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clusters", default=os.path.join(HERE, "fixtures"))
    ap.add_argument("--only", default="hetero4,doublet,triplet,tetra,ball12")
    ap.add_argument("--resolutions", default="10,20,40")
    ap.add_argument("--tissuefit", default=os.path.join(ROOT, "target", "release", "tissuefit"))
    ap.add_argument("--markdown", help="write the table here")
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for name in args.only.split(","):
            folder = os.path.join(args.clusters, name)
            truth = json.load(open(os.path.join(folder, "truth.json")))
            sources = [("Evolver mesh", os.path.join(folder, "cluster.vtk"), ["--length-unit", "um"])]
            for r in args.resolutions.split(","):
                sources.append((f"labels, {r} vox/diameter", os.path.join(folder, f"labels_{r}.tif"), []))
            for label, source, extra in sources:
                out = os.path.join(work, f"{name}-{len(rows)}")
                interfaces, cells, summary = run(args.tissuefit, source, out, extra)
                lateral, medium, pressure, missing, within = score(truth, interfaces, cells)
                both = lateral + medium
                row = {
                    "cluster": name, "input": label, "cell_cell": len(lateral), "missing": missing,
                    "lateral_median_pct": 100 * statistics.median(lateral) if lateral else None,
                    "lateral_max_pct": 100 * max(lateral) if lateral else None,
                    "all_median_pct": 100 * statistics.median(both) if both else None,
                    "all_max_pct": 100 * max(both) if both else None,
                    "pressure_median_pct": 100 * statistics.median(pressure) if pressure else None,
                    "pressure_max_pct": 100 * max(pressure) if pressure else None,
                    "within_1sd": within, "scored": len(both),
                    "residual_rms": summary["residual_rms"], "condition": summary["condition_number"],
                    "spectral_gap": summary.get("spectral_gap"),
                    "seconds": summary["wall_seconds"], "warnings": len(summary["warnings"]),
                }
                rows.append(row)
                print(f"{name:8s} {label:24s} cell-cell median {pct(lateral, statistics.median)} % "
                      f"max {pct(lateral, max)} %; all median {pct(both, statistics.median)} % max {pct(both, max)} %; "
                      f"pressure median {pct(pressure, statistics.median)} % max {pct(pressure, max)} %; "
                      f"missing {missing}", file=sys.stderr)
    fmt = lambda v: "–" if v is None else f"{v:.1f}"
    lines = [
        "| cluster | input | cell–cell interfaces: median / max error % | all interfaces (with cell–medium): "
        "median / max % | pressures: median / max % | undetermined | within ±1 tension_sd | residual rms | "
        "condition | spectral gap |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['cluster']} | {r['input']} | {fmt(r['lateral_median_pct'])} / {fmt(r['lateral_max_pct'])} "
            f"({r['cell_cell']}) | {fmt(r['all_median_pct'])} / {fmt(r['all_max_pct'])} | "
            f"{fmt(r['pressure_median_pct'])} / {fmt(r['pressure_max_pct'])} | {r['missing']} | "
            f"{r['within_1sd']} of {r['scored']} | "
            f"{r['residual_rms']:.3f} | {r['condition'] if r['condition'] is None else format(r['condition'], '.1f')} | "
            f"{'exact' if r['spectral_gap'] is None else format(r['spectral_gap'], '.1f')} |"
        )
    text = "\n".join(lines) + "\n"
    print(text)
    if args.markdown:
        open(args.markdown, "w").write(text)
    if args.json:
        json.dump(rows, open(args.json, "w"), indent=1)


if __name__ == "__main__":
    main()
