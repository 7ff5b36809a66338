"""Mesh motion with per-triangle quality guarantees.

The metric of this package is the graph metric of the per-triangle distortion
(:mod:`.planar.distortion`): a mesh ``Q`` is embedded as ``X(Q) = (m^½ ⊙ Q, w·φ(Q))`` where ``φ_t`` is the
strain of triangle ``t`` relative to a reference mesh, and ``g = M + w² JᵀJ`` (``J = ∂φ/∂Q``).
Along any path, ``|φ_t(γ(s)) − φ_t(γ(0))| ≤ ℓ(s)/w`` for EVERY triangle (``ℓ`` the length of
the path so far), whatever the number of triangles; with ``φ_t`` → ∞ at every degenerate
triangle the metric is complete. See :mod:`.planar.distortion` for the bound on the shape quality.

Layout: :mod:`.move` (``mt.move``: every kind of mesh, at unit size); :mod:`.engine` (what
every cell kind shares: handle paths, the continuation loop, sparse patterns, contact,
polish helpers); one subpackage per cell kind, each with its distortion, metric, move and
morph: :mod:`.planar` (triangles in the plane), :mod:`.surface` (triangles in space),
:mod:`.tets` (tetrahedra).
"""
