"""BCF out: clashes as a BCF 2.1 file, one topic per group of clashes
(``pip install 'pycinder[bim]'``).

Each topic is a group of clashes (:func:`pycinder.bim.groups.group_clashes`; without groups, a
topic per clash). It is titled after its first clash's elements (``IfcPipeSegment/Pipe 0 and
IfcBeam/Beam south``), as IfcClash titles them, with ``(+n clashes)`` for a group of more; its
description lists its clashes, a line each (``- A <-> B [new]: ...``: both GlobalIds, the
status, both elements and the depth or distance with the bound on its error), which
:func:`pycinder.bim.tracking.read_previous` reads back. Its status is a label (``new``,
``active`` or ``resolved``, :mod:`pycinder.bim.tracking`) and its TopicStatus (``Open``, or
``Closed`` for resolved). Its GUID is stable (:func:`pycinder.bim.groups.topic_guid`), so a
viewer updates its topics from one run to the next. Its viewpoint selects every element of the
group, colours them as the snapshot does (``a`` red, ``b`` blue) and holds a perspective camera:
the snapshot's (:mod:`pycinder.bim.snapshot`) where there is one, else one looking at the group
from above and to the side. Written with bcf-client (IfcOpenShell's BCF library) where it is
installed; otherwise by a small writer of BCF 2.1's own files (``bcf.version``,
``project.bcfp``, and per topic ``markup.bcf``, ``viewpoint.bcfv`` and ``snapshot.png``).
"""

from __future__ import annotations

import os
import uuid
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from .groups import GUID_NAMESPACE, ClashGroup, group_clashes, pair_key
from .snapshot import COLOUR_A, COLOUR_B, Camera, group_camera

__all__ = ["write_bcf", "read_bcf_guids"]


def _description(c: Any) -> str:
    text = f"{c.a.name} ({c.a.file}) clashes with {c.b.name} ({c.b.file})"
    for name in ("depth", "distance"):
        figure, bound = getattr(c, name, None), getattr(c, f"{name}_error", None)
        if figure is not None:
            text += f"; {name} {figure:.4g} m"
            if bound is not None:
                text += f" (error at most {bound:.2g} m)"
    return text + f"; mode: {c.mode}"


def _hex(colour: Sequence[float]) -> str:
    return "".join(f"{round(255 * x):02X}" for x in colour)


@dataclass
class _Topic:
    """What one topic holds, for either writer."""

    guid: str
    title: str
    description: str
    status: str
    selected: list[str] = field(default_factory=list)
    colours: dict[str, list[str]] = field(default_factory=dict)
    camera: Camera | None = None
    snapshot: bytes | None = None

    @property
    def topic_status(self) -> str:
        return "Closed" if self.status == "resolved" else "Open"

    @property
    def viewpoint_guid(self) -> str:
        return str(uuid.uuid5(GUID_NAMESPACE, f"{self.guid}/viewpoint"))


def _group_topic(g: ClashGroup, statuses: Mapping[tuple[str, str], str],
                 snapshot: tuple[bytes, Camera] | None) -> _Topic:
    lines = [f"{len(g.clashes)} clash{'es' if len(g.clashes) > 1 else ''} "
             f"(group {g.index}, {g.status})"]
    for c in g.clashes:
        key = pair_key(c.a.global_id, c.b.global_id)
        lines.append(f"- {c.a.global_id} <-> {c.b.global_id} [{statuses.get(key, 'new')}]: "
                     f"{_description(c)}")
    if g.resolved:
        lines.append("Resolved since the previous run:")
        lines += [f"- resolved: {a} <-> {b}" for a, b in g.resolved]
    elements = g.elements
    a_ids = list(dict.fromkeys(c.a.global_id for c in g.clashes))
    b_ids = [x for x in dict.fromkeys(c.b.global_id for c in g.clashes) if x not in a_ids]
    png, camera = snapshot if snapshot is not None else (None, None)
    if camera is None:
        camera = group_camera(elements)
    return _Topic(g.guid, g.title(), "\n".join(lines), g.status,
                  [b.global_id for b in elements], {_hex(COLOUR_A): a_ids, _hex(COLOUR_B): b_ids},
                  camera, png)


def _topics(clashes: Sequence[Any], groups: Sequence[ClashGroup] | None, tracking: Any,
            snapshots: Mapping[int, tuple[bytes, Camera]] | None,
            notes: Sequence[str] = ()) -> list[_Topic]:
    if groups is None:
        groups = group_clashes(clashes, None)
    statuses = tracking.clashes if tracking is not None else {}
    out = [_group_topic(g, statuses, (snapshots or {}).get(g.index)) for g in groups]
    for t in out:
        t.description = "\n".join([t.description, *notes])
    for t in getattr(tracking, "closed", []):
        lines = ["Resolved since the previous run:"]
        lines += [f"- resolved: {a} <-> {b}: {what}" for (a, b), what in t.pairs.items()]
        out.append(_Topic(t.guid, t.title, "\n".join(lines), "resolved"))
    return out


