"""Kernels: plain functions of point and index arrays, vectorized over triangles or
boundary pairs (edge vectors, signed areas, quality measures, the regularized
vertex–edge distance, admissibility tests), tetrahedra (``tetrahedra``) and triangles in
3D (``surface``). No classes with state, no I/O."""
