"""The writeup's figures, with numbers.

The study itself is :mod:`experiments.lib.studies.writeup`; this is its command::

    python -m experiments.writeup --help
"""
from experiments.lib.studies.writeup import STUDY

main = STUDY.main

if __name__ == "__main__":
    STUDY.script()
