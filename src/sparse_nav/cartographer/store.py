"""Map fragments on disk: named files in one directory, written atomically, verified on load.

A fragment file is one JSON header line followed by the payload (the points as little-endian
float32 x, y, z). The header carries the format name and version, the payload length and a
SHA-256 over the metadata and the payload, so a truncated, altered or foreign file is refused
instead of being read as a map.

Writes go to a temporary file in the same directory, which is flushed and fsync'ed, renamed over
the target and followed by an fsync of the directory: a crash at any moment leaves either the old
file or the new one under the fragment's name, never a mixture.
"""
import hashlib
import json
import os
import re
import tempfile

import numpy as np

FORMAT = "sparse_nav.fragment"
VERSION = 1
SUFFIX = ".frag"
_TEMP_PREFIX = ".tmp-"
_NAME = re.compile(r"[A-Za-z0-9_-]{1,64}")
_MAX_HEADER_BYTES = 65536


class FragmentError(ValueError):
    """A fragment name, file or content that is refused; the message says why."""


def validate_name(name):
    """Return ``name`` if it is 1-64 letters, digits, '_' or '-'; raise FragmentError otherwise.

    Names are never paths: '../x', '/etc/passwd', 'a/b', '' and '.hidden' are all refused.
    """
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise FragmentError(f"fragment name {name!r} refused: use 1-64 characters of letters, "
                            "digits, '_' and '-' (a name, never a path)")
    return name


def _check_points(points):
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise FragmentError(f"points must be an (N, 3) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise FragmentError("points contain NaN or Inf")
    return pts.astype("<f4")


def _checksum(meta, payload):
    """SHA-256 over the metadata (canonical JSON) and the payload."""
    digest = hashlib.sha256(json.dumps(meta, sort_keys=True, allow_nan=False).encode())
    digest.update(b"\n")
    digest.update(payload)
    return digest.hexdigest()


def encode(points, meta=None):
    """Bytes of a fragment file holding ``points`` (N, 3) and the JSON-able ``meta`` dict."""
    payload = _check_points(points).tobytes()
    meta = dict(meta or {})
    header = {"format": FORMAT, "version": VERSION, "n_points": len(payload) // 12,
              "payload_bytes": len(payload), "sha256": _checksum(meta, payload), "meta": meta}
    line = json.dumps(header, sort_keys=True, allow_nan=False).encode() + b"\n"
    if len(line) > _MAX_HEADER_BYTES:
        raise FragmentError(f"fragment metadata too large ({len(line)} bytes)")
    return line + payload


def decode(data, what="fragment"):
    """(points (N, 3) float64, meta dict) of fragment bytes; FragmentError names the defect."""
    end = data.find(b"\n", 0, _MAX_HEADER_BYTES)
    if end < 0:
        raise FragmentError(f"{what}: no fragment header (empty, truncated or not a fragment)")
    try:
        header = json.loads(data[:end].decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise FragmentError(f"{what}: unreadable header ({exc})") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise FragmentError(f"{what}: not a {FORMAT} file")
    if header.get("version") != VERSION:
        raise FragmentError(f"{what}: format version {header.get('version')!r}, this reader "
                            f"knows version {VERSION}")
    payload = data[end + 1:]
    expected = header.get("payload_bytes")
    n_points = header.get("n_points")
    if not isinstance(expected, int) or not isinstance(n_points, int) \
            or expected != 12 * n_points or n_points < 0:
        raise FragmentError(f"{what}: inconsistent header sizes")
    if len(payload) != expected:
        raise FragmentError(f"{what}: payload is {len(payload)} bytes, header says {expected} "
                            "(truncated or appended to)")
    meta = header.get("meta")
    if not isinstance(meta, dict):
        raise FragmentError(f"{what}: metadata is not a mapping")
    if _checksum(meta, payload) != header.get("sha256"):
        raise FragmentError(f"{what}: checksum mismatch (the file is corrupt)")
    points = np.frombuffer(payload, dtype="<f4").reshape(-1, 3).astype(np.float64)
    if not np.all(np.isfinite(points)):
        raise FragmentError(f"{what}: points contain NaN or Inf")
    return points, meta


class FragmentStore:
    """Fragments by name in ``map_dir``; every path it touches is ``map_dir/<name>.frag``."""

    def __init__(self, map_dir):
        if not map_dir:
            raise FragmentError("map_dir must be set")
        self.map_dir = os.path.realpath(os.path.expanduser(map_dir))
        os.makedirs(self.map_dir, mode=0o700, exist_ok=True)
        if not os.path.isdir(self.map_dir):
            raise FragmentError(f"map_dir {self.map_dir} is not a directory")

    def path(self, name):
        """The file of fragment ``name`` (validated; always directly inside map_dir)."""
        return os.path.join(self.map_dir, validate_name(name) + SUFFIX)

    def names(self):
        """Sorted names of the fragment files present (not verified; see load)."""
        out = []
        for entry in os.listdir(self.map_dir):
            stem, ext = os.path.splitext(entry)
            if ext == SUFFIX and _NAME.fullmatch(stem):
                out.append(stem)
        return sorted(out)

    def exists(self, name):
        return os.path.isfile(self.path(name))

    def save(self, name, points, meta=None):
        """Write fragment ``name`` atomically and durably; returns its path."""
        target = self.path(name)
        data = encode(points, meta)
        fd, tmp = tempfile.mkstemp(prefix=_TEMP_PREFIX + name + ".", dir=self.map_dir)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, target)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise
        self._sync_dir()
        return target

    def load(self, name):
        """(points, meta) of fragment ``name``; FragmentError if missing, corrupt or not a file."""
        path = self.path(name)
        try:
            # O_NOFOLLOW: a symlink planted in map_dir must not lead a load outside it.
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except FileNotFoundError:
            raise FragmentError(f"fragment {name!r}: no such fragment in {self.map_dir}") from None
        except OSError as exc:
            raise FragmentError(f"fragment {name!r}: cannot open ({exc.strerror})") from None
        with os.fdopen(fd, "rb") as f:
            data = f.read()
        return decode(data, what=f"fragment {name!r}")

    def delete(self, name):
        """Remove fragment ``name`` if present (durably)."""
        try:
            os.unlink(self.path(name))
        except FileNotFoundError:
            return
        self._sync_dir()

    def remove_stale_temporaries(self):
        """Delete temporary files left by writes that crashed; returns how many."""
        removed = 0
        for entry in os.listdir(self.map_dir):
            if entry.startswith(_TEMP_PREFIX):
                try:
                    os.unlink(os.path.join(self.map_dir, entry))
                    removed += 1
                except OSError:
                    pass
        return removed

    def _sync_dir(self):
        fd = os.open(self.map_dir, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
