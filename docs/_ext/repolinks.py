"""Links from the docs to files of the repository outside ``docs/`` (``../benchmarks/README.md``).

Pages link to such files with relative paths, which work where the Markdown is read on a forge.
In the HTML they become links to the same file: on the project's source repository when the
installed metadata names one (``Project-URL: Source``), else relative to the built page, which
reaches the file in a checkout.
"""

from __future__ import annotations

import os
from importlib import metadata
from pathlib import Path

from docutils import nodes
from sphinx import addnodes
from sphinx.transforms import SphinxTransform


def _source_url() -> str | None:
    try:
        urls = metadata.metadata("pycinder").get_all("Project-URL") or []
    except metadata.PackageNotFoundError:
        return None
    for entry in urls:
        label, _, url = entry.partition(",")
        if label.strip().lower() in ("source", "repository", "source code"):
            return url.strip().rstrip("/") + "/blob/main"
    return None


class RepositoryLinks(SphinxTransform):
    """Turn links to files outside the source folder into plain references."""

    default_priority = 5

    def apply(self, **kwargs: object) -> None:
        srcdir = Path(self.env.srcdir).resolve()
        root = srcdir.parent
        docdir = (srcdir / self.env.docname).parent
        base = _source_url()
        for node in list(self.document.findall(addnodes.pending_xref)) + list(
                self.document.findall(addnodes.download_reference)):
            if node.get("reftype") != "myst":
                continue
            target = str(node["reftarget"]).split("#", 1)[0]
            anchor = node.get("reftargetid")
            if isinstance(node, addnodes.pending_xref):
                if node.get("refdomain") != "doc" or target in self.env.found_docs:
                    continue
                path = Path(target + ".md") if os.path.isabs(target) else docdir / (target + ".md")
            else:
                path = docdir / target
            path = path.resolve()
            if not path.exists() or path.is_relative_to(srcdir) or not path.is_relative_to(root):
                continue
            rel = path.relative_to(root).as_posix()
            if base:
                uri = f"{base}/{rel}"
            else:
                page = Path(self.app.outdir).resolve() / self.env.docname
                uri = os.path.relpath(path, page.parent).replace(os.sep, "/")
            if anchor:
                uri += f"#{anchor}"
            ref = nodes.reference("", "", *node.children, refuri=uri, internal=False)
            node.replace_self(ref)


def setup(app):  # noqa: ANN001, ANN201
    app.add_transform(RepositoryLinks)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
