"""The scene suite's analysis: pure functions of numbers (tested on synthetic ones).

Input per scene (:class:`SceneNumbers`): per method (:class:`Cell`) the per-repeat errors
against the reference at equal spp and at equal time (:class:`Runs`: relMSE, relMSE with
the top 0.1% of pixel errors rejected, MSE, FLIP, raw: the reference's own expected error,
:class:`Floor`, is subtracted here by :func:`stats.excess_interval`), the time of each
render's samples and the image means (the bias check); the scene's header (hypothesis,
exact value). Output per scene (:class:`SceneResult`): every estimate with its interval,
the efficiency over the baseline at both budgets (:class:`.ratios.Ratio`: an interval, or a bound
where an error is below the reference's noise), the winner or the methods that cannot be
told apart, the hypothesis' verdict, vr_path's time per sample over path's and the bias
check, all as data: the words are the report's (:mod:`.report`).

Where both cells' pixels are independent estimates (independent sampler, box filter) their
relMSE is the expected one from the pixels' pass variances and their efficiency's interval
pairs their renders' costs (:mod:`.errors`); elsewhere both come from the repeats.
Verdicts use relMSE at equal time; a method wins only where the interval of its
efficiency over every other method excludes 1.
"""
from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field, replace

import numpy as np

from ... import stats
from ...methods import parse_method
from . import errors, ratios

g = stats.g
#: The budgets every cell is measured at; the first is the one verdicts use.
BUDGETS = ("equal_time", "equal_spp")
BUDGET_NAMES = {"equal_time": "equal time", "equal_spp": "equal spp"}
#: Family-wise level of a scene's bias check (Sidak over its methods): 99%, not 95%. The
#: check runs on every make run; at 95% one run in twenty flagged an unbiased method (a
#: default run put uniform+nee on the furnace at 1.9939 against 2, z = -2.9, where 24
#: fresh renders of 64 spp gave 1.99949 +- 0.00037), and a false "biased" is the verdict
#: that must not be wrong. A 4% bias still lies far outside (tests/test_suite.py).
BIAS_LEVEL = 0.99
#: The reference is too noisy for a comparison where its own expected relMSE exceeds this
#: share of the smallest expected relMSE measured against it.
FLOOR_SHARE = 0.1
#: The vr_path method whose time per sample is compared with path's on every scene.
TIMED_PAIR = ("bsdf+nee", "path")
#: The methods whose adaptive sampling ceiling a scene gives (``errors.oracle_gain``): the
#: first it renders (the guiding scenes render no ``bsdf+nee``).
CEILING_METHODS = (TIMED_PAIR[0], "guided+nee")


# ------------------------------------------------------------------ input

@dataclass(frozen=True)
class Runs:
    """One cell at one budget, per repeat: raw errors against the reference (its own
    expected error not subtracted), the seconds of each render's samples (spp x time per
    sample: the time compared), image means and their variances (the pixels' spread)."""
    spp: int
    relmse: tuple
    relmse_rejected: tuple
    mse: tuple
    seconds: tuple
    flip: tuple = ()          # per repeat, or the first repeat's only, or none
    means: tuple = ()
    mean_vars: tuple = ()
    expected: tuple = ()      # (expected relMSE from the pixels' pass variances, the
    #                           variance of that estimate): errors; () without passes
    costs: tuple = ()         # per budget (equal spp, equal time): (its spp, each repeat's
    #                           cost per sample)
    each: tuple = ()          # per repeat, its own expected relMSE (its pixels' variances)
    top: float = 0.0          # the largest share of ``expected`` one pixel of one render
    #                           holds (:func:`.errors.top_share`)
    rest: tuple = ()          # ``expected`` without that term (:func:`.errors.without_top`)
    jitter: tuple = ()        # per budget of ``costs``: the scene's pooled paired cost
    #                           jitter, (variance, dof) (:func:`.errors.cost_jitter`)


