"""The find_exit command-line tool: JSON form, plot, errors and exit status."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from sparse_nav.exit_finder.synthetic import Door, room_cloud, to_orbslam
from sparse_nav.pointfiles import write_points_csv
from sparse_nav.tools.find_exit import run

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
RECT = [(-3.0, -2.0), (3.0, -2.0), (3.0, 2.0), (-3.0, 2.0)]


@pytest.fixture(scope="module")
def room_file(tmp_path_factory):
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=(0.3, 0.2), clutter=100,
                           seed=21)
    path = str(tmp_path_factory.mktemp("exit") / "room.csv")
    write_points_csv(path, to_orbslam(xy))
    return path, doors[0]


def test_json_output_is_exactly_the_documented_form(room_file, capsys):
    path, door = room_file
    assert run([path, "--json", "--seed", "1"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert list(data) == ["exits", "method", "room_corners", "n_points_in", "n_points_used",
                          "runtime_s"]
    best = data["exits"][0]
    assert list(best) == ["x", "y", "score"]
    # x and z of the ORB-SLAM file, in its units.
    assert np.hypot(best["x"] - door[0], best["y"] - door[1]) < 0.3
    assert data["method"] == "ranked"


def test_text_output_plot_and_method(room_file, capsys, tmp_path):
    path, _ = room_file
    png = str(tmp_path / "exit.png")
    assert run([path, "--method", "seed", "--plot", png]) in (0, 1)
    out = capsys.readouterr().out
    assert "method: seed" in out and "room outline" in out
    with open(png, "rb") as handle:
        assert handle.read(8) == b"\x89PNG\r\n\x1a\n"


def test_a_two_column_file_is_a_clear_error(tmp_path, capsys):
    path = tmp_path / "flat.csv"
    path.write_text("".join(f"{i},{i % 7}\n" for i in range(100)))
    assert run([str(path), "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "flat.csv" in captured.err and "2 columns" in captured.err


def test_bad_clouds_and_files_exit_2_with_the_problem_named(tmp_path, capsys):
    few = tmp_path / "few.csv"
    few.write_text("0,0,0\n1,0,0\n0,0,1\n")
    assert run([str(few)]) == 2
    assert "a room needs at least" in capsys.readouterr().err
    line = tmp_path / "line.csv"
    line.write_text("".join(f"{i},0,{2 * i}\n" for i in range(100)))
    assert run([str(line), "--json"]) == 2
    assert "collinear" in capsys.readouterr().err
    assert run([str(tmp_path / "missing.csv")]) == 2
    assert "missing.csv" in capsys.readouterr().err
    assert run([str(line), "--seed", "-1"]) == 2
    with pytest.raises(SystemExit):
        run([str(line), "--method", "nonsense"])


def test_the_script_shim_runs(room_file):
    path, _ = room_file
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src"))
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "find_exit"), path,
                           "--json"], capture_output=True, text=True, env=env, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["exits"]
