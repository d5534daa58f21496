"""IFC files in (``pip install 'pycinder[bim]'``): one body per element, through IfcOpenShell.

IFC files (IFC2X3, IFC4) -> IfcClash's element set (IfcElement minus IfcFeatureElement) ->
IfcOpenShell's geometry iterator, in parallel (world coordinates, metres, openings applied),
cached per file by content hash -> one body per element, named ``Name [GlobalId]``
(:class:`IfcModel`), and groups of them (:class:`Group`). :mod:`pycinder.bim.ifc` checks them
for clashes.

* **Several files** form one federated model (architecture, structure, MEP): their elements are
  tested against each other as one set of bodies.
* **The cache** keeps each file's tessellation under its content's SHA-256 (and the versions of
  IfcOpenShell and of this format), so a re-check after a change in one file re-tessellates only
  that file. It lives in ``$PYCINDER_CACHE_DIR/ifc``, else in the user's cache folder
  (``$XDG_CACHE_HOME/pycinder/ifc`` or ``~/.cache/pycinder/ifc``); ``cache=`` overrides it.
* **Groups** select elements by file, by IFC class (subclasses included) or by an
  IfcClash-style selector (IfcOpenShell's ``ifcopenshell.util.selector`` syntax:
  ``"IfcPipeSegment, IfcDuctSegment"``, ``"IfcElement, ! IfcWall"``,
  ``"IfcWall, Name=Wall east 0"``); see :class:`Group`.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
import time
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..util.optional import require
from .checks import (FileBody, FileError, FileErrors, FileWarning, Limits, check_file,
                     display_name, file_labels)

__all__ = ["IfcBody", "IfcModel", "IfcOpening", "Group", "read_ifc", "default_cache_dir",
           "files_are_ifc"]

SHOWN_DUPLICATES = 5
"""Most duplicated GlobalIds the warning of :func:`read_ifc` names (the model lists them all:
:meth:`IfcModel.duplicates`)."""

CACHE_FORMAT = 2
"""Version of the cache's file layout (part of every cache key): 2 adds each file's relations
(:func:`_relations`)."""

Progress = Callable[[float, int, str], None]
"""``progress(done, total, text)``: ``done`` of ``total`` steps, a fraction within a step."""


def _ifcopenshell() -> Any:
    return require("ifcopenshell", "reading IFC files", "bim")


# -- bodies and models ----------------------------------------------------------------------


@dataclass
class IfcBody(FileBody):
    """One IFC element as a body: its mesh in world coordinates (metres), and what it is.

    Attributes
    ----------
    name : str
        ``Name [GlobalId]`` (the element's class stands in for a missing Name).
    mesh : trimesh.Trimesh
        (V, 3) vertices in metres, world coordinates; (F, 3) triangles.
    transform : (4, 4) float64
        Identity: the mesh is in world coordinates already.
    units : str
        ``"m"``.
    global_id : str
        The element's GlobalId.
    ifc_class : str
        Its class, as the file names it (``IfcWall``, ``IfcPipeSegment``, ...).
    file : str
        The label of the file it comes from (the file's name, see
        :func:`~pycinder.files.file_labels`).
    element_name : str
        The element's Name attribute ("" where it has none).
    storey : str
        The name of the building storey that holds it ("" where none does).
    """

    global_id: str = ""
    ifc_class: str = ""
    file: str = ""
    element_name: str = ""
    storey: str = ""


@dataclass
class IfcOpening:
    """An opening of an element (IfcOpeningElement or another subtraction that voids it): its
    shape in world coordinates, the element it voids and the element that fills it.

    Attributes
    ----------
    file : str
        The label of its file.
    host : str
        The GlobalId of the element it voids.
    filler : str
        The GlobalId of the element that fills it ("" where none does).
    mesh : trimesh.Trimesh
        Its shape, in metres, world coordinates.
    """

    file: str
    host: str
    filler: str
    mesh: Any


@dataclass
class IfcModel:
    """A federated model: the elements of one or more IFC files, as bodies.

    Attributes
    ----------
    bodies : list of IfcBody
    files : list of str
        The files' labels, in the order given.
    paths : list of str
        The files' paths.
    schemas : dict
        File label to its schema (``"IFC4"``, ``"IFC2X3"``, ...).
    tessellated : list of str
        Labels of the files tessellated by this read (the others came from the cache).
    seconds : dict
        ``"tessellation"`` (reading and tessellating, or loading from the cache).
    relations : dict
        File label to what the file says of how its elements relate: ``"fills"``,
        ``"aggregates"``, ``"connects"`` and ``"systems"``, each (K, 2) str of GlobalIds (see
        :data:`RELATIONS`; :mod:`pycinder.bim.rules` sets clashes aside by them).
    openings : list of IfcOpening
        The elements' openings (not bodies: they are cut from their hosts), for the clash rules.
    """

    bodies: list[IfcBody]
    files: list[str]
    paths: list[str]
    schemas: dict[str, str]
    tessellated: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)
    relations: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    openings: list[IfcOpening] = field(default_factory=list)
    _opened: dict[str, Any] = field(default_factory=dict, repr=False)

    def __len__(self) -> int:
        return len(self.bodies)

    @property
    def names(self) -> list[str]:
        """The bodies' names, ``Name [GlobalId]``."""
        return [b.name for b in self.bodies]

    def duplicates(self) -> list[list[int]]:
        """Elements whose GlobalId is in more than one file: per GlobalId, the indices of its
        bodies (in the order of the bodies), for each GlobalId found in two files or more."""
        where: dict[str, list[int]] = {}
        for k, b in enumerate(self.bodies):
            where.setdefault(b.global_id, []).append(k)
        return [ks for ks in where.values()
                if len({self.bodies[k].file for k in ks}) > 1]

    def file_index(self, which: str | os.PathLike[str]) -> str:
        """The label of a file of the model, given as its label, its path or its name.

        Raises
        ------
        ValueError
            Naming the file and the model's files, when it is none of them.
        """
        text = os.fspath(which)
        for label, path in zip(self.files, self.paths):
            if text in (label, path, os.path.basename(path)) or (
                    os.path.exists(text) and os.path.exists(path)
                    and os.path.samefile(text, path)):
                return label
        raise ValueError(f"{display_name(text)}: not a file of this model (its files: "
                         f"{', '.join(self.files)})")

    def select(self, group: Group | str | None = None) -> np.ndarray:
        """(N,) bool: which bodies ``group`` selects (a :class:`Group`, or a selector string;
        None selects every body).

        Raises
        ------
        ValueError
            A file that is not the model's, or a selector IfcOpenShell cannot parse.
        """
        if group is None:
            return np.ones(len(self.bodies), dtype=bool)
        if isinstance(group, str):
            group = Group(selector=group)
        mask = np.ones(len(self.bodies), dtype=bool)
        if group.files is not None:
            labels = {self.file_index(f) for f in group.files}
            mask &= np.array([b.file in labels for b in self.bodies], dtype=bool)
        if group.selector is not None:
            mask &= self._matches(group.selector)
        if group.exclude is not None:
            mask &= ~self._matches(group.exclude)
        return mask

    def _matches(self, selector: str) -> np.ndarray:
        classes = _class_list(selector)
        if classes is not None:  # class names alone: no need to open the files
            return np.array([self._is_a(b, classes) for b in self.bodies], dtype=bool)
        ifcopenshell = _ifcopenshell()
        selector_mod = require("ifcopenshell.util.selector", "IfcClash-style selectors", "bim",
                               package="ifcopenshell")
        chosen: set[tuple[str, str]] = set()
        for label, path in zip(self.files, self.paths):
            if label not in self._opened:
                self._opened[label] = ifcopenshell.open(path)
            try:
                found = selector_mod.filter_elements(self._opened[label], selector)
            except Exception as exc:  # the selector's grammar raises lark's own errors
                raise ValueError(f"selector {selector!r}: IfcOpenShell could not use it "
                                 f"({type(exc).__name__}: {str(exc).splitlines()[0]})") from None
            chosen |= {(label, e.GlobalId) for e in found if hasattr(e, "GlobalId")}
        return np.array([(b.file, b.global_id) in chosen for b in self.bodies], dtype=bool)

    def _is_a(self, body: IfcBody, classes: Sequence[str]) -> bool:
        schema = self.schemas.get(body.file, "IFC4")
        return any(_is_subclass(schema, body.ifc_class, c) for c in classes)


_CLASS_LIST = re.compile(r"^\s*Ifc\w+(\s*,\s*Ifc\w+)*\s*$", re.IGNORECASE)


def _class_list(selector: str) -> list[str] | None:
    """The class names of a selector that is a comma-separated list of classes, else None."""
    if not _CLASS_LIST.match(selector):
        return None
    return [c.strip() for c in selector.split(",")]


_SUBCLASS: dict[tuple[str, str, str], bool] = {}


def _is_subclass(schema: str, cls: str, ancestor: str) -> bool:
    """Whether IFC class ``cls`` is ``ancestor`` or derives from it in ``schema``."""
    key = (schema, cls.lower(), ancestor.lower())
    if key not in _SUBCLASS:
        wrapper = _ifcopenshell().ifcopenshell_wrapper
        try:
            decl = wrapper.schema_by_name(schema).declaration_by_name(cls)
        except Exception:
            decl = None
        answer = False
        while decl is not None:
            if decl.name().lower() == ancestor.lower():
                answer = True
                break
            decl = decl.supertype()
        _SUBCLASS[key] = answer
    return _SUBCLASS[key]


@dataclass(frozen=True)
class Group:
    """One side of a clash set: elements chosen by file and by selector.

    Parameters
    ----------
    files : sequence of str, optional
        The files whose elements are in the group (labels, paths or names); default: every file.
    selector : str, optional
        IfcClash-style selector of the elements included (``"IfcPipeSegment,
        IfcDuctSegment"``; IFC classes include their subclasses); default: every element.
    exclude : str, optional
        Selector of elements left out (IfcClash's exclude mode).

    Examples
    --------
    >>> from pycinder.bim.ifc import Group
    >>> Group(files=["mep.ifc"], selector="IfcPipeSegment, IfcDuctSegment")
    Group(files=('mep.ifc',), selector='IfcPipeSegment, IfcDuctSegment', exclude=None)
    """

    files: tuple[str, ...] | None = None
    selector: str | None = None
    exclude: str | None = None

    def __post_init__(self) -> None:
        if self.files is not None:
            if isinstance(self.files, (str, os.PathLike)):
                object.__setattr__(self, "files", (os.fspath(self.files),))
            else:
                object.__setattr__(self, "files", tuple(os.fspath(f) for f in self.files))

    def describe(self) -> str:
        """The group in words, for reports: ``"IfcBeam, IfcColumn in structure.ifc"``."""
        what = self.selector or "every element"
        if self.exclude:
            what += f" except {self.exclude}"
        if self.files is not None:
            what += " in " + ", ".join(self.files)
        return what


# -- reading --------------------------------------------------------------------------------


def default_cache_dir() -> Path:
    """Where tessellations are cached: ``$PYCINDER_CACHE_DIR/ifc``, else
    ``$XDG_CACHE_HOME/pycinder/ifc``, else ``~/.cache/pycinder/ifc``."""
    if os.environ.get("PYCINDER_CACHE_DIR"):
        return Path(os.environ["PYCINDER_CACHE_DIR"]) / "ifc"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "pycinder" / "ifc"


def _settings(ifcopenshell: Any) -> Any:
    import ifcopenshell.geom  # noqa: F401  (a submodule of the module required)

    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)  # metres (IfcOpenShell converts to SI by default)
    settings.set("weld-vertices", True)  # closed solids come out closed
    return settings