@dataclass(frozen=True)
class Cell:
    method: str
    runs: dict                # {budget: Runs}
    ns_per_sample: tuple      # per repeat
    overhead: float = 0.0     # fitted seconds per render call
    deterministic: bool = False
    block_bias: object = None     # the bias test against the reference (bias_test.CellBias)
    learns: bool = False      # a method that learns: its costs vary with what it learned
    trained: bool = True      # its equal-time renders learned (Method.trains at their count:
    #                           under a guide's thresholds it is its plain counterpart)


@dataclass(frozen=True)
class Floor:
    """The reference's own expected errors (0 where unknown: a user's EXR)."""
    relmse: float
    relmse_rejected: float
    mse: float
    known: bool = True


@dataclass(frozen=True)
class SceneNumbers:
    name: str
    cells: dict               # {method: Cell}
    floor: Floor
    baseline: str
    favours: tuple = ()       # header patterns (none: no hypothesis)
    over: tuple = ()
    hypothesis: str = ""
    exact: float | None = None
    failed: dict = field(default_factory=dict)    # {method: error}
    calibration: str = ""     # the method that renders the reference (its bias test is
    #                           the test's own negative control)
    oracle_gain: float = math.nan   # errors.oracle_gain of oracle_method's equal-time renders
    oracle_method: str = ""         # the first of CEILING_METHODS the scene renders


# ------------------------------------------------------------------ the winner

@dataclass(frozen=True)
class Ranking:
    order: tuple              # methods, best first (by the ratio's score over the baseline)
    winner: str | None        # the best, where its interval excludes every other method
    ties: tuple               # the best and the methods it cannot be told from

    def best(self) -> tuple:
        return (self.winner,) if self.winner else self.ties


def rank(relative: dict, compare) -> Ranking:
    """``relative``: {method: Ratio over the baseline}; ``compare(a, b)``: the Ratio of a
    over b. The best (highest score) wins only where it beats every other method at the
    interval's level; otherwise the methods it cannot be told from tie with it."""
    order = tuple(sorted(relative, key=lambda m: relative[m].score(), reverse=True))
    if not order:
        return Ranking((), None, ())
    best = order[0]
    ties = (best,) + tuple(m for m in order[1:] if not compare(best, m).greater())
    return Ranking(order, best if len(ties) == 1 else None, ties)


# ------------------------------------------------------------------ the hypothesis

@dataclass(frozen=True)
class Verdict:
    """The hypothesis' verdict as data (the report says it in words)."""
    status: str               # held | failed | undecided | untestable | none
    favoured: str | None = None     # the best favoured method
    against: tuple = ()       # failed: the method that beats it; undecided: those it cannot
    #                           be told from; held: the one it beats by the least
    ratio: ratios.Ratio | None = None   # failed, held: favoured over against[0]
    missing: str = ""         # untestable: the patterns ("favours" or "over") ...
    patterns: tuple = ()      # ... that match no method run


def matching(patterns, methods) -> list[str]:
    return [m for m in methods if any(fnmatch.fnmatchcase(m, p) for p in patterns)]


def hypothesis(favours, over, relative: dict, compare) -> Verdict:
    """Does the best method matching ``favours`` beat every method matching ``over``
    (methods of both lists count as favoured)? held: it beats each at the interval's
    level; failed: one of them beats it; undecided: neither (the budget cannot tell)."""
    if not favours:
        return Verdict("none")
    fav = matching(favours, relative)
    opp = [m for m in matching(over, relative) if m not in fav]
    if not fav or not opp:
        return Verdict("untestable", missing="favours" if not fav else "over",
                       patterns=tuple(favours if not fav else over))
    top = max(fav, key=lambda m: relative[m].score())
    ratios = {o: compare(top, o) for o in opp}
    winners = [o for o, r in ratios.items() if r.less()]
    if winners:
        return Verdict("failed", top, (winners[0],), ratios[winners[0]])
    unclear = [o for o, r in ratios.items() if not r.greater()]
    if unclear:
        return Verdict("undecided", top, tuple(unclear))
    weakest = min(ratios, key=lambda o: ratios[o].score())
    return Verdict("held", top, (weakest,), ratios[weakest])


# ------------------------------------------------------------------ bias

