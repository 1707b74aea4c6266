#!/usr/bin/python3
"""Planner benchmark on Moving AI maps read from ../shared/data/movingai (skipped when absent).

Side by side, on the same graph (8-connected, sqrt(2) diagonals, no corner cutting) and the same
scenarios (evenly spread over each .scen file, the last, hardest one included):
  - sparse_nav D* Lite: first plan (construction + search) and the replan after blocking the middle
    cell of the found path (incremental repair);
  - sparse_nav A* (a fresh search);
  - scipy.sparse.csgraph.dijkstra from the start over the whole graph (the reference lengths);
  - the PyPI ``pathplanning`` D* Lite (native code), first plan and replan, run in the bench-only
    virtual environment build/bench_venv (created with pip when missing; never a dependency).
Times are medians over repeats on a shared machine; the ratios are peer time / sparse_nav time.
Writes bench/results/planner.json.
"""
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from sparse_nav import _planning as planning
from sparse_nav.navigation.maps import read_movingai_map, read_scenarios

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATA = os.path.join(ROOT, "..", "shared", "data", "movingai")
MAPS = [("Berlin_0_512", "rsasaki0109_rust_robotics/street/Berlin_0_512.map"),
        ("Boston_0_1024", "Lucas-707_PAStar/Boston_0_1024.map"),
        ("maze512-1-0", "rsasaki0109_rust_robotics/maze/maze512-1-0.map")]
SCENARIOS_PER_MAP = int(os.environ.get("BENCH_PLANNER_SCENARIOS", "5"))
REPEATS = 3
VENV = os.path.join(ROOT, "build", "bench_venv")
PEER = os.path.join(HERE, "planner_pathplanning_peer.py")
MOVES = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)]


def csr_graph(free):
    """The planners' graph as CSR arrays: node y * width + x, edges only where a move is legal."""
    h, w = free.shape
    ys, xs = np.mgrid[0:h, 0:w]
    src, dst, wts = [], [], []
    for dx, dy in MOVES:
        nx, ny = xs + dx, ys + dy
        ok = (nx >= 0) & (ny >= 0) & (nx < w) & (ny < h)
        ok &= free
        nxc, nyc = np.clip(nx, 0, w - 1), np.clip(ny, 0, h - 1)
        ok &= free[nyc, nxc]
        if dx and dy:
            ok &= free[ys, nxc] & free[nyc, xs]
        src.append((ys * w + xs)[ok])
        dst.append((nyc * w + nxc)[ok])
        wts.append(np.full(int(ok.sum()), math.hypot(dx, dy)))
    src, dst, wts = np.concatenate(src), np.concatenate(dst), np.concatenate(wts)
    order = np.argsort(src, kind="stable")
    src, dst, wts = src[order], dst[order], wts[order]
    indptr = np.zeros(h * w + 1, dtype=np.int64)
    np.cumsum(np.bincount(src, minlength=h * w), out=indptr[1:])
    return indptr, dst.astype(np.int64), wts


def edges_through(cell, free):
    """Directed edges that blocking cell makes illegal: into or out of it, and the diagonals it
    is a side cell of."""
    h, w = free.shape
    x, y = cell
    out = []

    def legal(ax, ay, bx, by):
        inside = all(0 <= v < lim for v, lim in ((ax, w), (bx, w), (ay, h), (by, h)))
        if not inside or not (free[ay, ax] and free[by, bx]):
            return False
        return ax == bx or ay == by or (free[ay, bx] and free[by, ax])

    for dx, dy in MOVES:
        if legal(x, y, x + dx, y + dy):
            out.append((y * w + x, (y + dy) * w + x + dx))
            out.append(((y + dy) * w + x + dx, y * w + x))
    for (ax, ay), (bx, by) in (((x - 1, y), (x, y - 1)), ((x, y - 1), (x + 1, y)),
                               ((x + 1, y), (x, y + 1)), ((x, y + 1), (x - 1, y))):
        if legal(ax, ay, bx, by):
            out.append((ay * w + ax, by * w + bx))
            out.append((by * w + bx, ay * w + ax))
    return out


def timed(fn, repeats=REPEATS):
    times, value = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        value = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), value


def ensure_venv():
    """The bench-only venv with pathplanning; (python, None) or (None, why it is unavailable)."""
    python = os.path.join(VENV, "bin", "python")
    check = [python, "-c", "import pathplanning.planners.search.dstar_lite"]
    if os.path.exists(python) and subprocess.run(check, capture_output=True).returncode == 0:
        return python, None
    made = subprocess.run([sys.executable, "-m", "venv", VENV], capture_output=True, text=True)
    if made.returncode != 0:
        return None, f"python3 -m venv failed: {made.stderr.strip()[-200:]}"
    pip = subprocess.run([python, "-m", "pip", "install", "-q", "pathplanning"],
                         capture_output=True, text=True)
    if pip.returncode != 0 or subprocess.run(check, capture_output=True).returncode != 0:
        return None, f"pip install pathplanning failed: {pip.stderr.strip()[-300:]}"
    return python, None


