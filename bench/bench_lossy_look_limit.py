#!/usr/bin/python3
"""What the conductor's ``lossy_look_max_opening_deg`` would change in the looks around that the
committed mission benches recorded.

Every run in bench/results/mission_*.json lists its looks around beyond an exit: the conductor's
reason (the widest opening, the tracking losses counted, the side walls) and whether the robot
truly stood outside then. A look that lost tracking (``lossy_look_min_losses`` or more losses
counted) and was judged another room by its openings would have been judged out under a lower
limit when its widest opening exceeds that limit; only openings up to ``--current`` count (wider
ones were judged in by the rules of older commits). Per robot and mode, and per candidate limit,
this counts those flips and whether the robot was truly outside (a flip made right) or in a room
(a flip made wrong: the mission ends there, inside). Looks judged out stay out under any lower
limit. The files overlap (worlds run again at later commits); each run counts as recorded. Reads
nothing from ../shared; takes a second.

    /usr/bin/python3 bench/bench_lossy_look_limit.py
"""
import argparse
import collections
import glob
import json
import os
import re

from mission_looks import recorded_looks

HERE = os.path.dirname(os.path.abspath(__file__))
OPENING = re.compile(r"openings up to (\d+) deg")
LOSSES = re.compile(r"(\d+) tracking losses looking around")


def lossy_looks_judged_in(paths, min_losses):
    """(robot and mode, widest opening deg, truly outside) of each lossy look judged another room
    by its openings."""
    looks = []
    for kind, look in recorded_looks(paths):
        reason = look["reason"]
        opening, losses = OPENING.search(reason), LOSSES.search(reason)
        if look["then"] in ("done", "step_out") or not opening or not losses \
                or int(losses.group(1)) < min_losses:
            continue
        looks.append((kind, int(opening.group(1)), bool(look["truly_outside"])))
    return looks


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--limits", type=float, nargs="+", default=[22.5, 27.5, 32.5])
    parser.add_argument("--current", type=float, default=37.5,
                        help="the limit the looks were judged by (deg; default %(default)s)")
    parser.add_argument("--min-losses", type=int, default=1)
    parser.add_argument("--json", default=os.path.join(HERE, "results", "lossy_look_limit.json"))
    args = parser.parse_args()
    paths = sorted(glob.glob(os.path.join(HERE, "results", "mission_*.json")))
    looks = lossy_looks_judged_in(paths, args.min_losses)
    table = collections.defaultdict(dict)
    for kind in sorted({k for k, _, _ in looks}):
        for limit in args.limits:
            flipped = [out for k, opening, out in looks
                       if k == kind and limit < opening <= args.current]
            table[kind][str(limit)] = {"right": sum(flipped), "wrong": len(flipped) - sum(flipped)}
    print(f"{len(paths)} result files, {len(looks)} lossy looks judged another room; flips to "
          f"out, openings up to {args.current:g} deg:")
    print(f"{'runs':22s}" + "".join(f"{'> ' + format(limit, 'g') + ' deg':>16s}"
                                    for limit in args.limits))
    for kind, row in table.items():
        print(f"{kind:22s}" + "".join(f"{row[str(limit)]['right']:>7d} right,{row[str(limit)]['wrong']:>2d} wrong"
                                      for limit in args.limits))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"files": len(paths), "lossy_looks_judged_in": len(looks),
                       "current_limit_deg": args.current,
                       "flips_to_out": table}, f, indent=1)


if __name__ == "__main__":
    main()
