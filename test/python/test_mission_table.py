"""bench/mission_table.py: parts of a mission bench merged into one table, failures classed."""
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "bench"))

import mission_table  # noqa: E402


def run(world, success, phase, reason="", time_s=200.0, ended=True):
    return {"world": world, "robot": "ground", "success": success, "sim_time_s": time_s,
            "ended_at_s": time_s if ended else None, "final_phase": phase,
            "final_reason": reason, "tracking_losses": 3}


def write(path, kind, runs):
    with open(path, "w") as f:
        json.dump({"bench": "mission", "results": {kind: {"runs": runs}}}, f)
    return str(path)


def test_a_world_run_again_counts_once_as_the_last_file_has_it(tmp_path, capsys):
    first = write(tmp_path / "a.json", "ground stressed", [
        run("random:1", False, "go_to_exit", ended=False),
        run("random:2", True, "done", time_s=300.0),
        run("random:10", False, "done", "passed through the exit: openings up to 50 deg")])
    again = write(tmp_path / "b.json", "ground stressed", [
        run("random:1", True, "done", time_s=100.0),
        run("random:3", False, "gave_up", "SLAM tracking lost 3 times on the way to the exit "
                                          "(1.00, -2.00) without coming closer")])
    out = tmp_path / "table.json"
    assert mission_table.main([first, again, "--json", str(out)]) == 0
    row = json.load(open(out))["table"]["ground stressed"]
    assert row["worlds"] == 4 and row["successes"] == 2
    assert row["median_sim_time_to_exit_s"] == 300.0
    assert row["failures"] == {
        "judged out while inside": {"count": 1, "worlds": [10]},
        "gave up: SLAM tracking lost N times on the way to the exit": {"count": 1,
                                                                        "worlds": [3]}}
    assert "ground stressed: 2 of 4 (50 %)" in capsys.readouterr().out
    # In the other order, random:1 ran out of time.
    assert mission_table.main([again, first, "--json", str(out)]) == 0
    row = json.load(open(out))["table"]["ground stressed"]
    assert row["successes"] == 1
    assert row["failures"]["out of time in go_to_exit"] == {"count": 1, "worlds": [1]}


def test_a_run_without_a_report_is_a_failure_of_its_own():
    assert mission_table.failure_class({"world": "random:4", "error": "no report"}) == "no report"


def test_pooled_runs_all_count_with_an_interval_and_the_worlds_failed_again(tmp_path, capsys):
    first = write(tmp_path / "a.json", "drone stressed", [
        run("random:1", False, "done", "passed through the exit: openings up to 90 deg"),
        run("random:2", True, "done"),
        run("random:3", False, "look_around", ended=False)])
    again = write(tmp_path / "b.json", "drone stressed", [
        run("random:1", False, "gave_up", "SLAM tracking lost for more than 60 s"),
        run("random:2", True, "done"),
        run("random:3", True, "done")])
    out = tmp_path / "pooled.json"
    assert mission_table.main(["--pool", first, again, "--json", str(out)]) == 0
    row = json.load(open(out))["pooled"]["drone stressed"]
    assert row["runs"] == 6 and row["successes"] == 3 and row["success_share"] == 0.5
    low, high = row["interval_95"]
    assert 0.15 < low < 0.5 < high < 0.85   # Wilson, 3 of 6: about 0.19-0.81
    assert row["worlds_failed_once"] == 1
    assert row["worlds_failed_more_than_once"] == {
        "random:1": {"failed": 2, "runs": 2, "classes": [
            "judged out while inside", "gave up: SLAM tracking lost for more than N s"]}}
    assert "drone stressed: 3 of 6 runs (50.0 %" in capsys.readouterr().out
