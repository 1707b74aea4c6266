"""Read ORB-SLAM map-point files (text columns, PLY, PCD) into numpy arrays (ROS-free).

Supported inputs:

* Text (``csv``, ``txt``, ``xyz``): one point per line, the first three fields are x, y, z.
  Fields are separated by commas, semicolons, tabs or spaces (mixed is fine). Extra columns
  (ORB-SLAM savers often append the camera pose) are ignored, trailing empty fields
  (``1,2,3,,,``) are fine, blank lines and lines starting with ``#`` are skipped, and a single
  header line made only of non-numeric words (``x,y,z``) is skipped.
* PLY: ``ascii``, ``binary_little_endian`` and ``binary_big_endian``; the ``vertex`` element
  must have ``x``, ``y`` and ``z`` properties of any numeric type; other properties and elements
  are ignored.
* PCD: ``DATA ascii`` and ``DATA binary`` with ``x``, ``y`` and ``z`` fields; other fields are
  ignored. ``DATA binary_compressed`` is refused.

Every problem with a file's content raises :class:`PointFileError`, whose message starts with
the file's path and says what is wrong. A reader never returns an empty array: a file without
points, or whose points are all non-finite, is an error. Missing or unreadable files raise the
usual ``OSError``.
"""
import os
import re
import struct
import tempfile
import types
import warnings

import numpy as np

__all__ = ["PointFileError", "read_points", "read_points_with_info", "write_points_csv"]

FORMATS = ("csv", "txt", "xyz", "ply", "pcd")
UP_AXES = ("x", "-x", "y", "-y", "z", "-z")

# PLY scalar type names (with the common sized aliases) -> numpy dtype codes without byte order.
_PLY_TYPES = types.MappingProxyType({
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "int64": "i8", "uint64": "u8",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
})
_PLY_ENCODINGS = types.MappingProxyType({
    "ascii": None, "binary_little_endian": "<", "binary_big_endian": ">",
})
# numpy codes -> struct codes with standard sizes (numpy's own char for int64 is 'l', which
# struct reads as 4 bytes once a byte order is given).
_STRUCT_CODES = types.MappingProxyType({
    "i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "i8": "q", "u8": "Q",
    "f4": "f", "f8": "d",
})
_PCD_KINDS = types.MappingProxyType({"F": "f", "I": "i", "U": "u"})

# Bytes that separate fields in text files; all become a space before numpy parses them.
# \r, \v and \f are folded too so that numpy's notion of whitespace matches ours exactly.
_SEPARATORS_TO_SPACE = bytes.maketrans(b",;\t\r\v\f", b"      ")
_HARD_SEPARATORS_TO_COMMA = bytes.maketrans(b";", b",")
# A comma/semicolon field that is empty although a later field on its line is not ("1,,2"):
# collapsing separators would shift the columns, so such files take the exact slow path.
_EMPTY_FIELD_BEFORE_VALUE = re.compile(rb"(?:^|[\n,]),+[^,\n]")
_COMMENT_LINE = re.compile(rb"(?m)^[ \t\r\v\f]*#[^\n]*")
_FIELD_SPLIT = re.compile(r"[ \t\r\v\f]*[,;][ \t\r\v\f]*|[ \t\r\v\f]+")
_PLY_END_HEADER = re.compile(rb"(?m)^end_header[ \t]*\r?\n")
_PCD_COMMENT = re.compile(rb"#\s*\.PCD\b", re.IGNORECASE)
_CHUNK_BYTES = 1 << 20


class PointFileError(ValueError):
    """A point file could not be read; the message names the file and the problem."""


class _NotATable(Exception):
    """Internal: the vectorised text parser gave up; the exact per-line parser decides."""


