"""Tests of sparse_nav.pointfiles (no ROS): every format and variant on small fixtures."""
import os
import struct
import sys

import numpy as np
import pytest

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO_ROOT, "src"))

from sparse_nav import pointfiles  # noqa: E402
from sparse_nav.pointfiles import (  # noqa: E402
    PointFileError, read_points, read_points_with_info, write_points_csv)

DATA = os.path.join(REPO_ROOT, "..", "shared", "data")
CLOUD_EXTENSIONS = (".csv", ".txt", ".xyz", ".ply", ".pcd")

POINTS = np.array([[1.0, 2.0, 3.0], [-4.5, 0.25, 6.0], [7.0, -8.0, 0.125]])


def write(tmp_path, name, content):
    """Write str or bytes to tmp_path/name and return the path as str."""
    path = tmp_path / name
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    return str(path)


def assert_error(path, *fragments, **kwargs):
    """read_points raises PointFileError naming the file and containing each fragment."""
    with pytest.raises(PointFileError) as caught:
        read_points(path, **kwargs)
    message = str(caught.value)
    assert path in message
    for fragment in fragments:
        assert fragment in message, message
    return message




def test_csv_with_trailing_empty_fields(tmp_path):
    path = write(tmp_path, "cloud.csv", "1,2,3,,,\n-4.5,0.25,6,,,\n7,-8,0.125,,,\n")
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_csv_sixteen_columns_pose_ignored(tmp_path):
    pose = ",".join(["0.5"] * 13)
    path = write(tmp_path, "pose.csv", "".join(f"{x},{y},{z},{pose}\n" for x, y, z in POINTS))
    points, info = read_points_with_info(path)
    np.testing.assert_array_equal(points, POINTS)
    assert info["n_columns"] == 16 and info["extra_columns"] == 13


def test_whitespace_separated_txt(tmp_path):
    path = write(tmp_path, "map.txt", " 1 2 3\n-4.5\t0.25   6\n\t7  -8\t\t0.125  \n")
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_semicolon_and_mixed_separators(tmp_path):
    path = write(tmp_path, "semi.xyz", "1;2;3\n-4.5 ; 0.25;6\n7, -8,\t0.125\n")
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_header_line_comments_and_blank_lines(tmp_path):
    text = ("# saved by ORB-SLAM\n\nx,y,z,qx,qy\n1,2,3,0,0\n\n# pause\n"
            "-4.5,0.25,6,0,0\n7,-8,0.125,0,0\n\n")
    path = write(tmp_path, "header.csv", text)
    points, info = read_points_with_info(path)
    np.testing.assert_array_equal(points, POINTS)
    assert info["header"] == "x,y,z,qx,qy"
    assert info["n_rows"] == 3


def test_crlf_and_bom(tmp_path):
    data = b"\xef\xbb\xbfx,y,z\r\n1,2,3\r\n-4.5,0.25,6\r\n7,-8,0.125\r\n"
    path = write(tmp_path, "win.csv", data)
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_ragged_rows_take_first_three(tmp_path):
    path = write(tmp_path, "ragged.csv", "1,2,3\n-4.5,0.25,6,9,9,9,9\n7,-8,0.125,1\n")
    points, info = read_points_with_info(path)
    np.testing.assert_array_equal(points, POINTS)
    assert info["n_columns"] == 7 and info["extra_columns"] == 4


def test_non_numeric_or_empty_extra_columns_are_ignored(tmp_path):
    path = write(tmp_path, "labels.csv", "1,2,3,,chair\n-4.5,0.25,6,,table\n7,-8,0.125,x,\n")
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_nan_rows_dropped_and_counted(tmp_path):
    text = "1,2,3\nnan,1,2\n-4.5,0.25,6\n4,inf,5\n7,-8,0.125\n1,2,-Inf\n"
    path = write(tmp_path, "nan.csv", text)
    points, info = read_points_with_info(path)
    np.testing.assert_array_equal(points, POINTS)
    assert info["n_rows"] == 6 and info["n_dropped_non_finite"] == 3
    kept = read_points(path, drop_non_finite=False)
    assert kept.shape == (6, 3) and np.count_nonzero(~np.isfinite(kept).all(axis=1)) == 3


