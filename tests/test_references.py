"""The reference store (experiments/lib/references.py): rendered once, cached under a key of
everything the image depends on, extended chunk by chunk without re-rendering what is
there, with its own expected error estimated from the spread of its chunks (checked
against the furnace's exact value by an F test, with a negative control)."""
from __future__ import annotations

import json
import math
import os
import shutil

import numpy as np
import pytest
from scipy import stats as sps

import scenes
from experiments.lib import files
from experiments.lib import references as R
from experiments.lib.methods import Depth, parse_method
from experiments.lib.scenes import read_scene

FURNACE = scenes.path("furnace.xml")          # 8 x 8, every pixel exactly 2
VARIANT = "llvm_ad_rgb"
#: Two-sided level of the F test of the reference's own error.
ALPHA = 1e-3


def spec(path=FURNACE, width=8, height=8, depth=Depth(-1), method="path", chunk=4):
    return R.RefSpec(read_scene(path), width, height, depth, parse_method(method), VARIANT,
                     chunk)


def test_rendered_once_then_extended_without_rerendering(tmp_path, count_jobs):
    store = R.ReferenceStore(str(tmp_path / "refs"))
    s = spec()
    assert store.ensure(s, 32) == 8 and len(count_jobs) == 8       # 8 chunks of 4 spp
    first = store.read(s)
    assert first.spp == 32 and first.chunks == 8
    chunk0 = files.read_npz(store.store.path(f"{s.key}/chunk-00000"))["image"]
    count_jobs.clear()
    assert store.ensure(s, 32) == 0 and count_jobs == []            # a second run: nothing
    assert store.ensure(s, 48) == 4                                 # more spp: 4 new chunks
    assert count_jobs == [f"{s.key}/chunk-{i:05d}" for i in range(8, 12)]
    np.testing.assert_array_equal(
        files.read_npz(store.store.path(f"{s.key}/chunk-00000"))["image"], chunk0)
    more = store.read(s)
    assert more.spp == 48 and more.chunks == 12
    # the JSON beside it says how it was made, and no temporary file is left behind
    made = json.loads((tmp_path / "refs" / s.key / R.JSON_NAME).read_text())
    assert (made["spp"], made["chunks"], made["chunk_spp"], made["method"]) == (48, 12, 4, "path")
    assert made["key_fields"]["scene_sha256"] == s.info.sha256
    assert (tmp_path / "refs" / s.key / "reference.exr").exists()
    assert not [p for p in (tmp_path / "refs").rglob(".tmp-*")]
    # the first chunks of the extended reference are the old reference
    np.testing.assert_allclose(store.read(s, 32).image, first.image)
    # asked for fewer chunks than it holds (a later declaration of the first size), the
    # JSON and image still describe every chunk it holds, not the fewer
    assert store.ensure(s, 32) == 0
    again = json.loads((tmp_path / "refs" / s.key / R.JSON_NAME).read_text())
    assert (again["spp"], again["chunks"]) == (48, 12)
    np.testing.assert_allclose(files.read_exr(str(tmp_path / "refs" / s.key / "reference.exr")),
                               more.image, rtol=1e-6)


def test_key_is_the_content_not_the_path(tmp_path):
    copy = tmp_path / "elsewhere.xml"
    shutil.copy(FURNACE, copy)
    base = spec()
    assert spec(str(copy)).key.split("-")[-1] == base.key.split("-")[-1]   # same content
    others = [spec(width=4, height=4), spec(depth=Depth(3)), spec(method="bsdf+nee"),
              spec(chunk=8), R.RefSpec(base.info, 8, 8, Depth(-1), base.method,
                                       "llvm_ad_mono", 4)]
    keys = {base.key} | {o.key for o in others}
    assert len(keys) == len(others) + 1
    # an included file is part of the content: changing it changes the key
    (tmp_path / "part.xml").write_text('<scene version="3.0.0"><sensor type="perspective">'
                                       '<film type="hdrfilm"><integer name="width" '
                                       'value="4"/></film></sensor></scene>')
    (tmp_path / "wrap.xml").write_text('<scene version="3.0.0"><include filename="part.xml"/>'
                                       '</scene>')
    before = spec(str(tmp_path / "wrap.xml")).key
    (tmp_path / "part.xml").write_text((tmp_path / "part.xml").read_text()
                                       .replace('value="4"', 'value="5"'))
    assert spec(str(tmp_path / "wrap.xml")).key != before


