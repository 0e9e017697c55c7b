"""The plots of a reconstruction: the top view of the ground plane and the trajectories over time."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import LinearSegmentedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Polygon

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.engine.projection import camera_rotation
from warpskill.media import HAND_COLOR, HAND_HELD_COLOR, OBJECT_COLOR, STATIC_COLOR, figure, rgb

_AXIS_COLORS = {"x": "tab:red", "y": "tab:green", "z": "tab:blue"}


_GRASP_CMAP = LinearSegmentedColormap.from_list("grasp", [rgb(HAND_COLOR), rgb(HAND_HELD_COLOR)])


def top_view_figure(recon: Reconstruction) -> Figure:
    """Bird's-eye view of the ground plane (x right, y away from the camera) [m].

    Draws the static footprints, the object's footprint at the first (dashed) and last
    (filled) frame and its centre path, the hand tip path coloured by ``grasped``, the
    camera at the origin with its viewing direction and the part of the ground it sees.
    """
    corners = recon.object_corners()
    statics = recon.static_corners()
    tip = recon.hand_pos[:, :2]
    # Limits: the scene and the camera (at the origin), padded; the plot keeps x and y to scale.
    points = np.concatenate([tip, corners[..., :2].reshape(-1, 2), statics[..., :2].reshape(-1, 2), np.zeros((1, 2))])
    lo, hi = points.min(axis=0), points.max(axis=0)
    pad = 0.08 * max(hi - lo) + 0.02
    lo, hi = lo - pad, hi + pad
    plot_height = 6.0
    plot_width = float(np.clip(plot_height * (hi[0] - lo[0]) / (hi[1] - lo[1]), 3.0, 9.0))
    fig = figure(plot_width + 3.3, plot_height + 0.9)
    ax = fig.subplots()
    handles = _draw_statics(ax, recon, statics) + _draw_object(ax, recon, corners) + _draw_hand(ax, recon)
    handles += _draw_camera(ax, recon, lo, hi)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.set_xlabel("x [m] (image right)")
    ax.set_ylabel("y [m] (away from the camera)")
    ax.set_title(
        f"Top view{_action_suffix(recon)}\n"
        f"camera height {float(recon.camera_height):.3f} m, "
        f"elevation {math.degrees(float(recon.camera_elevation)):.1f} deg",
        fontsize=10,
    )
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    return fig


def _draw_statics(ax, recon: Reconstruction, statics: np.ndarray) -> list:
    """Draw the static boxes' footprints (corners ``statics`` (K, 8, 3) [m]); their legend handles."""
    static_rgb = rgb(STATIC_COLOR)
    for k, box in enumerate(statics):
        hull = _hull(box[:, :2])
        ax.add_patch(Polygon(hull, closed=True, facecolor=(*static_rgb, 0.3), edgecolor=static_rgb, lw=1.5))
        low = hull[np.argmin(hull[:, 1])]
        ax.annotate(
            f"static {k}", low, xytext=(0, -3), textcoords="offset points", ha="center", va="top", fontsize=8,
            color=static_rgb,
        )
    if not recon.num_static:
        return []
    return [Patch(facecolor=(*static_rgb, 0.3), edgecolor=static_rgb, label="static object")]


def _draw_object(ax, recon: Reconstruction, corners: np.ndarray) -> list:
    """Draw the object's footprint at the first and last frame (corners ``corners`` (F, 8, 3) [m]) and
    its centre path; their legend handles."""
    object_rgb = rgb(OBJECT_COLOR)
    first, last = _hull(corners[0, :, :2]), _hull(corners[-1, :, :2])
    ax.add_patch(Polygon(first, closed=True, fill=False, edgecolor=object_rgb, lw=1.5, ls="--"))
    ax.add_patch(Polygon(last, closed=True, facecolor=(*object_rgb, 0.35), edgecolor=object_rgb, lw=1.5))
    centre = recon.object_pos[:, :2]
    ax.plot(centre[:, 0], centre[:, 1], "-", color=object_rgb, lw=1.5, marker=".", ms=3)
    return [
        Patch(fill=False, edgecolor=object_rgb, ls="--", label="object, first frame"),
        Patch(facecolor=(*object_rgb, 0.35), edgecolor=object_rgb, label="object, last frame"),
        Line2D([], [], color=object_rgb, marker=".", ms=3, label="object centre path"),
    ]