def _digest(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 22):
            h.update(chunk)
    return h.hexdigest()


def _cache_key(digest: str, version: str) -> str:
    return hashlib.sha256(f"{digest}:{version}:{CACHE_FORMAT}".encode()).hexdigest()[:40]


RELATIONS = ("fills", "aggregates", "connects", "systems")
"""The relations read from each file (:func:`_relations`): each an array of GlobalId pairs."""


def _gid_pairs(pairs: Iterable[tuple[Any, Any]]) -> np.ndarray:
    """(K, 2) str: the GlobalIds of pairs of entities (each once, in order found)."""
    out = dict.fromkeys((a.GlobalId, b.GlobalId) for a, b in pairs
                        if a is not None and b is not None and a != b
                        and hasattr(a, "GlobalId") and hasattr(b, "GlobalId"))
    return np.array(list(out), dtype=str).reshape(-1, 2)


def _by_type(f: Any, name: str) -> list[Any]:
    """The file's entities of a class, none where its schema lacks the class."""
    try:
        return list(f.by_type(name))
    except RuntimeError:
        return []


def _relations(f: Any) -> dict[str, np.ndarray]:
    """What a file says of how its elements relate, as GlobalId pairs (K, 2) str:

    * ``fills``: an element filling an opening (IfcRelFillsElement) and the element the
      opening voids (IfcRelVoidsElement): a door and its wall;
    * ``aggregates``: a part and the element it is part of (IfcRelAggregates whose whole is
      an element, not a storey or a building): a flight and its stair, a plate and its curtain
      wall;
    * ``connects``: elements the file connects (IfcRelConnectsElements and its subclasses, such
      as walls joined at their ends by IfcRelConnectsPathElements; and elements whose ports are
      connected, IfcRelConnectsPorts);
    * ``systems``: an element and the system it is assigned to (IfcRelAssignsToGroup to an
      IfcSystem, IfcDistributionSystem, IfcBuildingSystem ...).

    And ``storeys``, (K, 2) str: an element and the name of the building storey that holds it
    (IfcRelContainedInSpatialStructure, or that of the element it is part of).
    """
    host = {rel.RelatedOpeningElement: rel.RelatingBuildingElement
            for rel in _by_type(f, "IfcRelVoidsElement")}
    fills = [(rel.RelatedBuildingElement, host.get(rel.RelatingOpeningElement))
             for rel in _by_type(f, "IfcRelFillsElement")]
    aggregates = [(part, rel.RelatingObject) for rel in _by_type(f, "IfcRelAggregates")
                  if rel.RelatingObject.is_a("IfcElement") for part in rel.RelatedObjects]
    connects = [(rel.RelatingElement, rel.RelatedElement)
                for rel in _by_type(f, "IfcRelConnectsElements")]
    port_of: dict[Any, Any] = {}
    for rel in _by_type(f, "IfcRelConnectsPortToElement"):
        port_of[rel.RelatingPort] = rel.RelatedElement
    for rel in _by_type(f, "IfcRelNests"):
        if rel.RelatingObject.is_a("IfcElement"):
            for part in rel.RelatedObjects:
                if part.is_a("IfcPort"):
                    port_of[part] = rel.RelatingObject
    connects += [(port_of.get(rel.RelatingPort), port_of.get(rel.RelatedPort))
                 for rel in _by_type(f, "IfcRelConnectsPorts")]
    systems = [(member, rel.RelatingGroup) for rel in _by_type(f, "IfcRelAssignsToGroup")
               if rel.RelatingGroup.is_a("IfcSystem") for member in rel.RelatedObjects
               if member.is_a("IfcElement")]
    whole = {part: parent for part, parent in aggregates}
    storey: dict[str, str] = {}
    for rel in _by_type(f, "IfcRelContainedInSpatialStructure"):
        structure = rel.RelatingStructure
        if structure.is_a("IfcBuildingStorey"):
            for item in rel.RelatedElements:
                storey[item.GlobalId] = structure.Name or structure.GlobalId
    for part in whole:  # a part is where its whole is
        top, seen = part, set()
        while top in whole and top not in seen:
            seen.add(top)
            top = whole[top]
        if top.GlobalId in storey and part.GlobalId not in storey:
            storey[part.GlobalId] = storey[top.GlobalId]
    return {"fills": _gid_pairs(fills), "aggregates": _gid_pairs(aggregates),
            "connects": _gid_pairs(connects), "systems": _gid_pairs(systems),
            "storeys": np.array(list(storey.items()), dtype=str).reshape(-1, 2)}