def write_bcf(clashes: Sequence[Any], path: str | os.PathLike[str], *,
              groups: Sequence[ClashGroup] | None = None, tracking: Any = None,
              snapshots: Mapping[int, tuple[bytes, Camera]] | None = None,
              project: str = "pycinder clashes", author: str = "pycinder",
              writer: str = "auto", notes: Sequence[str] = ()) -> Path:
    """Write clashes as a BCF 2.1 file: a topic per group.

    Parameters
    ----------
    clashes : sequence of Clash
        From :func:`pycinder.bim.ifc.find_clashes`.
    path : str or path-like
        The ``.bcf`` file (replaced if it exists).
    groups : sequence of ClashGroup, optional
        From :func:`pycinder.bim.groups.group_clashes` (of ``clashes``); default: a group, and
        a topic, per clash.
    tracking : Tracking, optional
        From :func:`pycinder.bim.tracking.track` on ``groups``: each clash's status in its
        line, and a closed topic for each of the previous run's topics that no group
        continues.
    snapshots : mapping, optional
        A group's :attr:`~pycinder.bim.groups.ClashGroup.index` to its picture (PNG bytes) and
        camera (:meth:`pycinder.bim.snapshot.Snapshotter.group`): the viewpoint's snapshot and
        camera. A group without one gets a camera looking at it, and no snapshot.
    project : str
        The BCF project's name.
    author : str
        Each topic's author.
    writer : {"auto", "bcf-client", "builtin"}
        ``"auto"``: bcf-client where installed, else the built-in writer.
    notes : sequence of str
        Lines that end every group's topic description: how the run was made (its clash rules
        and what they set aside, :meth:`~pycinder.bim.rules.SetAside.summary`).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ImportError
        ``writer="bcf-client"`` without bcf-client.
    ValueError
        An unknown ``writer``.
    """
    path = Path(path)
    if writer not in ("auto", "bcf-client", "builtin"):
        raise ValueError(f"writer must be 'auto', 'bcf-client' or 'builtin', got {writer!r}")
    topics = _topics(clashes, groups, tracking, snapshots, notes)
    if writer != "builtin":
        try:
            from bcf.v2.bcfxml import BcfXml
        except ImportError:
            if writer == "bcf-client":
                from ..util.optional import require

                require("bcf.v2.bcfxml", "writing BCF with bcf-client", "bim",
                        package="bcf-client")
            BcfXml = None
        if BcfXml is not None:
            return _write_bcf_client(BcfXml, topics, path, project, author)
    return _write_builtin(topics, path, project, author)


def _write_bcf_client(BcfXml: Any, topics: Sequence[_Topic], path: Path, project: str,
                      author: str) -> Path:
    from bcf.v2 import model as mdl
    from bcf.v2.topic import TopicHandler
    from bcf.v2.visinfo import VisualizationInfoHandler
    from xsdata.models.datatype import XmlDateTime

    bcfxml = BcfXml.create_new(project)
    now = XmlDateTime.from_datetime(datetime.now(timezone.utc))
    for t in topics:
        handler = TopicHandler(topic_dir=Path(t.guid))
        handler.markup = mdl.Markup(topic=mdl.Topic(
            guid=t.guid, title=t.title, description=t.description, creation_author=author,
            creation_date=now, topic_type="Clash", topic_status=t.topic_status,
            labels=[t.status]))
        bcfxml.topics[t.guid] = handler
        if t.camera is None:
            continue
        cam = t.camera
        components = mdl.Components(
            selection=mdl.ComponentSelection(
                component=[mdl.Component(ifc_guid=g) for g in t.selected]),
            visibility=mdl.ComponentVisibility(default_visibility=True),
            coloring=mdl.ComponentColoring(color=[
                mdl.ComponentColoringColor(color=colour,
                                           component=[mdl.Component(ifc_guid=g) for g in ids])
                for colour, ids in t.colours.items() if ids]))
        info = mdl.VisualizationInfo(
            guid=t.viewpoint_guid, components=components,
            perspective_camera=mdl.PerspectiveCamera(
                camera_view_point=mdl.Point(**_xyz_of(cam.position)),
                camera_direction=mdl.Direction(**_xyz_of(cam.direction)),
                camera_up_vector=mdl.Direction(**_xyz_of(cam.up)),
                field_of_view=float(cam.fov)))
        handler.add_visinfo_handler(VisualizationInfoHandler(info, snapshot=t.snapshot),
                                    "snapshot.png" if t.snapshot else None)
    if path.exists():
        path.unlink()
    bcfxml.save(path)
    bcfxml.close()
    return path