@dataclass(frozen=True)
class Bias:
    mean: float
    lo: float
    hi: float
    exact: float
    level: float
    checked: bool = True      # False: a deterministic method (pixel errors not independent)

    @property
    def inside(self) -> bool:
        return self.lo <= self.exact <= self.hi

    def text(self) -> str:
        if not self.checked:
            return f"{self.mean:.5g} (deterministic: no interval from the pixels' spread)"
        return f"{self.mean:.5g} ({self.level:.2%} CI {self.lo:.5g}-{self.hi:.5g})"


def bias(cell: Cell, exact: float, level: float) -> Bias:
    """The mean of every render of ``cell`` (weighted by spp) with its ``level`` interval
    from the pixels' spread (pixels are independent estimates where the scene has one
    value everywhere), against ``exact``."""
    from scipy.stats import norm
    runs = [r for r in cell.runs.values() if r.means]
    w = np.array([r.spp for r in runs for _ in r.means], float)
    m = np.array([x for r in runs for x in r.means], float)
    v = np.array([x for r in runs for x in r.mean_vars], float)
    mean = float(np.sum(w * m) / np.sum(w))
    se = float(math.sqrt(np.sum(w * w * v)) / np.sum(w))
    z = float(norm.ppf(0.5 + level / 2))
    return Bias(mean, mean - z * se, mean + z * se, exact, level, not cell.deterministic)


# ------------------------------------------------------------------ one scene

@dataclass(frozen=True)
class CellResult:
    method: str
    errors: dict              # {budget: {metric: Estimate}}
    relative: dict            # {budget: Ratio over the baseline}
    ns_per_sample: stats.Estimate
    spp: dict                 # {budget: spp rendered}
    bias: Bias | None = None
    overhead: float = 0.0     # seconds per render call besides the samples
    block_bias: object = None     # bias_test.CellBias, or None where not tested

    @property
    def biased(self) -> bool:
        """Flagged by the bias test (never a winner nor tied for best)."""
        return self.block_bias is not None and self.block_bias.status == "biased"


@dataclass(frozen=True)
class SceneResult:
    name: str
    baseline: str
    cells: dict               # {method: CellResult}
    ranking: Ranking
    verdict: Verdict
    time_ratio: stats.Estimate | None     # TIMED_PAIR[0] / TIMED_PAIR[1] per sample
    floor_share: float        # the reference's own relMSE over the smallest measured
    floor_known: bool
    failed: dict
    power: float | None = None    # smallest bias detected ~90%: the calibration cell's
    power_method: str = ""        # the calibration method (or the cell with the best power)
    calibration: str = ""         # the reference's own method
    #: {learning method: (Ratio of its equal-time efficiency over its counterpart without
    #: learning (Method.plain), whether the scene's header favours it, whether its
    #: equal-time renders trained)}
    learned: dict = field(default_factory=dict)
    oracle_gain: float = math.nan   # the adaptive sampling ceiling (SceneNumbers')
    #: {adaptive method: Ratio of its equal-time efficiency over its twin that samples
    #: every pixel alike (Method.unadapted)}
    adapted: dict = field(default_factory=dict)
    oracle_method: str = ""       # whose renders the ceiling reads (SceneNumbers')

    @property
    def reference_adequate(self) -> bool:
        return not self.floor_known or self.floor_share <= FLOOR_SHARE

    def bounds(self) -> list[str]:
        """Methods whose equal-time relMSE is below the reference's noise."""
        return [m for m, c in self.cells.items() if c.errors["equal_time"]["relmse"].bound]


METRICS = ("relmse", "relmse_rejected", "mse", "flip")


def _errors(runs: Runs, floor: Floor) -> dict:
    out = {k: stats.excess_interval(getattr(runs, k), getattr(floor, k))
           for k in ("relmse", "relmse_rejected", "mse")}
    if runs.expected:         # the pixels' variances: no floor, thousands of terms
        out["relmse"] = errors.estimate(*runs.expected, len(runs.each) or len(runs.relmse))
    out["flip"] = (stats.mean_interval(runs.flip) if runs.flip and min(runs.flip) > 0
                   else stats.Estimate(math.nan, math.nan, math.nan, len(runs.flip)))
    return out


