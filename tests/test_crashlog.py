"""Crashed pytest-xdist workers (tests/_crashlog.py): reported at the end, the test rerun once.

pytest runs, with two workers, a file with a test that kills its process with a
segmentation fault, always or only the first time (a marker file remembers).
The crash is reported after xdist's own failure report, in the last lines of the
log (the fatal error, the test, its stack); a test that crashes once passes on
its rerun in a fresh worker, and a test that crashes every time fails. The same
runs without the plugin are the negative control: the crash fails the run, and
xdist alone prints the fatal error only before its report, in the middle of a
long log.
"""
from __future__ import annotations

import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
#: xdist's failure report of the crash; what follows it is the tail of a CI log.
REPORT = "crashed while running"
#: The lines of a log's tail that must hold the plugin's report, per crash.
TAIL = 12

CRASHING = '''
import faulthandler
import os


def test_passes():
    assert True


def crash_here():
    faulthandler._sigsegv()


def test_crashes():
    marker = os.path.join(os.path.dirname(__file__), "crashed-once")
    if ALWAYS or not os.path.exists(marker):
        open(marker, "w").close()
        crash_here()
'''


def _run(tmp_path, always: bool, *plugin: str) -> subprocess.CompletedProcess:
    (tmp_path / "test_crash.py").write_text(f"ALWAYS = {always}\n" + CRASHING)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([HERE, os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "-p", "no:cacheprovider",
                           "--rootdir", str(tmp_path), "-o", "timeout=60", *plugin,
                           str(tmp_path / "test_crash.py")], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=120, cwd=str(tmp_path),
                          env=env)


def _summary(run) -> list[str]:
    """The plugin's section to the end of the log: after any report of xdist's, and short
    (the tail of a CI log shows it)."""
    lines = run.stdout.splitlines()
    start = next((i for i, line in enumerate(lines) if "crashed workers" in line), None)
    report = run.stdout.find(REPORT)
    assert start is not None and start > run.stdout[:max(report, 0)].count("\n"), run.stdout
    assert len(lines) - start <= TAIL * run.stdout.count("node down"), run.stdout
    return lines[start:]


def _assert_reports_the_crash(summary: list[str]) -> None:
    assert any(l.endswith(": Fatal Python error: Segmentation fault") for l in summary), summary
    assert any(l.strip() == "test_crash.py::test_crashes" for l in summary), summary
    frames = [l for l in summary if l.strip().startswith("File ")]
    assert "in crash_here" in frames[0] and "in test_crashes" in frames[1], frames
    assert not any("/_pytest/" in l or "/pluggy/" in l for l in frames), frames


def test_a_crash_is_reported_at_the_end_and_the_test_passes_on_its_rerun(tmp_path):
    run = _run(tmp_path, False, "-p", "_crashlog")
    assert run.returncode == 0, run.stdout
    assert "2 passed, 1 rerun" in run.stdout, run.stdout
    summary = _summary(run)
    _assert_reports_the_crash(summary)
    assert any("rerun once" in l and "test_crash.py::test_crashes" in l for l in summary)


def test_a_test_that_crashes_every_time_fails(tmp_path):
    run = _run(tmp_path, True, "-p", "_crashlog")
    assert run.returncode == 1, run.stdout
    assert "1 failed, 1 passed, 1 rerun" in run.stdout, run.stdout
    _assert_reports_the_crash(_summary(run))


def test_without_it_a_crash_fails_and_the_tail_misses_it(tmp_path):
    """Negative control: the test that crashes once, xdist's own handling only."""
    run = _run(tmp_path, False, "-p", "no:_crashlog")
    assert run.returncode == 1 and "1 failed, 1 passed" in run.stdout, run.stdout
    tail = run.stdout[run.stdout.index(REPORT):]
    assert "Fatal Python error" in run.stdout, run.stdout
    assert "Fatal Python error" not in tail and "in crash_here" not in tail, tail
