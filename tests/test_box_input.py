"""Masks drawn from box annotations: recognised, compared by their boxes, and the scale left to a weak prior."""

import numpy as np
import pytest
import torch

from warpskill.data.boxes.something_else import box_masks
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.guess import initial_guess
from warpskill.optimizer.inputs import drawn_from_boxes, working_inputs
from warpskill.optimizer.losses import MaskTargets, box_loss, diou_loss
from warpskill.optimizer.pipeline import optimize
from warpskill.optimizer.scene import camera_height_prior, footprint_prior
from warpskill.optimizer.weights import LossWeights
from warpskill.synthetic import make_demonstration

H, W = 48, 64


def _band(width: float, H: int = H, W: int = W) -> np.ndarray:
    """(H, W) float: a diagonal band ``width`` px wide from the top-left to the bottom-right corner."""
    rows, cols = np.mgrid[0:H, 0:W] + 0.5
    distance = np.abs(rows * W - cols * H) / np.hypot(H, W)
    return (distance < width / 2).astype(np.float64)


@pytest.mark.parametrize("shape", ["ellipse", "rectangle"])
def test_masks_drawn_from_boxes_are_recognised(shape):
    rng = np.random.default_rng(0)
    x0, y0 = rng.uniform(0, 30, 10), rng.uniform(0, 20, 10)
    boxes = np.stack([x0, y0, x0 + rng.uniform(5, 30, 10), y0 + rng.uniform(5, 25, 10)], 1)
    boxes[3] = np.nan  # an empty frame does not count
    assert drawn_from_boxes(box_masks(boxes, (H, W), shape))


def test_segmentation_masks_are_not_taken_for_boxes():
    demo = make_demonstration("pick_up", seed=1, image_size=(60, 107), duration=2.0)
    assert not drawn_from_boxes(demo.hand_mask.astype(bool))
    assert not drawn_from_boxes(np.stack([_band(6) > 0] * 5))
    assert not drawn_from_boxes(np.zeros((3, H, W), bool))


def test_box_demonstrations_are_recognised():
    demo = make_demonstration("pick_up", seed=1, image_size=(60, 107), duration=2.0, input="boxes")
    assert drawn_from_boxes(demo.hand_mask.astype(bool))


@pytest.mark.slow
@pytest.mark.parametrize("input, boxed", [("boxes", True), ("masks", False)])
def test_a_hand_and_object_drawn_from_boxes_are_compared_by_their_boxes(input, boxed):
    demo = make_demonstration("put_onto", seed=0, duration=2.0, input=input)
    given = working_inputs(demo, OptimizeConfig(), torch.device("cpu"))
    assert given.targets.boxed.tolist() == [boxed, boxed, False]  # the static box keeps the area fit
    assert given.hand_boxed == boxed


def test_a_cuboid_silhouette_fills_its_box_by_the_box_loss_but_not_by_the_ellipse_iou():
    ellipse = torch.as_tensor(box_masks(np.array([[8.0, 6.0, 56.0, 42.0]]), (H, W))[0], dtype=torch.float64)
    targets = MaskTargets(ellipse[None])

    def rectangle(margin: int) -> torch.Tensor:  # a front-on cuboid's silhouette, ``margin`` px inside the box
        out = torch.zeros(H, W, dtype=torch.float64)
        out[6 + margin : 42 - margin, 8 + margin : 56 - margin] = 1
        return out[None]

    by_box = [float(box_loss(rectangle(m), targets)[0]) for m in range(6)]
    by_area = [float(diou_loss(rectangle(m), targets)[0][0]) for m in range(6)]
    assert int(np.argmin(by_box)) == 0  # the whole box
    assert int(np.argmin(by_area)) > 0  # a smaller cuboid: the bias the box loss removes


