"""The batch options and their plumbing, shared by ``meshopt run`` and ``meshopt convert``:
``--jobs``, ``--resume``, ``--scheduler``, ``--shared-inputs`` (:func:`add_batch_args`,
:func:`check_batch_args`), the Dask client (:func:`batch_client`) and the per-record
report (:func:`reporter`)."""

from __future__ import annotations

import contextlib

from .. import strict_json
from ..errors import MeshoptError
from ._validate import int_at_least


def add_batch_args(parser) -> None:
    """``--jobs``, ``--resume``, ``--scheduler``, ``--shared-inputs``."""
    parser.add_argument("-j", "--jobs", type=_jobs, default=1, metavar="N",
                        help="files processed in N worker processes (0: all cores; "
                             "default 1)")
    parser.add_argument("--resume", action="store_true",
                        help="skip files an earlier run (killed or not) completely did with "
                             "the same input and settings (journal in the output directory)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on this Dask cluster, e.g. tcp://10.0.0.5:8786 (needs "
                             "meshopt-toolkit[dask])")
    parser.add_argument("--shared-inputs", action="store_true",
                        help="with --scheduler: workers read the inputs from the same path "
                             "(a shared file system) instead of receiving their bytes")


def _jobs(text: str) -> int:
    from ..batch.workers import cpu_count

    value = int_at_least(0, "0 (all cores) or a positive integer")(text)
    return cpu_count() if value == 0 else value


def check_batch_args(args) -> None:
    """Refuse contradictory batch options (one line, exit 1)."""
    if args.shared_inputs and not args.scheduler:
        raise MeshoptError("--shared-inputs is for --scheduler (local workers read the "
                           "inputs directly)")
    if args.scheduler and args.jobs != 1:
        raise MeshoptError("--jobs is for local workers; with --scheduler the cluster's "
                           "workers do the work")
    if getattr(args, "isolate", None) == "never" and args.jobs > 1:
        raise MeshoptError("--isolate never needs --jobs 1 (several jobs run in worker "
                           "processes)")
    if args.resume and getattr(args, "dry_run", False):
        raise MeshoptError("--resume and --dry-run cannot be combined (a dry run writes "
                           "nothing)")


@contextlib.contextmanager
def batch_client(args):
    """A Dask client for ``--scheduler`` (closed afterwards), else None."""
    if not args.scheduler:
        yield None
        return
    from ..batch.cluster import connect

    client = connect(args.scheduler)
    try:
        yield client
    finally:
        client.close()


def reporter(command: str, as_json: bool, bar, line_ok=None, dry_run: bool = False):
    """The per-record callback: warnings and errors on stderr, each naming the input, JSON
    lines on stdout (with ``"dry_run": true`` in a dry run), and ``line_ok(record)`` on
    stdout for each file done (``meshopt convert``'s "wrote ...", a dry run's "would
    write ...")."""
    from ._errors import naming

    def report(rec: dict) -> None:
        for warning in rec.get("warnings") or ():
            bar.message(f"meshopt {command}: warning: {naming(warning, [rec['input']])}")
        if rec["status"] == "failed":
            bar.message(f"meshopt {command}: error: {naming(rec['error'], [rec['input']])}")
        elif rec["status"] == "ok" and line_ok is not None:
            bar.clear()
            print(line_ok(rec), flush=True)
        if as_json:
            print(strict_json.dumps({**rec, "dry_run": True} if dry_run else rec), flush=True)

    return report
