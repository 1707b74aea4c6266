"""The seed 000 picture of an exit finder result, drawn with matplotlib's Agg canvas (ROS-free).

Cloud points red, the points on the room lines next to the best exit blue, the best exit green
(the other candidates orange, with their scores), the room outline the method used in black. All
in the input's horizontal axes and units. No pyplot: the figure is a standalone Agg canvas, so
drawing never touches a display or global matplotlib state.
"""
import numpy as np


def plot_result(result, planar_xy, path, axis_names=("x", "z"), title=None):
    """Write a PNG of ``result`` (an :class:`~.result.ExitResult`) over the cloud.

    Args:
        result: the finder's answer.
        planar_xy: (N, 2) horizontal input points (same axes and units as the result).
        path: output PNG file.
        axis_names: names of the two axes, for the labels.
        title: figure title; default names the method and the status.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 7), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    xy = np.asarray(planar_xy, dtype=float).reshape(-1, 2)
    ax.scatter(xy[:, 0], xy[:, 1], s=1, c="red", linewidths=0, label="cloud")
    line_points = result.details.get("line_points")
    if line_points is not None and len(line_points):
        ax.scatter(line_points[:, 0], line_points[:, 1], s=2, c="blue", linewidths=0,
                   label="walls next to the exit")
    if result.room_corners:
        outline = np.array(result.room_corners + result.room_corners[:1])
        ax.plot(outline[:, 0], outline[:, 1], "k-", lw=1.2, label="room outline")
    for k, (x, y, score) in enumerate(result.exits):
        if k == 0:
            ax.plot(x, y, "o", color="limegreen", ms=12, mec="darkgreen", label="exit")
        else:
            ax.plot(x, y, "o", color="orange", ms=6, mec="darkorange")
        ax.annotate(f"{score:.2f}", (x, y), textcoords="offset points", xytext=(6, 6),
                    fontsize=8)
    # Frame the room, not the far outliers.
    if len(xy):
        lo, hi = np.percentile(xy, [1, 99], axis=0)
        pad = 0.25 * np.maximum(hi - lo, 1e-9)
        ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
        ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(axis_names[0])
    ax.set_ylabel(axis_names[1])
    ax.set_title(title or f"{result.method}: {result.status} ({len(result.exits)} exits)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
