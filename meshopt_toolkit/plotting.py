"""Matplotlib helpers: mesh snapshots, strips and overlays of snapshots, quality plots.

matplotlib is imported lazily, only when a function here is called, and figures are drawn
with the Agg canvas directly (``matplotlib.figure.Figure`` + ``FigureCanvasAgg``), so no
pyplot global state and no display are involved. Every ``save_*`` function writes one PNG
and returns its path. Inverted triangles (signed area ≤ 0) are filled in red so a broken
mesh is visible at a glance.

Install the extra with ``pip install meshopt-toolkit[plot]``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ._typing import FloatArray, IntArray
from .errors import MeshoptError
from .kernels.triangles import signed_areas
from .scaling import unit_scale

__all__ = [
    "draw_mesh",
    "save_mesh_png",
    "save_overlay",
    "save_overlay_grid",
    "save_quality_plot",
    "save_snapshot_strip",
]


def _figure(width: float, height: float, dpi: int):
    """A new Agg-backed ``Figure`` (lazy import; a clear error when matplotlib is missing)."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MeshoptError(
            "plotting needs matplotlib: pip install 'meshopt-toolkit[plot]'"
        ) from exc
    fig = Figure(figsize=(width, height), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path, tight: bool = True) -> Path:
    """Tighten the layout (``tight=False``: a layout set by hand is kept) and write the PNG
    atomically (temporary file, then rename)."""
    from .io import atomic_path

    if tight:
        fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        fig.savefig(os.fspath(tmp), dpi=fig.dpi, format="png")
    return path


def _save_titled(fig, ax, title: str | None, path) -> Path:
    """Set the axes' title (if any) and :func:`_save`."""
    if title:
        ax.set_title(title)
    return _save(fig, path)


def _one_axes(width: float, height: float, dpi: int):
    """A new :func:`_figure` with one axes filling it: ``(fig, ax)``."""
    fig = _figure(width, height, dpi)
    return fig, fig.add_subplot(1, 1, 1)


