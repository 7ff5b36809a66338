"""ARAP with contact: a clean reference for ``bench_surface_clean_peer.py``.

What a user gets from libigl-style ARAP plus Incremental Potential Contact (Li et al.
2020, through ipctk): minimize

    E(x) = ARAP(x) + κ B(x)

* ARAP(x): Sorkine & Alexa's energy ``Σ_i Σ_{j∈N(i)} w_ij |x_j − x_i − R_i (p_j − p_i)|²``
  with the rest cotangent weights clamped at 0 (as ``_surface_measures.arap_energy``
  measures it) and R_i the best rotation of vertex i's fan (the local step);
* B(x): ipctk's barrier potential over the point–triangle and edge–edge pairs nearer than
  ``dhat`` (a fraction of the mean rest edge length);

with the handles fixed, in ``steps`` increments of the handle path ``path(t)`` (as libigl's
ARAP in 10 steps), each from the previous increment's result. One iteration is a local
step (rotations fitted to x) and a Newton step on the global quadratic with those rotations
plus the barrier (its Hessian projected to PSD by ipctk), with a backtracking line search
whose first trial is capped by ipctk's CCD (``compute_collision_free_stepsize``), so no
iterate passes through the surface.

An increment starts by moving the handles: the free vertices follow the handle increment
by the Laplacian (cotangent) extension, and that predictor is taken whole when CCD says the
straight move from the previous result is collision free. Otherwise the move is cut to the
CCD-safe fraction and the handles become unknowns pulled to their targets by a spring
``½ k Σ_h |x_h − target_h|²`` (IPC's treatment of prescribed boundary motion), k first
100× the mean diagonal of ARAP's Hessian and ×10 after each solve (at most 8) that leaves
a handle off its target by more than ``1e-3 · mean edge``; once within it, the handles
are snapped (a CCD-checked move) and fixed again.

κ is IPC's adaptive barrier stiffness (ipctk's ``initial_barrier_stiffness`` at the first
contact, raised by ``update_barrier_stiffness`` while the minimum distance falls), with the
mean diagonal entry of ARAP's Hessian standing for IPC's mean mass.

This module is benchmark-only: it imports no motion code of the package.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from _surface_measures import _vertex_covariances, best_rotations, cotangent_weights


@dataclass
class Arap:
    """The rest data of the ARAP energy: rest points ``V0`` (n, 3), undirected edges ``E``
    (k, 2), clamped cotangent weights ``W`` (k,), the edge difference operator ``D``
    (k, n) (``D x = x_j − x_i``) and the vertex-major Hessian ``H`` (3n, 3n)."""

    V0: np.ndarray
    E: np.ndarray
    W: np.ndarray
    D: sp.csr_matrix
    H: sp.csr_matrix = field(repr=False)

    @classmethod
    def from_mesh(cls, V0: np.ndarray, F: np.ndarray) -> "Arap":
        V0 = np.asarray(V0, float)
        E, W = cotangent_weights(V0, F)
        W = np.maximum(W, 0.0)
        k = len(E)
        D = sp.coo_matrix((np.r_[-np.ones(k), np.ones(k)],
                           (np.r_[np.arange(k), np.arange(k)], np.r_[E[:, 0], E[:, 1]])),
                          shape=(k, len(V0))).tocsr()
        L = (D.T @ sp.diags(W) @ D).tocsr()
        return cls(V0, E, W, D, sp.kron(4.0 * L, sp.eye(3), format="csr"))

    def rotations(self, X: np.ndarray) -> np.ndarray:
        """The local step: each vertex's best rotation (n, 3, 3) of its weighted fan."""
        return best_rotations(_vertex_covariances(self.V0, X, self.E, self.W))

    def _rotated(self, R: np.ndarray) -> np.ndarray:
        e0 = self.V0[self.E[:, 1]] - self.V0[self.E[:, 0]]
        return np.einsum("kij,kj->ki", R[self.E[:, 0]] + R[self.E[:, 1]], e0)

    def value(self, X: np.ndarray, R: np.ndarray | None = None) -> float:
        """ARAP(X) with the rotations ``R`` (the best ones, the local step, when None)."""
        R = self.rotations(X) if R is None else R
        e0 = self.V0[self.E[:, 1]] - self.V0[self.E[:, 0]]
        e1 = X[self.E[:, 1]] - X[self.E[:, 0]]
        ri = e1 - np.einsum("kij,kj->ki", R[self.E[:, 0]], e0)
        rj = e1 - np.einsum("kij,kj->ki", R[self.E[:, 1]], e0)
        return float(np.sum(self.W * (np.sum(ri * ri, 1) + np.sum(rj * rj, 1))))

    def gradient(self, X: np.ndarray, R: np.ndarray | None = None) -> np.ndarray:
        """Gradient (3n,) vertex-major of ARAP at X with rotations R (best when None: the
        gradient of the energy with the local step, by the envelope theorem)."""
        R = self.rotations(X) if R is None else R
        e1 = self.D @ X
        g = self.W[:, None] * (4.0 * e1 - 2.0 * self._rotated(R))
        return np.asarray(self.D.T @ g).ravel()


