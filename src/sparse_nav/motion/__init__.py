"""Motion core (ROS-free): seed 000's primitive, a look-ahead path follower, seed 001's discrete
Tello commands, go-to-wall with a fail counter, and the staleness guard."""
from sparse_nav.motion.controller import (FAILED, FOLLOWING, IDLE, REACHED, STATE_NAMES,
                                          STOPPED_LOST, STOPPED_STALE, TELLO_MAX_MOVE_CM,
                                          TELLO_MAX_TURN_DEG, TELLO_MIN_MOVE_CM,
                                          TELLO_MIN_TURN_DEG, WALL_REACHED, WALL_SEEKING,
                                          Decision, MotionConfig, MotionController,
                                          StalenessGuard, WallSeeker, tello_command)
from sparse_nav.motion.primitive import PathFollower, Target, signed_angle

__all__ = ["FAILED", "FOLLOWING", "IDLE", "REACHED", "STATE_NAMES", "STOPPED_LOST",
           "STOPPED_STALE", "TELLO_MAX_MOVE_CM", "TELLO_MAX_TURN_DEG", "TELLO_MIN_MOVE_CM",
           "TELLO_MIN_TURN_DEG", "WALL_REACHED", "WALL_SEEKING", "Decision", "MotionConfig",
           "MotionController", "PathFollower", "StalenessGuard", "Target", "WallSeeker",
           "signed_angle", "tello_command"]
