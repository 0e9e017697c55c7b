"""Pictures: the three files, the overlay's size and that it shows the scene where it projects."""

import math

import imageio.v3 as iio
import numpy as np
import pytest

from warpskill.contract.camera import Intrinsics
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.engine.raycast import raycast_masks
from warpskill.visual.overlay import MIN_OVERLAY_WIDTH
from warpskill.visual.pictures import save_pictures

N, H, W = 8, 48, 80
K_CAMERA = np.array([[70.0, 0.0, 40.0], [0.0, 70.0, 24.0], [0.0, 0.0, 1.0]])
HEIGHT, ELEVATION = 0.5, 0.6


def _yaw(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _hand_rotation(axis) -> np.ndarray:
    """A rotation whose local +z (the hand's axis, tip towards the arm) is ``axis``."""
    z = np.asarray(axis, float) / np.linalg.norm(axis)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def _scene(num_static: int = 1) -> Reconstruction:
    """A hand that carries a box to the right over 8 frames, beside a static box."""
    t = np.arange(N) / 2.0
    s = np.clip((np.arange(N) - 2) / 4.0, 0.0, 1.0)
    size = np.array([0.12, 0.12, 0.10])
    object_pos = np.stack([-0.12 + 0.2 * s, np.full(N, 0.8), size[2] / 2 + 0.04 * np.sin(np.pi * s)], axis=1)
    hand_pos = object_pos + [0.0, 0.0, size[2] / 2 - 0.01]
    hand_pos[:2] += [[0.0, -0.1, 0.15], [0.0, -0.05, 0.05]]
    grasped = ((np.arange(N) >= 2) & (np.arange(N) <= 6)).astype(float)
    return Reconstruction(
        fps=np.array(2.0),
        t=t,
        hand_pos=hand_pos,
        hand_rot=np.broadcast_to(_hand_rotation([0.0, 0.5, 0.85]), (N, 3, 3)),
        grasp=np.where(grasped > 0, 0.02, -0.02),
        grasped=grasped,
        object_pos=object_pos,
        object_rot=np.stack([_yaw(0.3 * v) for v in s]),
        object_size=size,
        static_pos=np.array([[0.25, 1.0, 0.05]])[:num_static],
        static_rot=_yaw(0.2)[None][:num_static],
        static_size=np.array([[0.15, 0.1, 0.1]])[:num_static],
        camera_K=K_CAMERA,
        camera_elevation=np.array(ELEVATION),
        camera_height=np.array(HEIGHT),
        image_size=np.array([H, W]),
        action=np.array("put_next_to"),
        loss=np.array(0.0),
    )


def _visible(recon: Reconstruction) -> np.ndarray:
    """(N, 2 + K, H, W) exact visible masks of ``recon``, straight from the ray caster."""
    K = recon.num_static
    return raycast_masks(
        recon.hand_pos,
        recon.hand_rot,
        np.concatenate([recon.object_pos[:, None], np.broadcast_to(recon.static_pos, (N, K, 3))], axis=1),
        np.concatenate([recon.object_rot[:, None], np.broadcast_to(recon.static_rot, (N, K, 3, 3))], axis=1),
        np.concatenate([recon.object_size[None], recon.static_size]),
        HEIGHT,
        ELEVATION,
        Intrinsics(K_CAMERA, (H, W)),
    )


def _demonstration(recon: Reconstruction, **overrides) -> Demonstration:
    """Masks one pixel to the right of the reconstruction's, with its trajectories as truth."""
    masks = np.roll(_visible(recon), 1, axis=-1)
    args = dict(
        hand_mask=masks[:, 0],
        object_mask=masks[:, 1],
        contact=recon.grasped > 0.5,
        fps=2.0,
        static_mask=masks[:, 2:].transpose(1, 0, 2, 3),
        camera_K=K_CAMERA,
        truth={"hand_pos": recon.hand_pos + 0.01, "object_pos": recon.object_pos - 0.01},
    )
    args.update(overrides)
    return Demonstration.from_arrays(**args)


def _enlarge(masks: np.ndarray, factor: int) -> np.ndarray:
    return masks.repeat(factor, axis=-2).repeat(factor, axis=-1)


def _interior(masks: np.ndarray) -> np.ndarray:
    """Mask pixels whose 4 neighbours are set too (away from the drawn outline)."""
    inner = masks.copy()
    inner[..., 1:, :] &= masks[..., :-1, :]
    inner[..., :-1, :] &= masks[..., 1:, :]
    inner[..., :, 1:] &= masks[..., :, :-1]
    inner[..., :, :-1] &= masks[..., :, 1:]
    return inner


def test_writes_three_pictures_and_overlay_shows_the_object_where_it_projects(tmp_path):
    recon = _scene()
    paths = save_pictures(recon, _demonstration(recon), tmp_path / "pictures")

    assert set(paths) == {"overlay", "top_view", "trajectories"}
    assert paths["overlay"] == tmp_path / "pictures" / "overlay.gif"
    for path in paths.values():
        assert path.is_file() and path.stat().st_size > 0
    for name in ("top_view", "trajectories"):
        assert iio.imread(paths[name]).ndim == 3

    frames = iio.imread(paths["overlay"])[..., :3].astype(int)
    scale = math.ceil(MIN_OVERLAY_WIDTH / W)
    assert frames.shape == (N, scale * H, scale * W, 3)

    visible = _enlarge(_visible(recon), scale)
    r, g, b = frames[..., 0], frames[..., 1], frames[..., 2]
    green = (g > r + 40) & (g > b + 40)
    orange = (r > g + 20) & (g > b + 15)  # also where the text panel darkens it (to 2/5)
    blue = (b > r + 60) & (b > g + 40)
    hand, obj, static = (_interior(visible[:, c]) for c in range(3))
    assert obj.sum() > 100 and hand.sum() > 100 and static.sum() > 100
    assert green[obj].mean() > 0.9
    assert orange[hand].mean() > 0.9
    assert blue[static].mean() > 0.9
    # Where nothing is rendered there is no green, apart from the colour key's swatch.
    empty = ~visible.any(axis=1)
    empty[:, -scale * H // 4 :, : scale * W // 2] = False
    assert green[empty].mean() < 0.001


def test_reconstruction_alone_without_statics_and_a_background(tmp_path):
    recon = _scene(num_static=0)
    background = np.zeros((N, H, W, 3), np.uint8)
    background[...] = (200, 30, 160)
    paths = save_pictures(recon, None, tmp_path, background=background)
    assert all(path.is_file() for path in paths.values())

    frames = iio.imread(paths["overlay"])[..., :3].astype(int)
    scale = math.ceil(MIN_OVERLAY_WIDTH / W)
    empty = ~_enlarge(_visible(recon), scale).any(axis=1)
    middle = slice(scale * H // 3, 2 * scale * H // 3)
    shown = frames[:, middle][empty[:, middle]]
    assert np.abs(np.median(shown, axis=0) - (200, 30, 160)).max() <= 8


def test_no_video_when_asked(tmp_path):
    recon = _scene()
    paths = save_pictures(recon, _demonstration(recon), tmp_path, frames_video=None)
    assert set(paths) == {"top_view", "trajectories"}
    assert not (tmp_path / "overlay.gif").exists()


def test_mismatched_inputs_raise(tmp_path):
    recon = _scene()
    demo = _demonstration(recon)
    short = _demonstration(
        recon,
        hand_mask=demo.hand_mask[:-1],
        object_mask=demo.object_mask[:-1],
        contact=demo.contact[:-1],
        static_mask=demo.static_mask[:, :-1],
        truth={},
    )
    with pytest.raises(ValueError, match="7 frames, the reconstruction 8"):
        save_pictures(recon, short, tmp_path)
    small = demo.resized(24, 40)
    with pytest.raises(ValueError, match=r"\(24, 40\).*\(48, 80\)"):
        save_pictures(recon, small, tmp_path)
    with pytest.raises(ValueError, match="background"):
        save_pictures(recon, demo, tmp_path, background=np.zeros((N, H, W), np.uint8))
    with pytest.raises(ValueError, match="frames_video"):
        save_pictures(recon, demo, tmp_path, frames_video="avi")
    assert not any(tmp_path.iterdir())
