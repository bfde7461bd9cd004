#!/usr/bin/env python3
"""The direct tension map of the real C. elegans 4-cell embryo (../shared/data/real: CShaper via
foambryo), from the label volume at several mesh resolutions and from foambryo's own mesh of the same
embryo, with the default far field (`auto`) and with the global fit alone. There is no truth for a real
embryo: the table shows whether the answer is whole (every interface determined) and whether it stays
the same when only the representation changes (labels vs mesh, mesh resolution).

    python3 validation/real/c_elegans_map.py --markdown OUT.md [--tissuefit PATH] [--real DIR] [--image PNG]

`--image` copies the default map's picture (`tensions.png`, labels at 400 nodes per cell).
`--per-cell RUN --status N` instead tabulates a per-cell fit's run folder (`tissuefit run
pipelines/real-embryo-map.toml`, which exited with status N): each interface's direct and refined
tension, its interval, and the observed and simulated relative tensions.
"""

import argparse
import csv
import json
import os
import shutil
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "validation", "evolver"))
from score_tensions import run as run_tensions  # noqa: E402  (the same `tissuefit tensions` call)
LABELS = "DERIVED_cshaper_4cells_labels_from_mesh.tif"
MESH = "foambryo-runner__Cshaper_4_cells_min-d-3.vtk"
PAIRS = ["1-0", "1-2", "1-3", "2-0", "2-3", "2-4", "3-0", "3-4", "4-0"]


def run(tissuefit, source, out, extra):
    interfaces, _, summary = run_tensions(tissuefit, source, out, extra)
    rows = {f"{r['cell_a']}-{r['cell_b']}": r for r in interfaces}
    tensions = {p: (float(rows[p]["tension"]) if p in rows and rows[p]["tension"] else None) for p in PAIRS}
    return tensions, summary


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tissuefit", default=os.path.join(ROOT, "target", "release", "tissuefit"))
    ap.add_argument("--real", default=os.path.join(os.path.dirname(ROOT), "shared", "data", "real"))
    ap.add_argument("--markdown", required=True)
    ap.add_argument("--image")
    ap.add_argument("--per-cell", metavar="RUN")
    ap.add_argument("--status", type=int, default=0)
    args = ap.parse_args()
    if args.per_cell:
        return per_cell(args.per_cell, args.status, args.markdown)
    labels, mesh = os.path.join(args.real, LABELS), os.path.join(args.real, MESH)
    inputs = [(f"labels, {n} nodes/cell", labels, ["--voxel-size", "1um", "--target-nodes", str(n)]) for n in (400, 800, 1600, 200)]
    inputs.insert(1, ("foambryo's mesh", mesh, []))
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for far in ("auto", "global"):
            for k, (name, source, extra) in enumerate(inputs):
                out = os.path.join(work, f"{far}-{k}")
                tensions, summary = run(args.tissuefit, source, out, extra + ["--far-field", far])
                rows.append((far, name, tensions, summary))
                if args.image and far == "auto" and k == 0:
                    shutil.copyfile(os.path.join(out, "tensions.png"), args.image)
    lines = [
        "| far field | input | " + " | ".join(PAIRS) + " | determined | local samples | residual rms |",
        "|---|---|" + "---|" * len(PAIRS) + "---|---|---|",
    ]
    for far, name, t, s in rows:
        cells = " | ".join("—" if t[p] is None else f"{t[p]:.2f}" for p in PAIRS)
        lines.append(
            f"| {far} | {name} | {cells} | {s['determined_interfaces']}/{s['interfaces']} | "
            f"{s['junction_samples_local']}/{s['junction_samples']} | {s['residual_rms']:.3f} |"
        )
    # Largest relative change of each far field's map against its labels-at-400 map.
    lines.append("")
    for far in ("auto", "global"):
        base = next(t for f, n, t, _ in rows if f == far and n.startswith("labels, 400"))
        for f, name, t, _ in rows:
            if f != far or name.startswith("labels, 400"):
                continue
            both = [p for p in PAIRS if t[p] is not None and base[p] is not None]
            worst = max(abs(t[p] / base[p] - 1.0) for p in both) if both else float("nan")
            lost = [p for p in PAIRS if (t[p] is None) != (base[p] is None)]
            lines.append(
                f"- {far}: {name} against labels at 400 nodes/cell: largest change {100 * worst:.0f} %"
                + (f"; determined in one and not the other: {', '.join(lost)}" if lost else "")
            )
    with open(args.markdown, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


def per_cell(run, status, markdown):
    fit = os.path.join(run, "fit")
    result = json.load(open(os.path.join(fit, "result.json")))
    rows = list(csv.DictReader(open(os.path.join(fit, "interfaces.csv"))))
    last = [r for r in csv.DictReader(open(os.path.join(fit, "iterations.csv")))]
    lines = [
        "| interface | direct (mN/m) | refined (mN/m) | ± sd | observed / simulated (relative) |",
        "|---|---|---|---|---|",
    ]
    def number(text):
        return "—" if text == "" else f"{float(text):.3f}"

    for r in rows:
        lines.append(
            f"| {r['cell_a']}-{r['cell_b']} | {number(r['direct_mn_per_m'])} | {number(r['tension_mn_per_m'])} | "
            f"{number(r['tension_sd_mn_per_m'])} | {number(r['observed_relative'])} / {number(r['simulated_relative'])} |"
        )
    converged = result.get("converged")
    lines += [
        "",
        f"- {len(rows)} interfaces, {len(last)} iterations, {result['wall_seconds']:.0f} s on {result['threads']} threads, exit status {status}; converged: {converged}; "
        f"mismatch (rms of the relative tensions) {result['rms_mismatch']:.4f} at the best iteration "
        f"(iteration {result['best_iteration']}; start {result['start_mismatch']:.4f}, tolerance {result['tolerance']})",
    ]
    with open(markdown, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
