"""Gmsh ``$NodeData`` sections: float point data written as gmsh views.

Each point datum becomes one ``$NodeData`` section (name, time 0, step 0, its number of
components, one row per node, the file's node tags), ASCII with
``repr`` values or binary doubles; meshio's gmsh reader (which :mod:`.gmsh` uses for
files with such sections) reads it back exactly, as float64. Gmsh views have 1, 3 or 9
components, so other shapes (texture coordinates (N, 2)) and non-float data are not
held.
"""

from __future__ import annotations

import numpy as np

#: components of a gmsh view: scalar, vector, tensor
COMPONENTS = (1, 3, 9)


def holds(name: str, values, n: int) -> bool:
    """Whether point datum ``name`` can be a ``$NodeData`` section of ``n`` nodes."""
    a = np.asarray(values)
    comps = 1 if a.ndim == 1 else (a.shape[1] if a.ndim == 2 else 0)
    return (a.dtype.kind == "f" and len(a) == n and comps in COMPONENTS
            and (a.ndim == 1 or comps > 1)  # (N, 1) would come back as (N,)
            and not any(c in name for c in '"\n\r'))


def write_node_data(fh, point_data: dict, binary: bool, tags=None) -> None:
    """Append one ``$NodeData`` section per point datum to the open file ``fh``, the
    nodes' ``tags`` in point order (default ``1..N``)."""
    for name, values in point_data.items():
        a = np.asarray(values, dtype=np.float64)
        rows = a.reshape(len(a), -1)
        n, k = rows.shape
        fh.write(f'$NodeData\n1\n"{name}"\n1\n0.0\n3\n0\n{k}\n{n}\n'.encode())
        node_tags = np.arange(1, n + 1) if tags is None else np.asarray(tags)
        if binary:
            rec = np.empty(n, dtype=[("tag", "<i4"), ("v", "<f8", (k,))])
            rec["tag"] = node_tags
            rec["v"] = rows
            fh.write(rec.tobytes() + b"\n")
        else:
            fh.write(_ascii_rows(node_tags, rows).encode())
        fh.write(b"$EndNodeData\n")


def _ascii_rows(tags: np.ndarray, rows: np.ndarray) -> str:
    """``tag v1 ... vk`` lines: ``%d`` then ``repr`` of each value (read back exactly)."""
    n, k = rows.shape
    line = "%d" + " %r" * k + "\n"
    flat = np.column_stack([tags.astype(object), rows.astype(object)]).ravel().tolist()
    return (line * n) % tuple(flat)
