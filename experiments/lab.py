"""Sampling lab: every vr_path strategy as a warp, and every sampler's point sets, measured.

The study itself is :mod:`experiments.lib.studies.lab.study`; this is its command::

    python -m experiments.lab --help
"""
from experiments.lib.studies.lab.study import STUDY

main = STUDY.main

if __name__ == "__main__":
    STUDY.script()