def _shapes(ifcopenshell: Any, f: Any, products: Iterable[Any], threads: int,
            said: Callable[[int], None] | None = None
            ) -> tuple[list[int], list[np.ndarray], list[np.ndarray]]:
    """IfcOpenShell's geometry iterator over ``products`` of file ``f`` (world coordinates,
    metres, openings applied): the ids of those with faces, in the file's order whatever the
    threads', and their vertices (V, 3) float64 and faces (F, 3) int64. ``said(count)`` after
    each shape."""
    import ifcopenshell.geom

    products = list(products)
    if not products:
        return [], [], []
    it = ifcopenshell.geom.iterator(_settings(ifcopenshell), f, max(threads, 1),
                                    include=products)
    verts, faces, ids = [], [], []
    if it.initialize():
        while True:
            shape = it.get()
            v = np.asarray(shape.geometry.verts, np.float64).reshape(-1, 3)
            t = np.asarray(shape.geometry.faces, np.int64).reshape(-1, 3)
            if len(t):
                verts.append(v)
                faces.append(t)
                ids.append(shape.id)
            if said is not None:
                said(len(ids))
            if not it.next():
                break
    order = np.argsort(ids, kind="stable")
    return [ids[k] for k in order], [verts[k] for k in order], [faces[k] for k in order]


