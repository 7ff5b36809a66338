"""Exception hierarchy of meshopt-toolkit.

The library raises these; only the command line turns them into one-line messages and
exit codes.
"""

from __future__ import annotations


class MeshoptError(Exception):
    """Base class of every error raised on purpose by meshopt-toolkit."""


class InvalidMeshError(MeshoptError, ValueError):
    """A mesh fails a validity check (readable, planar-manifold or admissible).

    The message names the offending vertex, triangle or edge.
    """


class NotAdmissibleError(InvalidMeshError):
    """A configuration has an inverted or zero-area triangle, or self-intersects."""


class ReadError(MeshoptError):
    """A file cannot be read as a mesh; the message names the file."""


class WriteError(MeshoptError):
    """A mesh cannot be written; the message names the file."""


class FileWriteError(WriteError):
    """A file cannot be written where it was asked: it exists (not overwriting), its
    folder is missing, or the file system refused (the message names the file and the
    OS error). Not a matter of what the format can hold: never retried with less."""


class FilterError(MeshoptError):
    """A filter or pipeline is invalid or failed."""


class ExpressionError(MeshoptError, ValueError):
    """A user expression (e.g. a right-hand side) is malformed or not allowed."""


class IntegrationError(MeshoptError):
    """A geodesic integration failed (step size underflow, drift, or leaving M+)."""


class OptimizationError(MeshoptError):
    """An optimization run cannot proceed (e.g. no descent direction)."""


class OptionError(MeshoptError, ValueError):
    """An operation's argument or option is invalid (a number out of range, an unknown
    method, metric or variant); raised before any work."""


class SelfIntersectionError(NotAdmissibleError):
    """A surface in space (or a tet mesh's boundary) intersects itself; the message
    names how many pairs of triangles and one of them."""
