"""Cloud preparation of seed 000, steps 1-3: drop the vertical axis, normalise, round and
de-duplicate, and the density filters PCL / IPCL / RPCL (ROS-free).

Frames: the input is (N, 3) in any frame whose vertical axis the caller names (``up_axis``, as in
:func:`sparse_nav.pointfiles.read_points`; ORB-SLAM's is ``'-y'``), or (N, 2) already horizontal.
The planar result keeps the two other axes in the input's order and units (x, z for ``±y``).
Every method then works in a normalised frame (see :class:`CloudFrame`) and maps its answer back.
"""
import dataclasses

import numpy as np
from scipy.spatial import cKDTree

from sparse_nav.exit_finder.result import ExitFinderError

# Columns kept when the named axis is vertical.
_PLANAR_COLUMNS = {"x": (1, 2), "y": (0, 2), "z": (0, 1)}
PLANAR_AXIS_NAMES = {"x": ("y", "z"), "y": ("x", "z"), "z": ("x", "y")}


def planar_columns(up_axis):
    """Indices of the two horizontal input columns for a vertical axis name like ``'-y'``."""
    key = up_axis.strip().lower().lstrip("+-") if isinstance(up_axis, str) else None
    if key not in _PLANAR_COLUMNS:
        raise ValueError(f"up_axis must be one of x, -x, y, -y, z, -z; got {up_axis!r}")
    return _PLANAR_COLUMNS[key]


def planar_points(points, up_axis="-y", drop_non_finite=True):
    """Seed step 1: the horizontal coordinates of a cloud.

    Args:
        points: (N, 3) array in a frame whose vertical axis is ``up_axis``, or (N, 2) already
            horizontal (then ``up_axis`` must be None).
        up_axis: the vertical axis (``'x'``, ``'-x'``, ``'y'``, ``'-y'``, ``'z'``, ``'-z'``); its
            sign does not matter for dropping it.
        drop_non_finite: drop rows with a NaN/inf horizontal coordinate, else refuse them.

    Returns:
        (xy, n_dropped): (M, 2) float64 horizontal points and the number of rows dropped.

    Raises:
        ExitFinderError("bad_input"): wrong shape, or non-finite rows when they are refused.
    """
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ExitFinderError("bad_input", f"points are not numeric: {exc}") from None
    n_in = len(pts) if pts.ndim >= 1 else 0
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ExitFinderError("bad_input", f"points must have shape (N, 3) (or (N, 2) without "
                                           f"an up axis), got {pts.shape}", n_in)
    if pts.shape[1] == 2:
        if up_axis is not None:
            raise ExitFinderError("bad_input", f"points have 2 columns, so there is no vertical "
                                               f"axis {up_axis!r} to drop; need (N, 3)", n_in)
        xy = pts
    else:
        if up_axis is None:
            raise ExitFinderError("bad_input", "3-column points need an up_axis to drop", n_in)
        try:
            xy = pts[:, planar_columns(up_axis)]
        except ValueError as exc:
            raise ExitFinderError("bad_input", str(exc), n_in) from None
    finite = np.isfinite(xy).all(axis=1)
    n_bad = int(len(xy) - np.count_nonzero(finite))
    if n_bad and not drop_non_finite:
        first = int(np.flatnonzero(~finite)[0])
        raise ExitFinderError("bad_input", f"{n_bad} of {len(xy)} points have a NaN or infinite "
                                           f"coordinate (first at row {first})", n_in)
    return np.ascontiguousarray(xy[finite]), n_bad


@dataclasses.dataclass(frozen=True)
class CloudFrame:
    """The normalised frame: q = (p - centre) / scale, p in input units, q in cloud radii (r.u.).

    ``centre`` is the mean of the planar points and ``scale`` the ``percentile``-th percentile of
    their distances from it. Both move with a rotation, translation or scaling of the input, so
    every method's answer does too. The mean is pulled by far outliers, but it only anchors the
    frame; the percentile keeps the scale itself robust to a few of them.
    """

    centre: np.ndarray
    scale: float

    @classmethod
    def of(cls, xy, percentile):
        centre = xy.mean(axis=0)
        scale = float(np.percentile(np.hypot(*(xy - centre).T), percentile))
        return cls(centre=centre, scale=scale)

    def to_norm(self, xy):
        """Input units (..., 2) -> r.u."""
        return (np.asarray(xy, dtype=float) - self.centre) / self.scale

    def from_norm(self, q):
        """r.u. (..., 2) -> input units."""
        return np.asarray(q, dtype=float) * self.scale + self.centre


def check_spread(xy, min_points, collinear_ratio, n_in, stage="finite"):
    """Refuse clouds that cannot hold a room: too few points, or (nearly) all on one line."""
    if len(xy) < min_points:
        raise ExitFinderError("too_few_points", f"{len(xy)} {stage} points; a room needs at "
                                                f"least {min_points}", n_in)
    centred = xy - xy.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[0] <= 0 or sv[1] <= collinear_ratio * sv[0]:
        what = "identical" if sv[0] <= 0 else "collinear"
        raise ExitFinderError("collinear", f"the {len(xy)} {stage} points are {what} (principal "
                                           f"spreads {sv[0]:.3g} and {sv[1]:.3g}): no room "
                                           f"shape in a line", n_in)


def round_dedup(q, decimals):
    """Seed step 2: round coordinates to ``decimals`` and drop duplicates (first kept, order
    preserved, so that seeded random draws later see the same order)."""
    rounded = np.round(q, decimals)
    # Negative zero and positive zero are one grid point.
    rounded += 0.0
    _, first = np.unique(rounded, axis=0, return_index=True)
    return rounded[np.sort(first)]


def neighbour_counts(q, radius, within=None):
    """Number of other points of ``within`` (default ``q``) closer than ``radius`` to each q."""
    if len(q) == 0:
        return np.zeros(0, dtype=int)
    tree = cKDTree(q if within is None else within)
    counts = tree.query_ball_point(q, r=radius, return_length=True)
    # A point of the set finds itself: not a neighbour.
    return np.asarray(counts) - (1 if within is None else 0)


def pcl_mask(q, radius, min_neighbours):
    """PCL (pseudo-clustering): True for the points with >= min_neighbours others within radius.

    All points are judged against the same input set, so one removal never affects another's
    verdict (the seed's "remove them all at once at the end").
    """
    return neighbour_counts(q, radius) >= min_neighbours


def ipcl(q, radius, min_neighbours, rounds):
    """IPCL: PCL applied ``rounds`` times, each round on the survivors of the previous one.

    Stops early once a round removes nothing. Returns the surviving points (order preserved).
    """
    for _ in range(rounds):
        if len(q) == 0:
            break
        keep = pcl_mask(q, radius, min_neighbours)
        if keep.all():
            break
        q = q[keep]
    return q


def rpcl(q, radius, min_neighbours):
    """RPCL (reverse PCL): the complement of PCL, the points with fewer than min_neighbours
    others within radius."""
    if len(q) == 0:
        return q
    return q[~pcl_mask(q, radius, min_neighbours)]