def _draw_hand(ax, recon: Reconstruction) -> list:
    """Draw the hand tip's path coloured by ``grasped``, its start and end; their legend handles."""
    tip = recon.hand_pos[:, :2]
    held = np.clip(recon.grasped, 0.0, 1.0)
    segments = np.stack([tip[:-1], tip[1:]], axis=1)
    ax.add_collection(LineCollection(segments, colors=_GRASP_CMAP(0.5 * (held[:-1] + held[1:])), lw=2.5))
    ax.scatter(tip[:, 0], tip[:, 1], c=_GRASP_CMAP(held), s=8, zorder=3)
    ax.plot(*tip[0], "o", mfc="none", mec="k", ms=8, zorder=4)
    ax.plot(*tip[-1], "s", mfc="none", mec="k", ms=8, zorder=4)
    return [
        Line2D([], [], color=_GRASP_CMAP(0.0), lw=2.5, label="hand tip, free"),
        Line2D([], [], color=_GRASP_CMAP(1.0), lw=2.5, label="hand tip, grasped"),
        Line2D([], [], ls="none", marker="o", mfc="none", mec="k", label="hand tip start"),
        Line2D([], [], ls="none", marker="s", mfc="none", mec="k", label="hand tip end"),
    ]


def _draw_camera(ax, recon: Reconstruction, lo: np.ndarray, hi: np.ndarray) -> list:
    """Draw the camera at the origin, its view direction and the ground it sees, clipped by the plot's
    limits ``lo``, ``hi`` (2,) [m]; their legend handles."""
    handles = []
    view = _ground_footprint(recon, far=2.0 * float(np.hypot(*(hi - lo))))
    ax.add_patch(Polygon(view, closed=True, facecolor="0.92", edgecolor="0.6", lw=1.0, zorder=0))
    height, elevation = float(recon.camera_height), float(recon.camera_elevation)
    arrow = 0.25 * max(hi - lo)
    ax.annotate("", xy=(0.0, arrow), xytext=(0.0, 0.0), arrowprops=dict(arrowstyle="->", color="k", lw=1.5))
    ax.plot(0.0, 0.0, marker="^", color="k", ms=10, ls="none", zorder=5)
    if elevation > 1e-3:
        ax.plot(0.0, height / math.tan(elevation), marker="x", color="k", ms=7, ls="none")
        handles.append(Line2D([], [], ls="none", marker="x", color="k", label="optical axis meets ground"))
    return handles + [
        Line2D([], [], ls="none", marker="^", color="k", ms=8, label="camera (arrow: view direction)"),
        Patch(facecolor="0.92", edgecolor="0.6", label="ground seen by the camera"),
    ]


