"""Mesh motion with per-triangle quality guarantees.

The metric of this package is the graph metric of the per-triangle distortion
(:mod:`.strain`): a mesh ``Q`` is embedded as ``X(Q) = (m^½ ⊙ Q, w·φ(Q))`` where ``φ_t`` is the
strain of triangle ``t`` relative to a reference mesh, and ``g = M + w² JᵀJ`` (``J = ∂φ/∂Q``).
Along any path, ``|φ_t(γ(s)) − φ_t(γ(0))| ≤ ℓ(s)/w`` for EVERY triangle (``ℓ`` the length of
the path so far), whatever the number of triangles; with ``φ_t`` → ∞ at every degenerate
triangle the metric is complete. See :mod:`.strain` for the bound on the shape quality.

Modules: :mod:`.strain` (φ and its Jacobian), :mod:`.graph_metric` (the metric, a
:class:`~meshopt_toolkit.riemannian.metrics.Metric`), :mod:`.similarity` (the similarities
of the plane and of space factored out of every motion, and the one handle path),
:mod:`.path` (the path energy as a sparse nonlinear least-squares problem, whose discrete
geodesics :func:`~meshopt_toolkit.riemannian.discrete_geodesic.discrete_geodesic` computes
by Levenberg–Marquardt), :mod:`.continuation` (the one continuation loop, ``march``),
:mod:`.move` (prescribed motion of handle vertices), :mod:`.morph` (morphing between two
meshes). Tet meshes: :mod:`.tet_distortion` (φ ∈ R⁷ per tet), :mod:`.tet_metric`,
:mod:`.similarity_3d` (a whole point set's similarity, tet boundary faces),
:mod:`.tet_least_squares` and :mod:`.tet_move` (prescribed motion, ``move_tets``).
"""
