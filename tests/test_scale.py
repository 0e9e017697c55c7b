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


@pytest.mark.slow
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

    from warpskill.cli.common import add_optimize_options

    parser = argparse.ArgumentParser()
    add_optimize_options(parser)
    args = parser.parse_args(["--known", "object_height=0.10", "static_height=0.05"])
    assert parse_known(args.known) == {"object_height": 0.10, "static_height": 0.05}
    assert np.isclose(parse_known(args.known)["object_height"], 0.1)


@pytest.mark.parametrize("axis, tolerance", [((1.0, 0.0, 0.15), 0.05), ((-1.0, 0.3, 0.3), 0.05), ((0.3, -0.6, 0.8), 0.2)],
                         ids=["across the view", "across and away", "reaching down"])
def test_the_hand_tip_depth_comes_from_the_masks_width_at_the_tip(axis, tolerance):
    import torch

    from warpskill.contract.camera import Intrinsics
    from warpskill.engine.projection import project, world_to_camera
    from warpskill.engine.raycast import raycast_masks
    from warpskill.geometry import frame_from_axis
    from warpskill.optimizer.measurements import MaskGeometry, hand_depth

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
    estimate = hand_depth(MaskGeometry(masks[:, 0].astype(float)), tip_pixel, intrinsics.K)
    assert estimate == pytest.approx(float(camera[0, 2]), rel=tolerance)


def test_the_hand_tilt_towards_the_camera_comes_from_its_foreshortening():
    import torch

    from warpskill.contract.camera import Intrinsics
    from warpskill.engine.projection import camera_rotation
    from warpskill.engine.raycast import raycast_masks
    from warpskill.geometry import frame_from_axis
    from warpskill.optimizer.measurements import TYPICAL_HAND_TILT, MaskGeometry, hand_tilt

    intrinsics = Intrinsics.default(120, 214)
    height, elevation = 0.45, 0.6
    to_camera = camera_rotation(torch.tensor(elevation, dtype=torch.float64)).numpy().T

    def tilt(axis):
        rot = frame_from_axis(np.array([axis], dtype=float))
        masks = raycast_masks(np.array([[0.02, 0.45, 0.06]]), rot, np.zeros((1, 0, 3)), np.zeros((1, 0, 3, 3)),
                              np.zeros((0, 3)), height, elevation, intrinsics)
        truth = -float((to_camera @ rot[0, :, 2])[2])  # the axis's component towards the camera
        return hand_tilt(MaskGeometry(masks[:, 0].astype(float)), intrinsics.K), truth

    # Reaching down towards the camera: short in the image, read as tilted well past the
    # typical forearm (perspective lengthens the near part: an underestimate, 0.61 here).
    estimate, truth = tilt((0.3, -0.3, 0.8))
    assert truth == pytest.approx(0.77, abs=0.01) and TYPICAL_HAND_TILT + 0.1 < estimate < truth
    estimate, truth = tilt((1.0, -0.1, 0.2))  # across the view: long, read as the typical tilt
    assert truth < TYPICAL_HAND_TILT and estimate == TYPICAL_HAND_TILT


def test_a_hand_mask_one_pixel_thin_reads_as_the_typical_tilt_and_no_depth():
    from warpskill.contract.camera import Intrinsics
    from warpskill.optimizer.measurements import TYPICAL_HAND_TILT, MaskGeometry, hand_depth, hand_tilt

    masks = np.zeros((1, 60, 107))
    masks[0, 30, 20:60] = 1.0  # a segmenter's sliver: no width across it
    geom, K = MaskGeometry(masks), Intrinsics.default(60, 107).K
    assert hand_tilt(geom, K) == TYPICAL_HAND_TILT
    assert hand_depth(geom, np.array([[20.0, 30.0]]), K) is None  # the camera starts at its typical height


def test_the_guess_leans_a_hand_reaching_down_towards_the_camera(put_onto):
    import torch

    from warpskill.optimizer.guess import initial_guess
    from warpskill.optimizer.inputs import working_inputs
    from warpskill.optimizer.measurements import TYPICAL_HAND_TILT

    given = working_inputs(put_onto, OptimizeConfig(), torch.device("cpu"))

    def toward_camera(hand_tilt):
        guess = initial_guess(given.masks.numpy(), given.contact_signal, given.intrinsics, put_onto.num_static,
                              hand_tilt=hand_tilt)
        axis = guess.hand_rot[:, :, 2].double()
        e = guess.camera_elevation.double()
        view = torch.stack([torch.zeros_like(e), torch.cos(e), -torch.sin(e)])  # the camera's optical axis
        return -(axis @ view)

    assert torch.allclose(toward_camera(False), torch.tensor(TYPICAL_HAND_TILT, dtype=torch.float64), atol=1e-5)
    assert float(toward_camera(True).median()) > TYPICAL_HAND_TILT + 0.1
