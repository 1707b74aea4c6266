"""ROS-free simulator standing in for ORB-SLAM3 (monocular) and the robot (DESIGN.md section 5).

Public API::

    World, WorldError, load_world, list_worlds, random_world     worlds and their loading
    Simulator, SimConfig                                          the simulator and its parameters
    SlamOutput, TrackingState                                     what emulated ORB-SLAM3 reports
    DroneCommandError                                             a refused Tello command
"""
from sparse_nav.sim.generator import random_world
from sparse_nav.sim.robots import DroneCommandError
from sparse_nav.sim.simulator import SimConfig, Simulator
from sparse_nav.sim.slam import SlamOutput, TrackingState
from sparse_nav.sim.world import World, WorldError, list_worlds, load_world

__all__ = ["World", "WorldError", "load_world", "list_worlds", "random_world", "Simulator",
           "SimConfig", "SlamOutput", "DroneCommandError", "TrackingState"]