def _ground_footprint(recon: Reconstruction, *, far: float, samples: int = 32) -> np.ndarray:
    """(M, 2) polygon [m]: the ground the image border sees, rays above the horizon cut at ``far`` [m]."""
    H, W = (float(x) for x in recon.image_size)
    t = np.linspace(0.0, 1.0, samples, endpoint=False)
    border = np.concatenate(
        [
            np.stack([t * W, np.zeros_like(t)], 1),
            np.stack([np.full_like(t, W), t * H], 1),
            np.stack([W - t * W, np.full_like(t, H)], 1),
            np.stack([np.zeros_like(t), H - t * H], 1),
        ]
    )
    K = recon.camera_K
    rays = np.stack([(border[:, 0] - K[0, 2]) / K[0, 0], (border[:, 1] - K[1, 2]) / K[1, 1], np.ones(len(border))], 1)
    directions = rays @ camera_rotation(float(recon.camera_elevation)).numpy().T
    height = float(recon.camera_height)
    flat = np.linalg.norm(directions[:, :2], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.where(directions[:, 2] < 0.0, height / -directions[:, 2] * flat, np.inf)
    reach = np.minimum(reach, far)
    return directions[:, :2] / np.maximum(flat, 1e-12)[:, None] * reach[:, None]


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull (M, 2) of 2D ``points`` (P, 2), counter-clockwise (monotone chain)."""
    pts = sorted(map(tuple, np.round(points, 12)))
    if len(pts) < 3:
        return np.array(pts)

    def half(seq):
        chain = []
        for p in seq:
            while len(chain) >= 2 and _cross(chain[-2], chain[-1], p) <= 0:
                chain.pop()
            chain.append(p)
        return chain

    lower, upper = half(pts), half(reversed(pts))
    return np.array(lower[:-1] + upper[:-1])


def _cross(o, a, b) -> float:
    """z of (a - o) x (b - o): positive when o, a, b turn counter-clockwise."""
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def trajectories_figure(recon: Reconstruction, demo: Demonstration | None = None) -> Figure:
    """Hand tip and object centre coordinates [m], grasp signal and ``grasped`` over time [s].

    Frames with ``demo.contact`` set are shaded; fields present in ``demo.truth`` are
    drawn dashed in the same colour.
    """
    truth = {} if demo is None else demo.truth
    t = recon.t
    fig = figure(9.0, 8.0)
    axes = fig.subplots(3, 1, sharex=True)
    for ax, key, title in (
        (axes[0], "hand_pos", "hand tip position"),
        (axes[1], "object_pos", "object centre position"),
    ):
        values = getattr(recon, key)
        for i, name in enumerate("xyz"):
            ax.plot(t, values[:, i], color=_AXIS_COLORS[name], lw=1.8, label=name)
            if key in truth:
                ax.plot(t, truth[key][:, i], color=_AXIS_COLORS[name], lw=1.2, ls="--")
        ax.set_ylabel(f"{title} [m]")
        ax.axhline(0.0, color="0.5", lw=0.6)

    ax = axes[2]
    ax.plot(t, recon.grasp, color="k", lw=1.8, label="grasp signal g")
    if "grasp" in truth:
        ax.plot(t, truth["grasp"], color="k", lw=1.2, ls="--")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_ylabel("grasp signal g [m]")
    twin = ax.twinx()
    twin.plot(t, recon.grasped, color="tab:purple", lw=1.8, label="grasped")
    if "grasped" in truth:
        twin.plot(t, truth["grasped"], color="tab:purple", lw=1.2, ls="--")
    twin.set_ylim(-0.05, 1.05)
    twin.set_ylabel("grasped (0 free, 1 held)", color="tab:purple")
    twin.tick_params(axis="y", colors="tab:purple")
    axes[-1].set_xlabel("time [s]")

    handles = [Line2D([], [], color=_AXIS_COLORS[name], lw=1.8, label=name) for name in "xyz"]
    handles += ax.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
    if demo is not None and demo.contact.any():
        half = 0.5 / float(recon.fps)
        for start, stop in _runs(demo.contact):
            for a in axes:
                a.axvspan(t[start] - half, t[stop - 1] + half, color="gold", alpha=0.25, lw=0)
        handles.append(Patch(color="gold", alpha=0.25, label="contact (demonstration)"))
    if truth:
        handles.append(Line2D([], [], color="0.3", lw=1.2, ls="--", label="ground truth"))
    axes[0].legend(
        handles=handles, loc="lower center", bbox_to_anchor=(0.5, 1.02), ncol=len(handles), fontsize=8, frameon=False
    )
    for a in axes:
        a.grid(True, lw=0.4, alpha=0.6)
        a.set_xlim(t[0] - 0.5 / float(recon.fps), t[-1] + 0.5 / float(recon.fps))
    fig.suptitle(f"Reconstructed trajectories{_action_suffix(recon)}", fontsize=11)
    return fig


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the runs of True in a 1-D bool array."""
    padded = np.concatenate([[False], np.asarray(flags, bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _action_suffix(recon: Reconstruction) -> str:
    """": put onto"" for a known action, "" otherwise (for titles)."""
    action = str(recon.action)
    return f": {action.replace('_', ' ')}" if action else ""