def _panels(n: int, ncols: int, panel_size: float, title_room: float, dpi: int):
    """A new :func:`_figure` of ``n`` square panels of ``panel_size`` inches in rows of
    ``ncols`` (fewer when ``n`` is smaller), ``title_room`` inches higher for a title:
    ``(fig, the panels' axes)``."""
    ncols = min(n, ncols)
    nrows = -(-n // ncols)
    fig = _figure(panel_size * ncols, panel_size * nrows + title_room, dpi)
    return fig, [fig.add_subplot(nrows, ncols, k + 1) for k in range(n)]


def draw_mesh(
    ax,
    points: FloatArray,
    triangles: IntArray,
    *,
    color: str = "0.2",
    linewidth: float = 0.7,
    alpha: float = 1.0,
    velocity: FloatArray | None = None,
    show_inverted: bool = True,
) -> None:
    """Draw the edges of a planar mesh on a matplotlib ``Axes``.

    Parameters
    ----------
    ax : matplotlib Axes
    points : (N, 2) positions
    triangles : (T, 3) connectivity
    color, linewidth, alpha : edge style
    velocity : (N, 2), optional
        Drawn as arrows at the vertices (nonzero ones only).
    show_inverted : fill triangles with signed area ≤ 0 in red
    """
    from matplotlib.collections import LineCollection, PolyCollection

    p = np.asarray(points, dtype=float)
    tri = np.asarray(triangles)
    loops = p[tri]  # (T, 3, 2)
    segs = np.concatenate([loops, loops[:, :1]], axis=1)  # closed triangles (T, 4, 2)
    ax.add_collection(LineCollection(segs, colors=color, linewidths=linewidth, alpha=alpha))
    if show_inverted:  # the signs at the mesh's power-of-two unit size: exact, no overflow
        bad = signed_areas(unit_scale(p).down(p), tri) <= 0
        if bad.any():
            ax.add_collection(PolyCollection(loops[bad], facecolors="red", alpha=0.4,
                                             edgecolors="red"))
    if velocity is not None:
        v = np.asarray(velocity, dtype=float)
        moving = np.any(v != 0, axis=1)
        if moving.any():
            ax.quiver(p[moving, 0], p[moving, 1], v[moving, 0], v[moving, 1],
                      angles="xy", scale_units="xy", scale=1.0, color="tab:green", width=0.004)
    ax.set_aspect("equal")
    ax.autoscale_view()


def _limits(frames: FloatArray, margin: float = 0.05):
    lo = frames.reshape(-1, 2).min(axis=0)
    hi = frames.reshape(-1, 2).max(axis=0)
    pad = margin * max(float(np.max(hi - lo)), 1e-12)
    return (lo[0] - pad, hi[0] + pad), (lo[1] - pad, hi[1] + pad)


def save_mesh_png(
    path,
    points: FloatArray,
    triangles: IntArray,
    *,
    title: str | None = None,
    velocity: FloatArray | None = None,
    size: float = 4.0,
    dpi: int = 120,
) -> Path:
    """One mesh (optionally with a velocity field) as a PNG."""
    fig, ax = _one_axes(size, size, dpi)
    draw_mesh(ax, points, triangles, velocity=velocity)
    frames = np.asarray(points, float)[None]
    if velocity is not None:
        frames = np.concatenate([frames, (np.asarray(points) + np.asarray(velocity))[None]])
    xl, yl = _limits(frames)
    ax.set_xlim(*xl)
    ax.set_ylim(*yl)
    return _save_titled(fig, ax, title, path)


def save_snapshot_strip(
    path,
    frames: FloatArray,
    triangles: IntArray,
    *,
    titles: Sequence[str] | None = None,
    ncols: int | None = None,
    share_axes: bool = True,
    panel_size: float = 2.5,
    dpi: int = 100,
) -> Path:
    """Snapshots ``frames`` (K, N, 2) side by side (wrapped into rows of ``ncols``).

    ``share_axes`` gives every panel the same limits (as thesis fig. 5.25), so motion and
    shrinking are visible.
    """
    frames = np.asarray(frames, dtype=float)
    fig, axes = _panels(len(frames), ncols or 6, panel_size, 0.3 if titles else 0, dpi)
    xl, yl = _limits(frames)
    for k, ax in enumerate(axes):
        draw_mesh(ax, frames[k], triangles, linewidth=0.5)
        if share_axes:
            ax.set_xlim(*xl)
            ax.set_ylim(*yl)
        ax.set_xticks([])
        ax.set_yticks([])
        if titles is not None:
            ax.set_title(titles[k], fontsize=8)
    return _save(fig, path)


def _overlay(ax, frames: FloatArray, triangles: IntArray) -> None:
    """Thesis style: first snapshot red, last blue, the ones between light grey."""
    for k in range(1, len(frames) - 1):
        draw_mesh(ax, frames[k], triangles, color="0.6", linewidth=0.4, alpha=0.7,
                  show_inverted=False)
    draw_mesh(ax, frames[0], triangles, color="tab:red", linewidth=0.9)
    if len(frames) > 1:
        draw_mesh(ax, frames[-1], triangles, color="tab:blue", linewidth=0.9)
    xl, yl = _limits(frames)
    ax.set_xlim(*xl)
    ax.set_ylim(*yl)


def save_overlay(path, frames: FloatArray, triangles: IntArray, *, title: str | None = None,
                 size: float = 4.0, dpi: int = 120) -> Path:
    """All snapshots of a path in one axes: initial red, final blue, between grey."""
    fig, ax = _one_axes(size, size, dpi)
    _overlay(ax, np.asarray(frames, float), triangles)
    return _save_titled(fig, ax, title, path)


def save_overlay_grid(
    path,
    panels: Sequence[tuple[FloatArray, str]],
    triangles: IntArray,
    *,
    ncols: int = 3,
    panel_size: float = 3.0,
    suptitle: str | None = None,
    dpi: int = 100,
) -> Path:
    """A grid of overlays, one per ``(frames (K, N, 2), title)`` panel (thesis fig. 5.21)."""
    fig, axes = _panels(len(panels), ncols, panel_size, 0.4 if suptitle else 0, dpi)
    for ax, (frames, title) in zip(axes, panels):
        _overlay(ax, np.asarray(frames, float), triangles)
        ax.set_title(title, fontsize=9)
        ax.tick_params(labelsize=7)
    if suptitle:
        fig.suptitle(suptitle)
    return _save(fig, path)


def save_quality_plot(
    path,
    times: FloatArray,
    series: Mapping[str, FloatArray],
    *,
    ylabel: str = "mesh aspect ratio  min 2r/R",
    title: str | None = None,
    size: tuple[float, float] = (6.0, 4.0),
    dpi: int = 120,
    yscale: str = "linear",
) -> Path:
    """Quality over time, one line per labelled series (thesis fig. 5.26).

    ``series`` maps a label to values (K,) at ``times`` (K,) (or ``(times_k, values_k)``
    pairs when the series have different times). ``yscale="symlog"`` shows values over
    several decades of either sign (linear below the smallest nonzero |value|).
    """
    fig, ax = _one_axes(*size, dpi)
    for label, vals in series.items():
        if isinstance(vals, tuple):
            t, y = vals
        else:
            t, y = times, vals
        ax.plot(np.asarray(t), np.asarray(y), marker="o", markersize=3, label=label)
    ax.set_xlabel("t")
    ax.set_ylabel(ylabel)
    if yscale == "symlog":
        values = np.concatenate([np.ravel(v[1] if isinstance(v, tuple) else v)
                                 for v in series.values()])
        nonzero = np.abs(values[np.isfinite(values) & (values != 0)])
        ax.set_yscale("symlog", linthresh=float(nonzero.min()) if nonzero.size else 1.0)
    elif yscale != "linear":
        ax.set_yscale(yscale)
    ax.axhline(0.0, color="0.7", linewidth=0.8)
    ax.grid(True, alpha=0.3)
    ax.legend()
    return _save_titled(fig, ax, title, path)


def save_optimization_plots(
    mesh_path,
    history_path,
    initial: FloatArray,
    final: FloatArray,
    triangles: IntArray,
    history: Mapping[str, FloatArray],
    rhs=None,
    *,
    dpi: int = 120,
) -> tuple[Path, Path]:
    """Figures of a shape-optimization run (thesis fig. 6.4–6.7).

    ``mesh_path``: the initial and the final mesh side by side over filled contours of the
    right-hand side ``rhs`` (a callable on (M, 2) points, optional) with its zero level
    set. ``history_path``: j and Λ (6.25) per iteration, from ``history`` columns
    ``iteration``, ``j``, ``objective`` and ``mean_shape_quality``.
    """
    initial = np.asarray(initial, float)
    final = np.asarray(final, float)
    fig = _figure(10.0, 4.6, dpi)
    xl, yl = _limits(np.stack([initial, final]), margin=0.08)
    for k, (pts, title) in enumerate([(initial, "initial mesh"), (final, "optimized mesh")]):
        ax = fig.add_subplot(1, 2, k + 1)
        if rhs is not None:
            gx, gy = np.meshgrid(np.linspace(*xl, 160), np.linspace(*yl, 160))
            r = np.asarray(rhs(np.stack([gx.ravel(), gy.ravel()], 1)), float).reshape(gx.shape)
            cs = ax.contourf(gx, gy, r, levels=20, cmap="viridis", alpha=0.55)
            ax.contour(gx, gy, r, levels=[0.0], colors="white", linewidths=1.2)
            fig.colorbar(cs, ax=ax, shrink=0.8, label="r")
        draw_mesh(ax, pts, triangles, linewidth=0.5)
        ax.set_xlim(*xl)
        ax.set_ylim(*yl)
        ax.set_title(title)
    first = _save(fig, mesh_path)

    it = np.asarray(history["iteration"])
    fig, ax = _one_axes(7.0, 4.2, dpi)
    ax.plot(it, history["j"], color="tab:blue", label="j = ∫y")
    if not np.allclose(history["objective"], history["j"]):
        ax.plot(it, history["objective"], color="tab:blue", linestyle="--", label="j + f2")
    ax.set_xlabel("iteration")
    ax.set_ylabel("shape functional", color="tab:blue")
    ax.grid(True, alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(it, history["mean_shape_quality"], color="tab:red", label="Λ (mean 1/ψ)")
    ax2.set_ylabel("Λ (6.25), 1 is best", color="tab:red")
    lines = ax.get_lines() + ax2.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], loc="upper right")
    return first, _save(fig, history_path)


