"""Methods (direction-sampling strategy + sampler) and scene loading for any Mitsuba scene.

A method name is ``strategy[+sampler[:randomization]]``, e.g. ``cosine``,
``bsdf+halton`` or ``bsdf+halton:owen``. Two names are fixed by the writeup:
``uniform+halton`` is plain (unrandomized) Halton, and ``bsdf+halton`` is
Halton with the sampler's default scrambling.

Scenes are loaded through :func:`load_scene`: the XML is read, the sensor's
``<sampler>`` is replaced by the method's sampler, the ``<integrator>`` by
``vr_path`` with the method's strategy (or the reference integrator), and the
film's size by the requested resolution. A user's own scene therefore needs no
``$strategy``-style parameters.
"""
from __future__ import annotations

import copy
import hashlib
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import mitsuba as mi

STRATEGIES = ("uniform", "cosine", "bsdf")
SAMPLERS = ("independent", "halton")
DEFAULT_METHODS = ("uniform", "cosine", "bsdf", "uniform+halton", "bsdf+halton")
DEFAULT_MAX_DEPTH = 8
#: Reference integrators: Mitsuba's ``path`` or ``vr_path`` (bsdf), both with
#: next-event estimation + MIS, which converge much faster than the methods.
REFERENCE_INTEGRATORS = ("path", "vr_path")


@dataclass(frozen=True)
class Method:
    """One compared method: a ``vr_path`` strategy and a sampler with its parameters."""
    name: str
    strategy: str
    sampler: str = "independent"
    sampler_params: tuple = ()   # ((name, value), ...), string values

    @property
    def is_halton(self) -> bool:
        return self.sampler == "halton"

    def settings(self) -> dict:
        return {"name": self.name, "strategy": self.strategy, "sampler": self.sampler,
                "sampler_params": dict(self.sampler_params)}


#: Names whose meaning is fixed rather than parsed.
NAMED = {"uniform+halton": Method("uniform+halton", "uniform", "halton",
                                  (("randomization", "none"),))}


def halton_randomizations() -> tuple[str, ...] | None:
    """Randomizations the ``halton`` sampler documents, or None if it does not say."""
    import importlib
    for module in ("integrators.halton", "integrators.qmc"):
        try:
            values = getattr(importlib.import_module(module), "RANDOMIZATIONS", None)
        except ImportError:
            continue
        if values is not None:
            return tuple(values)
    return None


def parse_method(name: str) -> Method:
    """The :class:`Method` called ``name``; ValueError with one clear line otherwise."""
    name = name.strip()
    if name in NAMED:
        return NAMED[name]
    strategy, _, rest = name.partition("+")
    sampler, _, randomization = rest.partition(":")
    sampler = sampler or "independent"
    if strategy not in STRATEGIES:
        raise ValueError(f"unknown method '{name}': strategy '{strategy}' is not one of "
                         f"{', '.join(STRATEGIES)} (methods look like "
                         f"{', '.join(DEFAULT_METHODS)}, or e.g. bsdf+halton:owen)")
    if sampler not in SAMPLERS:
        raise ValueError(f"unknown method '{name}': sampler '{sampler}' is not one of "
                         f"{', '.join(SAMPLERS)}")
    params = ()
    if randomization:
        if sampler != "halton":
            raise ValueError(f"unknown method '{name}': only halton takes a randomization")
        valid = halton_randomizations()
        if valid is not None and randomization not in valid:
            raise ValueError(f"unknown method '{name}': randomization '{randomization}' is "
                             f"not one of {', '.join(valid)}")
        params = (("randomization", randomization),)
    return Method(name, strategy, sampler, params)


def plugin_available(plugin_type: str) -> bool:
    """True if a sampler plugin of this type can be instantiated in the current variant."""
    try:
        mi.load_dict({"type": plugin_type})
        return True
    except Exception:  # noqa: BLE001  (Mitsuba raises RuntimeError for unknown plugins)
        return False


# ------------------------------------------------------------ scene XML

