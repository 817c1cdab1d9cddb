"""Paths of the checkout for the tests, defined once (conftest and test modules import them).

Code that needs the bundled scenes at run time finds them with
``scenes.path(name)`` (package data); the tests use the checkout's files and
run the scripts from the checkout's root.
"""
import os

#: The checkout's root (the folder above ``tests/``).
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: The bundled scenes in the checkout.
SCENES = os.path.join(ROOT, "scenes")


def scene_path(name: str) -> str:
    """The checkout's copy of the bundled scene ``name`` (e.g. ``"cbox.xml"``)."""
    return os.path.join(SCENES, name)
