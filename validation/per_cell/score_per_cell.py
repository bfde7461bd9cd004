#!/usr/bin/env python3
"""Runs `tissuefit fit` with `mode = "per_cell"` on label volumes with known interface tensions and
scores the refined map and the direct estimate it starts from against the truth (per-interface
relative errors, every interface, both maps scaled so their mean cell–medium tension is the truth's).

Cases: Surface Evolver's heterogeneous cluster (validation/evolver/fixtures/hetero4, six different
interface tensions, an outside truth) at 10 and 20 voxels per diameter (the relaxation of the
compact-embryo preset, 1,500 steps per pass; and 4,000 at 10 voxels); and our own model's truth:
hetero4's Evolver mesh relaxed by `tissuefit simulate` with per-cell lateral tensions
a = (0.29, 0.61, 0.77, 0.93) mN/m (free 1 mN/m), voxelised on the 10-voxel grid (a consistency
check: the forward model is then exact up to mesh resolution).

Usage: score_per_cell.py TISSUEFIT WORKDIR --markdown OUT.md
"""
import argparse, csv, json, pathlib, statistics, subprocess, time

ROOT = pathlib.Path(__file__).resolve().parents[2]
FIX = ROOT / "validation/evolver/fixtures"

MODEL = """
[model_overrides.numerics]
contact_model = "coupling"
polarity = "contacts"
dynamics = "overdamped"
damping = 3e-9
[[model_overrides.cell_types]]
kind = "epithelial"
area_elasticity = 0.0
max_pressure = inf
growth_rate = 0.0
faces.apical = { surface_tension = 1e-3, bending_modulus = 0.0, adhesion = 0.0 }
faces.basal = { surface_tension = 1e-3, bending_modulus = 0.0, adhesion = 0.0 }
faces.lateral = { surface_tension = 0.5e-3, bending_modulus = 0.0, adhesion = 0.0 }
[model_overrides.simulation]
mode = "equilibrium"
method = "fire"
max_steps = 1500
settle_steps = 500
remesh_every_steps = 50
[forward]
accept_residual = 1e9
measure_shifts = 4
[per_cell]
iterations = 6
tolerance = 0.005
"""

OWN_A = {1: 0.29, 2: 0.61, 3: 0.77, 4: 0.93}


def own_truth_model():
    text = MODEL.split("[forward]")[0].replace("model_overrides.", "")
    text = text.replace("max_steps = 1500", "max_steps = 4000").replace("settle_steps = 500", "settle_steps = 1000")
    text = text.replace('damping = 3e-9', 'damping = 3e-9\nmin_edge_length = 3e-7\ncontact_cutoff = 3e-7')
    for c, a in OWN_A.items():
        text += f"[[cell_overrides]]\nid = {c}\nsurface_tension = {{ lateral = {a}e-3 }}\n"
    return text


def errors(rows, column, truth_of):
    free = [float(r[column]) for r in rows if r["cell_b"] == "0"]
    scale = 1.0 / (sum(free) / len(free))
    e = [abs(float(r[column]) * scale / truth_of(int(r["cell_a"]), int(r["cell_b"])) - 1) for r in rows]
    return statistics.median(e), max(e)


def run(exe, work, name, labels, truth_of, steps=None):
    d = work / name.replace(" ", "_").replace("/", "_").replace(",", "").replace("'", "").replace("(", "").replace(")", "")
    d.mkdir(parents=True, exist_ok=True)
    cfg = d / "fit.toml"
    model = MODEL
    if steps:
        model = model.replace("max_steps = 1500", f"max_steps = {steps[0]}").replace("settle_steps = 500", f"settle_steps = {steps[1]}")
    cfg.write_text(f'mode = "per_cell"\n[observed]\nlabels = "{labels}"\n[observed.meshing]\ntarget_nodes = 200\n{model}')
    t0 = time.time()
    p = subprocess.run([exe, "fit", "--config", str(cfg), "--out", str(d / "out"), "-q"], capture_output=True, text=True)
    wall = time.time() - t0
    if p.returncode not in (0, 1):
        raise SystemExit(f"{name}: {p.stderr}")
    rows = list(csv.DictReader(open(d / "out/interfaces.csv")))
    result = json.load(open(d / "out/result.json"))
    its = list(csv.DictReader(open(d / "out/iterations.csv")))
    return dict(
        case=name,
        iterations=len(its),
        mismatches=[round(float(i["rms_mismatch"]), 4) for i in its],
        best_iteration=result["best_iteration"],
        refined=errors(rows, "tension_mn_per_m", truth_of),
        direct=errors(rows, "direct_mn_per_m", truth_of),
        wall=wall,
    )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("exe")
    ap.add_argument("work")
    ap.add_argument("--markdown", required=True)
    a = ap.parse_args()
    work = pathlib.Path(a.work)
    truth = json.load(open(FIX / "hetero4/truth.json"))

    def evolver(x, y):
        if y == 0:
            return truth["gamma_a"]
        return truth["interfaces"][f"{min(x, y)}-{max(x, y)}"]["tension"]

    def own(x, y):
        return 1.0 if y == 0 else OWN_A[x] + OWN_A[y]

    rows = [
        run(a.exe, work, "hetero4 (Evolver), 10 vox/diameter", FIX / "hetero4/labels_10.tif", evolver),
        run(a.exe, work, "hetero4 (Evolver), 10 vox/diameter, 4,000 steps per pass", FIX / "hetero4/labels_10.tif",
            evolver, steps=(4000, 1500)),
        run(a.exe, work, "hetero4 (Evolver), 20 vox/diameter", FIX / "hetero4/labels_20.tif", evolver),
    ]
    own_dir = work / "own"
    own_dir.mkdir(parents=True, exist_ok=True)
    (own_dir / "model.toml").write_text(own_truth_model())
    subprocess.run([a.exe, "simulate", str(FIX / "hetero4/cluster.vtk"), "--length-unit", "um", "--config",
                    str(own_dir / "model.toml"), "--out", str(own_dir / "sim"), "-q"], capture_output=True)
    subprocess.run([a.exe, "voxelize", str(own_dir / "sim/final.vtp"), "--like", str(FIX / "hetero4/labels_10.tif"),
                    "--out", str(own_dir / "labels_10.tif"), "-q"], check=True, capture_output=True)
    rows.append(run(a.exe, work, "own model's hetero4, 10 vox/diameter", own_dir / "labels_10.tif", own))
    with open(a.markdown, "w") as f:
        f.write("| case | iterations | rms mismatch per iteration | answer (best) | refined: median / max error % | direct estimate: median / max % | wall s |\n")
        f.write("|---|---|---|---|---|---|---|\n")
        for r in rows:
            f.write(f"| {r['case']} | {r['iterations']} | {', '.join(f'{m:.3f}' for m in r['mismatches'])} | "
                    f"{r['best_iteration']} | {100 * r['refined'][0]:.1f} / {100 * r['refined'][1]:.1f} | "
                    f"{100 * r['direct'][0]:.1f} / {100 * r['direct'][1]:.1f} | {r['wall']:.0f} |\n")
    print(open(a.markdown).read())


if __name__ == "__main__":
    main()
