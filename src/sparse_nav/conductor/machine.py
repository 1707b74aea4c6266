"""The conductor's automaton (seed 004) running the escape mission (seed 000), ROS-free.

The conductor decides; it does not move the robot or read topics. Its node feeds it an
:class:`Observation` per tick and carries out the :class:`Action` list it returns. Every change of
state or phase is recorded with its reason, so a run can be explained afterwards.

States (004): START builds the first map (scans), IDLE waits with a healthy map, GOAL navigates,
LOST waits for tracking to come back (motion stopped), RECOVER frees a robot that the map puts
inside an obstacle. Phases (000): initial scan -> wall scan -> find exit -> go to the exit -> pass
through -> done, or gave up with the reason. Beyond an exit the robot looks around: the room's side
walls going on past the door's wall, or walls all round where no room outline measures them, mean
another room of the building (a partition's door), whose exit is found in turn; a room with no
door but that one sends the robot back to the room before's next candidate.
"""
import dataclasses
import enum
import math
from typing import Dict, List, Optional, Tuple

import numpy as np

from sparse_nav.conductor.grid_queries import widest_opening_deg
from sparse_nav.exit_finder.geometry import boundary_distances, points_in_polygon


class State(enum.Enum):
    START = "START"
    IDLE = "IDLE"
    GOAL = "GOAL"
    LOST = "LOST"
    RECOVER = "RECOVER"


class Phase(enum.Enum):
    WAITING = "waiting"              # not started, or stopped
    INITIAL_SCAN = "initial_scan"
    WALL_SCAN = "wall_scan"
    FIND_EXIT = "find_exit"
    GO_TO_EXIT = "go_to_exit"
    PASS_THROUGH = "pass_through"
    LOOK_AROUND = "look_around"      # beyond an exit: outside, or in another room?
    BACK_OUT = "back_out"            # the room looked into led back into the room before:
                                     # back to where that look stood, which was out
    STEP_OUT = "step_out"            # a look around said out with the robot in the door:
                                     # on to the point beyond the exit, then done
    RETURN_TO_START = "return_to_start"
    DONE = "done"
    GAVE_UP = "gave_up"

    @property
    def final(self):
        return self in (Phase.DONE, Phase.GAVE_UP)


class ActionKind(enum.Enum):
    SCAN = "scan"            # payload: scan name ("initial", "wall", "random", "relocalise",
                             # "look_around"; "resume": go on with the scan a loss cut)
    FIND_EXIT = "find_exit"  # ask the exit finder; payload: an ExitRequest
    GOAL = "goal"            # payload: (x, y) in the map frame
    CANCEL_GOAL = "cancel_goal"
    STOP = "stop"            # zero velocity / no further drone command
    RECOVER_MOTION = "recover_motion"  # a small turn to merge maps or leave an occupied cell


@dataclasses.dataclass(frozen=True)
class Action:
    kind: ActionKind
    payload: object = None


@dataclasses.dataclass(frozen=True)
class ExitRequest:
    viewpoint: object = None  # the finder's viewpoint name (None: its default)
    # The last attempt before giving up: the finder reports candidates however unlikely it rates
    # them, since driving to a doubtful exit beats giving up in a room with one.
    last_attempt: bool = False


@dataclasses.dataclass
class Observation:
    """What the conductor knows at one tick; the node fills it from its topics."""

    time_s: float
    tracking_lost: bool = False          # SLAM lost its map (not: not initialised yet)
    slam_tracked_points: Optional[int] = None  # map points tracked at the newest SLAM state
                                         # (at a loss: the count it was lost with)
    slam_map_given_up: bool = False      # lost, and SLAM gave up its map: tracking comes back
                                         # in a new map (which needs a baseline) or by a merge
    slam_map_index: Optional[int] = None  # the SLAM map the robot tracks in (slam/state)
    # (from, into) SLAM map indices: the map changed while tracking, so SLAM merged `from` into
    # `into` (or re-anchored it there): what was found in `from` lives on in `into`.
    slam_merges: Tuple = ()
    map_ready: bool = False              # a grid with free cells around the robot exists
    robot_xy: Optional[Tuple[float, float]] = None
    robot_in_obstacle: bool = False
    scan_running: bool = False
    scan_failed: bool = False            # the last scan ended with too many soft fails
    scan_share_done: float = 0.0         # ... after this share of its steps succeeded
    scan_resumable: bool = False         # a stopped phase scan has steps left to go on with
    exit_xy: Optional[Tuple[float, float]] = None  # the newest answer of the exit finder
    exit_alternatives: Tuple = ()        # its further candidates, best first
    exit_answered: bool = False          # the exit finder answered since the last request
    exit_leads_out: bool = True          # the map shows free space beyond exit_xy (a way out)
    # The exit finder's room outline [(x, y), ...] in the current SLAM map; empty when unknown
    # or drawn in another SLAM map.
    room_outline: Tuple = ()
    # GridView.walls_around at the robot (bearings from the map's x axis), while looking around
    # beyond an exit; empty without a map or a pose.
    walls_around: Tuple = ()
    # GridView.side_walls_beyond_m of room_outline at the door come through, while looking around:
    # metres of the room's side walls the map shows carried on past the door's wall; None
    # without an outline (or a door) to measure them on.
    side_walls_beyond_m: Optional[float] = None
    # The navigator's goal: "planning" (accepted, no map or pose to plan on yet), "following",
    # "reached", "no_path", "goal_in_obstacle"; empty without a goal.
    navigator_state: str = ""
    motion_failed: bool = False          # the motion layer gave up (blocked, refused commands)
    start_requested: bool = False
    stop_requested: bool = False
    return_requested: bool = False


