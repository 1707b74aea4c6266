"""Lets the ROS-free tests import sparse_nav from src/ when no catkin workspace is sourced."""
import importlib.util
import os
import sys

if importlib.util.find_spec("sparse_nav") is None:
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "src"))
