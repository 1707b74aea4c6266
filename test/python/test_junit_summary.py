"""The make-test summary counts real test cases once and never hides a rostest failure."""
import importlib.util
import os

import pytest

SPEC = importlib.util.spec_from_file_location(
    "junit_summary", os.path.join(os.path.dirname(__file__), "..", "junit_summary.py"))
junit_summary = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(junit_summary)

HARNESS_OK = ('<testsuite tests="1" errors="0" failures="0">'
              '<testcase classname="rostest.runner.RosTest" name="testx"/></testsuite>')
NODE_FAILED = ('<testsuite tests="2"><testcase classname="T" name="a"/>'
               '<testcase classname="T" name="b"><failure>boom</failure></testcase></testsuite>')


def test_rostest_node_failure_counts_even_when_harness_passes(tmp_path):
    (tmp_path / "rostest-x.xml").write_text(HARNESS_OK)
    (tmp_path / "rosunit-x.xml").write_text(NODE_FAILED)
    passed, failed, skipped, broken = junit_summary.collect(str(tmp_path))
    assert len(passed) == 1 and len(failed) == 1 and not broken


def test_unreadable_file_is_a_failure(tmp_path):
    (tmp_path / "pytest.xml").write_text("<testsuite")
    assert junit_summary.collect(str(tmp_path))[3]


def test_suite_error_without_cases_is_a_failure(tmp_path):
    (tmp_path / "rostest-y.xml").write_text('<testsuite tests="1" errors="1" failures="0"/>')
    assert junit_summary.collect(str(tmp_path))[1]


@pytest.mark.parametrize("text, expected", [
    # pytest: the traceback first, the assertion last
    ("Traceback\n  File x\nAssertionError: 0.49 not greater than 0.7", "0.49 not greater than 0.7"),
    # rosunit: the assertion first, the traceback after it
    ('6.5 not less than 0.75 : the door\n  File "x.py", line 1, in t\n    self.assertLess(a, b)',
     "6.5 not less than 0.75"),
])
def test_failure_line_carries_the_assertion_message(tmp_path, text, expected):
    (tmp_path / "rosunit-z.xml").write_text(
        '<testsuite tests="1"><testcase classname="T" name="c">'
        f'<failure type="AssertionError">{text}</failure></testcase></testsuite>')
    failed = junit_summary.collect(str(tmp_path))[1]
    assert len(failed) == 1 and expected in failed[0]
