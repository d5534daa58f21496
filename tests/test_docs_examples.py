"""Every example of the README and the docs runs here, with the output it shows checked.

The collector reads the fenced code blocks of ``README.md`` and ``docs/**/*.md``:

- ```` ```python ```` and ```` ```pycon ````: a block holding ``>>>`` prompts is a doctest (its
  output checked with ``ELLIPSIS`` and ``NORMALIZE_WHITESPACE``: write ``...`` for what changes
  between machines, such as adapter names and timings); a block without prompts is run as a
  script. Each block runs alone, in a fresh namespace and an empty working directory: it makes
  its own imports and its own data.
- ```` ```console ````: each ``$ `` line is a command, run in an empty working directory of the
  block's own (``pycinder`` and ``python`` are this interpreter's); the lines up to the next
  ``$ `` are its output (stdout and stderr together), checked the same way.
- Shown, never run: the languages in ``SHOWN`` (install and make commands are ``sh``).
  A block in any other language fails, so a typo cannot turn an example off.

An example that needs an optional package says so in an HTML comment on the line before its
block, naming the modules it imports: ``<!-- requires: fcl -->``, ``<!-- requires: ray -->``.
It is skipped, naming them, only when one of them cannot be imported.

This file imports nothing from ``tests/`` or ``src/`` and takes no fixture from a conftest: it
also runs against an installed wheel, finding ``README.md`` and ``docs/`` next to ``tests/``.
"""

from __future__ import annotations

import doctest
import importlib.util
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUN = ("python", "pycon", "console")
SHOWN = ("sh", "text", "json", "jsonl", "toml", "wgsl", "")
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
FENCE = re.compile(r"^(?P<indent> *)(?P<fence>`{3,}|~{3,})(?P<info>[^`]*)$")
REQUIRES = re.compile(r"^\s*<!--\s*requires:\s*(?P<modules>[\w.,\s]+?)\s*-->\s*$")


@dataclass
class Block:
    path: Path
    line: int  # of the opening fence, counting from 1
    language: str
    code: str
    requires: tuple[str, ...]

    @property
    def id(self) -> str:
        return f"{self.path.relative_to(ROOT).as_posix()}:{self.line}"


def pages() -> list[Path]:
    found = [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))
    return [p for p in found if p.is_file() and "_build" not in p.relative_to(ROOT).parts]


def blocks(path: Path) -> list[Block]:
    """The fenced blocks of a Markdown page; MyST directives (```` ```{name} ````) excepted."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out: list[Block] = []
    k = 0
    while k < len(lines):
        opening = FENCE.match(lines[k])
        if not opening:
            k += 1
            continue
        fence, indent = opening["fence"], len(opening["indent"])
        info = opening["info"].strip()
        start = k
        body: list[str] = []
        k += 1
        while k < len(lines):
            closing = FENCE.match(lines[k])
            if closing and closing["fence"].startswith(fence) and not closing["info"].strip():
                break
            line = lines[k]
            body.append(line[indent:] if not line[:indent].strip() else line.lstrip())
            k += 1
        k += 1
        if info.startswith("{"):  # a MyST directive: eval-rst, toctree, ...
            continue
        requires: tuple[str, ...] = ()
        before = start - 1
        while before >= 0 and not lines[before].strip():
            before -= 1
        if before >= 0 and (m := REQUIRES.match(lines[before])):
            requires = tuple(n.strip() for n in m["modules"].split(",") if n.strip())
        language = info.split()[0].lower() if info else ""
        out.append(Block(path, start + 1, language, "\n".join(body) + "\n", requires))
    return out


ALL = [b for page in pages() for b in blocks(page)]
RUNNABLE = [b for b in ALL if b.language in RUN]


def test_pages_found() -> None:
    assert (ROOT / "README.md").is_file(), f"README.md not found next to {Path(__file__).parent}"
    assert (ROOT / "docs" / "index.md").is_file(), "docs/ not found next to tests/"
    assert len(RUNNABLE) >= 10, [b.id for b in RUNNABLE]


@pytest.mark.parametrize("block", ALL, ids=[b.id for b in ALL])
def test_language_known(block: Block) -> None:
    assert block.language in RUN + SHOWN, (
        f"{block.id}: a ```{block.language} block is neither run ({', '.join(RUN)}) nor shown "
        f"only ({', '.join(repr(s) for s in SHOWN)}); see tests/test_docs_examples.py")


def _skip_missing(block: Block) -> None:
    missing = [m for m in block.requires if importlib.util.find_spec(m) is None]
    if missing:
        pytest.skip(f"{block.id} needs {', '.join(missing)} (declared by <!-- requires: -->)")


def _run_doctest(block: Block) -> None:
    parser = doctest.DocTestParser()
    test = parser.get_doctest(block.code, {"__name__": "__docs__"}, block.id, str(block.path),
                              block.line)
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    report: list[str] = []
    runner.run(test, out=report.append)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{block.id}:\n" + "".join(report)


def _run_script(block: Block) -> None:
    code = compile(block.code, f"{block.id}", "exec")
    exec(code, {"__name__": "__docs__"})  # noqa: S102 - the docs' own examples


def _command(line: str) -> list[str]:
    words = shlex.split(line)
    if words[0] == "pycinder":
        return [sys.executable, "-m", "pycinder", *words[1:]]
    if words[0] == "python":
        return [sys.executable, *words[1:]]
    raise AssertionError(f"only pycinder and python commands run in console blocks: {line!r}")


def _run_console(block: Block, cwd: Path) -> None:
    steps: list[tuple[str, list[str]]] = []
    for line in block.code.splitlines():
        if line.startswith("$ "):
            steps.append((line[2:], []))
        else:
            assert steps, f"{block.id}: output before the first $ command"
            steps[-1][1].append(line)
    assert steps, f"{block.id}: a console block without a $ command"
    env = dict(os.environ, COLUMNS="100", PYTHONIOENCODING="utf-8")
    checker = doctest.OutputChecker()
    for command, shown in steps:
        done = subprocess.run(_command(command), cwd=cwd, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=600)
        want = "\n".join(shown).strip() + "\n"
        got = done.stdout.strip() + "\n"
        if want.strip() == "":
            want = "\n" if not got.strip() else want
        assert checker.check_output(want, got, FLAGS), (
            f"{block.id}: $ {command}\n--- shown\n{want}--- printed (exit {done.returncode})\n"
            f"{got}")


@pytest.mark.parametrize("block", RUNNABLE, ids=[b.id for b in RUNNABLE])
def test_example(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _skip_missing(block)
    monkeypatch.chdir(tmp_path)
    if block.language == "console":
        _run_console(block, tmp_path)
    elif ">>>" in block.code:
        _run_doctest(block)
    else:
        _run_script(block)
