"""The one owner of similarities and of the handles' paths, in the plane and in space.

Similarities ``z ↦ a z + b`` of the plane (complex ``a = s·e^{iθ}``, :class:`Similarity`)
and ``x ↦ c + b + s R (x − c)`` of space (:class:`Similarity3`): fitting (closed forms),
the inverse, two paths from the identity (``at``: the centre along the chord; ``screw``:
about the similarity's own fixed point or axis line). Handles are grouped by the connected
pieces of any cells joining them (:func:`handle_groups`: boundary edges, a surface's
triangles, a tet mesh's boundary faces) and each group follows its best similarity along
one of :data:`HANDLE_MOTIONS` plus the straight remainder (:class:`HandlePath`): the one
handle path of planar, tet and surface motions.

Every motion is factored as a similarity (closed form) composed with a residual
deformation; the distortions do not see rotations and see a uniform scale only as the same
shift of every cell's measure, so a motion that IS a similarity is followed exactly.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

from ..._typing import FloatArray, IntArray
from ...errors import OptionError
from ...scaling import UnitScale

#: the paths of :class:`HandlePath`: a group's similarity along its chord or screw motion
HANDLE_MOTIONS = ("chord", "screw")


def _c(P: FloatArray) -> np.ndarray:
    return P[:, 0] + 1j * P[:, 1]


def _r(z: np.ndarray) -> FloatArray:
    return np.column_stack([z.real, z.imag])


@dataclass(frozen=True)
class Similarity:
    """``z ↦ center + shift + a (z − center)`` with ``a = exp(log_scale + i·angle)``."""

    center: complex
    shift: complex
    log_scale: float
    angle: float

    @property
    def a(self) -> complex:
        return complex(np.exp(self.log_scale + 1j * self.angle))

    def __call__(self, P: FloatArray) -> FloatArray:
        return _r(self.center + self.shift + self.a * (_c(P) - self.center))

    def inverse(self, P: FloatArray) -> FloatArray:
        return _r(self.center + (_c(P) - self.center - self.shift) / self.a)

    def at(self, s: float) -> Similarity:
        """The similarity a fraction ``s`` of the way (angle, log-scale, shift linear)."""
        return Similarity(self.center, s * self.shift, s * self.log_scale, s * self.angle)

    def screw(self, s: float) -> Similarity:
        """The similarity a fraction ``s`` of its spiral motion ``p + a^s (z − p)`` about
        its fixed point ``p`` (a translation within 1e-6: :meth:`at`); ``s = 1``: itself."""
        if s == 1.0 or abs(1.0 - self.a) < 1e-6:
            return self if s == 1.0 else self.at(s)
        a_s = complex(np.exp(s * (self.log_scale + 1j * self.angle)))
        return Similarity(self.center, (1.0 - a_s) * self.shift / (1.0 - self.a),
                          s * self.log_scale, s * self.angle)

    @property
    def is_identity(self) -> bool:
        return self.shift == 0 and self.log_scale == 0 and self.angle == 0

    def as_dict(self) -> dict:
        """JSON-ready: ``angle_degrees``, ``scale`` and ``shift`` ``[x, y]``."""
        return {"angle_degrees": float(np.degrees(self.angle)),
                "scale": float(np.exp(self.log_scale)),
                "shift": [self.shift.real, self.shift.imag]}

    def scaled_up(self, scale: UnitScale) -> Similarity:
        """This similarity of unit-size coordinates in the user's (centre and shift
        multiplied by ``scale.factor``; the angle and scale are the same)."""
        (cx, sx), (cy, sy) = scale.up([[self.center.real, self.shift.real],
                                       [self.center.imag, self.shift.imag]])
        return Similarity(complex(cx, cy), complex(sx, sy), self.log_scale, self.angle)


def fit_similarity(source: FloatArray, target: FloatArray,
                   weights: FloatArray | None = None) -> Similarity:
    """Least-squares similarity taking ``source`` points to ``target`` points (Procrustes
    with scale, about the weighted centroid of ``source``); the angle in (−π, π]."""
    zs, zt = _c(np.asarray(source, float)), _c(np.asarray(target, float))
    w = np.ones(len(zs)) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    cs, ct = w @ zs, w @ zt
    ds, dt = zs - cs, zt - ct
    denom = float(w @ np.abs(ds) ** 2)
    if len(zs) < 2 or denom == 0.0:
        return Similarity(complex(cs), complex(ct - cs), 0.0, 0.0)
    a = complex(w @ (np.conj(ds) * dt)) / denom
    if a == 0:
        return Similarity(complex(cs), complex(ct - cs), 0.0, 0.0)
    return Similarity(complex(cs), complex(ct - cs), float(np.log(abs(a))), float(np.angle(a)))


@dataclass(frozen=True)
class Similarity3:
    """``x ↦ centre + shift + exp(log_scale) · R (x − centre)``, ``R`` = the rotation of
    ``rotvec`` (axis × angle, angle in [0, π] from a fit, up to 2π for a half turn taken
    the other way round); the coordinates in which :meth:`at` is linear, as
    :class:`.similarity.Similarity` in the plane."""

    centre: FloatArray
    shift: FloatArray
    log_scale: float
    rotvec: FloatArray

    @classmethod
    def identity(cls) -> Similarity3:
        return cls(np.zeros(3), np.zeros(3), 0.0, np.zeros(3))

    @property
    def scale(self) -> float:
        return float(np.exp(self.log_scale))

    @property
    def rotation(self) -> FloatArray:
        """``R`` (3×3, det +1)."""
        return Rotation.from_rotvec(self.rotvec).as_matrix()

    @property
    def matrix(self) -> FloatArray:
        """``s R`` (3×3)."""
        return np.exp(self.log_scale) * self.rotation

    @property
    def image(self) -> FloatArray:
        """Where the centre goes, ``centre + shift``."""
        return self.centre + self.shift

    @property
    def angle(self) -> float:
        return float(np.linalg.norm(self.rotvec))

    @property
    def is_identity(self) -> bool:
        return (not np.any(self.shift) and self.log_scale == 0.0
                and not np.any(self.rotvec))

    def as_dict(self) -> dict:
        """JSON-ready: ``angle_degrees``, the unit rotation ``axis``, ``scale`` and
        ``shift``."""
        return {"angle_degrees": float(np.degrees(self.angle)),
                "axis": (self.rotvec / (self.angle or 1.0)).tolist(),
                "scale": float(np.exp(self.log_scale)), "shift": self.shift.tolist()}

    def scaled_up(self, scale: UnitScale) -> Similarity3:
        """This similarity of unit-size coordinates in the user's (centre and shift
        scaled up; the rotation and scale are the same)."""
        return Similarity3(scale.up(self.centre), scale.up(self.shift), self.log_scale,
                           self.rotvec)

    def __call__(self, P: FloatArray) -> FloatArray:
        return self.centre + self.shift + (np.asarray(P, float) - self.centre) @ self.matrix.T

    def inverse(self, P: FloatArray) -> FloatArray:
        """The inverse map applied to ``P``."""
        return self.centre + (np.asarray(P, float) - self.centre - self.shift) @ np.linalg.inv(
            self.matrix).T

    def at(self, t: float) -> Similarity3:
        """The similarity a fraction ``t`` of the way along its path of least mass-weighted
        motion from the identity: the centre along the chord, the angle about the fixed
        axis and the log-scale linear in ``t`` (t = 1: the same similarity, bitwise)."""
        return Similarity3(self.centre, t * self.shift, t * self.log_scale, t * self.rotvec)

    def screw(self, t: float) -> Similarity3:
        """The similarity a fraction ``t`` of its screw (spiral) motion
        ``p + s^t R^t (x − p)`` plus the shift along the axis, about the axis line through
        ``p`` it turns about: a turn about a hinge moves along the arc, not the chord
        (t = 1: itself; ``screw(a)`` after ``screw(b)`` is ``screw(a + b)``)."""
        if t == 1.0:
            return self
        q, u, v_u = self._axis()
        log_st = t * self.log_scale
        # the shift along the axis under the scale: v_u (s^t − 1)/(s − 1), → t v_u at s = 1
        along = t if abs(self.log_scale) < 1e-12 else np.expm1(log_st) / np.expm1(
            self.log_scale)
        Rt = Rotation.from_rotvec(t * self.rotvec).as_matrix()
        return Similarity3(self.centre, q - np.exp(log_st) * (Rt @ q) + along * v_u * u,
                           log_st, t * self.rotvec)

    def _axis(self) -> tuple[FloatArray, FloatArray, float]:
        """``(p − c, u, b·u)``: the point of the axis line nearest the centre ``c``
        (relative to it), the unit axis ``u`` (0 without a turn) and the shift ``b``
        along it; ``(0, b/|b|, |b|)``, the chord, where the similarity is within 1e-6 of a
        translation."""
        v, angle = self.shift, self.angle
        if abs(1.0 - np.exp(self.log_scale + 1j * angle)) < 1e-6:
            size = float(np.linalg.norm(v))
            return np.zeros(3), (v / size if size > 0 else np.zeros(3)), size
        u = self.rotvec / angle if angle > 0 else np.zeros(3)
        v_u = float(v @ u)
        # (I − sR) maps the plane normal to u onto itself, invertibly: |1 − s e^{iθ}| > 0
        uu = np.outer(u, u)
        K = (np.eye(3) - self.matrix) @ (np.eye(3) - uu) + uu
        return np.linalg.solve(K, v - v_u * u), u, v_u


def fit_similarity_3d(source: FloatArray, target: FloatArray, scaling: bool = True
                      ) -> Similarity3:
    """Least-squares similarity taking ``source`` to ``target`` (Umeyama 1991: the
    rotation from the SVD of the cross-covariance, a reflection excluded; the scale that
    minimizes the residual, or 1 without ``scaling`` or where that scale is not positive),
    about the centroid of ``source``; a translation for fewer than 3 points or coincident
    ones."""
    X, Y = np.asarray(source, float), np.asarray(target, float)
    cx, cy = X.mean(axis=0), Y.mean(axis=0)
    Xc, Yc = X - cx, Y - cy
    var = float(np.sum(Xc**2))
    if len(X) < 3 or var == 0.0:
        return Similarity3(cx, cy - cx, 0.0, np.zeros(3))
    U, D, Vt = np.linalg.svd(Yc.T @ Xc)
    E = np.ones(3)
    E[2] = np.sign(np.linalg.det(U) * np.linalg.det(Vt)) or 1.0
    R = (U * E) @ Vt
    scale = float(D @ E) / var if scaling else 1.0
    log_scale = float(np.log(scale)) if scale > 0.0 else 0.0
    return Similarity3(cx, cy - cx, log_scale, Rotation.from_matrix(R).as_rotvec())


def rank_3d(points: FloatArray) -> int:
    """The dimension of the affine span of ``points`` (singular values above 1e-9 of the
    largest)."""
    if len(points) < 2:
        return 0
    x = points - points.mean(axis=0)
    s = np.linalg.svd(x, compute_uv=False)
    return int(np.sum(s > 1e-9 * max(s[0], 1e-300)))


def cell_edges(cells: IntArray) -> IntArray:
    """The edges ``(E, 2)`` of cells of ``k`` vertices ``(C, k)``, ``k ≥ 2``: the cells
    themselves for edges, each consecutive pair of a cell's vertices and the closing one
    for triangles, all six vertex pairs for tets (duplicates kept)."""
    C = np.asarray(cells)
    k = C.shape[1]
    if k == 2:
        return C
    pairs = [(0, 1), (1, 2), (2, 0)] if k == 3 else [(a, b) for a in range(k)
                                                      for b in range(a + 1, k)]
    return np.concatenate([C[:, list(p)] for p in pairs])


def handle_groups(handles: IntArray, cells: IntArray, n_vertices: int) -> list[IntArray]:
    """Positions (into ``handles``) of the handles grouped by connected pieces: handles
    joined by an edge of ``cells`` (boundary edges ``(E, 2)``, a surface's triangles, a tet
    mesh's boundary faces: :func:`cell_edges`) whose both ends are handles form one group;
    groups in the order of their first handle."""
    handles = np.asarray(handles)
    is_handle = np.full(n_vertices, -1)
    is_handle[handles] = np.arange(len(handles))
    e = cell_edges(cells)
    both = (is_handle[e[:, 0]] >= 0) & (is_handle[e[:, 1]] >= 0)
    i, j = is_handle[e[both, 0]], is_handle[e[both, 1]]
    graph = sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(len(handles), len(handles)))
    labels = connected_components(graph, directed=False)[1]
    return [np.flatnonzero(labels == c) for c in range(int(labels.max()) + 1 if len(labels)
                                                        else 0)]


class HandlePath:
    """Positions of the handles at fraction ``s`` of their motion from ``start`` to
    ``targets``, in the plane ``(k, 2)`` or in space ``(k, 3)``.

    Each group of handles (:func:`handle_groups`) follows the similarity that fits it best
    (:func:`fit_similarity`, :func:`fit_similarity_3d`) along its ``motion`` — "chord"
    (``at``: the centre along the chord) or "screw" (``screw``: about its fixed point or
    axis line, a turn about a hinge moves along the arc) — so a turning hole turns instead
    of collapsing through its centre, plus ``s`` times what the similarity leaves. A group
    with no similarity of its own (fewer than 3 handles; in space, a collinear one) moves
    linearly. Bitwise ``targets`` at ``s = 1``.
    """

    def __init__(self, start: FloatArray, targets: FloatArray, groups: list[IntArray],
                 motion: str = "chord") -> None:
        if motion not in HANDLE_MOTIONS:
            raise OptionError(f"motion must be one of {HANDLE_MOTIONS}, not {motion!r}")
        self.motion = motion
        self.start = np.asarray(start, float)
        self.targets = np.asarray(targets, float)
        planar = self.start.shape[1] == 2
        fit = fit_similarity if planar else fit_similarity_3d
        self.pieces = []
        for g in groups:
            X = self.start[g]
            turns = len(X) >= 3 if planar else rank_3d(X) >= 2
            S = fit(X, self.targets[g]) if turns else None
            rest = self.targets[g] - (S(X) if S is not None else X)
            self.pieces.append((g, S, rest))

    @property
    def similarities(self) -> list:
        """Each group's similarity (None: the group moves linearly)."""
        return [S for _, S, _ in self.pieces]

    def half_turns(self) -> list[int]:
        """The groups whose similarity turns by a half turn (within 1e-6 rad), the two
        ways round equally short: which one the fit took is its rounding's choice."""
        return [k for k, (_, S, _) in enumerate(self.pieces) if isinstance(S, Similarity3)
                and abs(S.angle - np.pi) <= 1e-6]

    def oriented_half_turns(self, centre: FloatArray) -> HandlePath:
        """This path with each half turn (:meth:`half_turns`) taken the way the scene
        decides, not the fit's rounding; ``centre`` is the moving body's centroid. Of the
        two ways, the one along which the group's centroid passes, half way, nearer
        ``centre`` (a cap turned about a hinge beside the body folds towards it); where
        both pass equally near (the centroid on the axis: a twist), the right-handed turn
        about the axis oriented from ``centre`` towards the group's centroid; where that is
        perpendicular too, the fit's way. The choice turns with the scene (rotation
        equivariant); a mirror image flips the second rule's handedness."""
        out = self
        for k in self.half_turns():
            if _half_turn_key(self.pieces[k][1], self.start[self.pieces[k][0]].mean(axis=0),
                              np.asarray(centre, float)) < 0.0:
                out = out.turned_the_other_way(k)
        return out

    def turned_the_other_way(self, k: int) -> HandlePath:
        """This path with group ``k``'s turn the other way round (the same rotation, its
        angle ``θ − 2π`` about the axis; in space only), the same targets."""
        g, S, rest = self.pieces[k]
        other = Similarity3(S.centre, S.shift, S.log_scale,
                            S.rotvec * (1.0 - 2.0 * np.pi / S.angle))
        out = copy.copy(self)
        out.pieces = self.pieces[:k] + [(g, other, rest)] + self.pieces[k + 1:]
        return out

    def __call__(self, s: float) -> FloatArray:
        if s >= 1.0:
            return self.targets.copy()  # bitwise the targets
        out = np.empty_like(self.start)
        for g, S, rest in self.pieces:
            if S is None:
                base = self.start[g]
            else:
                base = (S.screw(s) if self.motion == "screw" else S.at(s))(self.start[g])
            out[g] = base + s * rest
        return out


def _half_turn_key(S: Similarity3, group: FloatArray, centre: FloatArray) -> float:
    """Positive where ``S``'s own way of its half turn is the one
    :meth:`HandlePath.oriented_half_turns` takes, negative where the other is, 0 where
    neither rule decides. ``group``: the group's centroid at rest."""
    q, u, _ = S._axis()
    r = group - (S.centre + q)  # from the axis line's point nearest the fit's centre
    r_perp = r - (r @ u) * u
    size = float(np.linalg.norm(group - centre) + np.linalg.norm(r)) or 1.0
    # S's way passes, half way, through axis + r∥ + u × r⊥; the other through − u × r⊥
    nearer = -float(np.cross(u, r_perp) @ (group - r_perp - centre))
    if abs(nearer) > 1e-9 * size**2:
        return nearer
    along = float(u @ (group - centre))  # S right-handed about the axis towards the group
    return along if abs(along) > 1e-9 * size else 0.0
