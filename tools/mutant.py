"""One mutant of ``make mutants``: the :class:`Mutant` record (which text of which file it
replaces, with what, the bug it stands for, the tests to run first).

Its own module so that imports run one way: :mod:`tools.mutant_list` (the entries) and
:mod:`tools.mutants` (the run) both import it, and the run imports the list.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Mutant:
    name: str
    path: str              # file, relative to the checkout
    old: str               # exact text, found exactly once
    new: str
    why: str               # the realistic bug it stands for
    first: tuple = ()      # test files or ids run first, alone (then the whole suite)