def mean_edge_length(V: np.ndarray, F: np.ndarray) -> float:
    """Mean length of the undirected edges of a triangle mesh."""
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), 1), axis=0)
    return float(np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1).mean())


class Contact:
    """ipctk's barrier on a triangle surface: ``value``, ``gradient``, ``hessian`` (PSD
    projected), the CCD step bound and the minimum distance, with stiffness ``kappa``."""

    def __init__(self, V0: np.ndarray, F: np.ndarray, dhat: float):
        import ipctk

        self.ipctk = ipctk
        edges = ipctk.edges(np.asarray(F, np.int32))
        self.mesh = ipctk.CollisionMesh(np.asfortranarray(V0, float), edges,
                                        np.asarray(F, np.int32))
        self.dhat = dhat
        self.potential = ipctk.BarrierPotential(dhat, 1.0)
        self.kappa = 0.0
        self.kappa_max = 0.0
        self._last = None
        self.ccd = ipctk.AdditiveCCD()  # conservative; far faster than Tight Inclusion near contact

    def collisions(self, X: np.ndarray):
        """The pairs nearer than dhat at X (the last set kept for the same X)."""
        if self._last is not None and np.array_equal(self._last[0], X):
            return self._last[1]
        c = self.ipctk.NormalCollisions()
        c.build(self.mesh, np.asfortranarray(X), self.dhat)
        self._last = (X.copy(), c)
        return c

    def value(self, X: np.ndarray) -> float:
        """Barrier potential at X (stiffness 1)."""
        return float(self.potential(self.collisions(X), self.mesh, np.asfortranarray(X)))

    def gradient(self, X: np.ndarray) -> np.ndarray:
        return np.asarray(self.potential.gradient(self.collisions(X), self.mesh,
                                                  np.asfortranarray(X))).ravel()

    def hessian(self, X: np.ndarray, project: bool = True) -> sp.csr_matrix:
        how = (self.ipctk.PSDProjectionMethod.CLAMP if project
               else self.ipctk.PSDProjectionMethod.NONE)
        return sp.csr_matrix(self.potential.hessian(self.collisions(X), self.mesh,
                                                    np.asfortranarray(X), how))

    def max_step(self, X0: np.ndarray, X1: np.ndarray) -> float:
        """The largest fraction of the straight move X0 → X1 that CCD finds collision free."""
        return float(self.ipctk.compute_collision_free_stepsize(
            self.mesh, np.asfortranarray(X0), np.asfortranarray(X1),
            narrow_phase_ccd=self.ccd))

    def min_distance(self, X: np.ndarray) -> float:
        c = self.collisions(X)
        return float(c.compute_minimum_distance(self.mesh, np.asfortranarray(X))) \
            if len(c) else np.inf

    def adapt(self, X, grad_energy, average_mass, previous_distance) -> float:
        """IPC's adaptive κ: initialised at the first contact from the gradients, raised
        while the minimum distance keeps falling; returns the new minimum distance."""
        d = self.min_distance(X)
        if not np.isfinite(d):
            return d
        diag = float(np.linalg.norm(np.ptp(X, axis=0)))
        if self.kappa == 0.0:
            self.kappa, self.kappa_max = self.ipctk.initial_barrier_stiffness(
                diag, self.potential.barrier, self.dhat, average_mass, grad_energy,
                self.gradient(X))
        elif np.isfinite(previous_distance):
            self.kappa = self.ipctk.update_barrier_stiffness(
                previous_distance, d, self.kappa_max, self.kappa, diag)
        return d


@dataclass
class Result:
    """The peer's result: points (n, 3), per-increment Newton iterations, whether each
    increment converged, how many increments needed the handle spring, final κ."""

    points: np.ndarray
    iterations: list
    converged: list
    spring_increments: int
    kappa: float
    message: str = ""


def _laplacian_extension(arap: Arap, X, handles, target, free):
    """X with the handles at ``target`` and the free vertices moved by the cotangent
    Laplacian extension of the handle increment."""
    L = (arap.D.T @ sp.diags(arap.W) @ arap.D).tocsc()
    U = np.zeros_like(X)
    U[handles] = target - X[handles]
    Lff = L[free][:, free]
    rhs = -(L[free][:, handles] @ U[handles])
    U[free] = spla.splu(Lff.tocsc()).solve(rhs)
    return X + U


