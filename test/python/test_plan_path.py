"""plan_path CLI and the map readers on the hand-made maps of test/fixtures/planning (no master)."""
import json
import math
import os

import numpy as np
import pytest

from sparse_nav import _planning as planning
from sparse_nav.navigation.maps import (MapFileError, read_map_server, read_movingai_map,
                                        read_scenarios)
from sparse_nav.tools.plan_path import run

FIXTURES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "fixtures", "planning")
MAP = os.path.join(FIXTURES, "small.map")
SCEN = os.path.join(FIXTURES, "small.map.scen")
ROOM = os.path.join(FIXTURES, "room.yaml")


def cli(capsys, *argv):
    status = run(list(argv))
    out = capsys.readouterr()
    return status, out.out, out.err


def test_readers():
    grid = read_movingai_map(MAP)
    assert grid.shape == (5, 7)
    assert grid[1, 1:6].tolist() == [100] * 5 and grid[3, 2] == 100 and grid[0].sum() == 0
    scen = read_scenarios(SCEN)
    assert [s.optimal for s in scen] == [6.0, 4.0, 8.0, 6.82842712]
    assert scen[3].start == (0, 4) and scen[3].goal == (6, 2) and scen[3].bucket == 1
    room = read_map_server(ROOM)
    g = room.geometry
    assert (g.width, g.height, g.resolution, g.origin) == (20, 10, 0.1, (-1.0, -0.5, 0.0))
    # Image rows run down, map rows up: the wall (image rows 0-7) is in map rows 2-9.
    assert room.data[2:, 10].tolist() == [100] * 8 and room.data[:2, 10].tolist() == [0, 0]
    assert (room.data[7:, 18:] == -1).all() and room.data[0, 0] == 0
    assert g.world_to_cell(-0.95, -0.45) == (0, 0)
    assert g.cell_to_world(19, 9) == pytest.approx((0.95, 0.45))


@pytest.mark.parametrize("planner", ["dstar_lite", "astar"])
def test_movingai_json_matches_the_listed_optimum(capsys, planner):
    status, out, _ = cli(capsys, "--movingai-map", MAP, "--scen", SCEN, "--planner", planner,
                         "--json")
    assert status == 0
    result = json.loads(out)
    assert result["planner"] == planner
    rows = result["results"]
    assert [r["index"] for r in rows] == [0, 1, 2, 3]
    for r in rows:
        assert set(r) == {"index", "length", "optimal", "plan_ms", "replan_ms", "replan_length",
                          "replan_check_length"}
        assert r["length"] == pytest.approx(r["optimal"], rel=1e-6)
        assert r["plan_ms"] >= 0
        assert r["replan_length"] == pytest.approx(r["replan_check_length"], rel=1e-9)
        assert r["replan_length"] >= r["length"] - 1e-9
    # Scenario 2: blocking the middle of either 8-long route leaves the other one.
    assert rows[2]["replan_length"] == pytest.approx(8.0)
    # Scenario 0 runs along the open top row: blocking its middle costs a detour.
    assert rows[0]["replan_length"] > 6.0


def test_movingai_rrt_limit_and_sample(capsys):
    status, out, _ = cli(capsys, "--movingai-map", MAP, "--scen", SCEN, "--planner", "rrt",
                         "--limit", "2", "--json", "--seed", "5")
    assert status == 0
    rows = json.loads(out)["results"]
    assert [r["index"] for r in rows] == [0, 1]
    for r in rows:
        assert r["length"] >= r["optimal"] * (1 - 1e-9)
    status, out, _ = cli(capsys, "--movingai-map", MAP, "--scen", SCEN, "--sample", "2", "--json")
    assert [r["index"] for r in json.loads(out)["results"]] == [0, 3]
    status, out, _ = cli(capsys, "--movingai-map", MAP, "--scen", SCEN, "--limit", "1")
    assert status == 0 and "6.0000" in out


def test_map_server_plan_goes_through_the_gap(capsys):
    status, out, _ = cli(capsys, "--map", ROOM, "--start", "-0.45", "0.25", "--goal", "0.55", "0.25",
                         "--json")
    assert status == 0
    result = json.loads(out)
    path = result["path"]
    assert path[0] == pytest.approx([-0.45, 0.25]) and path[-1] == pytest.approx([0.55, 0.25])
    # The wall at x = 0.0..0.1 is open below y = -0.3 only.
    assert min(y for _, y in path) < -0.3
    assert result["length_m"] == pytest.approx(sum(math.dist(a, b) for a, b in zip(path, path[1:])))
    room = read_map_server(ROOM)
    grid = planning.Grid(room.data)
    cells = [room.geometry.world_to_cell(x, y) for x, y in path]
    assert all(planning.line_of_sight(grid, a, b) for a, b in zip(cells, cells[1:]))
    status, out, _ = cli(capsys, "--map", ROOM, "--start", "-0.45", "0.25", "--goal", "0.55", "0.25",
                         "--robot-radius-m", "0.25", "--json")
    assert status == 1 and json.loads(out)["path"] == []  # inflation closes the gap
    status, out, _ = cli(capsys, "--map", ROOM, "--start", "-0.5", "0.3", "--goal", "0.9", "0.4",
                         "--unknown-policy", "blocked")
    assert status == 1 and "no path" in out


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return str(path)


