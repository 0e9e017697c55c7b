"""On top of the static box or behind it: the masks say where it may be, the physics decides."""

import importlib
import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.evaluation import evaluate
from warpskill.engine.distances import static_overlap_depth, support_height
from warpskill.engine.records import Rollout
from warpskill.engine.projection import camera_rotation, project
from warpskill.engine.rotations import yaw_rotation
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.guess import ObjectDepth, initial_guess
from warpskill.optimizer.hypotheses import (
    PhysicsHypothesis,
    Placement,
    best_simulation,
    chosen_simulation,
    judged_simulations,
    read_evidence,
    settled_fit,
    stage_a_candidates,
)
from warpskill.optimizer.inputs import below_static_top_face, carried_into_view, cut_by_static, rests_on_static
from warpskill.optimizer.losses import MaskTargets
from warpskill.optimizer.pipeline import optimize
from warpskill.optimizer.scene import (
    SceneTrajectories,
    ends_behind_static,
    in_front_of_back_penalty,
    static_back,
    off_static_penalty,
    static_in_object_penalty,
)
from warpskill.optimizer.stage_a import initial_objective
from warpskill.optimizer.stage_b import PhysicalRollout, physical_objective
from warpskill.optimizer.weights import LossWeights
from warpskill.synthetic import make_demonstration

pipeline = importlib.import_module("warpskill.optimizer.pipeline")
N, H, W = 20, 40, 60
CONTACT = (np.arange(N) >= 4) & (np.arange(N) < 12)
STATIC = (20, 34, 20, 40)  # rows r0:r1, columns c0:c1


def _masks(object_box, static_box=STATIC):
    """(N, 3, H, W) masks: a hand at the top, the object's box after the release, the static box."""
    masks = np.zeros((N, 3, H, W), dtype=np.float32)
    masks[:12, 0, 0:8, 28:32] = 1
    for k in range(N):
        r0, r1, c0, c1 = object_box if k >= 12 else (10, 18, 5, 15)
        masks[k, 1, r0:r1, c0:c1] = 1
        r0, r1, c0, c1 = static_box
        masks[k, 2, r0:r1, c0:c1] = 1
    return masks


def test_an_object_whose_bottom_lies_inside_the_static_box_may_rest_on_it():
    on_top = _masks((14, 26, 24, 36))  # bottom row 26: inside the static box's rows 20-34
    assert rests_on_static(on_top, CONTACT).tolist() == [False] * 12 + [True] * 8
    on_top[15, 1, 38:40, 0:2] = 1  # a segmenter's stray blob stretches one frame's box below the static's
    assert rests_on_static(on_top, CONTACT).tolist() == [False] * 12 + [True] * 8
    on_top[16:18, 1, 38:40, 0:2] = 1  # in three of the eight frames: no longer most of them
    assert not rests_on_static(on_top, CONTACT).any()


@pytest.mark.parametrize("object_box, why", [
    ((12, 21, 24, 36), "behind: cut at the static's top edge"),
    ((26, 38, 24, 36), "in front: its bottom below the static's"),
    ((18, 28, 44, 56), "next to: beside the static box"),
])
def test_objects_behind_in_front_or_next_to_it_do_not(object_box, why):
    assert not rests_on_static(_masks(object_box), CONTACT).any(), why


def test_an_object_cut_at_the_static_box_top_edge_stands_behind_it():
    behind = _masks((12, 21, 24, 36))  # bottom row 21 at the static's top edge (20): its lower part hidden
    assert cut_by_static(behind, CONTACT).tolist() == [False] * 12 + [True] * 8
    assert not rests_on_static(behind, CONTACT).any()
    for object_box in ((14, 26, 24, 36), (26, 38, 24, 36), (18, 28, 44, 56)):  # on top, in front, next to
        assert not cut_by_static(_masks(object_box), CONTACT).any()


def test_a_static_box_cut_by_the_bottom_border_measures_the_margin_by_the_object():
    # The static's box runs from row 8 out of the view: its 32 rows are no height of the
    # static. An object 10 rows tall standing 3 rows into it is on top (a tenth of 32 rows
    # would call it cut at the edge); one whose bottom stops at the edge is behind.
    cut_static = (8, H, 20, 40)
    on_top = _masks((1, 11, 24, 36), cut_static)
    assert rests_on_static(on_top, CONTACT).tolist() == [False] * 12 + [True] * 8
    assert not cut_by_static(on_top, CONTACT).any()
    behind = _masks((0, 8, 24, 36), cut_static)
    assert cut_by_static(behind, CONTACT).tolist() == [False] * 12 + [True] * 8
    assert not rests_on_static(behind, CONTACT).any()


