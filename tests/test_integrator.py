"""Rollout adjoints of ``simulate`` against central differences (float64), input checks, and the
spline basis that feeds it."""

from dataclasses import replace

import numpy as np
import pytest
import torch
import warp as wp
from device_support import torch_devices
from warpskill.kernels.integrator import CUDA_LANES, lanes

from warpskill.engine.records import SceneInputs
from warpskill.engine.simulation import simulate
from warpskill.optimizer.spline import natural_cubic_basis, step_velocities

FPS, SPF = 30.0, 8  # dt = 1/240 s as in the default configuration, 1.2 s rollouts

# Any access warning is an error. (The rollout kernel reads state n and writes state n + 1 of its
# per-step arrays, a pattern Warp's static check flags in kernel arguments; it does not follow arrays
# held in structs, and the finite-difference tests below prove the pattern exact.)
pytestmark = pytest.mark.filterwarnings("error:.*may corrupt gradient computation")


@pytest.fixture(autouse=True)
def _verify_array_access(verify_array_access):
    """Every test here runs with Warp's gradient-corrupting access checks on."""


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _scenes() -> SceneInputs:
    """Two float64 scenes of 1.2 s with one static cuboid each.

    0: the hand comes down onto the cuboid and closes, lifts it straight up, carries it over
       the static cuboid while turning it, stops, opens, and the cuboid drops onto the static.
    1: a tilted cuboid falls onto the static's edge and tumbles to the ground while the hand
       moves and turns nearby without touching it.

    Contacts start and end with little tangential velocity in scene 0, so that the friction
    term's on/off jumps stay small against the finite-difference step.
    """
    steps = int(round(1.2 * FPS)) * SPF
    t = np.arange(steps) / (FPS * SPF)
    vel = np.zeros((2, steps, 7))
    vel[0, :, 6] = np.where(t < 0.85, 0.05, -0.2)  # grasp signal crosses 0 at 0.2 s and 1.06 s
    vel[0, t < 0.3, 2] = -0.08 / 0.3  # down
    vel[0, (t >= 0.35) & (t < 0.55), 2] = 0.1 / 0.2  # up
    vel[0, (t >= 0.55) & (t < 0.85), :6] = [0.17 / 0.3, 0.0, 0.0, 0.0, 0.0, 1.0]  # across, turning
    vel[1, :, :] = [0.05, -0.1, 0.02, 0.5, -1.0, 0.7, 0.0]
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.4), -np.sin(0.4)], [0.0, np.sin(0.4), np.cos(0.4)]])
    as_tensor = lambda a: torch.tensor(np.asarray(a, dtype=np.float64))  # noqa: E731
    return SceneInputs(
        hand_pos0=as_tensor([[0.0, 0.0, 0.1], [0.3, 0.2, 0.3]]),
        hand_rot0=as_tensor([np.eye(3), _yaw(0.5)]),
        grasp0=as_tensor([-0.01, -0.05]),
        hand_vel=as_tensor(vel),
        object_pos0=as_tensor([[0.0, 0.0, 0.021], [0.065, 0.03, 0.12]]),
        object_rot0=as_tensor([np.eye(3), _yaw(0.3) @ tilt]),
        object_size=as_tensor([[0.06, 0.05, 0.04], [0.05, 0.07, 0.04]]),
        static_pos=as_tensor([[[0.17, 0.0, 0.03]], [[0.15, 0.0, 0.04]]]),
        static_rot=as_tensor([[_yaw(0.3)], [_yaw(-0.2)]]),
        static_size=as_tensor([[[0.1, 0.12, 0.06]], [[0.12, 0.1, 0.08]]]),
    )


def _leaves(inputs: SceneInputs) -> SceneInputs:
    return inputs.map(lambda x: x.clone().requires_grad_(True))


def _projection(rollout, weights: dict[str, torch.Tensor]) -> torch.Tensor:
    return sum((getattr(rollout, name) * w).sum() for name, w in weights.items())


def test_grasp_scene_does_what_it_says():
    out = simulate(_scenes(), steps_per_frame=SPF, fps=FPS)
    grasped = out.grasped[0]
    assert grasped[:6].max() < 1e-3 and grasped[11:29].min() > 0.98 and grasped[-4:].max() < 1e-3
    assert out.object_pos[0, -1, 0] == pytest.approx(0.17, abs=1e-3)  # carried over the static cuboid
    assert out.object_pos[0, -1, 2] == pytest.approx(0.06 + 0.02, abs=2e-3)
    assert out.object_pos[1, -1, 2] < 0.05  # tumbled off onto the ground


