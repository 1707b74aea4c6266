"""extract_features (the C++ CLI of the line-feature core) on the hand-made files in test/fixtures/laser.

Skipped when the workspace with the tool is not built and sourced.
"""
import json
import os
import subprocess

import pytest

from workspace_tools import find_tool

FIXTURES = os.path.join(os.path.dirname(__file__), "..", "fixtures", "laser")


TOOL = find_tool("extract_features")
pytestmark = pytest.mark.skipif(TOOL is None, reason="extract_features not built (source the workspace)")


def run(*args):
    return subprocess.run([TOOL, *args], capture_output=True, text=True, timeout=120)


def fixture(name):
    return os.path.join(FIXTURES, name)


def test_json_per_scan_features_of_a_carmen_log():
    out = run(fixture("room.log.gz"), "--json")
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    assert r["format"] == "carmen" and r["n_scans"] == 2 and r["n_bad_lines"] == 2
    first = r["scans"][0]
    assert first["ok"]
    # The door is 4 m ahead, from y = -0.2 to 0.7 in the sensor frame.
    assert len(first["doors"]) == 1
    x1, y1, x2, y2 = first["doors"][0]
    assert abs((x1 + x2) / 2 - 4.0) < 0.05 and abs((y1 + y2) / 2 - 0.25) < 0.05
    assert all(len(w) == 4 for w in first["walls"])
    assert {c["type"] for c in first["corners"]} == {"outer"}
    assert r["total_ms"] >= 0.0 and r["counts"]["doors"] == 2


def test_world_frame_and_match_against_the_poses():
    r = json.loads(run(fixture("room.log"), "--json", "--world", "--match").stdout)
    for scan in r["scans"]:
        x1, y1, x2, y2 = scan["doors"][0]
        assert abs((x1 + x2) / 2 - 4.0) < 0.08 and abs((y1 + y2) / 2 - 0.75) < 0.08
    m = r["match"]
    assert m["pairs"] == 1 and m["failed"] == 0
    assert m["median_translation_error_m"] < 0.05
    assert m["median_rotation_error_deg"] < 1.0
    assert m["median_motion_m"] > 0.2  # the robot did move: the error is not trivially small


def test_summary_has_counts_but_no_scans():
    r = json.loads(run(fixture("robotlaser.log"), "--json", "--summary").stdout)
    assert "scans" not in r
    assert r["n_scans"] == 1 and r["max_beams"] == 361 and r["counts"]["walls"] >= 4
    text = run(fixture("robotlaser.log"), "--summary")
    assert text.returncode == 0 and "scans/s" in text.stdout


def test_csv_bad_rows_are_refused_with_reasons():
    r = json.loads(run(fixture("scans.csv"), "--json").stdout)
    assert r["format"] == "csv" and r["n_scans"] == 3 and r["n_ok"] == 1
    assert "do not match" in r["scans"][1]["reason"]
    assert "no valid return" in r["scans"][2]["reason"]
    assert r["scans"][1]["walls"] == [] and r["scans"][2]["doors"] == []


def test_corrupt_missing_files_and_bad_arguments():
    out = run(fixture("corrupt.log"))
    assert out.returncode == 2 and "not a text file" in out.stderr
    out = run(fixture("nothing_here.log"))
    assert out.returncode == 2 and "cannot open" in out.stderr
    assert run(fixture("room.log"), "--format", "bag").returncode == 2
    assert run(fixture("room.log"), "--door-min", "2", "--door-max", "1").returncode == 2
    assert run().returncode == 2
