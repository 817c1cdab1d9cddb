"""Figures written by worker processes (experiments/lib/figure_pool.py): the same files as
written in the process, none drawn while a render runs, every failure named."""
from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402

from experiments.lib import execute, figure_pool  # noqa: E402


def _figure(seed: int = 0):
    rng = np.random.default_rng(seed)
    fig, (a, b) = plt.subplots(1, 2, figsize=(4, 2))
    a.imshow(rng.random((12, 16, 3)), interpolation="nearest")
    b.plot(rng.random(20))
    b.set_title("a title")
    return fig


def test_a_worker_writes_the_same_png_as_this_process(tmp_path):
    here, there = str(tmp_path / "here.png"), str(tmp_path / "there.png")
    figure_pool.save(_figure(), [(here, "png", 100)])
    with figure_pool.parallel(2):
        figure_pool.save(_figure(), [(there, "png", 100), (str(tmp_path / "t.pdf"), "pdf", 100)])
        assert figure_pool._pending, "handed to a worker, not written here"
    with open(here, "rb") as f, open(there, "rb") as g:
        assert f.read() == g.read()
    assert os.path.getsize(tmp_path / "t.pdf") > 0


def test_a_render_waits_for_the_figures_handed_over(tmp_path, monkeypatch):
    """When a render starts, every figure handed over before it is on disk."""
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    d = mi.cornell_box()
    d["sensor"]["film"].update(width=8, height=8)
    scene = mi.load_dict(d)
    paths = [str(tmp_path / f"f{i}.png") for i in range(3)]
    seen = []
    render = mi.render

    def checked(*a, **k):
        seen.append([os.path.exists(p) for p in paths])
        return render(*a, **k)
    monkeypatch.setattr(mi, "render", checked)
    with figure_pool.parallel(2):
        for i, path in enumerate(paths):
            figure_pool.save(_figure(i), [(path, "png", 150)])
        execute._render(scene, None, 1, 1)
    assert seen == [[True] * 3]


def test_a_figure_that_fails_in_a_worker_is_named(tmp_path):
    bad = str(tmp_path / "bad.xyz")
    with pytest.raises(RuntimeError, match="bad.xyz"):
        with figure_pool.parallel(2):
            figure_pool.save(_figure(), [(str(tmp_path / "good.png"), "png", 100)])
            figure_pool.save(_figure(), [(bad, "no-such-format", 100)])
    assert os.path.exists(tmp_path / "good.png") and not os.path.exists(bad)
    assert not figure_pool._failed and figure_pool._pool is None


def test_a_figure_that_cannot_be_pickled_is_written_here(tmp_path):
    path = str(tmp_path / "lambda.png")
    fig = _figure()
    fig.axes[1].xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:.0f}"))
    with figure_pool.parallel(2):
        figure_pool.save(fig, [(path, "png", 100)])
        assert os.path.exists(path) and not figure_pool._pending


def test_a_figure_past_its_deadline_is_named_and_its_worker_ended(tmp_path, monkeypatch):
    """No wait without a deadline: a figure that takes longer than DEADLINE fails by name,
    the pool does not wait for its worker, and the worker's half-written temporary file is
    removed. The deadline falls once the worker has begun writing (its temporary file is
    there: a PDF is written as it is drawn, 200000 points take seconds), so the removal
    is tested, not only a worker ended before it wrote anything."""
    import time
    rng = np.random.default_rng(1)
    fig, ax = plt.subplots()
    ax.plot(rng.random(200_000), rng.random(200_000), ".", ms=1)
    start = time.perf_counter()
    with pytest.raises(RuntimeError, match="slow.pdf: not written within"):
        with figure_pool.parallel(2):
            figure_pool.save(fig, [(str(tmp_path / "slow.pdf"), "pdf", 72)])
            while not any(n.startswith(".tmp-") for n in os.listdir(tmp_path)):
                assert time.perf_counter() - start < 60, "the worker never began writing"
                time.sleep(0.01)
            monkeypatch.setattr(figure_pool, "DEADLINE", 0.01)
    assert time.perf_counter() - start < 60 and figure_pool._pool is None
    assert os.listdir(tmp_path) == [], "no file, whole or temporary, is left"