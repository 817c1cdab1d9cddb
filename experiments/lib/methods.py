"""The method grammar, the integrator/sampler dicts, and the one way to load and vary a scene.

Method names (one definition of every part, read from the plugins)::

    STRATEGY[+nee][+SAMPLER[:RANDOMIZATION]]      vr_path, e.g. cosine, bsdf+nee+orthogonal
    path[+SAMPLER[:RANDOMIZATION]]                Mitsuba's C++ path (always NEE + MIS)

STRATEGY is any ``vr_path`` strategy (:func:`strategies`, from
:mod:`integrators.path`), ``+nee`` turns on emitter sampling (next-event
estimation + MIS), SAMPLER is one of :data:`SAMPLERS` (default
``independent``) and RANDOMIZATION one of :data:`RANDOMIZATIONS` (``halton``
only; from :mod:`integrators.qmc`). One name is fixed by the writeup:
``uniform+halton`` is its plain (unrandomized) Halton; any other ``+halton``
without a randomization uses the sampler's default scrambling.

Scenes: :func:`read_scene` reads a scene file (film size, and the integrator
settings the experiments keep: max_depth, rr_depth, hide_emitters);
:func:`scene_xml` writes the scene with the method's integrator, sampler and
the requested resolution; :func:`scene_variant` writes a copy with some
``<default>`` parameters changed (the only way the experiments vary a scene).
``--scene cornell_box`` is Mitsuba's ``mi.cornell_box()``, written as XML by
:func:`builtin_scene`.
"""
from __future__ import annotations

import copy
import dataclasses
import hashlib
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import integrators
import mitsuba as mi
from integrators.choices import STRATEGIES
from integrators.qmc import RANDOMIZATIONS

from .files import read_text, write_text


def strategies() -> tuple[str, ...]:
    """The ``vr_path`` strategies: ``integrators.choices.STRATEGIES``, the one definition
    (importable before a variant is set)."""
    return tuple(STRATEGIES)


#: Samplers a method may use: Mitsuba's own and the bundled ``halton``.
NATIVE_SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")
SAMPLERS = NATIVE_SAMPLERS + ("halton",)
#: Mitsuba's C++ path tracer as a method (NEE + MIS): ``path[+SAMPLER]``.
PATH = "path"
#: The writeup's methods (no NEE), then what a user would run instead.
DEFAULT_METHODS = ("uniform", "cosine", "bsdf", "uniform+halton", "bsdf+halton", "bsdf+nee",
                   "path")
#: Names whose meaning is fixed rather than parsed.
PLAIN_HALTON = "uniform+halton"
#: Scene names that ``--scene`` accepts besides files.
BUILTIN_SCENES = ("cornell_box",)


@dataclass(frozen=True)
class Method:
    """One compared method: integrator (``vr_path`` strategy or ``path``), NEE, sampler."""
    name: str
    strategy: str | None            # None for Mitsuba's path
    nee: bool = False
    sampler: str = "independent"
    randomization: str | None = None   # halton only; None = the sampler's default

    @property
    def integrator(self) -> str:
        return PATH if self.strategy is None else "vr_path"

    @property
    def is_halton(self) -> bool:
        return self.sampler == "halton"

    @property
    def continues_sequence(self) -> bool:
        """Passes continue one sequence (seed kept, sample offset advanced): ``halton``."""
        return self.is_halton

    @property
    def deterministic(self) -> bool:
        """The same points in every pixel and every run: plain Halton."""
        return self.is_halton and self.randomization == "none"

    def settings(self) -> dict:
        return dataclasses.asdict(self)


def grammar() -> str:
    """The valid parts, for error messages and --help."""
    return (f"STRATEGY[+nee][+SAMPLER[:RANDOMIZATION]] or path[+SAMPLER[:RANDOMIZATION]]; "
            f"STRATEGY {'|'.join(strategies())}, SAMPLER {'|'.join(SAMPLERS)}, RANDOMIZATION "
            f"(halton only) {'|'.join(RANDOMIZATIONS)}")


