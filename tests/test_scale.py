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


def test_the_initial_scale_comes_from_the_contact_and_the_resting_object():
    # Stage (a)'s guess reads the scene's depth off the hand's width where it touches the
    # object, and the camera height off the object's bottom edge before the hand touches
    # it (it stands on the ground then): what the masks do elsewhere (a lifted object, a
    # hand near the camera) does not change the guess.
    import torch

    from warpskill.optimizer.inputs import working_inputs
    from warpskill.optimizer.stage_a import initial_guess

    demo = make_demonstration("pick_up", seed=0, image_size=(120, 214), duration=3.0)
    given = working_inputs(demo, OptimizeConfig(image_scale=0.5), torch.device("cpu"))
    masks, contact = given.masks.numpy(), given.contact_signal
    guess = initial_guess(masks, contact, given.intrinsics, demo.num_static)
    onset, last = np.flatnonzero(contact)[[0, -1]]
    spoiled = masks.copy()
    spoiled[onset:, 1] = np.roll(masks[onset:, 1], -8, axis=1)  # the object's box rises after the onset
    spoiled[last + 1:, 0] = np.maximum(masks[last + 1:, 0], np.roll(masks[last + 1:, 0], 3, axis=2))  # wider hand
    moved = initial_guess(spoiled, contact, given.intrinsics, demo.num_static)
    assert float(moved.camera_height) == pytest.approx(float(guess.camera_height), rel=0.05)
    truth = float(demo.truth["camera_height"])
    assert abs(float(guess.camera_height) / truth - 1) < 0.4


def test_stage_a_weighs_the_hand_by_its_own_weight():
    # The hand's known width is what fixes the scene's scale in stage (a): its silhouette
    # counts there with ``initial_hand``, in stage (b) with ``hand``.
    from dataclasses import replace

    import torch

    from warpskill.optimizer.inputs import working_inputs
    from warpskill.optimizer.losses import diou_loss
    from warpskill.optimizer.scene import SceneTrajectories, render_scene
    from warpskill.optimizer.stage_a import initial_objective
    from warpskill.optimizer.weights import LossWeights

    demo = make_demonstration("push_left_to_right", seed=0, image_size=(60, 107), duration=2.0)
    config = OptimizeConfig()
    given = working_inputs(demo, config, torch.device("cpu"))
    scene = SceneTrajectories(**{k: torch.as_tensor(np.asarray(demo.truth[k]), dtype=torch.float32)
                                 for k in SceneTrajectories.__dataclass_fields__})
    rendered = render_scene(scene, given.intrinsics, config.sigma)
    hand = float(diou_loss(rendered, given.targets)[0][:, 0].mean())

    def perceptual(weights):
        return float(initial_objective(scene, rendered, given.targets, given.contact, demo.fps, weights)["perceptual"])

    assert LossWeights().initial_hand > LossWeights().hand
    base = LossWeights(initial_hand=1.0)
    assert perceptual(replace(base, initial_hand=4.0)) - perceptual(base) == pytest.approx(3.0 * hand, rel=1e-4)
    assert perceptual(replace(base, hand=4.0)) == pytest.approx(perceptual(base), rel=1e-6)
