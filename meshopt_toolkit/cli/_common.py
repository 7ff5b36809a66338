"""Helpers shared by the subcommands: expanding batch inputs, parsing number lists,
checking and writing outputs."""

from __future__ import annotations

import argparse
import contextlib
import glob
import logging
import os
import sys
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import numpy as np

from .. import strict_json
from ..errors import MeshoptError, WriteError

#: extensions treated as meshes when a directory is given as input
MESH_SUFFIXES = (".msh", ".obj", ".ply", ".off", ".vtk", ".vtu", ".stl")


def add_output_flags(p: argparse.ArgumentParser, *, json: bool = True, plots: bool = False,
                     frames: int | None = None, frame_format: str | None = None) -> None:
    """The options a writing subcommand shares, with one spelling and help everywhere.

    ``--force`` always; ``--json`` (summary on stdout) and ``--no-plots`` (skip the PNG
    figures; ``--no-png`` is kept as its old spelling) where asked; ``--frames K`` with
    ``frames`` (the most frames allowed) and ``--format EXT`` of the frame files with
    ``frame_format`` (what the default is, e.g. "the input's").
    """
    if frames is not None:
        p.add_argument("--frames", type=int,
                       help=f"write K frames into the OUT directory (2 <= K <= {frames})")
    if frame_format is not None:
        p.add_argument("--format", default=None, metavar="EXT",
                       help=f"extension of the frame files, e.g. msh, vtk, obj "
                            f"(default: {frame_format})")
    if plots:
        p.add_argument("--no-plots", "--no-png", dest="no_plots", action="store_true",
                       help="do not write PNG figures")
    add_force_flag(p)
    if json:
        p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")


def add_mesh_output(p: argparse.ArgumentParser) -> None:
    """The required ``-o/--output OUT`` of a command that writes a mesh, or with ``--frames``
    a directory of frames (``args.output``, checked by :func:`checked_paths`)."""
    p.add_argument("-o", "--output", required=True,
                   help="output mesh file, or a directory with --frames")


def add_force_flag(p: argparse.ArgumentParser, note: str | None = None) -> None:
    """``--force``, the one way of every command to replace existing outputs; ``note``: what
    it means besides in this command, shown in parentheses."""
    p.add_argument("--force", action="store_true",
                   help="overwrite existing output files" + (f" ({note})" if note else ""))


def add_inputs(p: argparse.ArgumentParser, metavar: str = "INPUT") -> None:
    """The positional ``INPUT...`` (``args.inputs``) of a command over a batch: files, globs
    and directories, expanded by :func:`expand_inputs`."""
    p.add_argument("inputs", nargs="+", metavar=metavar,
                   help="mesh files, globs or directories")


def add_recursive_flag(p: argparse.ArgumentParser) -> None:
    """``-r/--recursive``: :func:`expand_inputs` descends into the input directories'
    sub-folders."""
    p.add_argument("-r", "--recursive", action="store_true",
                   help="include the sub-folders of input directories")


def add_contact_flag(p: argparse.ArgumentParser, what: str) -> None:
    """``--contact on|off`` (default on) of a command that moves ``what`` (e.g. "a surface
    in 3D"): along the motion it never passes through itself."""
    p.add_argument("--contact", choices=("on", "off"), default="on",
                   help=f"{what} never passes through itself along the motion, at the frames "
                        "or between them (where the given poses are free of "
                        "self-intersections; default on)")


def expand_inputs(items: list[str], recursive: bool = False,
                  include_hint: str = "use --recursive to include them") -> list[Path]:
    """Files, globs and directories (their mesh files) → sorted unique paths.

    A directory contributes the mesh files directly in it; with ``recursive`` also those
    in its sub-folders (hidden ones excluded). Skipped sub-folders are logged as a warning
    ending in ``include_hint`` (how the command includes them).

    Raises
    ------
    MeshoptError
        An item matches nothing.
    """
    paths: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found = _directory_meshes(p, recursive, include_hint)
            if not found:
                raise MeshoptError(f"{item}: directory has no mesh files ({', '.join(MESH_SUFFIXES)})")
            paths.extend(found)
        elif p.exists():
            paths.append(p)
        elif glob.has_magic(item):
            found = sorted(Path(g) for g in glob.glob(item))
            if not found:
                raise MeshoptError(f"{item}: pattern matches no file")
            paths.extend(found)
        else:
            raise MeshoptError(f"{item}: no such file or directory")
    seen: set[Path] = set()
    unique = []
    for p in paths:
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            unique.append(p)
    return unique