def read_points(path, fmt=None, up_axis=None, drop_non_finite=True):
    """Read a point file and return its points as an (N, 3) float64 array.

    Args:
        path: file to read (str or path-like).
        fmt: one of ``None``, ``'csv'``, ``'txt'``, ``'xyz'``, ``'ply'``, ``'pcd'``. ``None``
            detects the format from the content: a file starting with ``ply`` is PLY, one whose
            header has a ``# .PCD`` comment or starts with ``VERSION``/``FIELDS`` is PCD,
            anything else is read as text columns. A ``.ply``/``.pcd`` extension on a file
            without that header is an error rather than a guess. ``'csv'``, ``'txt'`` and
            ``'xyz'`` all select the same text reader.
        up_axis: ``None`` returns the file's own axes unchanged. Otherwise the file's vertical
            ("up") axis, one of ``'x'``, ``'-x'``, ``'y'``, ``'-y'``, ``'z'``, ``'-z'`` (a
            leading ``'+'`` and upper case are accepted), and the points are rotated so that
            this axis becomes +z. Every case is a proper rotation (determinant +1, never a
            mirror), written as new (x, y, z) from the file's (x, y, z):

            * ``'z'``:  (x, y, z)   identity
            * ``'-z'``: (x, -y, -z) 180 degrees about x
            * ``'y'``:  (x, -z, y)  +90 degrees about x
            * ``'-y'``: (x, z, -y)  -90 degrees about x; the ORB-SLAM camera frame (x right,
              y down, z forward) becomes x right, y forward, z up
            * ``'x'``:  (-z, y, x)  -90 degrees about y
            * ``'-x'``: (z, y, -x)  +90 degrees about y
        drop_non_finite: drop rows with a NaN or infinite coordinate (the number dropped is
            reported by :func:`read_points_with_info`); ``False`` keeps them.

    Returns:
        numpy.ndarray of shape (N, 3), dtype float64, N >= 1.

    Raises:
        PointFileError: the content is not a readable point cloud, or has no (finite) points.
        ValueError: ``fmt`` or ``up_axis`` is not one of the values above.
        OSError: the file cannot be opened or read.
    """
    points, _ = _read(path, fmt, up_axis, drop_non_finite)
    return points


def read_points_with_info(path, fmt=None, up_axis=None):
    """Like :func:`read_points` (non-finite rows are dropped), plus a dict describing the file.

    The dict has these keys:

    * ``'format'``: ``'text'``, ``'ply'`` or ``'pcd'``, the reader that was used.
    * ``'encoding'``: ``'text'`` for text files, the PLY format (``'ascii'``,
      ``'binary_little_endian'``, ``'binary_big_endian'``) or the PCD ``DATA`` value.
    * ``'n_rows'``: points stored in the file, before non-finite rows are dropped.
    * ``'n_dropped_non_finite'``: rows dropped because a coordinate was NaN or infinite.
    * ``'n_columns'``: values per row: for text the largest number of fields on a data line,
      for PLY the number of vertex properties, for PCD the sum of the field counts.
    * ``'extra_columns'``: ``n_columns - 3``, the values per row that were ignored.
    * ``'header'``: the skipped text header line (``None`` if there was none; always ``None``
      for PLY and PCD).
    """
    return _read(path, fmt, up_axis, True)


