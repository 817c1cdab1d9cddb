"""A user's own sampler enters the sampler study and the lab's point sets with no other edit.

One file, written here to a temporary directory and loaded with ``--plugin FILE``, defines
a deliberately plain Python sampler (independent uniform numbers from a hash of the seed,
the lane and the dimension), registers it with Mitsuba (``mi.register_sampler``) and with
the sampler table (``register_sampler(SamplerSpec(...))``). The documented commands, run
from outside in their own processes at tiny settings, must then:

- render it in the sampler study (its jobs in the store, its row in the table) and compare
  it, as a bundled sampler family, with the best native sampler in the conclusion table;
- draw its points in the lab, where a plain random sampler stratifies nothing: every pair
  is "lost" (discrepancy at least half that of independent points), while Mitsuba's
  stratified sampler in the same table keeps (0,1) stratified (the negative control).
"""
import csv
import json
import os
import subprocess
import sys
import textwrap

from _paths import ROOT

PLUGIN = textwrap.dedent('''
    """A deliberately plain sampler: independent numbers, hashed from (seed, lane, dimension)."""
    import drjit as dr
    import mitsuba as mi

    from experiments.lib.samplers import SamplerSpec, register_sampler


    class PlainSampler(mi.Sampler):
        def __init__(self, props):
            mi.Sampler.__init__(self, props)
            self._reset(mi.UInt32(0), 1)

        def _reset(self, seed, size):
            self._lane = dr.arange(mi.UInt32, size)
            self._seed = mi.UInt32(seed)
            self._dimension = dr.zeros(mi.UInt32, size)

        def seed(self, seed, wavefront_size=0xFFFFFFFF):
            mi.Sampler.seed(self, seed, wavefront_size)
            seed = dr.opaque(mi.UInt32, seed & 0xFFFFFFFF) if isinstance(seed, int) else \\
                mi.UInt32(seed)
            self._reset(seed, self.wavefront_size())

        def next_1d(self, active=True):
            value = mi.sample_tea_float32(self._lane, self._seed * 0x9E3779B9 + self._dimension,
                                          8)
            self._dimension += 1
            return value

        def next_2d(self, active=True):
            return mi.Point2f(self.next_1d(active), self.next_1d(active))

        def schedule_state(self):
            dr.schedule(self._lane, self._seed, self._dimension)

        def fork(self):
            props = mi.Properties("plain")
            props["sample_count"] = self.sample_count()
            return PlainSampler(props)

        def clone(self):
            other = self.fork()
            if self.wavefront_size() > 1:
                mi.Sampler.seed(other, 0, self.wavefront_size())
            other._lane = mi.UInt32(self._lane)
            other._seed = mi.UInt32(self._seed)
            other._dimension = mi.UInt32(self._dimension)
            return other


    mi.register_sampler("plain", PlainSampler)
    register_sampler(SamplerSpec("plain", description="a deliberately plain sampler"))
''')


def run(module, *argv):
    proc = subprocess.run([sys.executable, "-m", f"experiments.{module}", *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_a_plugin_sampler_enters_the_sampler_study_and_the_lab(tmp_path):
    plugin = tmp_path / "plain_sampler.py"
    plugin.write_text(PLUGIN)
    out = tmp_path / "study"
    run("samplers", "--plugin", str(plugin), "--out", str(out), "--resolution", "8x4",
        "--spp", "4", "--depths", "2", "--repeats", "2", "--reference-spp", "16",
        "--screen-resolution", "8x8", "--screen-counts", "4", "--screen-repeats", "2",
        "--screen-reference-spp", "16")
    table = rows(out / "samplers" / "samplers.csv")
    assert {r["sampler"] for r in table} >= {"independent", "stratified", "halton:owen",
                                             "plain"}
    mine = next(r for r in table if r["sampler"] == "plain")
    assert mine["spp rendered"] == "4" and mine["repeats"] == "2"
    stored = [os.path.relpath(os.path.join(d, f), out) for d, _, names in
              os.walk(out / "store") for f in names if f.endswith(".npz")]
    assert sum("/depth2/plain/" in p for p in stored) == 2 * 2        # 2 counts x 2 repeats
    conclusion = rows(out / "samplers" / "conclusion_depth2.csv")
    bundled = [r for r in conclusion if r["comparison"] == "bundled best / best native"]
    assert any(r["A / B"].startswith("plain / ") for r in bundled), bundled
    assert any(r["A / B"].startswith("halton:") for r in bundled), bundled
    natives = {r["A / B"].split(" / ")[1] for r in bundled}
    assert len(natives) == 1 and natives <= {"independent", "stratified", "multijitter",
                                             "orthogonal", "ldsampler"}
    summary = json.loads((out / "samplers" / "summary.json").read_text())
    assert any(r["sampler"] == "plain" for r in summary["rows"])
    # the screen-space pass takes it by default (it is not native), beside the others
    screen = rows(out / "samplers" / "screen_space.csv")
    assert {r["sampler"] for r in screen} == {"independent", "multijitter", "ldsampler",
                                              "halton:owen", "zsobol:owen", "plain"}
    assert any(r["A / B"].startswith("plain / ")
               for r in rows(out / "samplers" / "screen_conclusion_depth2.csv"))

    lab_out = tmp_path / "lab"
    run("lab", "--quick", "--plugin", str(plugin), "--out", str(lab_out))
    points = rows(lab_out / "lab" / "points_conclusion.csv")
    plain = next(r for r in points if r["sampler"] == "plain")
    assert plain["kind"] == "bundled"
    assert plain["stratified jointly (2-D)"] == "-" and plain["only per coordinate (1-D)"] == "-"
    assert plain["lost"] == "(0,1) (2,3) (10,11) (30,31) (1,2)"
    stratified = next(r for r in points if r["sampler"] == "stratified")   # negative control
    assert stratified["kind"] == "native" and "(0,1)" in stratified["stratified jointly (2-D)"]
    discrepancy = rows(lab_out / "lab" / "discrepancy.csv")
    assert {r["pair"] for r in discrepancy if r["sampler"] == "plain"} == {
        "(0,1)", "(2,3)", "(10,11)", "(30,31)", "(1,2)"}
    assert "plain" in (lab_out / "lab" / "summary.md").read_text()
    # conclusions a reader can scan: no paragraph of either section over 80 words
    for section in (out / "samplers" / "section.json", lab_out / "lab" / "section.json"):
        blocks = json.loads(section.read_text())["blocks"]
        paragraphs = [p for b in blocks if b["kind"] == "text" for p in b["text"].split("\n\n")]
        assert paragraphs and max(len(p.split()) for p in paragraphs) <= 80, section