def test_all_rows_non_finite_is_an_error(tmp_path):
    assert_error(write(tmp_path, "allnan.csv", "nan,nan,nan\n1,inf,2\n"), "no points")


def test_short_line_names_the_line(tmp_path):
    path = write(tmp_path, "cloud.csv", "1,2,3\n4,5,6\n7,8\n9,10,11\n")
    assert_error(path, "line 3 has 2 numeric columns, a point needs 3")


def test_short_line_after_header_and_comments_keeps_file_line_numbers(tmp_path):
    path = write(tmp_path, "cloud.txt", "# c\nx y z\n\n1 2 3\n4 5\n")
    assert_error(path, "line 5 has 2 numeric columns")


def test_short_line_with_a_word_is_reported_as_not_a_number(tmp_path):
    assert_error(write(tmp_path, "word.csv", "1,2,3\nabc,1\n"), "line 2", "column 1 ('abc')")


def test_two_column_file(tmp_path):
    assert_error(write(tmp_path, "flat.csv", "1,2\n3,4\n5,6\n"),
                 "has 2 columns, a point needs 3")


def test_two_column_file_with_header(tmp_path):
    assert_error(write(tmp_path, "flat.csv", "x,y\n1,2\n3,4\n"), "has 2 columns, a point needs 3")


def test_non_numeric_value_names_line_and_column(tmp_path):
    path = write(tmp_path, "bad.csv", "1,2,3\n4,5,6\n7,abc,9\n")
    assert_error(path, "line 3", "column 2", "'abc'", "not a number")


def test_second_non_numeric_line_is_not_a_header(tmp_path):
    assert_error(write(tmp_path, "twice.csv", "x,y,z\n1,2,3\nx,y,z\n4,5,6\n"),
                 "line 3", "not a number")


def test_empty_field_inside_xyz_is_an_error(tmp_path):
    assert_error(write(tmp_path, "hole.csv", "1,2,3\n4,,6,7\n"), "line 2", "column 2 is empty")


def test_empty_file(tmp_path):
    assert_error(write(tmp_path, "empty.csv", ""), "no points")


def test_comments_only_file(tmp_path):
    assert_error(write(tmp_path, "comments.txt", "# nothing\n\n   \n"), "no points")


def test_png_is_not_a_point_cloud(tmp_path):
    png = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x00\x10" + bytes(range(256))
    assert_error(write(tmp_path, "notacloud.png", png),
                 "not a point cloud (unknown format, first bytes")


def test_random_binary_is_not_a_point_cloud(tmp_path):
    noise = np.random.default_rng(7).integers(0, 256, size=4096, dtype=np.uint8).tobytes()
    assert_error(write(tmp_path, "noise.bin", noise), "not a point cloud (unknown format")


def test_chunked_reading_keeps_line_numbers(tmp_path, monkeypatch):
    # Tiny chunks make every few lines a separate numpy pass, as in a large file.
    monkeypatch.setattr(pointfiles, "_CHUNK_BYTES", 16)
    rows = [f"{i},{i + 0.5},{-i},7,8" for i in range(200)]
    good = write(tmp_path, "good.csv", "x,y,z,a,b\n" + "\n".join(rows) + "\n")
    expected = np.array([[i, i + 0.5, -i] for i in range(200)], dtype=float)
    np.testing.assert_array_equal(read_points(good), expected)
    rows[150] = "1,2"
    bad = write(tmp_path, "bad.csv", "x,y,z,a,b\n" + "\n".join(rows) + "\n")
    assert_error(bad, "line 152 has 2 numeric columns")


