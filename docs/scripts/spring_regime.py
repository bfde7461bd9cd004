#!/usr/bin/env python3
"""Spring-contact doublets against Young–Dupré over the regime a user meets (issue 20): writes the table
of docs/src/design/young-dupre.md (docs/src/generated/spring-regime.md).

Each row is one run of `examples/spring_regime.rs` (two equal cells, tension γ on every face, spring
adhesion w/(2γ) = ωc²/(4γ), FIRE with remeshing every 50 steps, full forces): the far-field contact
half-angle against Young–Dupré's cos(θ/2) = 1 − w/(2γ), the overlap, the remeshing operations and the
cost. The face quadrature (numerics.contact_quadrature = "faces") runs the whole grid; the vertex
quadrature (the default) runs w/(2γ) = 0.3 for comparison, and "faces, unit masses" repeats some
R = 10 µm rows with FIRE's contact masses off (`--unit-masses`), as every run was before them.

    cargo build --release --example spring_regime
    python3 docs/scripts/spring_regime.py --jobs 2 --markdown docs/src/generated/spring-regime.md

About 35 minutes on 2 cores (one thread per run). `--quick` runs four rows. To rerun only some
radii and keep the other rows of a table made by the same code:

    python3 docs/scripts/spring_regime.py --radii 2 --keep docs/src/generated/spring-regime.md \
        --markdown docs/src/generated/spring-regime.md
"""

import argparse
import concurrent.futures
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# (radius, l_min, cutoff) in µm: l_min/c = 1, 0.5, 2.5, 5, 2 at radii 2, 2, 5, 10, 10.
GEOMETRIES = [(2, 0.2, 0.2), (2, 0.2, 0.4), (5, 0.5, 0.2), (10, 1.0, 0.2), (10, 1.0, 0.5)]
RATIOS = [0.1, 0.3, 0.5]
STARTS = ["touch", "over"]


def grid(quick):
    runs = []
    for r, l, c in GEOMETRIES:
        for start in STARTS:
            for ratio in RATIOS:
                runs.append(("faces", r, l, c, ratio, start))
                if ratio == 0.3:
                    runs.append(("vertices", r, l, c, ratio, start))
                # FIRE without the contact masses, where the repulsion's stiffness limited it.
                if r == 10 and (ratio == 0.3 or (c == 0.5 and ratio == 0.1 and start == "touch")):
                    runs.append(("faces, unit masses", r, l, c, ratio, start))
    if quick:
        runs = [x for x in runs if x[1:4] == (2, 0.2, 0.2) and x[5] == "touch" and (x[4] == 0.3 or x[0] == "faces")][:4]
    return runs