def _directory_meshes(p: Path, recursive: bool, include_hint: str) -> list[Path]:
    # a FIFO or device named like a mesh is listed, so that it fails with one line
    files = sorted(q for q in (p.rglob("*") if recursive else p.iterdir())
                   if q.suffix.lower() in MESH_SUFFIXES and not q.is_dir()
                   and not any(part.startswith(".") for part in q.relative_to(p).parts))
    if not recursive:
        subs = sorted(q.name for q in p.iterdir() if q.is_dir() and not q.name.startswith("."))
        if subs:
            logging.getLogger("meshopt").warning(
                "%s: %d sub-folder(s) not searched (%s); %s",
                p, len(subs), ", ".join(subs[:5]) + (", ..." if len(subs) > 5 else ""),
                include_hint)
    return files


def float_list(n: int | None = None):
    """An argparse type for comma-separated floats, e.g. ``--beta 10,1,0,0.1``."""

    def parse(text: str) -> tuple[float, ...]:
        from ..expressions import quoted

        try:
            values = tuple(float(x) for x in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated numbers, "
                                             f"got {quoted(text)}") from None
        if n is not None and len(values) != n:
            raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers, got {len(values)}")
        return values

    return parse


# ------------------------------------------------------------------------------ outputs
# Checked before any work, so an unwritable output fails in a second with one line naming
# the path, not after a long computation with "internal error: PermissionError".


def check_writable(directory: Path, shown: Path | None = None) -> None:
    """Create and remove a temporary file in ``directory``; WriteError naming ``shown``.

    A real write, not ``os.access``: right for root, ACLs and read-only file systems.
    """
    shown = directory if shown is None else shown
    try:
        fd, name = tempfile.mkstemp(prefix=".meshopt-probe.", dir=directory)
    except OSError as exc:
        raise WriteError(f"{shown}: cannot write in {directory}: "
                         f"{exc.strerror or exc}") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)


def check_output_file(out: Path, *, force: bool, inputs: Iterable[Path] = ()) -> Path:
    """Check that the mesh file ``out`` can be written: the checks of every subcommand.

    Refused: an existing file without ``force``, a directory, one of ``inputs``, a missing
    or unwritable parent directory.

    Raises
    ------
    WriteError
        One line naming ``out`` and the reason.
    """
    out = Path(out)
    if out.is_dir():
        raise WriteError(f"{out}: is a directory (give a file name, or use --frames)")
    if out.exists() and not force:
        raise WriteError(f"{out}: exists (use --force to overwrite)")
    for src in inputs:
        if out.resolve() == Path(src).resolve():
            raise WriteError(f"{out}: refusing to overwrite the input mesh")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        what = "is not a directory" if parent.exists() else "does not exist"
        raise WriteError(f"{out}: {parent} {what}")
    check_writable(parent, out)
    return out


def frame_names(frames: int, fmt: str | None, src: str | Path) -> list[str]:
    """``frame_000.EXT`` … for ``frames`` frames, EXT the ``--format`` given (with or without
    the dot) or else the input's."""
    ext = (fmt or Path(src).suffix).strip().lower()
    ext = ext if ext.startswith(".") else "." + ext
    width = max(3, len(str(frames - 1)))
    return [f"frame_{k:0{width}d}{ext}" for k in range(frames)]


def check_mesh_format(name: str | Path, option: str | None = None) -> str:
    """The extension (``".msh"``) of the mesh file ``name``, if a format we write.

    ``name`` is a path, or with ``option`` the value of that option (``--format vtk``,
    ``--to .obj``: with or without the dot).

    Raises
    ------
    WriteError
        Unknown or missing extension; the message names the path or option and lists
        the formats.
    """
    from ..io import supported_extensions

    if option is None:
        ext, shown = Path(name).suffix.lower(), str(name)
    else:
        ext = str(name).strip().lower()
        ext, shown = (ext if ext.startswith(".") else "." + ext), f"{option} {name}"
    known = supported_extensions("write")
    if ext not in known:
        raise WriteError(f"{shown}: unknown mesh format {ext if len(ext) > 1 else '(none)'!r}; "
                         f"known: {', '.join(known)}")
    return ext