def test_the_behind_prior_pushes_the_object_past_the_static_box_back_only_in_its_frames():
    weights = LossWeights()
    scene = _one_box_scene(0.25, [0.1, 0.1, 0.1])  # on top: its centre 15 cm short of the back, its front 20
    frames = torch.tensor([0.0, 1.0])
    assert float(in_front_of_back_penalty(scene, frames, weights)) == pytest.approx(
        weights.penetration * 0.15**2 / 2, rel=1e-5)
    assert float(in_front_of_back_penalty(scene, frames, weights, whole_object=True)) == pytest.approx(
        weights.penetration * 0.20**2 / 2, rel=1e-5)
    assert float(in_front_of_back_penalty(scene, torch.zeros(2), weights)) == 0.0
    scene.object_pos.requires_grad_(True)
    in_front_of_back_penalty(scene, frames, weights).backward()
    assert scene.object_pos.grad[1, 1] < 0 and scene.object_pos.grad[0].abs().sum() == 0  # descent: farther back
    behind = _one_box_scene(0.05, [0.1, 0.1, 0.1])
    behind.object_pos[:, 1] = 0.3
    assert float(in_front_of_back_penalty(behind, frames, weights, whole_object=True)) == 0.0
    turned = _one_box_scene(0.05, [0.1, 0.3, 0.1])
    turned.object_rot = yaw_rotation(torch.full((2,), math.pi / 2))  # its 30 cm side across the view: 10 cm deep
    turned.object_pos[:, 1] = 0.21
    assert float(in_front_of_back_penalty(turned, frames, weights, whole_object=True)) == 0.0
    turned.object_rot = torch.eye(3).expand(2, 3, 3)  # 30 cm deep: its front 9 cm short of the back
    assert float(in_front_of_back_penalty(turned, frames, weights, whole_object=True)) == pytest.approx(
        weights.penetration * 0.09**2 / 2, rel=1e-4)


def test_no_static_box_or_no_release_gives_no_frames():
    masks = _masks((14, 26, 24, 36))
    assert not rests_on_static(masks[:, :2], CONTACT).any()
    assert not rests_on_static(masks, np.arange(N) >= 4).any()  # held to the end: no release
    assert not rests_on_static(masks, np.zeros(N, dtype=bool)).any()


def test_the_on_static_guess_stands_the_object_on_a_static_box_that_reaches_under_it():
    demo = make_demonstration("put_onto", seed=0, input="boxes")
    masks = demo.mask_stack(60, 107)
    resting = rests_on_static(demo.mask_stack(*demo.image_size), demo.contact)
    assert resting.any()
    guess = initial_guess(masks, demo.contact, demo.intrinsics, demo.num_static, object_depth="on the static",
                          resting=resting)
    top = guess.static_pos[0, 2] + 0.5 * guess.static_size[0, 2]
    bottom = guess.object_pos[torch.as_tensor(resting), 2] - 0.5 * guess.object_size[2]
    assert torch.allclose(bottom, top.expand_as(bottom), atol=1e-5)
    support = support_height(guess.object_pos[torch.as_tensor(resting)], guess.static_pos, guess.static_rot,
                             guess.static_size)
    assert torch.allclose(support, top.expand_as(support))
    with pytest.raises(ValueError, match="static box"):
        initial_guess(masks, demo.contact, demo.intrinsics, 0, object_depth="on the static", resting=resting)
    with pytest.raises(ValueError, match="object_depth must be one of .*'on the ground'.*not 'floating'"):
        initial_guess(masks, demo.contact, demo.intrinsics, demo.num_static, object_depth="floating")
    as_enum = initial_guess(masks, demo.contact, demo.intrinsics, demo.num_static, object_depth=ObjectDepth.STATIC,
                            resting=resting)
    assert torch.equal(as_enum.object_pos, guess.object_pos)  # the member and its value name the same guess