def _openings(ifcopenshell: Any, f: Any, threads: int) -> dict[str, np.ndarray]:
    """The file's openings (IfcOpeningElement and the other subtractions that void an element,
    IfcRelVoidsElement), tessellated, each with the GlobalId of the element it voids and of the
    element that fills it ("" where none does): ``opening_vertices`` (V, 3), ``opening_faces``
    (F, 3), their offsets, ``opening_hosts`` and ``opening_fillers`` (O,) str, for the clash
    rules (:mod:`pycinder.bim.rules`)."""
    host = {rel.RelatedOpeningElement: rel.RelatingBuildingElement
            for rel in _by_type(f, "IfcRelVoidsElement")}
    filler = {rel.RelatingOpeningElement: rel.RelatedBuildingElement
              for rel in _by_type(f, "IfcRelFillsElement")}
    ids, verts, faces = _shapes(ifcopenshell, f, host, threads)
    openings = [f.by_id(i) for i in ids]
    return {
        "opening_vertices": (np.concatenate(verts) if verts else np.zeros((0, 3))),
        "opening_faces": (np.concatenate(faces) if faces else np.zeros((0, 3))).astype(np.int32),
        "opening_vertex_offsets": np.cumsum([0] + [len(v) for v in verts]),
        "opening_face_offsets": np.cumsum([0] + [len(t) for t in faces]),
        "opening_hosts": np.array([host[o].GlobalId for o in openings], dtype=str),
        "opening_fillers": np.array([filler[o].GlobalId if o in filler else "" for o in openings],
                                    dtype=str)}


