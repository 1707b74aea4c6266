"""The runs, and their looks around beyond an exit, that the committed mission bench files recorded."""
import json


def recorded_runs(paths):
    """(robot and mode, run) of every run in the files, in file order."""
    for path in paths:
        with open(path) as f:
            results = json.load(f).get("results", {})
        for kind, table in results.items():
            for run in table.get("runs", []):
                yield kind, run


def recorded_looks(paths):
    """(robot and mode, look) of each look around in each run of each file, as recorded."""
    for kind, run in recorded_runs(paths):
        for look in run.get("look_arounds") or []:
            yield kind, look
