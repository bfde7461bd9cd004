#!/usr/bin/env python3
"""Relaxes a generated 200-cell spheroid with the coupled per-cell model and reports what a user
would see and what breaks: convergence, cells passing through each other (summary.json), and cell
surfaces that fold over themselves (read from the frames: a point just outside a face must have
winding number 0 with respect to its own cell's surface, a point just inside 1).

    spheroid_report.py TISSUEFIT WORK [--persistent] [--label NAME] [--markdown FILE --append]

Needs numpy. Used by docs/scripts/coupled-spheroid.sh.
"""
import argparse, json, re, subprocess, sys, time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "per_cell"))
from score_per_cell import MODEL as PER_CELL_MODEL  # noqa: E402

# The per-cell fit's forward model (its relaxation settings), 1,000 steps, a frame every 100.
MODEL = (PER_CELL_MODEL.split("[forward]")[0].replace("model_overrides.", "")
         .replace("max_steps = 1500", "max_steps = 1000\nsample_every_steps = 100"))


def read_vtp(path):
    """Points, triangles and cell ids of a tissuefit .vtp (raw appended binary, UInt64 headers)."""
    raw = Path(path).read_bytes()
    head, _, rest = raw.partition(b'<AppendedData encoding="raw">')
    data = rest[rest.index(b"_") + 1:]
    arrays = {}
    types = {"Float64": np.float64, "Int64": np.int64, "Int32": np.int32}
    for m in re.finditer(rb'<DataArray type="(\w+)" Name="(\w+)"(?: NumberOfComponents="(\d)")? format="appended" offset="(\d+)"', head):
        kind, name, comps, off = m.group(1).decode(), m.group(2).decode(), m.group(3), int(m.group(4))
        n = int(np.frombuffer(data[off:off + 8], np.uint64)[0])
        a = np.frombuffer(data[off + 8:off + 8 + n], types[kind])
        arrays[name] = a.reshape(-1, int(comps)) if comps else a
    if not (np.diff(arrays["offsets"]) == 3).all():
        raise SystemExit(f"{path}: not a triangle mesh")
    return arrays["Points"], arrays["connectivity"].reshape(-1, 3), arrays["cell_id"]


def winding(points, tris, queries):
    """Generalised winding number of each query point with respect to the triangles."""
    a, b, c = (points[tris[:, k]][None] - queries[:, None] for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
    det = np.einsum("ijk,ijk->ij", a, np.cross(b, c))
    dot = lambda x, y: np.einsum("ijk,ijk->ij", x, y)
    den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
    return (2 * np.arctan2(det, den)).sum(1) / (4 * np.pi)


def folded_cells(path):
    """Cells with a face (area above 0.01 µm²) whose outside point is not outside or inside point not inside."""
    points, tris, ids = read_vtp(path)
    folded = 0
    for cell in np.unique(ids):
        t = tris[ids == cell]
        p0, p1, p2 = (points[t[:, k]] for k in range(3))
        n = np.cross(p1 - p0, p2 - p0)
        area = np.linalg.norm(n, axis=1)
        unit = n / np.maximum(area, 1e-300)[:, None]
        centre = (p0 + p1 + p2) / 3
        out = winding(points, t, centre + 1e-9 * unit)
        inside = winding(points, t, centre - 1e-9 * unit)
        bad = ((np.abs(out) > 0.5) | (np.abs(inside - 1) > 0.5)) & (area / 2 > 1e-14)
        folded += bool(bad.any())
    return folded


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("exe")
    ap.add_argument("work", type=Path)
    ap.add_argument("--label", default="default")
    ap.add_argument("--persistent", action="store_true", help="numerics.coupling_persistent_junctions = true")
    ap.add_argument("--markdown", type=Path)
    ap.add_argument("--append", action="store_true")
    args = ap.parse_args()
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    tissue = work / "spheroid.vtp"
    if not tissue.exists():
        subprocess.run([args.exe, "generate", "mesh", "--kind", "spheroid", "--cells", "200", "--min-edge-length", "1.6um",
                        "--out", str(tissue), "-q"], check=True)
    name = re.sub(r"\W+", "_", args.label)
    cfg = work / f"model_{name}.toml"
    cfg.write_text(MODEL.replace('damping = 3e-9', 'damping = 3e-9\ncoupling_persistent_junctions = true') if args.persistent else MODEL)
    out = work / name
    t0 = time.time()
    p = subprocess.run([args.exe, "simulate", str(tissue), "--config", str(cfg), "--out", str(out), "--force", "--threads", "2", "-q"],
                       capture_output=True, text=True)
    if p.returncode not in (0, 1):
        raise SystemExit(f"simulate failed ({p.returncode}): {p.stderr}")
    s = json.loads((out / "summary.json").read_text())
    frames = sorted((out / "frames").glob("frame_*.vtp"))
    folds = [folded_cells(f) for f in frames]
    row = {
        "build": args.label,
        "exit": p.returncode,
        "residual": s["residual"],
        "inside": len(s.get("cells_inside_others", [])),
        "folded_first": folds[0],
        "folded_max": max(folds),
        "folded_last": folds[-1],
        "nodes": f'{s["nodes"]} → {s["final_nodes"]}',
        "us_per_node_step": s["seconds_per_node_step"] * 1e6,
        "wall": s["wall_seconds"],
    }
    print(json.dumps(row))
    if args.markdown:
        header = ("| junction groups | exit | residual at step 1,000 | cells inside another | folded cells after the first snap / most / last frame "
                  "| nodes | µs per node-step (wall, 2 threads) |\n|---|---|---|---|---|---|---|\n")
        line = (f'| {row["build"]} | {row["exit"]} | {row["residual"]:.2f} | {row["inside"]} | '
                f'{row["folded_first"]} / {row["folded_max"]} / {row["folded_last"]} | {row["nodes"]} | {row["us_per_node_step"]:.1f} |\n')
        if args.append and args.markdown.exists():
            args.markdown.write_text(args.markdown.read_text() + line)
        else:
            args.markdown.write_text(
                "<!-- generated by docs/scripts/coupled-spheroid.sh; do not edit -->\n"
                "200-cell spheroid (`generate mesh --kind spheroid --cells 200 --min-edge-length 1.6um`, 16,881 nodes), "
                "relaxed 1,000 FIRE steps with coupling, junction groups, polarity from contacts "
                "(c = l_min = 1.58 µm derived from the mesh), frames every 100 steps:\n\n" + header + line)


if __name__ == "__main__":
    sys.exit(main())
