#!/usr/bin/python3
"""The escape mission on generated worlds: success rate, sim time to the exit, losses survived.

Each run is `roslaunch sparse_nav demo.launch world:=random:SEED robot:=ROBOT` (the whole stack on
the built-in simulator, headless) and reads the run's report.json. The stress setting forces a
SLAM loss every 30 sim-seconds and drops 10 % of the SLAM messages. Reads nothing from ../shared.
A run costs minutes of wall time, so the default is small; `--worlds 50` is the full bench.
Each run also lists its looks around beyond an exit, each with its verdict and whether the robot
truly stood outside then; the summary counts them, which measures the conductor's judgement.
"""
import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.mission_report import tally_look_arounds  # noqa: E402

STRESS_LOSS_PERIOD_S = 30.0
STRESS_DROP_FRACTION = 0.1


def free_port():
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def run_mission(world, robot, stress, limit_s, rate_factor, tmp, failed_logs_dir,
                keep_all_logs=False):
    """One mission; returns the report (or an error entry) with the run's wall time. A run that
    fails (any run, with keep_all_logs) keeps its ROS logs, its report and summary.png in
    failed_logs_dir, for the reason."""
    name = f"{world.replace(':', '_')}_{robot}_{'stress' if stress else 'plain'}"
    out = os.path.join(tmp, name)
    args = ["roslaunch", "-p", str(free_port()), "sparse_nav", "demo.launch", f"world:={world}",
            f"robot:={robot}", f"output_dir:={out}", f"rate_factor:={rate_factor}",
            f"sim_time_limit_s:={limit_s}"]
    if stress:
        losses = [STRESS_LOSS_PERIOD_S * k for k in range(1, int(limit_s // STRESS_LOSS_PERIOD_S))]
        args += [f"force_loss_at_s:={json.dumps(losses)}",
                 f"slam_message_drop_fraction:={STRESS_DROP_FRACTION}"]
    ros_home = os.path.join(tmp, "ros_home")
    env = dict(os.environ, ROS_HOME=ros_home)
    start = time.monotonic()
    try:
        proc = subprocess.run(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              env=env, timeout=limit_s / max(rate_factor, 0.5) * 3 + 300)
    except subprocess.TimeoutExpired:
        return {"world": world, "robot": robot, "error": "wall-time limit"}
    wall_s = time.monotonic() - start
    report, error = None, None
    try:
        with open(os.path.join(out, "report.json")) as f:
            report = json.load(f)
    except (OSError, ValueError) as exc:
        error = f"no report: {exc}"
    logs = None
    if keep_all_logs or report is None or not report.get("success"):
        logs = _keep_logs(out, os.path.join(ros_home, "log", "latest"),
                          os.path.join(failed_logs_dir, name))
    shutil.rmtree(out, ignore_errors=True)
    if report is None:
        if logs is None:
            # roslaunch stopped before any node ran (a package not found, say): its own words.
            return {"world": world, "robot": robot, "error": error,
                    "roslaunch_stderr": proc.stderr.strip()[-400:]}
        return {"world": world, "robot": robot, "error": error, "logs": logs}
    scale = report.get("scale") or {}
    measured = report.get("scale_most_measured") or {}
    return {"world": world, "robot": robot, "success": report["success"],
            "sim_time_s": report["sim_time_s"], "ended_at_s": report.get("ended_at_s"),
            "tracking_losses": report["tracking_losses"],
            "final_phase": report["final_phase"], "final_reason": report["final_reason"],
            "exit_error_m": report["exit_error_m"], "wall_s": round(wall_s, 1),
            # A map built at the wrong scale fails the mission for reasons far from the scale.
            "scale_samples": scale.get("samples"),
            "scale_relative_error": scale.get("relative_error"),
            # The final map is often one begun outside after a last loss, barely measured.
            "scale_most_measured": {k: measured.get(k) for k in ("map_index", "samples",
                                                                  "relative_error")},
            "look_arounds": report.get("look_arounds", []),
            **({"logs": logs} if logs else {})}


def _keep_logs(out, ros_log, logs):
    """Copies a failed run's ROS log folder, report.json and summary.png into logs; returns it,
    or None when the run left no ROS log."""
    if not os.path.isdir(ros_log):
        return None
    shutil.rmtree(logs, ignore_errors=True)
    shutil.copytree(ros_log, logs, ignore_dangling_symlinks=True)
    for kept in ("report.json", "summary.png"):
        if os.path.isfile(os.path.join(out, kept)):
            shutil.copy(os.path.join(out, kept), logs)
    return logs


def summarise(runs):
    ok = [r for r in runs if r.get("success")]
    return {"runs": len(runs), "successes": len(ok),
            "look_arounds": tally_look_arounds(
                [look for r in runs for look in r.get("look_arounds", [])]),
            "success_rate": round(len(ok) / len(runs), 3) if runs else None,
            "median_sim_time_to_exit_s": (sorted(r["sim_time_s"] for r in ok)[len(ok) // 2]
                                          if ok else None),
            "losses_survived": sum(r["tracking_losses"] for r in ok),
            "errors": sum(1 for r in runs if "error" in r)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--worlds", type=int, default=3, help="generated worlds per robot kind")
    parser.add_argument("--first-seed", type=int, default=1)
    parser.add_argument("--robots", default="ground,drone")
    parser.add_argument("--sim-time-limit-s", type=float, default=600.0)
    parser.add_argument("--rate-factor", type=float, default=4.0)
    parser.add_argument("--no-stress", action="store_true", help="skip the stressed runs")
    parser.add_argument("--stress-only", action="store_true", help="skip the plain runs")
    parser.add_argument("--keep-all-logs", action="store_true",
                        help="keep the logs of successful runs too (next to the failed ones)")
    parser.add_argument("--out", default=os.path.join(HERE, "results", "mission.json"))
    args = parser.parse_args(argv)
    if shutil.which("roslaunch") is None:
        print("bench_mission: roslaunch not found; source the workspace (make bench does)")
        return 1
    tmp = tempfile.mkdtemp(prefix="bench_mission_")
    failed_logs = os.path.splitext(args.out)[0] + "_failed_logs"
    table = {}
    try:
        for stress in [s for s in (False, True) if not (s and args.no_stress)
                       and not (not s and args.stress_only)]:
            for robot in args.robots.split(","):
                runs = []
                for seed in range(args.first_seed, args.first_seed + args.worlds):
                    run = run_mission(f"random:{seed}", robot, stress, args.sim_time_limit_s,
                                      args.rate_factor, tmp, failed_logs, args.keep_all_logs)
                    print(json.dumps(run), flush=True)
                    runs.append(run)
                key = f"{robot}{' stressed' if stress else ''}"
                table[key] = {"summary": summarise(runs), "runs": runs}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"{'setting':<16} {'runs':>5} {'success':>8} {'median t (s)':>13} {'losses survived':>16}")
    for key, entry in table.items():
        s = entry["summary"]
        rate = "-" if s["success_rate"] is None else f"{100 * s['success_rate']:.0f}%"
        median = "-" if s["median_sim_time_to_exit_s"] is None else f"{s['median_sim_time_to_exit_s']:.0f}"
        print(f"{key:<16} {s['runs']:>5} {rate:>8} {median:>13} {s['losses_survived']:>16}")
    print("look arounds beyond an exit, verdict against the truth:")
    for key, entry in table.items():
        print(f"{key:<16} " + ", ".join(f"{k.replace('_', ' ')} {v}"
                                         for k, v in entry["summary"]["look_arounds"].items()))
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        json.dump({"bench": "mission", "data": "generated worlds random:SEED, none from ../shared",
                   "stress": {"loss_every_s": STRESS_LOSS_PERIOD_S,
                              "slam_message_drop_fraction": STRESS_DROP_FRACTION},
                   "rate_factor": args.rate_factor, "sim_time_limit_s": args.sim_time_limit_s,
                   "results": table}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
