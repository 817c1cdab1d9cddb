"""The wheel (issue #17): it holds every package and its data, and a study runs from it alone.

The checkout's packaged sources are copied to a temporary folder (so a stale
``build/`` there cannot leak into the wheel and the checkout stays clean),
built with ``pip wheel --no-deps --no-build-isolation`` and installed with
``pip install --no-deps --target`` into an empty folder. The installed copy
then runs ``run_all --help`` and a tiny convergence study from a folder
outside the checkout, with the checkout NOT importable: ``python -S`` skips
site-packages' ``.pth`` files (the editable install's finder would map
``experiments`` into the checkout), and ``PYTHONPATH`` is the target folder,
then the venv's site-packages (mitsuba, numpy, ...). The study must find the
bundled default scene and the viewer's assets inside the target folder.

Every subprocess runs under one deadline (:data:`DEADLINE_S`).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import time
import zipfile
from importlib import metadata

import pytest

from _paths import ROOT

#: The whole test (build, install, two script runs) must finish within this many seconds.
DEADLINE_S = 420
#: What the wheel is built from: the files pyproject.toml names or reads.
SOURCES = ("pyproject.toml", "README.md", "integrators", "experiments", "scenes")
PYTHON = sys.executable


class Deadline:
    def __init__(self, seconds: float):
        self.end = time.monotonic() + seconds

    def run(self, cmd: list[str], **kwargs) -> subprocess.CompletedProcess:
        left = self.end - time.monotonic()
        if left <= 0:
            pytest.fail(f"deadline of {DEADLINE_S} s passed before: {' '.join(cmd)}")
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=left, **kwargs)
        assert proc.returncode == 0, (f"{' '.join(cmd)} exited {proc.returncode}\n"
                                      f"stdout:\n{proc.stdout[-3000:]}\n"
                                      f"stderr:\n{proc.stderr[-3000:]}")
        return proc


def _version(text: str) -> tuple[int, ...]:
    return tuple(int(p) for p in text.split(".")[:2] if p.isdigit())


def require_build_tools() -> None:
    """The venv must be able to build the wheel without build isolation (no download)."""
    try:
        version = metadata.version("setuptools")
    except metadata.PackageNotFoundError:
        pytest.fail("setuptools is not installed: pip install -e '.[test]'")
    assert _version(version) >= (77,), f"setuptools {version} < 77: pip install -e '.[test]'"
    try:
        import setuptools.command.bdist_wheel  # noqa: F401  (setuptools >= 70.1)
    except ImportError:
        pytest.fail(f"setuptools {version} has no bdist_wheel (needs >= 70.1, as the test "
                    f"extra requires): pip install -e '.[test]'")


def copy_sources(dest: str) -> None:
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", "build", "dist")
    for name in SOURCES:
        src = os.path.join(ROOT, name)
        if os.path.isdir(src):
            shutil.copytree(src, os.path.join(dest, name), ignore=ignore)
        else:
            shutil.copy2(src, dest)


def isolated_env(target: str) -> dict[str, str]:
    """Environment for ``python -S``: the target folder, then the venv's site-packages."""
    site = [sysconfig.get_path("purelib"), sysconfig.get_path("platlib")]
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env["PYTHONPATH"] = os.pathsep.join([target] + list(dict.fromkeys(site)))
    env["PYTHONNOUSERSITE"] = "1"
    return env


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(wheel path, target folder, deadline) of the freshly built and installed wheel."""
    require_build_tools()
    deadline = Deadline(DEADLINE_S)
    base = tmp_path_factory.mktemp("packaging")
    src, dist, target = (str(base / n) for n in ("src", "dist", "target"))
    os.makedirs(src)
    copy_sources(src)
    deadline.run([PYTHON, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                  "--no-index", "-q", "-w", dist, src], cwd=str(base))
    (wheel,) = [os.path.join(dist, n) for n in os.listdir(dist) if n.endswith(".whl")]
    os.makedirs(target)
    deadline.run([PYTHON, "-m", "pip", "install", "--no-deps", "--no-index", "-q",
                  "--target", target, wheel], cwd=str(base))
    return wheel, target, deadline


def test_wheel_holds_every_package_and_its_data(installed):
    wheel, _, _ = installed
    names = set(zipfile.ZipFile(wheel).namelist())
    lib = sorted(n for n in os.listdir(os.path.join(ROOT, "experiments", "lib"))
                 if n.endswith(".py"))
    assert len(lib) >= 10
    for name in lib:
        assert f"experiments/lib/{name}" in names, f"experiments/lib/{name} not in the wheel"
    for name in ("experiments/__init__.py", "experiments/run_all.py",
                 "experiments/convergence.py", "integrators/__init__.py",
                 "integrators/choices.py", "experiments/lib/viewer_assets/viewer.js",
                 "experiments/lib/viewer_assets/viewer.css", "scenes/__init__.py",
                 "scenes/cbox.xml", "scenes/furnace.xml"):
        assert name in names, f"{name} not in the wheel"
    assert not any(n.startswith(("tests/", "benchmarks/", "tools/")) for n in names)


def test_installed_copy_runs_without_the_checkout(installed, tmp_path):
    _, target, deadline = installed
    env = isolated_env(target)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    probe = ("import json, sys, integrators, experiments.lib, scenes; "
             "from experiments.lib import cli, viewer; "
             "print(json.dumps({'lib': experiments.lib.__file__, "
             "'integrators': integrators.__file__, 'scenes': scenes.__file__, "
             "'scene': cli.DEFAULT_SCENE, 'assets': str(viewer.ASSETS_DIR), "
             "'path': sys.path}))")
    where = json.loads(deadline.run([PYTHON, "-S", "-c", probe], cwd=str(elsewhere),
                                    env=env).stdout.strip().splitlines()[-1])
    real = os.path.realpath(target)
    for key in ("lib", "integrators", "scenes", "scene", "assets"):
        assert os.path.realpath(where[key]).startswith(real + os.sep), (key, where[key])
    assert os.path.isfile(where["scene"])
    root = os.path.realpath(ROOT)
    entries = [os.path.realpath(p) for p in where["path"] if p]   # '' is the folder elsewhere
    assert root not in entries, where["path"]      # (the venv may live inside the checkout)

    deadline.run([PYTHON, "-S", "-m", "experiments.run_all", "--help"], cwd=str(elsewhere),
                 env=env)

    out = tmp_path / "out"
    deadline.run([PYTHON, "-S", "-m", "experiments.convergence", "--resolution", "8x4",
                  "--spp", "2", "--reference-spp", "4", "--methods", "bsdf",
                  "--time-budget", "1e-9", "--out", str(out)], cwd=str(elsewhere), env=env)
    section = json.loads((out / "convergence" / "section.json").read_text())
    scene = section["settings"]["scene"]
    assert os.path.realpath(scene).startswith(real + os.sep), scene
    assert (out / "index.html").is_file()
    for name in ("viewer.js", "viewer.css"):
        with open(os.path.join(target, "experiments", "lib", "viewer_assets", name), "rb") as f:
            assert (out / name).read_bytes() == f.read()
