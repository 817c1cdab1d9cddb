"""Sampler study: halton (each randomization) against Mitsuba's own samplers, by efficiency.

The study itself is :mod:`experiments.lib.studies.samplers`; this is its command::

    python -m experiments.samplers --help
"""
from experiments.lib.studies.samplers import STUDY

main = STUDY.main

if __name__ == "__main__":
    STUDY.script()
