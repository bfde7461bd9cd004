#!/usr/bin/env python3
"""Scores spring-contact adhesion maps (`mode = "per_cell"` with `contact_model = "spring"`) on Surface
Evolver truths: the clusters of coverage.py (4, 5 and 6 cells, additive interface tensions
T_ij = a_i + a_j with a_i drawn from [0.3, 0.85], free tension 1), each voxelised at 10 and 20 voxels
per cell diameter and fitted with the forward model of score_per_cell.py with spring contacts (the
face quadrature, no polarity): every cell one tension γ_i and its own adhesion ω_i, so that
T_ij = γ_i + γ_j − (ω_i + ω_j)·c²/4.

Evolver knows nothing of springs: its truth is the tensions. A cell's adhesion energy per side
W_i = ω_i·c²/4 = γ_i − a_i is what a spring model must have to make them, so the truth of W_i is
1 − a_i (in units of the free tension). Scored: every interface's tension (relative error, both maps
scaled so that their mean cell–medium tension is the truth's), every cell's W_i where cells.csv gives
it (absolute error in units of the free tension, and relative), and the fraction of each within its
±1 sd (nominal 68.3 %). The sds carry `per_cell.model_error` (calibrated on coupled maps) times
`per_cell.spring_model_error`; the factor that makes ±1 sd hold 68.3 % of the interfaces is
calibrated here on all truths (the binary's default, rounded) and scored leave-one-seed-out (each
seed with the factor calibrated on the others).

Usage: adhesion.py TISSUEFIT TRUTHS WORKDIR --markdown OUT.md [--json OUT.json] [--seeds 1-4]
       [--cells 4,5,6] [--resolutions 10,20]
"""
import argparse, csv, json, pathlib, statistics, subprocess, sys, time, tomllib

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "validation/per_cell"))
from coverage import DIAMETER_UM, make_truth, sd_with, span, z_scores  # noqa: E402
from score_per_cell import MODEL  # noqa: E402

SPRING = MODEL.replace('contact_model = "coupling"', 'contact_model = "spring"\ncontact_quadrature = "faces"') \
              .replace('polarity = "contacts"', 'polarity = "none"')


def fit(exe, truth, vox, work):
    d = work / f"{truth.name}_{vox}"
    d.mkdir(parents=True, exist_ok=True)
    labels = d / "labels.tif"
    subprocess.run([exe, "voxelize", str(truth / "cluster.vtk"), "--length-unit", "um", "--voxel-size",
                    f"{DIAMETER_UM / vox}um", "--out", str(labels), "-q"], check=True, capture_output=True)
    cfg = d / "fit.toml"
    cfg.write_text(f'mode = "per_cell"\n[observed]\nlabels = "{labels}"\n[observed.meshing]\ntarget_nodes = 200\n{SPRING}')
    t0 = time.time()
    p = subprocess.run([exe, "fit", "--config", str(cfg), "--out", str(d / "out"), "-q"], capture_output=True, text=True)
    wall = time.time() - t0
    if p.returncode not in (0, 1) or not (d / "out/cells.csv").exists():
        raise SystemExit(f"{truth.name} at {vox}: exit {p.returncode}: {p.stderr.strip()[-400:]}")
    rows = list(csv.DictReader(open(d / "out/interfaces.csv")))
    cells = list(csv.DictReader(open(d / "out/cells.csv")))
    used = tomllib.loads((d / "out/fit.toml").read_text())["per_cell"]["spring_model_error"]
    return rows, cells, json.load(open(d / "out/result.json")), wall, used


def covered_by(items, q):
    """The fraction of interface `items` within ±1 sd with their model error times q."""
    hits = [abs(z["rel"]) <= sd_with(z, q * z["model_error"]) * (1 + z["rel"]) for z in items]
    return sum(hits) / len(hits)


def factor_needed(items, target=0.683):
    """The multiplier q on the items' model error whose ±1 sd holds `target` of them (bisection)."""
    lo, hi = 0.0, 20.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if covered_by(items, mid) < target else (lo, mid)
    return hi


