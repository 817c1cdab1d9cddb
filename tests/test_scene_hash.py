"""A scene's content hash (experiments/lib/scenes.py) keys its references and seeds its
renders: it must not depend on where the project lies. The suite's cbox.xml includes
../cbox.xml; with the included file's absolute path in the hash, two clones of the project
rendered cbox's references with different seeds (and the reference-choice test passed in
one clone and failed in two others)."""
from __future__ import annotations

import shutil

import scenes
from experiments.lib import scenes as scene_files


def _copy(root, name):
    """The suite's cbox.xml and the file it includes, copied under ``root``/``name``."""
    top = root / name
    (top / "suite").mkdir(parents=True)
    shutil.copy(scenes.path("suite/cbox.xml"), top / "suite" / "cbox.xml")
    shutil.copy(scenes.path("cbox.xml"), top / "cbox.xml")
    return top


def test_a_scene_hashes_alike_wherever_it_lies(tmp_path):
    a, b = _copy(tmp_path, "one"), _copy(tmp_path, "elsewhere/two")
    files = scene_files.parse(str(a / "suite" / "cbox.xml")).files
    assert len(files) == 2                     # the included file is part of the hash
    assert scene_files.scene_hash(str(a / "suite" / "cbox.xml")) == \
        scene_files.scene_hash(str(b / "suite" / "cbox.xml")) == \
        scene_files.scene_hash(scenes.path("suite/cbox.xml"))
    # negative control: the included file's content changes the hash
    (b / "cbox.xml").write_text((b / "cbox.xml").read_text() + "\n<!-- changed -->\n")
    assert scene_files.scene_hash(str(a / "suite" / "cbox.xml")) != \
        scene_files.scene_hash(str(b / "suite" / "cbox.xml"))
