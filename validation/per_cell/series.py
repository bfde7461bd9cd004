#!/usr/bin/env python3
"""Scores `tissuefit fit-series` (a time series mapped in order, each frame started from the
previous frame's correction) on Surface Evolver time series: clusters of `--cells` cells with additive
tensions T_ij = a_i + a_j whose a_i drift linearly by up to ±`--drift` over `--frames` frames
(`make_cluster.py additive --frames N --frame k`), each frame relaxed by Evolver and voxelised at
`--vox` voxels per cell diameter on the first frame's grid. Every series is mapped twice: warm
(the default: each frame's direct estimate times the previous frame's correction) and `--cold`
(the direct estimate alone), with the per-cell model of
score_per_cell.py at `per_cell.tolerance = 0.02` (about the forward model's noise), so that the
iterations a frame needs to converge show what the warm start saves.

Reported per mode: iterations and wall time in all, frames converged, the first relaxation's
mismatch on frames ≥ 1 (how good the start was), the median per-interface error against the truth
(both maps scaled to a mean cell–medium tension of 1), the coverage of ±1 tension_sd, and the error
of each interface's change from the first frame to the last (what a time series is for: which
tensions rose, which fell), in percentage points of the first frame's tension.

Usage: series.py TISSUEFIT TRUTHS WORKDIR --markdown OUT.md [--json OUT.json] [--seeds 11-16]
       [--cells 5] [--frames 4] [--drift 0.3] [--vox 10]
"""
import argparse, csv, json, pathlib, statistics, subprocess, sys, time

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "validation/per_cell"))
from score_per_cell import MODEL  # noqa: E402  (the forward model of the accuracy table)

DIAMETER_UM = 8.0
SERIES_MODEL = MODEL.replace("tolerance = 0.005", "tolerance = 0.02")
assert SERIES_MODEL != MODEL


def seeds_of(text):
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def make_frames(exe, truths, work, seed, cells, frames, drift, vox):
    """Evolver truths of every frame and their label volumes on frame 0's grid."""
    out = []
    for k in range(frames):
        d = truths / f"a{cells}_s{seed}_d{drift}_f{k}of{frames}"
        if not (d / "truth.json").exists():
            subprocess.run([sys.executable, str(ROOT / "validation/evolver/make_cluster.py"), "additive",
                            "--seed", str(seed), "--cells", str(cells), "--frames", str(frames), "--frame", str(k),
                            "--drift", str(drift), "--refine", "2", "--out", str(d)], check=True, capture_output=True)
        labels = work / f"s{seed}" / f"frame{k}.tif"
        labels.parent.mkdir(parents=True, exist_ok=True)
        grid = ["--voxel-size", f"{DIAMETER_UM / vox}um"] if k == 0 else ["--like", str(out[0][1])]
        subprocess.run([exe, "voxelize", str(d / "cluster.vtk"), "--length-unit", "um", *grid, "--out", str(labels),
                        "-q"], check=True, capture_output=True)
        out.append((json.load(open(d / "truth.json")), labels))
    return out


def map_series(exe, frames, out, cold):
    cfg = out.parent / f"fit_{out.name}.toml"
    cfg.write_text(f'mode = "per_cell"\n[observed]\nlabels = "{frames[0][1]}"\n[observed.meshing]\n'
                   f'target_nodes = 200\n{SERIES_MODEL}')
    t0 = time.time()
    p = subprocess.run([exe, "fit-series", "--config", str(cfg), "--out", str(out), "-q",
                        *(["--cold"] if cold else []), *[str(f[1]) for f in frames]], capture_output=True, text=True)
    wall = time.time() - t0
    if p.returncode not in (0, 1) or not (out / "series.json").exists():
        sys.exit(f"{out}: exit {p.returncode}: {p.stderr.strip()[-400:]}")
    return json.load(open(out / "series.json")), list(csv.DictReader(open(out / "series_interfaces.csv"))), wall


def true_tension(truth, a, b):
    return truth["gamma_a"] if b == 0 else truth["interfaces"][f"{min(a, b)}-{max(a, b)}"]["tension"]


def score(frames, rows):
    """Per frame and interface: (estimate scaled to a mean free tension of the truth's, its sd, truth)."""
    by_frame = {}
    for r in rows:
        by_frame.setdefault(int(r["frame"]), []).append(r)
    out = {}
    for k, (truth, _) in enumerate(frames):
        rs = by_frame.get(k, [])
        free = [float(r["tension_mn_per_m"]) for r in rs if r["cell_b"] == "0"]
        if not free:
            continue
        scale = truth["gamma_a"] / statistics.mean(free)
        for r in rs:
            a, b = int(r["cell_a"]), int(r["cell_b"])
            sd = float(r["tension_sd_mn_per_m"]) * scale if r["tension_sd_mn_per_m"] else None
            out[(k, a, b)] = (float(r["tension_mn_per_m"]) * scale, sd, true_tension(truth, a, b))
    return out


