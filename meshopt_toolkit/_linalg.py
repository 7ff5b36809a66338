"""Small dense kernels shared by the hot paths."""

from __future__ import annotations

import numpy as np

from ._typing import FloatArray


def dot(a: FloatArray, b: FloatArray) -> float:
    """Euclidean inner product ``vec a · vec b`` of two arrays of equal shape.

    ``np.einsum`` on flat views rather than ``np.vdot``/BLAS ``ddot``: multi-threaded
    OpenBLAS wakes its threads on every call, which on a busy machine can cost far more
    than the arithmetic; einsum is single-threaded and predictable. No copies for contiguous
    arrays.
    """
    return float(np.einsum("i,i->", np.ravel(a), np.ravel(b)))
