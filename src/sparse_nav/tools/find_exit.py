"""``find_exit FILE``: the room's exit in an ORB-SLAM point file, from the command line.

Usage::

    find_exit FILE [--up-axis -y] [--method NAME] [--plot PNG] [--json] [--seed N]

FILE is any point file :func:`sparse_nav.pointfiles.read_points` reads (CSV/TXT/XYZ, PLY, PCD;
the first three columns are x, y, z). ``--up-axis`` names its vertical axis (default ``-y``,
ORB-SLAM's camera frame: x right, y down, z forward); the answer is in the two other axes of the
file, in its own units (for ``±y``: x and z). ``--json`` prints exactly::

    {"exits": [{"x": .., "y": .., "score": ..}, ...best first], "method": ..,
     "room_corners": [[x, y], ...], "n_points_in": .., "n_points_used": .., "runtime_s": ..}

where "x" and "y" are the first and second remaining axes. ``--plot`` writes seed 000's picture.

Exit status: 0 with an exit, 1 when a room was found but nothing marks an exit (the JSON then
has no exits), 2 on an error (unreadable file, too few points, collinear points, no room shape),
with a message on stderr naming the file and the problem.
"""
import argparse
import json
import os
import sys

from sparse_nav.exit_finder import DEFAULT_METHOD, METHODS, ExitFinderError, find_exit
from sparse_nav.exit_finder.cloud import PLANAR_AXIS_NAMES, planar_points
from sparse_nav.pointfiles import UP_AXES, PointFileError, read_points

PROG = "find_exit"


def _parser():
    parser = argparse.ArgumentParser(
        prog=PROG, description="Find the exit of a room in an ORB-SLAM point file (seed 000 and "
                               "its successors).")
    parser.add_argument("file", help="point file: CSV/TXT/XYZ, PLY or PCD with x, y, z")
    parser.add_argument("--up-axis", default="-y", choices=UP_AXES,
                        help="vertical axis of the file (default: -y, ORB-SLAM's)")
    parser.add_argument("--method", default=DEFAULT_METHOD, choices=METHODS,
                        help=f"exit finder method (default: {DEFAULT_METHOD})")
    parser.add_argument("--plot", metavar="PNG", help="write the seed 000 picture to this PNG")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--seed", type=int, default=None,
                        help="seed of the random draws (default: the config's, 0)")
    return parser


def _fail(message):
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return 2


def run(argv=None):
    """The tool; returns the exit status instead of exiting."""
    args = _parser().parse_args(argv)
    if args.seed is not None and args.seed < 0:
        return _fail(f"--seed must be >= 0, got {args.seed}")
    try:
        points = read_points(args.file)
    except (PointFileError, OSError) as exc:
        return _fail(str(exc))
    try:
        result = find_exit(points, method=args.method, up_axis=args.up_axis, seed=args.seed)
    except ExitFinderError as exc:
        return _fail(f"{args.file}: {exc}")
    axes = PLANAR_AXIS_NAMES[args.up_axis.lstrip("+-").lower()]
    if args.plot:
        from sparse_nav.exit_finder.plot import plot_result
        xy, _ = planar_points(points, args.up_axis)
        try:
            plot_result(result, xy, args.plot, axis_names=axes,
                        title=f"{os.path.basename(args.file)}\n{result.method}: "
                              f"{result.status}")
        except OSError as exc:
            return _fail(f"cannot write the plot {args.plot}: {exc}")
    if args.json:
        print(json.dumps(result.to_json_dict()))
    else:
        _print_text(result, axes)
    if not result.exits:
        print(f"{PROG}: {args.file}: no exit found: {result.reason}", file=sys.stderr)
        return 1
    return 0


def _print_text(result, axes):
    a, b = axes
    print(f"method: {result.method}  status: {result.status}  ({result.reason})")
    for k, (x, y, score) in enumerate(result.exits):
        print(f"exit {k}: {a} = {x:.4g}, {b} = {y:.4g}, score {score:.2f}")
    corners = ", ".join(f"({x:.3g}, {y:.3g})" for x, y in result.room_corners)
    print(f"room outline ({len(result.room_corners)} corners, {a}, {b}): {corners}")
    print(f"points: {result.n_points_in} in, {result.n_dropped_non_finite} non-finite dropped, "
          f"{result.n_points_used} used; {result.runtime_s:.3f} s")


def main(argv=None):
    """Entry point of the ``find_exit`` script."""
    sys.exit(run(argv))
