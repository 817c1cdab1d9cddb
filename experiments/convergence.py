"""Convergence sequences, error against spp and time, equal-time panel, efficiency table.

The study itself is :mod:`experiments.lib.studies.convergence`; this is its command::

    python -m experiments.convergence --help
"""
from experiments.lib.studies.convergence import STUDY

main = STUDY.main

if __name__ == "__main__":
    STUDY.script()