def test_fast_and_exact_text_readers_agree():
    # The vectorised reader must give what the line-by-line reader gives, or defer to it.
    rng = np.random.default_rng(1234)
    separators = [",", ";", " ", "\t", ", ", "  "]
    for _ in range(300):
        lines = []
        for _ in range(rng.integers(1, 12)):
            kind = rng.random()
            if kind < 0.08:
                lines.append(rng.choice(["", "   ", "# comment, 1,2", ",,,"]))
                continue
            n = int(rng.integers(1, 8)) if kind < 0.15 else int(rng.integers(3, 8))
            values = [str(v) for v in np.round(rng.normal(size=n) * 10, int(rng.integers(0, 5)))]
            if rng.random() < 0.05:
                values[int(rng.integers(0, n))] = rng.choice(["nan", "inf", "abc", "1-2", "",
                                                              "x y"])
            sep = str(rng.choice(separators))
            tail = "" if rng.random() < 0.7 else sep.strip() * int(rng.integers(1, 3))
            lines.append(sep.join(values) + tail)
        body = ("\n".join(lines) + ("\n" if rng.random() < 0.5 else "")).encode()
        try:
            exact = pointfiles._read_text_exact("f", body)
        except PointFileError as error:
            exact = str(error)
        try:
            fast = pointfiles._read_text_fast("f", body)
        except pointfiles._NotATable:
            continue
        except PointFileError as error:
            fast = str(error)
        if isinstance(exact, str) or isinstance(fast, str):
            assert fast == exact, body
        else:
            np.testing.assert_array_equal(fast[0], exact[0], err_msg=repr(body))
            assert fast[1] == exact[1], body




def ply_header(encoding, elements):
    """PLY header bytes; elements are (name, count, [property lines])."""
    lines = ["ply", f"format {encoding} 1.0", "comment made by test_pointfiles"]
    for name, count, props in elements:
        lines.append(f"element {name} {count}")
        lines.extend(f"property {p}" for p in props)
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode()


VERTEX_PROPS = ["float x", "float y", "float z", "uchar red", "uchar green", "uchar blue",
                "double quality"]
FACE_PROPS = ["list uchar int vertex_indices"]


def binary_ply(order, truncate=0):
    """A binary PLY with colour and quality per vertex and two faces after the vertices."""
    dtype = np.dtype([("x", order + "f4"), ("y", order + "f4"), ("z", order + "f4"),
                      ("r", "u1"), ("g", "u1"), ("b", "u1"), ("q", order + "f8")])
    table = np.zeros(len(POINTS), dtype=dtype)
    table["x"], table["y"], table["z"] = POINTS.T
    table["r"], table["q"] = 200, 0.75
    faces = b"".join(struct.pack(order + "B3i", 3, *tri) for tri in ((0, 1, 2), (2, 1, 0)))
    encoding = "binary_little_endian" if order == "<" else "binary_big_endian"
    header = ply_header(encoding, [("vertex", len(POINTS), VERTEX_PROPS),
                                   ("face", 2, FACE_PROPS)])
    data = header + table.tobytes() + faces
    return data[:len(data) - truncate] if truncate else data


def test_ply_ascii_with_extra_properties_and_faces(tmp_path):
    rows = "".join(f"{x} {y} {z} 255 0 10 0.5\n" for x, y, z in POINTS)
    data = ply_header("ascii", [("vertex", 3, VERTEX_PROPS), ("face", 1, FACE_PROPS)]) \
        + rows.encode() + b"3 0 1 2\n"
    points, info = read_points_with_info(write(tmp_path, "a.ply", data))
    np.testing.assert_array_equal(points, POINTS)
    assert info["format"] == "ply" and info["encoding"] == "ascii"
    assert info["n_columns"] == 7 and info["extra_columns"] == 4


