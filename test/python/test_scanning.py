"""Seed 000 scan patterns and their Tello / cmd_vel forms."""
import math

import numpy as np
import pytest

from sparse_nav.scanning import (InitialScanConfig, Step, initial_scan, to_tello_commands,
                                 to_velocity_segments)


def test_initial_scan_turns_a_full_circle_and_returns_each_iteration():
    steps = initial_scan()
    assert sum(s.ccw_deg for s in steps) == pytest.approx(-360.0)
    # Translation sums to zero: the scan stays where it started.
    assert sum(s.forward_m for s in steps) == pytest.approx(0.0)
    assert sum(s.left_m for s in steps) == pytest.approx(0.0)
    assert all(s.forward_m or s.left_m or s.ccw_deg for s in steps)


def test_tello_commands_within_limits():
    commands = to_tello_commands(initial_scan())
    assert commands[:5] == ["back 30", "right 30", "cw 20", "ccw 20", "left 30"]
    for c in commands:
        verb, value = c.split()
        assert verb in {"forward", "back", "left", "right", "cw", "ccw"}
        assert (1 <= int(value) <= 360) if verb in {"cw", "ccw"} else (20 <= int(value) <= 500)
    with pytest.raises(ValueError, match="outside"):
        to_tello_commands([Step(forward_m=0.1)])


def test_velocity_segments_reproduce_the_steps_on_a_unicycle():
    x = y = th = 0.0
    for v, w, duration in to_velocity_segments(initial_scan(InitialScanConfig(turn_deg=90))):
        n = 200
        for _ in range(n):
            x += v * math.cos(th) * duration / n
            y += v * math.sin(th) * duration / n
            th += w * duration / n
    assert np.hypot(x, y) < 0.02
    assert math.remainder(th, 2 * math.pi) == pytest.approx(0.0, abs=1e-6)


def test_bad_config():
    with pytest.raises(ValueError):
        initial_scan(InitialScanConfig(turn_deg=0))