def test_the_behind_guess_stands_the_object_on_the_ground_behind_a_box_as_tall_as_its_top_edge():
    demo = make_demonstration("put_onto", seed=0, input="boxes")  # the same boxes, read the other way
    masks, intrinsics = demo.mask_stack(60, 107), demo.intrinsics.resized(60, 107)
    resting = rests_on_static(demo.mask_stack(*demo.image_size), demo.contact)
    guess = initial_guess(masks, demo.contact, intrinsics, demo.num_static, object_depth="behind the static",
                          resting=resting)
    placed = torch.as_tensor(resting)
    bottom = guess.object_pos[placed, 2] - 0.5 * guess.object_size[2]
    assert float(bottom.abs().max()) < 5e-3  # on the ground
    front = guess.object_pos[placed, 1].mean() - 0.5 * guess.object_size[1]  # where it rests, on average
    assert float(front) > float(static_back(guess))
    # its back's top edge on the static box's top row (where first seen), as the box says
    top_back = torch.stack([guess.static_pos[0, 0], static_back(guess), guess.static_size[0, 2]])
    in_camera = camera_rotation(guess.camera_elevation).T @ (top_back - torch.stack(
        [torch.tensor(0.0), torch.tensor(0.0), guess.camera_height]).to(top_back))
    row = float(project(in_camera[None].double(), intrinsics.K)[0, 1])
    seen = masks[:, 2].any(axis=(1, 2))
    static_rows = np.flatnonzero((masks[np.flatnonzero(seen)[0], 2] > 0.5).any(axis=1))
    assert abs(row - static_rows.min()) <= 1.0

@pytest.mark.slow
def test_both_placements_go_through_the_physics(monkeypatch):
    starts = []
    make = pipeline.make_physical_scene

    def counted(fit, *args, **kwargs):
        starts.append(fit)
        return make(fit, *args, **kwargs)

    monkeypatch.setattr(pipeline, "make_physical_scene", counted)
    small = OptimizeConfig(iterations=3, init_iterations=3, behind_placement=True)
    demo = make_demonstration("put_onto", seed=0, input="boxes")
    optimize(demo, config=small, progress=False)
    assert len(starts) == 3  # stage (a)'s winner, on the static box, behind it (asked for)
    on_top, behind = starts[1], starts[2]
    assert not torch.equal(starts[0].object_pos, on_top.object_pos)
    assert on_top.object_pos[-1, 1] < static_back(on_top) < behind.object_pos[-1, 1]
    starts.clear()
    optimize(demo, config=replace(small, behind_placement=False), progress=False)
    assert len(starts) == 2  # by default: stage (a)'s winner and on the static box
    starts.clear()
    optimize(make_demonstration("put_in_front_of", seed=0, input="boxes"), config=small, progress=False)
    assert len(starts) == 1  # in front of the static box: nothing says it may stand on it



@pytest.mark.slow
@pytest.mark.parametrize("action, scenarios, seed", [("put_onto", "none", 0), ("put_behind", "turned", 1)])
def test_on_top_or_behind_is_chosen_by_the_evidence_of_a_generated_case(action, scenarios, seed):
    # Both are boxes whose object ends with its bottom inside the static box's rows: the put
    # onto on the box, the put behind behind a turned one (its far edge dips). Both placements
    # are simulated and the one the masks support after the release wins, each the right way.
    demo = make_demonstration(action, seed=seed, input="boxes", scenarios=scenarios)
    seen = read_evidence(demo, {}, OptimizeConfig(), torch.device("cpu"))
    assert seen.resting.any() and not seen.below_top_face.any()  # the boxes alone leave it open
    recon = optimize(demo, config=OptimizeConfig(iterations=20, init_iterations=20), progress=False)
    verdict = evaluate(recon, action)
    assert verdict.success, verdict.checks
    judged = recon.judgements()
    assert len(judged) >= 2 and sum(j["chosen"] for j in judged) == 1
    kept = next(j for j in judged if j["chosen"])
    assert kept["fit"] == min(j["fit"] for j in judged if not j["contradicted"])
    assert kept["ends_behind_static"] == (action == "put_behind")


def _box_demonstration(object_after, static_box, scale=4):
    """A 20-frame box demonstration at ``scale`` times :data:`H` x :data:`W`: the hand above,
    the object carried and released into ``object_after`` (r0, r1, c0, c1), a static box."""
    masks = _masks(object_after, static_box)
    big = masks.repeat(scale, axis=2).repeat(scale, axis=3).astype(bool)
    return Demonstration.from_arrays(big[:, 0], big[:, 1], CONTACT, 12.0, static_mask=big[:, 2][None])


