"""The dopri5 baseline (``warpskill.engine.reference.dopri5``: adaptive dopri5 with grasp/release
events, hard switch) against the analytic free fall, against Warp's ``simulate``
(semi-implicit Euler, dt = 1/240 s, sigmoid switch), and its gradients against finite
differences.

Tolerances, measured on these scenes (float64): free fall within 1e-7 m of the analytic
solution (Warp's Euler within g dt t / 2, 1 mm at 0.5 s); the scripted put_onto (rest,
grasp at 0.65 s, carry, release at 1.49 s, landing) within 0.2 mm of Warp in position
(bound 0.5 mm); in velocity 2.5 mm/s while the object settles, 12 mm/s while it lands on
the static cuboid (bound 20 mm/s where Warp's switch is saturated) and 24 mm/s on the
frame right after the release, where Warp's sigmoid is not (bound 50 mm/s).
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
import torch

from warpskill.engine.records import SceneInputs
from warpskill.engine.simulation import PhysicsConfig, simulate

pytest.importorskip("torchdiffeq")  # the optional extra "baselines"
from warpskill.engine.reference.dopri5 import simulate_dopri5
from warpskill.synthetic import scripted_inputs, scripted_scene

DURATION = 2.0  # [s]
FPS = 12.0


@pytest.fixture(scope="module", autouse=True)
def one_thread():
    """One Torch thread: dopri5's many small operations run fastest so (and ~5x slower
    with two threads on a loaded 2-core machine)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def put_onto(dtype=torch.float64) -> tuple[SceneInputs, dict]:
    return scripted_inputs(scripted_scene("put_onto", duration=DURATION), FPS, DURATION, dtype=dtype)


@pytest.fixture(scope="module")
def put_onto_rollouts():
    inputs, options = put_onto()
    events: list = []
    return inputs, options, simulate(inputs, **options), simulate_dopri5(inputs, **options, events=events), events[0]


def free_fall_inputs(frames: int = 7) -> tuple[SceneInputs, dict]:
    """A cuboid 2 m up, the hand 1 m away with its grasp open: nothing but gravity and damping."""
    inputs, options = scripted_inputs(scripted_scene("put_onto", duration=1.0), FPS, 1.0, dtype=torch.float64)
    steps = (frames - 1) * options["steps_per_frame"]
    fall = replace(
        inputs,
        hand_pos0=torch.tensor([[1.0, 0.0, 1.0]], dtype=torch.float64),
        grasp0=torch.tensor([-0.02], dtype=torch.float64),
        hand_vel=torch.zeros(1, steps, 7, dtype=torch.float64),
        object_pos0=torch.tensor([[0.0, 0.0, 2.0]], dtype=torch.float64),
        static_pos=inputs.static_pos[:, :0],
        static_rot=inputs.static_rot[:, :0],
        static_size=inputs.static_size[:, :0],
    )
    return fall, options


@pytest.mark.slow
def test_free_fall_matches_the_analytic_solution_and_warp():
    inputs, options = free_fall_inputs()
    out = simulate_dopri5(inputs, **options)
    c, g = PhysicsConfig().free_damping, PhysicsConfig().gravity
    t = torch.arange(out.object_pos.shape[1], dtype=torch.float64) / FPS
    z = 2.0 - g / c * (t - (1.0 - torch.exp(-c * t)) / c)
    vz = -g / c * (1.0 - torch.exp(-c * t))
    assert (out.object_pos[0, :, 2] - z).abs().max() < 1e-7
    assert (out.object_vel[0, :, 2] - vz).abs().max() < 1e-7
    assert (out.grasped == 0).all()
    warp = simulate(inputs, **options)
    dt = 1.0 / (FPS * options["steps_per_frame"])
    lag = (warp.object_pos[0, :, 2] - out.object_pos[0, :, 2]).abs()
    assert (lag <= g * dt * t / 2 * 1.01 + 1e-9).all()  # Euler's first-order error, no more


@pytest.mark.slow
def test_put_onto_agrees_with_warp(put_onto_rollouts):
    _, _, warp, ours, events = put_onto_rollouts
    assert len(events) == 2, "grasp and release"
    for name in ("hand_pos", "hand_rot", "grasp"):
        assert (getattr(warp, name) - getattr(ours, name)).abs().max() < 1e-9, name
    assert (warp.object_pos - ours.object_pos).norm(dim=-1).max() < 5e-4  # [m]
    assert (warp.tip_distance - ours.tip_distance).abs().max() < 5e-4  # [m]
    assert (warp.object_rot - ours.object_rot).abs().max() < 1e-6  # the object does not turn here
    eye = torch.eye(3, dtype=torch.float64)
    assert (ours.object_rot.transpose(-1, -2) @ ours.object_rot - eye).abs().max() < 1e-12
    assert set(ours.grasped.unique().tolist()) == {0.0, 1.0}
    saturated = (warp.grasped < 1e-3) | (warp.grasped > 1 - 1e-3)
    assert saturated.sum() >= ours.grasped.numel() - 2  # the frames just after the events are in the sigmoid
    assert (ours.grasped - warp.grasped)[saturated].abs().max() < 1e-3
    velocity = (warp.object_vel - ours.object_vel).norm(dim=-1)
    assert velocity[saturated].max() < 2e-2  # [m/s], the landing on the static cuboid
    assert velocity.max() < 5e-2  # [m/s]
    assert (warp.object_ang_vel - ours.object_ang_vel).abs().max() < 1e-6


