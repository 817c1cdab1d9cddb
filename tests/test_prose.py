"""experiments/lib/prose.py: the report layer's templates (jinja2)."""
import jinja2
import pytest

from experiments.lib import prose


def test_say_fills_a_template_and_folds_whitespace():
    text = prose.say("""{{ a }} is more efficient than {{ b }}
                        by {{ ratio | g }} ({{ share | pct }} of the time).""",
                     a="bsdf+nee", b="path", ratio=1.23456, share=0.5)
    assert text == "bsdf+nee is more efficient than path by 1.23 (50% of the time)."


def test_an_undefined_name_is_an_error_not_an_empty_word():
    with pytest.raises(jinja2.UndefinedError, match="ratio"):
        prose.say("by {{ ratio }}")


def test_and_join():
    assert prose.and_join(["a"]) == "a"
    assert prose.and_join(["a", "b"]) == "a and b"
    assert prose.and_join(["a", "b", "c"]) == "a, b and c"
    assert prose.and_join([]) == ""