@dataclasses.dataclass
class ConductorConfig:
    """Mission limits; defaults written once here."""

    wall_scan_enabled: bool = False      # 000 step 2 (off: in the sim its approaches cost losses)
    max_scan_rounds: int = 3             # initial scans without a map before giving up
    scan_map_min_share: float = 0.5      # a scan's SLAM map at its end must have tracked this
                                         # share of its time (merges count): else a new map
                                         # holds too little of the room, and it is scanned again
    failed_scan_min_share_done: float = 0.75  # an initial scan failed (too many soft fails)
                                         # after this share of its steps succeeded counts as
                                         # done: the map holds most of the room, and a new
                                         # round would take minutes to see it again
    max_scan_resumes: int = 15           # a phase scan cut by losses goes on where it was cut
                                         # this often; then the phase's rules judge it as cut
    max_exit_attempts: int = 3           # exit finder answers without an exit before giving up
    exit_answer_timeout_s: float = 20.0  # no answer from the exit finder in this time: retry
    max_goal_failures: int = 3           # navigator no_path/goal_in_obstacle answers per goal
    max_goal_losses: int = 3             # tracking lost this often in a row on the way to an
                                         # exit, never stall_progress_m closer between losses:
                                         # a route the camera cannot track along; next exit
                                         # (passing through: the pass-through ends there)
    goal_failure_grace_s: float = 10.0   # a failure must last this long to count (replanning)
    pass_through_m: float = 1.5          # beyond the exit, away from the room
    exit_check_near_m: float = 0.3       # the map is asked about free space this far beyond an
    exit_check_far_m: float = 1.2        # ... exit candidate up to this far (m): candidates with
    exit_min_free_share: float = 0.1     # at least this share free there go first
    reached_tolerance_m: float = 0.4     # the navigator's "reached" or this close counts
    left_room_margin_m: float = 1.0      # lost this far outside the outline passing through,
    left_room_wait_s: float = 20.0       # ... and not back within this: out (back: another room?)
    look_lost_out_s: float = 12.0        # looking around, tracking lost this long (more than a
                                         # relocalising try, wherever the robot is): out. A room
                                         # has walls to start a new map on at the first try
    look_lost_out_min_tracked_s: float = 1.0  # ... once the look has tracked this long (s); a
                                         # look begun lost (a pass-through cut short by losses)
                                         # has seen nothing yet: out only after lost_timeout_s
    inside_room_margin_m: float = 0.5    # passed through yet this far inside the outline: the
    rejected_exit_radius_m: float = 1.0  # ... exit was wrong; later candidates this close to it
                                         # are skipped
    back_out_door_radius_m: float = 2.5  # passed through a further room's exit back into the
                                         # room before this close to the door come out of: the
                                         # same door (back out); farther, the exit was wrong
    stall_timeout_s: float = 30.0        # no progress toward a goal for this long: a goal failure
    stall_progress_m: float = 0.2        # ... progress: this much closer than ever before
    exit_near_m: float = 1.0             # stalled this close to the exit (the point beyond it):
                                         # pass through (look around) from there
    lost_timeout_s: float = 60.0         # tracking lost this long: gave up (out, past an exit)
    scan_retry_lost_s: float = 5.0       # lost this long in a scan's retries (one step undone
                                         # and redone on one line): stop it, relocalise instead
    recover_timeout_s: float = 30.0      # inside an obstacle longer than this: gave up
    recover_clear_s: float = 10.0        # back inside within this of getting out: the same
                                         # episode, its time counts on (a robot on a cell's edge)
    merge_wait_s: float = 20.0           # tracking back in another SLAM map than the exit's:
                                         # relocalise this long for a merge back, then go on in
                                         # the new map (look around beyond the exit, else scan)
    max_rescans: int = 2                 # ... initial scans in a new map before giving up
    map_settle_s: float = 5.0            # a scan that ends within this of a SLAM map change
                                         # is judged this long after it: a new map often merges
                                         # back within seconds, and a grid seconds old holds
                                         # no room to look for the exit in
    max_rooms: int = 5                   # rooms escaped in turn; 1: done after the first exit
                                         # without looking around. A false exit in a room's
                                         # free middle leads into that room again, and counts
    room_max_opening_deg: float = 42.5   # beyond an exit, openings no wider than this all round
                                         # (the door come through aside): another room; between
                                         # the 5-deg bearings, so 45 deg counts as a way out
    walls_around_range_m: float = 8.0    # ... walls this close count (the node's grid query)
    room_side_walls_min_m: float = 0.5   # the room's side walls mapped this far on past the
                                         # door's wall: another room however wide the openings
                                         # (a partition's door; a blank wall ahead), unless the
                                         # look is lossy (below); less, or no outline to
                                         # measure them on: the openings decide
    lossy_look_min_losses: int = 1       # a look around that lost tracking this often judges
    lossy_look_max_opening_deg: float = 32.5  # ... its openings by this limit instead of
                                         # room_max_opening_deg (a 35-deg opening is out),
                                         # whatever the side walls
    partial_look_means_out: bool = True  # a look around that lost tracking and ended in a
                                         # SLAM map begun during it (no merge back) judges
                                         # its openings on a few seconds of map: out (done)
                                         # instead; beyond a door a camera loses tracking
                                         # in open space, and rarely in a room
    tracked_look_is_a_room: bool = True  # a look around that never lost tracking (sudden
                                         # losses aside), with a room outline to measure the
                                         # side walls on: another room however wide the
                                         # openings and short the side walls (a camera facing
                                         # open space loses tracking)
    recheck_lossy_look: bool = True      # a look around out by its losses alone (without them:
                                         # another room) looks around again in place, and is
                                         # out only if that look loses tracking too
    recheck_lossy_look_max_losses: int = 2  # ... when it lost tracking at most this often: a
                                         # glitch in a room costs a loss or two, open space
                                         # more (a look with more is out at once)
    sudden_loss_min_tracked_points: int = 200  # a loss with this many map points tracked at
                                         # it (a blurred or covered camera, not a view with too
                                         # little in it) is no sign of open space: a look
                                         # around does not count it
    step_out_min_outside_m: float = 1.0  # a look around says out with the robot less than this
                                         # outside the room outline: it goes on to the point
                                         # beyond the exit first (a look's relocalising sways,
                                         # or a pass-through cut short by losses, leave it in
                                         # the door); 0: done where it stands

    def validate(self):
        for name in ("max_scan_rounds", "max_scan_resumes", "max_exit_attempts",
                     "max_goal_failures", "max_goal_losses", "max_rooms", "max_rescans",
                     "lossy_look_min_losses", "sudden_loss_min_tracked_points",
                     "recheck_lossy_look_max_losses"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("exit_answer_timeout_s", "goal_failure_grace_s", "reached_tolerance_m",
                     "lost_timeout_s", "recover_timeout_s", "recover_clear_s",
                     "left_room_margin_m", "inside_room_margin_m", "rejected_exit_radius_m",
                     "back_out_door_radius_m",
                     "stall_timeout_s", "stall_progress_m", "exit_near_m",
                     "walls_around_range_m", "room_side_walls_min_m", "merge_wait_s",
                     "map_settle_s", "left_room_wait_s", "scan_retry_lost_s",
                     "look_lost_out_s", "look_lost_out_min_tracked_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        if not 0 <= self.exit_check_near_m < self.exit_check_far_m < math.inf:
            raise ValueError("need 0 <= exit_check_near_m < exit_check_far_m (finite)")
        if not 0 <= self.failed_scan_min_share_done <= 1:
            raise ValueError(f"failed_scan_min_share_done must be in [0, 1], got "
                             f"{self.failed_scan_min_share_done}")
        if not 0 <= self.scan_map_min_share <= 1:
            raise ValueError(f"scan_map_min_share must be in [0, 1], got "
                             f"{self.scan_map_min_share}")
        if not 0 <= self.exit_min_free_share <= 1:
            raise ValueError(f"exit_min_free_share must be in [0, 1], got "
                             f"{self.exit_min_free_share}")
        if not 0 < self.room_max_opening_deg < 360:
            raise ValueError(f"room_max_opening_deg must be in (0, 360), got "
                             f"{self.room_max_opening_deg}")
        if not 0 < self.lossy_look_max_opening_deg <= self.room_max_opening_deg:
            raise ValueError(f"lossy_look_max_opening_deg must be in (0, room_max_opening_deg], "
                             f"got {self.lossy_look_max_opening_deg}")
        for name in ("pass_through_m", "step_out_min_outside_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")


@dataclasses.dataclass(frozen=True)
class Transition:
    time_s: float
    state: State
    phase: Phase
    reason: str


_FAILED_NAVIGATION = ("no_path", "goal_in_obstacle")
# Where a loss with the robot last tracked clearly outside the room outline means out.
_BEYOND_THE_EXIT = (Phase.PASS_THROUGH, Phase.LOOK_AROUND, Phase.STEP_OUT)


def distance_outside(xy, outline):
    """How far (same units) the point xy lies outside the polygon outline; 0 inside it or
    when there is no outline (fewer than three vertices)."""
    return max(0.0, _signed_distance_outside(xy, outline))


def distance_inside(xy, outline):
    """How far the point xy lies inside the polygon outline (from its boundary); 0 outside it or
    when there is no outline."""
    return max(0.0, -_signed_distance_outside(xy, outline))


def _signed_distance_outside(xy, outline):
    poly = np.asarray(outline, dtype=float).reshape(-1, 2)
    if len(poly) < 3 or xy is None:
        return 0.0
    q = np.asarray(xy, dtype=float).reshape(1, 2)
    d = float(boundary_distances(q, poly)[0][0])
    return -d if points_in_polygon(q, poly)[0] else d


class Conductor:
    """Decides the mission's next actions from observations; see the module docstring."""

    def __init__(self, config=None):
        self.config = config or ConductorConfig()
        self.config.validate()
        self.state = State.IDLE
        self.phase = Phase.WAITING
        self.reason = "waiting for start"
        self.history: List[Transition] = []
        self.start_xy: Optional[Tuple[float, float]] = None
        # Where the present room's exit search looks from: the start, then the place looked
        # around from in each further room.
        self.room_origin_xy: Optional[Tuple[float, float]] = None
        self.rooms = 0
        self._exit_viewpoint = None  # the exit finder's viewpoint: its default, "robot" later
        self.exit_xy: Optional[Tuple[float, float]] = None
        self._alternatives: List[Tuple[float, float]] = []
        self._alternatives_map = None  # the SLAM map they (and exit_xy) were found in
        self._merge_wait_since_s = None  # tracking back in another map than the exit's, since
        self._rescans = 0
        self._door_xy = None  # the exit come through, where the robot looks around
        self._room_before_origin_xy = None  # room_origin_xy of the room the door led out of
        # The room before's outline, the SLAM map it was drawn in, its door come out of, and where
        # the look that took the place beyond that door for another room stood.
        self._room_before_outline = ()
        self._room_before_map = None
        self._room_before_door_xy = None
        self._room_look_xy = None
        self._room_unconfirmed = False  # walls all round, no exit of theirs found yet
        # Exits passed through without leaving the room. They hold in every SLAM map: slam_bridge
        # anchors a new map where the robot was last tracked, and such a door is near it.
        self._rejected: List[Tuple[float, float]] = []
        self.goal_xy: Optional[Tuple[float, float]] = None
        self._resume_state = State.IDLE
        self._scan_rounds = 0
        self._exit_attempts = 0
        self._exit_requested_s = None
        self._exit_answer = None  # (exit_xy, alternatives, leads_out) not acted on yet
        self._exit_paused_s = None  # when LOST or RECOVER interrupted the wait for the answer
        self._goal_failures = 0
        self._failure_since_s = None
        self._progress = None  # (time, best distance to the goal) of the last progress
        self._progress_paused = None  # (first, last) tick of LOST or RECOVER since progress
        self._goal_losses = 0  # losses in a row on the way to the goal without coming closer
        self._loss_distance = None  # the closest to the goal at those losses
        self._lost_since_s = None  # start of the present unbroken loss; None while tracking
        self._recover_since_s = None
        self._recover_left_s = None  # when the robot's cell was last found free again
        self._scan_started = False
        self._scan_cut = False  # the running phase scan ended while tracking was lost
        self._scan_kind = None
        self._scan_resumes = 0  # of the present phase scan
        # Sim-seconds the running phase scan tracked in each SLAM map (merges added up).
        self._scan_tracked_s: Dict[Optional[int], float] = {}
        self._last_time_s = None
        self._map_index_seen = None
        self._merges_applied = 0  # how many of Observation.slam_merges are applied
        self._map_changed_s = None  # when the SLAM map index last changed
        self._last_tracked_xy: Optional[Tuple[float, float]] = None
        # Beyond the exit: how far outside the room outline the robot was last tracked while the
        # outline was at hand (a change of SLAM map takes the outline away, not where it was).
        self._outside_by = 0.0
        self._step_out_why = ""  # the look around's verdict that sent the robot stepping out
        # (walls_around, side_walls_beyond_m) of the newest look around while tracking
        self._last_look = ((), None)
        self._look_losses = 0  # tracking losses of the present look around (few points tracked)
        self._look_sudden_losses = 0  # ... and those with plenty tracked (not counted above)
        self._look_rechecked = False  # the present look around is a second one (recheck_lossy_look)
        # SLAM map indices count up for each new map (merges go back to an older one): the
        # highest seen, and the highest seen when the present look around began.
        self._max_map_index = None
        self._look_known_map_index = None

    def _scan(self, name):
        """The SCAN action; _start_state waits for it to begin, then to end."""
        if name not in ("relocalise", "resume"):
            self._scan_resumes = 0
            self._scan_tracked_s = {}
        self._scan_kind = name
        self._scan_started = False
        return Action(ActionKind.SCAN, name)

    def _set(self, time_s, state, phase, reason):
        if (state, phase, reason) != (self.state, self.phase, self.reason):
            self.state, self.phase, self.reason = state, phase, reason
            self.history.append(Transition(time_s, state, phase, reason))

    @property
    def running(self):
        return self.phase not in (Phase.WAITING, Phase.DONE, Phase.GAVE_UP)

    def update(self, obs: Observation) -> List[Action]:
        """One tick: the actions to carry out now (often none)."""
        t = obs.time_s
        if obs.stop_requested:
            if self.running:
                self._set(t, State.IDLE, Phase.WAITING, "stopped on request")
                return [Action(ActionKind.CANCEL_GOAL), Action(ActionKind.STOP)]
            return []
        if obs.start_requested and not self.running:
            self._begin(t, obs)
            return [self._scan("initial")]
        if not self.running:
            return []
        if obs.return_requested and self.start_xy is not None:
            return self._navigate(t, Phase.RETURN_TO_START, self.start_xy, "return to start requested")

        self._follow_merges(obs)
        dt = 0.0 if self._last_time_s is None else max(0.0, t - self._last_time_s)
        self._last_time_s = t
        if self.state == State.START and obs.scan_running and not obs.tracking_lost:
            key = obs.slam_map_index
            self._scan_tracked_s[key] = self._scan_tracked_s.get(key, 0.0) + dt
        if obs.slam_map_index is not None:
            self._max_map_index = max(obs.slam_map_index, self._max_map_index or 0)
        if obs.slam_map_index != self._map_index_seen:
            if self._map_index_seen is not None:
                self._map_changed_s = t
            self._map_index_seen = obs.slam_map_index
        # Timed from the observations, not from entering LOST: tracking back in another SLAM map
        # keeps the state LOST, and forced losses every 30 s must not add up to lost_timeout_s.
        if not obs.tracking_lost:
            self._lost_since_s = None
        elif self._lost_since_s is None:
            self._lost_since_s = t
        out = self._left_the_room(t, obs)
        if out is not None:
            return out
        if not obs.tracking_lost and obs.robot_xy is not None:
            self._last_tracked_xy = tuple(obs.robot_xy)
            if self.phase in _BEYOND_THE_EXIT and len(obs.room_outline) >= 3:
                self._outside_by = distance_outside(obs.robot_xy, obs.room_outline)
            if self.phase == Phase.LOOK_AROUND and len(obs.walls_around):
                self._last_look = (tuple(obs.walls_around), obs.side_walls_beyond_m)
        if self.phase == Phase.FIND_EXIT and obs.exit_answered:
            # Seen once: an answer that arrives while lost or recovering is acted on after.
            self._exit_answer = (obs.exit_xy, tuple(obs.exit_alternatives), obs.exit_leads_out)
        safety = self._safety(t, obs)
        if safety is not None:
            # Time lost or recovering is not a stall, but it does not restart the stall clock
            # either: with a loss every 30 s, a robot parked short of an exit never stalled for
            # stall_timeout_s and waited for max_goal_losses losses instead (random:26).
            if self._progress is not None:
                self._progress_paused = ((self._progress_paused or (t, t))[0], t)
            if self.phase == Phase.FIND_EXIT and self._exit_paused_s is None:
                self._exit_paused_s = t
            return safety
        if self.state == State.START:
            return self._start_state(t, obs)
        if self.phase == Phase.FIND_EXIT:
            return self._find_exit(t, obs)
        if self.state == State.GOAL:
            return self._goal_state(t, obs)
        return []

    def _begin(self, t, obs):
        self.start_xy = self.room_origin_xy = obs.robot_xy
        self.rooms = 1
        self._exit_viewpoint = None
        self._alternatives = []
        self._alternatives_map = self._merge_wait_since_s = None
        self._rescans = 0
        self._last_look = ((), None)
        self._outside_by = 0.0
        self._room_unconfirmed = False
        self.exit_xy = self.goal_xy = None
        self._rejected = []
        self._scan_rounds = 1
        self._exit_attempts = 0
        self._set(t, State.START, Phase.INITIAL_SCAN, "mission started: initial scan")

    def _give_up(self, t, why):
        self._set(t, State.IDLE, Phase.GAVE_UP, why)
        return [Action(ActionKind.CANCEL_GOAL), Action(ActionKind.STOP)]

    def _left_the_room(self, t, obs):
        """DONE when tracking is lost while passing through or looking around beyond the exit
        with the last tracked position clearly outside the room outline, and not back within
        left_room_wait_s: a robot often loses tracking right after a door, facing what it has
        never seen. Tracking that comes back there is a room with walls to track (beyond a
        partition's door), whose look around decides. Without a loss the pass-through goal
        and the look around decide, because the outline covers only what the scan saw (an
        L-shaped room's far arm lies outside it).

        Looking around, a loss not relocalised within look_lost_out_s (more than the first
        relocalising try) is out wherever the robot was last tracked: a room has walls to start
        a new map on (config/conductor.yaml gives the runs that set it). A look that has not
        yet tracked look_lost_out_min_tracked_s has seen nothing beyond the door: its loss,
        often the pass-through's in a false exit, waits lost_timeout_s."""
        cfg = self.config
        if not obs.tracking_lost or self.state != State.LOST:
            return None
        lost_s = t - self._lost_since_s
        if self.phase == Phase.LOOK_AROUND:
            looked = self._scan_tracked_total_s() >= cfg.look_lost_out_min_tracked_s
            limit = cfg.look_lost_out_s if looked else cfg.lost_timeout_s
            if lost_s > limit:
                when = "looking around" if looked else "as the look around began"
                self._set(t, State.IDLE, Phase.DONE,
                          f"passed through the exit: tracking lost {when} and not back in "
                          f"{limit:g} s of relocalising: too little around to track, out")
                return [Action(ActionKind.CANCEL_GOAL), Action(ActionKind.STOP)]
        outside = self._lost_outside_by()
        if outside is None or outside < cfg.left_room_margin_m or lost_s < cfg.left_room_wait_s:
            return None
        return self._out(t, outside, f" and not back in {cfg.left_room_wait_s:g} s")

    def _lost_outside_by(self):
        """While passing through, looking around beyond the exit or stepping out, how far
        outside the room outline the robot was last tracked (0 inside it or without an outline);
        else None."""
        if self.phase not in _BEYOND_THE_EXIT:
            return None
        return self._outside_by

    def _out(self, t, outside, why):
        self._set(t, State.IDLE, Phase.DONE,
                  f"left the room: tracking lost {outside:.2f} m outside its outline{why}")
        return [Action(ActionKind.CANCEL_GOAL), Action(ActionKind.STOP)]

    def _safety(self, t, obs):
        """LOST and RECOVER take over from any state; None when neither applies."""
        cfg = self.config
        if obs.tracking_lost:
            if self.state != State.LOST:
                if self.state != State.RECOVER:  # RECOVER resumes the state it interrupted
                    self._resume_state = self.state
                self._count_goal_loss()
                tracked = obs.slam_tracked_points or 0
                lost = f"SLAM tracking lost ({tracked} map points tracked at it)"
                if self.phase == Phase.LOOK_AROUND:
                    if tracked >= cfg.sudden_loss_min_tracked_points:
                        self._look_sudden_losses += 1
                    else:
                        self._look_losses += 1
                if obs.slam_map_given_up:
                    lost += ", and SLAM gave up its map"
                elif self.state == State.START and obs.scan_running:
                    # The scan's retry mechanism undoes and redoes steps until tracking is back.
                    self._set(t, State.LOST, self.phase, f"{lost}: the scan retries")
                    return []
                self._set(t, State.LOST, self.phase, f"{lost}: stopped, relocalising")
                return [Action(ActionKind.STOP), self._scan("relocalise")]
            if t - self._lost_since_s > cfg.lost_timeout_s:
                # Within left_room_margin_m the robot may still be in the door; but one there,
                # turning to relocalise, would see the mapped room again: still lost, it is out.
                outside = self._lost_outside_by()
                if outside is not None and outside > 0:
                    return self._out(t, outside, f" and not back in {cfg.lost_timeout_s:g} s "
                                                 f"of relocalising")
                if self.phase == Phase.STEP_OUT:
                    return self._stepped_out(t, f"tracking lost stepping out and not back in "
                                                f"{cfg.lost_timeout_s:g} s: done where it was lost")
                return self._give_up(t, f"SLAM tracking lost for more than {cfg.lost_timeout_s:g} s")
            if not obs.scan_running:
                return [self._scan("relocalise")]
            if self._scan_kind != "relocalise":
                # A retried step goes back and forth along one short line: too little baseline
                # for SLAM to start a new map (0.3 m for 30 s in a ground robot's scan). The
                # retries bring back a view of the map, which helps only while SLAM still
                # relocalises in it.
                if obs.slam_map_given_up:
                    why = "SLAM gave up its map, and the scan's retries give no baseline for a new one"
                elif t - self._lost_since_s > cfg.scan_retry_lost_s:
                    why = f"SLAM tracking not back in {cfg.scan_retry_lost_s:g} s of the scan's retries"
                else:
                    return []
                self._set(t, State.LOST, self.phase, f"{why}: relocalising")
                return [Action(ActionKind.STOP), self._scan("relocalise")]
            return []
        if self.state == State.LOST and self._goal_in_another_map(obs):
            return self._wait_for_merge(t, obs)
        self._merge_wait_since_s = None
        if self.state == State.LOST:
            self._set(t, self._resume_state, self.phase, "SLAM tracking back")
            actions = []
            if self._scan_kind == "relocalise" and obs.scan_running:
                actions.append(Action(ActionKind.STOP))
                obs_scan_running = False
            else:
                obs_scan_running = obs.scan_running
            if self._resume_state == State.GOAL and self._goal_losses >= cfg.max_goal_losses:
                if self.phase == Phase.GO_TO_EXIT:
                    why = (f"SLAM tracking lost {self._goal_losses} times on the way to the exit "
                           f"({self.exit_xy[0]:.2f}, {self.exit_xy[1]:.2f}) without coming closer")
                    return actions + self._next_exit(t, why, why, scan_first=True)
                if self.phase == Phase.PASS_THROUGH:
                    return actions + self._pass_through_untrackable(t, obs)
                if self.phase == Phase.STEP_OUT:
                    return actions + self._stepped_out(
                        t, f"SLAM tracking lost {self._goal_losses} times stepping out without "
                           f"coming closer: done here")
            if self._resume_state == State.GOAL and self.goal_xy is not None:
                actions.append(Action(ActionKind.GOAL, self.goal_xy))  # the map may be new
            elif self._resume_state == State.START and not obs_scan_running:
                # The scan ended while tracking was lost: cut short. Not restarted here (a robot
                # that keeps losing tracking would scan forever); the phase's bounded rules decide.
                self._scan_started = self._scan_cut = True
            return actions
        recover_expired = (self._recover_since_s is not None
                           and t - self._recover_since_s > cfg.recover_timeout_s)
        if self.state == State.RECOVER:
            if obs.scan_running:
                return []  # the recovery motion runs; the cell is judged where it ends
            if obs.map_ready and obs.robot_in_obstacle:
                if recover_expired:
                    return self._give_up(t, f"inside an obstacle for more than "
                                            f"{cfg.recover_timeout_s:g} s")
                return [Action(ActionKind.RECOVER_MOTION)]
            self._recover_left_s = t
            self._set(t, self._resume_state, self.phase, "the robot's cell is free again")
            if self._resume_state == State.GOAL and self.goal_xy is not None:
                return [Action(ActionKind.GOAL, self.goal_xy)]
            return None
        # A phase scan that has just ended is read by the phase's rules first: a recovery motion
        # started now would look to them like that scan still running, and so on without end.
        scan_end_unread = self.state == State.START and self._scan_started
        if obs.map_ready and obs.robot_in_obstacle and not obs.scan_running and not scan_end_unread:
            relapse = (self._recover_left_s is not None
                       and t - self._recover_left_s < cfg.recover_clear_s)
            if not relapse:
                self._recover_since_s = t
            elif recover_expired:
                return self._give_up(t, f"inside an obstacle for more than "
                                        f"{cfg.recover_timeout_s:g} s")
            self._resume_state = self.state
            self._set(t, State.RECOVER, self.phase, "the map puts the robot inside an obstacle")
            return [Action(ActionKind.STOP), Action(ActionKind.RECOVER_MOTION)]
        return None

    def _follow_merges(self, obs):
        """What was filed under a SLAM map that has since merged into another (the exit and its
        alternatives, the running scan, rejected exits) is filed under the one it merged into."""
        for old, new in obs.slam_merges[self._merges_applied:]:
            if self._alternatives_map == old:
                self._alternatives_map = new
            if self._room_before_map == old:
                self._room_before_map = new
            if old in self._scan_tracked_s:
                self._scan_tracked_s[new] = (self._scan_tracked_s.get(new, 0.0)
                                             + self._scan_tracked_s.pop(old))
        self._merges_applied = len(obs.slam_merges)

    def _scan_map_share(self, obs):
        """Share of the running phase scan's tracked time that the SLAM map tracked now holds
        (maps merged into it count); 1 before any."""
        tracked = self._scan_tracked_total_s()
        return self._scan_tracked_s.get(obs.slam_map_index, 0.0) / tracked if tracked else 1.0

    def _scan_tracked_total_s(self):
        """Sim-seconds the running phase scan tracked, in all SLAM maps."""
        return sum(self._scan_tracked_s.values())

    def _goal_in_another_map(self, obs):
        """Tracking is back on the way to or through an exit, but in another SLAM map than the
        one the exit was found in (or merged into since): its coordinates mean nothing there."""
        return (self._resume_state == State.GOAL
                and self.phase in (Phase.GO_TO_EXIT, Phase.PASS_THROUGH, Phase.BACK_OUT,
                                   Phase.STEP_OUT)
                and None not in (self._alternatives_map, obs.slam_map_index)
                and obs.slam_map_index != self._alternatives_map)

    def _wait_for_merge(self, t, obs):
        """Relocalise (stay LOST) until SLAM merges the new map back into the exit's, at most
        merge_wait_s; then go on in the new map: through the exit already, look around there;
        else scan the room again and find the exit in it."""
        cfg = self.config
        if self._merge_wait_since_s is None:
            self._merge_wait_since_s = t
            self._set(t, State.LOST, self.phase, f"SLAM tracking back in map "
                      f"{obs.slam_map_index}, not the exit's map {self._alternatives_map}: "
                      f"relocalising until they merge")
        if t - self._merge_wait_since_s <= cfg.merge_wait_s:
            return [] if obs.scan_running else [self._scan("relocalise")]
        self._merge_wait_since_s = None
        stop = [Action(ActionKind.STOP)] if obs.scan_running else []
        why = f"no merge back into the exit's SLAM map within {cfg.merge_wait_s:g} s"
        if self.phase == Phase.STEP_OUT:
            return stop + self._stepped_out(t, f"{why} stepping out: done here")
        if self.phase in (Phase.PASS_THROUGH, Phase.BACK_OUT):
            return stop + self._look_around(t, f"{why}, past the exit: look around in the new "
                                               f"map", door_xy=self.exit_xy)
        if self._rescans >= cfg.max_rescans:
            return stop + self._give_up(t, f"{why}, after {self._rescans} scans in new maps")
        self._rescans += 1
        self._scan_rounds = 1
        self._exit_attempts = 0
        self.room_origin_xy = obs.robot_xy
        self._alternatives = []
        self._set(t, State.START, Phase.INITIAL_SCAN, f"{why}: scan the room again in the new "
                                                      f"map ({self._rescans}/{cfg.max_rescans})")
        return stop + [Action(ActionKind.CANCEL_GOAL), self._scan("initial")]

    def _pass_through_untrackable(self, t, obs):
        """Tracking lost max_goal_losses times passing through, never closer to the point beyond:
        a camera facing a wall up close (a false exit) or open space (out, a wall beyond too
        near for the point beyond). Still inside the room outline, the exit was wrong; else the
        look around from here decides, as it would have from the point beyond."""
        why = (f"SLAM tracking lost {self._goal_losses} times passing through "
               f"({self.exit_xy[0]:.2f}, {self.exit_xy[1]:.2f}) without coming closer to the "
               f"point beyond")
        return (self._wrong_exit_if_inside(t, obs, f"{why},")
                or self._look_around(t, f"{why}: look around from here", self.exit_xy))

    def _count_goal_loss(self):
        """A loss on the way to an exit or through it counts when the robot came no closer since
        the last one (a forced or occasional loss on a route that makes progress does not)."""
        if self.state != State.GOAL or self.phase not in (Phase.GO_TO_EXIT, Phase.PASS_THROUGH,
                                                          Phase.STEP_OUT) \
                or self._last_tracked_xy is None or self.goal_xy is None:
            return
        distance = math.dist(self._last_tracked_xy, self.goal_xy)
        if self._loss_distance is not None \
                and distance > self._loss_distance - self.config.stall_progress_m:
            self._goal_losses += 1
        else:
            self._goal_losses = 1
        self._loss_distance = (distance if self._loss_distance is None
                               else min(distance, self._loss_distance))

    def _start_state(self, t, obs):
        cfg = self.config
        if obs.scan_running:
            self._scan_started = True
            return []
        if not self._scan_started:
            return []  # the scan was asked for and has not begun yet
        if self._scan_cut and obs.scan_resumable and self._scan_resumes < cfg.max_scan_resumes:
            # Restarted after every loss, a scan longer than the time between losses (the
            # ground robot's initial scan takes 150 s) would never end. What SLAM mapped before
            # the loss is in the map again once the new map merges back.
            self._scan_cut = False
            self._scan_resumes += 1
            self._set(t, State.START, self.phase, f"SLAM tracking back: the scan goes on where "
                      f"the loss cut it ({self._scan_resumes}/{cfg.max_scan_resumes})")
            return [self._scan("resume")]
        if self._map_changed_s is not None and t - self._map_changed_s < cfg.map_settle_s:
            return []  # judged once the new SLAM map has merged back or grown a grid
        self._scan_started = False
        # Cut short: steps never run. A scan that ran all its steps, the last while lost, is
        # judged as any scan that ended (a new SLAM map by scan_map_min_share).
        cut, self._scan_cut = self._scan_cut and obs.scan_resumable, False
        if self.phase == Phase.LOOK_AROUND:
            return self._looked_around(t, obs)
        if self.phase == Phase.INITIAL_SCAN:
            # A loss that ended in a new SLAM map that did not merge back leaves a map (and a
            # grid) of the part of the room scanned since: when that part is small, scan the
            # whole room again in it while rounds are left; so does a scan cut short by a loss.
            rounds_left = self._scan_rounds < cfg.max_scan_rounds
            map_changed = self._scan_map_share(obs) < cfg.scan_map_min_share and rounds_left
            cut = cut and rounds_left
            failed = obs.scan_failed and obs.scan_share_done < cfg.failed_scan_min_share_done
            if obs.map_ready and not failed and not map_changed and not cut:
                done = (f"initial scan failed {obs.scan_share_done:.0%} through, most of the "
                        f"room seen" if obs.scan_failed else "initial scan done")
                if cfg.wall_scan_enabled:
                    self._set(t, State.START, Phase.WALL_SCAN, f"{done}: wall scan")
                    return [self._scan("wall")]
                return self._ask_exit(t, f"{done}: find the exit")
            if obs.map_ready and not rounds_left:
                # Scans that keep failing (tracking lost over and over) still leave a map: the
                # exit is looked for in it rather than given up with a map at hand.
                return self._ask_exit(t, f"the last of {self._scan_rounds} scans "
                                         f"{'failed' if obs.scan_failed else 'ended'}: find the "
                                         f"exit in the map there is")
            if self._scan_rounds >= cfg.max_scan_rounds:
                return self._give_up(t, f"no navigable map after {self._scan_rounds} scans")
            self._scan_rounds += 1
            why = (f"scan failed {obs.scan_share_done:.0%} through" if obs.scan_failed else
                   "the SLAM map changed during the scan" if map_changed else
                   "the scan ended while SLAM tracking was lost" if cut else "no navigable map yet")
            self._set(t, State.START, Phase.INITIAL_SCAN, f"{why}: scan again "
                      f"({self._scan_rounds}/{cfg.max_scan_rounds})")
            return [self._scan("initial" if self._scan_rounds % 2 else "random")]
        return self._ask_exit(t, "the scan ended while SLAM tracking was lost: find the exit" if cut
                              else "wall scan done: find the exit")

    def _ask_exit(self, t, why):
        self._exit_attempts += 1
        self._exit_requested_s = t
        self._exit_answer = self._exit_paused_s = None
        self._set(t, State.IDLE, Phase.FIND_EXIT, why)
        # Not in a room come into: there no exit but the door come through is an answer too.
        last = (self._exit_attempts >= self.config.max_exit_attempts
                and not self._room_unconfirmed)
        return [Action(ActionKind.FIND_EXIT, ExitRequest(self._exit_viewpoint, last))]

    @property
    def door_xy(self):
        """The exit come through, beyond which the robot looks around (None before one)."""
        return self._door_xy

    def _widest_opening(self, walls):
        """The widest opening around the robot but the one toward the exit it came through."""
        skip = None
        if self._door_xy is not None and self._last_tracked_xy is not None:
            skip = math.atan2(self._door_xy[1] - self._last_tracked_xy[1],
                              self._door_xy[0] - self._last_tracked_xy[0])
        return widest_opening_deg(walls, skip)

    def _look_around(self, t, why, door_xy):
        """Beyond the exit: look around there, door_xy the door come through; done at once
        with max_rooms 1."""
        if self.config.max_rooms == 1:
            self._set(t, State.IDLE, Phase.DONE, "passed through the exit")
            return [Action(ActionKind.CANCEL_GOAL), Action(ActionKind.STOP)]
        self._last_look = ((), None)
        self._look_losses = self._look_sudden_losses = 0
        self._look_known_map_index = self._max_map_index
        self._look_rechecked = False
        self._door_xy = door_xy
        self._set(t, State.START, Phase.LOOK_AROUND, why)
        return [Action(ActionKind.CANCEL_GOAL), self._scan("look_around")]

    def _looked_around(self, t, obs):
        """The room's side walls going on past the door's wall, walls all round (but for the
        door come through) whatever the side walls, or tracking kept all the way round beside a
        room outline: another room, whose exit is looked for from here, the door come through
        out of the running; else out: done (config/conductor.yaml says why side walls ending at
        the door's wall no longer mean out)."""
        cfg = self.config
        walls, side_m = ((tuple(obs.walls_around), obs.side_walls_beyond_m) if obs.walls_around
                         else self._last_look)
        if not len(walls):
            self._set(t, State.IDLE, Phase.DONE, "passed through the exit (no map to look "
                                                 "around in)")
            return [Action(ActionKind.STOP)]
        # Part of the look tracked in a map it did not end in, begun during it and never merged
        # back (tracking back in an older map is no sign of too little to track: that map knew
        # the place).
        known = self._look_known_map_index
        begun_since = obs.slam_map_index is not None and (known is None
                                                          or obs.slam_map_index > known)
        one_map = self._scan_map_share(obs) >= 1.0
        partial = self._look_losses > 0 and not one_map and begun_since
        if partial and cfg.partial_look_means_out:
            before = ", ".join(str(k) for k in self._scan_tracked_s if k != obs.slam_map_index)
            self._set(t, State.IDLE, Phase.DONE,
                      f"passed through the exit: tracking lost looking around ({self._look_losses} "
                      f"losses), and the look ended in SLAM map {obs.slam_map_index}, begun since, "
                      f"not in map {before}: too little around to track, out")
            return [Action(ActionKind.STOP)]
        opening = self._widest_opening(walls)
        seen = f"openings up to {opening:.0f} deg wide"
        # A camera facing open space loses tracking; one facing a room's walls rarely does.
        lossy = self._look_losses >= cfg.lossy_look_min_losses
        wide = opening > (cfg.lossy_look_max_opening_deg if lossy else cfg.room_max_opening_deg)
        walled_beside = side_m is not None and side_m >= cfg.room_side_walls_min_m
        # Beside a room outline, a look that kept tracking all the way round faced walls.
        tracked_in_room = cfg.tracked_look_is_a_room and not lossy and side_m is not None
        if side_m is None:
            side = "no room outline to measure the room's side walls on"
        elif walled_beside:
            side = f"the room's side walls go on {side_m:.1f} m past the door's wall"
        else:
            side = f"the room's side walls end at the door's wall ({side_m:.1f} m past it)"
        if self._look_losses:
            where = ("partly in a new SLAM map" if partial else "in one SLAM map" if one_map
                     else "ending in an older SLAM map")
            side += f"; {self._look_losses} tracking losses looking around, the look {where}"
        if self._look_sudden_losses:
            side += (f"; {self._look_sudden_losses} sudden tracking losses (at least "
                     f"{cfg.sudden_loss_min_tracked_points} map points tracked) not counted")
        if wide and (lossy or not (walled_beside or tracked_in_room)):
            # Side walls seen going on past the door's wall by a look that lost tracking this
            # often are the building's outside walls, or a wall beyond smeared along the view.
            why = ": too many losses for a room" if walled_beside else ""
            # Out by its losses alone: without them the look would be another room. Looking
            # around again tells the two apart: beyond a door, the open views lose tracking
            # again; in a room, a loss that was a glitch (a covered lens) is not repeated.
            by_losses = lossy and (walled_beside or opening <= cfg.room_max_opening_deg)
            if by_losses and cfg.recheck_lossy_look:
                if (not self._look_rechecked
                        and self._look_losses <= cfg.recheck_lossy_look_max_losses):
                    self._look_rechecked = True
                    self._look_losses = self._look_sudden_losses = 0
                    self._look_known_map_index = self._max_map_index
                    self._set(t, State.START, Phase.LOOK_AROUND,
                              f"{seen} around, {side}: out by its losses alone, look around "
                              f"again")
                    return [self._scan("look_around")]
                why += (", again on a second look" if self._look_rechecked else
                        f", not looked again (more than {cfg.recheck_lossy_look_max_losses} "
                        f"losses)")
            return self._out_after_look(t, obs, f"passed through the exit: {seen} around, "
                                                f"{side}{why}")
        if self._look_rechecked:
            seen += ", on a second look"
        # A blank wall ahead looks like open space; walls going on beside it do not.
        seen += f", {'but ' if wide else ''}{side}"
        if wide and not walled_beside:
            seen += ", tracking all the way round"
        if self.rooms >= cfg.max_rooms:
            kind = "another room" if wide else "walls all round"
            return self._give_up(t, f"{kind} beyond the exit ({seen}) after {self.rooms} rooms")
        if self._door_xy is not None:
            self._rejected.append(self._door_xy)
        self.rooms += 1
        self._room_unconfirmed = True
        self._outside_by = 0.0
        self._room_before_origin_xy = self.room_origin_xy
        self.room_origin_xy = obs.robot_xy or self._last_tracked_xy
        self._room_before_outline = tuple(obs.room_outline)
        self._room_before_map = obs.slam_map_index
        self._room_before_door_xy = self._door_xy
        self._room_look_xy = self.room_origin_xy
        self._exit_viewpoint = "robot"
        self._exit_attempts = 0
        return self._ask_exit(t, f"another room beyond the exit ({seen}): find its exit "
                                 f"({self.rooms}/{cfg.max_rooms})")

    def _out_after_look(self, t, obs, why):
        """The look around says out: done where the robot stands when that is at the point
        beyond the exit or step_out_min_outside_m outside the room outline; else on to the point
        beyond first, when the exit's coordinates hold in the SLAM map tracked now."""
        cfg = self.config
        beyond = self._beyond_exit() if self.exit_xy is not None else None
        if (beyond is not None and obs.robot_xy is not None and len(obs.room_outline) >= 3
                and obs.slam_map_index is not None
                and obs.slam_map_index == self._alternatives_map):
            outside = distance_outside(obs.robot_xy, obs.room_outline)
            if (outside < cfg.step_out_min_outside_m
                    and math.dist(obs.robot_xy, beyond) > cfg.reached_tolerance_m):
                self._step_out_why = why
                return self._navigate(t, Phase.STEP_OUT, beyond,
                                      f"{why}; {outside:.2f} m outside the room outline: step out "
                                      f"to ({beyond[0]:.2f}, {beyond[1]:.2f}) beyond the exit")
        self._set(t, State.IDLE, Phase.DONE, why)
        return [Action(ActionKind.STOP)]

    def _stepped_out(self, t, how):
        """Done after stepping out (or trying to) on the look around's word."""
        self._set(t, State.IDLE, Phase.DONE, f"{self._step_out_why}; {how}")
        return [Action(ActionKind.CANCEL_GOAL), Action(ActionKind.STOP)]

    def _find_exit(self, t, obs):
        cfg = self.config
        if self._exit_paused_s is not None:
            # The exit finder's time to answer does not run while the robot is lost or recovering.
            self._exit_requested_s += t - self._exit_paused_s
            self._exit_paused_s = None
        answered = self._exit_answer is not None
        exit_xy, alternatives, leads_out = self._exit_answer if answered else (None, (), True)
        self._exit_answer = None
        no_way_out = answered and exit_xy is not None and not leads_out
        if no_way_out and self._exit_attempts < cfg.max_exit_attempts:
            # Every candidate has a wall or furniture behind it on the map: look from elsewhere
            # before driving into it (on the last attempt the best candidate is tried).
            self._set(t, State.START, Phase.WALL_SCAN, "the map shows no way out beyond the "
                      "exits found: scan more")
            return [self._scan("random")]
        candidates, found = [], "exit found at"
        if answered and exit_xy is not None:
            candidates = [c for c in [tuple(exit_xy)] + [tuple(xy) for xy in alternatives]
                          if not self._was_rejected(c)]
        if answered and self._room_unconfirmed:
            if not candidates:
                why = "the walls around hold no exit but the door come through"
                if self._exit_attempts < cfg.max_exit_attempts:
                    # A second room's exit may lie where the look around did not see.
                    self._set(t, State.START, Phase.WALL_SCAN, f"{why}: scan more")
                    return [self._scan("random")]
                why += f" after {self._exit_attempts} attempts"
                back = self._untried_alternatives(obs)
                if not back:
                    # Still none: the space between a building and what stands beyond its exit.
                    self._set(t, State.IDLE, Phase.DONE, f"passed through the exit: {why}")
                    return [Action(ActionKind.STOP)]
                # A room whose only door is the one come through: the room before's exit lies
                # elsewhere, through its next candidate (the way there leads back through the door).
                candidates, found = back, f"{why}: back to the room before's next candidate"
                self.room_origin_xy = self._room_before_origin_xy
                self._room_before_outline = ()  # back into it on purpose
            self._room_unconfirmed = False
        if candidates:
            # The room before's untried candidates come last (a door into a room with no exit).
            candidates += self._untried_alternatives(obs, candidates)
            self._alternatives_map = obs.slam_map_index
            self.exit_xy = candidates[0]
            self._alternatives = candidates[1:]
            return self._navigate(t, Phase.GO_TO_EXIT, self.exit_xy,
                                  f"{found} ({self.exit_xy[0]:.2f}, {self.exit_xy[1]:.2f})")
        timed_out = t - self._exit_requested_s > cfg.exit_answer_timeout_s
        if not (answered or timed_out):
            return []
        why = ("no exit in the map" if answered and exit_xy is None
               else "only exits already passed through without leaving the room"
               if answered else "the exit finder did not answer")
        if self._exit_attempts >= cfg.max_exit_attempts:
            return self._give_up(t, f"{why} after {self._exit_attempts} attempts")
        self._set(t, State.START, Phase.WALL_SCAN, f"{why}: scan more")
        return [self._scan("random")]

    def _navigate(self, t, phase, goal_xy, why):
        if phase == Phase.GO_TO_EXIT:
            self._outside_by = 0.0
        self.goal_xy = tuple(goal_xy)
        self._goal_failures = 0
        self._failure_since_s = None
        self._progress = None
        self._goal_losses, self._loss_distance = 0, None
        self._set(t, State.GOAL, phase, why)
        return [Action(ActionKind.GOAL, self.goal_xy)]

    def _stalled(self, t, distance):
        """True when the robot has come no closer to the goal for stall_timeout_s (a robot parked
        at the free cell nearest to a goal inside an obstacle, the navigator still 'following')."""
        if distance is None:
            return False
        if self._progress_paused is not None and self._progress is not None:
            first, last = self._progress_paused
            self._progress = (self._progress[0] + last - first, self._progress[1])
        self._progress_paused = None
        if self._progress is None or distance < self._progress[1] - self.config.stall_progress_m:
            self._progress = (t, distance)
        return t - self._progress[0] > self.config.stall_timeout_s

    def _goal_state(self, t, obs):
        cfg = self.config
        distance = (math.dist(obs.robot_xy, self.goal_xy)
                    if obs.robot_xy is not None and self.goal_xy is not None else None)
        near = distance is not None and distance <= cfg.reached_tolerance_m
        stalled = self._stalled(t, distance)
        if stalled and distance <= cfg.exit_near_m and self.phase == Phase.STEP_OUT:
            return self._stepped_out(t, "no closer to the point beyond the exit: done here")
        if stalled and distance <= cfg.exit_near_m and self.phase in (Phase.GO_TO_EXIT,
                                                                      Phase.PASS_THROUGH,
                                                                      Phase.BACK_OUT):
            # Parked at the free cell nearest to a goal inside an obstacle, where the navigator
            # never says "reached": the exit, or the point beyond it in a wall out there.
            self._set(t, State.GOAL, self.phase, "no closer to the exit: pass through from here"
                      if self.phase == Phase.GO_TO_EXIT else
                      "no closer to the point beyond the exit: passed through from here"
                      if self.phase == Phase.PASS_THROUGH else "no closer: out from here")
            near = True
        if obs.navigator_state == "reached" or near:
            if self.phase == Phase.GO_TO_EXIT:
                target = self._beyond_exit()
                return self._navigate(t, Phase.PASS_THROUGH, target, "at the exit: pass through")
            if self.phase == Phase.PASS_THROUGH:
                passed = f"passed through ({self.exit_xy[0]:.2f}, {self.exit_xy[1]:.2f}) yet"
                return (self._wrong_exit_if_inside(t, obs, passed)
                        or self._back_in_room_before(t, obs)
                        or self._look_around(t, "passed through the exit: look around",
                                             self.exit_xy))
            if self.phase == Phase.STEP_OUT:
                return self._stepped_out(t, "stepped out beyond the exit")
            self._set(t, State.IDLE, Phase.DONE, "back at the start"
                      if self.phase == Phase.RETURN_TO_START else
                      "back out where the robot looked around beyond the room before's door")
            # Within tolerance the navigator may still hold the goal and publish its path.
            return [Action(ActionKind.CANCEL_GOAL), Action(ActionKind.STOP)]
        if stalled and obs.navigator_state == "planning" and self.phase == Phase.GO_TO_EXIT:
            # No map of the SLAM map tracked now to plan on (a new map whose floor is not found
            # yet): a robot waiting for one sees nothing new, so it would wait for ever. Scanning
            # builds the map, and the finder reads the exit again in it.
            self._set(t, State.START, Phase.WALL_SCAN, f"no map to plan on for "
                      f"{cfg.stall_timeout_s:g} s: scan more")
            return [Action(ActionKind.CANCEL_GOAL), self._scan("random")]
        failure = (f"navigator: {obs.navigator_state}" if obs.navigator_state in _FAILED_NAVIGATION
                   else "motion failed" if obs.motion_failed
                   else f"no progress for {cfg.stall_timeout_s:g} s" if stalled else None)
        if failure is not None:
            if self._failure_since_s is None:
                self._failure_since_s = t
            elif t - self._failure_since_s > cfg.goal_failure_grace_s:
                if self.phase == Phase.STEP_OUT:
                    # The look around said out already: no need to get farther at any cost.
                    return self._stepped_out(t, f"{failure} stepping out: done here")
                self._goal_failures += 1
                self._failure_since_s = None
                if self._goal_failures >= cfg.max_goal_failures:
                    given_up = f"{failure} {self._goal_failures} times"
                    if self.phase in (Phase.GO_TO_EXIT, Phase.PASS_THROUGH):
                        # The finder ranks several exits: an unreachable one is likely wrong.
                        # A map without a path to it is read again only after more of
                        # it is seen; a robot blocked or stalled there may try it once more.
                        return self._next_exit(t, f"{failure} at the exit ({self.exit_xy[0]:.2f}, "
                                                  f"{self.exit_xy[1]:.2f})", given_up,
                                               scan_first=obs.navigator_state in _FAILED_NAVIGATION)
                    return self._give_up(t, given_up)
                self._progress = None
                return [Action(ActionKind.GOAL, self.goal_xy)]
        else:
            self._failure_since_s = None
        return []

    def _back_in_room_before(self, t, obs):
        """Passed through the exit of a room come into, yet inside the room before's outline.
        Back through the door come out of, that 'room' was the space outside that door: back out
        to where the look that took it for a room stood. Through another door, that exit only
        leads back (a loose outline or a second door between the rooms): it was wrong. None when
        the robot is not in the room before."""
        cfg = self.config
        if (self.rooms < 2 or len(self._room_before_outline) < 3 or self._room_look_xy is None
                or self._room_before_door_xy is None
                or obs.slam_map_index != self._room_before_map):
            return None
        inside = distance_inside(obs.robot_xy, self._room_before_outline)
        if inside < cfg.inside_room_margin_m:
            return None
        (ex, ey), (lx, ly) = self.exit_xy, self._room_look_xy
        from_door = math.dist(self.exit_xy, self._room_before_door_xy)
        if from_door > cfg.back_out_door_radius_m:
            return self._wrong_exit(t, f"passed through ({ex:.2f}, {ey:.2f}) {inside:.2f} m into "
                                       f"the room before, {from_door:.2f} m from the door come "
                                       f"out of: not an exit")
        self._room_before_outline = ()
        return self._navigate(t, Phase.BACK_OUT, self._room_look_xy,
                              f"passed through ({ex:.2f}, {ey:.2f}) back into the room before "
                              f"({inside:.2f} m inside its outline): the look around at "
                              f"({lx:.2f}, {ly:.2f}) stood outside: back out there")

    def _untried_alternatives(self, obs, tried=()):
        """The candidates still in line, not rejected nor in tried, when they were found in the
        SLAM map tracked now (their coordinates mean nothing in another)."""
        if self._alternatives_map != obs.slam_map_index:
            return []
        return [c for c in self._alternatives if c not in tried and not self._was_rejected(c)]

    def _was_rejected(self, xy):
        """Near an exit passed through without leaving the room."""
        return any(math.dist(xy, r) < self.config.rejected_exit_radius_m for r in self._rejected)

    def _wrong_exit_if_inside(self, t, obs, why):
        """Passed through (or stopped passing through) yet inside_room_margin_m inside the room
        outline: the exit was wrong; None when the robot is not that far inside."""
        inside = distance_inside(obs.robot_xy, obs.room_outline)
        if inside < self.config.inside_room_margin_m:
            return None
        return self._wrong_exit(t, f"{why} {inside:.2f} m inside the room outline: not an exit")

    def _wrong_exit(self, t, why):
        """The exit led nowhere: it and candidates near it are out of the running."""
        self._rejected.append(self.exit_xy)
        self._alternatives = [c for c in self._alternatives if not self._was_rejected(c)]
        return self._next_exit(t, why, f"{why}, and no candidate is left")

    def _next_exit(self, t, why, given_up, scan_first=False):
        """The finder's next candidate; else the finder again while attempts are left, after a
        random scan with ``scan_first`` (an exit that could not be reached is in the map the
        finder would read again, and it would answer the same); else give up with the reason
        given_up."""
        if self._alternatives:
            self.exit_xy = self._alternatives.pop(0)
            return self._navigate(t, Phase.GO_TO_EXIT, self.exit_xy,
                                  f"{why}: next candidate ({self.exit_xy[0]:.2f}, "
                                  f"{self.exit_xy[1]:.2f})")
        if self._exit_attempts < self.config.max_exit_attempts:
            if scan_first:
                self._set(t, State.START, Phase.WALL_SCAN, f"{why}: scan more")
                return [Action(ActionKind.CANCEL_GOAL), self._scan("random")]
            return self._ask_exit(t, f"{why}; look for the exit again")
        return self._give_up(t, given_up)

    def _beyond_exit(self):
        """A point pass_through_m past the exit, on the line from the room's origin (the start in
        the first room) through the exit."""
        ex, ey = self.exit_xy
        sx, sy = self.room_origin_xy if self.room_origin_xy is not None else (0.0, 0.0)
        dx, dy = ex - sx, ey - sy
        norm = math.hypot(dx, dy)
        if norm < 1e-9:
            return (ex, ey)
        k = self.config.pass_through_m / norm
        return (ex + k * dx, ey + k * dy)