def _tessellate(path: str, label: str, threads: int, progress: Progress | None,
                step: tuple[int, int]) -> dict[str, np.ndarray]:
    """One file's element set, tessellated: concatenated arrays (see :func:`_bodies_of`)."""
    ifcopenshell = _ifcopenshell()

    try:
        f = ifcopenshell.open(path)
    except Exception as exc:
        raise FileError(f"{label}: could not read it as IFC ({type(exc).__name__}: "
                        f"{str(exc).splitlines()[0] if str(exc) else 'no reason given'})"
                        ) from None
    try:
        elements = set(f.by_type("IfcElement")) - set(f.by_type("IfcFeatureElement"))
    except RuntimeError as exc:
        raise FileError(f"{label}: schema {f.schema} has no IfcElement ({exc})") from None
    if not elements:
        raise FileError(f"{label}: holds no elements (IfcElement other than IfcFeatureElement)")
    done0, steps = step
    total = len(elements)

    def said(count: int) -> None:
        if progress and count % 64 == 0:
            progress(done0 + count / total, steps,
                     f"tessellating {label}: {count:,} of {total:,} elements")

    ids, verts, faces = _shapes(ifcopenshell, f, elements, threads, said)
    if not ids:
        raise FileError(f"{label}: none of its {total:,} elements has body geometry")
    entities = [f.by_id(i) for i in ids]
    v_off = np.cumsum([0] + [len(v) for v in verts])
    f_off = np.cumsum([0] + [len(t) for t in faces])
    openings = _openings(ifcopenshell, f, threads)
    return {
        "vertices": np.concatenate(verts), "faces": np.concatenate(faces).astype(np.int32),
        "vertex_offsets": v_off, "face_offsets": f_off,
        "global_ids": np.array([e.GlobalId for e in entities], dtype=str),
        "classes": np.array([e.is_a() for e in entities], dtype=str),
        "names": np.array([e.Name or "" for e in entities], dtype=str),
        "schema": np.array(f.schema), "left_out": np.array(total - len(ids)),
        **{f"relation_{k}": v for k, v in _relations(f).items()},
        **openings,
    }


