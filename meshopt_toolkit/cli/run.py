"""``meshopt run PIPELINE INPUT... -o OUTDIR``: run a JSON or .mlx pipeline over meshes.

Each input is loaded, the pipeline runs on it (meshopt filters in Python, MeshLab filters
routed to pymeshlab) and the current mesh is saved as ``OUTDIR/<stem><ext>`` unless the
pipeline has its own ``save_mesh`` step. Outputs are atomic and never overwrite without
``--force``. A failing file is reported and the others go on (exit status 1 with a
summary). Pipelines with MeshLab or plugin steps run each file in a worker process
(``--isolate auto``) so that a native crash cannot take the batch down.

The pipeline file is untrusted; the command line is the only authority:

- it writes only inside ``-o`` (absolute paths, ``..`` and escaping symlinks refused) and
  replaces files only with ``--force`` (whatever ``"overwrite"`` it says);
- it reads only the inputs and what ``--allow-read`` names;
- the current mesh may not grow past ``--max-triangles`` (estimated before each step,
  measured after it);
- a MeshLab step that inverts triangles of a planar mesh that was admissible fails the
  file (nothing written) unless ``--allow-inverted`` (then a warning on stderr).

``--dry-run`` runs no filter and writes nothing, but checks all of this from the inputs
(``-o`` is optional then: without it existing outputs are not looked for).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..errors import MeshoptError
from ._common import check_writable

HELP = "run a pipeline (.json or MeshLab .mlx) over one mesh or a batch"


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def add_args(parser) -> None:
    from ..pipeline.limits import DEFAULT_MAX_TRIANGLES

    parser.add_argument("pipeline", metavar="PIPELINE", help="pipeline file (.json or .mlx)")
    parser.add_argument("inputs", nargs="+", metavar="INPUT",
                        help="mesh files, globs or directories")
    parser.add_argument("-o", "--output", metavar="OUTDIR",
                        help="output directory (created if missing); the only place the "
                             "pipeline writes (optional with --dry-run)")
    parser.add_argument("--to", metavar="EXT", help="output format (default: the input's)")
    parser.add_argument("--force", action="store_true",
                        help="overwrite existing outputs (a pipeline cannot grant this itself)")
    parser.add_argument("--dry-run", action="store_true",
                        help="check the pipeline, paths and size budget on the inputs; run "
                             "no filter, write nothing")
    parser.add_argument("--allow-read", action="append", default=[], metavar="PATH",
                        help="a file or folder the pipeline may read (load_mesh), besides "
                             "the inputs; repeatable")
    parser.add_argument("--max-triangles", type=_positive_int, default=DEFAULT_MAX_TRIANGLES,
                        metavar="N", help="refuse steps that would make the mesh larger "
                                          f"(default {DEFAULT_MAX_TRIANGLES:,})")
    parser.add_argument("--allow-inverted", action="store_true",
                        help="write meshes a MeshLab step left with inverted triangles "
                             "(warning) instead of failing the file")
    parser.add_argument("--isolate", choices=("auto", "always", "never"), default="auto",
                        help="run each file in a worker process (auto: when the pipeline "
                             "has MeshLab or plugin steps)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON record per file (results of each step)")


def _outdir(args) -> Path | None:
    if args.output is None:
        if not args.dry_run:
            raise MeshoptError("-o/--output OUTDIR is required (except with --dry-run)")
        return None
    outdir = Path(args.output)
    if outdir.exists() and not outdir.is_dir():
        raise MeshoptError(f"{outdir}: exists and is not a directory")
    if not args.dry_run:
        try:
            outdir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise MeshoptError(f"{outdir}: cannot create the output directory: "
                               f"{exc.strerror or exc}") from None
        check_writable(outdir)  # before any file is processed
    return outdir


def run(args) -> int:
    from ..pipeline import load_pipeline
    from ..pipeline.batch import BatchRunner, RunOptions
    from ..progress import ProgressBar
    from ._common import expand_inputs

    pipeline = load_pipeline(args.pipeline)  # errors here are fatal (one line, exit 1)
    pipeline.validate()
    failures: list[str] = []
    inputs: list[Path] = []
    for item in args.inputs:
        try:
            inputs.extend(p for p in expand_inputs([item]) if p not in inputs)
        except MeshoptError as exc:
            failures.append(str(exc))
            print(f"meshopt run: error: {exc}", file=sys.stderr)
    for item in args.allow_read:
        if not Path(item).exists():
            raise MeshoptError(f"--allow-read {item}: no such file or directory")
    outdir = _outdir(args)
    ext = None
    if args.to:
        ext = args.to.lower() if args.to.startswith(".") else "." + args.to.lower()
    stems: dict[str, Path] = {}
    for p in inputs:
        key = p.stem + (ext or p.suffix.lower())
        if key in stems:
            where = key if outdir is None else outdir / key
            raise MeshoptError(f"{p} and {stems[key]} would both be written to {where}")
        stems[key] = p
    # a dry run executes no filter, so nothing native can crash
    auto = not pipeline.only_builtin and not args.dry_run
    isolate = {"always": True, "never": False}.get(args.isolate, auto)
    options = RunOptions(ext=ext, force=args.force, dry_run=args.dry_run,
                         inputs=[str(p) for p in inputs], allow_read=list(args.allow_read),
                         max_triangles=args.max_triangles, allow_inverted=args.allow_inverted)
    runner = BatchRunner(pipeline, outdir, isolate=isolate, options=options)
    done = 0
    with ProgressBar(len(inputs), "run") as bar:
        def report(rec: dict) -> None:
            nonlocal done
            for warning in rec.get("warnings", ()):
                if bar.enabled:
                    bar.stream.write("\n")
                print(f"meshopt run: warning: {rec['input']}: {warning}", file=sys.stderr)
            if rec["status"] == "ok":
                done += 1
            else:
                if bar.enabled:
                    bar.stream.write("\n")
                failures.append(rec["error"])
                print(f"meshopt run: error: {rec['error']}", file=sys.stderr)
            if args.json:
                print(json.dumps(rec), flush=True)
            bar.update(status=Path(rec["input"]).name)

        runner.run(inputs, report)
    verb = "checked" if args.dry_run else "processed"
    total = done + len(failures)
    print(f"meshopt run: {done} of {total} files {verb}"
          + (f", {len(failures)} failed" if failures else ""), file=sys.stderr)
    return 1 if failures or not inputs else 0
