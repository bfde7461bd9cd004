#!/usr/bin/env python3
"""Measures the coverage of the per-cell map's intervals (`tension_sd` of `fit/interfaces.csv`) on
Surface Evolver truths: clusters of 4, 5 and 6 cells with additive interface tensions
T_ij = a_i + a_j (a_i drawn from [0.3, 0.85], free tension 1; `make_cluster.py additive`), each
voxelised at 10 and 20 voxels per cell diameter and fitted with `mode = "per_cell"` (the model of
score_per_cell.py: compact-embryo relaxation, 1,500 steps per pass, 4 sub-voxel placements per
measurement). For every interface: the error of the refined tension against the truth (both maps
scaled so that their mean cell–medium tension is the truth's) in units of its `tension_sd`; the
coverage is the fraction with |error| ≤ 1 sd (nominal 68.3 %) and ≤ 2 sd (nominal 95.4 %). The same
for every cell's pressure (`pressure_sd` of cells.csv; Evolver's body pressure, per micrometre at
free tension 1) and lateral tension a_i (its sd through the least squares a_i + a_j = T_ij).

The seeds of `--calibrate` (default 1–8: 24 truths per resolution) set `per_cell.model_error` (the
binary's defaults are this calibration, rounded); each sd is rebuilt from the parts the fit wrote
with that model error, so the fits need not be rerun after a recalibration. Scored: the held-out
seeds (default 9–12) with the calibration, and every calibration seed with the model error
calibrated on the other calibration seeds (leave one seed out).

The truths are made first (Evolver, `--refine 2`, ~20–40 s each) unless TRUTHS already holds them.

Usage: coverage.py TISSUEFIT TRUTHS WORKDIR --markdown OUT.md [--json OUT.json] [--seeds 1-12]
       [--calibrate 1-8] [--cells 4,5,6] [--resolutions 10,20]
"""
import argparse, csv, json, math, pathlib, statistics, subprocess, sys, time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "validation/per_cell"))
from score_per_cell import MODEL  # noqa: E402  (the same forward model as the accuracy table)

DIAMETER_UM = 8.0


def make_truth(truths: pathlib.Path, cells: int, seed: int) -> pathlib.Path:
    d = truths / f"a{cells}_s{seed}"
    if not (d / "truth.json").exists():
        subprocess.run([sys.executable, str(ROOT / "validation/evolver/make_cluster.py"), "additive", "--seed", str(seed),
                        "--cells", str(cells), "--refine", "2", "--out", str(d)], check=True, capture_output=True)
    return d


def fit(exe: str, truth: pathlib.Path, vox: int, work: pathlib.Path, reuse: bool):
    d = work / f"{truth.name}_{vox}"
    if reuse and (d / "out/result.json").exists():
        wall = float((d / "wall.txt").read_text()) if (d / "wall.txt").exists() else 0.0
        return read_fit(d), json.load(open(d / "out/result.json")), wall
    d.mkdir(parents=True, exist_ok=True)
    labels = d / "labels.tif"
    size = DIAMETER_UM / vox
    subprocess.run([exe, "voxelize", str(truth / "cluster.vtk"), "--length-unit", "um", "--voxel-size", f"{size}um",
                    "--out", str(labels), "-q"], check=True, capture_output=True)
    cfg = d / "fit.toml"
    cfg.write_text(f'mode = "per_cell"\n[observed]\nlabels = "{labels}"\n[observed.meshing]\ntarget_nodes = 200\n{MODEL}')
    t0 = time.time()
    p = subprocess.run([exe, "fit", "--config", str(cfg), "--out", str(d / "out"), "-q"], capture_output=True, text=True)
    wall = time.time() - t0
    (d / "wall.txt").write_text(f"{wall:.3f}\n")
    if p.returncode not in (0, 1) or not (d / "out/interfaces.csv").exists():
        return None, f"{truth.name} at {vox}: exit {p.returncode}: {p.stderr.strip()[-300:]}", wall
    return read_fit(d), json.load(open(d / "out/result.json")), wall


def read_fit(d: pathlib.Path):
    """interfaces.csv and cells.csv of one fit."""
    return (list(csv.DictReader(open(d / "out/interfaces.csv"))), list(csv.DictReader(open(d / "out/cells.csv"))))


