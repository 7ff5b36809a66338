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

Temporaries: the batch's scratch folder ``OUTDIR/.meshopt-staging`` (and anything else it
may make and remove again) is recorded by its exact name in the journal *before* it is
created (:meth:`Journal.will_create`), and a later run removes exactly the recorded names
(:meth:`Journal.remove_temporaries`). Nothing is removed for looking like a temporary: a
user's ``.thesis.2024_v01.part`` or a ``.meshopt-staging`` folder the journal did not make
is never deleted (the latter is refused with one line).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sqlite3
import stat
from pathlib import Path

from ..errors import MeshoptError
from ..io._files import UNCAPPED, open_input

__all__ = ["Journal", "JOURNAL_NAME", "STAGING_NAME", "file_sha256", "config_sha256"]

#: the journal's file name inside the output directory
JOURNAL_NAME = ".meshopt-journal.db"
#: per-file scratch folders inside the output directory (removed at the start and the end)
STAGING_NAME = ".meshopt-staging"
_FORMAT = "1"


def file_sha256(path, chunk: int = 1 << 20, max_bytes: int | None = UNCAPPED) -> str:
    """Hex SHA-256 of a regular file's content (read in chunks: memory stays small).

    Raises
    ------
    ReadError
        Not a regular file (a FIFO, a device, a socket: refused before it is read), or
        larger than ``max_bytes`` (None: the default cap of mesh files).
    """
    h = hashlib.sha256()
    with open_input(path, max_bytes) as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def config_sha256(config: dict) -> str:
    """Hex SHA-256 of a JSON-able configuration (keys sorted)."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


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
                had_done = self._db.execute(
                    "SELECT 1 FROM sqlite_master WHERE name='done'").fetchone() is not None
                self._db.execute("CREATE TABLE IF NOT EXISTS meta (k TEXT PRIMARY KEY, v TEXT)")
                self._db.execute("CREATE TABLE IF NOT EXISTS done (key TEXT PRIMARY KEY, "
                                 "input TEXT, input_sha TEXT, config_sha TEXT, outputs TEXT)")
                self._db.execute("CREATE TABLE IF NOT EXISTS published (key TEXT, path TEXT, "
                                 "PRIMARY KEY (key, path))")
                # a journal written before temporaries were recorded made its staging
                # folder without recording it: that one folder is adopted
                older = had_done and self._db.execute(
                    "SELECT 1 FROM sqlite_master WHERE name='temporaries'").fetchone() is None
                self._db.execute("CREATE TABLE IF NOT EXISTS temporaries (path TEXT PRIMARY KEY)")
                if older and (self.outdir / STAGING_NAME).is_dir():
                    self._db.execute("INSERT OR IGNORE INTO temporaries VALUES (?)",
                                     (STAGING_NAME,))
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
            except (OSError, MeshoptError):  # gone, or no longer a regular file
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

    # -- temporaries -------------------------------------------------------------------
    def will_create(self, rel: str) -> Path:
        """Record (durably) that ``OUTDIR/rel`` is about to be created as a temporary.

        Returns the absolute path; :meth:`remove_temporaries` removes exactly it later.
        """
        rel = os.path.normpath(rel)
        if os.path.isabs(rel) or rel.split(os.sep)[0] == "..":
            raise MeshoptError(f"{rel}: a temporary outside the output directory")  # a bug
        with self._transaction():
            self._db.execute("INSERT OR IGNORE INTO temporaries VALUES (?)", (rel,))
        return self.outdir / rel

    def temporaries(self) -> list[str]:
        """The recorded temporaries (relative paths), in name order."""
        return [r[0] for r in self._db.execute("SELECT path FROM temporaries ORDER BY path")]

    def remove_temporaries(self) -> list[Path]:
        """Remove every recorded temporary that exists (a folder with its content; a
        symlink itself, never its target) and forget it; return the removed paths."""
        removed = []
        for rel in self.temporaries():
            path = self.outdir / rel
            try:
                mode = os.lstat(path).st_mode
            except FileNotFoundError:
                mode = None
            except OSError as exc:
                raise MeshoptError(f"{path}: cannot remove the batch's temporary: "
                                   f"{exc.strerror or exc}") from None
            if mode is not None:
                if stat.S_ISDIR(mode):
                    shutil.rmtree(path)
                else:
                    path.unlink()
                removed.append(path)
            with self._transaction():
                self._db.execute("DELETE FROM temporaries WHERE path=?", (rel,))
        return removed

    def reset_staging(self) -> Path:
        """A fresh, empty ``OUTDIR/.meshopt-staging``: the recorded temporaries of an
        earlier run (killed or not) removed, the folder recorded, then made.

        Raises
        ------
        MeshoptError
            ``.meshopt-staging`` exists but the journal did not make it (someone else's).
        """
        self.remove_temporaries()
        staging = self.outdir / STAGING_NAME
        if os.path.lexists(staging):
            raise MeshoptError(f"{staging}: exists but was not made by a batch in this "
                               "directory (not removed); move it away")
        self.will_create(STAGING_NAME)
        staging.mkdir()
        return staging

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