def test_bad_files_give_clear_errors(capsys, tmp_path):
    cases = [
        (["--movingai-map", str(tmp_path / "none.map"), "--scen", SCEN], "no such file"),
        (["--movingai-map", write(tmp_path, "a.map", "type grid\nheight 1\nwidth 1\nmap\n.\n"),
          "--scen", SCEN], "type octile"),
        (["--movingai-map", write(tmp_path, "b.map", "type octile\nheight 3\nwidth 2\nmap\n..\n"),
          "--scen", SCEN], "fewer than 3 rows"),
        (["--movingai-map", write(tmp_path, "c.map", b"\xff\xfe\x00"), "--scen", SCEN],
         "not a text file"),
        (["--movingai-map", MAP, "--scen", write(tmp_path, "a.scen", "0\tx\t1\n")], "version"),
        (["--movingai-map", MAP, "--scen", write(tmp_path, "b.scen", "version 1\n0\tx\t7\t5\n")],
         "expected 9 fields"),
        (["--movingai-map", MAP, "--scen", write(tmp_path, "c.scen",
                                                 "version 1\n0\tx\t9\t9\t0\t0\t1\t1\t1.4\n")],
         "9 x 9 map"),
        (["--movingai-map", MAP, "--scen", write(tmp_path, "d.scen",
                                                 "version 1\n0\tx\t7\t5\t0\t0\t9\t1\t1\n")],
         "outside the map"),
        (["--movingai-map", MAP], "needs --scen"),
        (["--movingai-map", MAP, "--scen", SCEN, "--limit", "0"], "--limit"),
        (["--map", ROOM, "--start", "0", "0"], "needs --start"),
        (["--map", ROOM, "--start", "5", "0", "--goal", "0", "0"], "outside the map"),
        (["--map", ROOM, "--start", "nan", "0", "--goal", "0", "0"], "finite"),
        (["--map", write(tmp_path, "a.yaml", "image: [unclosed\n"), "--start", "0", "0",
          "--goal", "0", "0"], "invalid YAML"),
        (["--map", write(tmp_path, "b.yaml", "image: room.pgm\n"), "--start", "0", "0",
          "--goal", "0", "0"], "missing or malformed key"),
        (["--map", write(tmp_path, "c.yaml", "image: nothere.pgm\nresolution: 0.1\n"
                                             "origin: [0, 0, 0]\n"), "--start", "0", "0",
          "--goal", "0", "0"], "no such image"),
        (["--map", write(tmp_path, "d.yaml", "image: junk.pgm\nresolution: 0.1\n"
                                             "origin: [0, 0, 0]\n"), "--start", "0", "0",
          "--goal", "0", "0"], "not an image"),
        (["--map", write(tmp_path, "e.yaml", "image: room.pgm\nresolution: -1\n"
                                             "origin: [0, 0, 0]\n"), "--start", "0", "0",
          "--goal", "0", "0"], "resolution"),
    ]
    write(tmp_path, "junk.pgm", b"P5\n garbage")
    for argv, message in cases:
        status, out, err = cli(capsys, *argv)
        assert status == 2, (argv, out, err)
        assert message in err and err.startswith("plan_path: error:"), (argv, err)


def test_movingai_data_when_present(capsys):
    """Every Moving AI map with its .scen: the first and the last (hardest) scenario match the
    listed optimum, and the incremental replan the fresh search (skips without the data)."""
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared",
                        "data", "movingai")
    maps = sorted(os.path.join(d, f) for d, _, fs in os.walk(root) for f in fs
                  if f.endswith(".map") and os.path.exists(os.path.join(d, f + ".scen")))
    if not maps:
        pytest.skip("Moving AI data absent")
    for path in maps:
        status, out, _ = cli(capsys, "--movingai-map", path, "--scen", path + ".scen",
                             "--sample", "2", "--json")
        rows = json.loads(out)["results"]
        assert status == 0 and len(rows) == 2, path
        assert rows[-1]["index"] == len(read_scenarios(path + ".scen")) - 1
        for r in rows:
            assert r["length"] == pytest.approx(r["optimal"], rel=1e-6), (path, r)
            if r["replan_length"] is not None:
                assert r["replan_length"] == pytest.approx(r["replan_check_length"], rel=1e-9)
        assert np.isfinite([r["plan_ms"] for r in rows]).all()
