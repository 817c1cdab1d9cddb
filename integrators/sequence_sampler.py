"""The state skeleton every sequence sampler of the project shares: :class:`SequenceSampler`
(the index and dimension of pbrt-v4's samplers, kept apart from their maths; the role of
Mitsuba's ``PCG32Sampler`` for Python samplers). The maths lives in :mod:`.qmc`."""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

from . import qmc

#: Why ``advance()`` is refused after an undeclared seeding (one message for every
#: sampler; formatted with the plugin name, the seeding's values and the subclass's hint).
ADVANCE_REFUSED = (
    "{name}: advance() after a seed() of {lanes} lanes (sample_count {spp}) whose samples "
    "per pixel per pass were not declared. Mitsuba calls it when it renders in several "
    "passes (an integrator with 'samples_per_pass', or more than 2^32 samples in one "
    "render), and it does not tell a Python sampler how many samples each pass takes, so "
    "the sample indices would be wrong. Render without 'samples_per_pass' (at most 2^32 "
    "samples per mi.render call) and, for more samples, render in passes of your own: keep "
    "the seed{hint} and set the sampler's 'sample_offset' to the samples already taken "
    "before each mi.render call. A caller that drives the sampler itself calls "
    "set_samples_per_wavefront(k) before seed().")


class SequenceSampler(mi.Sampler):
    r"""Base class of samplers that take the samples of a sequence per pixel (``halton``,
    ``zsobol``, ``examples/lattice_sampler.py``). Not a plugin itself.

    Shared parameters (read here; a plugin's docstring lists them in its table):

    * ``sample_count`` (int): samples per pixel, read by Mitsuba's ``Sampler``; a
      subclass validates it before calling ``super().__init__`` (Default: 4).
    * ``seed`` (int in [0, 2^32)): seed offset: ``seed(s)`` seeds with ``seed + s``, as
      Mitsuba's own samplers do (Default: 0).
    * ``sample_offset`` (int in [0, 2^31)): index of each pixel's first sample in its
      sequence; an attribute and a ``mi.traverse`` parameter, settable between renders
      without recompiling (Default: 0).

    State: per lane, in Dr.Jit arrays (so symbolic loops carry it): ``_lane_sample``, the
    sample of the lane within its pixel's samples of one pass; ``_dimension``, the next
    dimension drawn; ``_pass_offset``, the samples of the passes before (opaque); plus
    the subclass's own per-seeding tables, made by :meth:`_seed_lanes` and named in
    :attr:`STATE` for :meth:`clone`. The seed and ``sample_offset`` are opaque, so
    reseeding does not recompile a render kernel. :meth:`current_sample_index` is
    ``sample_offset + pass offset + lane sample``.

    Wavefront layout: lane ``l`` is sample ``l % k`` of pixel ``l // k``, ``k`` the
    samples per pixel of one pass. A caller that renders in passes declares ``k`` with
    ``set_samples_per_wavefront(k)`` before ``seed()``; the declaration holds for that
    seeding only. Without it, ``k`` is :meth:`_samples_per_wavefront`'s choice: the
    sample count when it divides the wavefront (one pass, Mitsuba's ``mi.render``), one
    sample per lane otherwise.

    Multi-pass renders: ``advance()`` moves to the next pass (pass offset ``+= k``,
    dimension 0). Mitsuba's own multi-pass renders (``samples_per_pass``) declare ``k``
    through a C++ call a Python sampler never sees, so ``advance()`` after an undeclared
    seeding raises a ``RuntimeError`` (:data:`ADVANCE_REFUSED`) instead of continuing
    with wrong sample indices; continue a sequence over ``mi.render`` calls with
    ``sample_offset`` instead.

    A subclass sets :attr:`PLUGIN`, :attr:`PARAMETERS` (its own plugin parameters, as
    attributes, that :meth:`fork` passes on), :attr:`STATE` and :attr:`ADVANCE_HINT`,
    parses its parameters and calls ``super().__init__(props, name=value, ...)``, and
    writes ``next_1d``/``next_2d`` and, if it needs them, the hooks
    :meth:`_samples_per_wavefront`, :meth:`_seed_lanes` and :meth:`_advanced`.
    """

    #: Plugin name: error messages and ``fork``'s properties.
    PLUGIN = "sequence"
    #: The subclass's own plugin parameters (attributes) that ``fork`` passes on.
    PARAMETERS: tuple = ()
    #: Attributes of one seeding that ``clone`` copies (Dr.Jit arrays copied, others shared).
    STATE: tuple = ("_lane_sample", "_pass_offset", "_dimension", "_spw", "_passes",
                    "_declared")
    #: Extra advice after "keep the seed" in the refusal of ``advance()``.
    ADVANCE_HINT = ""

    def __init__(self, props: mi.Properties, **parameters):
        seed = props.get("seed", 0)
        if not isinstance(seed, int) or not 0 <= seed < 2**32:
            raise ValueError(f"{self.PLUGIN}: 'seed' must be an integer in [0, 2^32), "
                             f"got {seed!r}")
        offset = props.get("sample_offset", 0)
        mi.Sampler.__init__(self, props)
        for name, value in parameters.items():
            setattr(self, name, value)
        self.base_seed = seed
        #: Samples per pixel per pass declared for the next seed() (0: none).
        self._declared_spw = 0
        self.sample_offset = offset
        self._reset(mi.UInt32(seed), 1, 1, declared=False)

    @classmethod
    def _read_choice(cls, props: mi.Properties, name: str, choices, default: str) -> str:
        value = props.get(name, default)
        if value not in choices:
            raise ValueError(f"{cls.PLUGIN}: unknown {name} {value!r}; "
                             f"valid choices are {', '.join(choices)}")
        return value

    # ------------------------------------------------------------ parameters

    @property
    def sample_offset(self) -> int:
        """Index of each pixel's first sample in its sequence (see the class docs)."""
        return self._offset

    @sample_offset.setter
    def sample_offset(self, value) -> None:
        value = int(value if not isinstance(value, dr.ArrayBase) else dr.slice(value, 0))
        if not 0 <= value <= qmc.MAX_INDEX:
            raise ValueError(f"{self.PLUGIN}: 'sample_offset' must lie in [0, 2^31), "
                             f"got {value}")
        self._offset = value
        self._sample_offset = dr.opaque(mi.UInt32, value)

    def set_samples_per_wavefront(self, samples_per_wavefront: int) -> None:
        if samples_per_wavefront <= 0:
            raise ValueError(f"{self.PLUGIN}: samples per wavefront must be > 0, got "
                             f"{samples_per_wavefront}")
        mi.Sampler.set_samples_per_wavefront(self, samples_per_wavefront)
        self._declared_spw = samples_per_wavefront       # for the next seed() only

    def traverse(self, callback):
        callback.put("sample_offset", self._sample_offset, mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys=[]):
        self.sample_offset = self._sample_offset

    # ----------------------------------------------------------------- state

    def _samples_per_wavefront(self, wavefront_size: int, declared: int) -> int:
        """Hook: the samples per pixel of one pass of this seeding (``declared``: the
        caller's declaration, 0 if none)."""
        if declared:
            return declared
        spp = self.sample_count()
        return spp if wavefront_size % spp == 0 else 1   # else a sequence per lane

    def _pixels(self, lanes: mi.UInt32, samples_per_wavefront: int) -> mi.UInt32:
        """Hook: the pixel of every lane (``lanes // samples_per_wavefront``)."""
        return lanes // dr.opaque(mi.UInt32, samples_per_wavefront)

    def _seed_lanes(self, seed: mi.UInt32, pixel: mi.UInt32, wavefront_size: int) -> None:
        """Hook: the subclass's per-seeding tables from the opaque ``seed`` (the render's
        seed plus ``seed``) and every lane's ``pixel``."""

    def _advanced(self) -> None:
        """Hook: called by ``advance()`` once the next pass is set up."""

    def _reset(self, seed, wavefront_size: int, samples_per_wavefront: int,
               declared: bool) -> None:
        lanes = dr.arange(mi.UInt32, wavefront_size)
        pixel = self._pixels(lanes, samples_per_wavefront)
        self._lane_sample = lanes - pixel * dr.opaque(mi.UInt32, samples_per_wavefront)
        self._pass_offset = dr.opaque(mi.UInt32, 0)
        self._dimension = dr.zeros(mi.UInt32, wavefront_size)
        self._spw, self._passes, self._declared = samples_per_wavefront, 0, declared
        self._seed_lanes(seed, pixel, wavefront_size)

    def seed(self, seed, wavefront_size: int = 0xFFFFFFFF) -> None:
        # Read before the base call: nanobind may dispatch it back into this
        # override once (nested), which must see the same declaration.
        declared_spw = self._declared_spw
        mi.Sampler.seed(self, seed, wavefront_size)
        if isinstance(seed, int):
            seed = dr.opaque(mi.UInt32, (seed + self.base_seed) & 0xFFFFFFFF)
        else:
            seed = mi.UInt32(seed) + self.base_seed
            dr.make_opaque(seed)
        wavefront_size = self.wavefront_size()
        spw = self._samples_per_wavefront(wavefront_size, declared_spw)
        self._reset(seed, wavefront_size, spw, declared_spw > 0)
        self._declared_spw = 0                   # the declaration is for this seeding only

    def advance(self) -> None:
        if not self._declared:
            raise RuntimeError(ADVANCE_REFUSED.format(
                name=self.PLUGIN, lanes=self.wavefront_size(), spp=self.sample_count(),
                hint=self.ADVANCE_HINT))
        self._passes += 1
        self._pass_offset = self._pass_offset + self._spw
        dr.make_opaque(self._pass_offset)
        self._dimension = dr.zeros(mi.UInt32, dr.width(self._dimension))
        self._advanced()

    def schedule_state(self) -> None:
        state = [getattr(self, name) for name in self.STATE]
        dr.schedule(self._sample_offset, *[v for v in state if isinstance(v, dr.ArrayBase)])

    def current_sample_index(self) -> mi.UInt32:
        """Index of every lane's current sample in its pixel's sequence."""
        return self._sample_offset + self._pass_offset + self._lane_sample

    # ------------------------------------------------------------ copy/fork

    def fork(self) -> mi.Sampler:
        props = mi.Properties(self.PLUGIN)
        props["sample_count"] = self.sample_count()
        props["seed"] = self.base_seed
        for name in self.PARAMETERS:
            props[name] = getattr(self, name)
        props["sample_offset"] = self.sample_offset
        return type(self)(props)                 # this variant's class

    def clone(self) -> mi.Sampler:
        sampler = self.fork()
        if self.wavefront_size() > 1:
            mi.Sampler.seed(sampler, 0, self.wavefront_size())
        for name in self.STATE:
            value = getattr(self, name)
            setattr(sampler, name, type(value)(value) if isinstance(value, dr.ArrayBase)
                    else value)
        return sampler

    def to_string(self) -> str:
        fields = [f"sample_count={self.sample_count()}", f"seed={self.base_seed}",
                  *[f"{name}={getattr(self, name)}" for name in self.PARAMETERS],
                  f"sample_offset={self.sample_offset}"]
        return f"{type(self).__name__}[{', '.join(fields)}]"
