"""config/conductor.yaml documents exactly what the conductor node reads, with valid values.

The node reads its mission limits and scan sizes as whole config dataclasses (one private
parameter per field, scan sizes in groups), so the generic yaml/code check cannot see them.
"""
import dataclasses
import os
import re

import yaml

from sparse_nav.conductor import ConductorConfig, ScanRunnerConfig
from sparse_nav.scanning import InitialScanConfig, RelocaliseConfig, WallScanConfig

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
GROUPS = {"initial_scan": InitialScanConfig, "wall_scan": WallScanConfig, "retry": ScanRunnerConfig,
          "relocalise": RelocaliseConfig}


def load():
    with open(os.path.join(ROOT, "config", "conductor.yaml")) as f:
        return yaml.safe_load(f)


def test_yaml_documents_every_parameter_and_no_other():
    source = open(os.path.join(ROOT, "src", "sparse_nav", "ros", "conductor_node.py")).read()
    direct = set(re.findall(r'get_param\(\s*"~(\w+)"', source))
    groups = dict(re.findall(r'_dataclass_params\("(\w*)/?", (\w+)\)', source))
    assert groups == {"": "ConductorConfig", **{g: cls.__name__ for g, cls in GROUPS.items()}}
    documented = load()
    fields = {f.name for f in dataclasses.fields(ConductorConfig)}
    assert set(documented) == direct | fields | set(GROUPS)
    for group, cls in GROUPS.items():
        assert set(documented[group]) == {f.name for f in dataclasses.fields(cls)}, group


def test_yaml_values_make_valid_configs_equal_to_the_defaults():
    documented = load()
    config = ConductorConfig(**{f.name: documented[f.name]
                                for f in dataclasses.fields(ConductorConfig)})
    config.validate()
    assert config == ConductorConfig()  # the yaml restates the defaults, written once in code
    for group, cls in GROUPS.items():
        value = cls(**documented[group])
        value.validate()
        assert value == cls(), group
