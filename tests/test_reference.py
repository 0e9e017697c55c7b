"""The Warp engine against its plain-Torch reference (``warpskill.engine.reference``): values and
gradients (Warp's bridges against Torch autograd) of the rollout and the soft silhouettes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from warpskill.contract.camera import Intrinsics
from warpskill.engine.records import SceneInputs
from warpskill.engine.reference.physics import simulate_reference
from warpskill.engine.reference.raster import render_reference
from warpskill.engine.rendering import render_silhouettes
from warpskill.engine.simulation import simulate
from warpskill.optimizer.scene import SceneTrajectories, render_scene
from warpskill.synthetic import make_demonstration, scripted_inputs, scripted_scene

DURATION = 2.0  # [s]: 480 steps of 1/240 s, the hand grasps, carries and releases


def rollout_inputs(dtype: torch.dtype) -> tuple[SceneInputs, dict]:
    """Scripted put_onto: grasp at about 0.7 s, carry onto the static cuboid, release at 1.5 s;
    the inputs and the keyword options of ``simulate``."""
    return scripted_inputs(scripted_scene("put_onto", duration=DURATION), 12.0, DURATION, dtype=dtype)


def leaves(inputs: SceneInputs) -> SceneInputs:
    return inputs.map(lambda v: v.clone().requires_grad_(True))


@pytest.fixture(scope="module")
def rollouts64():
    """Warp and reference rollouts (float64) and their input gradients under one random projection."""
    results = []
    for simulator in (simulate, simulate_reference):
        inputs, options = rollout_inputs(torch.float64)
        inputs = leaves(inputs)
        out = simulator(inputs, **options)
        generator = torch.Generator().manual_seed(1)  # the same weights for both
        weights = {k: torch.randn(v.shape, generator=generator, dtype=v.dtype) for k, v in vars(out).items()}
        sum((getattr(out, k) * w).sum() for k, w in weights.items()).backward()
        grads = {k: v.grad for k, v in inputs.items()}
        results.append((out, grads))
    return results


@pytest.mark.slow
def test_rollout_values_agree_in_float64(rollouts64):
    (warp, _), (ref, _) = rollouts64
    grasped = warp.grasped[0].detach()
    assert grasped.max() > 0.99 and grasped[-1] < 0.01, "the scene must grasp and release"
    for name in vars(warp):
        a, b = getattr(warp, name).detach(), getattr(ref, name).detach()
        assert (a - b).abs().max() < 1e-11, name  # [m], [m/s], [rad/s], rotations, switch


def test_rollout_gradients_agree_in_float64(rollouts64):
    (_, warp), (_, ref) = rollouts64
    for name in warp:
        rel = float((warp[name] - ref[name]).norm() / warp[name].norm())
        assert rel < 1e-8, f"{name}: relative difference {rel:.1e}"


@pytest.mark.slow
def test_rollout_values_agree_in_float32():
    inputs, options = rollout_inputs(torch.float32)
    warp, ref = simulate(inputs, **options), simulate_reference(inputs, **options)
    for name in vars(warp):
        a, b = getattr(warp, name), getattr(ref, name)
        assert b.dtype == torch.float32
        assert (a - b).abs().max() < 2e-5, name


def test_reference_rollout_rejects_what_simulate_rejects():
    inputs, options = rollout_inputs(torch.float64)
    with pytest.raises(ValueError, match="object_size must be positive"):
        simulate_reference(replace(inputs, object_size=-inputs.object_size), **options)
    with pytest.raises(ValueError, match="hand_vel must have"):
        simulate_reference(replace(inputs, hand_vel=inputs.hand_vel[:, :-1]), **options)


@pytest.fixture(scope="module")
def small_scene():
    """Eight frames of a put_onto demonstration at 60 x 107 px: the hand in front of and
    behind the object, the object over the static cuboid (overlapping soft layers)."""
    demo = make_demonstration("put_onto", noise="none", image_size=(60, 107), duration=2.5)
    truth = demo.truth
    frames = np.linspace(0, len(truth["t"]) - 1, 8).round().astype(int)
    f = lambda key: torch.as_tensor(truth[key], dtype=torch.float64)  # noqa: E731
    scene = SceneTrajectories(
        hand_pos=f("hand_pos")[frames],
        hand_rot=f("hand_rot")[frames],
        object_pos=f("object_pos")[frames],
        object_rot=f("object_rot")[frames],
        object_size=f("object_size"),
        static_pos=f("static_pos"),
        static_rot=f("static_rot"),
        static_size=f("static_size"),
        camera_height=f("camera_height"),
        camera_elevation=f("camera_elevation"),
    )
    return scene, Intrinsics(truth["camera_K"], demo.image_size).resized(60, 107)


def render_both(scene: SceneTrajectories, intrinsics: Intrinsics, dtype: torch.dtype, sigma: float):
    """Masks and scene gradients of a random projection, for the Warp and the reference raster."""
    weights = None
    results = []
    for renderer in (render_silhouettes, render_reference):
        s = SceneTrajectories(**{k: v.to(dtype).clone().requires_grad_(True) for k, v in vars(scene).items()})
        masks = _render_with(renderer, s, intrinsics, sigma)
        if weights is None:
            weights = torch.rand(masks.shape, generator=torch.Generator().manual_seed(2), dtype=dtype)
        (masks * weights).sum().backward()
        results.append((masks.detach(), {k: v.grad for k, v in vars(s).items()}))
    return results


def _render_with(renderer, scene: SceneTrajectories, intrinsics: Intrinsics, sigma: float) -> torch.Tensor:
    if renderer is render_silhouettes:
        return render_scene(scene, intrinsics, sigma)
    N, K = scene.hand_pos.shape[0], scene.static_pos.shape[0]
    return renderer(
        scene.hand_pos,
        scene.hand_rot,
        torch.cat([scene.object_pos[:, None], scene.static_pos[None].expand(N, K, 3)], 1),
        torch.cat([scene.object_rot[:, None], scene.static_rot[None].expand(N, K, 3, 3)], 1),
        torch.cat([scene.object_size[None], scene.static_size]),
        scene.camera_height,
        scene.camera_elevation,
        intrinsics,
        sigma=sigma,
    )


@pytest.mark.slow
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_render_values_and_gradients_agree(small_scene, dtype):
    scene, intrinsics = small_scene
    (warp, warp_grad), (ref, ref_grad) = render_both(scene, intrinsics, dtype, sigma=0.5)
    assert ref.dtype == dtype
    overlapping = ((ref > 0.01).sum(1) >= 2).sum()
    assert overlapping > 20, "the scene must overlap soft layers"
    assert (warp.double() - ref.double()).abs().max() < 2e-5  # the kernels rasterize in float32
    for name, grad in warp_grad.items():
        if grad is not None:
            rel = float((grad - ref_grad[name]).norm() / grad.norm())
            assert rel < 1e-4, f"{name}: relative difference {rel:.1e}"


def test_reference_render_handles_no_cuboids_and_a_clipped_hand(small_scene):
    scene, intrinsics = small_scene
    N = scene.hand_pos.shape[0]
    behind = scene.hand_pos.clone()
    behind[0, 1] = -5.0  # far behind the camera: not drawn
    empty = torch.zeros(N, 0, 3, dtype=torch.float64)
    args = (behind, scene.hand_rot, empty, torch.zeros(N, 0, 3, 3, dtype=torch.float64), torch.zeros(0, 3))
    camera = (scene.camera_height, scene.camera_elevation, intrinsics)
    ref = render_reference(*args, *camera)
    warp = render_silhouettes(*args, *camera)
    assert ref.shape == (N, 1, 60, 107) and ref[0].max() == 0
    assert (warp - ref).abs().max() < 2e-5
