"""The suite's bias test: every cell's renders against its scene's reference chunks.

Per cell (scene x method), the method's repeats at both budgets are one side of
:mod:`experiments.lib.bias` (its two independent halves: the equal-spp repeats and the
equal-time repeats, combined by their samples), the reference's chunks the other (halves:
even and odd chunks). Both tests (per 8x8 block and channel, Welch's t with both sides'
variances; pooled over the image per channel) run at levels that make the whole run one
family at :data:`LEVEL` (Sidak over its cells; within a cell half the level to the blocks
and half to the pooled test, each Sidak over its comparisons).

Variance: the pixels' spread over the renders (``pixels``) where the pixels of a render are
independent (the ``independent`` sampler and a ``box`` filter); otherwise the spread of the
block means over the renders (``renders``: valid for any randomized sampler, few dof).
A cell whose blocks are heavy-tailed (in more than :data:`TAILS_SHARE` of them one pixel
of one render rules the variance estimate, :func:`.bias.tail_share`, or the renders' own
samples state it with few degrees of freedom, :func:`.bias_image.own_tail_share`: the
block tests' size is void) is tested by its image sum alone (:mod:`.bias_image`), its
variance from each render's own samples where they state it (the independent sampler's
pixels, ``vr_moments``). Untestable, with the reason: a deterministic sampler, a user's
EXR reference (no chunks), fewer than 2 renders per half (4 in all), renders of unequal
sample counts within a budget, or heavy tails that void the image test too.

:func:`check_reference` is the same test of a candidate reference's chunks against the
reference's (:mod:`.reference_choice`). The result is data (:class:`CellBias`); the words
are the report's (:mod:`.report`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ... import bias, bias_image, samplers, scenes

#: Family-wise level of one run's bias tests (every cell of every scene).
LEVEL = 0.99
#: A cell whose blocks' variances are ruled by rare large values in more than this share of
#: them (:func:`.bias.tail_share`, :func:`.bias_image.own_tail_share`) is tested by its
#: image sum alone (heavy tails).
TAILS_SHARE = 0.05
#: Fewest renders per half of a side.
MIN_PER_HALF = 2
#: Why a cell is untestable (keys of summary.json's ``biased_reason``).
REASONS = ("deterministic", "user_reference", "too_few_renders", "unequal_counts",
           "heavy_tails", "no_power", "calibration", "unreached_lobe")
#: Fewest passages through a narrow lobe's core that a cell's samples must be able to make
#: for its biased verdict to stand (:func:`unreached`).
REACH_MIN = 10.0


@dataclass(frozen=True)
class CellBias:
    """The bias test of one cell, as data."""
    status: str                     # biased | unbiased | untestable
    reason: str = ""                # untestable: one of REASONS
    variance: str = ""              # pixels | renders | moments (the image test's, from
                                    # the renders' own samples)
    detectable: float = float("nan")   # smallest uniform relative bias found ~90% of runs
    delta: tuple = ()               # pooled relative difference per channel
    p_blocks: float = float("nan")  # smallest per-block p
    p_pooled: float = float("nan")
    alpha_blocks: float = float("nan")
    alpha_pooled: float = float("nan")
    flagged: np.ndarray | None = None     # (blocks_y, blocks_x) bool
    flagged_blocks: int = 0
    tail_share: float = float("nan")
    block: int = bias.BLOCK
    #: what was tested: ``blocks`` (per block and pooled) or ``image`` (the image's sum
    #: alone, where the blocks' tails are heavy: :mod:`.bias_image`)
    scope: str = "blocks"
    term_share: float = float("nan")   # image scope: the largest term's share of its variance
    own_dof: float = float("nan")      # image scope, ``moments``: its variance's dof
    own_skew: float = float("nan")     # image scope, ``moments``: its sum's skewness
    extra: int = 0                  # renders beyond the cell's own (.bias_renders)
    #: a flag tested again on fresh renders alone (.bias_renders.confirmed): "" (not
    #: flagged), "confirmed", "not confirmed" or "void" (their tails void it), and their
    #: test's smallest p
    retest: str = ""
    retest_p: float = float("nan")

    @property
    def biased(self):
        """summary.json's value: True, False or "untestable"."""
        return "untestable" if self.status == "untestable" else self.status == "biased"

    def fields(self) -> dict:
        return {"biased": self.biased, "biased_reason": self.reason,
                "bias_variance": self.variance, "bias_detectable": self.detectable,
                "bias_delta": list(self.delta), "bias_p_blocks": self.p_blocks,
                "bias_p_pooled": self.p_pooled, "bias_alpha_blocks": self.alpha_blocks,
                "bias_alpha_pooled": self.alpha_pooled, "bias_flagged_blocks":
                    self.flagged_blocks, "bias_tail_share": self.tail_share,
                "bias_scope": self.scope, "bias_term_share": self.term_share,
                "bias_dof": self.own_dof, "bias_skew": self.own_skew,
                "bias_extra_renders": self.extra, "bias_retest": self.retest,
                "bias_retest_p": self.retest_p}


