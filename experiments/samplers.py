"""Sampler study: every sampler of the sampler table, the bundled ones against Mitsuba's own.

The study itself is :mod:`experiments.lib.studies.sampler_comparison.study`; this is its
command::

    python -m experiments.samplers --help
"""
from experiments.lib.studies.sampler_comparison.study import STUDY

main = STUDY.main

if __name__ == "__main__":
    STUDY.script()
