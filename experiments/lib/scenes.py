"""Scene files read and varied the way Mitsuba's loader reads them.

Every scene goes through Mitsuba's own parser (:mod:`mitsuba.parser`), so whatever
``mi.load_file`` accepts works here: ``<include>`` fragments, ``<path>`` folders, ``$``
parameters with their ``<default>`` values, ``<ref>`` ids and relative asset paths.

* :func:`read_scene` -> :class:`SceneInfo`: film size, the integrator settings the
  experiments keep (max_depth, rr_depth, hide_emitters) and a content hash over every file
  the scene is made of (a changed fragment changes it).
* :func:`load_scene`: the scene with a method's integrator and sampler and the requested
  film size, swapped in Mitsuba's parsed representation (nodes added where the scene has
  none), then instantiated by Mitsuba.
* :func:`scene_variant`: a copy with some top-level ``<default>`` values changed (the one
  way the experiments vary a scene); :func:`scene_defaults` lists them.
* :func:`builtin_scene`: ``--scene cornell_box`` is ``mi.cornell_box()``, written as XML.
* The scene contract: a study declares what it needs (:class:`Needs`); :func:`unmet`
  says what a scene lacks, in words the report and stderr print.
"""
from __future__ import annotations

import copy
import functools
import hashlib
import os
from dataclasses import dataclass
from xml.etree import ElementTree

import mitsuba as mi

from .files import read_text, write_text
from .methods import Depth, Method

#: Scene names that ``--scene`` accepts besides files.
BUILTIN_SCENES = ("cornell_box",)
#: Mitsuba's hdrfilm size when a scene gives none.
DEFAULT_FILM = (768, 576)


# ------------------------------------------------------------ parsing

def _config() -> "mi.parser.ParserConfig":
    return mi.parser.ParserConfig(mi.variant())


_resolver_dirs: set[str] = set()


def _add_scene_dir(path: str) -> None:
    """Let relative paths of a scene (fragments, meshes, textures) resolve from copies of it
    written elsewhere (:func:`scene_variant`)."""
    directory = os.path.dirname(os.path.abspath(path))
    if directory not in _resolver_dirs:
        mi.file_resolver().prepend(directory)
        _resolver_dirs.add(directory)


def parse(path: str):
    """Mitsuba's parsed representation of the scene file (ValueError if it does not parse)."""
    if not os.path.isfile(path):
        raise ValueError(f"scene file '{path}' does not exist")
    try:
        return mi.parser.parse_file(_config(), os.path.abspath(path))
    except RuntimeError as e:
        raise ValueError(f"scene '{path}' does not parse: "
                         f"{str(e).strip().splitlines()[0]}") from None


@functools.lru_cache(maxsize=64)
def box_filter(path: str) -> bool:
    """Whether every reconstruction filter of the scene file is a ``box`` (Mitsuba's
    default, with none given, is a Gaussian): each sample then lands in its own pixel."""
    try:
        state = parse(path)
    except ValueError:
        return False
    kinds = [n.props.plugin_name() for n in state.nodes
             if n.type == mi.ObjectType.ReconstructionFilter]
    return bool(kinds) and all(k == "box" for k in kinds)


#: Emitters that no sampled direction reaches (a position or a direction that is a delta):
#: only next-event estimation sees their light.
DELTA_EMITTERS = ("point", "spot", "projector", "directional", "directionalarea")


@functools.lru_cache(maxsize=64)
def delta_emitters(path: str) -> tuple[str, ...]:
    """The plugin names of the scene's emitters that only next-event estimation reaches
    (:data:`DELTA_EMITTERS`), in file order; () where it has none or does not parse."""
    try:
        state = parse(path)
    except ValueError:
        return ()
    return tuple(n.props.plugin_name() for n in state.nodes
                 if n.type == mi.ObjectType.Emitter and
                 n.props.plugin_name() in DELTA_EMITTERS)