def cell_level(cells: int) -> float:
    """The per-cell level that makes ``cells`` cells one family at :data:`LEVEL`."""
    return bias.sidak(1.0 - LEVEL, max(1, cells))


def variance_kind(method, box: bool, trained: bool = True) -> str:
    """``pixels`` for the independent sampler under a box filter (each pixel an independent
    estimate), else ``renders``: a QMC sampler, a wider filter, or a method that learns
    from the render's own samples where its renders ``trained`` (its pixels share the
    learned guide; a job under the training thresholds is its plain counterpart's
    estimator, :meth:`.methods.Method.trains`)."""
    return "pixels" if box and method.sampler == samplers.DEFAULT and \
        not (method.learns and trained) else "renders"


def trained(method, budgets: list, pixels: int) -> bool:
    """Whether any render of ``budgets`` (lists of (image, spp, ...)) learned from its
    samples."""
    return any(method.trains(r[1], pixels) for b in budgets for r in b)


def reference_chunks(refs, spec) -> np.ndarray | None:
    """(chunks, H, W, C) images of every cached chunk of a reference (None: none)."""
    if spec is None:
        return None
    n = refs.cached(spec)
    jobs = refs.plan(spec, n * spec.chunk)[:n]
    return np.stack([np.asarray(refs.store.get(j.key).image, np.float64) for j in jobs]) \
        if jobs else None


def untestable(reason: str, variance: str = "") -> CellBias:
    return CellBias("untestable", reason, variance)


def check_cell(method, budgets: list, chunks: np.ndarray | None, box: bool, ref_box: bool,
               reference_method, alpha: float) -> CellBias:
    """The bias test of a cell: ``budgets`` its renders per budget (lists of (image, spp),
    or of (image, spp, variance, its variance, third cumulant): each render's per-pixel
    variance of its mean from its own samples' moments, how sure it is and the mean's
    third cumulant, which the image test reads where the pixels are independent),
    ``chunks`` the reference's chunk images (None: a user's EXR), ``alpha`` the cell's
    level (:func:`cell_level`)."""
    pixels = int(np.prod(budgets[0][0][0].shape[:2])) if budgets and budgets[0] else 0
    kind = variance_kind(method, box, trained(method, budgets, pixels))
    if method.deterministic:
        return untestable("deterministic", kind)
    if chunks is None:
        return untestable("user_reference", kind)
    if len(budgets) < 2 or min(len(b) for b in budgets) < MIN_PER_HALF \
            or len(chunks) < 2 * MIN_PER_HALF:
        return untestable("too_few_renders", kind)
    if any(len({r[1] for r in b}) > 1 for b in budgets):
        return untestable("unequal_counts", kind)
    halves = [bias.padded(np.stack([r[0] for r in b])) for b in budgets[:2]]
    samples = [len(b) * b[0][1] for b in budgets[:2]]
    ref = bias.padded(chunks)
    varying = bias.varying_pixels(bias.Renders(np.concatenate(halves)), bias.Renders(ref))
    side = bias.side_of_halves(halves, samples, varying, variance=kind)
    return _test(side, halves, samples, varying, kind, ref,
                 variance_kind(reference_method, ref_box), alpha, _own(budgets[:2], kind))


def _own(budgets: list, kind: str) -> list | None:
    """Per budget, its renders' own (variances, their variances, third cumulants) padded as
    the images, where every render states them and its pixels are independent
    (``pixels``); else None."""
    if kind != "pixels" or any(len(r) < 5 or any(x is None for x in r[2:5])
                               for b in budgets for r in b):
        return None
    return [tuple(bias.padded(np.stack([r[i] for r in b])) for i in (2, 3, 4))
            for b in budgets]


def check_reference(chunks: np.ndarray, against: np.ndarray, method, against_method,
                    box: bool, alpha: float) -> CellBias:
    """The bias test of a candidate reference: its ``chunks`` (independent randomizations
    of ``method``) against the chunks of the reference that every cell's bias test reads
    (``against``, of ``against_method``), halves its even and odd chunks, at level
    ``alpha``. The candidate stands in for that reference only where this passes."""
    kind = variance_kind(method, box)
    if method.deterministic:
        return untestable("deterministic", kind)
    if min(len(chunks), len(against)) < 2 * MIN_PER_HALF:
        return untestable("too_few_renders", kind)
    mine, ref = bias.padded(chunks), bias.padded(against)
    varying = bias.varying_pixels(bias.Renders(mine), bias.Renders(ref))
    side = bias.side_of_renders(mine, varying, variance=kind)
    even = np.arange(len(mine)) % 2 == 0
    return _test(side, [mine[even], mine[~even]], [even.sum(), (~even).sum()], varying,
                 kind, ref, variance_kind(against_method, box), alpha)