def check_output_dir(out: Path, *, force: bool, names: Iterable[str] | None = None) -> Path:
    """The checks of :func:`prepare_output_dir` without creating anything (before the work).

    ``out`` is a directory (or nothing yet, under a writable directory); without ``force``
    it is empty, or (with ``names``) holds none of ``names``.
    """
    out = Path(out)
    _check_existing_dir(out, force, names)
    if out.is_dir():
        check_writable(out, out)
        return out
    if out.suffix.lower() in MESH_SUFFIXES:
        raise WriteError(f"{out}: a directory is written here, not a mesh file "
                         "(give a directory name)")
    parent = out.absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise WriteError(f"{out}: cannot write in {parent}: not a directory")
    check_writable(parent, out)
    return out


def _check_existing_dir(out: Path, force: bool, names: Iterable[str] | None) -> None:
    """An existing ``out`` must be a directory, and without ``force`` empty, or (with
    ``names``) hold none of ``names``."""
    if out.exists() and not out.is_dir():
        raise WriteError(f"{out}: exists and is not a directory (a directory is written)")
    if not out.is_dir() or force:
        return
    if names is None:
        if any(out.iterdir()):
            raise WriteError(f"{out}: directory is not empty (use --force to overwrite)")
        return
    clash = [n for n in names if (out / n).exists()]
    if clash:
        raise WriteError(f"{out / clash[0]}: exists (use --force to overwrite)")


def prepare_output_dir(out: Path, *, force: bool, names: Iterable[str] | None = None) -> Path:
    """Create the output directory ``out`` (with parents) and check it is writable.

    An existing directory must be empty, or (with ``names``) hold none of ``names``,
    unless ``force``.

    Raises
    ------
    WriteError
        ``out`` exists and is not a directory, cannot be created or written, or holds
        outputs and ``force`` is false. One line naming the path.
    """
    out = Path(out)
    _check_existing_dir(out, force, names)
    make_output_dir(out)
    check_writable(out, out)
    return out


