#!/usr/bin/python3
"""How the looks around that never lost tracking were judged in the committed mission benches,
and where the robot truly stood: the evidence for the conductor's ``tracked_look_is_a_room``.

Every run in bench/results/mission_*.json lists its looks around beyond an exit with the
conductor's reason and whether the robot truly stood outside. A look whose reason counts no
tracking loss (sudden losses are not counted) and that was not ended by a loss (the lost
timeouts) is sorted by its verdict (out: done or step_out; else another room) and by the side
walls the reason gives (ending at the door's wall, going on past it, or no outline to measure them
on). Only files whose name ends in a commit at or after --since count (the rules for such looks
changed before it); the files overlap (worlds run again at later commits) and each run counts as
recorded. Reads nothing from ../shared; needs git for the commits' dates; takes a second.

    /usr/bin/python3 bench/bench_tracked_looks.py
"""
import argparse
import collections
import glob
import json
import os
import re
import subprocess

from mission_looks import recorded_looks

HERE = os.path.dirname(os.path.abspath(__file__))
COMMIT = re.compile(r"_([0-9a-f]{7,40})(?:_[a-z_]+)?\.json$")
ENDED_BY_A_LOSS = ("tracking losses looking around", "not back in", "left the room",
                   "tracking lost")


def commit_time(commit):
    """The commit's time (s since the epoch), or None when git does not know it."""
    done = subprocess.run(["git", "-C", HERE, "log", "-1", "--format=%ct", commit],
                          capture_output=True, text=True)
    return int(done.stdout) if done.returncode == 0 and done.stdout.strip() else None


def side_walls(reason):
    if "end at the door's wall" in reason:
        return "end"
    if "go on" in reason:
        return "go on"
    return "no outline" if "no room outline" in reason else "other"


def tracked_looks(paths):
    """(robot and mode, verdict, side walls, truly outside) of each look that kept tracking."""
    looks = []
    for kind, look in recorded_looks(paths):
        reason = look["reason"]
        if any(sign in reason for sign in ENDED_BY_A_LOSS):
            continue
        verdict = "out" if look["then"] in ("done", "step_out") else "another room"
        looks.append((kind, verdict, side_walls(reason), bool(look["truly_outside"])))
    return looks


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--since", default="c549619",
                        help="the first commit whose bench files count (default %(default)s, "
                             "2026-11-27: the looks' loss counts)")
    parser.add_argument("--json", default=os.path.join(HERE, "results", "tracked_looks.json"))
    args = parser.parse_args()
    since = commit_time(args.since)
    if since is None:
        parser.error(f"git does not know commit {args.since}")
    paths = []
    for path in sorted(glob.glob(os.path.join(HERE, "results", "mission_*.json"))):
        match = COMMIT.search(os.path.basename(path))
        when = commit_time(match.group(1)) if match else None
        if when is not None and when >= since:
            paths.append(path)
    counts = collections.Counter(tracked_looks(paths))
    table = collections.defaultdict(dict)
    for (kind, verdict, side, outside), n in sorted(counts.items()):
        table[kind][f"{verdict}, side walls {side}, truly {'outside' if outside else 'inside'}"] = n
    print(f"{len(paths)} result files since {args.since}; looks that never lost tracking:")
    for kind, row in table.items():
        for key, n in row.items():
            print(f"  {kind:16s} {key:55s} {n:4d}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"files": len(paths), "since": args.since, "looks": table}, f, indent=1)


if __name__ == "__main__":
    main()
