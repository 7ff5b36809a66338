"""``meshopt run PIPELINE INPUT... -o OUTDIR``: run a JSON or .mlx pipeline over meshes.

Each input is loaded, the pipeline runs on it (meshopt filters in Python, MeshLab filters
routed to pymeshlab) and the current mesh is saved as ``OUTDIR/<stem><ext>`` unless the
pipeline has its own ``save_mesh`` step. Outputs are atomic and never overwrite without
``--force``. A failing file is reported and the others go on (exit status 1 with a
summary). Pipelines with MeshLab or plugin steps run each file in a worker process
(``--isolate auto``) so that a native crash cannot take the batch down. ``--dry-run``
validates the pipeline, reads the inputs and checks the outputs without writing.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..errors import MeshoptError

HELP = "run a pipeline (.json or MeshLab .mlx) over one mesh or a batch"


def add_args(parser) -> None:
    parser.add_argument("pipeline", metavar="PIPELINE", help="pipeline file (.json or .mlx)")
    parser.add_argument("inputs", nargs="+", metavar="INPUT",
                        help="mesh files, globs or directories")
    parser.add_argument("-o", "--output", required=True, metavar="OUTDIR",
                        help="output directory (created if missing)")
    parser.add_argument("--to", metavar="EXT", help="output format (default: the input's)")
    parser.add_argument("--force", action="store_true", help="overwrite existing outputs")
    parser.add_argument("--dry-run", action="store_true",
                        help="validate the pipeline and inputs, write nothing")
    parser.add_argument("--isolate", choices=("auto", "always", "never"), default="auto",
                        help="run each file in a worker process (auto: when the pipeline "
                             "has MeshLab or plugin steps)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON record per file (results of each step)")


def run(args) -> int:
    from ..pipeline import load_pipeline
    from ..pipeline.batch import BatchRunner
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
    outdir = Path(args.output)
    if outdir.exists() and not outdir.is_dir():
        raise MeshoptError(f"{outdir}: exists and is not a directory")
    if not args.dry_run:
        outdir.mkdir(parents=True, exist_ok=True)
    ext = None
    if args.to:
        ext = args.to.lower() if args.to.startswith(".") else "." + args.to.lower()
    stems: dict[str, Path] = {}
    for p in inputs:
        key = p.stem + (ext or p.suffix.lower())
        if key in stems:
            raise MeshoptError(f"{p} and {stems[key]} would both be written to {outdir / key}")
        stems[key] = p
    # a dry run executes no filter, so nothing native can crash
    auto = not pipeline.only_builtin and not args.dry_run
    isolate = {"always": True, "never": False}.get(args.isolate, auto)
    runner = BatchRunner(pipeline, outdir, isolate=isolate, ext=ext, force=args.force,
                         dry_run=args.dry_run)
    done = 0
    with ProgressBar(len(inputs), "run") as bar:
        def report(rec: dict) -> None:
            nonlocal done
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
