"""Logging a :class:`~warpskill.visual.rerun_scene.SceneData` into a Rerun recording, and its layout.

:func:`log_scene` writes the entity tree of ``docs/viewer.md``: static data once, per-frame
data as columns on the timelines ``time`` (seconds) and ``frame`` (index); world frame of
``docs/formats.md`` (z up, metres). :func:`blueprint` is the recording's default layout.
Colours are the palette of :mod:`warpskill.media`, as in every picture. Imports ``rerun``
(the optional ``rerun-sdk``) on first use.
"""

from __future__ import annotations

import numpy as np

from warpskill.contract.vocabulary import MODEL_HAND_LENGTH, MODEL_HAND_RADIUS
from warpskill.geometry import quaternions
from warpskill.media import (
    GRIPPER_COLOR,
    HAND_COLOR,
    HAND_HELD_COLOR,
    OBJECT_COLOR,
    REPLAY_OBJECT_COLOR,
    ROBOT_COLOR,
    STATIC_COLOR,
    TRUTH_COLOR,
)
from warpskill.visual.rerun_scene import CLASS_IDS, SceneData

__all__ = ["blueprint", "log_scene"]

GROUND_COLOR = (110, 110, 100, 170)
"""RGBA of the ground plane."""

VIDEO_JPEG_QUALITY = 90
"""JPEG quality (0-100) of the demonstration's video frames in the recording."""

IMAGE_PLANE_DISTANCE = 0.15
"""Distance [m] from the camera at which the 3D view draws the image plane."""


def log_scene(rec, scene: SceneData) -> None:
    """Log the whole scene into the recording stream ``rec``."""
    import rerun as rr  # the optional extra "viewer"

    recon = scene.recon
    rec.set_log_tick_enabled(False)
    rec.set_log_time_enabled(False)
    index = _index(rr, recon.t)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    centre, half = _ground_extent(scene)
    rec.log("world/ground", rr.Boxes3D(centers=[(centre[0], centre[1], -0.001)], half_sizes=[(half, half, 0.001)],
                                       colors=[GROUND_COLOR], fill_mode="solid", labels=["ground z = 0"],
                                       show_labels=False), static=True)
    _log_camera(rr, rec, scene)

    # Hand: a cylinder from the tip along the hand's local +z, darker while grasped.
    held = np.clip(recon.grasped, 0.0, 1.0)[:, None]
    hand_colors = np.round((1.0 - held) * np.array(HAND_COLOR) + held * np.array(HAND_HELD_COLOR)).astype(np.uint8)
    _log_hand(rr, rec, index, recon.hand_pos, recon.hand_rot, hand_colors)
    _log_box_track(rr, rec, "world/object", index, recon.object_pos, recon.object_rot, recon.object_size,
                   OBJECT_COLOR, "object")
    if recon.num_static:
        rec.log("world/static", rr.Boxes3D(centers=recon.static_pos, quaternions=_xyzw(recon.static_rot),
                                           half_sizes=recon.static_size / 2, colors=[STATIC_COLOR] * recon.num_static,
                                           fill_mode="solid",
                                           labels=[f"static {k}" for k in range(recon.num_static)]), static=True)
    _log_path(rr, rec, "world/paths/hand_tip", recon.hand_pos, HAND_HELD_COLOR, 0.003)
    _log_path(rr, rec, "world/paths/object", recon.object_pos, OBJECT_COLOR, 0.003)

    truth = {} if scene.demo is None else scene.demo.truth
    if "object_pos" in truth and "object_rot" in truth:
        _log_box_track(rr, rec, "world/truth/object", index, truth["object_pos"], truth["object_rot"],
                       truth.get("object_size", recon.object_size), TRUTH_COLOR, "true object",
                       fill_mode="majorwireframe")
    if "hand_pos" in truth:
        _log_path(rr, rec, "world/truth/hand_tip_path", truth["hand_pos"], TRUTH_COLOR, 0.0015)

    _log_scalar(rr, rec, "plots/signal/g", index, recon.grasp, (230, 230, 230), "grasp signal g")
    _log_scalar(rr, rec, "plots/state/grasped", index, recon.grasped, (170, 90, 230), "grasped")
    if scene.demo is not None:
        _log_scalar(rr, rec, "plots/state/contact", index, scene.demo.contact.astype(float), (230, 180, 0),
                    "contact (demo)")
    if scene.replayed is not None:
        rep = scene.replayed
        rep_index = _index(rr, rep.t)
        _log_box_track(rr, rec, "world/replay/object", rep_index, rep.object_pos, rep.object_rot, rep.object_size,
                       REPLAY_OBJECT_COLOR, "replayed object", fill_mode="transparentfillmajorwireframe")
        _log_path(rr, rec, "world/paths/replay_object", rep.object_pos, REPLAY_OBJECT_COLOR, 0.003)
        _log_path(rr, rec, "world/paths/robot_tcp", rep.hand_pos, GRIPPER_COLOR, 0.002)
        _log_scalar(rr, rec, "plots/state/robot_grasped", rep_index, rep.grasped, REPLAY_OBJECT_COLOR,
                    "fingers touch object (replay)")
    if scene.robot is not None:
        _log_robot(rr, rec, scene.robot)


