"""What every study's typed settings share, made from the argparse Namespace in one place.

A study's library code takes a settings dataclass, never the Namespace, so that it can be
driven from Python, from another study or from a test without faking command-line
arguments. :class:`StudySettings` holds the options of :func:`~..cli.common_parser` with
what :func:`~..cli.parse_args` adds (the scene read, its depth settings, the methods as
parsed :class:`~..methods.Method` values, the executor); a study subclasses it with its
own options and builds it with :func:`common_fields` plus those. Its field names are those
:class:`~..study.Study` reads, so ``Study(settings)`` works.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..methods import Depth, Method
from ..scenes import SceneInfo


@dataclass(frozen=True)
class StudySettings:
    out: str                          # the report directory (``--out``)
    scene: str                        # the scene file
    info: SceneInfo
    resolution: tuple                 # (width, height)
    depth: Depth                      # the scene's path settings with --max-depth etc.
    methods: tuple                    # Method values, in order
    repeats: int                      # independent randomizations (--repeats)
    variant: str
    seed: int
    reference_spp: int
    reference_method: Method
    executor: object                  # a Dask executor, or None (the local loop)
    #: the reference store (``--reference-cache``); None: ``<out>/references``
    reference_cache: str | None = field(default=None, kw_only=True)
    #: the study's default --reference-spp, which sizes a reference's chunks whatever this
    #: run asks for (:func:`~..references.chunk_spp_for`); None: this run's reference_spp
    reference_spp_default: int | None = field(default=None, kw_only=True)
    #: an earlier run's --out whose equal-time counts are replayed (``--replay-counts``)
    replay_counts: str | None = field(default=None, kw_only=True)


def common_fields(args) -> dict:
    """The :class:`StudySettings` fields of a parsed Namespace (``cli.parse_args``)."""
    return {"out": args.out, "scene": args.scene, "info": args.info,
            "resolution": tuple(args.resolution), "depth": args.depth,
            "methods": tuple(args.method_objs), "repeats": int(args.repeats),
            "variant": args.variant, "seed": args.seed, "reference_spp": args.reference_spp,
            "reference_method": args.reference_method, "executor": args.executor,
            "reference_cache": args.reference_cache,
            "reference_spp_default": args.reference_spp_default,
            "replay_counts": args.replay_counts}
