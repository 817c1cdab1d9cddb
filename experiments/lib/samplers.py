"""Samplers as descriptors: the one table the grammar, the studies, the lab and the suite read.

A :class:`SamplerSpec` says everything the experiments need to know about a sampler
plugin: how to build its Mitsuba dict, which randomizations it takes (the method grammar's
``SAMPLER:RANDOMIZATION``), which of them give the same image in every run (deterministic:
one repeat stands for all), whether successive jobs continue one sequence through a
``sample_offset`` (instead of reseeding), whether it bakes the sample count into its render
kernel (Mitsuba's stratified, multijitter, orthogonal and ldsampler: a render at a new count
compiles, so timings are taken warm at exactly the timed count), and how it rounds a
requested count (by default: what the plugin itself reports, ``sample_count()`` after
``set_sample_count``, so the rule is Mitsuba's own).

:func:`register_sampler` adds one (a user's own Python sampler plugin, say); it then enters
the method grammar (``bsdf+nee+mysampler``), the sampler study and the lab's point sets.
The built-in table: Mitsuba's ``independent``, ``stratified``, ``multijitter``,
``orthogonal`` and ``ldsampler``, and the bundled ``halton`` and ``zsobol``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from integrators.qmc import RANDOMIZATIONS as QMC_RANDOMIZATIONS

#: The sampler of a method that names none.
DEFAULT = "independent"


def _no_extras(width: int, height: int) -> dict:
    return {}


@dataclass(frozen=True)
class SamplerSpec:
    """One sampler, as the experiments see it."""
    name: str                              # the grammar's SAMPLER (and the plugin type)
    randomizations: tuple = ()             # valid RANDOMIZATION values ('' : takes none)
    deterministic: tuple = ()              # randomizations whose image is the same every run
    continues_sequence: bool = False       # jobs continue one sequence (seed kept, offset moved)
    #: a continued sequence's whole length must be declared (``sequence_length``): the
    #: sampler orders pixels by it (zsobol's Morton index times the sequence length)
    sequence_length: bool = False
    bakes_spp: bool = False                # the sample count is compiled into the render kernel
    native: bool = False                   # one of Mitsuba's own samplers
    plugin: str = ""                       # Mitsuba plugin type (default: ``name``)
    #: plugin parameters that depend on the film (e.g. a Morton-order sampler's film width)
    film_parameters: Callable[[int, int], dict] = field(default=_no_extras, compare=False)
    description: str = ""

    @property
    def type(self) -> str:
        return self.plugin or self.name

    def labels(self) -> list[str]:
        """The sampler study's and the lab's entries: ``name``, or ``name:R`` for each
        randomization."""
        return [f"{self.name}:{r}" for r in self.randomizations] or [self.name]

    def is_deterministic(self, randomization: str | None) -> bool:
        return randomization is not None and randomization in self.deterministic

    def check_randomization(self, randomization: str | None) -> None:
        """ValueError naming the valid choices for a randomization this sampler lacks."""
        if randomization is None:
            return
        if not self.randomizations:
            raise ValueError(f"sampler '{self.name}' takes no randomization (samplers with "
                             f"one: {', '.join(n for n, s in _REGISTRY.items() if s.randomizations) or 'none'})")
        if randomization not in self.randomizations:
            raise ValueError(f"randomization '{randomization}' is not one of "
                             f"{', '.join(self.randomizations)} (sampler '{self.name}')")

    def dict(self, spp: int = 1, randomization: str | None = None, width: int = 0,
             height: int = 0) -> dict:
        """The Mitsuba plugin dict for ``spp`` samples per pixel on a ``width`` x ``height``
        film."""
        self.check_randomization(randomization)
        d = {"type": self.type, "sample_count": spp}
        if randomization is not None:
            d["randomization"] = randomization
        d.update(self.film_parameters(width, height))
        return d

    def sequence_attributes(self, offset: int, total: int) -> dict:
        """Attributes to set on the sampler before a render that continues its sequence at
        ``offset`` (of ``total`` samples per pixel in all; 0: the render's own count)."""
        out = {"sample_offset": offset}
        if self.sequence_length:
            out["sequence_length"] = total
        return out

    def rendered_count(self, spp: int) -> int:
        """The count a render at ``spp`` requested takes (the plugin's own rounding; needs a
        Mitsuba variant)."""
        import mitsuba as mi
        sampler = mi.load_dict(self.dict(spp, width=1, height=1))
        sampler.set_sample_count(spp)
        return int(sampler.sample_count())


_REGISTRY: dict[str, SamplerSpec] = {}


def register_sampler(spec: SamplerSpec, replace: bool = False) -> SamplerSpec:
    """Add ``spec`` to the table (ValueError for a name already there unless ``replace``)."""
    if not spec.name or any(c in spec.name for c in "+:,"):
        raise ValueError(f"invalid sampler name {spec.name!r}: it must be non-empty and "
                         f"contain none of '+', ':', ','")
    if spec.name in _REGISTRY and not replace:
        raise ValueError(f"sampler '{spec.name}' is already registered (pass replace=True "
                         f"to replace it)")
    _REGISTRY[spec.name] = spec
    return spec


def unregister_sampler(name: str) -> None:
    _REGISTRY.pop(name, None)


def names() -> tuple[str, ...]:
    """Every registered sampler, in registration order."""
    return tuple(_REGISTRY)


def native() -> tuple[str, ...]:
    """Mitsuba's own samplers."""
    return tuple(n for n, s in _REGISTRY.items() if s.native)


def get(name: str) -> SamplerSpec:
    """The descriptor of ``name``; ValueError listing the registered ones otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"sampler '{name}' is not one of {', '.join(_REGISTRY)}") from None


def labels() -> list[str]:
    """Every sampler with each randomization: the sampler study's and the lab's list."""
    return [label for spec in _REGISTRY.values() for label in spec.labels()]


def split_label(label: str) -> tuple[SamplerSpec, str | None]:
    """``'halton:owen'`` -> (halton's descriptor, 'owen'); checked."""
    name, colon, randomization = label.partition(":")
    spec = get(name)
    randomization = randomization if colon else None
    spec.check_randomization(randomization)
    return spec, randomization


def label_dict(label: str, spp: int, width: int = 0, height: int = 0) -> dict:
    """The plugin dict of a study label such as ``halton:owen``."""
    spec, randomization = split_label(label)
    return spec.dict(spp, randomization, width, height)


# ------------------------------------------------------------ the built-in table

for _name, _doc in (("independent", "Mitsuba's independent (uniform random) sampler"),
                    ("stratified", "Mitsuba's stratified sampler (count rounded to a square)"),
                    ("multijitter", "Mitsuba's correlated multi-jittered sampler"),
                    ("orthogonal", "Mitsuba's orthogonal array sampler (a prime squared)"),
                    ("ldsampler", "Mitsuba's low-discrepancy (0,2)-sequence sampler")):
    register_sampler(SamplerSpec(_name, bakes_spp=_name != "independent", native=True,
                                 description=_doc))
register_sampler(SamplerSpec(
    "halton", randomizations=tuple(QMC_RANDOMIZATIONS), deterministic=("none",),
    continues_sequence=True, description="the bundled randomized Halton sampler"))
register_sampler(SamplerSpec(
    "zsobol", randomizations=tuple(QMC_RANDOMIZATIONS), deterministic=("none",),
    continues_sequence=True, sequence_length=True,
    film_parameters=lambda width, height: {"film_width": width},
    description="the bundled Owen-scrambled Sobol' sampler in Morton order across pixels "
                "(blue-noise error; counts rounded up to powers of two)"))