def bench_map(name, path, peer_python):
    array = read_movingai_map(path)
    free = array == 0
    h, w = free.shape
    scenarios = read_scenarios(path + ".scen")
    picks = np.unique(np.linspace(0, len(scenarios) - 1, SCENARIOS_PER_MAP).round().astype(int))
    chosen = [scenarios[i] for i in picks]
    grid = planning.Grid(array)
    indptr, indices, weights = csr_graph(free)
    t0 = time.perf_counter()
    matrix = csr_matrix((weights, indices, indptr), shape=(h * w, h * w))
    scipy_setup_ms = (time.perf_counter() - t0) * 1e3
    rows, block_edges, block_ptr = [], [], [0]
    for sc in chosen:
        s, g = tuple(sc.start), tuple(sc.goal)
        row = {"index": sc.index, "bucket": sc.bucket, "optimal": sc.optimal}

        def first():
            d = planning.DStarLite(grid, s, g)
            d.plan()
            return d
        row["dstar_first_ms"], dstar = timed(first)
        row["dstar_length"] = dstar.cost()
        row["dstar_expansions"] = dstar.expansions
        cells = dstar.path()
        middle = cells[len(cells) // 2] if len(cells) > 2 else None
        row["blocked_cell"] = list(middle) if middle else None
        if middle:
            replans = []
            for _ in range(REPEATS):
                d = first()
                t0 = time.perf_counter()
                d.update_cells([(middle[0], middle[1], 100)])
                d.plan()
                replans.append((time.perf_counter() - t0) * 1e3)
            row["dstar_replan_ms"] = statistics.median(replans)
            row["dstar_replan_length"] = d.cost()
            changed = planning.Grid(array)
            changed.update_cells([(middle[0], middle[1], 100)])
            row["check_replan_length"] = planning.astar(changed, s, g)[1]
            edges = edges_through(middle, free)
            block_edges.extend(edges)
        block_ptr.append(len(block_edges))
        row["astar_ms"], (_, row["astar_length"]) = timed(lambda: planning.astar(grid, s, g))
        source = sc.start[1] * w + sc.start[0]
        row["scipy_ms"], dist = timed(lambda: dijkstra(matrix, indices=source), repeats=1)
        row["scipy_length"] = float(dist[sc.goal[1] * w + sc.goal[0]])
        rows.append(row)
    peer = None
    if peer_python:
        with tempfile.TemporaryDirectory() as tmp:
            src, dst = os.path.join(tmp, "in.npz"), os.path.join(tmp, "out.json")
            np.savez(src, width=w, indptr=indptr, indices=indices, weights=weights,
                     scenarios=np.array([(sc.start[1] * w + sc.start[0],
                                          sc.goal[1] * w + sc.goal[0]) for sc in chosen]),
                     block_edges=np.array(block_edges, dtype=np.int64).reshape(-1, 2),
                     block_ptr=np.array(block_ptr))
            run = subprocess.run([peer_python, PEER, src, dst], capture_output=True, text=True)
            if run.returncode == 0:
                with open(dst) as f:
                    peer = json.load(f)
            else:
                peer = {"error": run.stderr.strip()[-500:]}
    if peer and "results" in peer:
        for row, p in zip(rows, peer["results"]):
            row.update({"pathplanning_" + k: v for k, v in p.items()})
    return {"map": name, "file": os.path.relpath(path, ROOT), "cells": h * w,
            "free_cells": int(free.sum()), "edges": int(len(indices)),
            "scipy_setup_ms": scipy_setup_ms, "scenarios": rows,
            "pathplanning_error": peer.get("error") if peer else None}


def ratio(a, b):
    return a / b if a is not None and b else None


def summarise(result):
    rows = result["scenarios"]
    hardest = rows[-1]
    ok = all(math.isclose(r["dstar_length"], r["optimal"], rel_tol=1e-6)
             and math.isclose(r["astar_length"], r["optimal"], rel_tol=1e-6)
             and math.isclose(r["scipy_length"], r["optimal"], rel_tol=1e-6) for r in rows)
    replans_ok = all(r.get("dstar_replan_length") is None or
                     math.isclose(r["dstar_replan_length"], r["check_replan_length"], rel_tol=1e-9)
                     for r in rows)
    peer_ok = all(r.get("pathplanning_length") is None or
                  math.isclose(r["pathplanning_length"], r["optimal"], rel_tol=1e-6) for r in rows)
    result["summary"] = {
        "lengths_match_optimal": ok, "replans_match_fresh": replans_ok,
        "pathplanning_lengths_match_optimal": peer_ok,
        "hardest_index": hardest["index"],
        "hardest_dstar_first_ms": hardest["dstar_first_ms"],
        "hardest_dstar_replan_ms": hardest.get("dstar_replan_ms"),
        "hardest_astar_ms": hardest["astar_ms"],
        "hardest_scipy_ms": hardest["scipy_ms"],
        "hardest_pathplanning_first_ms": hardest.get("pathplanning_first_ms"),
        "hardest_pathplanning_replan_ms": hardest.get("pathplanning_replan_ms"),
        "ratio_astar_over_dstar_first": ratio(hardest["astar_ms"], hardest["dstar_first_ms"]),
        "ratio_scipy_over_dstar_first": ratio(hardest["scipy_ms"], hardest["dstar_first_ms"]),
        "ratio_pathplanning_over_dstar_first": ratio(hardest.get("pathplanning_first_ms"),
                                                     hardest["dstar_first_ms"]),
        "ratio_pathplanning_over_dstar_replan": ratio(hardest.get("pathplanning_replan_ms"),
                                                      hardest.get("dstar_replan_ms")),
        "median_ratio_pathplanning_over_dstar_first": _median_ratio(rows, "pathplanning_first_ms",
                                                                    "dstar_first_ms"),
        "median_ratio_pathplanning_over_dstar_replan": _median_ratio(
            rows, "pathplanning_replan_ms", "dstar_replan_ms"),
    }


def _median_ratio(rows, a, b):
    values = [r[a] / r[b] for r in rows if r.get(a) is not None and r.get(b)]
    return statistics.median(values) if values else None


def fmt(v, digits=2):
    return "-" if v is None else f"{v:.{digits}f}"


def main():
    if not os.path.isdir(DATA):
        print(f"bench_planner: {os.path.normpath(DATA)} absent, skipped (it reads ../shared)")
        return 0
    print(f"bench_planner: reads Moving AI maps from {os.path.normpath(DATA)}")
    peer_python, why = ensure_venv()
    version = None
    if peer_python:
        version = subprocess.run([peer_python, "-c", "from importlib import metadata; "
                                  "print(metadata.version('pathplanning'))"],
                                 capture_output=True, text=True).stdout.strip()
        print(f"peer: pathplanning {version} D* Lite in {VENV}")
    else:
        print(f"peer: PyPI pathplanning unavailable: {why}")
    results = []
    for name, rel in MAPS:
        path = os.path.join(DATA, rel)
        if not os.path.exists(path) or not os.path.exists(path + ".scen"):
            print(f"{name}: {rel} absent, skipped")
            continue
        result = bench_map(name, path, peer_python)
        summarise(result)
        results.append(result)
        print(f"\n{name} ({result['free_cells']} free cells, {result['edges']} edges)"
              + (f"; pathplanning error: {result['pathplanning_error']}"
                 if result["pathplanning_error"] else ""))
        print(f"{'scen':>5} {'optimal':>10} | {'D*L first':>9} {'replan':>7} | {'A*':>8} | "
              f"{'scipy':>8} | {'pp first':>9} {'pp replan':>9} | lengths ok")
        for r in result["scenarios"]:
            ok = math.isclose(r["dstar_length"], r["optimal"], rel_tol=1e-6)
            print(f"{r['index']:>5} {r['optimal']:>10.3f} | {fmt(r['dstar_first_ms']):>9} "
                  f"{fmt(r.get('dstar_replan_ms'), 3):>7} | {fmt(r['astar_ms']):>8} | "
                  f"{fmt(r['scipy_ms'], 1):>8} | {fmt(r.get('pathplanning_first_ms')):>9} "
                  f"{fmt(r.get('pathplanning_replan_ms'), 3):>9} | {ok}")
        s = result["summary"]
        print(f"hardest: D* Lite first {fmt(s['hardest_dstar_first_ms'])} ms, replan "
              f"{fmt(s['hardest_dstar_replan_ms'], 3)} ms; ratios (peer / ours, first plan): "
              f"A* {fmt(s['ratio_astar_over_dstar_first'])}, scipy "
              f"{fmt(s['ratio_scipy_over_dstar_first'])}, pathplanning "
              f"{fmt(s['ratio_pathplanning_over_dstar_first'])}; replan pathplanning / ours "
              f"{fmt(s['ratio_pathplanning_over_dstar_replan'])}")
    out = {"data": os.path.normpath(DATA), "scenarios_per_map": SCENARIOS_PER_MAP,
           "repeats": REPEATS, "pathplanning": version or f"unavailable: {why}",
           "load_average": os.getloadavg(), "maps": results}
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "planner.json"), "w") as f:
        json.dump(out, f, indent=1)
    print("\nwrote bench/results/planner.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
