"""bench/goal_loss_counts.py: the losses that gave up an exit, read from a conductor log."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "bench"))

import goal_loss_counts  # noqa: E402

PREFIX = "[rosout][INFO] 2026-12-07 18:46:50,228: conductor: "


def test_the_last_losses_of_the_phase_before_the_verdict_counted(tmp_path):
    lines = [
        "GOAL / go_to_exit: exit found at (2.00, 1.00)",
        "LOST / go_to_exit: SLAM tracking lost (900 map points tracked at it): stopped",
        "LOST / go_to_exit: SLAM tracking lost (30 map points tracked at it): stopped",
        "LOST / go_to_exit: SLAM tracking lost (1200 map points tracked at it), and SLAM gave up",
        "LOST / go_to_exit: SLAM tracking lost (25 map points tracked at it): stopped",
        "GOAL / go_to_exit: SLAM tracking lost 3 times on the way to the exit (2.00, 1.00) "
        "without coming closer: next candidate (0.00, 4.00)",
        "LOST / go_to_exit: SLAM tracking lost (700 map points tracked at it): stopped",
        "GOAL / pass_through: at the exit: pass through",
        "LOST / pass_through: SLAM tracking lost (26 map points tracked at it): stopped",
        "LOST / pass_through: SLAM tracking lost (27 map points tracked at it): stopped",
        "START / look_around: SLAM tracking lost 2 times passing through (0.00, 4.00) without "
        "coming closer to the point beyond: look around from here",
    ]
    log = tmp_path / "conductor-12.log"
    log.write_text("".join(PREFIX + line + "\n" for line in lines))
    assert goal_loss_counts.given_up_exits(str(log)) == [
        ("go_to_exit", [30, 1200, 25]), ("pass_through", [26, 27])]