def make_output_dir(out: Path) -> None:
    """Create the directory ``out`` and its parents; what the file system refuses is one
    WriteError line naming ``out``."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WriteError(f"{out}: cannot create the output directory: "
                         f"{exc.strerror or exc}") from None


def check_output_target(out: Path, src: Path, frames: int | None, force: bool,
                        frame_format: str | None = None) -> None:
    """Before any work: ``out`` may be written (a mesh file in a format we write), or with
    ``frames`` is (or will be) a directory for frames in ``frame_format`` (default: the
    format of ``src``)."""
    if frames is None:
        check_mesh_format(out)
        check_output_file(out, force=force, inputs=[src])
        return
    if frame_format is None:
        check_mesh_format(src)
    else:
        check_mesh_format(frame_format, "--format")
    check_output_dir(out, force=force)


#: what a planar-only command says of the other cell kinds (:func:`load_workpiece`)
_NOT_PLANAR = {"tetrahedra": "a tetrahedral mesh ({n:,} tetrahedra)",
               "surface triangles": "a triangle surface in 3D (its points are not on one "
                                    "plane)"}


def warn_dropped(cells, src) -> None:
    """One warning line naming what the file holds that the reader could not represent
    (``cells.dropped``: per-corner OBJ normals, unknown statements): an operation's output
    will not hold it."""
    if cells is not None and cells.dropped:
        logging.getLogger("meshopt").warning("%s: not kept in the output: %s", src,
                                             "; ".join(cells.dropped))


def load_workpiece(src: Path, what: str, *, cells=None):
    """The file's :class:`~meshopt_toolkit.io.workpiece.Workpiece` (every block, tag and
    datum kept; the plane's coordinates at the file's scale: the operations scale it
    themselves), its mesh checked admissible for ``what``; ``cells``: the file's
    :class:`~meshopt_toolkit.io.cells.CellMesh` when already read.

    Raises
    ------
    InvalidMeshError
        The file holds tetrahedra or a surface in 3D: ``"FILE: optimize supports planar
        triangle meshes; this is a tetrahedral mesh (384 tetrahedra)"``.
    """
    from ..errors import InvalidMeshError
    from ..io.workpiece import Workpiece
    from ..mesh.kinds import cells_kind
    from ._info_cells import other_cells

    if cells is None:
        from ..io import load_cells

        cells = load_cells(src)
        warn_dropped(cells, src)
    kind = cells_kind(cells)
    if kind in _NOT_PLANAR and not other_cells(cells):  # other cell types: refused below
        n = sum(len(c) for t, c in cells.cells if t == "tetra")
        raise InvalidMeshError(f"{src}: {what} supports planar triangle meshes; this is "
                               + _NOT_PLANAR[kind].format(n=n))
    return Workpiece.from_cells(cells).admissible(what)


def save_moved(wp, mesh, path: Path, *, force: bool = True,
               cell_data: dict | None = None) -> None:
    """Write the workpiece ``wp`` with the working mesh's vertices where ``mesh`` has
    them: every block, tag and datum of the input, ``cell_data`` added."""
    from ..io.workpiece import save_workpiece

    cells = wp.moved(mesh.points).to_cells(cell_data=cell_data)
    save_workpiece(cells, path, overwrite=force, computed=tuple(cell_data or ()))


def checked_paths(args: argparse.Namespace, filter_cls, options) -> tuple[Path, Path]:
    """``(input, output)`` of a command that writes a mesh or ``--frames`` (``args.mesh``,
    ``args.output``), checked before any work: ``--frames`` in ``[2, MAX_FRAMES]``, the
    options of ``filter_cls`` (:func:`~._params.check_options`) and the output
    (:func:`check_output_target`)."""
    from ..bounds import MAX_FRAMES
    from ._params import check_options
    from ._validate import check_int

    check_int("--frames", args.frames, 2, MAX_FRAMES)
    check_options(args, filter_cls, options)
    src, out = Path(args.mesh), Path(args.output)
    check_output_target(out, src, args.frames, args.force, frame_format=args.format)
    return src, out


def save_moved_frames(wp, meshes, out: Path, names: list[str], *, force: bool) -> None:
    """Create the directory ``out`` (only once the work is done: a refused or failed run
    leaves nothing behind) and write there, under ``names`` (:func:`frame_names`), the
    workpiece ``wp`` moved to each of ``meshes`` (:func:`save_moved`)."""
    prepare_output_dir(out, force=force)
    for name, m in zip(names, meshes):
        save_moved(wp, m, out / name)


@contextlib.contextmanager
def writing(path: Path) -> Iterator[None]:
    """Turn an ``OSError`` while writing ``path`` into one WriteError line naming it."""
    try:
        yield
    except OSError as exc:
        raise WriteError(f"{path}: cannot write: {exc.strerror or exc}") from None


def write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (temporary file, then rename)."""
    from ..io import atomic_path

    with atomic_path(path) as tmp, writing(path):
        tmp.write_text(text, encoding="utf-8")


def csv_table(columns: Mapping[str, Iterable]) -> str:
    """CSV text of ``columns`` (name → values, all of one length): the names as the header,
    then a row per index; floats with 10 significant digits, other values as written."""

    def cell(value) -> str:
        return f"{value:.10g}" if isinstance(value, (float, np.floating)) else str(value)

    return ",".join(columns) + "\n" + "".join(
        ",".join(map(cell, row)) + "\n" for row in zip(*columns.values()))


def write_summary(outdir: Path, summary: dict) -> None:
    """``summary.json`` in ``outdir``: strict JSON, indented, written atomically."""
    write_text(outdir / "summary.json", strict_json.dumps(summary, indent=2) + "\n")


def print_json(obj) -> None:
    """``obj`` as strict JSON on stdout, ended by a newline (``--json``)."""
    strict_json.dump(obj, sys.stdout)
    sys.stdout.write("\n")


LOCK_NAME = ".meshopt.lock"


@contextlib.contextmanager
def exclusive_output_dir(outdir: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``outdir`` while a run writes its set of files there, so
    two runs into one directory cannot leave one run's summary beside the other's mesh:
    the second fails at once with one line. The lock file is removed when the run ends."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    lock = outdir / LOCK_NAME
    try:
        fd = os.open(lock, os.O_CREAT | os.O_RDWR, 0o644)
    except OSError as exc:
        raise WriteError(f"{outdir}: cannot write there: {exc.strerror or exc}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise WriteError(f"{outdir}: another meshopt run is writing there "
                             f"(it holds {lock}); use another -o") from None
        try:
            yield
        finally:
            with contextlib.suppress(OSError):
                lock.unlink()
    finally:
        os.close(fd)