def write_points_csv(path, points):
    """Write points as ``x,y,z`` lines (no header), atomically.

    The data goes to a temporary file in the destination's directory, which is flushed,
    fsynced and then renamed over ``path`` with :func:`os.replace`, so readers never see a
    half-written file. Values are written with 17 significant digits, so reading the file back
    gives the same float64 values. A new file gets mode 0644; an existing file keeps its mode.

    Raises:
        ValueError: ``points`` is not an (N, 3) array of numbers.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {pts.shape}")
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    try:
        mode = os.stat(path).st_mode & 0o7777
    except FileNotFoundError:
        mode = 0o644
    fd, tmp_path = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp",
                                    dir=directory)
    try:
        with os.fdopen(fd, "wb") as handle:
            if len(pts):
                np.savetxt(handle, pts, fmt="%.17g", delimiter=",")
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp_path, mode)
        os.replace(tmp_path, path)
    except BaseException:
        # Leave no stray temporary file behind, whatever interrupted the write.
        try:
            os.unlink(tmp_path)
        except OSError:
            pass
        raise
    _fsync_directory(directory)




def _read(path, fmt, up_axis, drop_non_finite):
    """Read, drop non-finite rows, rotate; shared by both public readers."""
    if fmt is not None and fmt not in FORMATS:
        raise ValueError(f"fmt must be None or one of {', '.join(FORMATS)}; got {fmt!r}")
    rotation = _up_rotation(up_axis)
    name = os.fspath(path)
    if isinstance(name, bytes):
        name = os.fsdecode(name)
    with open(path, "rb") as handle:
        data = handle.read()

    kind = fmt if fmt is not None else _detect_format(name, data)
    if kind == "ply":
        points, info = _read_ply(name, data)
    elif kind == "pcd":
        points, info = _read_pcd(name, data)
    else:
        points, info = _read_text(name, data)

    info["n_rows"] = len(points)
    if len(points) == 0:
        raise PointFileError(f"{name}: no points")
    finite = np.isfinite(points).all(axis=1)
    n_bad = int(len(points) - np.count_nonzero(finite))
    info["n_dropped_non_finite"] = n_bad if drop_non_finite else 0
    if drop_non_finite and n_bad:
        if n_bad == len(points):
            raise PointFileError(f"{name}: no points: all {n_bad} rows have a NaN or "
                                 f"infinite coordinate")
        points = points[finite]
    points = np.ascontiguousarray(points, dtype=np.float64)
    if rotation is not None:
        points = points @ rotation.T
    return points, info


def _up_rotation(up_axis):
    """Rotation matrix taking the named up axis to +z (see read_points), or None."""
    if up_axis is None:
        return None
    key = up_axis.strip().lower().lstrip("+") if isinstance(up_axis, str) else None
    # Rows give new (x, y, z) in terms of the file's (x, y, z); each has determinant +1.
    if key == "z":
        rows = ((1, 0, 0), (0, 1, 0), (0, 0, 1))
    elif key == "-z":
        rows = ((1, 0, 0), (0, -1, 0), (0, 0, -1))
    elif key == "y":
        rows = ((1, 0, 0), (0, 0, -1), (0, 1, 0))
    elif key == "-y":
        rows = ((1, 0, 0), (0, 0, 1), (0, -1, 0))
    elif key == "x":
        rows = ((0, 0, -1), (0, 1, 0), (1, 0, 0))
    elif key == "-x":
        rows = ((0, 0, 1), (0, 1, 0), (-1, 0, 0))
    else:
        raise ValueError(f"up_axis must be None or one of {', '.join(UP_AXES)}; "
                         f"got {up_axis!r}")
    return np.array(rows, dtype=np.float64)


def _detect_format(name, data):
    """'ply', 'pcd' or 'text' from the first bytes; the extension only vetoes a guess."""
    if re.match(rb"ply[ \t]*\r?\n", data):
        return "ply"
    if _looks_like_pcd(data[:4096]):
        return "pcd"
    ext = os.path.splitext(name)[1].lower()
    if ext in (".ply", ".pcd"):
        label = ext[1:].upper()
        expected = "'ply' line" if ext == ".ply" else "'# .PCD', 'VERSION' or 'FIELDS' line"
        raise PointFileError(f"{name}: not a {label} file (no {expected} at the start; "
                             f"first bytes {data[:16]!r})")
    return "text"


def _looks_like_pcd(head):
    """True when the first non-comment header line is VERSION/FIELDS or a comment says .PCD."""
    for raw in head.split(b"\n")[:20]:
        line = raw.strip()
        if not line:
            continue
        if line.startswith(b"#"):
            if _PCD_COMMENT.match(line):
                return True
            continue
        word = line.split()[0].upper()
        return word in (b"VERSION", b"FIELDS")
    return False


def _fsync_directory(directory):
    """Make a rename durable; not every platform can open or fsync a directory."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)




def _check_text(name, data, what=None):
    """Refuse binary content before reading it as text (numpy would stop at a NUL byte)."""
    looks_binary = b"\x00" in data
    if not looks_binary and not data.isascii():
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            looks_binary = True
    if looks_binary:
        if what is not None:
            raise PointFileError(f"{name}: the {what} is not text (first bytes {data[:16]!r})")
        raise PointFileError(f"{name}: not a point cloud (unknown format, first bytes "
                             f"{data[:16]!r})")


