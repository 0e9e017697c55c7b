"""Pictures of a reconstruction, to judge it by eye.

:func:`save_pictures` writes three files into a folder:

- ``overlay.gif``: every frame, the reconstruction ray cast into the camera
  (:func:`warpskill.engine.raycast.raycast_masks`) as translucent colours (hand orange, object
  green, static objects blue) over the demonstration's masks in shades of grey (or over
  video frames), with the frame index, time, contact flag and grasp state in a corner.
  Grey without colour is mask the reconstruction misses; colour over the dark background
  is reconstruction the masks do not support.
- ``top_view.png``: a bird's-eye view of the ground plane (x right, y away from the
  camera): static footprints, the object's footprint at the first and last frame and its
  centre path, the hand tip path coloured by the grasp state, and the camera.
- ``trajectories.png``: hand tip and object centre coordinates, the grasp signal g and
  ``grasped`` over time, contact frames shaded, ground truth dashed when the
  demonstration has it.

Units: metres, seconds, radians (``FORMATS.md``); images are H x W pixels, RGB uint8.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import LinearSegmentedColormap, to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Polygon

from warpskill.contract.camera import Intrinsics
from warpskill.engine.projection import camera_rotation
from warpskill.engine.raycast import raycast_masks
from warpskill.visual.media import VIDEO_FORMATS, write_video

if TYPE_CHECKING:
    from warpskill.contract.demonstration import Demonstration
    from warpskill.contract.reconstruction import Reconstruction

HAND_COLOR = (255, 140, 20)
"""RGB of the reconstructed hand (orange)."""

OBJECT_COLOR = (40, 200, 70)
"""RGB of the reconstructed manipulated object (green)."""

STATIC_COLOR = (40, 110, 255)
"""RGB of the reconstructed static objects (blue)."""

FILL_ALPHA = 0.5
"""Opacity of the reconstruction's fill in the overlay; its outline is opaque."""

MASK_GREYS = {"background": 25, "static": 95, "hand": 165, "object": 235}
"""Grey level of each demonstration mask (and of the empty background) in the overlay."""

MIN_OVERLAY_WIDTH = 320
"""Overlays of narrower images are enlarged by a whole factor to at least this width [px]."""

RENDER_BUDGET = 6_000_000
"""Most pixels (frames x H x W) ray cast for one overlay; larger videos render smaller."""

"""Values of ``frames_video`` that write ``overlay.<format>``; None writes no overlay."""

_AXIS_COLORS = {"x": "tab:red", "y": "tab:green", "z": "tab:blue"}
_GRASP_CMAP = LinearSegmentedColormap.from_list("grasp", ["#ffb060", "#8b1a00"])