def _index(rr, t: np.ndarray) -> list:
    """The two timeline columns of frames at times ``t`` [s]: ``time`` and ``frame``."""
    t = np.asarray(t, float)
    return [rr.TimeColumn("time", duration=t), rr.TimeColumn("frame", sequence=np.arange(len(t)))]


def _log_camera(rr, rec, scene: SceneData) -> None:
    """The camera at (0, 0, h), OpenCV axes (x right, y down, z forward), its pinhole and label images."""
    recon = scene.recon
    se, ce = np.sin(float(recon.camera_elevation)), np.cos(float(recon.camera_elevation))
    R_wc = np.array([[1.0, 0.0, 0.0], [0.0, -se, ce], [0.0, -ce, -se]])
    H, W = (int(x) for x in recon.image_size)
    rec.log("world/camera", rr.Transform3D(translation=[0.0, 0.0, float(recon.camera_height)], mat3x3=R_wc),
            static=True)
    rec.log("world/camera/image", rr.Pinhole(image_from_camera=recon.camera_K, resolution=[W, H],
                                             camera_xyz=rr.ViewCoordinates.RDF,
                                             image_plane_distance=IMAGE_PLANE_DISTANCE), static=True)
    rec.log("world/camera/image", rr.AnnotationContext(_annotations(recon.num_static)), static=True)
    for k in range(recon.num_frames):
        rec.set_time("time", duration=float(recon.t[k]))
        rec.set_time("frame", sequence=k)
        if scene.frames is not None:
            rec.log("world/camera/image/video", rr.Image(scene.frames[k], draw_order=-1.0).compress(VIDEO_JPEG_QUALITY))
        if scene.masks is not None:
            rec.log("world/camera/image/masks", rr.SegmentationImage(scene.masks[k], opacity=1.0, draw_order=0.0))
        rec.log("world/camera/image/rendered", rr.SegmentationImage(scene.rendered[k], opacity=0.6, draw_order=1.0))
    rec.reset_time()


def _log_hand(rr, rec, index, pos, rot, colors) -> None:
    n = len(pos)
    rec.log("world/hand", rr.Cylinders3D.from_fields(fill_mode="solid", labels=["hand"], show_labels=False),
            static=True)
    rec.send_columns("world/hand", indexes=index, columns=rr.Cylinders3D.columns(
        centers=pos + rot[:, :, 2] * (MODEL_HAND_LENGTH / 2), quaternions=_xyzw(rot),
        lengths=np.full(n, MODEL_HAND_LENGTH), radii=np.full(n, MODEL_HAND_RADIUS), colors=colors))


def _log_box_track(rr, rec, entity, index, pos, rot, size, color, label, *, fill_mode="solid") -> None:
    """One cuboid per frame: centres (F, 3) [m], rotations (F, 3, 3), full edge lengths (3,) [m]."""
    n = len(pos)
    rec.log(entity, rr.Boxes3D.from_fields(fill_mode=fill_mode, labels=[label], show_labels=False), static=True)
    rec.send_columns(entity, indexes=index, columns=rr.Boxes3D.columns(
        centers=pos, quaternions=_xyzw(rot), half_sizes=np.tile(np.asarray(size) / 2, (n, 1)),
        colors=np.tile(np.asarray(color, np.uint8), (n, 1))))


def _log_path(rr, rec, entity, points, color, radius) -> None:
    rec.log(entity, rr.LineStrips3D([points], colors=[color], radii=radius), static=True)


def _log_scalar(rr, rec, entity, index, values, color, name) -> None:
    rec.log(entity, rr.SeriesLines(colors=[color], names=[name], widths=[2.0]), static=True)
    rec.send_columns(entity, indexes=index, columns=rr.Scalars.columns(scalars=np.asarray(values, float)))


def _log_robot(rr, rec, robot) -> None:
    """The Panda (a track of :data:`~warpskill.visual.rerun_scene.ROBOT_TRACK_FIELDS`): per link a per-frame world pose, its collision shapes logged once under it."""
    index = _index(rr, robot.times)
    for link, poses in robot.links.items():
        entity = f"world/robot/{link}"
        rec.send_columns(entity, indexes=index,
                         columns=rr.Transform3D.columns(translation=poses[:, :3, 3], mat3x3=poses[:, :3, :3]))
        color = GRIPPER_COLOR if "finger" in link or link == "panda_hand" else ROBOT_COLOR
        for i, shape in enumerate(robot.shapes.get(link, [])):
            child = f"{entity}/collision{i}"
            rec.log(child, rr.Transform3D(translation=shape.pose[:3, 3], mat3x3=shape.pose[:3, :3]), static=True)
            rec.log(child, _shape_archetype(rr, shape, color), static=True)
    _log_scalar(rr, rec, "plots/signal/gripper", index, robot.gripper, (80, 200, 230), "gripper opening [m]")