def test_ply_ascii_xyz_not_first_and_element_before_vertex(tmp_path):
    header = ply_header("ascii", [("camera", 2, ["float fx", "float fy"]),
                                  ("vertex", 3, ["int32 id", "double z", "double y",
                                                 "double x"])])
    rows = "".join(f"{i} {z} {y} {x}\n" for i, (x, y, z) in enumerate(POINTS))
    path = write(tmp_path, "order.ply", header + b"500 500\n400 400\n" + rows.encode())
    np.testing.assert_array_equal(read_points(path), POINTS)


@pytest.mark.parametrize("order", ["<", ">"])
def test_ply_binary_with_extra_properties_and_faces(tmp_path, order):
    points, info = read_points_with_info(write(tmp_path, "b.ply", binary_ply(order)))
    np.testing.assert_array_equal(points, POINTS)
    assert info["encoding"] == ("binary_little_endian" if order == "<" else "binary_big_endian")


@pytest.mark.parametrize("ply_type,code", [("uchar", "u1"), ("int16", "i2"), ("int", "i4"),
                                           ("uint32", "u4"), ("float64", "f8"),
                                           ("double", "f8"), ("char", "i1")])
def test_ply_binary_integer_and_alias_types(tmp_path, ply_type, code):
    values = np.array([[1, 2, 3], [4, 5, 6]])
    table = values.astype(">" + code)
    header = ply_header("binary_big_endian",
                        [("vertex", 2, [f"{ply_type} x", f"{ply_type} y", f"{ply_type} z"])])
    points = read_points(write(tmp_path, "t.ply", header + table.tobytes()))
    np.testing.assert_array_equal(points, values.astype(float))
    assert points.dtype == np.float64


def test_ply_binary_list_element_before_vertex(tmp_path):
    header = ply_header("binary_little_endian",
                        [("face", 2, FACE_PROPS), ("vertex", 3, ["float x", "float y",
                                                                 "float z"])])
    faces = struct.pack("<B3iB4i", 3, 0, 1, 2, 4, 0, 1, 2, 0)
    path = write(tmp_path, "lists.ply", header + faces + POINTS.astype("<f4").tobytes())
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_ply_vertex_with_list_property(tmp_path):
    props = ["float x", "list uchar float tags", "float y", "float z"]
    body = b"".join(struct.pack("<fB", x, 2) + struct.pack("<2f", 9, 9) + struct.pack("<2f", y, z)
                    for x, y, z in POINTS)
    path = write(tmp_path, "vlist.ply",
                 ply_header("binary_little_endian", [("vertex", 3, props)]) + body)
    np.testing.assert_array_equal(read_points(path), POINTS)
    rows = "".join(f"{x} 1 9 {y} {z}\n" for x, y, z in POINTS)
    path = write(tmp_path, "vlist_ascii.ply", ply_header("ascii", [("vertex", 3, props)])
                 + rows.encode())
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_ply_detected_by_content_not_extension(tmp_path):
    path = write(tmp_path, "cloud.bin", binary_ply("<"))
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_ply_truncated_binary(tmp_path):
    path = write(tmp_path, "cut.ply", binary_ply("<")[:-40])
    assert_error(path, "binary_little_endian vertex data is truncated", "of 3 vertices")


def test_ply_truncated_ascii(tmp_path):
    data = ply_header("ascii", [("vertex", 3, ["float x", "float y", "float z"])]) + b"1 2 3\n"
    assert_error(write(tmp_path, "cut.ply", data), "truncated", "1 of 3 vertex rows")


def test_ply_without_xyz(tmp_path):
    header = ply_header("binary_big_endian", [("vertex", 1, ["float a", "float b"])])
    assert_error(write(tmp_path, "x.ply", header + bytes(8)),
                 "binary_big_endian vertex element has no x/y/z properties")


def test_ply_without_z(tmp_path):
    header = ply_header("ascii", [("vertex", 1, ["float x", "float y"])])
    assert_error(write(tmp_path, "noz.ply", header + b"1 2\n"),
                 "ascii vertex element has no z property")