def test_an_object_that_covers_a_narrower_static_box_top_edge_is_tried_on_it_too():
    # Its bottom meets the static's top edge as an object's cut by the box does; it spans the
    # box across, so the box's top edge may be hidden under it: both placements are tried.
    cpu = torch.device("cpu")
    for object_after, covering in (((12, 21, 22, 38), True), ((12, 21, 27, 33), False)):  # wider or narrower
        seen = read_evidence(_box_demonstration(object_after, (20, 34, 24, 36)), {}, OptimizeConfig(), cpu)
        assert not seen.resting.any() and bool(seen.behind is not None)
        assert bool(seen.covering.any()) is covering
        for behind, depths in ((False, [ObjectDepth.STATIC]), (True, [ObjectDepth.STATIC, ObjectDepth.BEHIND])):
            placements = [c.placement for c in stage_a_candidates([seen], 0.45, cpu, behind=behind)
                          if c.placement is not None]
            assert [p.depth for p in placements] == depths * int(covering)
            for placement in placements:
                assert placement.frames.bool().tolist() == [False] * 12 + [True] * 8


def test_a_put_behind_tries_behind_the_static_box_without_being_asked():
    # The action names the relation: its placement goes to the physics by default; a put onto's does not.
    cpu = torch.device("cpu")
    demo = _box_demonstration((12, 21, 22, 38), (20, 34, 24, 36))
    for action, depths in (("put_behind", [ObjectDepth.STATIC, ObjectDepth.BEHIND]), ("put_onto", [ObjectDepth.STATIC])):
        seen = read_evidence(replace(demo, action=action), {}, OptimizeConfig(), cpu)
        placements = [c.placement.depth for c in stage_a_candidates([seen], 0.45, cpu) if c.placement is not None]
        assert placements == depths


def _one_box_scene(object_z, object_size):
    eye = torch.eye(3)
    return SceneTrajectories(
        hand_pos=torch.zeros(2, 3), hand_rot=eye.expand(2, 3, 3), object_pos=torch.tensor([[0.0, 0.0, object_z]] * 2),
        object_rot=eye.expand(2, 3, 3), object_size=torch.tensor(object_size), static_pos=torch.tensor([[0.0, 0.0, 0.1]]),
        static_rot=eye[None], static_size=torch.tensor([[0.3, 0.3, 0.2]]), camera_height=torch.tensor(0.45),
        camera_elevation=torch.tensor(0.6),
    )


def test_a_static_box_inside_a_larger_object_is_penalised_and_one_under_it_is_not():
    weights = LossWeights()
    enclosing = _one_box_scene(0.125, [0.5, 0.5, 0.25])  # every object sample point outside the static box
    assert float(static_in_object_penalty(enclosing, weights)) > 1.0
    resting = _one_box_scene(0.25, [0.1, 0.1, 0.1])  # standing on its top
    assert float(static_in_object_penalty(resting, weights)) == pytest.approx(0.0, abs=1e-9)
    scene = _one_box_scene(0.125, [0.5, 0.5, 0.25])
    scene.object_pos.requires_grad_(True)
    static_in_object_penalty(scene, weights).backward()
    assert scene.object_pos.grad[:, 2].sum() < 0  # the gradient lifts the object off the static box


def test_the_on_static_placement_keeps_the_object_centre_off_the_top_face_edge():
    # Static top 30 x 30 cm, object 10 cm wide: the margin is 2.5 cm, so a centre 14 cm off
    # the static's centre (inside its top face, 1 cm from the edge) is pulled inwards.
    weights, supported = LossWeights(), torch.ones(2)
    for x, penalised in ((0.0, False), (0.12, False), (0.14, True), (0.2, True)):
        scene = _one_box_scene(0.25, [0.1, 0.1, 0.1])
        scene.object_pos[:, 0] = x
        scene.object_pos.requires_grad_(True)
        penalty = off_static_penalty(scene, supported, weights)
        assert (float(penalty.detach()) > 1e-6) is penalised, x
        if penalised:
            penalty.backward()
            assert scene.object_pos.grad[:, 0].sum() > 0  # descent moves the centre back over the box


def test_an_object_that_enters_through_the_border_is_held_from_the_first_frame():
    masks = _masks((14, 26, 24, 36))
    masks[:3, 1] = 0  # unseen until frame 3, where it enters at the top border with the hand
    masks[3, 1] = 0
    masks[3, 1, 0:6, 26:34] = 1
    assert carried_into_view(masks, CONTACT).tolist() == [True] * 4 + [False] * (N - 4)
    assert not (carried_into_view(masks, CONTACT) & CONTACT).any()


