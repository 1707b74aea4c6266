"""Top-view pictures of a run (ROS-free, matplotlib without a display)."""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import matplotlib.transforms  # noqa: E402
import numpy as np  # noqa: E402


def plot_summary(path, world, points, true_path, estimated_path, title="", found_exit=None,
                 exit_lines=(), planned_path=()):
    """Writes a PNG: true walls and exits, SLAM points (red), true and estimated trajectories.

    Seed 000's picture on top: the exit found (green) and the room lines next to it (blue), and
    the last planned path. Every input is in the world's (ground truth) frame, metres.
    """
    fig, ax = plt.subplots(figsize=(8, 8), dpi=100)
    for x1, y1, x2, y2 in world.wall_segments():
        ax.plot([x1, x2], [y1, y2], color="black", linewidth=2)
    pts = np.asarray(points).reshape(-1, 3)
    if len(pts):
        ax.scatter(pts[:, 0], pts[:, 1], s=2, color="red", label=f"SLAM points ({len(pts)})")
    for exit_ in world.exits:
        # Drawn over the trajectories, which cross the door and would hide it.
        ax.scatter([exit_["x"]], [exit_["y"]], s=300, marker="*", facecolors="none",
                   edgecolors="green", linewidths=2, zorder=6, label="true exit")
    for (x1, y1), (x2, y2) in exit_lines:
        ax.plot([x1, x2], [y1, y2], color="blue", linewidth=2.5, label="room lines at the exit")
    if found_exit is not None:
        ax.scatter([found_exit[0]], [found_exit[1]], s=120, color="green", zorder=5,
                   label="exit found")
    if len(planned_path) > 1:
        xy = np.asarray(planned_path)
        ax.plot(xy[:, 0], xy[:, 1], color="orange", linewidth=2, label="planned path")
    for trajectory, style, label in ((true_path, "b-", "true trajectory"),
                                     (estimated_path, "c--", "estimated trajectory")):
        if len(trajectory):
            xy = np.asarray(trajectory)
            ax.plot(xy[:, 0], xy[:, 1], style, linewidth=1.5, label=label)
    xmin, ymin, xmax, ymax = world.bounds()
    margin = 1.0
    ax.set_xlim(xmin - margin, xmax + margin)
    ax.set_ylim(ymin - margin, ymax + margin)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title)
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles))
    ax.legend(unique.values(), unique.keys(), loc="upper right", fontsize=8)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_grid(path, world, cells, resolution_m, origin_xy, t_truth_map, title=""):
    """Writes a PNG of an occupancy grid drawn in the world's (ground truth) frame.

    cells: (rows, cols) int8, row 0 at the grid's lowest y, 100 occupied / 0 free / -1 unknown;
    origin_xy: the grid origin in its own (map) frame; t_truth_map: 4x4 map -> world transform.
    Free cells are light, occupied dark, unknown transparent; true walls are drawn over them. An
    empty grid (SLAM has just started a new map) gives the walls alone, and says so.
    """
    rows, cols = cells.shape
    image = np.full((rows, cols, 4), 0.0)
    image[cells == 0] = (0.85, 0.95, 0.85, 1.0)
    image[cells == 100] = (0.1, 0.1, 0.1, 1.0)
    yaw = np.arctan2(t_truth_map[1, 0], t_truth_map[0, 0])
    transform = (matplotlib.transforms.Affine2D().rotate(yaw)
                 .translate(t_truth_map[0, 3], t_truth_map[1, 3]))
    fig, ax = plt.subplots(figsize=(8, 8), dpi=100)
    extent = (origin_xy[0], origin_xy[0] + cols * resolution_m,
              origin_xy[1], origin_xy[1] + rows * resolution_m)
    if cells.size:
        artist = ax.imshow(image, origin="lower", extent=extent, interpolation="nearest")
        artist.set_transform(transform + ax.transData)
    else:
        title += " (the grid is empty)"
    for x1, y1, x2, y2 in world.wall_segments():
        ax.plot([x1, x2], [y1, y2], color="red", linewidth=1, alpha=0.8)
    for exit_ in world.exits:
        ax.scatter([exit_["x"]], [exit_["y"]], s=200, marker="*", color="green")
    xmin, ymin, xmax, ymax = world.bounds()
    ax.set_xlim(xmin - 1.0, xmax + 1.0)
    ax.set_ylim(ymin - 1.0, ymax + 1.0)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title + "\ngrid: free light, occupied dark; true walls red")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
