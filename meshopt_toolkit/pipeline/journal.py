"""The batch journal: what a batch has completely written into its output directory.

A small SQLite file, ``OUTDIR/.meshopt-journal.db``, written only by the process that runs
the batch (the client, for a Dask cluster). For each file it records a *job key* — the
hash of the input's resolved path, the input's content hash, the *config hash* (the
pipeline and every option that changes an output) and the output name the batch fixes —
and the outputs with their sizes and content hashes. ``--resume`` skips a file when the
journal has its key as done and every output it recorded is still there, unchanged; a
changed pipeline or input gives another key, so it is done again.

Protocol per file, each step committed before the next:

1. ``published``: the outputs about to be moved into place;
2. the moves (rename or hard link: atomic);
3. ``done``: the file is complete, with each output's size and content hash.

A kill between 1 and 3 leaves outputs that the journal knows as this job's own: the rerun
may replace them without ``--force`` (nothing else is ever replaced without it). SQLite
runs in WAL mode with ``synchronous=NORMAL``: a commit costs no fsync, and after a kill -9
nothing committed is lost; after a power cut the last commits may be, but the journal
stays consistent and a skip is always checked against the outputs' hashes, so it is never
wrong (at worst an output is redone and needs ``--force`` to be replaced). The journal is
opened with an exclusive lock: two batches cannot share an output directory at once.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import sqlite3
from pathlib import Path

from ..errors import MeshoptError

__all__ = ["Journal", "JOURNAL_NAME", "STAGING_NAME", "file_sha256", "config_sha256",
           "remove_stray_parts"]

#: the journal's file name inside the output directory
JOURNAL_NAME = ".meshopt-journal.db"
#: per-file scratch folders inside the output directory (removed at the start and the end)
STAGING_NAME = ".meshopt-staging"
_FORMAT = "1"
# the temporary files of io._atomic.atomic_path: mkstemp(prefix=".NAME.", suffix=".part")
_PART = re.compile(r"^\..+\.[A-Za-z0-9_]{8}\.part$")


def file_sha256(path, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of a file's content (read in chunks: memory stays small)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def config_sha256(config: dict) -> str:
    """Hex SHA-256 of a JSON-able configuration (keys sorted)."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def remove_stray_parts(outdir) -> list[Path]:
    """Remove the temporary ``.NAME.XXXXXXXX.part`` files a killed run left in ``outdir``.

    Only files named like those of :func:`meshopt_toolkit.io._atomic.atomic_path` are
    removed, in ``outdir`` and its subfolders. Returns the removed paths.
    """
    removed = []
    for root, dirs, files in os.walk(outdir):
        dirs[:] = [d for d in dirs if d != STAGING_NAME]
        for name in files:
            if _PART.match(name):
                path = Path(root) / name
                try:
                    path.unlink()
                    removed.append(path)
                except FileNotFoundError:
                    pass
    return removed


