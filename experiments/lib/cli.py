"""The argument parser every script shares, its validation, and the main-function wrapper.

Bad arguments end the program with exit code 2 and one line on stderr
(``<prog>: error: ...``) before anything is written.
"""
from __future__ import annotations

import argparse
import atexit
import os
import re
import signal
import tempfile
import sys

import mitsuba as mi
import scenes
from integrators.choices import JIT_VARIANT_PREFIXES

from . import extensions
from . import plan
from .store import STORE_DIR, ReplayError
from .methods import DEFAULT_METHODS, Method, grammar, parse_method
from .scenes import (BUILTIN_SCENES, builtin_scene, effective_depth, load_scene,
                     read_scene)

#: The bundled scene (package data of :mod:`scenes`, found in a checkout and an install alike).
DEFAULT_SCENE = scenes.path("cbox.xml")
DEFAULT_OUT = "results"
DEFAULT_VARIANT = "llvm_ad_rgb"


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (no usage dump) and exit code 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def resolution(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not m or int(m.group(1)) < 1 or int(m.group(2)) < 1:
        raise argparse.ArgumentTypeError(
            f"invalid resolution '{text}': expected WIDTHxHEIGHT with positive integers, "
            f"e.g. 256x128")
    return int(m.group(1)), int(m.group(2))


def _int_at_least(text: str, lowest: int) -> int:
    try:
        value = int(text)
    except ValueError:
        value = lowest - 1
    if value < lowest:
        raise argparse.ArgumentTypeError(f"invalid value '{text}': expected an integer >= {lowest}")
    return value


def positive_int(text: str) -> int:
    return _int_at_least(text, 1)


def nonnegative_int(text: str) -> int:
    return _int_at_least(text, 0)


def int_list(option: str, lowest: int):
    """An argparse type for ``option``: comma-separated integers >= ``lowest``, duplicates
    dropped."""
    def parse(text: str) -> list[int]:
        try:
            values = [int(x) for x in text.split(",") if x.strip()]
        except ValueError:
            values = []
        if not values or min(values) < lowest:
            raise argparse.ArgumentTypeError(
                f"invalid {option} '{text}': expected comma-separated integers >= {lowest}, "
                f"e.g. {lowest},{lowest + 4}")
        return list(dict.fromkeys(values))
    return parse


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = 0.0
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"invalid value '{text}': expected a number > 0")
    return value


