"""Kernels: plain functions of point and index arrays, vectorized over triangles or
boundary pairs (edge vectors, signed areas, quality measures, the regularized
vertex–edge distance, admissibility tests). No classes with state, no I/O."""
