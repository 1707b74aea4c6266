"""Exit finder of seed 000 and its successors: where is the door of the room in a sparse cloud?

ROS-free. Entry point :func:`find_exit`; methods in :data:`METHODS`; every threshold in
:class:`ExitFinderConfig`; the answer is an :class:`ExitResult`, a cloud that holds no room
raises :class:`ExitFinderError`. Modules: ``cloud`` (seed steps 1-3), ``seed`` (steps 4-8 and the
seed's alternatives), ``gaps`` (door gaps on any room outline), ``geometry``, ``plot``.
"""
from sparse_nav.exit_finder.config import ExitFinderConfig
from sparse_nav.exit_finder.finder import DEFAULT_METHOD, METHODS, find_exit, prepare
from sparse_nav.exit_finder.result import ExitFinderError, ExitResult

__all__ = ["ExitFinderConfig", "ExitFinderError", "ExitResult", "DEFAULT_METHOD", "METHODS",
           "find_exit", "prepare"]
