"""``plan_path``: the navigator's planners on map files, from the command line.

Usage::

    plan_path --movingai-map MAP --scen SCEN [--planner dstar_lite|astar|rrt] [--limit N]
              [--sample N] [--seed N] [--json]
    plan_path --map YAML --start X Y --goal X Y [--planner ...] [--robot-radius-m R]
              [--unknown-policy free|costly|blocked] [--no-smooth] [--seed N] [--json]

Moving AI mode runs the scenarios of a ``.scen`` file on its ``.map`` and prints, with ``--json``::

    {"planner": .., "results": [{"index": i, "length": .., "optimal": .., "plan_ms": ..,
                                 "replan_ms": .., "replan_length": .., "replan_check_length": ..}]}

``length`` is the found path's length in cells (octile for the grid planners, Euclidean for RRT),
``optimal`` the file's. The replan blocks the middle cell of the found path and plans again from
the same start (D* Lite repairs its search incrementally; A* and RRT search afresh);
``replan_check_length`` is a fresh A* search on the changed grid. A missing path is ``null``.
``--limit N`` takes the first N scenarios, ``--sample N`` N of them evenly spread from the first
to the last (the hardest bucket).

map_server mode plans from START to GOAL (metres, map frame) and prints the path in metres;
``--json`` prints ``{"planner", "path": [[x, y], ...], "length_m", "plan_ms", "start_cell",
"goal_cell"}``.

Exit status: 0 when every run found a path, 1 when some found none, 2 on an error (unreadable or
malformed file, start or goal outside the map), with a message on stderr.
"""
import argparse
import json
import math
import sys
import time

import numpy as np

from sparse_nav.navigation.maps import (MapFileError, read_map_server, read_movingai_map,
                                        read_scenarios)
from sparse_nav.navigation.rrt import Rrt, RrtConfig

PROG = "plan_path"
PLANNERS = ("dstar_lite", "astar", "rrt")


def _parser():
    parser = argparse.ArgumentParser(prog=PROG, description="Plan paths with sparse_nav's D* Lite, "
                                                            "A* or RRT on map files.")
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--movingai-map", metavar="MAP", help="Moving AI .map file (with --scen)")
    mode.add_argument("--map", metavar="YAML", help="map_server YAML (with --start and --goal)")
    parser.add_argument("--scen", metavar="SCEN", help="Moving AI .scen file")
    parser.add_argument("--start", nargs=2, type=float, metavar=("X", "Y"), help="start [m]")
    parser.add_argument("--goal", nargs=2, type=float, metavar=("X", "Y"), help="goal [m]")
    parser.add_argument("--planner", choices=PLANNERS, default="dstar_lite")
    parser.add_argument("--limit", type=int, help="run the first N scenarios")
    parser.add_argument("--sample", type=int, help="run N scenarios spread from first to last")
    parser.add_argument("--seed", type=int, default=0, help="RRT seed (default 0)")
    parser.add_argument("--robot-radius-m", type=float, default=0.0,
                        help="map mode: inflation radius (default 0)")
    parser.add_argument("--unknown-policy", choices=("free", "costly", "blocked"), default="costly",
                        help="map mode: unknown cells (default costly)")
    parser.add_argument("--no-smooth", action="store_true", help="map mode: no string pulling")
    parser.add_argument("--json", action="store_true", help="print JSON")
    return parser


class _Error(Exception):
    pass


def _planning():
    from sparse_nav import _planning
    return _planning


def _plan(planner, grid, start, goal, seed):
    """(path cells, length, plan_ms, state) where state lets _replan repair the same search."""
    planning = _planning()
    t0 = time.perf_counter()
    if planner == "dstar_lite":
        dstar = planning.DStarLite(grid, start, goal)
        dstar.plan()
        path, length, state = dstar.path(), dstar.cost(), dstar
    elif planner == "astar":
        path, length = planning.astar(grid, start, goal)
        state = None
    else:
        result = Rrt(grid.traversable_mask(), RrtConfig(seed=seed)).plan(start, goal)
        path, length, state = result.path, result.length, None
    return path, length, (time.perf_counter() - t0) * 1e3, state


def _replan(planner, grid, start, goal, blocked, state, seed):
    planning = _planning()
    change = [(blocked[0], blocked[1], 100)]
    if planner == "dstar_lite":
        t0 = time.perf_counter()
        state.update_cells(change)
        state.plan()
        return state.cost(), (time.perf_counter() - t0) * 1e3
    grid.update_cells(change)
    _, length, ms, _ = _plan(planner, grid, start, goal, seed)
    return length, ms


def _finite(value):
    return value if value is not None and math.isfinite(value) else None


def _select(scenarios, limit, sample):
    if limit is not None:
        if limit < 1:
            raise _Error(f"--limit must be >= 1, got {limit}")
        scenarios = scenarios[:limit]
    if sample is not None:
        if sample < 1:
            raise _Error(f"--sample must be >= 1, got {sample}")
        if sample < len(scenarios):
            picks = np.unique(np.linspace(0, len(scenarios) - 1, sample).round().astype(int))
            scenarios = [scenarios[i] for i in picks]
    return scenarios


