"""The method grammar: a name parsed once into a :class:`Method` value that jobs carry.

Method names (every part read from its registry)::

    STRATEGY[+nee][+SAMPLER[:RANDOMIZATION]][+adaptive]   vr_path, e.g. bsdf+nee+orthogonal
    path[+SAMPLER[:RANDOMIZATION]][+adaptive]             Mitsuba's C++ path (NEE + MIS)

STRATEGY is any registered ``vr_path`` strategy (:func:`integrators.strategies.names`:
uniform, cosine, bsdf, mis and any a user registers), ``+nee`` turns on emitter sampling
(next-event estimation + MIS), SAMPLER any registered sampler (:mod:`.samplers`; default
``independent``) and RANDOMIZATION one of that sampler's randomizations. One name is fixed
by the writeup: ``uniform+halton`` is its plain (unrandomized) Halton, i.e.
``uniform+halton:none``; any other sampler without a randomization uses the sampler's
default. ``+adaptive`` nests the integrator in ``vr_adaptive`` (a pilot, then the samples
where the relative error is: :mod:`integrators.adaptive`): with the independent sampler
only, and not for a strategy that learns between passes.

A :class:`Method` is plain frozen data (picklable, hashable): jobs carry it, and its
``name`` is what the job keys hash, so keys do not depend on how a method is represented.
Its meaning for a render is :meth:`Method.integrator_dict` and :meth:`Method.sampler_dict`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from integrators import guide_passes
from integrators import strategies as _strategies

from . import samplers

#: Mitsuba's C++ path tracer as a method (NEE + MIS): ``path[+SAMPLER]``.
PATH = "path"
#: The writeup's methods (no NEE), then what a user would run instead.
DEFAULT_METHODS = ("uniform", "cosine", "bsdf", "uniform+halton", "bsdf+halton", "bsdf+nee",
                   "path")
#: Names whose meaning is fixed by the writeup rather than parsed: the writeup's plain
#: (unrandomized) Halton.
FIXED = {"uniform+halton": "uniform+halton:none"}


#: Words of the grammar that no strategy may be called (a strategy ``nee`` would make
#: ``bsdf+nee`` ambiguous).
ADAPTIVE = "adaptive"
RESERVED = (PATH, "nee", ADAPTIVE)


def strategies() -> tuple[str, ...]:
    """The registered ``vr_path`` strategies (built-in ones first); ValueError if one is
    named like a word of the grammar or like a sampler."""
    names = tuple(_strategies.names())
    clash = [n for n in names if n in RESERVED or n in samplers.names()]
    if clash:
        raise ValueError(f"strategy name '{clash[0]}' clashes with the method grammar "
                         f"({', '.join(RESERVED)} and the samplers {', '.join(samplers.names())} "
                         f"are taken): register it under another name")
    return names


@dataclass(frozen=True)
class Depth:
    """Path-length settings of a render (None: the integrator's own default)."""
    max_depth: int | None = None
    rr_depth: int | None = None
    hide_emitters: bool | None = None

    def describe(self) -> str:
        return ", ".join(f"{k} {'plugin default' if v is None else v}"
                         for k, v in dataclasses.asdict(self).items())


@dataclass(frozen=True)
class Method:
    """One compared method: integrator (``vr_path`` strategy or ``path``), NEE, sampler."""
    name: str
    strategy: str | None            # None for Mitsuba's path
    nee: bool = False
    sampler: str = samplers.DEFAULT
    randomization: str | None = None   # None: the sampler's default
    adaptive: bool = False             # nested in vr_adaptive (+adaptive)

    def __str__(self) -> str:
        return self.name

    @property
    def integrator(self) -> str:
        return PATH if self.strategy is None else _strategies.integrator_type(self.strategy)

    @property
    def learns(self) -> bool:
        """Its strategy learns from the render's own samples between passes (its integrator
        is not ``vr_path``, e.g. ``guided``): its pixels share what was learned, so they are
        not independent estimates."""
        return self.strategy is not None and self.integrator != "vr_path"

    def trains(self, spp: int, pixels: int) -> bool:
        """Whether a job of ``spp`` samples per pixel on ``pixels`` pixels learns from its
        own samples: never for a method that does not learn; for ``vr_guided_path`` only at
        its default training thresholds or above (below them it is its plain counterpart's
        estimator, :func:`integrators.guide_passes.trains`); always for another learning
        integrator, which states no thresholds."""
        if not self.learns:
            return False
        if self.integrator == "vr_guided_path":
            return guide_passes.trains(spp, pixels)
        return True

    @property
    def plain(self) -> str | None:
        """A learning method's counterpart without the learning: the same name with the
        BSDF's own sampling (``bsdf``) in place of its strategy (``guided+nee`` ->
        ``bsdf+nee``); None for a method that does not learn."""
        return "bsdf" + self.name[len(self.strategy):] if self.learns else None

    @property
    def unadapted(self) -> str | None:
        """An adaptive method's twin that spends its samples alike in every pixel: the
        same name without ``+adaptive`` (``bsdf+nee+adaptive`` -> ``bsdf+nee``); None for
        a method that is not adaptive."""
        return self.name[:-len(ADAPTIVE) - 1] if self.adaptive else None

    @property
    def sampler_spec(self) -> samplers.SamplerSpec:
        return samplers.get(self.sampler)

    @property
    def sampler_label(self) -> str:
        """``sampler[:randomization]``, as the sampler study names it."""
        return self.sampler + (f":{self.randomization}" if self.randomization else "")

    @property
    def continues_sequence(self) -> bool:
        """Successive jobs continue one sequence (seed kept, sample offset advanced)."""
        return self.sampler_spec.continues_sequence

    @property
    def deterministic(self) -> bool:
        """The same image in every run (e.g. plain Halton): one repeat stands for all."""
        return self.sampler_spec.is_deterministic(self.randomization)

    def settings(self) -> dict:
        return dataclasses.asdict(self)

    def integrator_dict(self, depth: Depth = Depth()) -> dict:
        """The integrator plugin dict (settings of ``depth`` left None keep its defaults)."""
        d = ({"type": PATH} if self.strategy is None else
             {"type": self.integrator, "strategy": self.strategy, "emitter_sampling": self.nee})
        d.update({k: v for k, v in dataclasses.asdict(depth).items() if v is not None})
        return {"type": "vr_adaptive", "nested": d} if self.adaptive else d

    def sampler_dict(self, spp: int = 1, width: int = 0, height: int = 0) -> dict:
        return self.sampler_spec.dict(spp, self.randomization, width, height)


def grammar() -> str:
    """The valid parts, for error messages and --help."""
    rand = [f"{n}: {'|'.join(samplers.get(n).randomizations)}" for n in samplers.names()
            if samplers.get(n).randomizations]
    return (f"STRATEGY[+nee][+SAMPLER[:RANDOMIZATION]][+{ADAPTIVE}] or "
            f"path[+SAMPLER[:RANDOMIZATION]][+{ADAPTIVE}]; "
            f"STRATEGY {'|'.join(strategies())}, SAMPLER {'|'.join(samplers.names())}, "
            f"RANDOMIZATION ({'; '.join(rand) or 'none'})")


def parse_method(name: str) -> Method:
    """The :class:`Method` called ``name``; ValueError with one clear line otherwise."""
    name = name.strip()

    def bad(why: str) -> ValueError:
        return ValueError(f"unknown method '{name}': {why} (methods look like {grammar()})")

    parts = FIXED.get(name, name).split("+")
    adaptive = len(parts) > 1 and parts[-1] == ADAPTIVE
    parts = parts[:-1] if adaptive else parts
    head, rest = parts[0], parts[1:]
    if head != PATH and head not in strategies():
        raise bad(f"strategy '{head}' is not one of {', '.join(strategies())} or {PATH}")
    nee = head == PATH
    if rest and rest[0] == "nee":
        if head == PATH:
            raise bad("path always uses next-event estimation, '+nee' is not needed")
        nee, rest = True, rest[1:]
    sampler, randomization = samplers.DEFAULT, None
    if rest:
        if len(rest) > 1:
            raise bad(f"too many parts after '{parts[0]}'")
        sampler, colon, randomization = rest[0].partition(":")
        randomization = randomization if colon else None
        if sampler not in samplers.names():
            raise bad(f"sampler '{sampler}' is not one of {', '.join(samplers.names())}")
        try:
            samplers.get(sampler).check_randomization(randomization)
        except ValueError as e:
            raise bad(str(e)) from None
        if head != PATH and _strategies.integrator_type(head) != "vr_path" \
                and samplers.get(sampler).bakes_spp:
            valid = [n for n in samplers.names() if not samplers.get(n).bakes_spp]
            raise bad(f"'{head}' learns between passes, and the sampler '{sampler}' compiles "
                      f"the sample count into the kernel (every pass would recompile); "
                      f"valid samplers for it: {', '.join(valid)}")
    if adaptive and head != PATH and _strategies.integrator_type(head) != "vr_path":
        raise bad(f"'{head}' learns between its own passes, which one adaptive pass of "
                  f"per-pixel counts cannot hold: '+{ADAPTIVE}' goes with a vr_path strategy "
                  f"or path")
    if adaptive and sampler != samplers.DEFAULT:
        raise bad(f"'+{ADAPTIVE}' gives pixels unequal counts that are not powers of two, "
                  f"which break the points of '{sampler}': use the {samplers.DEFAULT} sampler")
    return Method(name, None if head == PATH else head, nee, sampler, randomization, adaptive)


def method_name(base: Method, sampler_label: str) -> str:
    """``base`` (a method without a sampler) driven by ``sampler_label`` (the default
    sampler adds nothing to the name)."""
    return base.name if sampler_label == samplers.DEFAULT else f"{base.name}+{sampler_label}"
