"""Batched engine calls and ``optimize_many``: the same results as one scene at a time."""

import numpy as np
import pytest
import torch

from warpskill.contract.camera import Intrinsics
from warpskill.engine.simulation import simulate
from warpskill.optimizer.batching import Backend, render_many, simulate_many
from warpskill.optimizer.checkpoint import Checkpoint
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.loop import copy_state, keep_state, minimise
from warpskill.optimizer.losses import MaskProfile, MaskTargets, masks_loss
from warpskill.optimizer.pipeline import optimize, optimize_many
from warpskill.optimizer.scene import SceneTrajectories, render_scene
from warpskill.optimizer.stage_b import make_physical_scene
from warpskill.synthetic import make_demonstration

SMALL = OptimizeConfig(iterations=6, init_iterations=6)


def _truth_scene(action, seed, dtype=torch.float64):
    truth = make_demonstration(action, seed=seed, noise="none", image_size=(60, 107), duration=2.0).truth
    scene = SceneTrajectories(
        **{k: torch.as_tensor(truth[k], dtype=dtype) for k in SceneTrajectories.__dataclass_fields__})
    return scene, truth


@pytest.mark.slow
def test_render_many_matches_one_scene_at_a_time_values_and_gradients():
    intrinsics = Intrinsics.default(60, 107)
    cases = [_truth_scene("put_onto", 0)[0], _truth_scene("pick_up", 1)[0], _truth_scene("put_behind", 2)[0]]
    for scene in cases:
        for name in ("object_pos", "camera_height", "camera_elevation"):
            getattr(scene, name).requires_grad_(True)
    weights = [torch.rand(scene.hand_pos.shape[0], 2 + scene.static_pos.shape[0], 60, 107, dtype=torch.float64)
               for scene in cases]

    batched = render_many(cases, [intrinsics] * 3, 0.5)
    sum((masks * w).sum() for masks, w in zip(batched, weights)).backward()
    grads = [{n: getattr(s, n).grad.clone() for n in ("object_pos", "camera_height", "camera_elevation")}
             for s in cases]
    for scene, masks, w, grad in zip(cases, batched, weights, grads):
        for name in grad:
            getattr(scene, name).grad = None
        alone = render_scene(scene, intrinsics, 0.5)
        (alone * w).sum().backward()
        assert masks.shape == alone.shape
        np.testing.assert_allclose(masks.detach().numpy(), alone.detach().numpy(), atol=2e-5)
        for name, value in grad.items():
            np.testing.assert_allclose(value.numpy(), getattr(scene, name).grad.numpy(), rtol=1e-3, atol=1e-4,
                                       err_msg=name)


@pytest.mark.slow
def test_render_many_profiles_match_the_masks_profiles_values_and_gradients():
    # Profiles straight from the raster, for a group of three scenes of which two share their
    # targets (two hypotheses of one video), against the profiles of each scene's own masks.
    intrinsics = Intrinsics.default(60, 107)
    onto, behind = _truth_scene("put_onto", 0)[0], _truth_scene("put_behind", 2)[0]
    nudged = SceneTrajectories(**{**vars(onto), "object_pos": onto.object_pos + 0.01})
    cases = [onto, behind, nudged]
    gen = torch.Generator().manual_seed(4)
    shared, own = (MaskTargets((torch.rand(s.hand_pos.shape[0], 3, 60, 107, generator=gen) > 0.6).float())
                   for s in (onto, behind))
    targets = [shared, own, shared]
    leaves = [{n: getattr(s, n).detach().clone().requires_grad_(True) for n in ("object_pos", "camera_height")}
              for s in cases]

    def loss(render):
        scenes = [SceneTrajectories(**{**vars(s), **leaf}) for s, leaf in zip(cases, leaves)]
        profiles = render(scenes)
        total = sum(masks_loss(p, t).sum() for p, t in zip(profiles, targets))
        grads = torch.autograd.grad(total, [x for leaf in leaves for x in leaf.values()])
        return profiles, grads

    batched, batched_grads = loss(lambda scenes: render_many(scenes, [intrinsics] * 3, 0.5, Backend(), targets))
    alone, alone_grads = loss(lambda scenes: [MaskProfile.of(render_scene(s, intrinsics, 0.5), t)
                                              for s, t in zip(scenes, targets)])
    for a, b in zip(batched, alone):
        assert isinstance(a, MaskProfile)
        np.testing.assert_allclose(a.overlap.detach().numpy(), b.overlap.detach().numpy(), atol=2e-3)
        np.testing.assert_allclose(a.moments.rows.detach().numpy(), b.moments.rows.detach().numpy(), atol=2e-4)
    for a, b in zip(batched_grads, alone_grads):
        np.testing.assert_allclose(a.numpy(), b.numpy(), rtol=1e-3, atol=1e-4)


