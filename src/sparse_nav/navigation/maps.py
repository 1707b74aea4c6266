"""Map files the planners read: Moving AI benchmark maps and scenarios, and map_server maps.

Arrays are OccupancyGrid values indexed [y, x] (0 free, 100 occupied, -1 unknown). Every reader
raises :class:`MapFileError` naming the file and the problem.
"""
import math
import os
from dataclasses import dataclass

import numpy as np
import yaml

# Moving AI: '.' and 'G' are passable ground, 'S' swamp is passable; '@', 'O', 'T', 'W' are not.
MOVINGAI_PASSABLE = ".GS"


class MapFileError(ValueError):
    pass


@dataclass
class Scenario:
    index: int          # position among the file's scenarios, from 0
    bucket: int
    map_name: str
    width: int
    height: int
    start: tuple        # (x, y) cells
    goal: tuple
    optimal: float      # the listed optimal length (octile, no corner cutting)


@dataclass
class GridGeometry:
    """Where a grid lies in its frame, as in nav_msgs/MapMetaData."""
    width: int
    height: int
    resolution: float   # m per cell
    origin: tuple       # (x, y, yaw) of cell (0, 0)'s outer corner in the map frame [m, m, rad]

    def validate(self, max_cells):
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"empty grid ({self.width} x {self.height} cells)")
        if self.width * self.height > max_cells:
            raise ValueError(f"grid of {self.width} x {self.height} cells exceeds {max_cells} cells")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"resolution must be finite and > 0, got {self.resolution}")
        if len(self.origin) != 3 or not all(math.isfinite(v) for v in self.origin):
            raise ValueError("origin must be finite")

    def world_to_cell(self, x, y):
        """The cell containing map point (x, y); it may lie outside the grid."""
        ox, oy, yaw = self.origin
        dx, dy = x - ox, y - oy
        c, s = math.cos(yaw), math.sin(yaw)
        return (int(math.floor((c * dx + s * dy) / self.resolution)),
                int(math.floor((-s * dx + c * dy) / self.resolution)))

    def cell_to_world(self, cx, cy):
        """The centre of cell (cx, cy) in the map frame; accepts fractional cells."""
        ox, oy, yaw = self.origin
        u, v = (cx + 0.5) * self.resolution, (cy + 0.5) * self.resolution
        c, s = math.cos(yaw), math.sin(yaw)
        return ox + c * u - s * v, oy + s * u + c * v

    def in_bounds(self, cx, cy):
        return 0 <= cx < self.width and 0 <= cy < self.height


@dataclass
class MapServerMap:
    data: np.ndarray    # int8 [y, x], y up (row 0 is the bottom row of the image)
    geometry: GridGeometry


def _read_text(path):
    try:
        with open(path, encoding="ascii", errors="strict") as f:
            return f.read()
    except FileNotFoundError:
        raise MapFileError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise MapFileError(f"{path}: is a directory") from None
    except UnicodeDecodeError:
        raise MapFileError(f"{path}: not a text file") from None
    except OSError as exc:
        raise MapFileError(f"{path}: {exc.strerror}") from None


def read_movingai_map(path):
    """A Moving AI ``.map`` (``type octile``) as an int8 array [y, x] of 0 and 100."""
    lines = _read_text(path).splitlines()
    header = [line.split() for line in lines[:4]]
    try:
        if header[0] != ["type", "octile"]:
            raise ValueError("the first line must be 'type octile'")
        if header[1][0] != "height" or header[2][0] != "width" or header[3] != ["map"]:
            raise ValueError("expected 'height H', 'width W' and 'map' lines")
        height, width = int(header[1][1]), int(header[2][1])
    except (IndexError, ValueError) as exc:
        raise MapFileError(f"{path}: not a Moving AI map: {exc}") from None
    if height <= 0 or width <= 0:
        raise MapFileError(f"{path}: height and width must be > 0, got {height} x {width}")
    rows = lines[4:4 + height]
    if len(rows) != height or any(len(r.rstrip("\r")) < width for r in rows):
        raise MapFileError(f"{path}: the map has fewer than {height} rows of {width} characters")
    chars = np.array([list(r[:width]) for r in rows])
    passable = np.isin(chars, list(MOVINGAI_PASSABLE))
    return np.where(passable, 0, 100).astype(np.int8)


def read_scenarios(path):
    """The scenarios of a Moving AI ``.scen`` file (version 1)."""
    lines = _read_text(path).splitlines()
    if not lines or not lines[0].lower().startswith("version"):
        raise MapFileError(f"{path}: not a Moving AI scenario file (no 'version' line)")
    out = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split("\t") if "\t" in line else line.split()
        try:
            if len(fields) != 9:
                raise ValueError(f"expected 9 fields, got {len(fields)}")
            bucket, width, height, sx, sy, gx, gy = (int(fields[i]) for i in (0, 2, 3, 4, 5, 6, 7))
            optimal = float(fields[8])
            if not math.isfinite(optimal):
                raise ValueError("the optimal length is not finite")
        except ValueError as exc:
            raise MapFileError(f"{path}:{number}: malformed scenario: {exc}") from None
        out.append(Scenario(len(out), bucket, fields[1], width, height, (sx, sy), (gx, gy), optimal))
    if not out:
        raise MapFileError(f"{path}: no scenarios")
    return out


def read_map_server(yaml_path):
    """A map_server map (YAML + image), trinary mode, as :class:`MapServerMap`."""
    text = _read_text(yaml_path)
    try:
        meta = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise MapFileError(f"{yaml_path}: invalid YAML: {exc}") from None
    if not isinstance(meta, dict):
        raise MapFileError(f"{yaml_path}: not a map_server YAML (expected a mapping)")
    try:
        image = str(meta["image"])
        resolution = float(meta["resolution"])
        origin = [float(v) for v in meta["origin"]]
        negate = int(meta.get("negate", 0))
        occupied = float(meta.get("occupied_thresh", 0.65))
        free = float(meta.get("free_thresh", 0.196))
    except (KeyError, TypeError, ValueError) as exc:
        raise MapFileError(f"{yaml_path}: missing or malformed key: {exc}") from None
    if not (math.isfinite(resolution) and resolution > 0):
        raise MapFileError(f"{yaml_path}: resolution must be finite and > 0, got {resolution}")
    if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
        raise MapFileError(f"{yaml_path}: origin must be three finite numbers [x, y, yaw]")
    mode = meta.get("mode", "trinary")
    if mode != "trinary":
        raise MapFileError(f"{yaml_path}: only mode 'trinary' is supported, got {mode!r}")
    if not os.path.isabs(image):
        image = os.path.join(os.path.dirname(os.path.abspath(yaml_path)), image)
    pixels = _read_image(image)
    p = pixels.astype(float) / 255.0 if negate else (255.0 - pixels.astype(float)) / 255.0
    data = np.full(pixels.shape, -1, dtype=np.int8)
    data[p > occupied] = 100
    data[p < free] = 0
    data = np.ascontiguousarray(data[::-1])
    geometry = GridGeometry(data.shape[1], data.shape[0], resolution, tuple(origin))
    return MapServerMap(data, geometry)


def _read_image(path):
    import cv2
    if not os.path.isfile(path):
        raise MapFileError(f"{path}: no such image file")
    pixels = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if pixels is None or pixels.size == 0:
        raise MapFileError(f"{path}: not an image OpenCV can read")
    return pixels