def _xyz_of(v: np.ndarray) -> dict[str, float]:
    return {"x": float(v[0]), "y": float(v[1]), "z": float(v[2])}


def _xyz(tag: str, v: np.ndarray) -> str:
    return (f"<{tag}><X>{v[0]:.6f}</X><Y>{v[1]:.6f}</Y><Z>{v[2]:.6f}</Z></{tag}>")


def _component(g: str) -> str:
    return f"<Component IfcGuid={quoteattr(g)} />"


def _write_builtin(topics: Sequence[_Topic], path: Path, project: str, author: str) -> Path:
    now = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S+00:00")
    head = '<?xml version="1.0" encoding="UTF-8"?>\n'
    tmp = path.with_name(path.name + ".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("bcf.version", head + '<Version VersionId="2.1"><DetailedVersion>2.1'
                                         "</DetailedVersion></Version>")
        z.writestr("project.bcfp", head + f'<ProjectExtension><Project ProjectId='
                                          f'"{uuid.uuid4()}"><Name>{escape(project)}</Name>'
                                          "</Project><ExtensionSchema></ExtensionSchema>"
                                          "</ProjectExtension>")
        for t in topics:
            view = t.viewpoint_guid
            viewpoints = "" if t.camera is None else (
                f"<Viewpoints Guid={quoteattr(view)}><Viewpoint>viewpoint.bcfv</Viewpoint>"
                + ("<Snapshot>snapshot.png</Snapshot>" if t.snapshot else "")
                + "</Viewpoints>")
            z.writestr(f"{t.guid}/markup.bcf", head + (
                f"<Markup><Topic Guid={quoteattr(t.guid)} TopicType=\"Clash\" "
                f"TopicStatus={quoteattr(t.topic_status)}>"
                f"<Title>{escape(t.title)}</Title><Labels>{escape(t.status)}</Labels>"
                f"<CreationDate>{now}</CreationDate>"
                f"<CreationAuthor>{escape(author)}</CreationAuthor>"
                f"<Description>{escape(t.description)}</Description></Topic>"
                f"{viewpoints}</Markup>"))
            if t.camera is None:
                continue
            if t.snapshot:
                z.writestr(f"{t.guid}/snapshot.png", t.snapshot)
            cam = t.camera
            colours = "".join(f"<Color Color={quoteattr(colour)}>"
                              + "".join(_component(g) for g in ids) + "</Color>"
                              for colour, ids in t.colours.items() if ids)
            colouring = f"<Coloring>{colours}</Coloring>" if colours else ""
            z.writestr(f"{t.guid}/viewpoint.bcfv", head + (
                f"<VisualizationInfo Guid={quoteattr(view)}><Components>"
                f"<Selection>{''.join(_component(g) for g in t.selected)}</Selection>"
                f'<Visibility DefaultVisibility="true" />{colouring}</Components>'
                f"<PerspectiveCamera>{_xyz('CameraViewPoint', cam.position)}"
                f"{_xyz('CameraDirection', cam.direction)}{_xyz('CameraUpVector', cam.up)}"
                f"<FieldOfView>{cam.fov:g}</FieldOfView></PerspectiveCamera>"
                "</VisualizationInfo>"))
    os.replace(tmp, path)
    return path


def read_bcf_guids(path: str | os.PathLike[str]) -> list[tuple[str, list[str]]]:
    """Each topic's title and its viewpoints' selected GlobalIds, read from the BCF file's XML
    (any BCF 2.x writer's).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    list of (str, list of str)
        Per topic, in the archive's order: its title and the GlobalIds of its viewpoints'
        selected components.
    """
    import xml.etree.ElementTree as ET

    def local(tag: str) -> str:
        return tag.rsplit("}", 1)[-1]

    out = []
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
        for name in names:
            if not name.endswith("/markup.bcf"):
                continue
            folder = name[: -len("markup.bcf")]
            markup = ET.fromstring(z.read(name))
            title = next((e.text or "" for e in markup.iter() if local(e.tag) == "Title"), "")
            guids: list[str] = []
            for e in markup.iter():
                if local(e.tag) == "Viewpoint" and e.text and folder + e.text in names:
                    view = ET.fromstring(z.read(folder + e.text))
                    for selection in view.iter():
                        if local(selection.tag) == "Selection":
                            guids += [comp.get("IfcGuid", "") for comp in selection
                                      if local(comp.tag) == "Component"]
            out.append((title, guids))
    return out
