"""BCF out: clashes as a BCF 2.1 file, one topic per clash (``pip install 'pycinder[bim]'``).

Each topic is titled after both elements (``IfcPipeSegment/Pipe 0 and IfcBeam/Beam south``), as
IfcClash titles them, and holds one viewpoint looking at the clash's point with both elements'
GlobalIds as its selected components, as IfcClash and Navisworks export them; the depth or
distance, where the mode gives one, is in the description with the bound on its error. Written
with bcf-client (IfcOpenShell's BCF library) where it is installed; otherwise by a small writer
of BCF 2.1's own files (``bcf.version``, ``project.bcfp``, and per topic ``markup.bcf`` and
``viewpoint.bcfv``).
"""

from __future__ import annotations

import os
import uuid
import zipfile
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape, quoteattr

import numpy as np

__all__ = ["write_bcf", "read_bcf_guids"]


def _title(c: Any) -> str:
    return (f"{c.a.ifc_class}/{c.a.element_name or c.a.global_id} and "
            f"{c.b.ifc_class}/{c.b.element_name or c.b.global_id}")


def _description(c: Any) -> str:
    text = f"{c.a.name} ({c.a.file}) clashes with {c.b.name} ({c.b.file})"
    for name in ("depth", "distance"):
        figure, bound = getattr(c, name, None), getattr(c, f"{name}_error", None)
        if figure is not None:
            text += f"; {name} {figure:.4g} m"
            if bound is not None:
                text += f" (error at most {bound:.2g} m)"
    return text + f"; mode: {c.mode}"


def write_bcf(clashes: Sequence[Any], path: str | os.PathLike[str], *,
              project: str = "pycinder clashes", author: str = "pycinder",
              writer: str = "auto") -> Path:
    """Write clashes as a BCF 2.1 file.

    Parameters
    ----------
    clashes : sequence of Clash
        From :func:`pycinder.bim.ifc.find_clashes`.
    path : str or path-like
        The ``.bcf`` file (replaced if it exists).
    project : str
        The BCF project's name.
    author : str
        Each topic's author.
    writer : {"auto", "bcf-client", "builtin"}
        ``"auto"``: bcf-client where installed, else the built-in writer.

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
            return _write_bcf_client(BcfXml, clashes, path, project, author)
    return _write_builtin(clashes, path, project, author)


def _write_bcf_client(BcfXml: Any, clashes: Sequence[Any], path: Path, project: str,
                      author: str) -> Path:
    bcfxml = BcfXml.create_new(project)
    for c in clashes:
        topic = bcfxml.add_topic(_title(c), _description(c), author, "Clash")
        topic.add_viewpoint_from_point_and_guids(np.asarray(c.point, np.float64),
                                                 c.a.global_id, c.b.global_id)
    if path.exists():
        path.unlink()
    bcfxml.save(path)
    bcfxml.close()
    return path


def _camera(point: np.ndarray, distance: float = 5.0) -> tuple[np.ndarray, np.ndarray,
                                                               np.ndarray]:
    """A camera looking at ``point`` from above and to the side (bcf-client's choice):
    its position, direction and up vector."""
    direction = np.array([-1.0, -1.0, -1.0]) / np.sqrt(3.0)
    up = np.array([-1.0, -1.0, 2.0]) / np.sqrt(6.0)
    return point - distance * direction, direction, up


def _xyz(tag: str, v: np.ndarray) -> str:
    return (f"<{tag}><X>{v[0]:.6f}</X><Y>{v[1]:.6f}</Y><Z>{v[2]:.6f}</Z></{tag}>")


def _write_builtin(clashes: Sequence[Any], path: Path, project: str, author: str) -> Path:
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
        for c in clashes:
            topic, view = str(uuid.uuid4()), str(uuid.uuid4())
            z.writestr(f"{topic}/markup.bcf", head + (
                f"<Markup><Topic Guid={quoteattr(topic)} TopicType=\"Clash\">"
                f"<Title>{escape(_title(c))}</Title><CreationDate>{now}</CreationDate>"
                f"<CreationAuthor>{escape(author)}</CreationAuthor>"
                f"<Description>{escape(_description(c))}</Description></Topic>"
                f"<Viewpoints Guid={quoteattr(view)}><Viewpoint>viewpoint.bcfv</Viewpoint>"
                "</Viewpoints></Markup>"))
            position, direction, up = _camera(np.asarray(c.point, np.float64))
            components = "".join(f"<Component IfcGuid={quoteattr(g)} />"
                                 for g in (c.a.global_id, c.b.global_id))
            z.writestr(f"{topic}/viewpoint.bcfv", head + (
                f"<VisualizationInfo Guid={quoteattr(view)}><Components>"
                f"<Selection>{components}</Selection>"
                '<Visibility DefaultVisibility="true" /></Components>'
                f"<PerspectiveCamera>{_xyz('CameraViewPoint', position)}"
                f"{_xyz('CameraDirection', direction)}{_xyz('CameraUpVector', up)}"
                "<FieldOfView>60</FieldOfView></PerspectiveCamera></VisualizationInfo>"))
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