@pytest.mark.parametrize("change, why", [
    (lambda m: None, "on the table from the first frame"),
    (lambda m: m[:3, 1].fill(0), "first seen inside the image: uncovered, not carried in"),
])
def test_objects_seen_first_inside_the_image_are_not_carried_in(change, why):
    masks = _masks((14, 26, 24, 36))
    change(masks)
    assert not carried_into_view(masks, CONTACT).any(), why
    assert not carried_into_view(_masks((14, 26, 24, 36)), np.zeros(N, dtype=bool)).any()


def test_an_object_behind_the_static_box_is_told_from_one_on_it():
    on_top = _one_box_scene(0.25, [0.1, 0.1, 0.1])  # static box 0.3 deep around y = 0
    assert not ends_behind_static(on_top)
    behind = _one_box_scene(0.05, [0.1, 0.1, 0.1])
    behind.object_pos[-1, 1] = 0.2  # past the back at y = 0.15
    assert ends_behind_static(behind)
    turned = _one_box_scene(0.05, [0.1, 0.1, 0.1])
    turned.static_rot = torch.tensor([[[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]])  # yaw 90 deg
    turned.static_size = torch.tensor([[0.6, 0.3, 0.2]])  # 0.6 along x: after the turn, 0.6 deep
    turned.object_pos[-1, 1] = 0.2
    assert not ends_behind_static(turned)


def test_on_top_and_behind_are_chosen_by_their_fit_unless_no_box_could_hide_the_bottom():
    # Bottom row 24 within the static box's top face (rows 20-34: its upper 0.4): behind the
    # box is as good an answer as on it (a turned box's far edge dips), the fits decide. Bottom
    # row 28, deeper than the top face and within the box's columns: nothing hides it there,
    # so ending behind contradicts the masks; beside the box (a wider object) it does not.
    cpu = torch.device("cpu")
    behind = _one_box_scene(0.05, [0.1, 0.1, 0.1])
    behind.object_pos[-1, 1] = 0.2
    on_top = _one_box_scene(0.25, [0.1, 0.1, 0.1])
    results = [PhysicalRollout(scene, None, None, None) for scene in (behind, on_top)]  # only their ends are read

    def fitting(fits):
        return [PhysicsHypothesis(0, scene, CONTACT, None, None, fit=fit) for scene, fit in zip((behind, on_top), fits)]

    shallow = read_evidence(_box_demonstration((12, 24, 24, 36), STATIC), {}, OptimizeConfig(), cpu)
    assert shallow.resting.any() and not shallow.below_top_face.any()
    assert chosen_simulation(shallow, fitting((2.6, 2.8)), results) == 0
    assert chosen_simulation(shallow, fitting((2.8, 2.6)), results) == 1
    deep = read_evidence(_box_demonstration((14, 28, 24, 36), STATIC), {}, OptimizeConfig(), cpu)
    assert deep.below_top_face.any() and chosen_simulation(deep, fitting((2.6, 2.8)), results) == 1
    wider = read_evidence(_box_demonstration((14, 28, 14, 46), STATIC), {}, OptimizeConfig(), cpu)
    assert wider.resting.any() and not wider.below_top_face.any()
    assert chosen_simulation(wider, fitting((2.6, 2.8)), results) == 0


def test_every_simulation_is_judged_and_the_one_kept_is_marked():
    cpu = torch.device("cpu")
    behind = _one_box_scene(0.05, [0.1, 0.1, 0.1])
    behind.object_pos[-1, 1] = 0.2
    on_top = _one_box_scene(0.25, [0.1, 0.1, 0.1])
    results = [PhysicalRollout(scene, None, None, None) for scene in (behind, on_top)]
    deep = read_evidence(_box_demonstration((14, 28, 24, 36), STATIC), {}, OptimizeConfig(), cpu)
    placed = Placement(ObjectDepth.STATIC, torch.as_tensor(deep.placement, dtype=torch.float32))
    own = [PhysicsHypothesis(0, behind, CONTACT, None, None, fit=2.6),
           PhysicsHypothesis(0, on_top, CONTACT, None, placed, fit=2.8)]
    judged = judged_simulations(deep, own, results)
    # the better fit ends behind where no box could hide the bottom: ruled out, the other kept
    assert [(j.start, j.fit, j.ends_behind_static, j.contradicted, j.chosen) for j in judged] == [
        ("stage (a)", 2.6, True, True, False), ("on the static", 2.8, False, False, True)]
    assert judged[1].as_dict()["contact_frames"] == int(CONTACT.sum())


def test_an_object_bottom_below_the_static_top_face_within_its_columns_is_found_after_the_release():
    assert below_static_top_face(_masks((14, 28, 24, 36)), CONTACT).tolist() == [False] * 12 + [True] * 8
    assert not below_static_top_face(_masks((12, 24, 24, 36)), CONTACT).any()  # within the top face
    assert not below_static_top_face(_masks((14, 28, 14, 46)), CONTACT).any()  # wider: its bottom beside the box


def test_the_settled_fit_leaves_out_the_frames_in_contact():
    losses = torch.tensor([1.0, 9.0, 9.0, 2.0])
    assert settled_fit(losses, np.array([False, True, True, False])) == 1.5
    assert settled_fit(losses, np.ones(4, bool)) == 5.25  # no frame without contact: all of them


def test_the_best_simulation_is_the_best_fit_the_masks_do_not_contradict():
    assert best_simulation([2.6, 2.8], [True, False]) == 1
    assert best_simulation([2.6, 2.8], [False, False]) == 0
    assert best_simulation([2.6, 2.8], [True, True]) == 0


def test_only_the_physics_objective_asks_an_object_on_the_box_edge_to_move_back():
    weights, frames = LossWeights(), torch.tensor([0.0, 1.0])
    scene = _one_box_scene(0.25, [0.1, 0.1, 0.1])
    scene.object_pos[:, 1] = 0.17  # centre past the back (0.15), front over the box
    masks = torch.zeros(2, 3, 8, 8)
    targets = MaskTargets(masks)
    zero = torch.zeros(1, 2)
    rollout = Rollout(hand_pos=scene.hand_pos[None], hand_rot=scene.hand_rot[None], grasp=zero, grasped=zero,
                      tip_distance=zero, object_pos=scene.object_pos[None], object_rot=scene.object_rot[None],
                      object_vel=torch.zeros(1, 2, 3), object_ang_vel=torch.zeros(1, 2, 3))
    physics = physical_objective(PhysicalRollout(scene, rollout.map(lambda x: x[0]), torch.zeros(3), torch.zeros(2)),
                                 masks, targets, torch.zeros(2), torch.ones(2), weights, behind=frames)
    fit = initial_objective(scene, masks, targets, torch.zeros(2), 12.0, weights, behind=frames)
    assert float(physics["behind the static"]) == pytest.approx(weights.penetration * 0.03**2 / 2, rel=1e-4)
    assert float(fit["behind the static"]) == 0.0


def test_the_static_overlap_depth_is_the_shortest_way_out():
    static = (torch.tensor([[0.0, 0.0, 0.1]]), torch.eye(3)[None], torch.tensor([[0.3, 0.3, 0.2]]))
    eye, cube = torch.eye(3), torch.full((3,), 0.1)
    depth = lambda pos: float(static_overlap_depth(torch.tensor(pos), eye, cube, *static)[0])  # noqa: E731
    assert depth([0.12, 0.0, 0.05]) == pytest.approx(0.08)  # 8 cm in through the side face, 2 cm out
    assert depth([0.0, 0.0, 0.22]) == pytest.approx(0.03)  # sunk 3 cm into the top: up is the shortest
    assert depth([0.0, 0.0, 0.25]) == 0.0 and depth([0.25, 0.0, 0.05]) == 0.0  # on the top, beside it
    pos = torch.tensor([0.11, 0.02, 0.07], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda p: static_overlap_depth(p, eye.double(), cube.double(),
                                                                    *(x.double() for x in static)), (pos,))


def test_the_first_fit_keeps_the_object_out_of_the_static_box():
    # A carried object passing through the box's side is penalised as one sunk in the ground is.
    weights, masks = LossWeights(), torch.zeros(2, 3, 8, 8)
    inside, over = _one_box_scene(0.05, [0.1, 0.1, 0.1]), _one_box_scene(0.25, [0.1, 0.1, 0.1])
    terms = [initial_objective(s, masks, MaskTargets(masks), torch.ones(2), 12.0, weights)["penetration"]
             for s in (inside, over)]
    assert float(terms[0]) == pytest.approx(weights.penetration * 0.2**2, rel=1e-4)  # 20 cm to any way out
    assert float(terms[1]) == 0.0
