"""Known lengths fix the scene's scale: ``optimize(demo, known=...)`` and ``--known``."""

import numpy as np
import pytest

from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.known import KNOWN_LENGTHS, check_known, parse_known
from warpskill.optimizer.pipeline import optimize
from warpskill.synthetic import make_demonstration

SMALL = OptimizeConfig(iterations=6, init_iterations=6)


@pytest.fixture(scope="module")
def put_onto():
    return make_demonstration("put_onto", seed=0, image_size=(60, 107), duration=2.0)


@pytest.mark.parametrize("name, value", [("object_height", 0.1), ("camera_height", 0.6), ("static_width", 0.2)])
def test_a_known_length_comes_out_exactly(put_onto, name, value):
    recon = optimize(put_onto, config=SMALL, progress=False, known={name: value})
    got = {"object_height": recon.object_size[2], "camera_height": float(recon.camera_height),
           "static_width": recon.static_size[0, 0]}[name]
    assert got == pytest.approx(value, rel=1e-5)


def test_a_known_length_scales_the_whole_scene(put_onto):
    free = optimize(put_onto, config=SMALL, progress=False, init_only=True)
    ratio = 1.5
    known = optimize(put_onto, config=SMALL, progress=False, init_only=True,
                     known={"object_height": ratio * float(free.object_size[2])})
    # Stage (a) with the height pinned starts from the same guess scaled about the camera:
    # the camera height scales with it (up to what the few iterations change).
    assert float(known.camera_height) / float(free.camera_height) == pytest.approx(ratio, rel=0.15)


def test_known_lengths_are_checked():
    assert parse_known(["object_height=0.1", "camera_height=0.5"]) == {"object_height": 0.1, "camera_height": 0.5}
    assert parse_known(None) == {}
    with pytest.raises(ValueError, match="NAME=METRES"):
        parse_known(["object_height"])
    with pytest.raises(ValueError, match="unknown length"):
        check_known({"hand_length": 0.4})
    with pytest.raises(ValueError, match="positive"):
        check_known({"object_height": -1})
    assert "object_height" in KNOWN_LENGTHS and "camera_height" in KNOWN_LENGTHS


def test_the_command_line_takes_known_lengths():
    import argparse

    from warpskill.cli.common import add_optimise_options

    parser = argparse.ArgumentParser()
    add_optimise_options(parser)
    args = parser.parse_args(["--known", "object_height=0.10", "static_height=0.05"])
    assert parse_known(args.known) == {"object_height": 0.10, "static_height": 0.05}
    assert np.isclose(parse_known(args.known)["object_height"], 0.1)


@pytest.mark.parametrize("axis, tolerance", [((1.0, 0.0, 0.15), 0.05), ((-1.0, 0.3, 0.3), 0.05), ((0.3, -0.6, 0.8), 0.2)],
                         ids=["across the view", "across and away", "reaching down"])
def test_the_hand_tip_depth_comes_from_the_masks_width_at_the_tip(axis, tolerance):
    import torch

    from warpskill.contract.camera import Intrinsics
    from warpskill.contract.geometry import frame_from_axis
    from warpskill.engine.projection import project, world_to_camera
    from warpskill.engine.raycast import raycast_masks
    from warpskill.optimizer.stage_a import _hand_depth, _MaskGeometry

    # The default camera's pixels are not square (fx != fy): a hand lying across the view is
    # measured top to bottom. A hand reaching down from the camera's side (local z up and
    # towards the camera, which looks along +y) comes closer to the camera, and widens,
    # away from its tip (the old estimate, over a disc three widths around the tip: -42 %).
    intrinsics = Intrinsics.default(120, 214)
    height, elevation = 0.45, 0.6
    tip = np.array([[0.02, 0.45, 0.06]])
    masks = raycast_masks(tip, frame_from_axis(np.array([axis])), np.zeros((1, 0, 3)), np.zeros((1, 0, 3, 3)),
                          np.zeros((0, 3)), height, elevation, intrinsics)
    f64 = lambda x: torch.tensor(x, dtype=torch.float64)  # noqa: E731
    camera = world_to_camera(f64(tip), f64(height), f64(elevation))
    tip_pixel = project(camera, torch.as_tensor(intrinsics.K)).numpy()
    estimate = _hand_depth(_MaskGeometry(masks[:, 0].astype(float)), tip_pixel, intrinsics.K)
    assert estimate == pytest.approx(float(camera[0, 2]), rel=tolerance)