def test_simulate_many_pads_shorter_scenes_without_changing_them():
    config = OptimizeConfig()
    scenes = []
    for action, seed, duration in (("pick_up", 0, 2.0), ("pull_left_to_right", 1, 3.0), ("push_right_to_left", 2, 2.5)):
        demo = make_demonstration(action, seed=seed, noise="none", image_size=(60, 107), duration=duration)
        fit = SceneTrajectories(
            **{k: torch.as_tensor(demo.truth[k], dtype=torch.float32) for k in SceneTrajectories.__dataclass_fields__})
        scenes.append(make_physical_scene(fit, demo.contact, demo.fps, config))
    inputs = [scene.simulation_inputs() for scene in scenes]
    options = [scene.simulation_options() for scene in scenes]
    batched = simulate_many(inputs, options)
    for given, option, rollout in zip(inputs, options, batched):
        alone = simulate(given, **option)
        for name, value in vars(alone).items():
            assert getattr(rollout, name).shape == value.shape, name
            np.testing.assert_allclose(getattr(rollout, name).detach().numpy(), value.detach().numpy(), atol=1e-6,
                                       err_msg=name)


class _Bowl(torch.nn.Module):
    """A quadratic bowl with its own minimum: Adam and the plateau schedule have work to do."""

    def __init__(self, centre):
        super().__init__()
        self.x = torch.nn.Parameter(torch.zeros(3))
        self.register_buffer("centre", torch.as_tensor(centre, dtype=torch.float32))

    def loss(self):
        return {"bowl": (self.x - self.centre).square().sum() + 0.05 * self.x.abs().sum()}


@pytest.mark.slow
def test_minimise_treats_each_module_as_if_it_were_alone():
    config = OptimizeConfig(plateau_patience=3)
    centres = ([0.3, -0.2, 0.1], [2.0, 1.0, -1.0])
    store = Checkpoint(None, "")
    together = [_Bowl(c) for c in centres]
    losses = minimise(together, lambda live: [together[b].loss() for b in live], iterations=400, learning_rate=0.05,
                       config=config, progress=False, label="bowls", store=store)
    for module, loss, centre in zip(together, losses, centres):
        alone = _Bowl(centre)
        [expected] = minimise([alone], lambda live: [alone.loss()], iterations=400, learning_rate=0.05,
                               config=config, progress=False, label="bowl", store=store)
        assert loss == expected
        torch.testing.assert_close(module.x, alone.x, rtol=0, atol=0)


@pytest.mark.slow
def test_optimize_many_matches_optimize_on_each():
    demos = [make_demonstration(a, seed=0, image_size=(60, 107), duration=2.0) for a in ("pick_up", "put_onto")]
    many = optimize_many(demos, config=SMALL, progress=False)
    for demo, recon in zip(demos, many):
        alone = optimize(demo, config=SMALL, progress=False)
        assert str(recon.action) == demo.action and recon.num_frames == demo.num_frames
        assert float(recon.loss) == pytest.approx(float(alone.loss), rel=1e-3)
        np.testing.assert_allclose(recon.object_pos, alone.object_pos, atol=2e-3)
        np.testing.assert_allclose(recon.hand_pos, alone.hand_pos, atol=2e-3)


