#!/usr/bin/env python3
"""Foam-like cell clusters relaxed by Surface Evolver: outside truths for tissuefit.

For each cluster kind this script
  1. builds an initial cell complex: cell i is the Voronoi cell of its seed clipped by the convex
     hull of balls around the seeds (polyhedral, shared by all cells so that shared faces agree);
  2. writes it as a Surface Evolver datafile (`cluster.fe`): one body per cell with a fixed volume,
     facet tension gamma_a = 1 on cell-medium faces and T_ij on the face between cells i and j;
  3. relaxes it with Evolver (refinement, equiangulation, conjugate gradient, then Hessian steps)
     and dumps the triangulated equilibrium;
  4. checks the equilibrium: at every triple line (two cells and the medium) the Young/Neumann
     balance T_ij = 2 gamma_a cos(theta/2) for equal free tensions, with theta the external angle
     between the two free surfaces, and more generally the vector force balance of the three
     tensions, both per edge;
  5. writes the equilibrium as a multi-material legacy VTK (label1/label2 per triangle, 0 = medium,
     lengths in micrometres, mean cell diameter `--diameter`) that `tissuefit` reads, and
     `truth.json`: the tensions, the global ratio gamma_l/gamma_a = T_cc/(2 gamma_a) where it is one
     number, and the Evolver geometry's own triple-line angles, contact areas and volumes.

Requires Debian's `evolver-nox` (binary `evolver`), numpy and scipy. Usage:

    python3 validation/evolver/make_cluster.py doublet --out validation/evolver/out/doublet
    python3 validation/evolver/make_cluster.py all --out validation/evolver/out

See docs/src/validation/evolver.md for the whole recipe (voxelising, fitting, comparing).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, HalfspaceIntersection, cKDTree

# ----------------------------------------------------------------------------------------------
# Cluster definitions
# ----------------------------------------------------------------------------------------------


@dataclass
class Cluster:
    name: str
    seeds: np.ndarray  # (n, 3)
    radius: float  # radius of the ball around each seed that clips its Voronoi cell
    ratio: float | None  # gamma_l / gamma_a = T_cc / (2 gamma_a) when it is one number
    pair_tension: dict = field(default_factory=dict)  # (i, j) -> T_ij, i < j (0-based)
    per_cell: list | None = None  # additive clusters: the per-cell a_i with T_ij = a_i + a_j
    description: str = ""

    def tension(self, i: int, j: int) -> float:
        key = (min(i, j), max(i, j))
        if key in self.pair_tension:
            return self.pair_tension[key]
        assert self.ratio is not None
        return 2.0 * self.ratio


def tetrahedron(edge: float) -> np.ndarray:
    v = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    return v * edge / (2.0 * math.sqrt(2.0))


def ball_seeds(n: int, rng: np.random.Generator, spacing: float) -> np.ndarray:
    """n seeds packed in a ball: random sequential addition at distance >= spacing, then a few
    rounds of Lloyd-like repulsion so that the spacing is even."""
    radius = spacing * (n / 0.55) ** (1.0 / 3.0) / 2.0
    pts: list[np.ndarray] = []
    while len(pts) < n:
        p = rng.uniform(-radius, radius, 3)
        if np.linalg.norm(p) > radius:
            continue
        if all(np.linalg.norm(p - q) >= spacing for q in pts):
            pts.append(p)
    pts_a = np.array(pts)
    for _ in range(200):
        force = np.zeros_like(pts_a)
        for i in range(n):
            d = pts_a[i] - pts_a
            r = np.linalg.norm(d, axis=1)
            r[i] = np.inf
            push = np.clip(1.15 * spacing - r, 0, None) / r
            force[i] = (d * push[:, None]).sum(axis=0)
        force -= 0.05 * pts_a  # gentle pull to the centre keeps the cluster compact
        pts_a += 0.2 * force
    return pts_a - pts_a.mean(axis=0)


def random_additive(seed: int, cells: int, frame: int = 0, frames: int = 1, drift: float = 0.3) -> Cluster:
    """A cluster of `cells` (4: tetrahedral, more: packed in a ball) whose cell-cell tensions are
    additive, T_ij = a_i + a_j with per-cell a_i drawn uniformly from [0.3, 0.85] (so T in
    [0.6, 1.7] < 2 gamma_a: every contact stays a contact): the truths a per-cell map can make
    exactly, for measuring the coverage of its intervals (docs/scripts/per-cell.sh coverage).

    A time series (`frame` of `frames`): each a_i drifts linearly by a factor 1 + r_i from the
    first frame to the last, r_i drawn from [-drift, drift] after the a_i (frame 0 is the plain
    draw), the seeds and volumes kept; for `tissuefit fit-series` (docs/scripts/per-cell.sh series)."""
    rng = np.random.default_rng(1000 + seed)
    d = 1.0
    seeds = tetrahedron(d) if cells == 4 else ball_seeds(cells, rng, d)
    a = rng.uniform(0.3, 0.85, cells)
    if frames > 1:
        r = rng.uniform(-drift, drift, cells)
        a = a * (1 + r * frame / (frames - 1))
    label = f"additive{cells}_s{seed}" + (f"_f{frame}" if frames > 1 else "")
    cl = Cluster(label, seeds, 0.8 * d if cells == 4 else 0.75 * d, None,
                 description=f"{cells} cells, additive tensions a_i + a_j, a = "
                             + ", ".join(f"{x:.3f}" for x in a) + f" (seed {seed}"
                             + (f", frame {frame} of {frames}" if frames > 1 else "") + ")")
    for i in range(cells):
        for j in range(i + 1, cells):
            cl.pair_tension[(i, j)] = float(a[i] + a[j])
    cl.per_cell = [float(x) for x in a]
    return cl


def make_clusters() -> dict[str, Cluster]:
    c: dict[str, Cluster] = {}
    d = 1.0  # seed spacing; the ball radius sets how much neighbouring cells overlap
    c["doublet"] = Cluster("doublet", np.array([[-d / 2, 0, 0], [d / 2, 0, 0]]), 0.8 * d, 0.60,
                           description="two equal cells, gamma_l/gamma_a = 0.60")
    tri = np.array([[math.cos(a), math.sin(a), 0.0] for a in (0, 2 * math.pi / 3, 4 * math.pi / 3)]) * d / math.sqrt(3)
    c["triplet"] = Cluster("triplet", tri, 0.8 * d, 0.85, description="planar triplet, gamma_l/gamma_a = 0.85")
    c["tetra"] = Cluster("tetra", tetrahedron(d), 0.8 * d, 0.60, description="tetrahedral 4-cell cluster, 0.60")
    rng = np.random.default_rng(12)
    ball = ball_seeds(12, rng, d)
    c["ball12"] = Cluster("ball12", ball, 0.75 * d, 0.85, description="12 cells packed in a ball, 0.85")
    # Heterogeneous: a tetrahedral cluster whose six interfaces have six tensions (T in [0.9, 1.7]).
    het = Cluster("hetero4", tetrahedron(d), 0.8 * d, None,
                  description="tetrahedral 4-cell cluster, six interface tensions 0.9-1.7")
    pairs = [(i, j) for i in range(4) for j in range(i + 1, 4)]
    for k, p in enumerate(pairs):
        het.pair_tension[p] = 0.9 + 0.16 * k
    c["hetero4"] = het
    # Held out: made after profile.model_error was calibrated on the clusters above, at ratios and
    # cell counts none of them has, to check the fit's accuracy and coverage on cases it was not
    # tuned on (docs: Surface Evolver clusters, held-out fits).
    c["heldout_ball8"] = Cluster("heldout_ball8", ball_seeds(8, np.random.default_rng(5), d), 0.75 * d, 0.70,
                                 description="held out: 8 cells packed in a ball, 0.70")
    c["heldout_triplet"] = Cluster("heldout_triplet", tri, 0.8 * d, 0.70,
                                   description="held out: planar triplet, gamma_l/gamma_a = 0.70")
    return c


# ----------------------------------------------------------------------------------------------
# Initial cell complex
# ----------------------------------------------------------------------------------------------


def sphere_directions(n: int) -> np.ndarray:
    """n nearly even unit vectors (Fibonacci sphere)."""
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    theta = math.pi * (1 + 5**0.5) * k
    return np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)


def build_complex(cl: Cluster, n_dirs: int = 48):
    """Vertices, polygonal faces (vertex loops) with their two sides (cell index or -1 = medium): the
    Voronoi cells of the seeds clipped by the convex hull of balls of `cl.radius` around them."""
    seeds = cl.seeds
    n = len(seeds)
    # One convex outer boundary for all cells (the convex hull of the balls around the seeds), so
    # that the face two cells share is cut identically from both sides.
    dirs = sphere_directions(n_dirs)
    cloud = np.concatenate([s + cl.radius * dirs for s in seeds])
    hull = ConvexHull(cloud)
    hull_planes: list[tuple[np.ndarray, float]] = []
    for eq in hull.equations:
        u, off = eq[:3], -eq[3]
        if all(np.linalg.norm(u - q) > 1e-9 or abs(off - o) > 1e-9 for q, o in hull_planes):
            hull_planes.append((u, off))
    raw_vertices: list[np.ndarray] = []
    cell_faces: list[list[tuple[tuple, list[int]]]] = []
    for i in range(n):
        planes = []  # (normal, offset, key) with normal . x <= offset
        for j in range(n):
            if j == i:
                continue
            nrm = seeds[j] - seeds[i]
            mid = 0.5 * (seeds[i] + seeds[j])
            planes.append((nrm / np.linalg.norm(nrm), float(np.dot(nrm / np.linalg.norm(nrm), mid)), ("c", min(i, j), max(i, j))))
        for k, (u, off) in enumerate(hull_planes):
            planes.append((u, off, ("m", i, k)))
        hs = np.array([np.append(p[0], -p[1]) for p in planes])
        hi = HalfspaceIntersection(hs, seeds[i])
        verts = hi.intersections
        faces = []
        for nrm, off, key in planes:
            on = np.where(np.abs(verts @ nrm - off) < 1e-9)[0]
            if len(on) < 3:
                continue
            pts = verts[on]
            # unique points (the intersection may repeat a vertex shared by > 3 planes)
            uniq: list[np.ndarray] = []
            for p in pts:
                if all(np.linalg.norm(p - q) > 1e-9 for q in uniq):
                    uniq.append(p)
            if len(uniq) < 3:
                continue
            pts = np.array(uniq)
            ctr = pts.mean(axis=0)
            a = pts[0] - ctr
            a /= np.linalg.norm(a)
            b = np.cross(nrm, a)
            ang = np.arctan2((pts - ctr) @ b, (pts - ctr) @ a)
            order = np.argsort(ang)  # counter-clockwise seen from outside (normal points outward)
            loop = []
            for p in pts[order]:
                loop.append(len(raw_vertices))
                raw_vertices.append(p)
            area = 0.5 * np.linalg.norm(sum(np.cross(pts[order][q] - ctr, pts[order][(q + 1) % len(order)] - ctr) for q in range(len(order))))
            if area < 1e-10:
                continue
            faces.append((key, loop))
        cell_faces.append(faces)
    # merge coincident vertices
    rv = np.array(raw_vertices)
    tree = cKDTree(rv)
    groups = tree.query_ball_point(rv, 1e-7)
    canon = np.arange(len(rv))
    for a, g in enumerate(groups):
        canon[a] = min(g)
    uniq_ids = sorted(set(canon.tolist()))
    remap = {old: new for new, old in enumerate(uniq_ids)}
    vertices = rv[uniq_ids]
    faces = {}  # key -> (loop of the first cell that wrote it, owner cell, other side)
    for i, fs in enumerate(cell_faces):
        for key, loop in fs:
            loop = [remap[int(canon[v])] for v in loop]
            # drop repeated consecutive vertices
            clean = [v for q, v in enumerate(loop) if v != loop[q - 1]]
            if len(clean) < 3:
                continue
            if key[0] == "c":
                if key in faces:
                    continue  # the other cell wrote it
                other = key[2] if key[1] == i else key[1]
                faces[key] = (clean, i, other)
            else:
                faces[key] = (clean, i, -1)
    return vertices, list(faces.values())


def write_fe(path: str, cl: Cluster, vertices: np.ndarray, faces, volumes: np.ndarray) -> None:
    edges: dict[tuple[int, int], int] = {}
    edge_list: list[tuple[int, int]] = []
    face_lines = []
    body_faces: dict[int, list[int]] = {i: [] for i in range(len(cl.seeds))}
    for f_id, (loop, owner, other) in enumerate(faces, start=1):
        signed = []
        for q in range(len(loop)):
            a, b = loop[q], loop[(q + 1) % len(loop)]
            if (a, b) in edges:
                signed.append(edges[(a, b)])
            elif (b, a) in edges:
                signed.append(-edges[(b, a)])
            else:
                edge_list.append((a, b))
                edges[(a, b)] = len(edge_list)
                signed.append(len(edge_list))
        t = 1.0 if other < 0 else cl.tension(owner, other)
        face_lines.append(f"{f_id} " + " ".join(str(e) for e in signed) + f" tension {t:.10g} color {1 + (owner % 14)}")
        body_faces[owner].append(f_id)  # loop is counter-clockwise seen from outside the owner
        if other >= 0:
            body_faces[other].append(-f_id)
    with open(path, "w") as fh:
        fh.write(f"// {cl.name}: {cl.description}\n// generated by validation/evolver/make_cluster.py\n\n")
        fh.write("vertices\n")
        for k, v in enumerate(vertices, start=1):
            fh.write(f"{k} {v[0]:.12g} {v[1]:.12g} {v[2]:.12g}\n")
        fh.write("\nedges\n")
        for k, (a, b) in enumerate(edge_list, start=1):
            fh.write(f"{k} {a + 1} {b + 1}\n")
        fh.write("\nfaces\n")
        fh.write("\n".join(face_lines) + "\n")
        fh.write("\nbodies\n")
        for i in range(len(cl.seeds)):
            fh.write(f"{i + 1} " + " ".join(str(f) for f in body_faces[i]) + f" volume {volumes[i]:.12g}\n")


def complex_volumes(vertices: np.ndarray, faces, n: int) -> np.ndarray:
    vol = np.zeros(n)
    for loop, owner, other in faces:
        p = vertices[loop]
        for q in range(1, len(loop) - 1):
            v6 = np.dot(p[0], np.cross(p[q], p[q + 1])) / 6.0
            vol[owner] += v6
            if other >= 0:
                vol[other] -= v6
    return vol


# ----------------------------------------------------------------------------------------------
# Evolver run and dump
# ----------------------------------------------------------------------------------------------

EVOLVER_SCRIPT = r"""
// relaxation: refine to the wanted resolution, keeping triangles well shaped
U
t 0.05
g 50
o
t 0.05
r
u
V
g 100
o
r
u
V
g 200
{REFINE_MORE}
u
V
g 300
u
V
g 500
{HESSIAN}
w 1e-6
t 0.002
g 100
printf "ENERGY %.15g\n", total_energy
printf "DUMP-BEGIN\n"
foreach vertex vv do printf "V %d %.15g %.15g %.15g\n", vv.id, vv.x, vv.y, vv.z
foreach facet ff do printf "F %d %d %d %d %d %.10g\n", ff.vertex[1].id, ff.vertex[2].id, ff.vertex[3].id, ff.frontbody, ff.backbody, ff.tension
foreach body bb do printf "B %d %.15g %.15g %.15g\n", bb.id, bb.volume, bb.target, bb.pressure
printf "DUMP-END\n"
q
q
"""


def run_evolver(fe_path: str, refine: int, hessian: bool, log_path: str) -> tuple[str, float]:
    more = "\n".join(["r\nu\nV\ng 200"] * max(0, refine - 2))
    hess = "g 500\nhessian_seek\nhessian_seek\ng 200\nhessian_seek\nhessian_seek" if hessian else "g 2000"
    script = EVOLVER_SCRIPT.replace("{REFINE_MORE}", more).replace("{HESSIAN}", hess)
    script_path = fe_path.replace(".fe", ".cmd")
    with open(script_path, "w") as fh:
        fh.write(script)
    with open(log_path, "w") as log:
        proc = subprocess.run(["evolver", "-x", "-f", script_path, fe_path], stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, stderr=log, text=True, timeout=3600)
        log.write(proc.stdout)
    if proc.returncode not in (0, 1) or "DUMP-END" not in proc.stdout:
        raise SystemExit(f"evolver failed on {fe_path} (exit {proc.returncode}); see {log_path}")
    energy = float([l for l in proc.stdout.splitlines() if l.startswith("ENERGY")][-1].split()[1])
    return proc.stdout, energy


def parse_dump(text: str):
    body = text.split("DUMP-BEGIN", 1)[1].split("DUMP-END", 1)[0]
    verts: dict[int, np.ndarray] = {}
    tris = []
    bodies = {}
    for line in body.splitlines():
        p = line.split()
        if not p:
            continue
        if p[0] == "V":
            verts[int(p[1])] = np.array([float(p[2]), float(p[3]), float(p[4])])
        elif p[0] == "F":
            tris.append((int(p[1]), int(p[2]), int(p[3]), int(p[4]), int(p[5]), float(p[6])))
        elif p[0] == "B":
            bodies[int(p[1])] = (float(p[2]), float(p[3]), float(p[4]))
    ids = sorted(verts)
    index = {v: k for k, v in enumerate(ids)}
    xyz = np.array([verts[v] for v in ids])
    tri = np.array([[index[a], index[b], index[c]] for a, b, c, *_ in tris], dtype=int)
    front = np.array([t[3] for t in tris], dtype=int)
    back = np.array([t[4] for t in tris], dtype=int)
    tension = np.array([t[5] for t in tris])
    return xyz, tri, front, back, tension, bodies


# ----------------------------------------------------------------------------------------------
# Measurements on the Evolver surface
# ----------------------------------------------------------------------------------------------


def triple_lines(xyz, tri, front, back, tension):
    """Per triple edge between cells a < b and the medium: external angle between the two free
    surfaces, and the residual of the vector force balance of the three tensions (relative)."""
    edge_faces: dict[tuple[int, int], list[int]] = {}
    for f, (a, b, c) in enumerate(tri):
        for u, v in ((a, b), (b, c), (c, a)):
            edge_faces.setdefault((min(u, v), max(u, v)), []).append(f)
    out = []
    for (u, v), fs in edge_faces.items():
        if len(fs) != 3:
            continue
        sides = [tuple(sorted((front[f], back[f]))) for f in fs]
        cell_cell = [k for k, s in enumerate(sides) if s[0] > 0]
        if len(cell_cell) != 1:
            continue  # not a cell-cell-medium line
        e = xyz[v] - xyz[u]
        length = np.linalg.norm(e)
        e /= length
        pull = []
        for f in fs:
            third = [w for w in tri[f] if w != u and w != v][0]
            d = xyz[third] - xyz[u]
            d -= np.dot(d, e) * e
            pull.append(d / np.linalg.norm(d))
        free = [k for k in range(3) if k != cell_cell[0]]
        cos_between = float(np.dot(pull[free[0]], pull[free[1]]))
        theta = math.acos(max(-1.0, min(1.0, cos_between)))  # wedge of medium between the free faces
        force = sum(tension[f] * pull[k] for k, f in enumerate(fs))
        scale = max(tension[f] for f in fs)
        out.append({"cells": sides[cell_cell[0]], "theta_deg": math.degrees(theta), "length": float(length),
                    "balance": float(np.linalg.norm(force) / scale),
                    "t_cc": float(tension[fs[cell_cell[0]]])})
    return out


def contact_areas(xyz, tri, front, back):
    areas: dict[tuple[int, int], float] = {}
    for f, (a, b, c) in enumerate(tri):
        if front[f] > 0 and back[f] > 0:
            key = (min(front[f], back[f]), max(front[f], back[f]))
            areas[key] = areas.get(key, 0.0) + 0.5 * float(np.linalg.norm(np.cross(xyz[b] - xyz[a], xyz[c] - xyz[a])))
    return areas


# ----------------------------------------------------------------------------------------------
# Output
# ----------------------------------------------------------------------------------------------


def write_vtk(path: str, xyz_um: np.ndarray, tri, front, back) -> None:
    with open(path, "w") as fh:
        fh.write("# vtk DataFile Version 4.2\nSurface Evolver cluster (lengths in micrometres)\nASCII\nDATASET UNSTRUCTURED_GRID\n")
        fh.write(f"POINTS {len(xyz_um)} double\n")
        for p in xyz_um:
            fh.write(f"{p[0]:.9g} {p[1]:.9g} {p[2]:.9g}\n")
        fh.write(f"CELLS {len(tri)} {4 * len(tri)}\n")
        for a, b, c in tri:
            fh.write(f"3 {a} {b} {c}\n")
        fh.write(f"CELL_TYPES {len(tri)}\n" + "5\n" * len(tri))
        fh.write(f"CELL_DATA {len(tri)}\nSCALARS label1 int 1\nLOOKUP_TABLE default\n")
        fh.write("\n".join(str(max(0, f)) for f in front) + "\n")
        fh.write("SCALARS label2 int 1\nLOOKUP_TABLE default\n")
        fh.write("\n".join(str(max(0, b)) for b in back) + "\n")


def make(cl: Cluster, out: str, diameter_um: float, refine: int, hessian: bool) -> dict:
    os.makedirs(out, exist_ok=True)
    vertices, faces = build_complex(cl)
    vols = complex_volumes(vertices, faces, len(cl.seeds))
    if np.any(vols <= 0):
        raise SystemExit(f"{cl.name}: a cell of the initial complex has non-positive volume {vols}")
    # equal target volumes: the mean of the initial ones (the relaxed cells are equal in volume)
    target = np.full(len(vols), vols.mean())
    fe = os.path.join(out, "cluster.fe")
    write_fe(fe, cl, vertices, faces, target)
    text, energy = run_evolver(fe, refine, hessian, os.path.join(out, "evolver.log"))
    xyz, tri, front, back, tension, bodies = parse_dump(text)
    lines = triple_lines(xyz, tri, front, back, tension)
    areas = contact_areas(xyz, tri, front, back)
    v_mean = float(np.mean([b[0] for b in bodies.values()]))
    d_equiv = (6.0 * v_mean / math.pi) ** (1.0 / 3.0)
    scale = diameter_um / d_equiv  # Evolver length -> micrometres
    write_vtk(os.path.join(out, "cluster.vtk"), xyz * scale, tri, front, back)
    per_pair: dict[str, dict] = {}
    for ln in lines:
        key = f"{ln['cells'][0]}-{ln['cells'][1]}"
        d = per_pair.setdefault(key, {"weighted_theta": 0.0, "length": 0.0, "max_balance": 0.0, "t_cc": ln["t_cc"]})
        d["weighted_theta"] += ln["theta_deg"] * ln["length"]
        d["length"] += ln["length"]
        d["max_balance"] = max(d["max_balance"], ln["balance"])
    pairs = {}
    for key, d in sorted(per_pair.items()):
        theta = d["weighted_theta"] / d["length"]
        young = math.degrees(2.0 * math.acos(min(1.0, d["t_cc"] / 2.0)))
        a, b = (int(x) for x in key.split("-"))
        pairs[key] = {"tension": d["t_cc"], "ratio": d["t_cc"] / 2.0, "theta_deg": theta,
                      "young_theta_deg": young, "max_force_balance": d["max_balance"],
                      "contact_area_um2": areas.get((a, b), 0.0) * scale**2}
    for (a, b), area in areas.items():  # interfaces without a free rim (enclosed)
        pairs.setdefault(f"{a}-{b}", {"tension": cl.tension(a - 1, b - 1), "ratio": cl.tension(a - 1, b - 1) / 2.0,
                                      "theta_deg": None, "young_theta_deg": None, "max_force_balance": None,
                                      "contact_area_um2": area * scale**2})
    ratios = [p["ratio"] for p in pairs.values()]
    truth = {
        "cluster": cl.name,
        "description": cl.description,
        "cells": len(cl.seeds),
        "gamma_a": 1.0,
        "lateral_over_apical": cl.ratio,
        "mean_interface_ratio": float(np.mean(ratios)) if ratios else None,
        "cell_diameter_um": diameter_um,
        "evolver_length_to_um": scale,
        "evolver_energy": energy,
        "volumes_um3": {str(k): v[0] * scale**3 for k, v in sorted(bodies.items())},
        "pressures": {str(k): v[2] for k, v in sorted(bodies.items())},
        "triple_line_edges": len(lines),
        "max_force_balance": max((ln["balance"] for ln in lines), default=None),
        "median_force_balance": float(np.median([ln["balance"] for ln in lines])) if lines else None,
        "p99_force_balance": float(np.percentile([ln["balance"] for ln in lines], 99)) if lines else None,
        "interfaces": pairs,
        "per_cell_lateral": None if cl.per_cell is None else {str(i + 1): a for i, a in enumerate(cl.per_cell)},
        "evolver": {"vertices": int(len(xyz)), "facets": int(len(tri)), "refine": refine, "hessian": hessian},
    }
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2)
    return truth


def main() -> None:
    clusters = make_clusters()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("kind", choices=sorted(clusters) + ["all", "additive"],
                    help="a named cluster, all of them, or `additive` (random additive tensions: --seed, --cells)")
    ap.add_argument("--seed", type=int, default=1, help="with `additive`: the draw of seeds and tensions")
    ap.add_argument("--cells", type=int, default=4, help="with `additive`: the number of cells")
    ap.add_argument("--frame", type=int, default=0, help="with `additive` and --frames: the time point (0-based)")
    ap.add_argument("--frames", type=int, default=1,
                    help="with `additive`: a time series of this many frames whose a_i drift linearly")
    ap.add_argument("--drift", type=float, default=0.3,
                    help="with --frames: each a_i changes by a factor 1 + r, r in [-drift, drift], over the series")
    ap.add_argument("--out", required=True, help="output folder (with `all`: one sub-folder per cluster)")
    ap.add_argument("--diameter", type=float, default=8.0, help="mean equivalent cell diameter in micrometres")
    ap.add_argument("--refine", type=int, default=3, help="refinement passes (each quadruples the facets)")
    ap.add_argument("--no-hessian", action="store_true", help="gradient steps only (no Hessian polish)")
    args = ap.parse_args()
    if args.kind == "additive":
        cl = random_additive(args.seed, args.cells, args.frame, args.frames, args.drift)
        clusters[cl.name] = cl
        args.kind = cl.name
    kinds = sorted(clusters) if args.kind == "all" else [args.kind]
    for k in kinds:
        out = os.path.join(args.out, k) if args.kind == "all" else args.out
        t = make(clusters[k], out, args.diameter, args.refine, not args.no_hessian)
        fb = "n/a" if t["max_force_balance"] is None else (
            f"{t['median_force_balance']:.2e} median, {t['p99_force_balance']:.2e} 99th percentile, "
            f"{t['max_force_balance']:.2e} max")
        print(f"{k}: {t['cells']} cells, {t['evolver']['facets']} facets, energy {t['evolver_energy']:.6g}, "
              f"triple-line force balance (|sum of tensions| / largest, per edge) {fb}", file=sys.stderr)
        for key, p in t["interfaces"].items():
            th = p["theta_deg"]
            if th is not None:
                print(f"  {key}: T = {p['tension']:.3f}, theta = {th:.2f} deg (Young {p['young_theta_deg']:.2f})", file=sys.stderr)


if __name__ == "__main__":
    main()