def z_scores(rows, truth):
    """Errors of the refined tensions in units of their sd, and relative errors (every interface),
    with the parts of each sd (the model error apart) to rescore them with another model error."""
    def true_tension(a, b):
        if b == 0:
            return truth["gamma_a"]
        return truth["interfaces"][f"{min(a, b)}-{max(a, b)}"]["tension"]

    free = [float(r["tension_mn_per_m"]) for r in rows if r["cell_b"] == "0" and r["tension_mn_per_m"]]
    scale = truth["gamma_a"] / (sum(free) / len(free))
    out = []
    for r in rows:
        if not r["tension_mn_per_m"] or not r["tension_sd_mn_per_m"]:
            continue
        a, b = int(r["cell_a"]), int(r["cell_b"])
        t, sd = float(r["tension_mn_per_m"]) * scale, float(r["tension_sd_mn_per_m"]) * scale
        truth_t = true_tension(a, b)
        num = lambda k: float(r[k]) if r.get(k) else None
        out.append(dict(a=a, b=b, tension=t, z=(t - truth_t) / sd, rel=t / truth_t - 1, rel_sd=sd / t, free=b == 0,
                        source=r["sd_source"],
                        mismatch=num("mismatch"), placement_sd=num("placement_sd"), placements=num("placements"),
                        model_error=num("model_error")))
    return out


def cell_items(interface_rows, cell_rows, truth):
    """Each cell's pressure (relative error, the binary's z, and the free surface it leans on) and
    lateral tension a_i (ours and the truth's, scaled like the tensions), both against the truth."""
    free = [float(r["tension_mn_per_m"]) for r in interface_rows if r["cell_b"] == "0" and r["tension_mn_per_m"]]
    mean_free = sum(free) / len(free)  # mN/m; the truth's free tension is 1
    per_um = lambda pa: pa / (mean_free * 1e-3) * 1e-6  # Pa -> (free tension 1) per micrometre
    pressures, lateral = [], []
    for c in cell_rows:
        cell = int(c["cell"])
        if c.get("pressure_pa") and c.get("pressure_sd_pa") and str(cell) in truth["pressures"]:
            ours, truth_p = per_um(float(c["pressure_pa"])), truth["pressures"][str(cell)] / truth["evolver_length_to_um"]
            pressures.append(dict(cell=cell, rel=ours / truth_p - 1, z=(ours - truth_p) / per_um(float(c["pressure_sd_pa"]))))
        known = truth.get("per_cell_lateral") or {}
        if c.get("lateral_tension_mn_per_m") and str(cell) in known:
            lateral.append(dict(cell=cell, ours=float(c["lateral_tension_mn_per_m"]) / mean_free,
                                truth=known[str(cell)]))
    return pressures, lateral


def sd_with(z, m):
    """The relative sd the interface would have with relative model error m."""
    if z["placement_sd"] is None or z["mismatch"] is None:
        return None
    return math.sqrt(z["mismatch"] ** 2 + z["placement_sd"] ** 2 * (1 + 1 / z["placements"]) + m ** 2)


def covered(z, m):
    sd = sd_with(z, m)
    return sd is not None and abs(z["rel"]) <= sd * (1 + z["rel"])  # |t - T| <= sd_rel * t, t = T (1 + rel)


def needed(items, target, covered_with):
    """The model error m whose ±1 sd holds `target` of `items` (bisection: coverage grows with m)."""
    frac = lambda m: sum(covered_with(z, m) for z in items) / len(items)
    if frac(0.0) >= target:
        return 0.0
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if frac(mid) < target else (lo, mid)
    return hi


def fit_model_error(points):
    """m² = floor² + (coefficient · r)² through (r, m) points by least squares (both ≥ 0)."""
    if not points:
        return None
    if len(points) == 1:
        r, m = points[0]
        return dict(coefficient=m / r, floor=0.0, needed={round(1 / r): m})
    n = len(points)
    sx = sum(r * r for r, _ in points); sy = sum(m * m for _, m in points)
    sxx = sum(r ** 4 for r, _ in points); sxy = sum(r * r * m * m for r, m in points)
    den = n * sxx - sx * sx
    C = (n * sxy - sx * sy) / den if den > 0 else 0.0
    F = (sy - C * sx) / n
    if C < 0:
        C, F = 0.0, sy / n
    if F < 0:
        F, C = 0.0, sxy / sxx
    return dict(coefficient=math.sqrt(C), floor=math.sqrt(F), needed={round(1 / r): m for r, m in points})


def resolution_of(cases):
    return statistics.mean(1 / c["voxels_per_diameter"] for c in cases)