def _test(side, halves: list, samples: list, varying: np.ndarray, kind: str, ref: np.ndarray,
          ref_kind: str, alpha: float, own: list | None = None) -> CellBias:
    """Both tests of ``side`` (its renders in ``halves`` of ``samples`` per pixel in all,
    variance ``kind``) against the renders ``ref`` (variance ``ref_kind``) at level
    ``alpha``; where the blocks' tails are heavy, the image test in their place, its
    variance from the renders' ``own`` (:func:`_own`) where given."""
    blocks_y, blocks_x, channels = side.full.mean.shape
    tails = bias.tail_share(halves, varying)
    if own is not None:
        tails = max(tails, bias_image.own_tail_share(own, samples, varying))
    if tails <= TAILS_SHARE:
        other = bias.side_of_renders(ref, varying, variance=ref_kind)
        alpha_blocks = bias.sidak(alpha / 2, blocks_y * blocks_x * channels)
        alpha_pooled = bias.sidak(alpha / 2, channels)
        agreement = bias.compare(side, other, varying, alpha_blocks, alpha_pooled)
        return CellBias("unbiased" if agreement.passed else "biased", variance=kind,
                        detectable=float(agreement.detectable),
                        delta=tuple(float(x) for x in agreement.delta),
                        p_blocks=float(agreement.p_blocks.min()),
                        p_pooled=float(agreement.p_pooled.min()), alpha_blocks=alpha_blocks,
                        alpha_pooled=alpha_pooled, flagged=agreement.flagged,
                        flagged_blocks=int(agreement.flagged.sum()), tail_share=tails)
    image_kind = kind if own is None else "moments"
    image = bias_image.compare(
        bias_image.side_sums(halves, samples, varying, image_kind, own),
        bias_image.side_sums([ref], [1], varying, ref_kind), bias.sidak(alpha, channels))
    status = ("unbiased" if image.passed else "biased") if image.testable else "untestable"
    reason = "" if image.testable else "heavy_tails" if not image.size_holds else "no_power"
    return CellBias(status, reason, variance=image_kind,
                    detectable=float(image.detectable),
                    delta=tuple(float(x) for x in image.delta), p_pooled=float(image.p.min()),
                    alpha_pooled=image.alpha, flagged=np.zeros((blocks_y, blocks_x), bool),
                    tail_share=tails, scope="image", term_share=image.top,
                    own_dof=image.own_dof if math.isfinite(image.own_dof) else math.nan,
                    own_skew=image.own_skew if image_kind == "moments" else math.nan)


def calibrated(cells: dict, reference_method: str) -> dict:
    """``cells`` ({method name: CellBias} of one scene) with the test's own calibration
    applied: where the method that renders the reference is among them and its own test
    does not pass (its renders disagree with its own reference, or their tails void the
    test), the reference or the test's variances are not to be trusted on this scene, and
    every ``biased`` verdict there becomes untestable (``calibration``), its numbers kept."""
    own = cells.get(reference_method)
    if own is None or own.status == "unbiased":
        return cells
    return {name: dataclasses.replace(c, status="untestable", reason="calibration")
            if c.status == "biased" else c for name, c in cells.items()}


def unreached(cells: dict, samples: dict, reach) -> dict:
    """``cells`` ({method name: CellBias} of one scene) where a ``biased`` verdict stands
    only if the method's samples could have reached the light of the scene's narrowest
    lobe: ``samples[name]`` (the cell's samples in all, both budgets) times ``reach(name)``
    (the share of its paths that can pass through that lobe's core at most,
    :func:`experiments.lib.scene_probes.path_reach`, asked for biased cells alone) at least
    :data:`REACH_MIN`. Below it a correct estimator misses that light in almost every
    render, and its samples, whose moments then pass every heavy-tail gate, cannot tell
    that from a bias (uniform+nee on Mitsuba's test_roughdielectric_path, Beckmann 0.02:
    -53.6% +- 2.4 at 1024 spp x 8 renders, -11% +- 564 at 16384 x 4): the verdict becomes
    untestable (``unreached_lobe``), its numbers kept."""
    return {name: dataclasses.replace(c, status="untestable", reason="unreached_lobe")
            if c.status == "biased" and samples[name] * reach(name) < REACH_MIN else c
            for name, c in cells.items()}


def flag_overlay(image: np.ndarray, flagged: np.ndarray, block: int = bias.BLOCK) -> np.ndarray:
    """The image (H, W, 3) with its flagged blocks tinted red (the viewer's bias map)."""
    h, w = image.shape[:2]
    mask = np.kron(flagged, np.ones((block, block)))[:h, :w].astype(bool)
    out = np.array(image, dtype=np.float64)
    level = float(np.mean(out)) or 1.0
    out[mask] = 0.5 * out[mask] + 0.5 * np.array([2.0 * level, 0.0, 0.0])
    return out