def _bodies_of(data: dict[str, np.ndarray], label: str) -> list[IfcBody]:
    import trimesh

    out = []
    v_off, f_off = data["vertex_offsets"], data["face_offsets"]
    verts, faces = data["vertices"], data["faces"]
    storeys = dict(data["relation_storeys"].tolist())
    for k, (gid, cls, name) in enumerate(zip(data["global_ids"].tolist(),
                                             data["classes"].tolist(),
                                             data["names"].tolist())):
        v = verts[v_off[k]:v_off[k + 1]]
        t = faces[f_off[k]:f_off[k + 1]]
        mesh = trimesh.Trimesh(v, t, process=False)
        out.append(IfcBody(f"{name or cls} [{gid}]", mesh, np.eye(4), "m", global_id=gid,
                           ifc_class=cls, file=label, element_name=name,
                           storey=storeys.get(gid, "")))
    return out


def _openings_of(data: dict[str, np.ndarray], label: str) -> list[IfcOpening]:
    import trimesh

    v_off, f_off = data["opening_vertex_offsets"], data["opening_face_offsets"]
    verts, faces = data["opening_vertices"], data["opening_faces"]
    return [IfcOpening(label, host, filler,
                       trimesh.Trimesh(verts[v_off[k]:v_off[k + 1]],
                                       faces[f_off[k]:f_off[k + 1]], process=False))
            for k, (host, filler) in enumerate(zip(data["opening_hosts"].tolist(),
                                                   data["opening_fillers"].tolist()))]


def _read_one(path: str, label: str, cache: Path | None, threads: int, limits: Limits,
              progress: Progress | None, step: tuple[int, int]) -> tuple[dict, bool]:
    """A file's tessellation from the cache, or made (and cached); and whether it was made."""
    if check_file(path, label, limits) != "ifc":  # missing, empty, too large, not STEP ...
        raise FileError(f"{label}: is not an IFC file (its name does not end in .ifc)")
    ifcopenshell = _ifcopenshell()
    entry = None
    if cache is not None:
        entry = cache / f"{_cache_key(_digest(path), ifcopenshell.version)}.npz"
        if entry.exists():
            try:
                with np.load(entry, allow_pickle=False) as z:
                    return {k: z[k] for k in z.files}, False
            except (OSError, ValueError, KeyError):
                pass  # a damaged entry is made again
    if progress:
        progress(step[0], step[1], f"tessellating {label}")
    data = _tessellate(path, label, threads, progress, step)
    if len(data["faces"]) > limits.max_triangles:
        raise FileError(f"{label}: holds {len(data['faces']):,} triangles, over the limit of "
                        f"{limits.max_triangles:,} (--max-triangles)")
    if entry is not None:
        entry.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=entry.parent, suffix=".tmp.npz")
        os.close(fd)
        try:
            np.savez(tmp, **data)
            os.replace(tmp, entry)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    return data, True


