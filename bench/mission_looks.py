"""The looks around beyond an exit that the committed mission bench files recorded."""
import json


def recorded_looks(paths):
    """(robot and mode, look) of each look around in each run of each file, as recorded."""
    for path in paths:
        with open(path) as f:
            results = json.load(f).get("results", {})
        for kind, table in results.items():
            for run in table.get("runs", []):
                for look in run.get("look_arounds") or []:
                    yield kind, look
