"""Find a libLLVM that Dr.Jit's LLVM backend can use, before drjit is imported.

Dr.Jit 1.5 needs libLLVM >= 17. Debian 12 ships libLLVM 14 and 15; with 15
every render aborts the process ("LLVM ERROR: Cannot select: fminimum"), with
14 Dr.Jit refuses to start. Dr.Jit reads ``DRJIT_LIBLLVM_PATH`` exactly once,
when ``drjit`` is first imported, so the choice must be made before that.

This module never imports drjit at module level. It is used in two ways:

* ``integrators/__init__.py`` calls :func:`configure` first thing: it sets
  ``DRJIT_LIBLLVM_PATH`` to the newest suitable library unless the variable is
  already set, and raises a clear error if drjit was already imported with an
  unsuitable one.
* ``make install`` runs ``python3 integrators/llvm.py --ensure``: it prints the
  library it would use, installs Debian's ``libllvm19`` with apt-get when none is
  found and it runs as root, and otherwise exits 1 with one line saying what to
  install.
"""
from __future__ import annotations

import glob
import os
import re
import shutil
import subprocess
import sys

MIN_VERSION = 17
APT_PACKAGE = "libllvm19"
ENV_VAR = "DRJIT_LIBLLVM_PATH"

SEARCH_PATTERNS = (
    "/usr/lib/*-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/lib/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM.dylib",
    "/usr/local/opt/llvm/lib/libLLVM.dylib",
)

_VERSION_RES = (
    re.compile(r"libLLVM-(\d+)"),        # libLLVM-19.so
    re.compile(r"libLLVM\.so\.(\d+)"),   # libLLVM.so.19.1
    re.compile(r"llvm-(\d+)/lib/"),      # /usr/lib/llvm-19/lib/libLLVM.so
    re.compile(r"libLLVM(\d+)\."),       # libLLVM19.so (some distributions)
)


def library_version(path: str) -> int | None:
    """Major LLVM version encoded in a library path, or None if unknown."""
    for regex in _VERSION_RES:
        m = regex.search(path)
        if m:
            return int(m.group(1))
    return None


def candidates() -> list[tuple[int, str]]:
    """All libLLVM files on this machine with a known version, newest first."""
    found = {}
    for pattern in SEARCH_PATTERNS:
        for path in glob.glob(pattern):
            version = library_version(path)
            if version is not None and os.path.isfile(path):
                found.setdefault(os.path.realpath(path), (version, path))
    return sorted(found.values(), reverse=True)


def find_library(min_version: int = MIN_VERSION) -> str | None:
    """Path of the newest libLLVM with major version >= ``min_version``."""
    for version, path in candidates():
        if version >= min_version:
            return path
    return None


def loaded_version() -> int | None:
    """Major version of the libLLVM an already imported drjit loaded."""
    dr = sys.modules.get("drjit")
    if dr is None:
        return None
    try:
        return int(dr.detail.llvm_version()[0])
    except Exception:
        return None


class LLVMError(ImportError):
    """No usable libLLVM for Dr.Jit's LLVM backend."""


def configure() -> str | None:
    """Point Dr.Jit at a libLLVM >= 17; return the path chosen (or in use).

    Does nothing but check when drjit is already imported: then it is too late
    to choose, and an unsuitable library raises :class:`LLVMError` with the fix.
    """
    if "drjit" in sys.modules:
        version = loaded_version()
        if version is not None and version < MIN_VERSION:
            raise LLVMError(
                f"drjit was imported before 'integrators' and loaded libLLVM {version}; "
                f"Dr.Jit's LLVM backend needs libLLVM >= {MIN_VERSION}. Install one "
                f"(Debian: apt-get install {APT_PACKAGE}) and set {ENV_VAR} to it, or "
                f"import integrators before mitsuba/drjit.")
        return os.environ.get(ENV_VAR)
    if os.environ.get(ENV_VAR):
        return os.environ[ENV_VAR]
    path = find_library()
    if path is not None:
        os.environ[ENV_VAR] = path
    return path


def ensure() -> int:
    """Command-line helper for ``make install``: make sure a libLLVM >= 17 exists."""
    env_path = os.environ.get(ENV_VAR)
    if env_path:
        print(f"libLLVM: using {ENV_VAR}={env_path}")
        return 0
    path = find_library()
    if path is None and hasattr(os, "geteuid") and os.geteuid() == 0 \
            and shutil.which("apt-get"):
        print(f"libLLVM: no libLLVM >= {MIN_VERSION} found; installing {APT_PACKAGE} with apt-get")
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        subprocess.run(["apt-get", "update", "-qq"], check=False, env=env)
        subprocess.run(["apt-get", "install", "-y", "-qq", APT_PACKAGE],
                       check=False, env=env)
        path = find_library()
    if path is None:
        print(f"error: Dr.Jit needs libLLVM >= {MIN_VERSION} and none was found; "
              f"install it (Debian/Ubuntu: sudo apt-get install {APT_PACKAGE}) "
              f"or set {ENV_VAR} to its path", file=sys.stderr)
        return 1
    print(f"libLLVM: {path} (version {library_version(path)})")
    return 0


if __name__ == "__main__":
    if sys.argv[1:] == ["--ensure"]:
        sys.exit(ensure())
    print(find_library() or "")