def test_optimize_many_needs_a_demonstration():
    with pytest.raises(ValueError, match="at least one"):
        optimize_many([])


def test_a_non_finite_loss_names_the_stage_scene_and_iteration():
    bowls = [_Bowl([0.0, 0.0, 0.0]), _Bowl([1.0, 1.0, 1.0])]
    calls = []

    def objective(live):
        calls.append(live)
        terms = [bowls[b].loss() for b in live]
        if len(calls) == 3:
            terms[1]["bowl"] = terms[1]["bowl"] * float("nan")
        return terms

    with pytest.raises(FloatingPointError, match=r"bowls \(scene 1\): the loss became nan at iteration 2"):
        minimise(bowls, objective, iterations=10, learning_rate=0.05, config=OptimizeConfig(), progress=False,
                  label="bowls", store=Checkpoint(None, ""))


def test_minimise_stops_a_rival_far_behind_at_a_rung_and_lets_near_ties_go_on():
    # Bowls 0 and 1 are rivals; 1 starts far from its minimum, so its loss is far above 0's
    # at the rung. Bowl 2 starts as far but has no rivals. Bowls 3 and 4 tie within the margin.
    centres = ([0.1, 0.0, 0.0], [3.0, 3.0, 3.0], [3.0, 3.0, 3.0], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0])
    bowls = [_Bowl(c) for c in centres]
    seen = []

    def objective(live):
        seen.append(list(live))
        return [bowls[b].loss() for b in live]

    minimise(bowls, objective, iterations=30, learning_rate=0.05, config=OptimizeConfig(), progress=False,
              label="bowls", store=Checkpoint(None, ""), rivals=["a", "a", None, "b", "b"], rungs=[(5, 0.1)])
    assert all(1 in live for live in seen[:5])
    assert all(1 not in live and {0, 2, 3, 4} <= set(live) for live in seen[5:])
    assert len(seen) == 30


def test_minimise_stops_a_module_whose_best_loss_has_converged():
    # Bowl 0 starts at its minimum (its best loss never falls); bowl 1 far from it keeps improving.
    bowls = [_Bowl([0.0, 0.0, 0.0]), _Bowl([3.0, 3.0, 3.0])]
    seen = []

    def objective(live):
        seen.append(list(live))
        return [bowls[b].loss() for b in live]

    config = OptimizeConfig(converge_window=8, converge_tolerance=1e-3)
    minimise(bowls, objective, iterations=20, learning_rate=0.05, config=config, progress=False, label="bowls",
             store=Checkpoint(None, ""))
    assert all(0 in live for live in seen[:8]) and all(live == [1] for live in seen[9:])
    assert len(seen) == 20


def test_minimise_runs_the_coarse_objective_first_then_restarts_from_the_best():
    bowl = _Bowl([1.0, 0.0, 0.0])
    calls = []

    def objective(kind, shift):
        def terms(live):
            calls.append(kind)
            return [{"bowl": bowl.loss()["bowl"] + shift}]
        return terms

    config = OptimizeConfig(converge_window=0)
    [best] = minimise([bowl], objective("fine", 0.0), iterations=12, learning_rate=0.05, config=config,
                      progress=False, label="bowl", store=Checkpoint(None, ""), coarse=(5, objective("coarse", -10.0)))
    assert calls[:5] == ["coarse"] * 5 and calls[5:] == ["fine"] * 7
    assert best > 0.0  # the best loss is the fine objective's, not the coarse one's lower values


def test_keep_state_overwrites_a_snapshot_that_shares_nothing_with_the_module():
    module = torch.nn.Linear(3, 2)
    snapshot = copy_state(module)
    with torch.no_grad():
        module.weight.add_(1.0)
    keep_state(module, snapshot)
    assert torch.equal(snapshot["weight"], module.weight) and torch.equal(snapshot["bias"], module.bias)
    assert not snapshot["weight"].requires_grad
    with torch.no_grad():
        module.weight.mul_(2.0)
    assert not torch.equal(snapshot["weight"], module.weight)  # a copy, not the parameter itself