def method_list(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise argparse.ArgumentTypeError("--methods needs at least one method")
    for name in names:
        try:
            parse_method(name)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    return list(dict.fromkeys(names))


def common_parser(prog: str, description: str, spp: int | None = None,
                  time_budget: float | None = None, default_resolution: str = "256x128",
                  methods=DEFAULT_METHODS, repeats: int = 3) -> Parser:
    """The options every script takes; ``spp``/``time_budget`` add those options (defaults)."""
    p = Parser(prog=prog, description=description,
               formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--scene", default=DEFAULT_SCENE,
                   help="Mitsuba scene XML (its integrator and sampler are replaced per method), "
                        f"or a built-in scene: {', '.join(BUILTIN_SCENES)} (Mitsuba's "
                        "mi.cornell_box())")
    p.add_argument("--resolution", type=resolution, default=default_resolution,
                   metavar="WxH", help="film resolution")
    if spp is not None:
        p.add_argument("--spp", type=positive_int, default=spp,
                       help="samples per pixel of the longest render")
    p.add_argument("--methods", type=method_list, default=",".join(methods),
                   help="comma-separated methods: " + grammar()
                        + " (uniform+halton is the writeup's plain Halton)")
    p.add_argument("--max-depth", type=max_depth, default=None,
                   help="longest path (-1: unbounded); default: the scene's integrator's, "
                        "else the integrator's own default")
    p.add_argument("--rr-depth", type=positive_int, default=None,
                   help="depth where Russian roulette starts; default: the scene's, else the "
                        "integrator's own")
    p.add_argument("--variant", default=DEFAULT_VARIANT,
                   help="Mitsuba variant: llvm_* or cuda_* (e.g. cuda_ad_rgb on a GPU)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="base random seed")
    p.add_argument("--repeats", type=positive_int, default=repeats, metavar="R",
                   help="independent randomizations of every compared render: errors are "
                        "expected values over them, with 95%% confidence intervals (R >= 2)")
    p.add_argument("--out", default=DEFAULT_OUT, help="output directory (report: OUT/index.html)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=positive_int, metavar="N",
                       help="render on a local Dask cluster of N worker processes (one thread "
                            "each) instead of in this process")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="render on the Dask cluster whose scheduler is at ADDRESS (e.g. "
                            "tcp://<host>:8786); its workers set up --variant themselves")
    if time_budget is not None:
        p.add_argument("--time-budget", type=positive_float, default=time_budget, metavar="SECONDS",
                       help="render time per method in the equal-time comparison")
    p.add_argument("--reference-spp", type=positive_int, default=1024,
                   help="samples per pixel of the reference")
    p.add_argument("--reference-method", type=one_method, default="path",
                   help="method of the reference, with next-event estimation: path (Mitsuba's) "
                        "or e.g. bsdf+nee")
    p.add_argument("--reference-cache", default=None, metavar="DIR",
                   help="the reference store every study and run shares (references are "
                        "keyed by the scene's content and settings, and extended in place); "
                        "default: OUT/references")
    p.add_argument("--replay-counts", default=None, metavar="OUT",
                   help="take every equal-time render's sample count from the job of the same "
                        "name in an earlier run's OUT/store instead of from this run's timings "
                        "(re-measure a run with the same renders)")
    add_plugin_option(p)
    return p


def add_plugin_option(p: Parser) -> None:
    """``--plugin FILE``: a researcher's extension file (see :mod:`.extensions`)."""
    p.add_argument(extensions.OPTION, action="append", default=[], metavar="FILE",
                   help="a Python file that registers your own strategy, sampler or study "
                        "(imported first; repeatable)")


def load_extensions(argv=None) -> None:
    """Import the ``--plugin`` files of ``argv`` before any parser is built (so that their
    strategies, samplers and studies are known to it), with the Mitsuba variant of
    ``--variant`` set first. A bad file ends the program with exit code 2 and one line."""
    files = extensions.files_in(argv)
    if not files:
        return
    argv = list(sys.argv[1:] if argv is None else argv)
    variant = next((argv[i + 1] for i, a in enumerate(argv[:-1]) if a == "--variant"),
                   next((a.split("=", 1)[1] for a in argv if a.startswith("--variant=")),
                        DEFAULT_VARIANT))
    parser = Parser(prog=os.path.basename(sys.argv[0]) or "experiments")
    _set_variant(parser, variant)
    try:
        extensions.load_all(files)
    except extensions.ExtensionError as e:
        parser.error(str(e))


def max_depth(text: str) -> int:
    return _int_at_least(text, -1)


def one_method(text: str) -> Method:
    """An argparse type: the parsed :class:`~.methods.Method` (its ``str`` is its name)."""
    try:
        return parse_method(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def common_fields(args) -> dict:
    """The :class:`.study.StudySettings` fields of a parsed Namespace (``cli.parse_args``)."""
    return {"out": args.out, "scene": args.scene, "info": args.info,
            "resolution": tuple(args.resolution), "depth": args.depth,
            "methods": tuple(args.method_objs), "repeats": int(args.repeats),
            "variant": args.variant, "seed": args.seed, "reference_spp": args.reference_spp,
            "reference_method": args.reference_method, "executor": args.executor,
            "reference_cache": args.reference_cache,
            "reference_spp_default": args.reference_spp_default,
            "replay_counts": args.replay_counts}


def explicit_options(parser: Parser, argv) -> set[str]:
    """Destinations of the options given on the command line (not left at their default)."""
    given = set()
    for token in (sys.argv[1:] if argv is None else argv):
        action = parser._option_string_actions.get(token.split("=", 1)[0])
        if action is not None:
            given.add(action.dest)
    return given


def _check_out(out: str) -> str | None:
    """Why ``out`` cannot be written, or None."""
    path = os.path.abspath(out)
    if os.path.exists(path) and not os.path.isdir(path):
        return f"--out '{out}' exists and is not a directory"
    parent = path
    while not os.path.exists(parent):
        parent = os.path.dirname(parent)
    try:                                   # really try: root passes os.access everywhere
        fd, probe = tempfile.mkstemp(prefix=".probe-", dir=parent)
        os.close(fd)
        os.remove(probe)
    except OSError:
        return f"--out '{out}' is not writable ('{parent}' does not allow creating files)"
    return None


def _set_variant(parser: Parser, variant: str) -> None:
    jit = [v for v in mi.variants() if v.split("_")[0] in JIT_VARIANT_PREFIXES]
    if variant not in mi.variants():
        parser.error(f"unknown variant '{variant}': this Mitsuba has {', '.join(jit)}")
    if variant not in jit:
        parser.error(f"variant '{variant}' is not supported: the plugins need a JIT variant "
                     f"({', '.join(jit)})")
    try:
        mi.set_variant(variant)
        mi.load_dict({"type": "vr_path"})
    except Exception as e:  # noqa: BLE001  (no GPU for cuda_*, etc.)
        hint = " (no CUDA GPU here?)" if variant.startswith("cuda") else ""
        parser.error(f"variant '{variant}' cannot be used here{hint}: "
                     f"{str(e).strip().splitlines()[0]}")


def parse_args(parser: Parser, argv=None) -> argparse.Namespace:
    """Parse and validate; set the Mitsuba variant.

    Adds ``args.info`` (the scene), ``args.depth`` (its integrator settings
    with --max-depth/--rr-depth applied), ``args.method_objs``,
    ``args.explicit`` (the options given on the command line) and
    ``args.executor`` (the Dask cluster of --workers/--scheduler, else None).
    """
    args = parser.parse_args(argv)
    args.explicit = explicit_options(parser, argv)
    # the size of a reference's chunks follows the study's default, not this run's count
    args.reference_spp_default = parser.get_default("reference_spp")
    builtin = args.scene in BUILTIN_SCENES
    if not builtin and not os.path.isfile(args.scene):
        parser.error(f"scene file '{args.scene}' does not exist (or use a built-in scene: "
                     f"{', '.join(BUILTIN_SCENES)})")
    problem = _check_out(args.out)
    if problem:
        parser.error(problem)
    if args.replay_counts is not None and not os.path.isdir(
            os.path.join(args.replay_counts, STORE_DIR)):
        parser.error(f"--replay-counts '{args.replay_counts}' has no {STORE_DIR}/ folder: give "
                     f"the --out of an earlier run")
    _set_variant(parser, args.variant)
    mi.set_log_level(mi.LogLevel.Error)   # not the samplers' "rounding to N" per render
    args.executor = open_executor(parser, args)     # before anything is written
    if builtin:
        args.scene = builtin_scene(args.scene, os.path.join(args.out, "cache", "scenes"))
    try:
        args.info = read_scene(args.scene)
    except (ValueError, OSError) as e:
        parser.error(str(e))
    args.depth = effective_depth(args.info, args.max_depth, args.rr_depth)
    args.method_objs = [parse_method(n) for n in args.methods]   # checked by method_list
    for method in args.method_objs:
        try:
            plan.check_terminates(method, args.depth)
        except ValueError as e:
            parser.error(str(e))
    width, height = args.resolution
    try:   # the scene must load as every method would load it
        load_scene(args.scene, width, height, args.method_objs[0], args.depth)
    except Exception as e:  # noqa: BLE001
        parser.error(f"scene '{args.scene}' does not load: {str(e).strip().splitlines()[-1]}")
    return args


#: Dask executors opened by :func:`open_executor`, closed by :func:`close_executors`.
_EXECUTORS: list = []


def open_executor(parser: Parser, args: argparse.Namespace):
    """The executor that ``--workers`` / ``--scheduler`` ask for; None (the local loop)
    without them. An unusable cluster is a one-line error (exit 2) within 10 s."""
    if args.workers is None and args.scheduler is None:
        return None
    try:
        from . import cluster
    except ImportError as e:
        parser.error(f"--workers and --scheduler need dask.distributed ({e}); install it "
                     f"with: pip install '.[cluster]'")
    try:
        if args.workers is not None:
            executor = cluster.DaskExecutor.local(args.workers, args.variant)
        else:
            executor = cluster.DaskExecutor.connect(args.scheduler, args.variant)
    except cluster.ClusterError as e:
        parser.error(str(e))
    if not _EXECUTORS:
        atexit.register(close_executors)
    _EXECUTORS.append(executor)
    print(f"rendering on {executor.describe()}", file=sys.stderr)
    return executor


def close_executors() -> None:
    """Close every executor :func:`open_executor` opened (and the clusters it started)."""
    while _EXECUTORS:
        _EXECUTORS.pop().close()


def main_wrapper(main):
    """Run ``main()``; Ctrl-C or kill ends it with one line (finished files are kept)."""
    def handler(signum, frame):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, handler)
    try:
        main()
    except ReplayError as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("\ninterrupted: finished files are kept; run the same command again to resume",
              file=sys.stderr)
        sys.exit(130)
    finally:
        close_executors()