def calibrate_class(cases, items_of, covered_with, target=0.683):
    """A model error (coefficient per voxel size / diameter, floor) from `cases`: at each
    resolution the m whose ±1 sd holds `target` of that resolution's items (`items_of(case)`;
    `covered_with(item, m)`), then m² = floor² + (coefficient · voxel/diameter)² through them."""
    points = []
    for vox in sorted({c["vox"] for c in cases}):
        sub = [c for c in cases if c["vox"] == vox]
        items = [i for c in sub for i in items_of(c)]
        if items:
            points.append((resolution_of(sub), needed(items, target, covered_with)))
    return fit_model_error(points)


def calibrate(cases, free):
    """`per_cell.model_error` of one class of interfaces (cell–medium when `free`)."""
    return calibrate_class(cases, lambda c: [z for z in c["z"] if z["free"] == free and sd_with(z, 0) is not None],
                           covered)


def model_error(coefficients, kind, resolution):
    k = coefficients[kind]
    return math.sqrt(k["floor"] ** 2 + (k["coefficient"] * resolution) ** 2)


def free_sd(case, cell, coefficients):
    """The relative sd of `cell`'s free surface under `coefficients`' interface model error."""
    r = 1 / case["voxels_per_diameter"]
    for z in case["z"]:
        if z["free"] and z["a"] == cell:
            return sd_with(z, model_error(coefficients, "cell_medium", r))
    return None


def pressure_covered(case, p, coefficients, m):
    """|error| ≤ sd for pressure item `p`: sd² = (its free surface's sd)² + m², relative."""
    s = free_sd(case, p["cell"], coefficients)
    return s is not None and abs(p["rel"]) <= math.hypot(s, m) * (1 + p["rel"])


def calibrate_pressure(cases, coefficients):
    """`per_cell.model_error.pressure` and `pressure_floor` from `cases`, given the interfaces'."""
    return calibrate_class(
        cases, lambda c: [(c, p) for p in c["pressures"] if free_sd(c, p["cell"], coefficients) is not None],
        lambda cp, m: pressure_covered(cp[0], cp[1], coefficients, m))


def lateral_items(case, coefficients):
    """[(least-squares sd, error, ours)] of `case`'s lateral tensions a_i with the interfaces' sds
    under `coefficients`, propagated through the least squares a_i + a_j = T_ij as the binary does
    (independent errors; only cells whose a_i the cell–cell interfaces determine)."""
    r = 1 / case["voxels_per_diameter"]
    rows = [z for z in case["z"] if not z["free"] and sd_with(z, 0) is not None]
    cells = sorted({x["cell"] for x in case["lateral"]})
    if not rows or not cells:
        return []
    index = {c: k for k, c in enumerate(cells)}
    rows = [z for z in rows if z["a"] in index and z["b"] in index]
    A = np.zeros((len(rows), len(cells)))
    sd = np.zeros(len(rows))
    for i, z in enumerate(rows):
        A[i, index[z["a"]]] = A[i, index[z["b"]]] = 1.0
        sd[i] = z["tension"] * sd_with(z, model_error(coefficients, "cell_cell", r))
    pinv = np.linalg.pinv(A)
    _, sv, vt = np.linalg.svd(A)
    rank = int(np.sum(sv > 1e-9 * sv[0]))
    out = []
    for x in case["lateral"]:
        k = index[x["cell"]]
        if abs(np.sum(vt[:rank, k] ** 2) - 1) > 1e-6:
            continue
        out.append((math.sqrt(float(np.sum((pinv[k] * sd) ** 2))), x["ours"] - x["truth"], x["ours"]))
    return out


def lateral_is_covered(item, m):
    """|error| ≤ sd for a lateral tension: sd² = (least squares' sd)² + (m · a_i)²."""
    s, error, ours = item
    return abs(error) <= math.hypot(s, m * abs(ours))


def calibrate_lateral(cases, coefficients):
    """`per_cell.model_error.lateral` and `lateral_floor` from `cases`, given the interfaces'."""
    return calibrate_class(cases, lambda c: lateral_items(c, coefficients), lateral_is_covered)


def three_figures(coefficients):
    """`coefficients` as the binary's defaults carry them: three significant figures."""
    r = lambda x: float(f"{x:.3g}")
    return {k: dict(v, coefficient=r(v["coefficient"]), floor=r(v["floor"])) for k, v in coefficients.items()}


def calibrate_all(cases):
    coefficients = {"cell_cell": calibrate(cases, False), "cell_medium": calibrate(cases, True)}
    coefficients["pressure"] = calibrate_pressure(cases, coefficients)
    coefficients["lateral"] = calibrate_lateral(cases, coefficients)
    return three_figures(coefficients)


def lateral_covered(case, coefficients):
    """(covered, scored) lateral tensions of `case` under `coefficients`."""
    m = model_error(coefficients, "lateral", 1 / case["voxels_per_diameter"])
    hits = [lateral_is_covered(i, m) for i in lateral_items(case, coefficients)]
    return sum(hits), len(hits)