def test_events_are_where_the_grasp_signal_crosses_zero(put_onto_rollouts):
    inputs, options, _, _, events = put_onto_rollouts
    dt = 1.0 / (FPS * options["steps_per_frame"])
    g = torch.cat([inputs.grasp0, inputs.grasp0 + dt * inputs.hand_vel[0, :, 6].cumsum(0)])
    crossings = []
    for n in range(len(g) - 1):
        if (g[n] > 0) != (g[n + 1] > 0):  # the tip is inside the object: f = -g here
            crossings.append(float(n * dt + dt * g[n] / (g[n] - g[n + 1])))
    assert len(crossings) == 2
    for ours, exact in zip(events, crossings):
        assert abs(ours - exact) < 1e-7


def test_float32_inputs_give_float32_outputs():
    inputs, options = free_fall_inputs(frames=2)
    out = simulate_dopri5(inputs.to(torch.float32), **options)
    assert out.object_pos.dtype == torch.float32


def test_rejects_what_simulate_rejects():
    inputs, options = free_fall_inputs(frames=2)
    with pytest.raises(ValueError, match="hand_vel must have"):
        simulate_dopri5(replace(inputs, hand_vel=inputs.hand_vel[:, :-1]), **options)


def release_window(rollout, inputs: SceneInputs, spf: int, first: int = 16, frames: int = 4) -> SceneInputs:
    """Frames ``first`` .. ``first + frames - 1`` of put_onto as a scene of its own: the object
    held at rest relative to the hand, released at 1.49 s, landing on the static cuboid."""
    start, stop = first * spf, (first + frames - 1) * spf
    dt = 1.0 / (FPS * spf)
    moved = dt * inputs.hand_vel[:, :start].sum(1)
    pick = lambda name: getattr(rollout, name)[:, first].detach().clone()  # noqa: E731
    return replace(
        inputs,
        hand_pos0=inputs.hand_pos0 + moved[:, :3],
        grasp0=inputs.grasp0 + moved[:, 6],
        hand_vel=inputs.hand_vel[:, start:stop].clone(),
        object_pos0=pick("object_pos"),
        object_rot0=pick("object_rot"),
    )


@pytest.mark.slow
def test_gradients_match_finite_differences_across_the_release(put_onto_rollouts):
    """Through the release event (its time moves with grasp0 and the grasp rates) and the
    landing. The tolerances are tightened: at the default rtol 1e-7 the solver's error
    control makes the rollout only piecewise smooth at the scale of finite differences
    (at rtol 1e-6 the grasp0 derivative is 4% off the converged value)."""
    inputs, options, _, ours, _ = put_onto_rollouts
    scene = release_window(ours, inputs, options["steps_per_frame"])
    options = {**options, "rtol": 1e-9, "atol": 1e-11}
    generator = torch.Generator().manual_seed(0)
    probe = simulate_dopri5(scene, **options)
    shapes = {"pos": probe.object_pos.shape, "vel": probe.object_vel.shape, "tip": probe.tip_distance.shape}
    weights = {k: torch.randn(shape, generator=generator, dtype=torch.float64) for k, shape in shapes.items()}

    def loss(values: SceneInputs) -> torch.Tensor:
        events: list = []
        out = simulate_dopri5(values, **options, events=events)
        assert len(events[0]) == 1, "the window holds the release"
        terms = (out.object_pos * weights["pos"], 0.1 * out.object_vel * weights["vel"], out.tip_distance * weights["tip"])
        return sum(term.sum() for term in terms)

    leaves = scene.map(lambda v: v.clone().requires_grad_(True))
    loss(leaves).backward()
    eps = 1e-6
    for name in ("grasp0", "hand_vel", "object_size"):
        value = getattr(scene, name)
        direction = torch.randn(value.shape, generator=generator, dtype=torch.float64)
        if name == "hand_vel":
            direction[..., 3:6] = 0.0  # the scripted hand does not turn
        analytic = float((getattr(leaves, name).grad * direction).sum())
        shifted = [loss(replace(scene, **{name: value + sign * eps * direction})) for sign in (1, -1)]
        numeric = float(shifted[0] - shifted[1]) / (2 * eps)
        assert math.isfinite(analytic)
        assert abs(analytic - numeric) <= 1e-3 * abs(numeric) + 1e-5, f"{name}: {analytic} vs {numeric}"


def test_bench_engine_swaps_the_rollout_only():
    from warpskill.bench.speed import backend
    from warpskill.engine.rendering import render_silhouettes

    engine = backend("dopri5")
    assert engine.simulate is simulate_dopri5 and engine.render is render_silhouettes
    assert backend("warp").simulate is simulate