def parse_method(name: str) -> Method:
    """The :class:`Method` called ``name``; ValueError with one clear line otherwise."""
    name = name.strip()

    def bad(why: str) -> ValueError:
        return ValueError(f"unknown method '{name}': {why} (methods look like {grammar()})")

    if name == PLAIN_HALTON:
        return Method(name, "uniform", False, "halton", "none")
    parts = name.split("+")
    head, rest = parts[0], parts[1:]
    if head != PATH and head not in strategies():
        raise bad(f"strategy '{head}' is not one of {', '.join(strategies())} or {PATH}")
    nee = head == PATH
    if rest and rest[0] == "nee":
        if head == PATH:
            raise bad("path always uses next-event estimation, '+nee' is not needed")
        nee, rest = True, rest[1:]
    sampler, randomization = "independent", None
    if rest:
        if len(rest) > 1:
            raise bad(f"too many parts after '{parts[0]}'")
        sampler, colon, randomization = rest[0].partition(":")
        randomization = randomization if colon else None
        if sampler not in SAMPLERS:
            raise bad(f"sampler '{sampler}' is not one of {', '.join(SAMPLERS)}")
        if colon and sampler != "halton":
            raise bad(f"only halton takes a randomization, not {sampler}")
        if colon and randomization not in RANDOMIZATIONS:
            raise bad(f"randomization '{randomization}' is not one of "
                      f"{', '.join(RANDOMIZATIONS)}")
    return Method(name, None if head == PATH else head, nee, sampler, randomization)


# ------------------------------------------------------------ plugin dicts

def vr_path_dict(strategy: str = "bsdf", emitter_sampling: bool = False,
                 max_depth: int | None = None, rr_depth: int | None = None,
                 hide_emitters: bool | None = None) -> dict:
    """The ``vr_path`` plugin dict (settings left None keep the plugin's defaults)."""
    d = {"type": "vr_path", "strategy": strategy, "emitter_sampling": emitter_sampling}
    for key, value in (("max_depth", max_depth), ("rr_depth", rr_depth),
                       ("hide_emitters", hide_emitters)):
        if value is not None:
            d[key] = value
    return d


@dataclass(frozen=True)
class Depth:
    """Path-length settings of a render (None: the integrator's own default)."""
    max_depth: int | None = None
    rr_depth: int | None = None
    hide_emitters: bool | None = None

    def describe(self) -> str:
        return ", ".join(f"{k} {'plugin default' if v is None else v}"
                         for k, v in dataclasses.asdict(self).items())


def integrator_dict(method: Method, depth: Depth = Depth()) -> dict:
    if method.integrator == PATH:
        d = {"type": "path"}
        for key, value in dataclasses.asdict(depth).items():
            if value is not None:
                d[key] = value
        return d
    return vr_path_dict(method.strategy, method.nee, depth.max_depth, depth.rr_depth,
                        depth.hide_emitters)


def sampler_dict(method: Method, spp: int = 1) -> dict:
    d = {"type": method.sampler, "sample_count": spp}
    if method.randomization is not None:
        d["randomization"] = method.randomization
    return d


# ------------------------------------------------------------ scene files