def file_hash(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def content_hash(files) -> str:
    """sha256 of a scene made of ``files`` (in parse order): the file's own hash for a
    single file, else a hash over every file's path relative to the first one's folder and
    content (not the absolute path: the keys and seeds of a scene's renders would then
    differ between two clones of the project)."""
    files = [str(f) for f in files]
    if len(files) == 1:
        return file_hash(files[0])
    digest = hashlib.sha256()
    root = os.path.dirname(os.path.abspath(files[0]))
    for f in files:
        relative = os.path.relpath(os.path.abspath(f), root).replace(os.sep, "/")
        digest.update(relative.encode() + file_hash(f).encode())
    return digest.hexdigest()


def scene_hash(path: str) -> str:
    """The content hash of the scene at ``path`` (every file it includes)."""
    return content_hash(parse(path).files)


def _children(state, node) -> list[int]:
    """Indices of the nodes a node references."""
    out = []
    for key in node.props.keys():
        value = node.props[key]
        if isinstance(value, mi.Properties.ResolvedReference):
            out.append(value.index())
    return out


def _first(state, indices, kind):
    for i in indices:
        if state.nodes[i].type == kind:
            return i
    return None


def _sensor(state, path: str) -> int:
    i = _first(state, _children(state, state.root), mi.ObjectType.Sensor)
    if i is None:
        raise ValueError(f"scene '{path}' has no <sensor>")
    return i


def _props(d: dict) -> "mi.Properties":
    """``d``'s properties, a nested plugin dict (``vr_adaptive``'s ``nested``) as the
    object it describes."""
    p = mi.Properties(d["type"])
    for key, value in d.items():
        if key != "type":
            p[key] = mi.load_dict(value) if isinstance(value, dict) else value
    return p


def _attach(state, parent: int, kind, props) -> int:
    """Replace ``parent``'s child of ``kind`` by a node of ``props`` (added if none)."""
    i = _first(state, _children(state, state.nodes[parent]), kind)
    if i is None:
        node = mi.parser.SceneNode()
        node.type = kind
        node.props = props
        state.nodes.append(node)
        i = len(state.nodes) - 1
        taken = set(state.nodes[parent].props.keys())
        key = next(f"_vr_{n}" for n in range(len(taken) + 1) if f"_vr_{n}" not in taken)
        state.nodes[parent].props[key] = mi.Properties.ResolvedReference(i)
    else:
        state.nodes[i].props = props
    return i


# ------------------------------------------------------------ scene information

@dataclass(frozen=True)
class SceneInfo:
    """What the experiments need to know about a scene file."""
    path: str
    width: int
    height: int
    depth: Depth          # the scene's own integrator settings (None where it has none)
    sha256: str

    @property
    def name(self) -> str:
        """The file's name without its extension."""
        return os.path.splitext(os.path.basename(self.path))[0]


def read_scene(path: str) -> SceneInfo:
    """Film size, integrator settings and content hash of a scene (ValueError if unusable)."""
    state = parse(path)
    sensor = _sensor(state, path)
    film = _first(state, _children(state, state.nodes[sensor]), mi.ObjectType.Film)
    width, height = DEFAULT_FILM
    if film is not None:
        props = state.nodes[film].props
        width = int(props.get("width", width))
        height = int(props.get("height", height))
    integrator = _first(state, _children(state, state.root), mi.ObjectType.Integrator)

    def setting(name, kind):
        if integrator is None or name not in state.nodes[integrator].props:
            return None
        value = state.nodes[integrator].props[name]
        if kind is bool and not isinstance(value, bool) or kind is int and (
                isinstance(value, bool) or not isinstance(value, int)):
            raise ValueError(f"scene '{path}': integrator parameter '{name}' = {value!r} is "
                             f"not {'a boolean' if kind is bool else 'an integer'}")
        return value

    depth = Depth(setting("max_depth", int), setting("rr_depth", int),
                  setting("hide_emitters", bool))
    return SceneInfo(os.path.abspath(path), width, height, depth, content_hash(state.files))


def _with_sensor(path: str, width: int, height: int, method: Method, spp: int):
    """The parsed scene with ``method``'s sampler and a ``width`` x ``height`` film in its
    first sensor; (state, index of that sensor)."""
    _add_scene_dir(path)
    state = parse(path)
    sensor = _sensor(state, path)
    _attach(state, sensor, mi.ObjectType.Sampler,
            _props(method.sampler_dict(spp, width, height)))
    film = _first(state, _children(state, state.nodes[sensor]), mi.ObjectType.Film)
    if film is None:
        film = _attach(state, sensor, mi.ObjectType.Film, _props({"type": "hdrfilm"}))
    state.nodes[film].props["width"] = int(width)
    state.nodes[film].props["height"] = int(height)
    return state, sensor


def _instantiate(state):
    config = _config()
    mi.parser.transform_all(config, state)
    return mi.parser.instantiate(config, state)


def load_scene(path: str, width: int, height: int, method: Method, depth: Depth = Depth(),
               spp: int = 1):
    """The scene with ``method``'s integrator and sampler (``spp`` samples per pixel) on a
    ``width`` x ``height`` film (the scene's first sensor), everything else as the file
    says; instantiated by Mitsuba."""
    state, _ = _with_sensor(path, width, height, method, spp)
    _attach(state, 0, mi.ObjectType.Integrator, _props(method.integrator_dict(depth)))
    return _instantiate(state)


def load_sensor(path: str, width: int, height: int, method: Method, spp: int = 1):
    """The scene's first sensor alone, with ``method``'s sampler on a ``width`` x
    ``height`` film: ``mi.render(scene, sensor=..., integrator=...)`` renders a scene
    loaded once with it, exactly as :func:`load_scene` of that method would (its other
    objects, shapes and emitters, are not instantiated again: a new instance of them would
    change the render kernels of every scene already loaded, Dr.Jit tracing calls over
    every live instance)."""
    state, sensor = _with_sensor(path, width, height, method, spp)
    root = state.nodes[0].props
    for key in list(root.keys()):
        value = root[key]
        if isinstance(value, mi.Properties.ResolvedReference) and value.index() != sensor:
            del root[key]
    return _instantiate(state).sensors()[0]


def effective_depth(info: SceneInfo, max_depth: int | None = None,
                    rr_depth: int | None = None, hide_emitters: bool | None = None) -> Depth:
    """The scene's own settings, each replaced where the command line gives one."""
    d = info.depth
    return Depth(d.max_depth if max_depth is None else max_depth,
                 d.rr_depth if rr_depth is None else rr_depth,
                 d.hide_emitters if hide_emitters is None else hide_emitters)


# ------------------------------------------------------------ scene variants

def _xml_value(value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    return repr(float(value)) if isinstance(value, float) else str(value)


def scene_defaults(path: str) -> dict[str, str]:
    """The ``<default name=... value=...>`` parameters of a scene file (they are top-level
    elements of the file ``mi.load_file`` is given, so its own XML holds them all)."""
    root = ElementTree.parse(path).getroot()
    return {d.get("name"): d.get("value") for d in root.iter("default")}


def scene_variant(info: SceneInfo, directory: str, name: str,
                  overrides: dict[str, object]) -> SceneInfo:
    """``info``'s scene with some ``<default>`` values replaced, written to ``directory/name.xml``.

    KeyError if the scene does not declare one of the parameters. Relative
    paths inside the scene keep resolving against the original file's folder.
    """
    root = copy.deepcopy(ElementTree.parse(info.path).getroot())
    found = set()
    for d in root.iter("default"):
        if d.get("name") in overrides:
            d.set("value", _xml_value(overrides[d.get("name")]))
            found.add(d.get("name"))
    missing = set(overrides) - found
    if missing:
        raise KeyError(", ".join(sorted(missing)))
    path = os.path.join(directory, name + ".xml")
    text = ElementTree.tostring(root, encoding="unicode")
    if read_text(path) != text:
        write_text(path, text)
    _add_scene_dir(info.path)
    return read_scene(path)


# ------------------------------------------------------------ the scene contract

@dataclass(frozen=True)
class Needs:
    """What a study needs of a scene: top-level ``<default>`` parameters (to vary them) and
    BSDF plugins (to probe them)."""
    defaults: tuple = ()
    bsdfs: tuple = ()

    def describe(self) -> str:
        parts = [f"a <default> parameter {d}" for d in self.defaults]
        parts += [f"a {b} BSDF" for b in self.bsdfs]
        return ", ".join(parts) or "nothing"


def unmet(info: SceneInfo, needs: Needs) -> list[str]:
    """What ``info``'s scene lacks of ``needs``, one phrase each (empty: all met)."""
    have = scene_defaults(info.path)
    missing = [f"no <default> parameter {d}" for d in needs.defaults if d not in have]
    if needs.bsdfs:
        state = parse(info.path)
        kinds = {n.props.plugin_name() for n in state.nodes if n.type == mi.ObjectType.BSDF}
        missing += [f"no {b} BSDF" for b in needs.bsdfs if b not in kinds]
    return missing


# ------------------------------------------------------------ built-in scenes

_CATEGORIES = {"BSDF": "bsdf", "Shape": "shape", "Emitter": "emitter", "Sensor": "sensor",
               "Sampler": "sampler", "Film": "film", "ReconstructionFilter": "rfilter",
               "Integrator": "integrator", "Texture": "texture", "Medium": "medium",
               "PhaseFunction": "phase"}


def _tag(value) -> str:
    return ("boolean" if isinstance(value, bool) else "integer" if isinstance(value, int)
            else "float" if isinstance(value, float) else "string")


def _dict_to_xml(parent: ElementTree.Element, name: str | None, value) -> None:
    """One entry of a Mitsuba scene dict as XML (the subset ``mi.cornell_box()`` uses)."""
    attrs = {"name": name} if name else {}
    if isinstance(value, dict):
        kind = value["type"]
        if kind == "ref":
            ElementTree.SubElement(parent, "ref", id=value["id"], **attrs)
        elif kind == "rgb":
            ElementTree.SubElement(parent, "rgb", value=", ".join(map(str, value["value"])),
                                   **attrs)
        else:
            category = mi.PluginManager.instance().plugin_type(kind).name
            node = ElementTree.SubElement(parent, _CATEGORIES.get(category, category.lower()),
                                 type=kind)
            if name and parent.tag == "scene":
                node.set("id", name)
            for key, item in value.items():
                if key != "type":
                    _dict_to_xml(node, key, item)
    elif isinstance(value, (mi.ScalarTransform4f, mi.Transform4f)):
        node = ElementTree.SubElement(parent, "transform", **attrs)
        matrix = mi.ScalarTransform4f(value).matrix
        ElementTree.SubElement(node, "matrix", value=" ".join(
            repr(float(matrix[i][j])) for i in range(4) for j in range(4)))
    elif isinstance(value, (list, tuple)) and len(value) == 3:
        ElementTree.SubElement(parent, "vector", x=str(value[0]), y=str(value[1]), z=str(value[2]),
                      **attrs)
    else:
        ElementTree.SubElement(parent, _tag(value), value=_xml_value(value), **attrs)


def builtin_scene(name: str, directory: str) -> str:
    """Write the built-in scene ``name`` (``cornell_box``) as XML into ``directory``."""
    if name not in BUILTIN_SCENES:
        raise ValueError(f"unknown built-in scene '{name}': choose {', '.join(BUILTIN_SCENES)}")
    scene = getattr(mi, name)()
    root = ElementTree.Element("scene", version="3.0.0")
    # referenced BSDFs first, then everything else (Mitsuba resolves ids in order)
    items = sorted((k, v) for k, v in scene.items() if k != "type")
    items.sort(key=lambda kv: 0 if isinstance(kv[1], dict) and
               mi.PluginManager.instance().plugin_type(kv[1]["type"]).name == "BSDF" else 1)
    for key, value in items:
        _dict_to_xml(root, key, value)
    ElementTree.indent(root)
    path = os.path.join(directory, f"{name}.xml")
    text = ElementTree.tostring(root, encoding="unicode") + "\n"
    if read_text(path) != text:
        write_text(path, text)
    return path