def _shape_archetype(rr, shape, color):
    """A collision shape (:class:`warpskill.robot.LinkShape`) as a Rerun archetype in its own frame."""
    size = shape.size
    if shape.kind == "mesh":
        return rr.Mesh3D(vertex_positions=shape.vertices, triangle_indices=shape.triangles,
                         vertex_normals=_vertex_normals(shape.vertices, shape.triangles), albedo_factor=color)
    if shape.kind == "box":
        return rr.Boxes3D(half_sizes=[size], colors=[color], fill_mode="solid")
    if shape.kind == "cylinder":
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], colors=[color], fill_mode="solid")
    if shape.kind == "capsule":  # Rerun's capsule runs from its origin along +z
        return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[(0, 0, -size[1])], colors=[color])
    radii = size if shape.kind == "ellipsoid" else np.full(3, size[0])
    return rr.Ellipsoids3D(half_sizes=[radii], colors=[color], fill_mode="solid")


def _vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(V, 3) unit vertex normals: the area-weighted sum of the adjacent faces' normals."""
    a, b, c = (vertices[triangles[:, i]] for i in range(3))
    face = np.cross(b - a, c - a)  # length: twice the area
    normals = np.zeros_like(vertices)
    for i in range(3):
        np.add.at(normals, triangles[:, i], face)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)


def _annotations(num_static: int) -> list:
    """Class id -> (label, RGBA) of the label images."""
    classes = [
        (CLASS_IDS["background"], "background", (0, 0, 0, 0)),
        (CLASS_IDS["hand"], "hand", (*HAND_COLOR, 255)),
        (CLASS_IDS["object"], "object", (*OBJECT_COLOR, 255)),
    ]
    classes += [(CLASS_IDS["static"] + k, f"static {k}", (*STATIC_COLOR, 255)) for k in range(num_static)]
    return classes


def _ground_extent(scene: SceneData) -> tuple[np.ndarray, float]:
    """Centre (2,) and half edge [m] of a square ground patch under the scene, the camera and the robot."""
    recon = scene.recon
    points = [recon.hand_pos[:, :2], recon.object_pos[:, :2], recon.static_pos[:, :2], np.zeros((1, 2))]
    if scene.robot is not None:
        points.append(scene.robot.base[None, :2, 3])
    xy = np.concatenate(points)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    return 0.5 * (lo + hi), float(0.5 * max(hi - lo) + 0.5)

def _xyzw(R: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions in Rerun's order (x, y, z, w) of rotation matrices (..., 3, 3)."""
    return np.roll(quaternions(R), -1, axis=-1)


def blueprint(scene: SceneData):
    """Default layout: the 3D scene left; the masks, the rendered silhouettes and the plots right."""
    import rerun.blueprint as rrb  # the optional extra "viewer"

    images = []
    if scene.frames is not None:
        images.append(rrb.Spatial2DView(origin="world/camera/image", contents="$origin/video", name="video (demo)"))
    if scene.masks is not None:
        images.append(rrb.Spatial2DView(origin="world/camera/image", contents="$origin/masks", name="masks (demo)"))
    images.append(
        rrb.Spatial2DView(origin="world/camera/image", contents="$origin/rendered", name="rendered (reconstruction)")
    )
    recon = scene.recon
    signal = [recon.grasp, [0.0]] + ([] if scene.robot is None else [scene.robot.gripper])
    lo, hi = min(float(np.min(x)) for x in signal), max(float(np.max(x)) for x in signal)
    pad = 0.08 * (hi - lo) + 1e-3
    plots = [
        rrb.TimeSeriesView(origin="plots/state", name="held / contact (0 or 1)",
                           axis_y=rrb.ScalarAxis(range=(-0.05, 1.05))),
        rrb.TimeSeriesView(origin="plots/signal", name="grasp signal, gripper opening [m]",
                           axis_y=rrb.ScalarAxis(range=(lo - pad, hi + pad))),
    ]
    # Look at the scene from the right of the camera and above, the camera and the robot in view.
    centre = np.concatenate([recon.object_pos, recon.static_pos]).mean(axis=0)
    target = np.array([centre[0], 0.5 * centre[1], 0.15])
    eye = rrb.EyeControls3D(position=target + np.array([1.3, 0.5, 0.8]), look_target=target, eye_up=[0.0, 0.0, 1.0])
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="scene (world, z up, m)", eye_controls=eye),
            rrb.Vertical(rrb.Horizontal(*images), *plots),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline="time", state="collapsed"),
        collapse_panels=True,
    )