class Journal:
    """The journal of one output directory (see the module docstring).

    Parameters
    ----------
    outdir : path
        An existing directory.

    Raises
    ------
    MeshoptError
        Another batch holds the journal, or it cannot be created or read.
    """

    def __init__(self, outdir) -> None:
        self.outdir = Path(outdir)
        self.path = self.outdir / JOURNAL_NAME
        try:
            self._db = sqlite3.connect(self.path, timeout=0.2, isolation_level=None)
        except sqlite3.Error as exc:
            raise MeshoptError(f"{self.path}: cannot open the batch journal: {exc}") from None
        try:
            self._db.execute("PRAGMA locking_mode=EXCLUSIVE")
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=NORMAL")
            with self._transaction():
                self._db.execute("CREATE TABLE IF NOT EXISTS meta (k TEXT PRIMARY KEY, v TEXT)")
                self._db.execute("CREATE TABLE IF NOT EXISTS done (key TEXT PRIMARY KEY, "
                                 "input TEXT, input_sha TEXT, config_sha TEXT, outputs TEXT)")
                self._db.execute("CREATE TABLE IF NOT EXISTS published (key TEXT, path TEXT, "
                                 "PRIMARY KEY (key, path))")
                row = self._db.execute("SELECT v FROM meta WHERE k='format'").fetchone()
                if row is None:
                    self._db.execute("INSERT INTO meta VALUES ('format', ?)", (_FORMAT,))
                elif row[0] != _FORMAT:
                    raise MeshoptError(f"{self.path}: journal format {row[0]} is not "
                                       f"{_FORMAT}; remove it to start over")
        except sqlite3.OperationalError as exc:
            self._db.close()
            if "locked" in str(exc):
                raise MeshoptError(f"{self.outdir}: another batch is writing to this directory "
                                   f"(its journal {JOURNAL_NAME} is locked)") from None
            raise MeshoptError(f"{self.path}: cannot use the batch journal: {exc}") from None
        except sqlite3.DatabaseError as exc:
            self._db.close()
            raise MeshoptError(f"{self.path}: not a batch journal ({exc}); remove it to start "
                               "over") from None

    def _transaction(self):
        db = self._db

        class _Tx:
            def __enter__(self_):
                db.execute("BEGIN IMMEDIATE")

            def __exit__(self_, exc_type, *_):
                db.execute("ROLLBACK" if exc_type else "COMMIT")

        return _Tx()

    @staticmethod
    def key(src, input_sha: str, config_sha: str, name: str | None = None) -> str:
        """The job key of one input under one configuration (and output name, if fixed)."""
        text = f"{os.path.realpath(src)}\0{input_sha}\0{config_sha}\0{name or ''}"
        return hashlib.sha256(text.encode()).hexdigest()[:40]

    def completed(self, key: str) -> list[dict] | None:
        """The outputs of a done job, if it is done and they are all intact, else None.

        Each output is ``{"path": relative path, "size", "sha256"}``; intact means present
        with the recorded size and content hash.
        """
        row = self._db.execute("SELECT outputs FROM done WHERE key=?", (key,)).fetchone()
        if row is None:
            return None
        outputs = json.loads(row[0])
        for item in outputs:
            path = self.outdir / item["path"]
            try:
                if path.stat().st_size != item["size"] or file_sha256(path) != item["sha256"]:
                    return None
            except OSError:
                return None
        return outputs

    def is_own(self, key: str, rel: str) -> bool:
        """Whether ``rel`` was being published by an earlier, interrupted attempt of this job.

        Outputs of a *done* job are not "own" any more: if one was changed since, it is the
        user's, and only ``--force`` replaces it.
        """
        row = self._db.execute("SELECT 1 FROM published WHERE key=? AND path=?",
                               (key, rel)).fetchone()
        return row is not None

    def will_publish(self, key: str, rels: list[str]) -> None:
        """Record (durably) that these outputs of ``key`` are about to be moved into place."""
        with self._transaction():
            self._db.executemany("INSERT OR IGNORE INTO published VALUES (?, ?)",
                                 [(key, r) for r in rels])

    def mark_done(self, key: str, src, input_sha: str, config_sha: str,
                  outputs: list[dict]) -> None:
        """Record that job ``key`` is complete with these outputs."""
        with self._transaction():
            self._db.execute("INSERT OR REPLACE INTO done VALUES (?, ?, ?, ?, ?)",
                             (key, str(src), input_sha, config_sha, json.dumps(outputs)))
            self._db.execute("DELETE FROM published WHERE key=?", (key,))

    def close(self) -> None:
        """Release the lock (the WAL is checkpointed into the database file)."""
        try:
            self._db.close()
        except sqlite3.Error:  # pragma: no cover
            pass

    def __enter__(self) -> "Journal":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def reset_staging(outdir) -> Path:
    """Remove and recreate ``OUTDIR/.meshopt-staging`` (leftovers of a killed run)."""
    staging = Path(outdir) / STAGING_NAME
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    return staging
