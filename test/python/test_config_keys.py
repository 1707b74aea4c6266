"""Each config/<node>.yaml documents exactly the private parameters its node reads."""
import os
import re

import pytest
import yaml

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
NODES = {"sim": "src/sparse_nav/ros/sim_node.py",
         "slam_bridge": "src/sparse_nav/ros/slam_bridge_node.py",
         "cartographer": "src/sparse_nav/ros/cartographer_node.py",
         "motion": "src/sparse_nav/ros/motion_node.py",
         "navigator": "src/sparse_nav/ros/navigator_node.py",
         "exit_finder": "src/sparse_nav/ros/exit_finder_node.py",
         "cloud_filter": "src/ros/cloud_filter_nodelet.cpp",
         "ground_mapper": "src/ros/ground_mapper_nodelet.cpp",
         "grid_builder": "src/ros/grid_builder_nodelet.cpp",
         "feature_extractor": "src/ros/feature_extractor_nodelet.cpp"}


def params_read_by(source):
    text = open(os.path.join(ROOT, source)).read()
    keys = set(re.findall(r'get_param\(\s*"~(\w+)"', text))
    keys |= set(re.findall(r'loadParam\(pnh, "(\w+)"', text))
    # The rospy nodes read their Config fields by name with sparse_nav.ros.params.read_fields.
    for block in re.findall(r'read_fields\(\w+, \(([^)]*)\)', text):
        keys |= set(re.findall(r'"(\w+)"', block))
    return keys


@pytest.mark.parametrize("node", sorted(NODES))
def test_yaml_and_code_agree(node):
    with open(os.path.join(ROOT, "config", f"{node}.yaml")) as f:
        documented = set(yaml.safe_load(f))
    read = params_read_by(NODES[node])
    assert documented - read == set(), "documented but never read"
    assert read - documented == set(), "read but not documented"