def run_movingai(args):
    if not args.scen:
        raise _Error("--movingai-map needs --scen")
    array = read_movingai_map(args.movingai_map)
    scenarios = _select(read_scenarios(args.scen), args.limit, args.sample)
    height, width = array.shape
    planning = _planning()
    base = planning.Grid(array)
    results = []
    for sc in scenarios:
        if (sc.width, sc.height) != (width, height):
            raise _Error(f"{args.scen}: scenario {sc.index} is for a {sc.width} x {sc.height} map, "
                         f"{args.movingai_map} is {width} x {height}")
        for name, (x, y) in (("start", sc.start), ("goal", sc.goal)):
            if not (0 <= x < width and 0 <= y < height):
                raise _Error(f"{args.scen}: scenario {sc.index}: {name} ({x}, {y}) is outside the map")
        grid = planning.Grid(array) if args.planner != "dstar_lite" else base
        path, length, plan_ms, state = _plan(args.planner, grid, sc.start, sc.goal, args.seed)
        row = {"index": sc.index, "length": _finite(length), "optimal": sc.optimal,
               "plan_ms": plan_ms, "replan_ms": None, "replan_length": None,
               "replan_check_length": None}
        if len(path) > 2:
            middle = path[len(path) // 2]
            cell = (int(round(middle[0])), int(round(middle[1])))
            if cell not in (tuple(sc.start), tuple(sc.goal)):
                replan_length, replan_ms = _replan(args.planner, grid, sc.start, sc.goal, cell,
                                                   state, args.seed)
                check_grid = planning.Grid(array)
                check_grid.update_cells([(cell[0], cell[1], 100)])
                _, check = planning.astar(check_grid, sc.start, sc.goal)
                row.update(replan_ms=replan_ms, replan_length=_finite(replan_length),
                           replan_check_length=_finite(check))
        results.append(row)
    out = {"planner": args.planner, "results": results}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{'index':>6} {'length':>12} {'optimal':>12} {'plan_ms':>9} {'replan_ms':>9} "
              f"{'replan':>12} {'check':>12}")
        for r in results:
            print(f"{r['index']:>6} {_txt(r['length'])} {_txt(r['optimal'])} {_txt(r['plan_ms'], 9, 2)} "
                  f"{_txt(r['replan_ms'], 9, 3)} {_txt(r['replan_length'])} "
                  f"{_txt(r['replan_check_length'])}")
    return 0 if all(r["length"] is not None for r in results) else 1


def _txt(value, width=12, digits=4):
    return f"{'-':>{width}}" if value is None else f"{value:>{width}.{digits}f}"


def run_map(args):
    if args.start is None or args.goal is None:
        raise _Error("--map needs --start X Y and --goal X Y")
    if not all(math.isfinite(v) for v in (*args.start, *args.goal)):
        raise _Error("--start and --goal must be finite")
    if not (math.isfinite(args.robot_radius_m) and args.robot_radius_m >= 0):
        raise _Error(f"--robot-radius-m must be finite and >= 0, got {args.robot_radius_m}")
    m = read_map_server(args.map)
    g = m.geometry
    planning = _planning()
    try:
        grid = planning.Grid(m.data, unknown_policy=args.unknown_policy,
                             inflation_radius=args.robot_radius_m / g.resolution)
    except ValueError as exc:
        raise _Error(str(exc)) from None
    cells = []
    for name, p in (("start", args.start), ("goal", args.goal)):
        c = g.world_to_cell(*p)
        if not g.in_bounds(*c):
            raise _Error(f"{name} ({p[0]}, {p[1]}) is outside the map {args.map}")
        cells.append(c)
    path, _, plan_ms, _ = _plan(args.planner, grid, cells[0], cells[1], args.seed)
    if path and args.planner != "rrt" and not args.no_smooth:
        path = planning.smooth(grid, path)
    points = [list(g.cell_to_world(*c)) for c in path]
    length_m = sum(math.dist(a, b) for a, b in zip(points, points[1:])) if points else None
    if args.json:
        print(json.dumps({"planner": args.planner, "path": points, "length_m": length_m,
                          "plan_ms": plan_ms, "start_cell": list(cells[0]),
                          "goal_cell": list(cells[1])}))
    elif points:
        print(f"path of {length_m:.3f} m in {plan_ms:.2f} ms:")
        for x, y in points:
            print(f"{x:.3f} {y:.3f}")
    else:
        print(f"no path from {tuple(args.start)} to {tuple(args.goal)}")
    return 0 if points else 1


def run(argv=None):
    """The tool; returns the exit status instead of exiting."""
    args = _parser().parse_args(argv)
    try:
        return run_movingai(args) if args.movingai_map else run_map(args)
    except (_Error, MapFileError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2


def main():
    sys.exit(run())
