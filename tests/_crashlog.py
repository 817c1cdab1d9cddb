"""Crashed pytest-xdist workers: reported where a log's tail shows them, the test rerun once.

A worker killed by a fatal signal (a segmentation fault, an abort in Dr.Jit or
LLVM) shows up as "worker 'gwN' crashed while running X"; its fatal-error report
(Python's ``faulthandler``) scrolls by in the middle of the log, and a CI log's
tail loses the signal and the crashing thread's stack. Here each worker writes
the id of every test it starts, then any fatal-error report, to a file of its
own; the controller prints, at the end of the run, for each crashed worker the
crashing thread's stack, the last tests it started and the fatal error.

A test whose worker crashed runs once more, in a fresh worker (xdist's
``pytest_handlecrashitem``), and its result there is its result: a crash is a
fault of the process (seen once in CI, in a zsobol render test, never
reproduced here), not a verdict of the test. The crash is still reported (above, and as a rerun,
``R``, in the counts); a test that crashes twice fails, and at most
:data:`MAX_RERUNS` crashes are rerun in a session.

Only under xdist: a single process that crashes reports to stderr as usual.
"""
import faulthandler
import itertools
import os
import shutil
import tempfile
from pathlib import Path

import pytest

#: The folder of the workers' files (set by the controller, inherited by the workers).
ENV = "VR_TEST_CRASH_DIR"
#: The last test ids shown for a crashed worker, and the most frames of its stack.
LAST_TESTS, FRAMES = 4, 16
MARKER = "Fatal Python error"
#: Frames of the test runner itself, left out of the stack shown.
RUNNER = ("/_pytest/", "/pluggy/", "/xdist/", "/execnet/", '"<string>"')
#: The most crashed tests rerun in one session (a crash on every test is no fluke).
MAX_RERUNS = 3

_log = None
#: The crashed tests rerun so far (in the controller).
_reruns: list[str] = []


def _is_worker(config) -> bool:
    return hasattr(config, "workerinput")


@pytest.hookimpl(trylast=True)          # after pytest's own faulthandler plugin
def pytest_configure(config):
    global _log
    if _is_worker(config):
        folder = os.environ.get(ENV)
        if folder and Path(folder).is_dir():
            name = config.workerinput.get("workerid", f"pid{os.getpid()}")
            _log = open(Path(folder) / f"{name}.log", "a", buffering=1)
            faulthandler.enable(file=_log, all_threads=True)
    elif config.pluginmanager.hasplugin("xdist") and config.getoption("numprocesses", None):
        config._vr_crash_dir = tempfile.mkdtemp(prefix="vr-crash-")
        os.environ[ENV] = config._vr_crash_dir


@pytest.hookimpl(optionalhook=True)
def pytest_handlecrashitem(crashitem, report, sched):
    """Run a crashed test once more, in a fresh worker."""
    if crashitem not in _reruns and len(_reruns) < MAX_RERUNS:
        _reruns.append(crashitem)
        sched.mark_test_pending(crashitem)
        report.outcome = "rerun"


def pytest_report_teststatus(report, config):
    if report.outcome == "rerun":
        return "rerun", "R", ("RERUN", {"yellow": True})
    return None


def pytest_runtest_logstart(nodeid, location):
    if _log is not None:
        _log.write(f"start {nodeid}\n")


def crash_summary(folder) -> list[str]:
    """For each worker whose file holds a fatal-error report: the crashing thread's
    frames (most recent first, the test runner's left out), the last tests it started,
    and the error last, where the tail of a log shows it."""
    lines = []
    for path in sorted(Path(folder).glob("*.log")):
        text = path.read_text(errors="replace").splitlines()
        at = next((i for i, line in enumerate(text) if MARKER in line), None)
        if at is None:
            continue
        started = [line[len("start "):] for line in text[:at] if line.startswith("start ")]
        current = next((i for i in range(at, len(text)) if "Current thread" in text[i]),
                       len(text))
        frames = itertools.takewhile(str.strip, text[current + 1:])   # to the blank line
        stack = [line for line in frames if not any(part in line for part in RUNNER)]
        lines += [f"worker {path.stem}, the crashing thread (most recent call first):",
                  *stack[:FRAMES], "the last tests it started:",
                  *[f"  {nodeid}" for nodeid in started[-LAST_TESTS:]],
                  f"worker {path.stem}: {text[at].strip()}"]
    return lines


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    folder = getattr(config, "_vr_crash_dir", None)
    lines = crash_summary(folder) if folder else []
    if _reruns:
        lines.append(f"rerun once, in a fresh worker, after a crash: {', '.join(_reruns)}")
    if lines:
        terminalreporter.section("crashed workers (faulthandler)", sep="=", red=True)
        for line in lines:
            terminalreporter.line(line)


def pytest_unconfigure(config):
    global _log
    if _log is not None:
        faulthandler.disable()
        _log.close()
        _log = None
    folder = getattr(config, "_vr_crash_dir", None)
    if folder:
        shutil.rmtree(folder, ignore_errors=True)
        os.environ.pop(ENV, None)
