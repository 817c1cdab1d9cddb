"""The mutation run's list stays applicable (``make mutants`` itself is not part of
``make test``): every mutant's text occurs exactly once in its file, the mutation changes
the file, and every test it names to run first exists."""
import os
import shutil

import pytest

from _paths import ROOT
from tools import mutants as T
from tools.mutant_list import MUTANTS


@pytest.mark.parametrize("mutant", MUTANTS, ids=[m.name for m in MUTANTS])
def test_mutant_applies_once_and_names_existing_tests(mutant, tmp_path):
    copy = tmp_path / "copy"
    (copy / os.path.dirname(mutant.path)).mkdir(parents=True)
    shutil.copy(os.path.join(ROOT, mutant.path), copy / mutant.path)
    T.apply(mutant, str(copy))
    assert (copy / mutant.path).read_text() != open(os.path.join(ROOT, mutant.path)).read()
    for first in mutant.first:
        path, _, name = first.partition("::")
        assert os.path.isfile(os.path.join(ROOT, path)), first
        if name:
            base = name.split("[")[0]
            assert f"def {base}(" in open(os.path.join(ROOT, path)).read(), first


def test_a_stale_mutant_is_refused(tmp_path):
    stale = T.Mutant("stale", "integrators/warps.py", "text that is not there", "x", "none")
    (tmp_path / "integrators").mkdir()
    shutil.copy(os.path.join(ROOT, stale.path), tmp_path / stale.path)
    with pytest.raises(T.StaleMutant, match="occurs 0 times"):
        T.apply(stale, str(tmp_path))
