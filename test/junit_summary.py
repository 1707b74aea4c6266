#!/usr/bin/python3
"""Sum every JUnit XML under a results directory (pytest, gtest, rostest) into one line.

Prints the failing test cases, then `N passed, N failed` and exits non-zero when anything failed,
errored, or when no test ran at all (a suite that silently ran nothing must not look green).
"""
import os
import sys
import xml.etree.ElementTree as ET


def _reason(problem, max_chars=600):
    """The failure's message and the end of its text (where the assertion is), for the CI log."""
    text = " ".join(filter(None, [problem.get("message", ""), problem.text or ""]))
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    if not lines:
        return ""
    # rosunit writes the assertion first and the traceback after it; pytest the other way round.
    first, last = lines[0], lines[-1]
    text = first if first == last else f"{first} | ... | {last}"
    return "\n    " + (text if len(text) <= max_chars else text[:max_chars] + "...")


def collect(results_dir):
    passed, failed, skipped, broken = [], [], [], []
    for dirpath, _, files in os.walk(results_dir):
        for name in sorted(files):
            if not name.endswith(".xml"):
                continue
            path = os.path.join(dirpath, name)
            try:
                root = ET.parse(path).getroot()
            except ET.ParseError as exc:
                broken.append(f"{path}: unreadable result file ({exc})")
                continue
            cases = root.iter("testcase")
            found = False
            # rostest-*.xml only says whether the harness ran its test node (it passes even when
            # the node's tests fail); the node's own results are in rosunit-*.xml. So a rostest
            # file contributes failures only, and the test cases are counted from rosunit files.
            harness = name.startswith("rostest-")
            for case in cases:
                found = True
                label = f"{name}: {case.get('classname', '')}.{case.get('name', '')}"
                problem = case.find("failure")
                if problem is None:
                    problem = case.find("error")
                if problem is not None:
                    failed.append(f"{label}{_reason(problem)}")
                elif harness:
                    continue
                elif case.find("skipped") is not None:
                    skipped.append(label)
                else:
                    passed.append(label)
            # rostest writes a suite with errors="1" and no testcase when its test node never ran.
            if not found and int(root.get("errors", 0) or 0) + int(root.get("failures", 0) or 0) > 0:
                failed.append(f"{name}: suite reported errors without test cases")
    return passed, failed, skipped, broken


def main():
    results_dir = sys.argv[1] if len(sys.argv) > 1 else "build/test_results"
    passed, failed, skipped, broken = collect(results_dir)
    failed += broken
    for label in failed:
        print(f"FAILED {label}")
    for label in skipped:
        print(f"skipped {label}")
    line = f"{len(passed)} passed, {len(failed)} failed"
    if skipped:
        line += f", {len(skipped)} skipped"
    print(line)
    if not passed:
        print("no test ran", file=sys.stderr)
        return 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