def test_a_thin_band_filling_a_box_matches_its_ellipse_by_box_not_by_iou():
    ellipse = torch.as_tensor(box_masks(np.array([[0.0, 0.0, W, H]]), (H, W))[0], dtype=torch.float64)
    thin, thick = torch.as_tensor(_band(4)), torch.as_tensor(_band(30))
    targets = MaskTargets(ellipse[None])
    # The dIoU asks the band to be as wide as the ellipse (a near, large-looking hand) ...
    assert diou_loss(thin[None], targets)[0] > diou_loss(thick[None], targets)[0] + 0.2
    # ... the box loss is content with the thin band that spans the box.
    assert box_loss(thin[None], targets)[0] < 0.05
    short = torch.zeros(H, W, dtype=torch.float64)
    short[: H // 2, : W // 2] = thin[: H // 2, : W // 2]
    assert box_loss(short[None], targets)[0] > 0.4


def test_box_loss_of_empty_masks():
    target = torch.zeros(2, H, W, dtype=torch.float64)
    target[0, 10:20, 10:30] = 1
    rendered = torch.zeros(2, H, W, dtype=torch.float64, requires_grad=True)
    loss = box_loss(rendered, MaskTargets(target))
    assert loss.tolist() == [2.0, 0.0]  # empty rendering: maximal; empty target: no term
    (loss.sum()).backward()
    assert torch.isfinite(rendered.grad).all()


@pytest.mark.slow
def test_box_loss_gradient_matches_finite_differences():
    rng = np.random.default_rng(3)
    target = torch.as_tensor(box_masks(np.array([[5.0, 4.0, 17.0, 13.0]]), (16, 24)), dtype=torch.float64)
    rendered = torch.as_tensor(rng.uniform(0.0, 1.0, (1, 16, 24)) * (rng.uniform(size=(1, 16, 24)) < 0.3),
                               dtype=torch.float64).requires_grad_()
    targets = MaskTargets(target)
    assert torch.autograd.gradcheck(lambda r: box_loss(r, targets), (rendered,), eps=1e-6, atol=1e-6)


def test_the_camera_height_prior_is_zero_at_the_typical_height_and_grows_in_log():
    weights = LossWeights()

    def prior(height):
        return float(camera_height_prior(type("S", (), {"camera_height": torch.tensor(height)})(), weights))

    assert prior(weights.typical_camera_height) == pytest.approx(0.0, abs=1e-12)
    assert prior(weights.typical_camera_height * 2) == pytest.approx(prior(weights.typical_camera_height / 2))
    assert prior(0.1) > prior(0.3) > 0


def test_the_footprint_prior_is_zero_for_a_square_footprint_and_grows_in_log_of_depth_over_width():
    weights = LossWeights()

    def prior(size):
        return footprint_prior(type("S", (), {"object_size": torch.tensor(size, dtype=torch.float64)})(), weights)

    assert float(prior([0.08, 0.08, 0.20])) == pytest.approx(0.0, abs=1e-12)  # the height plays no part
    assert float(prior([0.05, 0.10, 0.07])) == pytest.approx(float(prior([0.10, 0.05, 0.07])))
    assert float(prior([0.05, 0.10, 0.07])) == pytest.approx(weights.object_footprint * np.log(2.0) ** 2)
    assert float(prior([0.05, 0.20, 0.07])) > float(prior([0.05, 0.10, 0.07])) > 0
    size = torch.tensor([0.06, 0.11, 0.09], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda s: footprint_prior(type("S", (), {"object_size": s})(), weights), (size,))


@pytest.mark.slow
def test_the_footprint_prior_keeps_a_box_drawn_object_about_as_deep_as_wide():
    # A box says nothing of the object's depth; with a known height, a deeper object farther
    # away draws the same box. Stage (a) on a box demonstration, without and with the prior.
    demo = make_demonstration("put_next_to", seed=6, input="boxes", duration=2.0)
    height = float(demo.truth["object_size"][2])

    def depth_over_width(footprint):
        # coarse_iterations=0: started at half resolution, the fit without the prior keeps the footprint too
        config = OptimizeConfig(init_iterations=80, coarse_iterations=0,
                                weights=LossWeights(object_footprint=footprint))
        fit = optimize(demo, progress=False, init_only=True, config=config, known={"object_height": height})
        return fit.object_size[1] / fit.object_size[0]

    without, with_prior = depth_over_width(0.0), depth_over_width(LossWeights().object_footprint)
    assert abs(np.log(with_prior)) < abs(np.log(without)) - 0.05


def test_each_prior_is_on_only_where_it_has_something_to_decide():
    weights = LossWeights()

    def priors(known_length, object_from_boxes):
        scene = weights.for_scene(known_length=known_length, object_from_boxes=object_from_boxes)
        assert scene.object == weights.object  # the other weights as they are
        return scene.camera_height, scene.object_footprint

    assert priors(False, False) == (weights.camera_height, 0.0)
    assert priors(False, True) == (weights.camera_height, 0.0)
    assert priors(True, False) == (0.0, 0.0)
    assert priors(True, True) == (weights.camera_height, weights.object_footprint)  # a box leaves the scale free


def test_boxed_hands_leave_the_initial_camera_at_its_typical_height():
    demo = make_demonstration("pull_left_to_right", seed=0, image_size=(60, 107), duration=2.0, input="boxes")
    masks = demo.mask_stack(60, 107)
    guess = initial_guess(masks, demo.contact, demo.intrinsics, demo.num_static, hand_width=False)
    typical = LossWeights().typical_camera_height
    assert float(guess.camera_height) == pytest.approx(typical)
    measured = initial_guess(masks, demo.contact, demo.intrinsics, demo.num_static, hand_width=True)
    assert float(measured.camera_height) != pytest.approx(typical)


def test_parts_out_of_sight_are_runs_of_empty_frames_of_a_part_seen_elsewhere():
    from warpskill.optimizer.inputs import out_of_sight

    masks = np.zeros((10, 3, 8, 8), dtype=np.float32)
    masks[:, 0, :2, :2] = 1
    masks[[0, 1, 2, 3, 5, 9], 1, 3:5, 3:5] = 1  # lost for one frame (4), hidden for three (6-8)
    masks[:, 2] = 0  # a static part never seen: nothing is known of it
    masks[6:, 0] = 0  # the hand is never asked to hide
    absent = out_of_sight(masks)
    assert absent[:, 1].tolist() == [False] * 6 + [True] * 3 + [False]
    masks[:4, 1] = 0  # not yet seen in frames 0-3: carried into the view, perhaps
    assert out_of_sight(masks)[:, 1].tolist() == [False] * 6 + [True] * 3 + [False]
    assert not absent[:, 0].any() and not absent[:, 2].any()


def test_a_rendering_of_a_hidden_part_is_asked_to_vanish():
    from warpskill.optimizer.losses import hidden_loss

    target = torch.zeros(4, 2, H, W, dtype=torch.float64)
    target[:2, 1, 10:20, 10:30] = 1  # seen with 200 px in frames 0-1, hidden in 2-3
    absent = torch.zeros(4, 2, dtype=torch.bool)
    absent[2:, 1] = True
    targets = MaskTargets(target, absent=absent)
    rendered = torch.zeros(4, 2, H, W, dtype=torch.float64, requires_grad=True)
    with torch.no_grad():
        rendered[2, 1, :5, :10] = 1  # 50 px still showing: a quarter of the typical 200
        rendered[3, 1] = 1  # everything showing: at most 1
    loss = hidden_loss(rendered, targets)
    assert loss[2, 1].item() == pytest.approx(0.25) and loss[3, 1].item() == pytest.approx(1.0)
    loss[2, 1].backward()
    assert (rendered.grad[2, 1] > 0).all()


def test_a_carried_box_that_grows_is_read_as_the_object_coming_closer():
    from warpskill.contract.camera import Intrinsics

    N, h, w = 12, 60, 107
    masks = np.zeros((N, 2, h, w), dtype=np.float32)
    masks[:, 0, 0:20, 50:54] = 1
    for k in range(N):
        half = 6 if k < 6 else 6 + 3 * (k - 5)  # from frame 6 on, the box widens into the bottom border
        masks[k, 1, 30 - half // 2 : 30 + half // 2 if k < 6 else h, 53 - half : 53 + half] = 1
    contact = np.arange(N) >= 3
    guess = initial_guess(masks, contact, Intrinsics.default(h, w), 0, object_depth="resting depth", hand_width=False)
    from warpskill.engine.projection import world_to_camera

    def depth(guess):
        return world_to_camera(guess.object_pos.double(), guess.camera_height.double(),
                               guess.camera_elevation.double())[:, 2]

    assert depth(guess)[-1] < 0.6 * depth(guess)[0]  # 12 px wide, then 36: about a third as far
    assert torch.allclose(depth(guess)[:6], depth(guess)[0].expand(6), rtol=1e-3)
    # Not in the hand: the box's bottom edge on the ground places it, as for any resting cuboid.
    resting = initial_guess(masks, contact, Intrinsics.default(h, w), 0, object_depth="resting depth",
                            hand_width=False, carried=np.zeros(N, bool))
    assert depth(resting)[-1] > 0.9 * depth(resting)[0]
