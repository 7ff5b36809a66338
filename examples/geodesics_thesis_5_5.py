"""Reproduce the geodesic experiments of thesis §5.5 (figures 5.21–5.27).

Writes PNG figures (and a short text summary) into ``--out`` (default ``out/geodesics``):

- ``elementary_{translation,shear,scaling,rotation}.png``: 20 snapshots on [0, 3] of the
  geodesics of f1 (5.47) with α1, α3 ∈ {0, 0.5, 1} on the crossed-diagonal square
  (figs. 5.21–5.24); initial mesh red, final blue, inverted triangles filled red.
  For α1 = 0, f1 = (α3/2)‖Q − Qref‖² is smooth on all of R^{2N}: its metric is complete
  there but not on M+, and its geodesics may leave M+ (shown, as in the thesis).
  Velocities: translation (0.5, 0.25); shear (0.5 y, 0); scaling −0.5·q at the four
  corners only ("the tangent vectors at the four corner vertices are pointing inwards");
  rotation 0.5·(−y, x).
- ``squeeze_complete_vs_euclidean.png``: the 5-vertex square with the two bottom corners
  pushed inwards and upwards, 16 snapshots on [0, 2], complete (α1 = α3 = 1) vs Euclidean
  (fig. 5.25). The initial velocity is our reading of fig. 5.1 (the figure's arrows are not
  in the text): V = (±0.5, 1.25) at the bottom corners, so that the Euclidean path is
  degenerate at t = 0.8, as stated in §5.1.1.
- ``disc_aspect_ratio.png`` and ``disc_snapshots.png``: the 25-vertex disc with a
  boundary-only velocity, mesh aspect ratio along geodesics for α = α1 = α3 ∈ {0, 0.25,
  0.5, 0.75, 1} and 0.05 (fig. 5.26), snapshots at t = 0, 1, 2 (fig. 5.27). The thesis' velocity is
  only drawn; we use a squeeze (−0.6 x, 0.3 y) on the boundary.

Run: ``python examples/geodesics_thesis_5_5.py [--out DIR]`` (about a minute).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from meshopt_toolkit import data_path, load
from meshopt_toolkit.deform import deform
from meshopt_toolkit.riemannian.geodesics import geodesic
from meshopt_toolkit.kernels.triangles import aspect_ratios, signed_areas
from meshopt_toolkit.penalties import HeightPenalty
from meshopt_toolkit.plotting import (
    save_overlay_grid,
    save_quality_plot,
    save_snapshot_strip,
)


class ReferencePenalty:
    """f = (α3/2)‖Q − Qref‖², smooth on all of R^{2N} (f1 with α1 = α2 = 0)."""

    def __init__(self, reference, alpha3: float) -> None:
        self.reference = np.array(reference, dtype=float)
        self.alpha3 = float(alpha3)

    def value(self, Q):
        return 0.5 * self.alpha3 * float(np.sum((Q - self.reference) ** 2))

    def gradient(self, Q):
        return self.alpha3 * (Q - self.reference)

    def hvp(self, Q, V):
        return self.alpha3 * np.asarray(V, dtype=float)

    def gradient_and_curvature(self, Q, V):
        return self.gradient(Q), self.alpha3 * float(np.vdot(V, V))

    def is_admissible(self, Q):
        return bool(np.isfinite(Q).all())


def f1_path(mesh, V, alpha1, alpha3, times):
    """Points (K, N, 2) along the f1 geodesic (α2 = 0); straight lines for α1 = α3 = 0."""
    if alpha1 == 0 and alpha3 == 0:
        metric = None
    elif alpha1 == 0:
        metric = ReferencePenalty(mesh.points, alpha3)
    else:
        metric = HeightPenalty(mesh, alpha=(alpha1, 0.0, alpha3))
    return geodesic(metric, mesh.points, V, times[-1], times=times).points


def elementary(out: Path, log) -> None:
    mesh = load(data_path("square_crossed.msh")).as_planar()
    P = mesh.points
    corners = np.all(np.abs(P) == 1.0, axis=1)  # thesis: corner vectors point inwards
    velocities = {
        "translation": np.tile([0.5, 0.25], (len(P), 1)),
        "shear": np.stack([0.5 * P[:, 1], np.zeros(len(P))], axis=1),
        "scaling": np.where(corners[:, None], -0.5 * P, 0.0),
        "rotation": 0.5 * np.stack([-P[:, 1], P[:, 0]], axis=1),
    }
    times = np.linspace(0.0, 3.0, 20)
    levels = (0.0, 0.5, 1.0)
    for name, V in velocities.items():
        panels = []
        for a3 in levels:
            for a1 in levels:
                pts = f1_path(mesh, V, a1, a3, times)
                bad = sum(signed_areas(p, mesh.triangles).min() <= 0 for p in pts)
                panels.append((pts, f"α1 = {a1:g}, α3 = {a3:g}" + (" (leaves M+)" if bad else "")))
                ar = aspect_ratios(pts[-1], mesh.triangles).min()
                log(f"{name:12s} alpha1={a1:3.1f} alpha3={a3:3.1f}: final min aspect ratio "
                    f"{ar:7.3f}, frames outside M+: {bad}")
        save_overlay_grid(out / f"elementary_{name}.png", panels, mesh.triangles,
                          suptitle=f"{name}: 20 snapshots on [0, 3]")


def squeeze(out: Path, log) -> None:
    mesh = load(data_path("square5.msh")).as_planar()
    V = np.zeros((5, 2))
    V[0] = [0.5, 1.25]
    V[1] = [-0.5, 1.25]
    times = np.linspace(0.0, 2.0, 16)
    euclid = mesh.points[None] + times[:, None, None] * V[None]
    pen = HeightPenalty(mesh, alpha=(1.0, 0.0, 1.0))
    comp = geodesic(pen, mesh.points, V, 2.0, times=times, on_violation="raise")
    frames = np.empty((32, 5, 2))
    frames[0::2] = comp.points
    frames[1::2] = euclid
    titles = [f"{kind}, t = {t:.2f}" for t in times for kind in ("complete", "Euclidean")]
    save_snapshot_strip(out / "squeeze_complete_vs_euclidean.png", frames, mesh.triangles,
                        titles=titles, ncols=8, panel_size=2.0)
    ea = [signed_areas(p, mesh.triangles).min() for p in euclid]
    first_bad = times[np.argmax(np.array(ea) <= 0)]
    long = geodesic(pen, mesh.points, V, 50.0, times=np.linspace(0, 50, 101), on_violation="raise")
    la = [signed_areas(p, mesh.triangles).min() for p in long.points]
    # the bottom corners are repelled and reverse direction (thesis: around t = 0.53)
    fine = geodesic(pen, mesh.points, V, 2.0, times=np.linspace(0, 2, 201))
    along = fine.velocities[:, 0] @ V[0]
    turn = fine.times[np.argmax(along < 0)] if np.any(along < 0) else float("nan")
    log(f"squeeze: Euclidean path has a non-positive area from t = {first_bad:.2f} on (grid of "
        f"16 frames); complete path min area on [0, 2] = {min(signed_areas(p, mesh.triangles).min() for p in comp.points):.3g}, "
        f"on [0, 50] = {min(la):.3g}; bottom corners reverse direction at t = {turn:.2f} "
        "(nan: not with this velocity; thesis: t = 0.53 with its drawn one); "
        f"energy drift {long.max_energy_drift:.1e}")


def disc(out: Path, log) -> None:
    mesh = load(data_path("disc_25.msh")).as_planar()
    P = mesh.points
    b = mesh.boundary_vertices
    V = np.zeros_like(P)
    V[b] = np.stack([-0.6 * P[b, 0], 0.3 * P[b, 1]], axis=1)
    series = {}
    runs = {}
    for a in (0.0, 0.05, 0.25, 0.5, 0.75, 1.0):
        if a == 0:
            res = deform(mesh, V, time=2.0, frames=16, metric="euclidean")
        else:
            res = deform(mesh, V, time=2.0, frames=16, alpha=(a, 0.0, a))
        series[f"α = {a:g}"] = res.aspect_ratio
        runs[a] = res
        log(f"disc alpha={a:4.2f}: aspect ratio {res.aspect_ratio[0]:.3f} -> min "
            f"{res.aspect_ratio.min():.3f} (t = 2: {res.aspect_ratio[-1]:.3f})")
    log("disc: for alpha >= 0.25 the curves coincide: |grad f1| >> 1 there, and the geodesic "
        "equation becomes independent of the scale of f (A = -grad f c/(1 + |grad f|^2)); "
        "alpha = 0.05 (not in the thesis) shows the transition")
    times = runs[1.0].times
    save_quality_plot(out / "disc_aspect_ratio.png", times, series,
                      title="mesh aspect ratio along geodesics (boundary-only velocity)")
    frames, titles = [], []
    for t in (0.0, 1.0, 2.0):
        k = int(np.argmin(np.abs(times - t)))
        for a in (0.0, 0.25, 0.5):
            frames.append(runs[a].points[k])
            titles.append(f"α = {a:g}, t = {times[k]:.2f}")
    save_snapshot_strip(out / "disc_snapshots.png", np.array(frames), mesh.triangles,
                        titles=titles, ncols=3, panel_size=3.0)


def main() -> None:
    ap = argparse.ArgumentParser(description="thesis §5.5 geodesic experiments")
    ap.add_argument("--out", default="out/geodesics", help="output directory")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lines: list[str] = []

    def log(msg: str) -> None:
        print(msg)
        lines.append(msg)

    for part in (squeeze, disc, elementary):
        t0 = time.perf_counter()
        part(out, log)
        log(f"[{part.__name__}: {time.perf_counter() - t0:.1f} s]")
    (out / "summary.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"figures in {out}/")


if __name__ == "__main__":
    main()