def floor_share(numbers: SceneNumbers) -> float:
    """The reference's own expected relMSE over the smallest expected relMSE measured
    against it (raw, at either budget)."""
    raw = [float(np.mean(r.relmse)) for c in numbers.cells.values() for r in c.runs.values()]
    smallest = min((x for x in raw if x > 0), default=math.inf)
    return numbers.floor.relmse / smallest if math.isfinite(smallest) else 0.0


def with_jitter(cells: dict, base: str) -> dict:
    """``cells`` whose every Runs carries the scene's pooled paired cost jitter
    (:func:`.errors.cost_jitter` over the renders of every cell that does not learn against
    the baseline's: a learning method's cost per repeat varies with what that repeat
    learned, which is its own variance, not the machine's)."""
    if base not in cells:
        return cells
    jitter = errors.cost_jitter([c.runs[BUDGETS[0]] for c in cells.values() if not c.learns],
                                cells[base].runs[BUDGETS[0]])
    return {m: replace(c, runs={b: replace(r, jitter=jitter) for b, r in c.runs.items()})
            for m, c in cells.items()}


def analyse_scene(numbers: SceneNumbers) -> SceneResult:
    floor, base = numbers.floor, numbers.baseline
    cells = with_jitter(numbers.cells, base)

    def compare(a: str, b: str, budget: str = BUDGETS[0]) -> ratios.Ratio:
        return ratios.efficiency(cells[a].runs[budget], cells[b].runs[budget], floor.relmse)

    relative = {b: {m: compare(m, base, b) for m in cells} for b in BUDGETS}
    flagged = {m for m, c in cells.items()
               if c.block_bias is not None and c.block_bias.status == "biased"}
    ranking = rank({m: r for m, r in relative[BUDGETS[0]].items() if m not in flagged},
                   compare)
    verdict = hypothesis(numbers.favours, numbers.over, relative[BUDGETS[0]], compare)
    level = BIAS_LEVEL ** (1 / max(1, len(cells)))
    results = {m: CellResult(
        m, {b: _errors(c.runs[b], floor) for b in BUDGETS}, {b: relative[b][m] for b in BUDGETS},
        stats.mean_interval(c.ns_per_sample), {b: c.runs[b].spp for b in BUDGETS},
        bias(c, numbers.exact, level) if numbers.exact is not None else None, c.overhead,
        c.block_bias) for m, c in cells.items()}
    a, b = TIMED_PAIR
    time_ratio = (stats.ratio_interval([list(cells[a].ns_per_sample)],
                                       [list(cells[b].ns_per_sample)])
                  if a in cells and b in cells else None)
    share = floor_share(numbers)
    power, power_method = scene_power(cells, numbers.calibration)
    favoured = set(matching(numbers.favours, list(cells)))
    learned = {m: (compare(m, plain), m in favoured, cells[m].trained) for m in cells
               if (plain := _twin(m, "plain")) in cells}
    adapted = {m: compare(m, twin) for m in cells if (twin := _twin(m, "unadapted")) in cells}
    return SceneResult(numbers.name, base, results, ranking, verdict, time_ratio, share,
                       floor.known, dict(numbers.failed), power, power_method,
                       numbers.calibration, learned, numbers.oracle_gain, adapted,
                       numbers.oracle_method)


def _twin(name: str, kind: str) -> str | None:
    """A cell's method's counterpart without learning (``kind`` "plain",
    :attr:`.Method.plain`) or without adaptive sampling ("unadapted",
    :attr:`.Method.unadapted`); None for a label outside the method grammar (an analysis
    fed other cells' names)."""
    try:
        return getattr(parse_method(name), kind)
    except ValueError:
        return None