def save_pictures(
    recon: Reconstruction,
    demo: Demonstration | None,
    out_dir: str | os.PathLike,
    *,
    background: np.ndarray | None = None,
    frames_video: str | None = "gif",
    render_scale: float | None = None,
) -> dict[str, Path]:
    """Write the overlay video, the top view and the trajectory plots of ``recon``.

    Args:
        recon: the reconstruction to draw.
        demo: the demonstration it was fitted to (masks, contact, ground truth), or None
            to draw the reconstruction alone.
        out_dir: folder to write into; created if missing.
        background: optional (N, H, W, 3) uint8 RGB video frames drawn under the
            reconstruction instead of the demonstration's masks.
        frames_video: ``"gif"`` (``overlay.gif``), ``"mp4"`` (``overlay.mp4``) or None
            (no overlay).
        render_scale: ray cast at this fraction of the image size (then enlarged to it);
            None picks 1 unless the video exceeds :data:`RENDER_BUDGET` pixels.

    Returns:
        Picture name (``"overlay"``, ``"top_view"``, ``"trajectories"``) -> path written.

    Raises:
        ValueError: ``demo`` or ``background`` disagrees with ``recon`` in frame count,
            image size or intrinsics, or ``frames_video`` / ``render_scale`` is invalid.
    """
    _check_inputs(recon, demo, background)
    _check_render_scale(render_scale)
    if frames_video is not None and frames_video not in VIDEO_FORMATS:
        raise ValueError(f"frames_video: expected one of {VIDEO_FORMATS} or None, got {frames_video!r}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {}
    if frames_video is not None:
        frames = overlay_frames(recon, demo, background=background, render_scale=render_scale)
        paths["overlay"] = write_video(out_dir / f"overlay.{frames_video}", frames, float(recon.fps))
    paths["top_view"] = _save_figure(top_view_figure(recon), out_dir / "top_view.png")
    paths["trajectories"] = _save_figure(trajectories_figure(recon, demo), out_dir / "trajectories.png")
    return paths


# --------------------------------------------------------------------------- overlay


def overlay_frames(
    recon: Reconstruction,
    demo: Demonstration | None = None,
    *,
    background: np.ndarray | None = None,
    render_scale: float | None = None,
) -> np.ndarray:
    """The overlay video of :func:`save_pictures` as an array.

    Args:
        recon, demo, background, render_scale: as in :func:`save_pictures`.

    Returns:
        (N, s H, s W, 3) uint8 RGB frames, s the smallest whole factor with
        s W >= :data:`MIN_OVERLAY_WIDTH` (1 for ordinary videos); output pixel
        (s i + a, s j + b) shows image pixel (i, j).
    """
    _check_inputs(recon, demo, background)
    H, W = (int(x) for x in recon.image_size)
    labels = render_labels(recon, render_scale=render_scale)
    if background is not None:
        base = np.asarray(background, dtype=np.uint8)
    elif demo is not None:
        base = _mask_images(demo)
    else:
        base = np.full((recon.num_frames, H, W, 3), MASK_GREYS["background"], np.uint8)
    s = max(1, math.ceil(MIN_OVERLAY_WIDTH / W))
    if s > 1:
        base = base.repeat(s, axis=1).repeat(s, axis=2)
        labels = labels.repeat(s, axis=1).repeat(s, axis=2)
    frames = _paint(base, labels)
    contact = None if demo is None else demo.contact
    with_masks = demo is not None and background is None
    for k, frame in enumerate(frames):
        _annotate(frame, recon, k, None if contact is None else bool(contact[k]), with_masks=with_masks)
    return frames


def render_labels(recon: Reconstruction, *, render_scale: float | None = None) -> np.ndarray:
    """Which primitive each pixel sees, ray cast from the reconstruction's camera.

    Args:
        recon: the reconstruction.
        render_scale: ray cast at this fraction of ``recon.image_size`` and enlarge the
            result (nearest pixel); None: 1, or less to stay within :data:`RENDER_BUDGET`.

    Returns:
        (N, H, W) int8: -1 nothing, 0 the hand, 1 the object, 2 + k static object k.
    """
    H, W = (int(x) for x in recon.image_size)
    N, K = recon.num_frames, recon.num_static
    if render_scale is None:
        render_scale = min(1.0, math.sqrt(RENDER_BUDGET / (N * H * W)))
    _check_render_scale(render_scale)
    intrinsics = Intrinsics(recon.camera_K, (H, W)).scaled(render_scale)
    cuboid_pos = np.concatenate([recon.object_pos[:, None], np.broadcast_to(recon.static_pos, (N, K, 3))], axis=1)
    cuboid_rot = np.concatenate(
        [recon.object_rot[:, None], np.broadcast_to(recon.static_rot, (N, K, 3, 3))], axis=1
    )
    cuboid_size = np.concatenate([recon.object_size[None], recon.static_size], axis=0)
    masks = raycast_masks(
        recon.hand_pos,
        recon.hand_rot,
        cuboid_pos,
        cuboid_rot,
        cuboid_size,
        float(recon.camera_height),
        float(recon.camera_elevation),
        intrinsics,
    )  # (N, 2 + K, h, w), at most one channel set per pixel
    labels = np.where(masks.any(axis=1), masks.argmax(axis=1), -1).astype(np.int8)
    if intrinsics.image_size != (H, W):
        labels = np.stack([cv2.resize(frame, (W, H), interpolation=cv2.INTER_NEAREST) for frame in labels])
    return labels


def _mask_images(demo: Demonstration) -> np.ndarray:
    """(N, H, W, 3) uint8: the demonstration's masks as grey silhouettes (:data:`MASK_GREYS`)."""
    grey = np.full(demo.hand_mask.shape, MASK_GREYS["background"], np.uint8)
    grey[demo.static_mask.any(axis=0)] = MASK_GREYS["static"]
    grey[demo.hand_mask] = MASK_GREYS["hand"]
    grey[demo.object_mask] = MASK_GREYS["object"]
    return np.repeat(grey[..., None], 3, axis=-1)


def _label_colors(num_labels: int) -> np.ndarray:
    """(num_labels, 3) float RGB of labels 0 (hand), 1 (object), 2.. (static objects)."""
    colors = [HAND_COLOR, OBJECT_COLOR] + [STATIC_COLOR] * (num_labels - 2)
    return np.array(colors[:num_labels], dtype=np.float32)


def _paint(base: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Blend label colours over ``base`` (N, H, W, 3): translucent fill, opaque 1-px outline."""
    colors = _label_colors(max(int(labels.max()) + 1, 2))
    hit = labels >= 0
    edge = np.zeros_like(hit)
    for axis in (1, 2):  # a pixel whose label differs from a 4-neighbour's, on the labelled side
        diff = np.diff(labels, axis=axis) != 0
        before, after = [slice(None)] * 3, [slice(None)] * 3
        before[axis], after[axis] = slice(None, -1), slice(1, None)
        edge[tuple(before)] |= diff
        edge[tuple(after)] |= diff
    edge &= hit
    alpha = np.where(edge[hit], 1.0, FILL_ALPHA).astype(np.float32)[:, None]
    out = base.copy()
    out[hit] = np.round(base[hit] * (1.0 - alpha) + colors[labels[hit]] * alpha).astype(np.uint8)
    return out


def _annotate(frame: np.ndarray, recon: Reconstruction, k: int, contact: bool | None, *, with_masks: bool) -> None:
    """Write frame index, time, contact and grasp state (top left) and a colour key (bottom left)."""
    H, W = frame.shape[:2]
    scale = float(np.clip(W / 900.0, 0.35, 0.7))
    thickness = 1
    font = cv2.FONT_HERSHEY_SIMPLEX
    (_, text_h), baseline = cv2.getTextSize("Ag", font, scale, thickness)
    step = text_h + baseline + 3
    held = float(recon.grasped[k])
    lines = [
        (f"frame {k}/{recon.num_frames - 1}  t {recon.t[k]:.2f} s", (255, 255, 255)),
        (f"g {recon.grasp[k]:+.3f}  grasped {held:.2f}", (255, 190, 120) if held > 0.5 else (255, 255, 255)),
    ]
    if contact is not None:
        lines.insert(1, ("contact: yes" if contact else "contact: no", (255, 230, 60) if contact else (200, 200, 200)))
    width = max(cv2.getTextSize(text, font, scale, thickness)[0][0] for text, _ in lines)
    _shade(frame, 0, 0, width + 8, step * len(lines) + 4)
    for n, (text, color) in enumerate(lines):
        cv2.putText(frame, text, (4, 2 + step * (n + 1) - baseline), font, scale, color, thickness, cv2.LINE_AA)

    key = [("hand", HAND_COLOR), ("object", OBJECT_COLOR)]
    if recon.num_static:
        key.append(("static", STATIC_COLOR))
    if with_masks:
        key.append(("masks", (MASK_GREYS["object"],) * 3))
    box = text_h
    x, y = 4, H - 4
    total = sum(box + 3 + cv2.getTextSize(name, font, scale, thickness)[0][0] + 8 for name, _ in key)
    _shade(frame, 0, H - box - 8, total + 4, H)
    for name, color in key:
        cv2.rectangle(frame, (x, y - box), (x + box, y), color, -1)
        x += box + 3
        cv2.putText(frame, name, (x, y), font, scale, (255, 255, 255), thickness, cv2.LINE_AA)
        x += cv2.getTextSize(name, font, scale, thickness)[0][0] + 8


def _shade(frame: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> None:
    """Darken the rectangle [x0, x1) x [y0, y1) of ``frame`` in place, so text stays legible."""
    y0, x0 = max(y0, 0), max(x0, 0)
    region = frame[y0:y1, x0:x1]
    region[...] = (region.astype(np.uint16) * 2 // 5).astype(np.uint8)


# --------------------------------------------------------------------------- top view


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
    fig = _figure(plot_width + 3.3, plot_height + 0.9)
    ax = fig.subplots()
    handles = []
    static_rgb = _rgb(STATIC_COLOR)
    object_rgb = _rgb(OBJECT_COLOR)

    for k, box in enumerate(statics):
        hull = _hull(box[:, :2])
        ax.add_patch(Polygon(hull, closed=True, facecolor=(*static_rgb, 0.3), edgecolor=static_rgb, lw=1.5))
        low = hull[np.argmin(hull[:, 1])]
        ax.annotate(
            f"static {k}", low, xytext=(0, -3), textcoords="offset points", ha="center", va="top", fontsize=8,
            color=static_rgb,
        )
    if recon.num_static:
        handles.append(Patch(facecolor=(*static_rgb, 0.3), edgecolor=static_rgb, label="static object"))

    first, last = _hull(corners[0, :, :2]), _hull(corners[-1, :, :2])
    ax.add_patch(Polygon(first, closed=True, fill=False, edgecolor=object_rgb, lw=1.5, ls="--"))
    ax.add_patch(Polygon(last, closed=True, facecolor=(*object_rgb, 0.35), edgecolor=object_rgb, lw=1.5))
    centre = recon.object_pos[:, :2]
    ax.plot(centre[:, 0], centre[:, 1], "-", color=object_rgb, lw=1.5, marker=".", ms=3)
    handles += [
        Patch(fill=False, edgecolor=object_rgb, ls="--", label="object, first frame"),
        Patch(facecolor=(*object_rgb, 0.35), edgecolor=object_rgb, label="object, last frame"),
        Line2D([], [], color=object_rgb, marker=".", ms=3, label="object centre path"),
    ]

    held = np.clip(recon.grasped, 0.0, 1.0)
    segments = np.stack([tip[:-1], tip[1:]], axis=1)
    ax.add_collection(LineCollection(segments, colors=_GRASP_CMAP(0.5 * (held[:-1] + held[1:])), lw=2.5))
    ax.scatter(tip[:, 0], tip[:, 1], c=_GRASP_CMAP(held), s=8, zorder=3)
    ax.plot(*tip[0], "o", mfc="none", mec="k", ms=8, zorder=4)
    ax.plot(*tip[-1], "s", mfc="none", mec="k", ms=8, zorder=4)
    handles += [
        Line2D([], [], color=_GRASP_CMAP(0.0), lw=2.5, label="hand tip, free"),
        Line2D([], [], color=_GRASP_CMAP(1.0), lw=2.5, label="hand tip, grasped"),
        Line2D([], [], ls="none", marker="o", mfc="none", mec="k", label="hand tip start"),
        Line2D([], [], ls="none", marker="s", mfc="none", mec="k", label="hand tip end"),
    ]

    # The ground the camera sees, clipped by the limits.
    view = _ground_footprint(recon, far=2.0 * float(np.hypot(*(hi - lo))))
    ax.add_patch(Polygon(view, closed=True, facecolor="0.92", edgecolor="0.6", lw=1.0, zorder=0))
    height, elevation = float(recon.camera_height), float(recon.camera_elevation)
    arrow = 0.25 * max(hi - lo)
    ax.annotate("", xy=(0.0, arrow), xytext=(0.0, 0.0), arrowprops=dict(arrowstyle="->", color="k", lw=1.5))
    ax.plot(0.0, 0.0, marker="^", color="k", ms=10, ls="none", zorder=5)
    if elevation > 1e-3:
        ax.plot(0.0, height / math.tan(elevation), marker="x", color="k", ms=7, ls="none")
        handles.append(Line2D([], [], ls="none", marker="x", color="k", label="optical axis meets ground"))
    handles += [
        Line2D([], [], ls="none", marker="^", color="k", ms=8, label="camera (arrow: view direction)"),
        Patch(facecolor="0.92", edgecolor="0.6", label="ground seen by the camera"),
    ]

    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.set_xlabel("x [m] (image right)")
    ax.set_ylabel("y [m] (away from the camera)")
    ax.set_title(
        f"Top view{_action_suffix(recon)}\n"
        f"camera height {height:.3f} m, elevation {math.degrees(elevation):.1f} deg",
        fontsize=10,
    )
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    return fig


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


# --------------------------------------------------------------------------- trajectories


def trajectories_figure(recon: Reconstruction, demo: Demonstration | None = None) -> Figure:
    """Hand tip and object centre coordinates [m], grasp signal and ``grasped`` over time [s].

    Frames with ``demo.contact`` set are shaded; fields present in ``demo.truth`` are
    drawn dashed in the same colour.
    """
    truth = {} if demo is None else demo.truth
    t = recon.t
    fig = _figure(9.0, 8.0)
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


# --------------------------------------------------------------------------- helpers


def _check_inputs(recon: Reconstruction, demo: Demonstration | None, background: np.ndarray | None) -> None:
    """Raise ValueError unless ``demo`` and ``background`` match ``recon``'s frames and image."""
    N = recon.num_frames
    size = tuple(int(x) for x in recon.image_size)
    if demo is not None:
        if demo.num_frames != N:
            raise ValueError(f"demonstration has {demo.num_frames} frames, the reconstruction {N}")
        if tuple(demo.image_size) != size:
            raise ValueError(f"demonstration images are {demo.image_size} (H, W), the reconstruction's {size}")
        if not np.allclose(demo.intrinsics.K, recon.camera_K, rtol=1e-6, atol=1e-6):
            raise ValueError(
                f"demonstration camera_K {demo.intrinsics.K.tolist()} differs from the reconstruction's "
                f"{recon.camera_K.tolist()}"
            )
    if background is not None:
        background = np.asarray(background)
        if background.shape != (N, *size, 3) or background.dtype != np.uint8:
            raise ValueError(
                f"background: expected (N, H, W, 3) = {(N, *size, 3)} uint8 RGB frames, "
                f"got {background.shape} {background.dtype}"
            )


def _figure(width: float, height: float) -> Figure:
    """A figure of ``width`` x ``height`` inches with constrained layout, drawn by Agg.

    Built without pyplot: no global backend switch, no display, nothing left open.
    """
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _check_render_scale(render_scale: float | None) -> None:
    """Raise ValueError unless ``render_scale`` is None or a fraction in (0, 1]."""
    if render_scale is not None and not 0.0 < render_scale <= 1.0:
        raise ValueError(f"render_scale: expected a fraction in (0, 1], got {render_scale}")


def _save_figure(fig: Figure, path: Path) -> Path:
    """Save ``fig`` as a PNG at 120 dpi."""
    fig.savefig(path, dpi=120)
    return path


def _rgb(color: tuple[int, int, int]) -> tuple[float, float, float]:
    """An 8-bit RGB triple as matplotlib floats in [0, 1]."""
    return to_rgb(np.array(color) / 255.0)


def _action_suffix(recon: Reconstruction) -> str:
    """": put onto"" for a known action, "" otherwise (for titles)."""
    action = str(recon.action)
    return f": {action.replace('_', ' ')}" if action else ""
