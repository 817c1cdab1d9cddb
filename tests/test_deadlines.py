"""No test can hang: the project's pytest configuration gives every test a deadline.

pytest-timeout (``timeout`` in pyproject.toml's ``[tool.pytest.ini_options]``)
fails a test that runs past the deadline, with the stack of every thread, and
the session goes on. Checked by running pytest with this project's
configuration on a test that waits forever (the deadline shortened to 2 s
with ``-o timeout=2``): it must fail with pytest-timeout's message well before
the outer bound.
"""
from __future__ import annotations

import os
import subprocess
import sys
import re
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_the_configuration_sets_a_deadline():
    with open(os.path.join(ROOT, "pyproject.toml"), encoding="utf-8") as f:
        text = f.read()
    options = text[text.index("[tool.pytest.ini_options]"):]
    timeout = re.search(r"^timeout\s*=\s*(\d+)", options, re.M)
    method = re.search(r'^timeout_method\s*=\s*"(\w+)"', options, re.M)
    assert timeout and 60 <= int(timeout.group(1)) <= 1800   # generous, but a deadline
    assert method and method.group(1) in ("signal", "thread")


def test_a_hanging_test_fails_fast(tmp_path):
    hang = tmp_path / "test_hang.py"
    hang.write_text("import threading\n\n\ndef test_waits_forever():\n"
                    "    threading.Event().wait()\n")
    start = time.monotonic()
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          "-c", os.path.join(ROOT, "pyproject.toml"), "--rootdir", str(tmp_path),
                          "-o", "timeout=2", str(hang)], capture_output=True, text=True,
                         timeout=60, cwd=str(tmp_path))
    elapsed = time.monotonic() - start
    assert run.returncode == 1, run.stdout + run.stderr
    assert "Timeout (>2.0s) from pytest-timeout" in run.stdout, run.stdout
    assert "1 failed" in run.stdout and elapsed < 30
