#!/usr/bin/python3
"""The success table of the escape mission from bench_mission.py result files, with each failure
put in a class.

A full bench (50 worlds per robot kind, plain and stressed) takes hours, so it is often run in
parts, and a part run again after a change. Pass the files in the order they were run: a world
found in several files counts once, as the last file has it. Per robot kind (and stress): the
worlds, the successes, the median sim time to the exit of the successes, and the failures by
class: judged out while inside a room, out of sim time (by the phase it was in), gave up (by its
reason), and runs that left no report. Reads only the files given; takes a second.

    /usr/bin/python3 bench/mission_table.py bench/results/mission_ground_stressed_1-31_72008ba.json \\
        bench/results/mission_ground_stressed_32-36_404cdf4.json
"""
import argparse
import collections
import json
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_mission import summarise  # noqa: E402


def failure_class(run):
    """A short name for why a run failed."""
    if "error" in run:
        return "no report"
    if run["final_phase"] == "done":
        return "judged out while inside"
    if run["final_phase"] == "gave_up":
        # The reason's numbers differ from run to run; its words say why.
        reason = re.sub(r"\s*\(.*", "", run["final_reason"])
        return f"gave up: {re.sub(r'[-0-9.]+', 'N', reason)[:60]}"
    # Any other phase at the end: the sim-time limit stopped the run there.
    return f"out of time in {run['final_phase']}"


def merge(paths):
    """{robot kind: {world: run}}: the last file holding a world has its say."""
    table = collections.defaultdict(dict)
    for path in paths:
        with open(path) as f:
            results = json.load(f).get("results", {})
        for kind, entry in results.items():
            for run in entry.get("runs", []):
                table[kind][run["world"]] = run
    return table


def seed(world):
    match = re.search(r"(\d+)$", world)
    return int(match.group(1)) if match else -1


def summary(runs):
    """bench_mission's summary of the runs, with their failures by class."""
    failed = collections.defaultdict(list)
    for r in runs:
        if not r.get("success"):
            failed[failure_class(r)].append(seed(r["world"]))
    s = summarise(runs)
    return {"worlds": s["runs"], "successes": s["successes"],
            "median_sim_time_to_exit_s": s["median_sim_time_to_exit_s"],
            "look_arounds": s["look_arounds"],
            "failures": {k: {"count": len(w), "worlds": sorted(w)}
                         for k, w in sorted(failed.items(), key=lambda kw: -len(kw[1]))}}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", help="bench_mission.py result files, oldest first")
    parser.add_argument("--json", help="also write the table here")
    args = parser.parse_args(argv)
    table = {kind: summary([runs[w] for w in sorted(runs, key=seed)])
             for kind, runs in sorted(merge(args.files).items())}
    for kind, row in table.items():
        median = row["median_sim_time_to_exit_s"]
        print(f"{kind}: {row['successes']} of {row['worlds']} "
              f"({100 * row['successes'] / row['worlds']:.0f} %), median time to the exit "
              f"{'-' if median is None else f'{median:.0f} s'}")
        for name, failures in row["failures"].items():
            print(f"  {failures['count']:3d} {name}: random:"
                  + ", ".join(str(s) for s in failures["worlds"]))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"files": args.files, "table": table}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
