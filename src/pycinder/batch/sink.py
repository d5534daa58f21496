"""Where batch results go: JSON lines, or Parquet; a run again with the same file resumes.

JSON lines: one result a line, each written whole with a single ``write`` on a file opened for
appending, as soon as it arrives. A run that is stopped (killed, interrupted) loses no line it
wrote; a line torn by a crash is dropped when the file is opened again, and its scene is run
again. On opening, ids already written are read back (a repeated id keeps its first line), and
the run skips them; ``failed`` holds those whose line is an error, so that a resumed run can
say that they failed (or, with ``retry_errors``, drops their lines and runs them again).

Parquet (an OUT ending in ``.parquet``) cannot be appended to: results go to a JSON-lines
journal beside it (``OUT.partial.jsonl``), and the Parquet file is written, whole and atomically,
from its previous rows and the journal when the run ends or is interrupted. Its columns are the
rows' keys (:mod:`pycinder.batch`): ``id``, ``pairs``, ``names``, ``stats`` (JSON text),
``status``, ``error``, ``error_kind``, ``attempts`` and ``collides`` (a robot manifest's rows,
:mod:`.robot_run`), null where a row has no such key.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..util.optional import require
from .manifest import id_key


def read_lines(path: Path) -> tuple[list[dict], int, bool]:
    """The results in a JSON-lines file, how many lines were dropped (torn or not JSON), and
    whether the file ends with a whole line."""
    if not path.exists():
        return [], 0, True
    rows, dropped = [], 0
    data = path.read_bytes()
    for line in data.split(b"\n"):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
        except (json.JSONDecodeError, UnicodeDecodeError):
            dropped += 1
            continue
        if isinstance(row, dict) and "id" in row:
            rows.append(row)
        else:
            dropped += 1
    return rows, dropped, not data or data.endswith(b"\n")


def _dedupe(rows: list[dict], retry_errors: bool) -> tuple[list[dict], int]:
    """Rows with each id once (the first), without errors when they are to be retried; and the
    number left out."""
    seen, out = set(), []
    for row in rows:
        key = id_key(row["id"])
        if key in seen or (retry_errors and "error" in row):
            continue
        seen.add(key)
        out.append(row)
    return out, len(rows) - len(out)


def failed_keys(rows: list[dict]) -> set[str]:
    """The id keys of the error rows among ``rows``."""
    return {id_key(r["id"]) for r in rows if "error" in r}


def _dump(row: dict) -> bytes:
    return (json.dumps(row, separators=(",", ":")) + "\n").encode()


def _replace(path: Path, rows: list[dict]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(b"".join(_dump(r) for r in rows))
    os.replace(tmp, path)


class JsonLinesSink:
    """Appends results to a JSON-lines file; ``done`` holds the id keys already in it, ``failed``
    those of them whose row is an error.

    Parameters
    ----------
    path : path
    retry_errors : bool
        Drop the error lines already in the file, so that their scenes run again.
    """

    def __init__(self, path: str | Path, retry_errors: bool = False) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        rows, dropped, whole = read_lines(self.path)
        kept, removed = _dedupe(rows, retry_errors)
        self.repaired = dropped + removed
        if self.repaired or not whole:  # a last line that is whole but lacks its newline stays
            _replace(self.path, kept)
        self.done = {id_key(r["id"]) for r in kept}
        self.failed = failed_keys(kept)
        self.previous = len(kept)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)

    def write(self, result: dict) -> None:
        """Write one result as one line, at once."""
        data = _dump(result)
        written = os.write(self._fd, data)
        while written < len(data):  # only on a full disk or a signal: finish the line
            written += os.write(self._fd, data[written:])
        self.done.add(id_key(result["id"]))
        if "error" in result:
            self.failed.add(id_key(result["id"]))

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class ParquetSink:
    """Results to Parquet through a JSON-lines journal (see the module's notes). Ids must be all
    integers or all strings (one column type)."""

    def __init__(self, path: str | Path, retry_errors: bool = False) -> None:
        self.pa = require("pyarrow", "Parquet output of pycinder batch", "cluster")
        require("pyarrow.parquet", "Parquet output of pycinder batch", "cluster", "pyarrow")
        self.path = Path(path)
        self.journal = JsonLinesSink(self.path.with_name(self.path.name + ".partial.jsonl"),
                                     retry_errors)
        self.rows = self._read() if self.path.exists() else []
        self.rows, removed = _dedupe(self.rows, retry_errors)
        self.repaired = self.journal.repaired + removed
        self.done = self.journal.done | {id_key(r["id"]) for r in self.rows}
        self.failed = self.journal.failed | failed_keys(self.rows)
        self.previous = len(self.done)
        self._kind: type | None = None
        for row in self.rows:
            self._check_id(row["id"])

    def _check_id(self, scene_id: Any) -> None:
        kind = str if isinstance(scene_id, str) else int
        if self._kind is None:
            self._kind = kind
        elif kind is not self._kind:
            raise ValueError(f"Parquet output needs ids of one type: id {scene_id!r} is not "
                             f"a{'n integer' if self._kind is int else ' string'} like those "
                             "before it (write JSON lines instead)")

    def _read(self) -> list[dict]:
        import pyarrow.parquet as pq

        rows = pq.read_table(self.path).to_pylist()
        for row in rows:
            row["stats"] = json.loads(row["stats"]) if row.get("stats") else None
            for key in [k for k, v in row.items() if v is None]:
                del row[key]
        return rows

    def write(self, result: dict) -> None:
        self._check_id(result["id"])
        self.journal.write(result)
        self.done = self.journal.done | self.done
        self.failed = self.journal.failed | self.failed

    def close(self) -> None:
        """Write the Parquet file from its previous rows and the journal; remove the journal."""
        import pyarrow.parquet as pq

        if self.journal._fd < 0:
            return
        self.journal.close()
        new = read_lines(self.journal.path)[0]
        for row in new:
            self._check_id(row["id"])
        rows, _ = _dedupe(self.rows + new, retry_errors=False)
        pa = self.pa
        schema = pa.schema([
            ("id", pa.string() if self._kind is str else pa.int64()),
            ("pairs", pa.list_(pa.list_(pa.int64()))),
            ("names", pa.list_(pa.list_(pa.string()))),
            ("stats", pa.string()),
            ("status", pa.string()),
            ("error", pa.string()),
            ("error_kind", pa.string()),
            ("attempts", pa.int64()),
            ("collides", pa.bool_()),
        ])
        table = pa.Table.from_pylist([{
            "id": r["id"], "pairs": r.get("pairs"), "names": r.get("names"),
            "stats": json.dumps(r["stats"]) if r.get("stats") is not None else None,
            "status": r.get("status", "error" if "error" in r else "ok"),  # rows before 0.3
            "error": r.get("error"), "error_kind": r.get("error_kind"),
            "attempts": r.get("attempts"), "collides": r.get("collides")} for r in rows],
            schema=schema)
        tmp = self.path.with_name(self.path.name + ".tmp")
        pq.write_table(table, tmp)
        os.replace(tmp, self.path)
        self.journal.path.unlink()


def open_sink(path: str | Path, retry_errors: bool = False) -> JsonLinesSink | ParquetSink:
    """The sink for OUT: Parquet when it ends in ``.parquet``, else JSON lines."""
    if str(path).lower().endswith(".parquet"):
        return ParquetSink(path, retry_errors)
    return JsonLinesSink(path, retry_errors)