def _normalise_text(data):
    """Strip a UTF-8 BOM and make \\n the only line break (old Mac files use bare \\r)."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if b"\r" in data and b"\n" not in data:
        data = data.replace(b"\r", b"\n")
    return data


def _is_number(token):
    """True if ``float`` accepts the token (nan and inf included)."""
    try:
        float(token)
    except ValueError:
        return False
    return True


def _split_fields(line):
    """Fields of one text line, trailing empty fields removed."""
    fields = _FIELD_SPLIT.split(line.strip(" \t\r\v\f"))
    while fields and fields[-1] == "":
        fields.pop()
    return fields


def _is_header(fields):
    """A header line has words, none of which is a number."""
    words = [f for f in fields if f]
    return bool(words) and not any(_is_number(f) for f in words)


def _find_header(data):
    """(start, end, text) of a leading header line, or None; comments and blanks may precede."""
    start = 0
    while start < len(data):
        end = data.find(b"\n", start)
        if end < 0:
            end = len(data)
        line = data[start:end].decode("utf-8", "replace")
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            if _is_header(_split_fields(line)):
                return start, end, stripped
            return None
        start = end + 1
    return None


def _read_text(name, data):
    """Text columns: the vectorised parser when the file is regular, else the exact one."""
    _check_text(name, data)
    data = _normalise_text(data)
    header = _find_header(data)
    body = data
    if header is not None:
        # Blank the header but keep its newline so that line numbers stay those of the file.
        body = data[:header[0]] + data[header[1]:]
    try:
        points, n_columns = _read_text_fast(name, body)
    except _NotATable:
        points, n_columns = _read_text_exact(name, body)
    info = {
        "format": "text", "encoding": "text", "n_columns": n_columns,
        "extra_columns": max(n_columns - 3, 0), "header": header[2] if header else None,
    }
    return points, info


def _read_text_fast(name, body):
    """Vectorised reader; raises _NotATable when the exact reader must decide.

    The body is cut at line breaks into chunks of about _CHUNK_BYTES so that the numpy
    temporaries stay in cache, which matters more than the number of passes.
    """
    pieces = []
    row_counts = []
    first_short = None
    lines_before = 0
    position = 0
    while position < len(body):
        end = body.find(b"\n", min(position + _CHUNK_BYTES, len(body)))
        end = len(body) if end < 0 else end + 1
        chunk = body[position:end]
        position = end
        points, counts = _first_three_columns(chunk)
        rows = np.flatnonzero(counts > 0)
        short = np.flatnonzero(counts[rows] < 3)
        if len(short) and first_short is None:
            line = int(rows[short[0]])
            # Only its token count is known; a word in it needs the exact reader's message.
            text = chunk.split(b"\n")[line].decode("utf-8", "replace")
            if not all(_is_number(field) for field in _split_fields(text)):
                raise _NotATable()
            first_short = (lines_before + line + 1, int(counts[line]))
        pieces.append(points)
        row_counts.append(counts[rows])
        lines_before += len(counts) - 1  # counts has one entry per line break, plus one
    row_counts = np.concatenate(row_counts) if row_counts else np.zeros(0, dtype=np.intp)
    if not len(row_counts):
        raise PointFileError(f"{name}: no points (the file has no data lines)")
    if first_short is not None:
        raise _short_rows_error(name, row_counts, *first_short)
    return np.concatenate(pieces), int(row_counts.max())


def _first_three_columns(chunk):
    """(x y z rows, tokens per line) of a chunk of whole text lines.

    Only the first three fields of a line are parsed; the rest are cut away before numpy
    sees them, which is most of the work for files that carry a 16-value pose per point.
    Lines with fewer than three fields give no row (the caller reports them).
    """
    if b"," in chunk or b";" in chunk:
        compact = chunk.translate(_HARD_SEPARATORS_TO_COMMA, b" \t\r\v\f")
        if (b",," in compact or b"\n," in compact or compact.startswith(b",")) \
                and _EMPTY_FIELD_BEFORE_VALUE.search(compact):
            raise _NotATable()
    if b"#" in chunk:
        chunk = _COMMENT_LINE.sub(b"", chunk)
    buf = np.frombuffer(chunk.translate(_SEPARATORS_TO_SPACE), dtype=np.uint8)
    starts, line_breaks, counts = _token_layout(buf)
    if not len(starts):
        return np.empty((0, 3)), counts
    rows = np.flatnonzero(counts >= 3)
    row_counts = counts[rows]
    # Index of each line's first token: tokens are numbered through the chunk in order.
    first_token = (np.cumsum(counts) - counts)[rows]
    line_ends = np.append(line_breaks, len(buf))
    # Byte ranges to cut: from the fourth token to the end of its line, and whole lines with
    # fewer than three tokens, so that every remaining line holds exactly three tokens.
    wide = row_counts > 3
    short = np.flatnonzero((counts > 0) & (counts < 3))
    cut_from = np.concatenate((starts[first_token[wide] + 3],
                               np.concatenate(([0], line_breaks + 1))[short]))
    if len(cut_from):
        cut_to = np.concatenate((line_ends[rows[wide]], line_ends[short]))
        delta = np.zeros(len(buf) + 1, dtype=np.int8)
        delta[cut_from] = 1
        delta[cut_to] = -1
        buf = buf[np.cumsum(delta[:-1], dtype=np.int8) == 0]
    flat = _parse_numbers(buf.tobytes())
    if len(flat) != 3 * len(rows):
        raise _NotATable()
    return flat.reshape(-1, 3), counts


def _token_layout(buf):
    """(token start offsets, newline offsets, tokens per line) of space/newline text."""
    gap = buf <= 32
    token_start = np.empty(len(buf), dtype=bool)
    if len(buf):
        token_start[0] = not gap[0]
        np.greater(gap[:-1], gap[1:], out=token_start[1:])
    starts = np.flatnonzero(token_start)
    line_breaks = np.flatnonzero(buf == 10)
    counts = np.bincount(np.searchsorted(line_breaks, starts), minlength=len(line_breaks) + 1)
    return starts, line_breaks, counts


def _parse_numbers(text):
    """All numbers of space-separated text; _NotATable at the first token numpy cannot read."""
    if not text.strip():
        return np.empty(0)  # numpy reads blank text as [-1.0]
    with warnings.catch_warnings():
        # numpy warns (and stops) at the first token it cannot parse; make that an exception.
        warnings.simplefilter("error", DeprecationWarning)
        try:
            return np.fromstring(text, dtype=np.float64, sep=" ")
        except (DeprecationWarning, ValueError):
            raise _NotATable() from None


def _numeric_table(text):
    """Values and per-line token counts of a body where every token must be a number.

    ``text`` may only contain spaces and newlines as whitespace. Raises _NotATable when a
    token is not a number, so that the caller can find the exact line with Python.
    """
    buf = np.frombuffer(text, dtype=np.uint8)
    starts, _, counts = _token_layout(buf)
    flat = _parse_numbers(text)
    if len(starts) != len(flat):
        # numpy may read one token as two numbers; the counts must agree exactly.
        raise _NotATable()
    return flat, counts


def _read_text_exact(name, body):
    """Line-by-line parser: slower, exact, and the source of the precise error messages."""
    text = body.decode("utf-8", "replace")
    values = []
    counts = []
    for number, line in enumerate(text.split("\n"), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        fields = _split_fields(line)
        if not fields:
            continue  # only separators, e.g. ",,,": as blank as a blank line
        xyz = []
        for column, field in enumerate(fields[:3], start=1):
            if field == "":
                raise PointFileError(f"{name}: line {number}: column {column} is empty")
            try:
                xyz.append(float(field))
            except ValueError:
                raise PointFileError(f"{name}: line {number}: column {column} "
                                     f"({field[:40]!r}) is not a number") from None
        if len(xyz) < 3:
            row_counts = [len(_split_fields(other)) for other in text.split("\n")
                          if not other.strip().startswith("#")]
            raise _short_rows_error(name, np.array(row_counts), number, len(xyz))
        values.append(xyz)
        counts.append(len(fields))
    if not values:
        raise PointFileError(f"{name}: no points (the file has no data lines)")
    return np.array(values, dtype=np.float64), max(counts)


def _short_rows_error(name, row_counts, line_number, n_numeric):
    """Error for a row with fewer than 3 columns; about the whole file if no row has 3."""
    row_counts = row_counts[row_counts > 0]  # blank lines are not rows
    widest = int(row_counts.max())
    if widest < 3:
        if int(row_counts.min()) == widest:
            return PointFileError(f"{name}: has {widest} column{'s' if widest != 1 else ''}, "
                                  f"a point needs 3 (x, y, z)")
        return PointFileError(f"{name}: has at most {widest} columns, a point needs 3 "
                              f"(x, y, z)")
    return PointFileError(f"{name}: line {line_number} has {n_numeric} numeric column"
                          f"{'s' if n_numeric != 1 else ''}, a point needs 3")


def _first_bad_token_line(name, text, first_line_number, what):
    """Error for the first non-numeric token of a strictly numeric body (PLY/PCD ascii)."""
    for offset, line in enumerate(text.decode("utf-8", "replace").split("\n")):
        for token in line.split():
            if not _is_number(token):
                return PointFileError(f"{name}: line {first_line_number + offset}: "
                                      f"{token[:40]!r} is not a number in the {what}")
    return PointFileError(f"{name}: the {what} is not plain numbers")




def _read_ply(name, data):
    """PLY ascii/binary: x, y, z of the vertex element."""
    if not re.match(rb"ply[ \t]*\r?\n", data):
        raise PointFileError(f"{name}: not a PLY file (does not start with a 'ply' line; "
                             f"first bytes {data[:16]!r})")
    end = _PLY_END_HEADER.search(data)
    if end is None:
        raise PointFileError(f"{name}: PLY header has no end_header line (truncated?)")
    try:
        header_lines = data[:end.start()].decode("ascii").splitlines()
    except UnicodeDecodeError:
        raise PointFileError(f"{name}: PLY header is not ASCII text") from None
    encoding, elements = _parse_ply_header(name, header_lines)
    body = data[end.end():]
    body_first_line = len(header_lines) + 2

    index = next((i for i, e in enumerate(elements) if e["name"] == "vertex"), None)
    if index is None:
        raise PointFileError(f"{name}: PLY file has no vertex element "
                             f"(elements: {', '.join(e['name'] for e in elements) or 'none'})")
    vertex = elements[index]
    names = [p["name"] for p in vertex["props"]]
    missing = [axis for axis in "xyz" if axis not in names]
    if missing:
        raise PointFileError(f"{name}: {encoding} vertex element has no {'/'.join(missing)} "
                             f"propert{'y' if len(missing) == 1 else 'ies'} "
                             f"(it has: {', '.join(names) or 'none'})")
    for axis in "xyz":
        if vertex["props"][names.index(axis)]["list"]:
            raise PointFileError(f"{name}: PLY vertex property {axis} is a list, not a number")

    if encoding == "ascii":
        points = _ply_ascii_vertices(name, body, elements, index, body_first_line)
    else:
        points = _ply_binary_vertices(name, body, elements, index, _PLY_ENCODINGS[encoding],
                                      encoding)
    info = {"format": "ply", "encoding": encoding, "n_columns": len(names),
            "extra_columns": len(names) - 3, "header": None}
    return points, info


def _parse_ply_header(name, lines):
    """(encoding, elements); each element is {'name', 'count', 'props'}."""
    encoding = None
    elements = []
    for number, line in enumerate(lines[1:], start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        bad = PointFileError(f"{name}: PLY header line {number} is malformed: {line.strip()!r}")
        if words[0] == "format":
            if len(words) < 2 or words[1] not in _PLY_ENCODINGS:
                raise PointFileError(f"{name}: PLY format {' '.join(words[1:2])!r} is unknown "
                                     f"(expected ascii, binary_little_endian or "
                                     f"binary_big_endian)")
            encoding = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise bad
            elements.append({"name": words[1], "count": int(words[2]), "props": []})
        elif words[0] == "property":
            if not elements:
                raise PointFileError(f"{name}: PLY header line {number}: property before any "
                                     f"element")
            if len(words) == 5 and words[1] == "list":
                types_ = words[2:4]
                prop = {"name": words[4], "list": True, "count_type": words[2],
                        "type": words[3]}
            elif len(words) == 3:
                types_ = words[1:2]
                prop = {"name": words[2], "list": False, "type": words[1]}
            else:
                raise bad
            for type_name in types_:
                if type_name not in _PLY_TYPES:
                    raise PointFileError(f"{name}: PLY header line {number}: unknown property "
                                         f"type {type_name!r}")
            elements[-1]["props"].append(prop)
        else:
            raise bad
    if encoding is None:
        raise PointFileError(f"{name}: PLY header has no format line")
    return encoding, elements


def _ply_ascii_vertices(name, body, elements, index, first_line):
    """x, y, z from ASCII PLY rows: one element row per non-blank line."""
    vertex = elements[index]
    _check_text(name, body, "ascii PLY data")
    text = body.translate(_SEPARATORS_TO_SPACE)
    try:
        flat, counts = _numeric_table(text)
    except _NotATable:
        raise _first_bad_token_line(name, text, first_line, "ascii PLY data") from None
    rows = np.flatnonzero(counts > 0)
    skip = sum(e["count"] for e in elements[:index])
    n = vertex["count"]
    if len(rows) < skip + n:
        raise PointFileError(f"{name}: ascii PLY data is truncated: {max(len(rows) - skip, 0)} "
                             f"of {n} vertex rows present")
    row_counts = counts[rows]
    row_starts = np.cumsum(row_counts) - row_counts
    v_lines = rows[skip:skip + n]
    v_counts = row_counts[skip:skip + n]
    v_starts = row_starts[skip:skip + n]
    props = vertex["props"]
    if not any(p["list"] for p in props):
        wrong = np.flatnonzero(v_counts != len(props))
        if len(wrong):
            k = int(wrong[0])
            raise PointFileError(f"{name}: line {first_line + int(v_lines[k])}: vertex row has "
                                 f"{int(v_counts[k])} values, the header declares {len(props)}")
        columns = [[p["name"] for p in props].index(axis) for axis in "xyz"]
        return flat[v_starts[:, None] + np.array(columns)]
    # A list property in the vertex element moves later columns row by row.
    points = np.empty((n, 3))
    for k in range(n):
        row = flat[v_starts[k]:v_starts[k] + v_counts[k]]
        position = 0
        for prop in props:
            if position >= len(row):
                raise PointFileError(f"{name}: line {first_line + int(v_lines[k])}: vertex row "
                                     f"is shorter than the header declares")
            if prop["list"]:
                position += 1 + int(row[position])
                continue
            if prop["name"] in ("x", "y", "z"):
                points[k, "xyz".index(prop["name"])] = row[position]
            position += 1
    return points


def _ply_binary_vertices(name, body, elements, index, order, encoding):
    """x, y, z from binary PLY; elements after the vertex element are never read."""
    offset = 0
    for element in elements[:index]:
        offset = _skip_binary_element(name, body, offset, element, order, encoding)
    vertex = elements[index]
    n = vertex["count"]
    props = vertex["props"]
    if not any(p["list"] for p in props):
        dtype = np.dtype([(f"p{i}", order + _PLY_TYPES[p["type"]]) for i, p in enumerate(props)])
        need = n * dtype.itemsize
        if len(body) - offset < need:
            have = max(len(body) - offset, 0) // dtype.itemsize
            raise PointFileError(f"{name}: {encoding} vertex data is truncated: {have} of {n} "
                                 f"vertices present ({len(body) - offset} of {need} bytes)")
        table = np.frombuffer(body, dtype=dtype, count=n, offset=offset)
        names = [p["name"] for p in props]
        with np.errstate(invalid="ignore"):  # signalling NaNs in the file are still just NaN
            return np.column_stack([table[f"p{names.index(axis)}"].astype(np.float64)
                                    for axis in "xyz"])
    points = np.empty((n, 3))
    for k in range(n):
        for prop in props:
            value, offset = _read_binary_property(name, body, offset, prop, order, encoding)
            if prop["name"] in ("x", "y", "z"):
                points[k, "xyz".index(prop["name"])] = value
    return points


def _skip_binary_element(name, body, offset, element, order, encoding):
    """Offset just past a binary element that precedes the vertex element."""
    props = element["props"]
    if not any(p["list"] for p in props):
        size = sum(np.dtype(_PLY_TYPES[p["type"]]).itemsize for p in props)
        offset += element["count"] * size
        if offset > len(body):
            raise PointFileError(f"{name}: {encoding} data is truncated inside element "
                                 f"{element['name']!r}, before the vertex element")
        return offset
    for _ in range(element["count"]):
        for prop in props:
            _, offset = _read_binary_property(name, body, offset, prop, order, encoding)
    return offset


def _read_binary_property(name, body, offset, prop, order, encoding):
    """(value, new offset) of one binary property; a list returns its length as the value."""
    fmt = order + _STRUCT_CODES[_PLY_TYPES[prop["count_type" if prop["list"] else "type"]]]
    try:
        (value,) = struct.unpack_from(fmt, body, offset)
        offset += struct.calcsize(fmt)
        if prop["list"]:
            offset += int(value) * np.dtype(_PLY_TYPES[prop["type"]]).itemsize
            if offset > len(body):
                raise struct.error("list runs past the end of the file")
    except struct.error:
        raise PointFileError(f"{name}: {encoding} data is truncated (property "
                             f"{prop['name']!r} at byte {offset} of the data)") from None
    return value, offset




def _read_pcd(name, data):
    """PCD v0.5-0.7 with DATA ascii or binary: the x, y, z fields."""
    header, body, body_first_line = _parse_pcd_header(name, data)
    fields = header.get("FIELDS")
    if not fields:
        raise PointFileError(f"{name}: PCD header has no FIELDS line")
    n_fields = len(fields)
    counts = header.get("COUNT", ["1"] * n_fields)
    if not all(c.isdigit() and int(c) > 0 for c in counts):
        raise PointFileError(f"{name}: PCD COUNT {' '.join(counts)!r} is not a list of counts")
    counts = [int(c) for c in counts]
    for key, values in (("SIZE", header.get("SIZE")), ("TYPE", header.get("TYPE")),
                        ("COUNT", counts)):
        if values is not None and len(values) != n_fields:
            raise PointFileError(f"{name}: PCD {key} has {len(values)} entries but FIELDS has "
                                 f"{n_fields}")
    missing = [axis for axis in "xyz" if axis not in fields]
    if missing:
        raise PointFileError(f"{name}: PCD has no {'/'.join(missing)} field"
                             f"{'' if len(missing) == 1 else 's'} (FIELDS {' '.join(fields)})")
    n = _pcd_point_count(name, header)
    data_kind = header["DATA"][0].lower()
    if data_kind == "ascii":
        points = _pcd_ascii_points(name, body, fields, counts, n, body_first_line)
    elif data_kind == "binary":
        points = _pcd_binary_points(name, body, header, fields, counts, n)
    elif data_kind == "binary_compressed":
        raise PointFileError(f"{name}: PCD DATA binary_compressed is not supported; re-save "
                             f"the cloud with DATA binary or DATA ascii")
    else:
        raise PointFileError(f"{name}: PCD DATA {header['DATA'][0]!r} is unknown (expected "
                             f"ascii or binary)")
    info = {"format": "pcd", "encoding": data_kind, "n_columns": sum(counts),
            "extra_columns": sum(counts) - 3, "header": None}
    return points, info


def _parse_pcd_header(name, data):
    """(header dict of upper-case key -> list of words, body bytes, first body line number)."""
    known = ("VERSION", "FIELDS", "COLUMNS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT",
             "VIEWPOINT", "POINTS", "DATA")
    header = {}
    start = 0
    number = 0
    while start < len(data):
        end = data.find(b"\n", start)
        end = len(data) if end < 0 else end
        number += 1
        raw = data[start:end]
        start = end + 1
        try:
            line = raw.decode("ascii").strip()
        except UnicodeDecodeError:
            raise PointFileError(f"{name}: PCD header line {number} is not ASCII text") from None
        if not line or line.startswith("#"):
            continue
        words = line.split()
        key = words[0].upper()
        if key not in known:
            raise PointFileError(f"{name}: PCD header line {number} is not a header entry: "
                                 f"{line[:60]!r}")
        header["FIELDS" if key == "COLUMNS" else key] = words[1:]
        if key == "DATA":
            if len(words) < 2:
                raise PointFileError(f"{name}: PCD DATA line names no encoding")
            return header, data[start:], number + 1
    raise PointFileError(f"{name}: PCD header has no DATA line (truncated or not a PCD file)")


def _pcd_point_count(name, header):
    """Point count from WIDTH*HEIGHT and/or POINTS, which must agree when both are given."""
    def integer(key):
        values = header.get(key)
        if values is None:
            return None
        if len(values) != 1 or not values[0].isdigit():
            raise PointFileError(f"{name}: PCD {key} {' '.join(values)!r} is not a count")
        return int(values[0])

    width, height, points = integer("WIDTH"), integer("HEIGHT"), integer("POINTS")
    from_size = width * (height if height is not None else 1) if width is not None else None
    if from_size is not None and points is not None and from_size != points:
        raise PointFileError(f"{name}: PCD header disagrees with itself: WIDTH*HEIGHT = "
                             f"{from_size} but POINTS = {points}")
    count = points if points is not None else from_size
    if count is None:
        raise PointFileError(f"{name}: PCD header has neither POINTS nor WIDTH/HEIGHT")
    return count


def _pcd_ascii_points(name, body, fields, counts, n, first_line):
    """x, y, z columns of PCD ascii rows, which hold sum(COUNT) values each."""
    _check_text(name, body, "PCD ascii data")
    text = body.translate(_SEPARATORS_TO_SPACE)
    try:
        flat, line_counts = _numeric_table(text)
    except _NotATable:
        raise _first_bad_token_line(name, text, first_line, "PCD ascii data") from None
    rows = np.flatnonzero(line_counts > 0)
    if len(rows) != n:
        raise PointFileError(f"{name}: PCD header says {n} points but the ascii data has "
                             f"{len(rows)} rows")
    width = sum(counts)
    wrong = np.flatnonzero(line_counts[rows] != width)
    if len(wrong):
        k = int(rows[wrong[0]])
        raise PointFileError(f"{name}: line {first_line + k}: PCD row has {int(line_counts[k])} "
                             f"values, the header declares {width}")
    columns = [sum(counts[:fields.index(axis)]) for axis in "xyz"]
    return flat.reshape(n, width)[:, columns] if n else np.empty((0, 3))


def _pcd_binary_points(name, body, header, fields, counts, n):
    """x, y, z from PCD binary: packed little-endian rows of all fields."""
    sizes, kinds = header.get("SIZE"), header.get("TYPE")
    if sizes is None or kinds is None:
        raise PointFileError(f"{name}: PCD DATA binary needs SIZE and TYPE header lines")
    layout = []
    for i, (field, size, kind, count) in enumerate(zip(fields, sizes, kinds, counts)):
        code = f"{_PCD_KINDS.get(kind.upper(), '?')}{size}"
        try:
            dtype = np.dtype("<" + code)
        except TypeError:
            raise PointFileError(f"{name}: PCD field {field!r} has unsupported TYPE {kind} "
                                 f"SIZE {size}") from None
        # Field names may repeat (PCL pads with '_'), so columns are numbered instead.
        layout.append((f"f{i}", dtype, (count,)) if count != 1 else (f"f{i}", dtype))
    dtype = np.dtype(layout)
    need = n * dtype.itemsize
    if len(body) < need:
        raise PointFileError(f"{name}: PCD binary data is truncated: {len(body) // dtype.itemsize}"
                             f" of {n} points present ({len(body)} of {need} bytes)")
    table = np.frombuffer(body, dtype=dtype, count=n)
    columns = []
    with np.errstate(invalid="ignore"):  # signalling NaNs in the file are still just NaN
        for axis in "xyz":
            column = table[f"f{fields.index(axis)}"]
            columns.append((column[:, 0] if column.ndim == 2 else column).astype(np.float64))
    return np.column_stack(columns)
