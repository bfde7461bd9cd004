#!/usr/bin/env python3
"""Fit the Surface Evolver clusters through `tissuefit run`, as a user would, and tabulate the answer
against the truth.

For each cluster folder (made by make_cluster.py: cluster.vtk + truth.json) and each resolution
(voxels per mean cell diameter), this voxelises the Evolver equilibrium with `tissuefit voxelize`
(unless the label TIFF is already there: the committed fixtures), writes a pipeline
(`fit-template.toml` with the labels and the truth filled in) and runs `tissuefit run` on it. The
table gives the fitted gamma_l/gamma_a, its error, the reported range and whether the range holds the
truth; `--markdown FILE` writes it for the docs book.

    python3 validation/evolver/run_fits.py --clusters validation/evolver/fixtures \\
        --resolutions 10,20 --work /tmp/evolver-fits --markdown docs/src/generated/evolver-fits.md

The tissuefit binary is `target/release/tissuefit` (build it first) or `--tissuefit PATH`.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def labels_for(tissuefit, cluster_dir, truth, per_diameter, work):
    """The label TIFF of the cluster at `per_diameter` voxels per mean cell diameter."""
    committed = os.path.join(cluster_dir, f"labels_{per_diameter}.tif")
    if os.path.exists(committed):
        return committed
    out = os.path.join(work, f"labels_{per_diameter}.tif")
    voxel_um = truth["cell_diameter_um"] / per_diameter
    subprocess.run([tissuefit, "voxelize", os.path.join(cluster_dir, "cluster.vtk"), "--length-unit", "um",
                    "--voxel-size", f"{voxel_um:.6g}um", "--compress", "deflate", "--out", out, "-q"], check=True)
    return out


def tabulate(row, result_path, ratio, model_error=0.05, key_part="lateral"):
    """The row completed from a fit's result.json."""
    r = json.load(open(result_path))
    # the fitted ratio of result.json (its key names the ratio: γ_lateral/γ_apical, or the spring fits' w/(2γ))
    key = next((k for k in r.get("ratios", {}) if key_part in k), None)
    x = r["ratios"][key] if key else None
    fitted = x["value"] if x else None
    lo_hi = x["range"] if x else None
    # The range from the objective alone (the profile's noise bounds; without profile.model_error).
    # A fit run before model_error existed has only that one: its model-error range is then
    # computed here with the same formula (value · exp(±√(o² + ln(1 + m)²))) and marked "post hoc".
    # w/(2γ) is ω/γ times c²/4: the same log offsets as the profile's adhesion_over_tension slice.
    slice_name = "adhesion_over_tension" if key == "adhesion_energy_over_tension" else key
    sl = next((s for s in r.get("profile", []) if key and s["name"] == slice_name), None)
    noise, post_hoc = None, False
    if sl and fitted is not None:
        lo_o, hi_o = sl.get("noise_lower", "absent"), sl.get("noise_upper", "absent")
        if lo_o == "absent":
            post_hoc = True
            lo_o, hi_o = sl.get("lower"), sl.get("upper")
            e = math.log1p(model_error)
            if lo_o is not None and hi_o is not None and lo_hi:
                lo_hi = [min(lo_hi[0], fitted * math.exp(-math.hypot(lo_o, e))),
                         max(lo_hi[1], fitted * math.exp(math.hypot(hi_o, e)))]
        if lo_o is not None and hi_o is not None:
            noise = [fitted * math.exp(lo_o), fitted * math.exp(hi_o)]
    row.update({"fitted": fitted, "error_pct": None if fitted is None else 100 * (fitted - ratio) / ratio,
                "range": lo_hi, "holds": None if not lo_hi else lo_hi[0] <= ratio <= lo_hi[1],
                "noise_range": noise, "noise_holds": None if not noise else noise[0] <= ratio <= noise[1],
                "post_hoc": post_hoc,
                "determined": x.get("determined") if x else None,
                "evaluations": r.get("evaluations"), "objective": r.get("objective"),
                "poor_fit": r.get("poor_fit"), "roughen": r.get("roughen")})
    return row


