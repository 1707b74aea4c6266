"""What an exit finder returns, and the error it raises when a cloud holds no room (ROS-free)."""
import dataclasses

# Status values: "ok" (exits found), "no_exit" (a room, but no evidence of an exit anywhere).
# ExitFinderError.status: "bad_input", "too_few_points", "collinear", "no_room_shape".
STATUS_OK = "ok"
STATUS_NO_EXIT = "no_exit"


class ExitFinderError(ValueError):
    """The cloud cannot give an exit; ``status`` says why in one word, the message in a sentence.

    Attributes:
        status: ``"bad_input"`` (wrong shape, non-finite values refused), ``"too_few_points"``
            (fewer points than a room needs, before or after filtering), ``"collinear"`` (the
            points lie on one line) or ``"no_room_shape"`` (no valid room outline was found).
        n_points_in: rows given to the finder.
    """

    def __init__(self, status, message, n_points_in=0):
        super().__init__(message)
        self.status = status
        self.n_points_in = int(n_points_in)


@dataclasses.dataclass
class ExitResult:
    """An exit finder's answer, in the two horizontal axes of the input and in its units.

    For an ORB-SLAM cloud with up axis ``'-y'`` (or ``'y'``) the two axes are the input's x and z;
    for ``'±z'`` they are x and y, for ``'±x'`` y and z. Nothing is rescaled: coordinates are in
    the input's own units (SLAM units for a monocular map).

    Attributes:
        exits: ``[(x, y, score), ...]`` best first; ``score`` in [0, 1] is the method's
            confidence (its meaning is per method, see the method docs). Empty when
            ``status == "no_exit"``.
        method: name of the method that produced the answer (``"auto"`` names the one it chose,
            e.g. ``"auto:gaps"``).
        room_corners: ``[(x, y), ...]`` the room outline the method used, in order around it.
        n_points_in: rows given to the finder (before dropping non-finite rows).
        n_points_used: points left after de-duplication and IPCL, the ones the method used.
        runtime_s: wall time of the call (s).
        status: ``"ok"`` or ``"no_exit"``.
        reason: a sentence explaining the status.
        n_dropped_non_finite: rows dropped because a coordinate was NaN or infinite.
        details: method internals for plots and debugging (``"line_points"``: the cloud points
            on the room lines next to the best exit, ``"cloud"``: the points used), in the same
            axes and units as ``exits``.
    """

    exits: list
    method: str
    room_corners: list
    n_points_in: int
    n_points_used: int
    runtime_s: float
    status: str = STATUS_OK
    reason: str = ""
    n_dropped_non_finite: int = 0
    details: dict = dataclasses.field(default_factory=dict, repr=False)

    def to_json_dict(self):
        """The documented JSON form: exits, method, room_corners, counts and runtime."""
        return {
            "exits": [{"x": float(x), "y": float(y), "score": float(s)} for x, y, s in self.exits],
            "method": self.method,
            "room_corners": [[float(x), float(y)] for x, y in self.room_corners],
            "n_points_in": int(self.n_points_in),
            "n_points_used": int(self.n_points_used),
            "runtime_s": float(self.runtime_s),
        }