def save_morph_figures(result, strip_path, quality_path, max_panels: int = 9) -> tuple[Path, Path]:
    """Figures of a geodesic morph (:class:`~meshopt_toolkit.motion.planar.scalar_morph_result.MorphResult`): a strip of
    at most ``max_panels`` equally spaced frames, and the minimum aspect ratio per frame
    against linear interpolation of the same pair (negative = inverted triangles)."""
    K = result.n_frames
    idx = np.unique(np.round(np.linspace(0, K - 1, min(K, max_panels))).astype(int))
    strip = save_snapshot_strip(
        strip_path, result.points[idx], result.triangles, ncols=len(idx),
        titles=[f"t = {result.times[k]:.2f}, AR {result.min_aspect_ratio[k]:.2g}" for k in idx],
    )
    series = {f"geodesic ({getattr(result, 'metric_name', result.method)})": result.min_aspect_ratio,
              "linear interpolation": result.linear_min_aspect_ratio}
    if getattr(result, "rigid_min_aspect_ratio", None) is not None:
        series["as-rigid-as-possible"] = result.rigid_min_aspect_ratio
    quality = save_quality_plot(
        quality_path, result.times, series,
        ylabel="min aspect ratio 2r/R (signed; < 0: inverted)",
        title="geodesic morph vs interpolation",
        yscale="symlog",
    )
    return strip, quality