def summarise(runs, frames_n):
    errors, z1, changes, iterations, converged, starts, wall, nframes = [], [], [], 0, 0, [], 0.0, 0
    for series, scored, w in runs:
        wall += w
        for f in series["frames"]:
            nframes += 1
            iterations += f["iterations"] or 0
            converged += bool(f["converged"])
            if f["frame"] > 0 and f["start_mismatch"] is not None:
                starts.append(f["start_mismatch"])
        for (k, a, b), (est, sd, truth) in scored.items():
            errors.append(abs(est / truth - 1))
            if sd:
                z1.append(abs(est - truth) <= sd)
            if k == frames_n - 1 and (0, a, b) in scored:
                e0, _, t0 = scored[(0, a, b)]
                changes.append(abs((est - e0) - (truth - t0)) / t0)
    return {
        "frames": nframes, "converged": converged, "iterations": iterations, "wall_seconds": wall,
        "median_start_mismatch_later_frames": statistics.median(starts) if starts else None,
        "median_error": statistics.median(errors), "interfaces": len(errors),
        "within_1sd": sum(z1) / len(z1) if z1 else None,
        "median_change_error": statistics.median(changes) if changes else None,
        "max_change_error": max(changes) if changes else None,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("tissuefit")
    ap.add_argument("truths", type=pathlib.Path)
    ap.add_argument("work", type=pathlib.Path)
    ap.add_argument("--markdown", type=pathlib.Path, required=True)
    ap.add_argument("--json", type=pathlib.Path)
    ap.add_argument("--seeds", default="11-16")
    ap.add_argument("--cells", type=int, default=5)
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--drift", type=float, default=0.3)
    ap.add_argument("--vox", type=int, default=10)
    args = ap.parse_args()
    runs = {"warm": [], "cold": []}
    for seed in seeds_of(args.seeds):
        frames = make_frames(args.tissuefit, args.truths, args.work, seed, args.cells, args.frames, args.drift,
                             args.vox)
        for mode in runs:
            series, rows, wall = map_series(args.tissuefit, frames, args.work / f"s{seed}" / mode, mode == "cold")
            runs[mode].append((series, score(frames, rows), wall))
            print(f"seed {seed} {mode}: {wall:.0f} s, iterations "
                  f"{[f['iterations'] for f in series['frames']]}", file=sys.stderr)
    s = {mode: summarise(r, args.frames) for mode, r in runs.items()}
    pct = lambda x: "–" if x is None else f"{100 * x:.1f} %"
    lines = [
        f"| start | frames converged | iterations | wall (s) | first mismatch, frames ≥ 1 | median error | "
        f"within ±1 sd | change first → last: median error | max |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for mode, label in [("warm", "direct estimate × previous frame's correction (default)"), ("cold", "direct estimate (`--cold`)")]:
        x = s[mode]
        lines.append(f"| {label} | {x['converged']}/{x['frames']} | {x['iterations']} | {x['wall_seconds']:.0f} | "
                     f"{pct(x['median_start_mismatch_later_frames'])} | {pct(x['median_error'])} | "
                     f"{pct(x['within_1sd'])} | {pct(x['median_change_error'])} | {pct(x['max_change_error'])} |")
    n = len(seeds_of(args.seeds))
    lines.append("")
    lines.append(f"{n} Surface Evolver time series (seeds {args.seeds}) of {args.cells} cells, {args.frames} frames each, "
                 f"every a_i drifting by up to ±{100 * args.drift:.0f} % over the series; {args.vox} voxels per "
                 f"diameter; {s['warm']['interfaces']} interface-frames per mode. Errors against the truth with both "
                 f"maps scaled to a mean cell–medium tension of 1; the change error in points of the first frame's "
                 f"tension. Wall time on the machine that ran `docs/scripts/per-cell.sh series`.")
    args.markdown.write_text("\n".join(lines) + "\n")
    if args.json:
        args.json.write_text(json.dumps({"settings": vars(args) | {"truths": str(args.truths), "work": str(args.work),
                                                                   "markdown": str(args.markdown),
                                                                   "json": str(args.json)},
                                         "summary": s}, indent=2) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
