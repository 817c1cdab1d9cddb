"""``make mutants``: realistic bugs applied one at a time to a copy of the checkout; the
test suite must fail on every one.

Each mutant (:data:`tools.mutant_list.MUTANTS`) replaces one exact piece of source text
(it must occur exactly once, or the mutant is stale and the run says so) with a plausible
mistake: a warp or pdf off by a factor, a MIS weight that no longer sums to one, roulette
without eta^2, a sampler's dimension or index off by one, a metric, an interval, a verdict
turned round, the reference floor forgotten, warm timing switched off, a store key that
forgets a field. The copy holds every file git tracks, as it is in the working tree (so
uncommitted edits are tested too), then the mutation. The tests run there as ``make test``
runs them (``pytest tests`` under the project's configuration, the copy first on
``sys.path``), stopping at the first failure (``-x``): first the tests most likely to
catch the mutant (``first``: files or test ids) on their own, in one process; only where
they pass, the whole suite as ``make test`` runs it (its pytest-xdist workers). A mutant
no test kills is a survivor: the run prints it and exits with status 1.

    python -m tools.mutants            # every mutant
    python -m tools.mutants --list     # what they are
    python -m tools.mutants --only rr-eta,halton-dimension
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

from tools.mutant import Mutant
from tools.mutant_list import MUTANTS

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: A mutant's test run ends after this many seconds (a survivor then counts as one).
TIMEOUT = 900
#: pytest-xdist workers of the whole-suite stage (as ``make test``).
WORKERS = 2


@dataclass
class Outcome:
    mutant: Mutant
    killed_by: str | None
    seconds: float
    note: str = ""


class StaleMutant(ValueError):
    """The mutant's text is not in the file exactly once (the code moved on)."""


def tracked_files(root: str = ROOT) -> list[str]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=root, capture_output=True,
                         check=True).stdout.decode()
    return [f for f in out.split("\0") if f]


def copy_checkout(dest: str, root: str = ROOT) -> None:
    """Every tracked file of the working tree (uncommitted edits included) under ``dest``."""
    for rel in tracked_files(root):
        src = os.path.join(root, rel)
        if os.path.isfile(src):
            target = os.path.join(dest, rel)
            os.makedirs(os.path.dirname(target), exist_ok=True)
            shutil.copy2(src, target)


def apply(mutant: Mutant, root: str) -> None:
    path = os.path.join(root, mutant.path)
    with open(path, encoding="utf-8") as f:
        text = f.read()
    count = text.count(mutant.old)
    if count != 1:
        raise StaleMutant(f"mutant '{mutant.name}': its text occurs {count} times in "
                          f"{mutant.path} (expected exactly once): update tools/mutant_list.py")
    with open(path, "w", encoding="utf-8") as f:
        f.write(text.replace(mutant.old, mutant.new))


_FAILED = re.compile(r"^(FAILED|ERROR) (\S+)", re.M)


def first_failure(output: str) -> str | None:
    """The first test pytest's short summary names as failed (or erroring)."""
    m = _FAILED.search(output)
    return m.group(2) if m else None


def environment(copy: str) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = copy + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("PYTEST_ADDOPTS", None)
    return env


def check_imports_the_copy(copy: str) -> None:
    """The copy's packages, not the editable install's, are the ones the tests import."""
    probe = ("import integrators, experiments, os, sys; "
             "print(os.path.dirname(integrators.__file__)); "
             "print(os.path.dirname(experiments.__file__))")
    out = subprocess.run([sys.executable, "-c", probe], cwd=copy, env=environment(copy),
                         capture_output=True, text=True, timeout=120).stdout.split()
    expected = [os.path.join(copy, "integrators"), os.path.join(copy, "experiments")]
    if [os.path.realpath(p) for p in out] != [os.path.realpath(p) for p in expected]:
        raise RuntimeError(f"the copy at {copy} does not shadow the installed packages "
                           f"(imports resolved to {out})")


def run_one(mutant: Mutant, timeout: float = TIMEOUT) -> Outcome:
    with tempfile.TemporaryDirectory(prefix=f"mutant-{mutant.name}-") as tmp:
        copy = os.path.join(tmp, "checkout")
        copy_checkout(copy)
        apply(mutant, copy)
        check_imports_the_copy(copy)
        base = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider"]
        stages = ([base + list(mutant.first)] if mutant.first else []) + [
            base + ["-n", str(WORKERS), "tests"]]
        start = time.perf_counter()
        for argv in stages:
            left = timeout - (time.perf_counter() - start)
            try:
                proc = subprocess.run(argv, cwd=copy, env=environment(copy),
                                      capture_output=True, text=True, timeout=max(1.0, left))
            except subprocess.TimeoutExpired:
                return Outcome(mutant, None, time.perf_counter() - start,
                               f"no failure within {timeout:g} s")
            if proc.returncode != 0:
                break
        seconds = time.perf_counter() - start
        if proc.returncode == 0:
            return Outcome(mutant, None, seconds, "the whole suite passed")
        killer = first_failure(proc.stdout)
        if killer is None:
            tail = (proc.stdout + proc.stderr).strip().splitlines()[-1:] or ["?"]
            killer = f"(pytest exit {proc.returncode}: {tail[0][:80]})"
        return Outcome(mutant, killer, seconds)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.mutants", description=__doc__.split("\n")[0])
    p.add_argument("--list", action="store_true", help="list the mutants and exit")
    p.add_argument("--only", default="", help="comma-separated mutant names to run")
    p.add_argument("--timeout", type=float, default=TIMEOUT,
                   help="seconds a mutant's test run may take")
    args = p.parse_args(argv)
    names = {m.name for m in MUTANTS}
    chosen = [n.strip() for n in args.only.split(",") if n.strip()]
    bad = [n for n in chosen if n not in names]
    if bad:
        p.error(f"unknown mutant '{bad[0]}': choose from {', '.join(sorted(names))}")
    mutants = [m for m in MUTANTS if not chosen or m.name in chosen]
    if args.list:
        for m in mutants:
            print(f"{m.name:24s} {m.path}: {m.why}")
        return 0
    outcomes, start = [], time.perf_counter()
    for i, m in enumerate(mutants, 1):
        print(f"[{i}/{len(mutants)}] {m.name} ({m.path}): {m.why}", flush=True)
        try:
            o = run_one(m, args.timeout)
        except StaleMutant as e:
            o = Outcome(m, None, 0.0, str(e))
        outcomes.append(o)
        verdict = f"killed by {o.killed_by}" if o.killed_by else f"SURVIVED: {o.note}"
        print(f"    {verdict} in {o.seconds:.0f} s", flush=True)
    survivors = [o for o in outcomes if not o.killed_by]
    print(f"\n{len(outcomes) - len(survivors)} of {len(outcomes)} mutants killed in "
          f"{time.perf_counter() - start:.0f} s")
    print("| mutant | file | killed by | seconds |\n|---|---|---|---|")
    for o in outcomes:
        print(f"| {o.mutant.name} | {o.mutant.path} | "
              f"{o.killed_by or 'SURVIVED: ' + o.note} | {o.seconds:.0f} |")
    return 1 if survivors else 0


if __name__ == "__main__":
    sys.exit(main())