def test_ply_without_end_header(tmp_path):
    assert_error(write(tmp_path, "open.ply", b"ply\nformat ascii 1.0\nelement vertex 1\n"),
                 "no end_header")


def test_ply_extension_without_ply_header(tmp_path):
    assert_error(write(tmp_path, "fake.ply", "1 2 3\n"), "not a PLY file")




def pcd_header(fields, sizes, types_, counts, n, data, width=None, points=True):
    lines = ["# .PCD v0.7 - Point Cloud Data file format", "VERSION 0.7",
             "FIELDS " + " ".join(fields), "SIZE " + " ".join(map(str, sizes)),
             "TYPE " + " ".join(types_), "COUNT " + " ".join(map(str, counts)),
             f"WIDTH {n if width is None else width}", "HEIGHT 1",
             "VIEWPOINT 0 0 0 1 0 0 0"]
    if points:
        lines.append(f"POINTS {n}")
    lines.append(f"DATA {data}")
    return ("\n".join(lines) + "\n").encode()


def test_pcd_ascii_with_rgb(tmp_path):
    header = pcd_header(["x", "y", "z", "rgb"], [4] * 4, "FFFF", [1] * 4, 3, "ascii")
    rows = "".join(f"{x} {y} {z} 4.2108e+06\n" for x, y, z in POINTS)
    points, info = read_points_with_info(write(tmp_path, "a.pcd", header + rows.encode()))
    np.testing.assert_array_equal(points, POINTS)
    assert info["format"] == "pcd" and info["encoding"] == "ascii"
    assert info["n_columns"] == 4 and info["extra_columns"] == 1


def test_pcd_ascii_fields_in_other_order_width_only(tmp_path):
    header = pcd_header(["intensity", "z", "x", "y"], [4] * 4, "FFFF", [1] * 4, 3, "ascii",
                        points=False)
    rows = "".join(f"0.5 {z} {x} {y}\n" for x, y, z in POINTS)
    np.testing.assert_array_equal(read_points(write(tmp_path, "o.pcd", header + rows.encode())),
                                  POINTS)


