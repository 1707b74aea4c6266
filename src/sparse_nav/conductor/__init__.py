"""The mission's deliberative layer (seed 004's conductor running seed 000's mission), ROS-free."""
from sparse_nav.conductor.machine import (Action, ActionKind, Conductor, ConductorConfig,
                                          ExitRequest, Observation, Phase, State, Transition)
from sparse_nav.conductor.scan_runner import ScanRunner, ScanRunnerConfig, take_off

__all__ = ["Action", "ActionKind", "Conductor", "ConductorConfig", "ExitRequest", "Observation",
           "Phase", "State", "Transition", "ScanRunner", "ScanRunnerConfig", "take_off"]