CPU_BLOCKS = "cpu blocks"
"""The CPU running the GPU's shape: a block of CUDA_LANES threads per scene as cooperative fibers."""


def _use(device: str, monkeypatch: pytest.MonkeyPatch) -> str:
    """The Torch device of ``device`` (a Torch device or CPU_BLOCKS), set up to run there."""
    if device != CPU_BLOCKS:
        return device
    monkeypatch.setattr(wp.config, "enable_cpu_blocks", True)
    assert lanes(wp.get_device("cpu")) == CUDA_LANES
    return "cpu"


@pytest.mark.parametrize("device", [d for d in torch_devices() if d != "cpu"] + [CPU_BLOCKS])
def test_lanes_sharing_a_scene_give_what_one_thread_gives(device, monkeypatch):
    """Sample points shared by a block's lanes sum in another order (and a GPU rounds its own
    way): the same float64 rollout as one thread per scene on the CPU, to rounding."""
    alone = simulate(_scenes(), steps_per_frame=SPF, fps=FPS)
    out = simulate(_scenes().map(lambda x: x.to(_use(device, monkeypatch))), steps_per_frame=SPF, fps=FPS)
    for name, value in vars(alone).items():
        assert torch.allclose(getattr(out, name).cpu(), value, rtol=1e-9, atol=1e-9), name


@pytest.mark.parametrize("device", [*torch_devices(), CPU_BLOCKS])
def test_rollout_adjoints_match_finite_differences(device, monkeypatch):
    torch.manual_seed(0)
    inputs = _leaves(_scenes().map(lambda x: x.to(_use(device, monkeypatch))))
    out = simulate(inputs, steps_per_frame=SPF, fps=FPS)
    weights = {name: torch.randn_like(value) for name, value in vars(out).items()}
    _projection(out, weights).backward()

    eps = 1e-6
    for name, x in inputs.items():
        for _ in range(2):  # random directions
            u = torch.randn_like(x)
            with torch.no_grad():
                plus = simulate(replace(inputs, **{name: x + eps * u}), steps_per_frame=SPF, fps=FPS)
                minus = simulate(replace(inputs, **{name: x - eps * u}), steps_per_frame=SPF, fps=FPS)
                fd = (_projection(plus, weights) - _projection(minus, weights)).item() / (2 * eps)
            adjoint = (x.grad * u).sum().item()
            assert adjoint == pytest.approx(fd, rel=1e-6, abs=1e-6), name


def test_repeated_backward_accumulates_the_same_gradient():
    inputs = _leaves(_scenes())
    out = simulate(inputs, steps_per_frame=SPF, fps=FPS)
    loss = out.object_pos.sum() + out.grasped.sum()
    loss.backward(retain_graph=True)
    first = {name: x.grad.clone() for name, x in inputs.items()}
    loss.backward()
    for name, x in inputs.items():
        assert torch.allclose(x.grad, 2 * first[name], rtol=1e-12, atol=0), name


def test_rollouts_of_one_shape_share_buffers_without_a_trace():
    """The engine copies each call's inputs into buffers kept per shape and reuses their gradient
    buffers: two rollouts pending at once, backward in either order, and a rollout after them,
    each get exactly the gradients they get alone."""
    first, second = _scenes(), _scenes()
    second = replace(second, hand_vel=0.5 * second.hand_vel, object_size=1.2 * second.object_size)

    def pending(inputs: SceneInputs):
        leaves = _leaves(inputs)
        out = simulate(leaves, steps_per_frame=SPF, fps=FPS)
        return leaves, out.object_pos.sum() + out.grasped.sum() + out.object_vel.square().sum()

    def alone(inputs: SceneInputs) -> dict[str, torch.Tensor]:
        leaves, loss = pending(inputs)
        loss.backward()
        return {name: x.grad for name, x in leaves.items()}

    expected = [alone(first), alone(second)]
    (leaves_1, loss_1), (leaves_2, loss_2) = pending(first), pending(second)
    loss_2.backward()
    loss_1.backward()
    for leaves, grads in zip((leaves_1, leaves_2), expected):
        for name, x in leaves.items():
            assert torch.equal(x.grad, grads[name]), name
    for name, grad in alone(first).items():
        assert torch.equal(grad, expected[0][name]), name