def file_hash(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def plugins_version() -> str:
    """Hash of the plugin sources (``integrators/*.py``) and Mitsuba's version.

    Part of every render's settings, so renders and references made with other
    plugin code are made again rather than reused.
    """
    import integrators
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


def _child(parent: ET.Element, tag: str, name: str) -> ET.Element | None:
    for el in parent.findall(tag):
        if el.get("name") == name:
            return el
    return None


@dataclass(frozen=True)
class SceneInfo:
    """What the experiments need to know about a scene file."""
    path: str
    width: int
    height: int
    max_depth: int
    sha256: str


def read_scene(path: str) -> SceneInfo:
    """Parse a scene file: film size and the integrator's max_depth (ValueError if unusable)."""
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

    def film_int(name, default):
        el = _child(film, "integer", name)
        return int(_resolve(el.get("value"), defaults)) if el is not None else default

    max_depth = DEFAULT_MAX_DEPTH
    integrator = root.find("integrator")
    if integrator is not None:
        el = _child(integrator, "integer", "max_depth")
        if el is not None:
            max_depth = int(_resolve(el.get("value"), defaults))
    return SceneInfo(os.path.abspath(path), film_int("width", 768), film_int("height", 576),
                     max_depth, file_hash(path))


def _set_int(parent: ET.Element, name: str, value: int) -> None:
    el = _child(parent, "integer", name)
    if el is None:
        el = ET.SubElement(parent, "integer", name=name)
    el.set("value", str(value))


def scene_xml(path: str, width: int, height: int, integrator: dict,
              sampler: str = "independent", sampler_params: tuple = ()) -> str:
    """The scene's XML with its integrator, sampler and film size replaced.

    ``integrator`` is a dict of properties with a ``type`` entry; ints, bools and
    strings become the matching XML elements.
    """
    root = copy.deepcopy(ET.parse(path).getroot())
    for old in root.findall("integrator"):
        root.remove(old)
    node = ET.Element("integrator", type=integrator["type"])
    for key, value in integrator.items():
        if key == "type":
            continue
        tag = ("boolean" if isinstance(value, bool) else "integer" if isinstance(value, int)
               else "string")
        ET.SubElement(node, tag, name=key,
                      value=str(value).lower() if isinstance(value, bool) else str(value))
    root.insert(0, node)

    sensor = root.find("sensor")
    for old in sensor.findall("sampler"):
        sensor.remove(old)
    node = ET.SubElement(sensor, "sampler", type=sampler)
    ET.SubElement(node, "integer", name="sample_count", value="1")
    for key, value in sampler_params:
        ET.SubElement(node, "string", name=key, value=str(value))

    film = sensor.find("film")
    _set_int(film, "width", width)
    _set_int(film, "height", height)
    return ET.tostring(root, encoding="unicode")


_resolver_dirs: set[str] = set()


def _add_scene_dir(path: str) -> None:
    """Let relative paths in the scene (meshes, textures, includes) resolve."""
    directory = os.path.dirname(os.path.abspath(path))
    if directory not in _resolver_dirs:
        mi.file_resolver().prepend(directory)
        _resolver_dirs.add(directory)


def method_integrator(method: Method, max_depth: int) -> dict:
    return {"type": "vr_path", "strategy": method.strategy, "max_depth": max_depth,
            "emitter_sampling": False}


def reference_integrator(kind: str, max_depth: int) -> dict:
    if kind == "path":
        return {"type": "path", "max_depth": max_depth}
    return {"type": "vr_path", "strategy": "bsdf", "max_depth": max_depth,
            "emitter_sampling": True}


def load_scene(info: SceneInfo, width: int, height: int, integrator: dict,
               sampler: str = "independent", sampler_params: tuple = ()):
    """Load ``info``'s scene with the given integrator, sampler and resolution."""
    _add_scene_dir(info.path)
    return mi.load_string(scene_xml(info.path, width, height, integrator, sampler,
                                    sampler_params))


def load_method_scene(info: SceneInfo, method: Method, width: int, height: int):
    return load_scene(info, width, height, method_integrator(method, info.max_depth),
                      method.sampler, method.sampler_params)