def adhesion_items(rows, cells, truth):
    """Each cell's adhesion energy W_i against 1 − a_i, in units of the mean free tension."""
    free = [float(r["tension_mn_per_m"]) for r in rows if r["cell_b"] == "0" and r["tension_mn_per_m"]]
    mean_free = sum(free) / len(free)
    known = truth["per_cell_lateral"]
    out = []
    for c in cells:
        if not c["adhesion_energy_mj_per_m2"] or c["cell"] not in known:
            continue
        w = float(c["adhesion_energy_mj_per_m2"]) / mean_free
        sd = float(c["adhesion_energy_sd_mj_per_m2"]) / mean_free
        t = 1.0 - known[c["cell"]]
        out.append(dict(cell=int(c["cell"]), ours=w, truth=t, err=w - t, rel=w / t - 1, covered=abs(w - t) <= sd))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("exe")
    ap.add_argument("truths")
    ap.add_argument("work")
    ap.add_argument("--markdown", required=True)
    ap.add_argument("--json")
    ap.add_argument("--seeds", default="1-4")
    ap.add_argument("--cells", default="4,5,6")
    ap.add_argument("--resolutions", default="10,20")
    a = ap.parse_args()
    truths, work = pathlib.Path(a.truths), pathlib.Path(a.work)
    truths.mkdir(parents=True, exist_ok=True)
    work.mkdir(parents=True, exist_ok=True)
    cases = [make_truth(truths, int(n), s) for s in span(a.seeds) for n in a.cells.split(",")]
    table, by_seed, used = [], {}, set()
    for vox in (int(v) for v in a.resolutions.split(",")):
        tens, adh, walls, converged, warned = [], [], [], 0, 0
        for truth_dir in cases:
            truth = json.load(open(truth_dir / "truth.json"))
            rows, cells, result, wall, factor = fit(a.exe, truth_dir, vox, work)
            used.add(factor)
            zs = z_scores(rows, truth)
            by_seed.setdefault(int(truth_dir.name.split("_s")[1]), []).extend(
                (vox, z) for z in zs if sd_with(z, 0) is not None)
            tens += zs
            adh += adhesion_items(rows, cells, truth)
            walls.append(wall)
            converged += bool(result["converged"])
            warned += any("beyond the range" in w for w in result["warnings"])
            print(f"{truth_dir.name} at {vox}: {result['rms_mismatch']:.4f} rms mismatch, {wall:.0f} s", flush=True)
        rel = [abs(z["rel"]) for z in tens]
        table.append(dict(
            voxels_per_diameter=vox, truths=len(cases), converged=converged, warned_strong=warned,
            interfaces=len(tens), interface_median_error=statistics.median(rel), interface_max_error=max(rel),
            interface_within_1sd=sum(abs(z["z"]) <= 1 for z in tens) / len(tens),
            cells=len(adh), adhesion_median_abs_error=statistics.median(abs(x["err"]) for x in adh),
            adhesion_max_abs_error=max(abs(x["err"]) for x in adh),
            adhesion_median_rel_error=statistics.median(abs(x["rel"]) for x in adh),
            adhesion_within_1sd=sum(x["covered"] for x in adh) / len(adh),
            median_wall_seconds=statistics.median(walls)))
    # The factor on the coupled model error that holds 68.3 %: on all truths, and leave one seed out.
    (factor,) = used
    every = [z for items in by_seed.values() for _, z in items]
    calibrated = factor * factor_needed(every)
    for r in table:
        hit = n = 0
        for seed, items in by_seed.items():
            q = factor_needed([z for s, its in by_seed.items() if s != seed for _, z in its])
            test = [z for v, z in items if v == r["voxels_per_diameter"]]
            hit += covered_by(test, q) * len(test)
            n += len(test)
        r["interface_within_1sd_left_out"] = hit / n
    lines = [
        f"Spring-contact adhesion maps on {len(cases)} Surface Evolver clusters ({a.cells} cells, seeds {a.seeds}, "
        "additive tensions, free tension 1; the truth of a cell's adhesion energy W = ω·c²/4 is 1 − a_i). "
        "Generated by `docs/scripts/per-cell.sh adhesion` (validation/per_cell/adhesion.py).",
        "",
        "| voxels per diameter | fits converged | interfaces | median error | max error | within ±1 sd "
        "| left out | cells | W: median abs. error | W: max abs. error | W: median rel. error | W within ±1 sd "
        "| median wall (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in table:
        lines.append(
            f"| {r['voxels_per_diameter']} | {r['converged']}/{r['truths']} | {r['interfaces']} "
            f"| {100 * r['interface_median_error']:.1f} % | {100 * r['interface_max_error']:.1f} % "
            f"| {100 * r['interface_within_1sd']:.1f} % | {100 * r['interface_within_1sd_left_out']:.1f} % "
            f"| {r['cells']} | {r['adhesion_median_abs_error']:.3f} "
            f"| {r['adhesion_max_abs_error']:.3f} | {100 * r['adhesion_median_rel_error']:.1f} % "
            f"| {100 * r['adhesion_within_1sd']:.1f} % | {r['median_wall_seconds']:.0f} |")
    lines += ["", "W errors are in units of the free tension (1 = the free surface's tension). Fits whose cells "
              f"went beyond w/(2γ) = 0.6 (warned): {', '.join(str(r['warned_strong']) for r in table)} "
              f"(at {', '.join(str(r['voxels_per_diameter']) for r in table)} voxels per diameter). "
              f"The intervals ran with per_cell.spring_model_error = {factor:g}; the factor whose ±1 sd holds 68.3 % "
              f"of all these interfaces is {calibrated:.2f}; \"left out\": each seed scored with the factor "
              "calibrated on the other seeds."]
    for r in table:
        r["spring_model_error_used"] = factor
        r["spring_model_error_calibrated"] = calibrated
    pathlib.Path(a.markdown).write_text("\n".join(lines) + "\n")
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps(table, indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