def f_test(ref: R.Reference, exact: float) -> float:
    """Two-sided p-value of mean((ref - exact)^2) against the reference's own expected MSE
    (one channel: the furnace is grey). Per pixel, (ref - exact)^2 / var is chi2(1) and
    the floor var * chi2(P - 1) / (P - 1), so their ratio over the pixels is F(n, n (P-1))."""
    n = ref.image.shape[0] * ref.image.shape[1]
    err = float(np.mean((ref.image[..., 0] - exact) ** 2))
    floor = float(np.mean(ref.relmse_floor_map[..., 0] * (ref.image[..., 0] ** 2 + 0.01)))
    f = err / floor
    cdf = sps.f.cdf(f, n, n * (ref.chunks - 1))
    return 2 * min(cdf, 1 - cdf)


@pytest.mark.parametrize("method", ["path", "bsdf+nee+zsobol:owen"])
def test_own_error_estimates_the_true_error(tmp_path, monkeypatch, method):
    """16 chunks of 8 spp: the F test assumes normal chunk means, and the furnace's
    roulette makes a 2-spp chunk mean skewed (most chunks of a pixel equal, a few far
    above: 0.2% of seeds rejected at ALPHA = 0.1%, and a key of this test's once gave
    p = 6e-6); with 8 spp per chunk 0.1% of 1000 seeds were rejected, the least p 8e-4.
    A sampler that continues one sequence over a cell's jobs (zsobol) takes a seed of its
    own per chunk: its chunks are independent scrambles, their spread its own error. The
    chunks' seeds derive from their keys, which hold the plugins' hash: pinned here, so that
    an edit of any plugin does not draw new seeds for this test (over 200 hashes zsobol's
    least p was 2.4e-3, 0 below ALPHA; one hash's draw gave 1.1e-4)."""
    monkeypatch.setattr(R.plan, "plugins_version", lambda: "test_references-pinned")
    store = R.ReferenceStore(str(tmp_path))
    s = spec(chunk=8, method=method)
    store.ensure(s, 128)
    ref = store.read(s)
    # mse_floor is the variance of the mean from the chunks' spread: hand-computed here
    chunks = np.stack([files.read_npz(store.store.path(f"{s.key}/chunk-{i:05d}"))["image"]
                       for i in range(ref.chunks)]).astype(np.float64)
    by_hand = np.mean(chunks.var(axis=0, ddof=1) / ref.chunks)
    assert ref.mse_floor == pytest.approx(by_hand, rel=1e-5)
    assert f_test(ref, 2.0) > ALPHA
    # negative control: a floor P times too small (the per-chunk spread divided by P^2)
    small = R.Reference(ref.image, ref.spp, ref.chunks, 0.0, method, "",
                        ref.mse_floor / ref.chunks, ref.relmse_floor / ref.chunks,
                        ref.relmse_floor_map / ref.chunks)
    assert f_test(small, 2.0) < ALPHA


def test_reference_meta_is_what_study_reference_returns(tmp_path):
    store = R.ReferenceStore(str(tmp_path))
    s = spec()
    store.ensure(s, 32)
    meta = store.read_jobs(store.plan(s, 32)).meta()
    assert {"seconds", "passes", "spp", "method", "mse_floor", "relmse_floor",
            "relmse_floor_map"} <= set(meta)
    assert meta["passes"] == 8 and meta["spp"] == 32 and meta["floor_known"]


def test_a_users_exr_has_no_known_error(tmp_path):
    image = np.full((4, 6, 3), 0.5)
    files.write_exr(str(tmp_path / "cbox.exr"), image)
    found = R.user_references(str(tmp_path))
    assert found == {"cbox": str(tmp_path / "cbox.exr")}
    ref = R.Reference.from_exr(found["cbox"])
    assert not ref.floor_known and "unknown" in ref.describe()
    assert ref.meta()["mse_floor"] == 0.0 and not ref.floor_map().any()
    with pytest.raises(ValueError, match="not a folder"):
        R.user_references(str(tmp_path / "nothing"))
    os.remove(found["cbox"])
    with pytest.raises(ValueError, match="holds no .exr"):
        R.user_references(str(tmp_path))


def test_a_reference_that_cannot_estimate_its_own_error_is_refused(tmp_path):
    with pytest.raises(ValueError, match="spread of its chunks"):
        spec(method="path+halton:none")     # every chunk the same image
    assert spec(method="path+halton").chunk == 4    # randomized: a scramble per chunk
    with pytest.raises(KeyError, match="chunks"):
        R.ReferenceStore(str(tmp_path)).read(spec())
    assert math.isfinite(spec().chunks_for(1)) and spec().chunks_for(1) == R.MIN_CHUNKS