def pcd_binary_body(with_nan=False):
    """Rows of x y z rgb normal(3) _ with a double x and a 3-count normal field."""
    dtype = np.dtype([("x", "<f8"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<u4"),
                      ("normal", "<f4", (3,)), ("_", "u1")])
    pts = np.vstack([POINTS, [[np.nan, np.nan, np.nan]]]) if with_nan else POINTS
    table = np.zeros(len(pts), dtype=dtype)
    table["x"], table["y"], table["z"] = pts.T
    table["rgb"] = 0x00FF8000
    table["normal"] = [0, 0, 1]
    header = pcd_header(["x", "y", "z", "rgb", "normal", "_"], [8, 4, 4, 4, 4, 1],
                        ["F", "F", "F", "U", "F", "U"], [1, 1, 1, 1, 3, 1], len(pts), "binary")
    return header + table.tobytes()


def test_pcd_binary_with_rgb_and_nan(tmp_path):
    points, info = read_points_with_info(write(tmp_path, "b.pcd", pcd_binary_body(True)))
    np.testing.assert_array_equal(points, POINTS)
    assert info["encoding"] == "binary" and info["n_dropped_non_finite"] == 1
    assert info["n_columns"] == 8


def test_pcd_binary_truncated(tmp_path):
    assert_error(write(tmp_path, "cut.pcd", pcd_binary_body()[:-5]), "truncated", "2 of 3")


def test_pcd_binary_compressed_refused(tmp_path):
    header = pcd_header(["x", "y", "z"], [4] * 3, "FFF", [1] * 3, 3, "binary_compressed")
    assert_error(write(tmp_path, "c.pcd", header + bytes(40)), "binary_compressed",
                 "not supported")


def test_pcd_without_z(tmp_path):
    header = pcd_header(["x", "y", "rgb"], [4] * 3, "FFF", [1] * 3, 1, "ascii")
    assert_error(write(tmp_path, "noz.pcd", header + b"1 2 3\n"), "no z field")


def test_pcd_points_disagree_with_width(tmp_path):
    header = pcd_header(["x", "y", "z"], [4] * 3, "FFF", [1] * 3, 3, "ascii", width=2)
    assert_error(write(tmp_path, "w.pcd", header + b"1 2 3\n4 5 6\n7 8 9\n"), "WIDTH*HEIGHT")


def test_pcd_ascii_row_count_mismatch(tmp_path):
    header = pcd_header(["x", "y", "z"], [4] * 3, "FFF", [1] * 3, 3, "ascii")
    assert_error(write(tmp_path, "short.pcd", header + b"1 2 3\n4 5 6\n"), "3 points",
                 "2 rows")


def test_pcd_ascii_bad_value_names_line(tmp_path):
    header = pcd_header(["x", "y", "z"], [4] * 3, "FFF", [1] * 3, 2, "ascii")
    assert_error(write(tmp_path, "bad.pcd", header + b"1 2 3\n4 oops 6\n"), "line 13",
                 "'oops' is not a number")


@pytest.mark.filterwarnings("error")
def test_corrupted_files_raise_only_point_file_errors(tmp_path):
    # Seeded byte flips, cuts and insertions in valid files of every format.
    seeds = [binary_ply("<"), binary_ply(">"), pcd_binary_body(True),
             ply_header("ascii", [("vertex", 2, VERTEX_PROPS), ("face", 1, FACE_PROPS)])
             + b"1 2 3 255 0 10 0.5\n4 5 6 1 1 1 1\n3 0 1 1\n",
             pcd_header(["x", "y", "z", "rgb"], [4] * 4, "FFFF", [1] * 4, 2, "ascii")
             + b"1 2 3 4\n5 6 7 8\n",
             b"x,y,z\n1,2,3,,\n4,5,6,7\n"]
    rng = np.random.default_rng(5)
    path = str(tmp_path / "fuzz")
    for i in range(600):
        data = bytearray(seeds[i % len(seeds)])
        op = i % 3
        if op == 0:
            data[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
        elif op == 1:
            data = data[:int(rng.integers(0, len(data)))]
        else:
            data.insert(int(rng.integers(0, len(data))), int(rng.choice(list(b" \n,#.-e9an"))))
        with open(path, "wb") as handle:
            handle.write(bytes(data))
        try:
            points = read_points(path)
        except PointFileError as error:
            assert path in str(error)
        else:
            assert points.ndim == 2 and points.shape[1] == 3 and len(points) > 0




AXES = {"x": [1, 0, 0], "-x": [-1, 0, 0], "y": [0, 1, 0], "-y": [0, -1, 0],
        "z": [0, 0, 1], "-z": [0, 0, -1]}


@pytest.mark.parametrize("up_axis", sorted(AXES))
def test_up_axis_is_a_proper_rotation_to_plus_z(tmp_path, up_axis):
    path = write(tmp_path, "basis.csv", "1,0,0\n0,1,0\n0,0,1\n")
    # Row i of the result is R applied to basis vector i, i.e. column i of R.
    rotation = read_points(path, up_axis=up_axis).T
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rotation) == pytest.approx(1.0)
    np.testing.assert_allclose(rotation @ np.array(AXES[up_axis], float), [0, 0, 1])


def test_up_axis_minus_y_is_orbslam_convention(tmp_path):
    path = write(tmp_path, "orb.csv", "1,2,3\n")
    np.testing.assert_array_equal(read_points(path, up_axis="-y"), [[1, 3, -2]])
    np.testing.assert_array_equal(read_points(path, up_axis="-Y"), [[1, 3, -2]])
    np.testing.assert_array_equal(read_points(path, up_axis=None), [[1, 2, 3]])
    np.testing.assert_array_equal(read_points(path, up_axis="+y"), [[1, -3, 2]])


def test_bad_arguments_are_value_errors_not_file_errors(tmp_path):
    path = write(tmp_path, "ok.csv", "1,2,3\n")
    for kwargs in ({"up_axis": "up"}, {"fmt": "las"}):
        with pytest.raises(ValueError) as caught:
            read_points(path, **kwargs)
        assert not isinstance(caught.value, PointFileError)


def test_forced_text_format(tmp_path):
    path = write(tmp_path, "cloud.dat", "1 2 3\n")
    np.testing.assert_array_equal(read_points(path, fmt="xyz"), [[1, 2, 3]])
    assert_error(path, "not a PLY file", fmt="ply")


def test_info_keys(tmp_path):
    _, info = read_points_with_info(write(tmp_path, "i.csv", "1,2,3,4\n"))
    assert {"format", "n_rows", "n_dropped_non_finite", "n_columns", "extra_columns"} <= set(info)
    assert info["format"] == "text" and info["n_rows"] == 1 and info["extra_columns"] == 1




def test_write_points_csv_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    points = rng.normal(size=(50, 3)) * 1e3
    path = str(tmp_path / "out.csv")
    write_points_csv(path, points)
    np.testing.assert_array_equal(read_points(path), points)
    assert os.listdir(tmp_path) == ["out.csv"]


def test_write_points_csv_replaces_and_keeps_mode(tmp_path):
    path = write(tmp_path, "out.csv", "9,9,9\n")
    os.chmod(path, 0o640)
    write_points_csv(path, POINTS)
    np.testing.assert_array_equal(read_points(path), POINTS)
    assert os.stat(path).st_mode & 0o777 == 0o640


def test_write_points_csv_failure_leaves_old_file(tmp_path, monkeypatch):
    path = write(tmp_path, "out.csv", "9,9,9\n")

    def failing_replace(src, dst):
        raise OSError("disk unplugged")

    monkeypatch.setattr(pointfiles.os, "replace", failing_replace)
    with pytest.raises(OSError):
        write_points_csv(path, POINTS)
    assert open(path).read() == "9,9,9\n"
    assert os.listdir(tmp_path) == ["out.csv"]


def test_write_points_csv_rejects_bad_shape(tmp_path):
    with pytest.raises(ValueError):
        write_points_csv(str(tmp_path / "bad.csv"), np.zeros((4, 2)))




def shared_cloud_files():
    found = []
    for folder in ("orbslam_rooms", "orbslam_clouds"):
        for root, _, names in os.walk(os.path.join(DATA, folder)):
            found.extend(os.path.join(root, n) for n in names
                         if n.lower().endswith(CLOUD_EXTENSIONS))
    return sorted(found)


@pytest.mark.skipif(not os.path.isdir(DATA), reason="../shared/data not present")
def test_every_shared_cloud_loads():
    files = shared_cloud_files()
    assert files
    for path in files:
        points, info = read_points_with_info(path)
        assert len(points) > 0, path
        assert points.shape[1] == 3 and np.isfinite(points).all(), path


@pytest.mark.skipif(not os.path.isdir(DATA), reason="../shared/data not present")
def test_shared_pcd_matches_its_text_twin():
    folder = os.path.join(DATA, "orbslam_clouds", "StefanoVr__Homework3")
    pcd, pcd_info = read_points_with_info(os.path.join(folder, "pointcloud.pcd"))
    txt, txt_info = read_points_with_info(os.path.join(folder, "MapPointsSave.txt"))
    assert pcd_info["format"] == "pcd" and txt_info["format"] == "text"
    assert pcd.shape == txt.shape == (8718, 3)
    # The text file holds the same points rounded to 7 decimals.
    np.testing.assert_allclose(pcd, txt, atol=1e-7)
