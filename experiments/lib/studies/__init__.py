"""Studies as a registry: what ``run_all`` runs, in their declared order, and the one ``main``.

A study is a :class:`StudySpec`: its name (the report section and ``run_all``'s
``--NAME default|quick|off`` option), its title, its declared ``order`` (``run_all`` runs
the studies and the report shows their sections in this order, so a study that reads
another's results, as the convergence study reads the sampler study's winner, comes after
it), its parser, and ``run(args)``, which plans, measures, analyses (a pure function of
numbers, tested on synthetic ones) and reports. ``quick`` is the extra argv of
``--NAME quick`` (tiny settings for tests); ``shared`` adds options that ``run_all`` also
takes and passes on (``forwarded``: destination -> option string).

Built-in studies are modules of this package, or subpackages with a ``study`` module
(:data:`BUILTIN`); a researcher's own study is one file that calls :func:`register_study`
(loaded with ``--plugin FILE``, see :mod:`experiments.lib.extensions`);
``docs/extending.md`` shows one.
"""
from __future__ import annotations

import importlib
import os
import sys
from dataclasses import dataclass, field
from typing import Callable

from ..scenes import Needs, SceneInfo, unmet

#: The built-in studies' modules in this package, a study that is a package by its
#: ``study`` module (each registers itself when imported, under its own name:
#: ``sampler_comparison.study`` registers the study ``samplers``).
BUILTIN = ("sampler_comparison.study", "convergence", "writeup", "lab.study", "stability",
           "suite.study")
#: ``run_all``'s choices for every study.
MODES = ("default", "quick", "off")


@dataclass(frozen=True)
class StudySpec:
    name: str
    title: str
    order: int
    build_parser: Callable                      # () -> cli.Parser
    run: Callable                               # (args) -> None
    parse: Callable | None = None               # argv -> args (default: cli.parse_args)
    quick: tuple = ()                           # extra argv of run_all's --NAME quick
    shared: Callable | None = None              # (parser) -> None: options run_all takes too
    forwarded: dict = field(default_factory=dict)  # {dest: option} run_all passes on when given
    needs: Needs = Needs()                      # what it needs of every scene (the contract)
    description: str = ""

    def parse_args(self, argv=None):
        from .. import cli
        return self.parse(argv) if self.parse else cli.parse_args(self.build_parser(), argv)

    def main(self, argv=None) -> None:
        """Parse, run, write the report: the ``main`` of every study script."""
        from .. import cli, report
        cli.load_extensions(argv)
        args = self.parse_args(argv)
        self.run(args)
        print(f"report: {report.build_report(args.out, args.variant)}")

    def script(self) -> None:
        """``python -m experiments.NAME``: :meth:`main` under the interrupt handler."""
        from .. import cli
        cli.main_wrapper(self.main)


def check_scene(study: str, info: SceneInfo, needs: Needs, part: str = "") -> str | None:
    """The scene contract, in one place for every study: None when ``info``'s scene has
    what ``needs`` asks, else why not, in one sentence that is also printed on stderr (the
    study puts it in its report section and goes on without that part)."""
    missing = unmet(info, needs)
    if not missing:
        return None
    what = f"{study} ({part})" if part else study
    reason = f"the scene has {', '.join(missing)}"
    print(f"{what}: skipped on {os.path.basename(info.path)}: {reason}", file=sys.stderr)
    return reason


_REGISTRY: dict[str, StudySpec] = {}


def register_study(spec: StudySpec, replace: bool = False) -> StudySpec:
    """Add a study (ValueError for a name already registered, unless ``replace``)."""
    if not spec.name.isidentifier() or spec.name in ("run_all", "all"):
        raise ValueError(f"invalid study name {spec.name!r}: use a Python identifier other "
                         f"than run_all and all")
    if spec.name in _REGISTRY and not replace and _REGISTRY[spec.name] != spec:
        raise ValueError(f"study '{spec.name}' is already registered (pass replace=True to "
                         f"replace it)")
    _REGISTRY[spec.name] = spec
    return spec


def load_builtin() -> None:
    for name in BUILTIN:
        importlib.import_module(f"{__name__}.{name}")


def ordered() -> list[StudySpec]:
    """Every registered study (the built-in ones included), in declared order."""
    load_builtin()
    return sorted(_REGISTRY.values(), key=lambda s: (s.order, s.name))


def get(name: str) -> StudySpec:
    load_builtin()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown study '{name}': choose from "
                         f"{', '.join(s.name for s in ordered())}") from None