def run_one(binary, steps, timeout, spec):
    quadrature, r, l, c, ratio, start = spec
    args = [binary, "--quadrature", quadrature.split(",")[0], "--radius", str(r), "--lmin", str(l), "--cutoff",
            str(c), "--ratio", str(ratio), "--start", start, "--steps", str(steps)]
    if quadrature.endswith("unit masses"):
        args.append("--unit-masses")
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    try:
        proc = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"spec": spec, "error": f"did not finish in {timeout:.0f} s (stopped)"}
    if proc.returncode != 0:
        return {"spec": spec, "error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "failed"}
    line = proc.stdout.strip().splitlines()[-1]
    fields = {}
    for token in line.split(" "):
        if "=" in token:
            k, v = token.split("=", 1)
            fields[k] = v
    fields["spec"] = spec
    return fields


def read_table(path):
    """The rows of a table this script wrote, as run_one returns them (spec, and its fields or error)."""
    rows = []
    for line in open(path, encoding="utf-8"):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 17 or cells[0] in ("quadrature", "---"):
            continue
        q, r, l, c, _, ratio, start = cells[:7]
        num = lambda x: int(x) if float(x).is_integer() and "." not in x else float(x)
        spec = (q, num(r), float(l), float(c), float(ratio), start)
        if cells[8].startswith("failed: "):
            rows.append({"spec": spec, "error": cells[8][len("failed: "):]})
            continue
        steps = cells[12].split(" ")[0]
        splits_collapses = cells[15]
        rows.append({"spec": spec, "yd_deg": cells[7].rstrip("°"), "half_angle_deg": cells[8].rstrip("°"),
                     "error_deg": cells[9].rstrip("°"), "overlap_pct": cells[10].rstrip(" %"), "xi": cells[11],
                     "steps": steps, "converged": "false" if "(max)" in cells[12] else "true",
                     "residual": cells[13], "nodes_per_cell": cells[14], "splits": splits_collapses,
                     "collapses": "0", "wall_s": cells[16].rstrip(" s")})
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "examples", "spring_regime"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--steps", type=int, default=40000)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per run before it is stopped")
    ap.add_argument("--markdown", help="write the table here")
    ap.add_argument("--radii", help="run only these radii (µm, comma-separated)")
    ap.add_argument("--keep", help="with --radii: take the other rows from this table")
    a = ap.parse_args()
    runs = grid(a.quick)
    kept = {}
    if a.radii:
        radii = {float(r) for r in a.radii.split(",")}
        if a.keep:
            kept = {row["spec"]: row for row in read_table(a.keep)}
        missing = [s for s in runs if float(s[1]) not in radii and s not in kept]
        if missing:
            sys.exit(f"--radii without a row for {missing[0]} in --keep: rerun those radii too")
    rows = []
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as pool:
        todo = lambda s: kept[s] if s in kept and float(s[1]) not in radii else run_one(a.binary, a.steps, a.timeout, s)
        for row in pool.map(todo, runs):
            q, r, l, c, ratio, start = row["spec"]
            msg = row.get("error") or f"half-angle {row['half_angle_deg']}° vs {row['yd_deg']}° ({row['error_deg']}°)"
            print(f"{q} R={r} l={l} c={c} w/2γ={ratio} {start}: {msg}", file=sys.stderr, flush=True)
            rows.append(row)
    groups = ("faces", "vertices", "faces, unit masses")
    errors = {q: [float(x["error_deg"]) for x in rows if "error" not in x and x["spec"][0] == q] for q in groups}
    failed = {q: sum(1 for x in rows if "error" in x and x["spec"][0] == q) for q in groups}
    out = ["| quadrature | R (µm) | l_min (µm) | c (µm) | l_min/c | w/(2γ) | start | Young–Dupré | measured | error "
           "| overlap | ξ (Pa/m) | steps | residual | nodes/cell | splits + collapses | wall |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for x in rows:
        q, r, l, c, ratio, start = x["spec"]
        if "error" in x:
            out.append(f"| {q} | {r} | {l} | {c} | {l / c:.1f} | {ratio} | {start} | | failed: {x['error']} | | | | | | | | |")
            continue
        ops = int(x["splits"]) + int(x["collapses"])
        out.append(f"| {q} | {r} | {l} | {c} | {l / c:.1f} | {ratio} | {start} | {float(x['yd_deg']):.1f}° | "
                   f"{float(x['half_angle_deg']):.1f}° | {float(x['error_deg']):+.1f}° | {float(x['overlap_pct']):.3f} % | "
                   f"{float(x['xi']):.1e} | {x['steps']}{'' if x['converged'] == 'true' else ' (max)'} | "
                   f"{float(x['residual']):.1e} | {x['nodes_per_cell']} | {ops} | {float(x['wall_s']):.0f} s |")
    summary = []
    for name, errs in errors.items():
        if errs:
            worst = max(errs, key=abs)
            within = sum(abs(e) <= 3.0 for e in errs)
            summary.append(f"{name}: {within} of {len(errs)} completed runs within ±3° of Young–Dupré, worst "
                           f"{worst:+.1f}°, {failed[name]} more failed")
    out.append("")
    out.append("Half-angles from the far field (sphere fits to the free caps); " + "; ".join(summary) + ". "
               f"{a.steps} FIRE steps per run, one thread each, {a.jobs} runs at a time.")
    text = "\n".join(out) + "\n"
    if a.markdown:
        with open(a.markdown, "w") as fh:
            fh.write(text)
    print(text)


if __name__ == "__main__":
    main()
