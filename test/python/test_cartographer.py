"""Cartographer core: fragment names, file format, corrupt files, map switches and merges."""
import os

import numpy as np
import pytest

from sparse_nav.cartographer import (Cartographer, CartographerConfig, FragmentError,
                                     FragmentStore, auto_name, decode, encode, validate_name,
                                     voxel_unique)
from sparse_nav.slam_bridge import LOST, NEW_MAP, NOT_INITIALIZED, OK


def cloud(seed, n=200):
    return np.random.default_rng(seed).uniform(-3.0, 3.0, size=(n, 3))


@pytest.mark.parametrize("name", ["../x", "/etc/passwd", "a/b", "..", ".", "", ".hidden",
                                  "x" * 65, "a b", "a\nb", "a\x00b", "é", "x.frag", None, 3])
def test_hostile_names_are_refused(tmp_path, name):
    store = FragmentStore(str(tmp_path))
    with pytest.raises(FragmentError, match="name"):
        store.save(name, cloud(0))
    with pytest.raises(FragmentError, match="name"):
        store.load(name)
    assert os.listdir(tmp_path) == []


def test_good_names_stay_inside_map_dir(tmp_path):
    store = FragmentStore(str(tmp_path / "maps"))
    for name in ("a", "s001_map002", "Kitchen-2", "x" * 64):
        assert validate_name(name) == name
        path = store.save(name, cloud(1))
        assert os.path.dirname(path) == str(tmp_path / "maps")
    assert store.names() == sorted(["a", "s001_map002", "Kitchen-2", "x" * 64])


def test_round_trip_keeps_points_and_meta(tmp_path):
    store = FragmentStore(str(tmp_path))
    pts = cloud(2)
    store.save("f", pts, {"map_index": 3, "frame": "map"})
    loaded, meta = store.load("f")
    np.testing.assert_allclose(loaded, pts, atol=1e-5)
    assert meta == {"map_index": 3, "frame": "map"}
    store.save("empty", np.empty((0, 3)))
    assert store.load("empty")[0].shape == (0, 3)


def test_save_refuses_bad_points(tmp_path):
    store = FragmentStore(str(tmp_path))
    bad = cloud(3)
    bad[5, 1] = np.nan
    with pytest.raises(FragmentError, match="NaN"):
        store.save("f", bad)
    with pytest.raises(FragmentError, match="shape"):
        store.save("f", np.zeros((4, 2)))
    assert store.names() == []


def test_every_truncation_and_bit_flip_is_refused():
    data = encode(cloud(4, n=30), {"k": 1})
    for cut in range(len(data)):
        with pytest.raises(FragmentError):
            decode(data[:cut])
    rng = np.random.default_rng(0)
    for pos in rng.integers(0, len(data), size=300):
        flipped = bytearray(data)
        flipped[pos] ^= 1 << int(rng.integers(0, 8))
        with pytest.raises(FragmentError):
            decode(bytes(flipped))
    with pytest.raises(FragmentError, match="appended"):
        decode(data + b"\x00")


@pytest.mark.parametrize("content, message", [
    (b"", "no fragment header"), (b"garbage", "no fragment header"),
    (b"{not json}\n", "unreadable header"), (b'{"format": "other"}\n', "not a"),
    (b'{"format": "sparse_nav.fragment", "version": 99}\n', "version 99"),
    (b"\x89HDF\r\n\x1a\n", "unreadable header")])
def test_foreign_files_are_refused_with_a_clear_error(tmp_path, content, message):
    store = FragmentStore(str(tmp_path))
    (tmp_path / "bad.frag").write_bytes(content)
    with pytest.raises(FragmentError, match=message):
        store.load("bad")


def test_symlink_out_of_map_dir_is_refused(tmp_path):
    outside = tmp_path / "outside.frag"
    outside.write_bytes(encode(cloud(5)))
    maps = tmp_path / "maps"
    store = FragmentStore(str(maps))
    os.symlink(outside, maps / "link.frag")
    with pytest.raises(FragmentError, match="cannot open"):
        store.load("link")


def test_missing_fragment_is_a_clear_error(tmp_path):
    with pytest.raises(FragmentError, match="no such fragment"):
        FragmentStore(str(tmp_path)).load("nothing")


def make(tmp_path, **kwargs):
    return Cartographer(CartographerConfig(map_dir=str(tmp_path), **kwargs))


def test_first_map_is_index_zero(tmp_path):
    carto = make(tmp_path)
    assert carto.on_slam_state(NOT_INITIALIZED, 0, 0.0) == []
    assert carto.on_slam_state(OK, 0, 1.0) == ["following SLAM map 0 as s001_map000"]
    assert carto.on_cloud(cloud(1), 2.0)
    assert carto.flush(3.0) == ["s001_map000"]