def coverage_of(cases, coefficients, vox):
    """Within ±1 sd under `coefficients` at `vox`: (interfaces, pressures, lateral tensions), each
    (covered, scored)."""
    sub = [c for c in cases if c["vox"] == vox]
    zs = [(z, 1 / c["voxels_per_diameter"]) for c in sub for z in c["z"] if sd_with(z, 0) is not None]
    t = (sum(covered(z, model_error(coefficients, "cell_medium" if z["free"] else "cell_cell", r)) for z, r in zs),
         len(zs))
    ps = [(c, p) for c in sub for p in c["pressures"] if free_sd(c, p["cell"], coefficients) is not None]
    p = (sum(pressure_covered(c, x, coefficients, model_error(coefficients, "pressure", 1 / c["voxels_per_diameter"]))
             for c, x in ps), len(ps))
    lat = [lateral_covered(c, coefficients) for c in sub]
    return t, p, (sum(h for h, _ in lat), sum(n for _, n in lat))


def summary(zs):
    n = len(zs)
    if n == 0:
        return dict(n=0)
    return dict(
        n=n,
        within1=sum(abs(z["z"]) <= 1 for z in zs) / n,
        within2=sum(abs(z["z"]) <= 2 for z in zs) / n,
        median_error=statistics.median(abs(z["rel"]) for z in zs),
        median_rel_sd=statistics.median(z["rel_sd"] for z in zs),
        rms_z=math.sqrt(sum(z["z"] ** 2 for z in zs) / n),
    )


def rounded(x):
    """x with every float to 5 significant digits (a smaller committed file)."""
    if isinstance(x, float):
        return float(f"{x:.5g}")
    if isinstance(x, dict):
        return {k: rounded(v) for k, v in x.items()}
    if isinstance(x, list):
        return [rounded(v) for v in x]
    return x


def span(text):
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(x) for x in text.split(",")]