class _Solver:
    """Newton iterations of one increment (the local step before each)."""

    def __init__(self, arap: Arap, contact: Contact, tolerance: float):
        self.arap, self.contact, self.tol = arap, contact, tolerance
        self.average_mass = float(arap.H.diagonal().mean())
        self.distance = np.inf
        self._factor = None

    def _solve(self, H, dofs, constant):
        """A solve with H restricted to ``dofs``; ARAP's own Hessian factored once."""
        if constant and self._factor is not None and np.array_equal(self._factor[0], dofs):
            return self._factor[1]
        solve = spla.splu(H.tocsr()[dofs][:, dofs].tocsc()).solve
        if constant:
            self._factor = (dofs, solve)
        return solve

    def energy(self, X, R, spring):
        e = self.arap.value(X, R)
        if self.contact.kappa > 0:
            e += self.contact.kappa * self.contact.value(X)
        if spring is not None:
            k, idx, target = spring
            e += 0.5 * k * float(np.sum((X[idx] - target) ** 2))
        return e

    def iterate(self, X, fixed, spring, max_iterations):
        """Newton on the free DOFs (the vertices not in ``fixed``) until the step's largest
        displacement is below tolerance; returns (X, iterations, converged)."""
        n = len(X)
        free = np.setdiff1d(np.arange(n), fixed)
        dofs = (3 * free[:, None] + np.arange(3)).ravel()
        for it in range(1, max_iterations + 1):
            R = self.arap.rotations(X)
            g = self.arap.gradient(X, R)
            self.distance = self.contact.adapt(X, g, self.average_mass, self.distance)
            H = self.arap.H
            touching = self.contact.kappa > 0 and len(self.contact.collisions(X)) > 0
            if touching:
                g = g + self.contact.kappa * self.contact.gradient(X)
                H = H + self.contact.kappa * self.contact.hessian(X)
            if spring is not None:
                k, idx, target = spring
                G = np.zeros_like(X)
                G[idx] = k * (X[idx] - target)
                g = g + G.ravel()
                s = np.zeros(n)
                s[idx] = k
                H = H + sp.diags(np.repeat(s, 3))
            p = np.zeros(3 * n)
            p[dofs] = -self._solve(H, dofs, constant=not touching and spring is None)(g[dofs])
            P = p.reshape(n, 3)
            alpha = min(1.0, self.contact.max_step(X, X + P))
            e0, slope = self.energy(X, R, spring), float(g @ p)
            while alpha > 1e-12:
                Y = X + alpha * P
                if self.energy(Y, R, spring) <= e0 + 1e-4 * alpha * slope:
                    break
                alpha *= 0.5
            else:
                return X, it, False
            X = Y
            if np.abs(alpha * P).max() < self.tol:
                return X, it, True
        return X, max_iterations, False


def arap_contact(V0, F, handles, path, steps: int = 10, dhat_scale: float = 0.1,
                 max_iterations: int = 50, tolerance: float = 1e-4) -> Result:
    """ARAP with IPC contact along the handle path (module docstring).

    Parameters
    ----------
    V0 : (n, 3) float array, the rest surface; F : (m, 3) int array
    handles : (h,) int array; path : callable t ↦ (h, 3) handle positions, path(0) = rest
    steps : increments of the path
    dhat_scale : the barrier's activation distance as a fraction of the mean edge length
    max_iterations : Newton iterations per increment (and per spring stage)
    tolerance : convergence when the largest vertex move of a step is below
        ``tolerance · mean edge length``

    Returns
    -------
    Result
    """
    V0 = np.asarray(V0, float)
    handles = np.asarray(handles, int)
    h = mean_edge_length(V0, F)
    arap, contact = Arap.from_mesh(V0, F), Contact(V0, F, dhat_scale * h)
    solver = _Solver(arap, contact, tolerance * h)
    free = np.setdiff1d(np.arange(len(V0)), handles)
    X = V0.copy()
    iterations, converged, springs = [], [], 0
    for k in range(1, steps + 1):
        target = np.asarray(path(k / steps), float)
        guess = _laplacian_extension(arap, X, handles, target, free)
        alpha = contact.max_step(X, guess)
        its = 0
        if alpha < 1.0:
            springs += 1
            X = X + alpha * (guess - X)
            stiffness = 1e2 * solver.average_mass
            for _ in range(8):
                X, n_it, _ = solver.iterate(X, np.array([], int), (stiffness, handles, target),
                                            max_iterations)
                its += n_it
                off = np.abs(X[handles] - target).max()
                if off < 1e-3 * h:
                    break
                stiffness *= 10.0
            snapped = X.copy()
            snapped[handles] = target
            if contact.max_step(X, snapped) < 1.0:
                return Result(X, iterations + [its], converged + [False], springs,
                              contact.kappa, f"increment {k}: the handles cannot reach "
                              f"their targets without contact (off by {off:.2e})")
            X = snapped
        else:
            X = guess
        X, n_it, ok = solver.iterate(X, handles, None, max_iterations)
        iterations.append(its + n_it)
        converged.append(ok)
    return Result(X, iterations, converged, springs, contact.kappa)