def test_new_map_keeps_the_old_fragment(tmp_path):
    carto = make(tmp_path)
    assert carto.on_slam_state(NOT_INITIALIZED, 0, 0.0) == []
    assert carto.on_cloud(cloud(0), 1.0) is False   # no map yet
    carto.on_slam_state(OK, 1, 2.0)
    assert carto.on_cloud(cloud(1), 3.0)
    carto.on_slam_state(LOST, 1, 4.0)
    events = carto.on_slam_state(NEW_MAP, 2, 5.0)
    assert "kept s001_map001" in events[0]
    pts, meta = carto.store.load("s001_map001")
    np.testing.assert_allclose(pts, cloud(1), atol=1e-5)
    assert meta["map_index"] == 1 and meta["session"] == 1
    # A cloud stamped before the switch belongs to the old map and is dropped.
    assert carto.on_cloud(cloud(9), 4.5) is False
    assert carto.on_cloud(cloud(2), 6.0)
    assert carto.flush(7.0) == ["s001_map002"]
    np.testing.assert_allclose(carto.store.load("s001_map001")[0], cloud(1), atol=1e-5)


def test_merge_combines_into_the_earlier_fragment(tmp_path):
    carto = make(tmp_path, merge_voxel_m=0.01)
    carto.on_slam_state(OK, 1, 0.0)
    carto.on_cloud(cloud(1), 1.0)
    carto.on_slam_state(NEW_MAP, 2, 2.0)
    carto.on_cloud(cloud(2), 3.0)
    carto.flush(3.5)
    events = carto.on_slam_state(NEW_MAP, 1, 4.0)
    assert "merged map 2 into map 1" in events[0]
    assert carto.store.names() == ["s001_map001"]
    pts, meta = carto.store.load("s001_map001")
    assert len(pts) == 400
    assert meta["merged_from"] == ["s001_map002"]
    assert carto.current.map_index == 1
    # The wrapper's next cloud of map 1 need not hold map 2's points: they stay in the fragment.
    carto.on_cloud(cloud(1)[:100], 5.0)
    carto.flush(6.0)
    assert len(carto.store.load("s001_map001")[0]) == 300


def test_saves_as_it_goes_at_most_every_period(tmp_path):
    carto = make(tmp_path, save_period_s=5.0)
    carto.on_slam_state(OK, 1, 0.0)
    carto.on_cloud(cloud(1), 0.5)
    assert carto.save_due(1.0) == ["s001_map001"]
    carto.on_cloud(cloud(2), 2.0)
    assert carto.save_due(3.0) == []          # within the period
    assert carto.save_due(6.0) == ["s001_map001"]
    assert carto.save_due(12.0) == []         # nothing changed
    np.testing.assert_allclose(carto.store.load("s001_map001")[0], cloud(2), atol=1e-5)


def test_reload_reports_corrupt_files_and_starts_a_new_session(tmp_path):
    carto = make(tmp_path)
    carto.on_slam_state(OK, 1, 0.0)
    carto.on_cloud(cloud(1), 1.0)
    carto.flush(1.0)
    carto.save_as("kitchen", 1.0)
    (tmp_path / "broken.frag").write_bytes(encode(cloud(3))[:-7])
    again = make(tmp_path)
    assert again.reload() == ["kitchen", "s001_map001"]
    assert "truncated" in again.load_errors["broken"]
    assert again.session == 2
    again.on_slam_state(OK, 1, 0.0)
    assert again.current.name == auto_name(2, 1) == "s002_map001"
    listing = {name: (n, err) for name, n, err in again.list()}
    assert listing["kitchen"] == (200, "")
    assert listing["broken"][0] is None and "truncated" in listing["broken"][1]


def test_bad_clouds_are_refused_and_keep_the_last_good_one(tmp_path):
    carto = make(tmp_path, max_points=1000)
    carto.on_slam_state(OK, 1, 0.0)
    carto.on_cloud(cloud(1), 1.0)
    bad = cloud(2)
    bad[0, 0] = np.inf
    for points, message in ((bad, "NaN or Inf"), (np.zeros((5, 2)), "shape"),
                            (np.zeros((1001, 3)), "max_points")):
        with pytest.raises(FragmentError, match=message):
            carto.on_cloud(points, 2.0)
    np.testing.assert_allclose(carto.current.points, cloud(1))
    with pytest.raises(FragmentError, match="name"):
        carto.save_as("../escape", 3.0)


def test_voxel_unique_keeps_one_point_per_voxel():
    pts = np.array([[0.01, 0.01, 0.01], [0.02, 0.02, 0.02], [0.2, 0.0, 0.0]])
    np.testing.assert_array_equal(voxel_unique(pts, 0.05), pts[[0, 2]])


def test_config_is_validated(tmp_path):
    for kwargs in ({"save_period_s": 0.0}, {"merge_voxel_m": -1.0}, {"max_points": 0}):
        with pytest.raises(ValueError):
            make(tmp_path, **kwargs)
