"""Runs the PyPI ``pathplanning`` D* Lite (native) on the graphs bench_planner.py writes; run by
bench_planner.py inside the bench-only virtual environment build/bench_venv, never imported by
sparse_nav. Usage: planner_pathplanning_peer.py IN.npz OUT.json

IN.npz holds the exact graph sparse_nav searches (CSR: 8-connected, sqrt(2) diagonals, no corner
cutting), the scenarios and, per scenario, the edges to block for the replan.
"""
import json
import math
import sys
import time
from importlib import metadata

import numpy as np
from pathplanning.native import NativeGraph
from pathplanning.planners.search.dstar_lite import DStarLitePlanner

SQRT2 = math.sqrt(2.0)


def main(src, dst):
    data = np.load(src)
    width = int(data["width"])

    def octile(a, b):
        dx = abs(a % width - b % width)
        dy = abs(a // width - b // width)
        return max(dx, dy) + (SQRT2 - 1.0) * min(dx, dy)

    rows = []
    for k, (start, goal) in enumerate(data["scenarios"]):
        # A fresh graph per scenario: edge updates must not leak into the next one.
        t0 = time.perf_counter()
        graph = NativeGraph.from_csr(data["indptr"], data["indices"], data["weights"],
                                     heuristic=octile)
        planner = DStarLitePlanner(graph, int(start), int(goal),
                                   max_materialized_nodes=len(data["indptr"]))
        setup_ms = (time.perf_counter() - t0) * 1e3
        t0 = time.perf_counter()
        first = planner.plan()
        first_ms = (time.perf_counter() - t0) * 1e3
        row = {"setup_ms": setup_ms, "first_ms": first_ms,
               "length": first.stats["path_cost"] if first.success else None,
               "replan_ms": None, "replan_length": None}
        lo, hi = data["block_ptr"][k], data["block_ptr"][k + 1]
        if hi > lo:
            edges = data["block_edges"][lo:hi]
            t0 = time.perf_counter()
            planner.update_edges([(int(a), int(b), math.inf) for a, b in edges])
            replan = planner.plan()
            row["replan_ms"] = (time.perf_counter() - t0) * 1e3
            row["replan_length"] = replan.stats["path_cost"] if replan.success else None
        planner.close()
        rows.append(row)
    with open(dst, "w") as f:
        json.dump({"version": metadata.version("pathplanning"), "results": rows}, f)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