def file_hash(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def plugins_version() -> str:
    """Hash of the plugin sources (``integrators/*.py``) and Mitsuba's version.

    Part of every render job's key, so renders made with other plugin code are
    made again rather than reused.
    """
    digest = hashlib.sha256(mi.__version__.encode())
    directory = os.path.dirname(os.path.abspath(integrators.__file__))
    for name in sorted(os.listdir(directory)):
        if name.endswith(".py"):
            with open(os.path.join(directory, name), "rb") as f:
                digest.update(name.encode() + f.read())
    return digest.hexdigest()[:16]


def _defaults(root: ET.Element) -> dict[str, str]:
    return {d.get("name"): d.get("value") for d in root.iter("default")}


def _resolve(value: str | None, defaults: dict[str, str]) -> str | None:
    if value is not None and value.startswith("$"):
        return defaults.get(value[1:], value)
    return value


def _child(parent: ET.Element, tags, name: str) -> ET.Element | None:
    for el in parent:
        if el.tag in tags and el.get("name") == name:
            return el
    return None


@dataclass(frozen=True)
class SceneInfo:
    """What the experiments need to know about a scene file."""
    path: str
    width: int
    height: int
    depth: Depth          # the scene's own integrator settings (None where it has none)
    sha256: str


def read_scene(path: str) -> SceneInfo:
    """Parse a scene file: film size and integrator settings (ValueError if unusable)."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise ValueError(f"scene '{path}' is not valid XML: {e}") from None
    if root.tag != "scene":
        raise ValueError(f"scene '{path}' has no <scene> root element")
    defaults = _defaults(root)
    film = root.find("sensor/film")
    if film is None:
        raise ValueError(f"scene '{path}' has no <sensor> with a <film>")

    def value(parent, tag, name, convert, default=None):
        el = _child(parent, (tag,), name) if parent is not None else None
        if el is None:
            return default
        text = _resolve(el.get("value"), defaults)
        try:
            return convert(text)
        except (TypeError, ValueError):
            raise ValueError(f"scene '{path}': {tag} '{name}' = '{text}' is not a valid "
                             f"{tag}") from None

    def boolean(text):
        if text.lower() not in ("true", "false"):
            raise ValueError(text)
        return text.lower() == "true"

    integrator = root.find("integrator")
    depth = Depth(value(integrator, "integer", "max_depth", int),
                  value(integrator, "integer", "rr_depth", int),
                  value(integrator, "boolean", "hide_emitters", boolean))
    return SceneInfo(os.path.abspath(path), value(film, "integer", "width", int, 768),
                     value(film, "integer", "height", int, 576), depth, file_hash(path))


def _set(parent: ET.Element, tag: str, name: str, value) -> None:
    el = _child(parent, (tag,), name)
    if el is None:
        el = ET.SubElement(parent, tag, name=name)
    el.set("value", _xml_value(value))


def _xml_value(value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    return repr(float(value)) if isinstance(value, float) else str(value)


def _tag(value) -> str:
    return ("boolean" if isinstance(value, bool) else "integer" if isinstance(value, int)
            else "float" if isinstance(value, float) else "string")


def scene_xml(path: str, width: int, height: int, integrator: dict, sampler: dict) -> str:
    """The scene's XML with its integrator, sampler and film size replaced.

    ``integrator``/``sampler`` are flat plugin dicts with a ``type`` entry.
    """
    root = copy.deepcopy(ET.parse(path).getroot())
    for old in root.findall("integrator"):
        root.remove(old)
    node = ET.Element("integrator", type=integrator["type"])
    for key, value in integrator.items():
        if key != "type":
            ET.SubElement(node, _tag(value), name=key, value=_xml_value(value))
    root.insert(0, node)

    sensor = root.find("sensor")
    for old in sensor.findall("sampler"):
        sensor.remove(old)
    node = ET.SubElement(sensor, "sampler", type=sampler["type"])
    for key, value in sampler.items():
        if key != "type":
            ET.SubElement(node, _tag(value), name=key, value=_xml_value(value))
    film = sensor.find("film")
    _set(film, "integer", "width", width)
    _set(film, "integer", "height", height)
    return ET.tostring(root, encoding="unicode")


_resolver_dirs: set[str] = set()


def _add_scene_dir(path: str) -> None:
    """Let relative paths in the scene (meshes, textures, includes) resolve."""
    directory = os.path.dirname(os.path.abspath(path))
    if directory not in _resolver_dirs:
        mi.file_resolver().prepend(directory)
        _resolver_dirs.add(directory)


def load_scene(path: str, width: int, height: int, method: Method, depth: Depth = Depth(),
               spp: int = 1):
    """Load the scene file with ``method``'s integrator and sampler at ``width`` x ``height``."""
    _add_scene_dir(path)
    return mi.load_string(scene_xml(path, width, height, integrator_dict(method, depth),
                                    sampler_dict(method, spp)))


def effective_depth(info: SceneInfo, max_depth: int | None = None,
                    rr_depth: int | None = None, hide_emitters: bool | None = None) -> Depth:
    """The scene's own settings, each replaced where the command line gives one."""
    d = info.depth
    return Depth(d.max_depth if max_depth is None else max_depth,
                 d.rr_depth if rr_depth is None else rr_depth,
                 d.hide_emitters if hide_emitters is None else hide_emitters)


# ------------------------------------------------------------ scene variants

def scene_defaults(path: str) -> dict[str, str]:
    """The ``<default name=... value=...>`` parameters of a scene file."""
    return _defaults(ET.parse(path).getroot())


def scene_variant(info: SceneInfo, directory: str, name: str,
                  overrides: dict[str, object]) -> SceneInfo:
    """``info``'s scene with some ``<default>`` values replaced, written to ``directory/name.xml``.

    KeyError if the scene does not declare one of the parameters. Relative
    paths inside the scene keep resolving against the original file's folder.
    """
    root = copy.deepcopy(ET.parse(info.path).getroot())
    found = set()
    for d in root.iter("default"):
        if d.get("name") in overrides:
            d.set("value", _xml_value(overrides[d.get("name")]))
            found.add(d.get("name"))
    missing = set(overrides) - found
    if missing:
        raise KeyError(", ".join(sorted(missing)))
    path = os.path.join(directory, name + ".xml")
    text = ET.tostring(root, encoding="unicode")
    if read_text(path) != text:
        write_text(path, text)
    _add_scene_dir(info.path)
    return read_scene(path)


# ------------------------------------------------------------ built-in scenes

_CATEGORIES = {"BSDF": "bsdf", "Shape": "shape", "Emitter": "emitter", "Sensor": "sensor",
               "Sampler": "sampler", "Film": "film", "ReconstructionFilter": "rfilter",
               "Integrator": "integrator", "Texture": "texture", "Medium": "medium",
               "PhaseFunction": "phase"}


def _dict_to_xml(parent: ET.Element, name: str | None, value) -> None:
    """One entry of a Mitsuba scene dict as XML (the subset ``mi.cornell_box()`` uses)."""
    attrs = {"name": name} if name else {}
    if isinstance(value, dict):
        kind = value["type"]
        if kind == "ref":
            ET.SubElement(parent, "ref", id=value["id"], **attrs)
        elif kind == "rgb":
            ET.SubElement(parent, "rgb", value=", ".join(map(str, value["value"])), **attrs)
        else:
            category = mi.PluginManager.instance().plugin_type(kind).name
            node = ET.SubElement(parent, _CATEGORIES.get(category, category.lower()),
                                 type=kind)
            if name and parent.tag == "scene":
                node.set("id", name)
            for key, item in value.items():
                if key != "type":
                    _dict_to_xml(node, key, item)
    elif isinstance(value, (mi.ScalarTransform4f, mi.Transform4f)):
        node = ET.SubElement(parent, "transform", **attrs)
        matrix = mi.ScalarTransform4f(value).matrix
        ET.SubElement(node, "matrix", value=" ".join(
            repr(float(matrix[i][j])) for i in range(4) for j in range(4)))
    elif isinstance(value, (list, tuple)) and len(value) == 3:
        ET.SubElement(parent, "vector", x=str(value[0]), y=str(value[1]), z=str(value[2]),
                      **attrs)
    else:
        ET.SubElement(parent, _tag(value), value=_xml_value(value), **attrs)


def builtin_scene(name: str, directory: str) -> str:
    """Write the built-in scene ``name`` (``cornell_box``) as XML into ``directory``."""
    if name not in BUILTIN_SCENES:
        raise ValueError(f"unknown built-in scene '{name}': choose {', '.join(BUILTIN_SCENES)}")
    scene = getattr(mi, name)()
    root = ET.Element("scene", version="3.0.0")
    # referenced BSDFs first, then everything else (Mitsuba resolves ids in order)
    items = sorted((k, v) for k, v in scene.items() if k != "type")
    items.sort(key=lambda kv: 0 if isinstance(kv[1], dict) and
               mi.PluginManager.instance().plugin_type(kv[1]["type"]).name == "BSDF" else 1)
    for key, value in items:
        _dict_to_xml(root, key, value)
    ET.indent(root)
    path = os.path.join(directory, f"{name}.xml")
    text = ET.tostring(root, encoding="unicode") + "\n"
    if read_text(path) != text:
        write_text(path, text)
    return path
