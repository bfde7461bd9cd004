#!/usr/bin/env python3
"""Compare two `tissuefit measure` outputs of the same cluster (e.g. the Surface Evolver equilibrium and
tissuefit's relaxation of it), cell by cell and contact by contact, with the same measuring code on
both sides. Areas are compared scale-free (area / V^(2/3) of the cell or the pair), since a
compressible simulation may hold the cells at another volume than Evolver's fixed one.

    python3 validation/evolver/compare.py EVOLVER_MEASURE_DIR TISSUEFIT_MEASURE_DIR [--json OUT]

Prints one line per contact and a summary: max |Δ rim angle|, max |Δ far-field angle| (degrees),
max relative Δ of the scale-free contact area, max |Δ sphericity|, and the volume ratio.
"""

import argparse
import csv
import json
import math
import os


def load(d):
    cells = {r["cell"]: r for r in csv.DictReader(open(os.path.join(d, "cells.csv")))}
    contacts = {(r["cell_a"], r["cell_b"]): r for r in csv.DictReader(open(os.path.join(d, "contacts.csv")))}
    return cells, contacts


def num(x):
    return float(x) if x not in ("", None) else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("reference")
    ap.add_argument("candidate")
    ap.add_argument("--json", help="write the summary here")
    a = ap.parse_args()
    rc, rk = load(a.reference)
    cc, ck = load(a.candidate)
    if set(rc) != set(cc):
        raise SystemExit(f"the two measurements have different cells: {sorted(rc)} vs {sorted(cc)}")
    out = {"contacts": {}, "cells": {}}
    worst = {"rim_deg": 0.0, "far_field_deg": 0.0, "contact_area_rel": 0.0, "sphericity": 0.0}
    print(f"{'contact':>8} {'rim ref':>8} {'rim':>8} {'ff ref':>8} {'ff':>8} {'area ratio':>10}")
    for key in sorted(set(rk) | set(ck), key=lambda k: (int(k[0]), int(k[1]))):
        r, c = rk.get(key), ck.get(key)
        if r is None or c is None:
            print(f"{key[0]}-{key[1]}: only in {'candidate' if r is None else 'reference'}")
            worst["contact_area_rel"] = max(worst["contact_area_rel"], 1.0)
            continue
        def scaled(row, cells):
            v = 0.5 * (float(cells[key[0]]["volume"]) + float(cells[key[1]]["volume"]))
            return float(row["area"]) / v ** (2 / 3)
        ratio = scaled(c, cc) / scaled(r, rc)
        rim_r, rim_c = num(r["contact_angle_deg"]), num(c["contact_angle_deg"])
        ff_r, ff_c = num(r.get("far_field_angle_deg")), num(c.get("far_field_angle_deg"))
        fmt = lambda x: f"{x:8.2f}" if x is not None else f"{'-':>8}"
        print(f"{key[0]:>4}-{key[1]:<3} {fmt(rim_r)} {fmt(rim_c)} {fmt(ff_r)} {fmt(ff_c)} {ratio:10.4f}")
        if rim_r is not None and rim_c is not None:
            worst["rim_deg"] = max(worst["rim_deg"], abs(rim_c - rim_r))
        if ff_r is not None and ff_c is not None:
            worst["far_field_deg"] = max(worst["far_field_deg"], abs(ff_c - ff_r))
        worst["contact_area_rel"] = max(worst["contact_area_rel"], abs(ratio - 1))
        out["contacts"][f"{key[0]}-{key[1]}"] = {"rim": [rim_r, rim_c], "far_field": [ff_r, ff_c], "area_ratio": ratio}
    vol = []
    for k in sorted(rc, key=int):
        ds = float(cc[k]["sphericity"]) - float(rc[k]["sphericity"])
        worst["sphericity"] = max(worst["sphericity"], abs(ds))
        vol.append(float(cc[k]["volume"]) / float(rc[k]["volume"]))
        out["cells"][k] = {"sphericity": [float(rc[k]["sphericity"]), float(cc[k]["sphericity"])]}
    worst["volume_ratio_min"] = min(vol)
    worst["volume_ratio_max"] = max(vol)
    out["worst"] = worst
    print("worst: " + ", ".join(f"{k} {v:.4g}" for k, v in worst.items()))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=2)


if __name__ == "__main__":
    main()