def pct(pair):
    hit, n = pair
    return f"{100 * hit / n:.1f} % ({n})" if n else "–"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("exe")
    ap.add_argument("truths")
    ap.add_argument("work")
    ap.add_argument("--markdown", required=True)
    ap.add_argument("--json")
    ap.add_argument("--seeds", default="1-12")
    ap.add_argument("--cells", default="4,5,6")
    ap.add_argument("--resolutions", default="10,20")
    ap.add_argument("--calibrate", default="1-8", help="seeds whose truths set the model error; the rest are held out")
    ap.add_argument("--reuse-seeds", default="",
                    help="seeds whose fits in WORKDIR are read, not rerun (their coverage is scored from the parts)")
    a = ap.parse_args()
    reuse = set(span(a.reuse_seeds)) if a.reuse_seeds else set()
    truths, work = pathlib.Path(a.truths), pathlib.Path(a.work)
    truths.mkdir(parents=True, exist_ok=True)
    per_case, failures = [], []
    for vox in span(a.resolutions):
        for cells in span(a.cells):
            for seed in span(a.seeds):
                t = make_truth(truths, cells, seed)
                truth = json.load(open(t / "truth.json"))
                rows, result, wall = fit(a.exe, t, vox, work, seed in reuse)
                if rows is None:
                    failures.append(result)
                    print(f"FAILED {result}", file=sys.stderr)
                    continue
                interface_rows, cell_rows = rows
                zs = z_scores(interface_rows, truth)
                pressures, lateral = cell_items(interface_rows, cell_rows, truth)
                per_case.append(dict(truth=t.name, cells=cells, seed=seed, vox=vox, wall=wall,
                                     voxels_per_diameter=result["voxels_per_diameter"],
                                     converged=result["converged"], rms_mismatch=result["rms_mismatch"], z=zs,
                                     pressures=pressures, lateral=lateral))
                s = summary(zs)
                print(f"{t.name} at {vox} vox: {s['n']} interfaces, within 1 sd {s['within1']:.2f}, "
                      f"median error {100 * s['median_error']:.1f} %, median sd {100 * s['median_rel_sd']:.1f} %, "
                      f"pressure median error "
                      f"{100 * statistics.median([abs(p['rel']) for p in pressures] or [math.nan]):.1f} %, {wall:.0f} s",
                      file=sys.stderr)
    seeds = sorted({c["seed"] for c in per_case})
    calib_seeds = sorted(set(span(a.calibrate)) & set(seeds))
    held_seeds = [s for s in seeds if s not in calib_seeds]
    defaults = calibrate_all(per_case)
    print(f"model error calibrated on all {len(per_case)} fits: {defaults}", file=sys.stderr)
    fold = calibrate_all([c for c in per_case if c["seed"] in calib_seeds])
    # Leave one seed out: each seed's truths scored with the model error calibrated on the other
    # seeds' (out of sample, every truth once): what the defaults, calibrated on all of them, cover.
    loso = {s: calibrate_all([c for c in per_case if c["seed"] != s]) for s in seeds} if len(seeds) > 1 else {}
    names = ["cell_cell", "cell_medium", "pressure", "lateral"]
    as_toml = lambda coefs: ", ".join(f"{k} = {coefs[k]['coefficient']:.3g}, {k}_floor = {coefs[k]['floor']:.3g}"
                                      for k in names)
    lines = [f"The binary's `per_cell.model_error` defaults are the calibration on all {len(seeds)} seeds "
             f"({len(per_case)} fits): {as_toml(defaults)}.", "",
             "| truths scored | resolution | truths | interfaces within ±1 sd (nominal 68.3 %) | cell–cell / cell–medium "
             "| pressures within ±1 sd | lateral tensions a_i within ±1 sd | interfaces within ±2 sd (95.4 %) | "
             "median error % (interfaces / pressures) | median sd % | wall s per fit |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]

    def row(label, scored, vox):
        """One table row: `scored` (case, the coefficients it is scored with) at `vox`."""
        scored = [(c, k) for c, k in scored if c["vox"] == vox]
        if not scored:
            return
        counts = [coverage_of([c], k, vox) for c, k in scored]
        t, p, lat = ((sum(x[i][0] for x in counts), sum(x[i][1] for x in counts)) for i in range(3))
        zs = [(z, 1 / c["voxels_per_diameter"], k) for c, k in scored for z in c["z"] if sd_with(z, 0) is not None]
        cc = [covered(z, model_error(k, "cell_cell", x)) for z, x, k in zs if not z["free"]]
        cm = [covered(z, model_error(k, "cell_medium", x)) for z, x, k in zs if z["free"]]
        sds = [sd_with(z, model_error(k, "cell_medium" if z["free"] else "cell_cell", x)) for z, x, k in zs]
        within2 = sum(abs(z["rel"]) <= 2 * s * (1 + z["rel"]) for (z, _, _), s in zip(zs, sds)) / len(zs)
        sub = [c for c, _ in scored]
        lines.append(
            f"| {label} | {vox} voxels per diameter | {len(sub)} | {pct(t)} | {100 * sum(cc) / len(cc):.0f} % / "
            f"{100 * sum(cm) / len(cm):.0f} % | {pct(p)} | {pct(lat)} | {100 * within2:.1f} % | "
            f"{100 * statistics.median(abs(z['rel']) for z, _, _ in zs):.1f} / "
            f"{100 * statistics.median([abs(x['rel']) for c in sub for x in c['pressures']] or [math.nan]):.1f} | "
            f"{100 * statistics.median(sds):.1f} | "
            f"{statistics.median([c['wall'] for c in sub if c['wall'] > 0] or [math.nan]):.0f} |")

    for vox in span(a.resolutions):
        if loso:
            row(f"every seed, left out ({seeds[0]}–{seeds[-1]})", [(c, loso[c["seed"]]) for c in per_case], vox)
    for vox in span(a.resolutions):
        if held_seeds and calib_seeds:
            row(f"seeds {held_seeds[0]}–{held_seeds[-1]}, calibrated on {calib_seeds[0]}–{calib_seeds[-1]}",
                [(c, fold) for c in per_case if c["seed"] in held_seeds], vox)
    bare = {k: dict(coefficient=0.0, floor=0.0) for k in names}
    lines.append("")
    if held_seeds and calib_seeds:
        lines.append(f"The model error calibrated on seeds {calib_seeds[0]}–{calib_seeds[-1]} alone: {as_toml(fold)}.")
    lines.append("Without any model error (m = 0) the interfaces' ±1 sd holds " +
                 ", ".join(f"{pct(coverage_of(per_case, bare, vox)[0])} at {vox}" for vox in span(a.resolutions)) +
                 " voxels per diameter (all seeds).")
    if failures:
        lines.append("")
        lines.append(f"Failed fits ({len(failures)}): " + "; ".join(failures))
    pathlib.Path(a.markdown).write_text("\n".join(lines) + "\n")
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps(rounded(dict(coefficients=defaults, calibrated_on_fold=dict(seeds=calib_seeds, coefficients=fold), cases=per_case)),
                                                   separators=(",", ":")) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
