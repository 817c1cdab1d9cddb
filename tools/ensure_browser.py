"""Make sure a Chromium exists for the browser tests (``make dev`` runs this).

The report viewer is tested in a real browser with Playwright for Python.
Playwright's own browser download is not used (it is not reachable everywhere,
and CI machines are plain Debian): the tests drive Debian's ``chromium``
package at :data:`CHROMIUM`. Like ``integrators/llvm.py --ensure`` for
libLLVM, this script installs the package with apt-get when the browser is
missing and it runs as root, and otherwise exits 1 with one line saying what
to install. ``VR_CHROMIUM`` points the tests at another Chromium binary.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys

APT_PACKAGE = "chromium"
CHROMIUM = "/usr/bin/chromium"
ENV_VAR = "VR_CHROMIUM"


def browser_path() -> str:
    """The Chromium the tests use: ``$VR_CHROMIUM`` or Debian's ``/usr/bin/chromium``."""
    return os.environ.get(ENV_VAR) or CHROMIUM


def usable(path: str) -> bool:
    return os.path.isfile(path) and os.access(path, os.X_OK)


def ensure() -> int:
    path = browser_path()
    if not usable(path) and ENV_VAR not in os.environ and hasattr(os, "geteuid") \
            and os.geteuid() == 0 and shutil.which("apt-get"):
        print(f"browser: {path} not found; installing {APT_PACKAGE} with apt-get")
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        subprocess.run(["apt-get", "update", "-qq"], check=False, env=env)
        subprocess.run(["apt-get", "install", "-y", "-qq", "--no-install-recommends",
                        APT_PACKAGE], check=False, env=env)
    if not usable(path):
        print(f"error: the viewer tests need Chromium at {path} and it was not found; "
              f"install it (Debian/Ubuntu: sudo apt-get install {APT_PACKAGE}) "
              f"or set {ENV_VAR} to a Chromium binary", file=sys.stderr)
        return 1
    print(f"browser: {path}")
    return 0


if __name__ == "__main__":
    if sys.argv[1:] == ["--ensure"]:
        sys.exit(ensure())
    print(browser_path())
