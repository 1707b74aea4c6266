"""build_grid (the C++ CLI of the perception core) on small generated point files.

Skipped when the workspace with the tool is not built and sourced.
"""
import json
import subprocess

import numpy as np
import pytest

from workspace_tools import find_tool

TOOL = find_tool("build_grid")
pytestmark = pytest.mark.skipif(TOOL is None, reason="build_grid not built (source the workspace)")


def run(*args):
    return subprocess.run([TOOL, *map(str, args)], capture_output=True, text=True, timeout=300)


def room_cloud(seed=3, door=(1.0, 1.9)):
    """A 5 m x 4 m room, z up, walls 0.3-2.4 m with a door gap in the south wall, a sparse floor
    and a few stray points; the camera at (2.5, 2, 1.2)."""
    rng = np.random.default_rng(seed)
    walls = []
    for (x0, y0, x1, y1) in ((0, 0, 5, 0), (5, 0, 5, 4), (5, 4, 0, 4), (0, 4, 0, 0)):
        t = rng.uniform(0, 1, 1500)
        z = rng.uniform(0.3, 2.4, 1500)
        p = np.c_[x0 + t * (x1 - x0), y0 + t * (y1 - y0), z]
        if y0 == y1 == 0:
            p = p[(p[:, 0] < door[0]) | (p[:, 0] > door[1])]
        walls.append(p)
    floor = np.c_[rng.uniform(0.2, 4.8, 150), rng.uniform(0.2, 3.8, 150), np.zeros(150)]
    stray = np.c_[rng.uniform(1, 4, 5), rng.uniform(1, 3, 5), rng.uniform(0.5, 2, 5)]
    cloud = np.vstack(walls + [floor, stray])
    return cloud + rng.normal(0, 0.01, cloud.shape)


def write(path, points):
    np.savetxt(path, points, delimiter=",", fmt="%.5f")
    return path


def test_a_room_gives_a_map_server_grid_with_the_door_open(tmp_path):
    csv = write(tmp_path / "room.csv", room_cloud())
    out = run(csv, "--out", tmp_path / "room", "--up-axis", "z", "--camera", "2.5,2,1.2", "--json")
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    assert r["floor"]["found"] and r["floor"]["tilt_deg"] < 1.0 and abs(r["floor"]["d"]) < 0.05
    for stage in ("guard", "voxel", "floor", "density", "octree", "slice", "grid"):
        assert stage in r["stages_ms"]
    for ext in ("pgm", "yaml", "png"):
        assert (tmp_path / f"room.{ext}").stat().st_size > 0
    meta = dict(line.split(": ", 1) for line in (tmp_path / "room.yaml").read_text().splitlines())
    assert meta["image"] == "room.pgm" and float(meta["resolution"]) == pytest.approx(0.05)
    ox, oy = (float(v) for v in meta["origin"].strip("[]").split(",")[:2])
    with open(tmp_path / "room.pgm", "rb") as f:
        assert f.readline().strip() == b"P5"
        width, height = (int(v) for v in f.readline().split())
        assert int(f.readline()) == 255
        image = np.frombuffer(f.read(), np.uint8).reshape(height, width)[::-1]  # row 0: lowest y

    def cell(x, y):
        return image[int((y - oy) / 0.05), int((x - ox) / 0.05)]

    assert cell(4.0, 0.0) == 0        # a wall is occupied
    assert cell(2.5, 2.0) == 254      # the middle of the room is free
    assert cell(1.45, 0.0) != 0       # the door is not closed


def test_a_cloud_inside_the_floor_band_is_a_clear_error_not_an_empty_map(tmp_path):
    # A monocular map in SLAM units without --scale: a whole room 0.1 units tall.
    csv = write(tmp_path / "small.csv", room_cloud() * 0.05)
    out = run(csv, "--out", tmp_path / "small", "--up-axis", "z", "--json")
    assert out.returncode == 2
    assert "no grid to write" in out.stderr and "--scale" in out.stderr
    assert "no grid to write" in json.loads(out.stdout)["error"]
    assert not (tmp_path / "small.pgm").exists()


def test_a_floor_tilted_beyond_the_limit_is_reported_not_guessed(tmp_path):
    a = np.radians(30.0)
    rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    csv = write(tmp_path / "tilted.csv", room_cloud() @ rot.T)
    out = run(csv, "--out", tmp_path / "tilted", "--up-axis", "z")
    assert out.returncode == 2
    assert "no floor plane within 15" in out.stderr


@pytest.mark.parametrize("content", ["", "x,y\n1,2\n3,4\n", "not a point file at all\n\x00\x01"])
def test_bad_files_give_a_clear_error(tmp_path, content):
    bad = tmp_path / "bad.csv"
    bad.write_text(content)
    out = run(bad, "--out", tmp_path / "bad", "--up-axis", "z")
    assert out.returncode == 2
    assert out.stderr.startswith("build_grid: ") and "Assertion" not in out.stderr
    assert not (tmp_path / "bad.pgm").exists()


def test_non_finite_rows_are_dropped_and_counted(tmp_path):
    cloud = room_cloud()
    cloud[:20, 0] = np.nan
    cloud[20:25, 2] = np.inf
    csv = tmp_path / "nan.csv"
    np.savetxt(csv, cloud, delimiter=",", fmt="%.5f")
    out = run(csv, "--out", tmp_path / "nan", "--up-axis", "z", "--camera", "2.5,2,1.2", "--json")
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    assert r["n_non_finite"] == 25 and r["floor"]["found"]


def test_an_update_looks_at_the_moved_points_and_repeats_on_request(tmp_path):
    cloud = room_cloud()
    moved = cloud.copy()
    moved[:40] += np.random.default_rng(5).normal(0, 0.03, (40, 3))   # 40 wall points move
    first = write(tmp_path / "room.csv", cloud)
    second = write(tmp_path / "moved.csv", moved)
    out = run(first, "--out", tmp_path / "room", "--up-axis", "z", "--camera", "2.5,2,1.2",
              "--update", second, "--repeat-update", 2, "--json")
    assert out.returncode == 0, out.stderr
    update = json.loads(out.stdout)["update"]
    assert update["changed_points"] == 40
    assert update["full_rebuild"] is False
    assert update["recomputed_tiles"] < update["tiles"]
    assert len(update["repeated_ms"]) == 4 and all(t > 0 for t in update["repeated_ms"])


def test_repeated_rebuilds_are_timed_and_leave_the_outputs_as_they_were(tmp_path):
    csv = write(tmp_path / "room.csv", room_cloud())
    common = ["--up-axis", "z", "--camera", "2.5,2,1.2", "--json"]
    once = run(csv, "--out", tmp_path / "once", *common)
    again = run(csv, "--out", tmp_path / "again", *common, "--repeat-rebuild", 3)
    assert once.returncode == 0 and again.returncode == 0, once.stderr + again.stderr
    r_once, r_again = json.loads(once.stdout), json.loads(again.stdout)
    assert r_once["repeated_rebuild_ms"] == []
    assert len(r_again["repeated_rebuild_ms"]) == 3
    assert all(t > 0 for t in r_again["repeated_rebuild_ms"])
    assert r_again["grid"] == r_once["grid"]
    assert (tmp_path / "again.pgm").read_bytes() == (tmp_path / "once.pgm").read_bytes()
