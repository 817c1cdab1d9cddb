"""Stability sweeps: where each sampling method breaks down, measured and charted.

The study itself is :mod:`experiments.lib.studies.stability`; this is its command::

    python -m experiments.stability --help
"""
from experiments.lib.studies.stability import STUDY

main = STUDY.main

if __name__ == "__main__":
    STUDY.script()