def read_ifc(paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]], *,
             cache: str | os.PathLike[str] | bool | None = None, threads: int | None = None,
             progress: Progress | None = None, limits: Limits | None = None) -> IfcModel:
    """Read IFC files (IFC2X3, IFC4) as one federated model, one body per element.

    The elements are IfcClash's default set: every IfcElement that is not an IfcFeatureElement
    (openings, projections) and has body geometry. IfcOpenShell's geometry iterator tessellates
    them in parallel, in world coordinates and metres, with openings applied.

    Parameters
    ----------
    paths : path or sequence of paths
    cache : path, bool or None
        Folder of the tessellation cache; None or True: :func:`default_cache_dir`; False: no
        cache (every file is tessellated).
    threads : int, optional
        Tessellation threads (default: the CPU count).
    progress : callable, optional
        Called as ``progress(done, total, text)`` while files are read and tessellated: ``done``
        of ``total`` files, with the fraction of a file's elements tessellated so far.
    limits : Limits, optional
        Largest file in bytes and most triangles per file (default
        :class:`~pycinder.files.Limits`).

    Returns
    -------
    IfcModel

    Raises
    ------
    FileErrors
        Naming every file that cannot be used (missing, not IFC, no elements with geometry,
        over a limit), one message per file.
    ImportError
        Without ifcopenshell (``pip install 'pycinder[bim]'``).

    Examples
    --------
    .. code-block:: python

        model = read_ifc(["architecture.ifc", "structure.ifc", "mep.ifc"])
        model.bodies[0].name, model.bodies[0].ifc_class   # ('Wall east 0 [2qXY...]', 'IfcWall')
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    paths = [os.fspath(p) for p in paths]
    if not paths:
        raise ValueError("read_ifc needs at least one IFC file")
    _ifcopenshell()
    folder = None if cache is False else (default_cache_dir() if cache in (None, True)
                                          else Path(os.fspath(cache)))  # type: ignore[arg-type]
    limits = limits or Limits()
    threads = threads or os.cpu_count() or 1
    labels = file_labels(paths)
    bodies: list[IfcBody] = []
    errors: list[str] = []
    schemas: dict[str, str] = {}
    relations: dict[str, dict[str, np.ndarray]] = {}
    openings: list[IfcOpening] = []
    made: list[str] = []
    t0 = time.perf_counter()
    for k, (path, label) in enumerate(zip(paths, labels)):
        if progress:
            progress(k, len(paths), f"reading {label}")
        try:
            data, was_made = _read_one(path, label, folder, threads, limits, progress,
                                       (k, len(paths)))
        except (FileError, ImportError) as exc:
            errors.append(str(exc))
            continue
        if was_made:
            made.append(label)
        schemas[label] = str(data["schema"])
        relations[label] = {k: data[f"relation_{k}"] for k in RELATIONS}
        openings += _openings_of(data, label)
        bodies += _bodies_of(data, label)
    if errors:
        raise FileErrors(errors)
    model = IfcModel(bodies, labels, paths, schemas, made,
                     {"tessellation": time.perf_counter() - t0}, relations, openings)
    twice = model.duplicates()
    if twice:
        shown = "; ".join(f"{model.bodies[group[0]].name} in "
                          f"{', '.join(model.bodies[k].file for k in group)}"
                          for group in twice[:SHOWN_DUPLICATES])
        more = (f"; and {len(twice) - SHOWN_DUPLICATES} more" if len(twice) > SHOWN_DUPLICATES
                else "")
        warnings.warn(f"{len(twice)} GlobalIds are in more than one file ({shown}{more}): "
                      "each copy is a body of its own, and the duplicates rule (on by default) "
                      "reports them apart rather than tested against each other",
                      FileWarning, stacklevel=2)
    return model


def load_file(path: str, label: str, limits: Limits = Limits()) -> list[FileBody]:
    """One IFC file's elements as bodies, for :func:`pycinder.files.load_file` (cached as
    :func:`read_ifc` caches them)."""
    try:
        data, _ = _read_one(path, label, default_cache_dir(), os.cpu_count() or 1, limits,
                            None, (0, 1))
    except ImportError as exc:
        raise ImportError(f"{label}: {exc}") from None
    return list(_bodies_of(data, label))


# -- clashes --------------------------------------------------------------------------------


def files_are_ifc(paths: Iterable[str | os.PathLike[str]]) -> list[bool]:
    """Which of ``paths`` name IFC files (by their extension, ``.ifc``)."""
    return [os.fspath(p).lower().endswith(".ifc") for p in paths]