def rough_cell(rough):
    """result.json's `roughen` as a table cell: the amplitude, and whether it was estimated."""
    if not rough:
        return "0"
    how = "estimated" if rough["estimated"] else "given"
    return f"{rough['voxels']:.2f} ({how}; roughness {rough['observed']:.3f} observed, {rough['simulated']:.3f} simulated)"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clusters", default=os.path.join(HERE, "fixtures"), help="folder of cluster folders")
    ap.add_argument("--only", default="", help="comma-separated cluster names (default: all with a truth ratio)")
    ap.add_argument("--resolutions", default="10,20,40", help="voxels per cell diameter, comma-separated")
    ap.add_argument("--work", required=True, help="folder for the label volumes, pipelines and run directories")
    ap.add_argument("--template", help="the pipeline template (default fit-template.toml, with --spring "
                    "fit-template-aggregate.toml)")
    ap.add_argument("--spring", action="store_true",
                    help="fit spring adhesion (the aggregate preset): the truth is w/(2γ) = 1 − γ_l/γ_a")
    ap.add_argument("--model", default=os.path.join(HERE, "model.toml"), help="the forward model (@MODEL@)")
    ap.add_argument("--tissuefit", default=os.path.join(ROOT, "target", "release", "tissuefit"))
    ap.add_argument("--markdown", help="write the table here (Markdown)")
    ap.add_argument("--json", help="write the rows here (JSON)")
    ap.add_argument("--collect", action="store_true",
                    help="run nothing: tabulate the runs already in --work (those with a fit/result.json)")
    a = ap.parse_args()
    template = open(a.template or os.path.join(
        HERE, "fit-template-aggregate.toml" if a.spring else "fit-template.toml")).read()
    key_part = "adhesion_energy" if a.spring else "lateral"
    names = sorted(d for d in os.listdir(a.clusters) if os.path.exists(os.path.join(a.clusters, d, "truth.json")))
    if a.only:
        names = [n for n in names if n in a.only.split(",")]
    rows = []
    for name in names:
        cdir = os.path.join(a.clusters, name)
        truth = json.load(open(os.path.join(cdir, "truth.json")))
        ratio = truth.get("lateral_over_apical")
        if ratio is None:
            print(f"{name}: heterogeneous tensions, no single ratio to fit; skipped", file=sys.stderr)
            continue
        if a.spring:
            ratio = round(1.0 - ratio, 12)
        for res in [int(r) for r in a.resolutions.split(",")]:
            work = os.path.join(a.work, f"{name}_{res}")
            os.makedirs(work, exist_ok=True)
            if a.collect:
                if not os.path.exists(os.path.join(work, "run", "fit", "result.json")):
                    continue
                log = os.path.join(work, "run.log")
                proc = subprocess.CompletedProcess([], returncode=None, stdout="")
                wall = float("nan")
                manifest = os.path.join(work, "run", "manifest.json")
                if os.path.exists(manifest):
                    stages = json.load(open(manifest)).get("stages", [])
                    wall = sum(st.get("wall_seconds") or 0 for st in stages)
                row = {"cluster": name, "cells": truth["cells"], "per_diameter": res, "truth": ratio,
                       "exit": None, "wall_s": round(wall, 1)}
                result_path = os.path.join(work, "run", "fit", "result.json")
                rows.append(tabulate(row, result_path, ratio, key_part=key_part))
                continue
            labels = labels_for(a.tissuefit, cdir, truth, res, work)
            pipeline = os.path.join(work, "pipeline.toml")
            with open(pipeline, "w") as fh:
                fh.write(template.replace("@LABELS@", os.path.abspath(labels)).replace("@TRUTH@", f"{ratio}")
                         .replace("@MODEL@", os.path.abspath(a.model)))
            started = time.time()
            proc = subprocess.run([a.tissuefit, "run", pipeline, "--out", os.path.join(work, "run"), "--force"],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            wall = time.time() - started
            with open(os.path.join(work, "run.log"), "w") as fh:
                fh.write(proc.stdout)
            row = {"cluster": name, "cells": truth["cells"], "per_diameter": res, "truth": ratio, "exit": proc.returncode,
                   "wall_s": round(wall, 1)}
            result_path = os.path.join(work, "run", "fit", "result.json")
            if os.path.exists(result_path):
                row = tabulate(row, result_path, ratio, key_part=key_part)
            rows.append(row)
            err = row.get("error_pct")
            print(f"{name} @ {res} vox/diam: truth {ratio}, fitted {row.get('fitted')}, "
                  f"error {'n/a' if err is None else f'{err:+.1f} %'}, range {row.get('range')}, exit {proc.returncode}, "
                  f"{wall:.0f} s", file=sys.stderr, flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=2)
    if a.markdown:
        with open(a.markdown, "w") as fh:
            # A column for forward.roughen_voxels when a fit roughened its simulated masks.
            roughened = any(r.get("roughen") for r in rows)
            fh.write("| cluster | cells | vox/diam | truth | fitted | error | reported range | holds truth "
                     "| range from the objective alone | holds truth | evaluations | wall |"
                     + (" simulated masks roughened by (voxels RMS) |" if roughened else "") + "\n")
            fh.write("|---|---|---|---|---|---|---|---|---|---|---|---|" + ("---|" if roughened else "") + "\n")
            for r in rows:
                f, rg, err, holds = r.get("fitted"), r.get("range"), r.get("error_pct"), r.get("holds")
                fitted = "failed" if f is None else f"{f:.3f}"
                error = "" if err is None else f"{err:+.1f} %"
                rng = "" if not rg else f"[{rg[0]:.3f}, {rg[1]:.3f}]"
                held = "" if holds is None else ("yes" if holds else "no")
                if r.get("post_hoc") and rng:
                    rng += " (post hoc)"
                nr, nh = r.get("noise_range"), r.get("noise_holds")
                nrng = "" if not nr else f"[{nr[0]:.3f}, {nr[1]:.3f}]"
                nheld = "" if nh is None else ("yes" if nh else "no")
                fh.write(f"| {r['cluster']} | {r['cells']} | {r['per_diameter']} | {r['truth']:.2f} | {fitted} | {error} | "
                         f"{rng} | {held} | {nrng} | {nheld} | {r.get('evaluations', '')} | {r['wall_s']:.0f} s |"
                         + (f" {rough_cell(r.get('roughen'))} |" if roughened else "") + "\n")
            cover = [r["holds"] for r in rows if r.get("holds") is not None]
            ncover = [r["noise_holds"] for r in rows if r.get("noise_holds") is not None]
            fh.write(f"\nReported ranges hold the truth in {sum(cover)} of {len(cover)} fits; the ranges from the "
                     f"objective alone in {sum(ncover)} of {len(ncover)}.\n")

if __name__ == "__main__":
    main()
