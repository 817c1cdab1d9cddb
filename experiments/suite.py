"""Scene suite: every method on scenes that each isolate one phenomenon, with the winner per scene.

The study itself is the package :mod:`experiments.lib.studies.suite`; this is its command::

    python -m experiments.suite --help
"""
from experiments.lib.studies.suite.study import STUDY

main = STUDY.main

if __name__ == "__main__":
    STUDY.script()