def learned_over_plain(results: list[SceneResult]) -> dict:
    """{learning method: ([(scene, Ratio over its plain counterpart)] on the scenes whose
    header does not favour it, the geometric mean of those that are intervals, how many,
    the scenes of those rows where its equal-time renders did not train)}: what learning
    costs where it should not help (issue 31's "other bundled scenes"). Where it did not
    train it is its plain counterpart's estimator, so that ratio is the two cells' noise."""
    out = {}
    for r in results:
        for m, (ratio, favoured, trained) in r.learned.items():
            if not favoured:
                out.setdefault(m, []).append((r.name, ratio, trained))
    return {m: ([(s, x) for s, x, _ in rows], *geometric_mean([x for _, x, _ in rows]),
                [s for s, _, trained in rows if not trained]) for m, rows in out.items()}


def adapted_over_plain(results: list[SceneResult]) -> dict:
    """{adaptive method: ([(scene, Ratio over its twin that samples every pixel alike)],
    the geometric mean of those that are intervals, how many)}: what adaptive sampling
    gains, or costs, on every scene that renders both."""
    out = {}
    for r in results:
        for m, ratio in r.adapted.items():
            out.setdefault(m, []).append((r.name, ratio))
    return {m: (rows, *geometric_mean([x for _, x in rows])) for m, rows in out.items()}


def geometric_mean(ratios: list) -> tuple[float, int]:
    """(the geometric mean of the ``ratios`` (:class:`.ratios.Ratio`) that are intervals,
    not bounds, and positive; how many; nan and 0 where none is)."""
    logs = [math.log(x.value) for x in ratios if x.side == "" and x.value > 0]
    return (math.exp(sum(logs) / len(logs)) if logs else math.nan), len(logs)


def scene_power(cells: dict, calibration: str) -> tuple:
    """(smallest uniform relative bias the scene's bias test detects ~90% of the time, the
    cell it is measured on): the calibration cell's (the reference's own method, a negative
    control whose variance is the test's), else the best of the tested cells'."""
    tested = {m: c.block_bias.detectable for m, c in cells.items()
              if c.block_bias is not None and math.isfinite(c.block_bias.detectable)}
    if calibration in tested:
        return tested[calibration], calibration
    if tested:
        best = min(tested, key=tested.get)
        return tested[best], best
    return None, ""


def geometric_means(results: list[SceneResult]) -> dict:
    """{method: (geometric mean of its equal-time efficiency over the baseline across the
    scenes where it is an interval, not a bound; how many scenes)}."""
    gm = {}
    for m in dict.fromkeys(m for r in results for m in r.cells):
        mean, n = geometric_mean([r.cells[m].relative["equal_time"] for r in results
                                  if m in r.cells])
        if n:
            gm[m] = (mean, n)
    return gm


# ------------------------------------------------------------------ crops

def _window_means(image: np.ndarray, size: int) -> np.ndarray:
    """Mean of every ``size`` x ``size`` window of a 2-D array (summed-area table)."""
    s = np.pad(np.cumsum(np.cumsum(image, 0), 1), ((1, 0), (1, 0)))
    return (s[size:, size:] - s[:-size, size:] - s[size:, :-size] + s[:-size, :-size]) \
        / (size * size)


def crop_boxes(maps: list[np.ndarray], size: int) -> list[tuple[int, int, int, int]]:
    """Two ``size`` x ``size`` crops ((x, y, w, h)) of per-method error maps (H, W): first
    where the errors are largest (their mean over the methods), then, not overlapping it,
    where the methods differ most (the spread of their log window means, each floored at
    1% of the mean window error, so that windows every method renders almost exactly do
    not count)."""
    h, w = maps[0].shape
    size = max(1, min(size, h, w))
    windows = np.stack([_window_means(np.asarray(m, float), size) for m in maps])
    level = windows.mean(axis=0)
    y0, x0 = np.unravel_index(int(np.argmax(level)), level.shape)
    floor = 0.01 * float(level.mean()) + 1e-30
    spread = np.log10(np.maximum(windows, floor)).std(axis=0)
    ys, xs = np.indices(spread.shape)
    apart = (np.abs(ys - y0) >= size) | (np.abs(xs - x0) >= size)
    if apart.any():
        spread = np.where(apart, spread, -np.inf)
    y1, x1 = np.unravel_index(int(np.argmax(spread)), spread.shape)
    return [(int(x0), int(y0), size, size), (int(x1), int(y1), size, size)]