def test_outputs_do_not_depend_on_gradient_recording():
    inputs = _scenes()
    with torch.no_grad():
        plain = simulate(inputs, steps_per_frame=SPF, fps=FPS)
    recorded = simulate(_leaves(inputs), steps_per_frame=SPF, fps=FPS)
    for name, value in vars(plain).items():
        assert torch.equal(value, getattr(recorded, name).detach()), name


def test_float32_rollout_matches_float64():
    inputs = _scenes()
    exact = simulate(inputs, steps_per_frame=SPF, fps=FPS)
    single = simulate(inputs.to(torch.float32), steps_per_frame=SPF, fps=FPS)
    for name, value in vars(exact).items():
        assert getattr(single, name).dtype == torch.float32
        assert (getattr(single, name).double() - value).abs().max() < 2e-5, name  # [m], [m/s], [rad/s], ...


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(hand_pos0=torch.zeros(2, 4, dtype=torch.float64)), "hand_pos0 must have shape"),
        (dict(static_rot=torch.zeros(2, 2, 3, 3, dtype=torch.float64)), "static_rot must have shape"),
        (dict(grasp0=torch.zeros(2, dtype=torch.float32)), "grasp0 has dtype"),
        (dict(object_pos0=torch.full((2, 3), float("nan"), dtype=torch.float64)), "object_pos0 contains NaN"),
        (dict(object_size=torch.zeros(2, 3, dtype=torch.float64)), "object_size must be positive"),
        (dict(hand_vel=torch.zeros(2, 9, 7, dtype=torch.float64)), "hand_vel must have"),
    ],
)
def test_simulate_rejects_bad_inputs(change, message):
    with pytest.raises(ValueError, match=message):
        simulate(replace(_scenes(), **change), steps_per_frame=SPF, fps=FPS)


# ---------------------------------------------------------------------------------------------
# spline basis


def test_spline_interpolates_knots_and_reproduces_lines():
    knots = np.linspace(0.0, 2.0, 6)
    assert np.allclose(natural_cubic_basis(6, 2.0, knots), np.eye(6), atol=1e-14)
    times = np.linspace(0.0, 2.0, 37)
    line = 0.3 - 1.7 * knots
    assert np.allclose(natural_cubic_basis(6, 2.0, times) @ line, 0.3 - 1.7 * times, atol=1e-13)


def test_spline_is_natural_and_twice_continuously_differentiable():
    values = np.random.default_rng(0).normal(size=7)
    h = 1e-4
    spline = lambda t: natural_cubic_basis(7, 3.0, np.atleast_1d(t)) @ values  # noqa: E731
    second = lambda t: (spline(t + h) - 2 * spline(t) + spline(t - h)) / h**2  # noqa: E731
    curvature = abs(second(np.linspace(0.1, 2.9, 50))).max()
    assert curvature > 1.0
    # zero curvature at both ends (one-sided differences), continuous curvature at a knot
    assert abs((spline(2 * h) - 2 * spline(h) + spline(0.0)) / h**2) < 1e-3 * curvature
    assert abs((spline(3.0) - 2 * spline(3.0 - h) + spline(3.0 - 2 * h)) / h**2) < 1e-3 * curvature
    assert abs(second(1.0 - 2 * h) - second(1.0 + 2 * h)) < 1e-3 * curvature


def test_step_velocities_sample_the_spline_at_step_starts():
    ctrl = torch.randn(2, 5, 7, dtype=torch.float64)
    out = step_velocities(ctrl, num_frames=9, fps=4.0, steps_per_frame=3)
    assert out.shape == (2, 24, 7) and out.dtype == torch.float64
    basis = natural_cubic_basis(5, 2.0, np.arange(24) / 12.0)
    assert torch.allclose(out, torch.einsum("sk,bkc->bsc", torch.as_tensor(basis), ctrl))
    assert torch.allclose(out[:, 0], ctrl[:, 0])
    assert torch.allclose(out[:, 6], ctrl[:, 1])  # t = 0.5 s is the second knot
