"""Seed 000's retry mechanism around a scan, ROS-free.

Every step that succeeds is remembered. A step after which the pose is unknown (a soft fail) is
undone and executed again, slower. After ``max_soft_fails`` soft fails in a row the runner also
undoes the last step that succeeded, so the robot goes back to where tracking last worked. After
``max_total_fails`` soft fails the scan has failed. A step the robot backed off from
``fails_before_pass`` times is passed (see ``report``).

A scan cut off (stopped for relocalising) goes on from where its cut step began, when the robot
has odometry to find that place again (see ``return_steps``); cut off again and again at one place,
it skips to the end of that place's turn (see ``interrupt``).
"""
import collections
import dataclasses
import math
from typing import List, Optional, Tuple

from sparse_nav.scanning import Step, pose_after, steps_to_pose


@dataclasses.dataclass
class ScanRunnerConfig:
    slow_factor: float = 0.5      # speed of a retried step relative to the one before
    min_speed_factor: float = 0.25
    max_soft_fails: int = 2       # in a row, before the last success is undone too
    max_total_fails: int = 8      # over the whole scan, before it is given up
    resume_return_max_m: float = 2.0  # a scan cut off goes back this far at most (m) to where its
    #                                   cut step began before going on; 0: goes on where it is
    cuts_before_skip: int = 2     # a scan cut off this often at one place skips to the end of
    #                               the turn that place belongs to; 0: never
    fails_before_pass: int = 2    # a step backed off from this often (tracking lost in it) is
    #                               passed: the robot goes on, unwatched, to the end of the turn
    #                               that place belongs to; 0: never

    def validate(self):
        if not 0 < self.min_speed_factor <= self.slow_factor <= 1:
            raise ValueError("need 0 < min_speed_factor <= slow_factor <= 1")
        if self.max_soft_fails < 1 or self.max_total_fails < 1:
            raise ValueError("max_soft_fails and max_total_fails must be >= 1")
        if not (math.isfinite(self.resume_return_max_m) and self.resume_return_max_m >= 0):
            raise ValueError("resume_return_max_m must be finite and >= 0")
        for name in ("cuts_before_skip", "fails_before_pass"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0")


class ScanRunner:
    """Hands out (step, speed factor) one at a time; the caller reports how each went.

    ``while_lost``: the scan is the relocalising motion, run while tracking is lost by
    definition; a lost pose after a step is then no soft fail (undoing each step would rock the
    robot on the spot and never reach the turn at the motion's end).
    """

    def __init__(self, steps: List[Step], config=None, while_lost: bool = False):
        self.config = config or ScanRunnerConfig()
        self.config.validate()
        self.while_lost = while_lost
        # (step, speed factor, its place in the scan: None for a step that undoes another)
        self._todo: List[Tuple[Step, float, Optional[int]]] = [
            (s, 1.0, k) for k, s in reversed(list(enumerate(steps)))]
        self._current: Optional[Tuple[Step, float, Optional[int]]] = None
        self._places = len(steps)
        self.succeeded: List[Step] = []
        self._succeeded_at: List[int] = []
        self.skipped: List[Step] = []  # passed over where the view could not be tracked
        self._cuts = collections.Counter()  # per place in the scan
        self._backed_off = collections.Counter()  # per place in the scan
        self._pass_to = None         # where a passed place's turn ends, to go to unwatched
        self._pass_steps = collections.deque()
        self.watching = True         # the step handed out is one to back off from when lost
        self.soft_fails = 0
        self.total_fails = 0
        self.failed = False
        self.step_start_pose = None  # where the step in progress began
        self._resume_pose = None     # where the scan cut off goes on from

    @property
    def share_done(self):
        """Share of the scan's steps that succeeded so far (1 for a scan without steps)."""
        return len(self._succeeded_at) / self._places if self._places else 1.0

    @property
    def done(self):
        return self.failed or (not self._todo and self._current is None
                               and self._pass_to is None)

    def next_step(self, pose=None):
        """The next (step, speed_factor), or None when the scan is over (see ``failed``).

        pose: (x_m, y_m, yaw_rad) of the robot as the step begins, in a frame that holds still
        through SLAM losses (wheel odometry), or None without one."""
        if self._current is not None:
            raise RuntimeError("report() the step in progress first")
        if self._pass_to is not None and not self._pass_steps:
            self._pass_steps.extend(steps_to_pose(pose, self._pass_to) if pose is not None else [])
            if not self._pass_steps:
                self._pass_to = None
        self.watching = not self._pass_steps
        if not self.watching:
            self._current = (self._pass_steps.popleft(), 1.0, None)
        elif self.done:
            return None
        else:
            self._current = self._todo.pop()
        self.step_start_pose, self._resume_pose = pose, None
        return self._current[0], self._current[1]

    def interrupt(self):
        """The step in progress was cut off (the scan stopped for relocalising): the next
        next_step() hands it out again, to be done from its start, and the scan goes on from
        there. Without return_steps, a turn cut halfway turns a little more than planned.

        Cut off cuts_before_skip times at one place in the scan, the scan skips to the end of
        the turn that place belongs to: a view that loses tracking every time (a nearly blank
        wall, a wall up close) would otherwise cost a relocalising round per try, up to the
        conductor's max_scan_resumes, and the robot is no wiser at the end."""
        if self._current is None:
            return
        if not self.watching:
            # Passing a place: the scan goes on where its turn ends (return_steps goes there).
            self._current, self._resume_pose = None, self._pass_to
            self._pass_to = None
            self._pass_steps.clear()
            return
        self._todo.append(self._current)
        self._current = None
        self._resume_pose = self.step_start_pose
        place = next((k for _, _, k in reversed(self._todo) if k is not None), None)
        self._cuts[place] += 1
        if self.config.cuts_before_skip and self._cuts[place] >= self.config.cuts_before_skip:
            self._skip_turn()

    def _skip_turn(self):
        """Drops the steps to do up to the end of the next turn of the scan, and moves the
        place to go on from to where they would have ended."""
        passed = []
        while self._todo:
            step, _, place = self._todo.pop()
            passed.append(step)
            if place is not None:
                self.skipped.append(step)
                if step.ccw_deg and not step.forward_m and not step.left_m:
                    break
        self.soft_fails = 0
        if self._resume_pose is not None:
            self._resume_pose = pose_after(self._resume_pose, passed)

    def return_steps(self, pose):
        """Steps from pose (as in next_step) to where the scan cut off goes on (where its cut
        step began, or where the turn it skipped ends), before it goes on: [] when either place
        is unknown or they lie farther apart than resume_return_max_m.

        Without them a robot that loses tracking again and again in a scan walks off: each cut
        step is redone from wherever the relocalising motion left it (a relocalising drive is
        stopped as soon as tracking is back, up to 0.6 m out), and such a walk ended a ground
        robot's initial scan 6 m away in a narrow corner, losing tracking there until the time
        limit (random:46)."""
        target = self._resume_pose
        if pose is None or target is None or self._current is not None \
                or not self.config.resume_return_max_m \
                or math.dist(pose[:2], target[:2]) > self.config.resume_return_max_m:
            return []
        return steps_to_pose(pose, target)

    def back_off_steps(self, pose):
        """Steps from pose (as in next_step) back to where the step in progress began, for a
        step stopped where tracking was lost: [] when either place is unknown."""
        if pose is None or self.step_start_pose is None:
            return []
        return steps_to_pose(pose, self.step_start_pose)

    def report_motion(self, moved: bool, lost: bool):
        """After the step from next_step(): whether the motion was carried out and whether SLAM
        tracking is lost after it."""
        self.report(moved and not (lost and not self.while_lost))

    def report_backed_off(self, tracked_again: bool):
        """The step from next_step() was stopped where tracking was lost and the robot went
        back to where the step began: a soft fail whose retry needs no undo step. Not
        tracked_again there, the last success is undone too, back to a view tracked longer."""
        self.report(False, returned=True, undo_last=not tracked_again)

    def report(self, pose_known: bool, returned: bool = False, undo_last: bool = False):
        """After the step from next_step(): pose_known False is a soft fail. returned: the
        robot is back where the step began (see report_backed_off); undo_last: undo the last
        success before the retry even before max_soft_fails."""
        if self._current is None:
            raise RuntimeError("no step in progress")
        step, speed, place = self._current
        self._current = None
        if not self.watching:
            if not self._pass_steps:
                self._pass_to = None  # passed: the scan goes on, tracking back or not
            return
        if pose_known:
            # An undo step neither ends a run of fails nor becomes part of the scan.
            if place is not None:
                self.soft_fails = 0
                self.succeeded.append(step)
                self._succeeded_at.append(place)
            return
        self.soft_fails += 1
        self.total_fails += 1
        if self.total_fails >= self.config.max_total_fails:
            self.failed = True
            return
        if returned and place is not None:
            self._backed_off[place] += 1
            if self.config.fails_before_pass and self.step_start_pose is not None \
                    and self._backed_off[place] >= self.config.fails_before_pass:
                # Lost at the same place of a step at two speeds: a view too bare to track,
                # which fails the same way at any speed, and the retries would fail the scan
                # (random:30, 44, 46 of the ground robot). The place's turn is done unwatched.
                self._todo.append((step, speed, place))
                self._resume_pose = self.step_start_pose
                self._skip_turn()
                self._pass_to, self._resume_pose = self._resume_pose, None
                return
        slower = max(self.config.min_speed_factor, speed * self.config.slow_factor)
        retry = [] if returned else [(step.undo(), slower, None)]
        if (undo_last or self.soft_fails >= self.config.max_soft_fails) and self.succeeded:
            last, last_at = self.succeeded.pop(), self._succeeded_at.pop()
            # Back past the last success, then do it again, then the failing step.
            retry += [(last.undo(), slower, None), (last, slower, last_at)]
            self.soft_fails = 0
        retry.append((step, slower, place))
        self._todo.extend(reversed(retry))


def config_for_scan(kind, config):
    """The retry settings for a scan of this kind. A look around beyond an exit passes no place:
    its losses, and the SLAM map they cost, are the conductor's evidence that the robot is out,
    and a pass turns on unwatched until SLAM gives up its map, so a look inside a room facing a
    bare wall ended in a new map and was taken for out (plain ground random:20, 26 at 170eb3f)."""
    return dataclasses.replace(config, fails_before_pass=0) if kind == "look_around" else config


def _describe_steps(steps):
    """Odometry steps in a log line: "+0.30 m, -24 deg"."""
    return ", ".join(f"{s.forward_m:+.2f} m" if s.forward_m else f"{s.ccw_deg:+.0f} deg"
                     for s in steps)


def drive_scan(runner, execute, tracking_lost, odom_pose, stop_requested, pause,
               log=lambda text: None):
    """Runs a ScanRunner's steps on a robot: the conductor node's scan loop, ROS-free (the
    offline bench drives the simulator through it too).

    execute(step, speed_factor, should_stop) -> whether the whole step was carried out;
    tracking_lost() -> SLAM lost now; odom_pose() -> (x, y, yaw) in a frame that holds still
    through losses, or None (see ScanRunner.next_step); stop_requested() -> the scan is to stop
    (relocalising): the step in progress is interrupted; pause(seconds) lets SLAM's state catch
    up with the last motion; log(text) tells what the loop decided.
    """
    def drive(steps):
        for step in steps:
            if stop_requested():
                return
            execute(step, 1.0, stop_requested)

    back = runner.return_steps(odom_pose())
    if back:
        log(f"back to where the scan goes on ({_describe_steps(back)})")
    drive(back)
    while not stop_requested():
        item = runner.next_step(odom_pose())
        if item is None:
            break
        step, speed = item
        # A step that loses tracking is stopped there and the ground robot drives straight
        # back to where it began: SLAM relocalises in the same map only while recently lost
        # (3 s in ORB-SLAM3), less than the rest of the step, the pause and a slow undo take.
        watch = (runner.watching and runner.step_start_pose is not None
                 and not runner.while_lost and not tracking_lost())
        done = execute(step, speed, lambda: stop_requested() or (watch and tracking_lost()))
        backed_off = not done and watch and not stop_requested() and tracking_lost()
        if backed_off:
            back = runner.back_off_steps(odom_pose())
            log(f"tracking lost in a scan step: back to where it began "
                f"({_describe_steps(back) or 'there already'})")
            drive(back)
        skipped = len(runner.skipped)
        if stop_requested():
            runner.interrupt()
            if len(runner.skipped) > skipped:
                log(f"the scan was cut off at one place {runner.config.cuts_before_skip} times: "
                    f"it skips {len(runner.skipped) - skipped} steps, to the end of that "
                    f"place's turn")
            break
        pause(0.5)
        if backed_off:
            runner.report_backed_off(tracked_again=not tracking_lost())
        else:
            runner.report_motion(done, tracking_lost())
        if len(runner.skipped) > skipped:
            log(f"tracking lost {runner.config.fails_before_pass} times at one place of the "
                f"scan: it passes {len(runner.skipped) - skipped} steps, turning on unwatched "
                f"to the end of that place's turn")


def take_off(send):
    """Sends the Tello's "command" and "takeoff" through send(text) -> answer.

    Returns (flying, why): flying when both are answered "ok" or the drone already flies;
    otherwise why names the refused command and its answer. "takeoff" is not sent when "command"
    is refused (the drone is not in SDK mode), and a scan must not be flown on a landed drone:
    every move would be refused.
    """
    answer = send("command")
    if answer != "ok":
        return False, f"command -> {answer}"
    answer = send("takeoff")
    if answer == "ok" or "already flying" in str(answer):
        return True, ""
    return False, f"takeoff -> {answer}"
