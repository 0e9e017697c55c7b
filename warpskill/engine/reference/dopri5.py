"""The paper's own integrator choice: adaptive dopri5 (``torchdiffeq``) with event handling,
in float64 PyTorch, for the same forward model as :func:`warpskill.engine.simulation.simulate`.

The continuous-time model (docs/architecture.md, "Physics", with dt -> 0), per scene with
r = x_o - x_h and the hard switch s in {0, 1} (1 = grasped) in place of the sigmoid blend:

    x_h' = v_h,   R_h' = [w_h]x R_h,   g' = grasp rate
    V = s (v_h + w_h x r) + v_o,   W = s w_h + w_o          (total object velocities)
    j_v, j_w = contact impulses at the pose with V, W and friction (1 - s) mu
    v_o' = j_v - s k_g v_o + (1 - s) (gravity - c v_o)
    w_o' = j_w - s k_g w_o - (1 - s) c w_o
    x_o' = V,   R_o' = [W]x R_o

The hand is driven by the per-step velocities ``hand_vel`` held constant over each step
(piecewise constant, as the Euler steps of ``simulate`` read them), so the right-hand side
jumps at every step boundary; each step is therefore its own dopri5 solve (the same as one
solve with a jump at every boundary), started with the step itself as first trial step.

Events: a grasp where f = max(d_tip, -g) falls below 0, a release where -g rises above it
(the grasp is latched: once closed it holds until the signal lets go, as the rigid carry
keeps the tip where it was). A step whose end has f of the other sign is solved again
with :func:`torchdiffeq.odeint_event`, which finds the event time t*; there a grasp zeroes
the own velocities, a release adds the hand's carrying velocities to them (the total
velocity stays continuous), and the rest of the step is solved in the new regime. At most
one event per step: a switch and its reversal within one step (1/240 s) go unseen.

Gradients flow by autograd through the solver's operations. The event time's dependence on
the inputs (t* is found by bisection, without gradient) is linked up by the implicit
function theorem, dt*/dp = -(df/dp) / (df/dt), and the state is carried across the jump
with the matching first-order correction (the saltation matrix) — what
``odeint_event`` does, extended to inputs that its right-hand side and event function
capture (here every input).

Scenes are solved one after another (their events differ). Slow: the second "original
approach" baseline of ``warpskill bench speed`` (engine ``dopri5``).
"""

from __future__ import annotations

import itertools

import torch
from torchdiffeq import odeint, odeint_event

from warpskill.engine.records import Rollout, SceneInputs
from warpskill.engine.reference.geometry import orthonormalize, skew
from warpskill.engine.reference.physics import (
    contact_impulses,
    sample_points,
    tip_distance,
)
from warpskill.engine.simulation import PhysicsConfig

RTOL = 1e-7  # dopri5's default relative tolerance (torchdiffeq's default)
ATOL = 1e-9  # dopri5's default absolute tolerance [m, m/s, rad/s] (torchdiffeq's default)

# The flat state (31,) of one scene: field -> size, in order
_SIZES = {"hand_pos": 3, "hand_rot": 9, "grasp": 1, "object_pos": 3, "object_rot": 9, "own_vel": 3, "own_ang_vel": 3}
_ENDS = list(itertools.accumulate(_SIZES.values()))
_LAYOUT = {name: (end - size, end) for (name, size), end in zip(_SIZES.items(), _ENDS)}  # field -> (start, end)


def _unpack(y: torch.Tensor) -> dict[str, torch.Tensor]:
    """Views of the flat state (31,) as batch-of-one tensors."""
    out = {name: y[start:end][None] for name, (start, end) in _LAYOUT.items()}
    out["hand_rot"] = out["hand_rot"].reshape(1, 3, 3)
    out["object_rot"] = out["object_rot"].reshape(1, 3, 3)
    out["grasp"] = out["grasp"][:, 0]
    return out


def _pack(state: dict[str, torch.Tensor]) -> torch.Tensor:
    return torch.cat([state[name].reshape(-1) for name in _LAYOUT])


class _Scene:
    """The right-hand side and event function of one scene (all tensors float64, batch of one)."""

    def __init__(self, config: PhysicsConfig, object_size: torch.Tensor, statics: tuple) -> None:
        self.config = config
        self.object_size = object_size  # (1, 3)
        self.points = sample_points(object_size)
        self.statics = statics
        self.fall = torch.zeros_like(object_size)
        self.fall[:, 2] = -config.gravity

    def event(self, y: torch.Tensor, grasped: bool) -> torch.Tensor:
        """The switch's event function (scalar) [m], negative while grasped: f = max(d_tip, -g)
        while free, -g while ``grasped`` (the grasp holds until the signal lets go)."""
        x = _unpack(y)
        if grasped:
            return -x["grasp"][0]
        distance = tip_distance(x["hand_pos"], x["object_pos"], x["object_rot"], self.object_size)
        return torch.maximum(distance, -x["grasp"])[0]

    def rhs(self, grasped: bool, drive: torch.Tensor):
        """dy/dt of the regime ``grasped`` under the step's hand velocities ``drive`` (7,)."""
        config = self.config
        s = 1.0 if grasped else 0.0
        v_h, w_h, rate = drive[None, :3], drive[None, 3:6], drive[None, 6]

        def f(t: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
            x = _unpack(y)
            carried = v_h + torch.linalg.cross(w_h, x["object_pos"] - x["hand_pos"])
            velocity = s * carried + x["own_vel"]
            angular_velocity = s * w_h + x["own_ang_vel"]
            friction = torch.full_like(x["grasp"], (1.0 - s) * config.mu)
            j_v, j_w = contact_impulses(
                config, friction, self.points, self.statics, x["object_pos"], x["object_rot"], velocity,
                angular_velocity,
            )
            if grasped:
                d_vel = j_v - config.grasp_decay * x["own_vel"]
                d_ang_vel = j_w - config.grasp_decay * x["own_ang_vel"]
            else:
                d_vel = j_v + self.fall - config.free_damping * x["own_vel"]
                d_ang_vel = j_w - config.free_damping * x["own_ang_vel"]
            derivative = {
                "hand_pos": v_h,
                "hand_rot": skew(w_h) @ x["hand_rot"],
                "grasp": rate,
                "object_pos": velocity,
                "object_rot": skew(angular_velocity) @ x["object_rot"],
                "own_vel": d_vel,
                "own_ang_vel": d_ang_vel,
            }
            return _pack(derivative)

        return f

    def jump(self, y: torch.Tensor, grasping: bool, drive: torch.Tensor) -> torch.Tensor:
        """The state right after a grasp (own velocities zeroed) or a release (the hand's
        carrying velocities handed over to the own ones)."""
        x = _unpack(y)
        if grasping:
            x["own_vel"] = torch.zeros_like(x["own_vel"])
            x["own_ang_vel"] = torch.zeros_like(x["own_ang_vel"])
        else:
            v_h, w_h = drive[None, :3], drive[None, 3:6]
            x["own_vel"] = x["own_vel"] + v_h + torch.linalg.cross(w_h, x["object_pos"] - x["hand_pos"])
            x["own_ang_vel"] = x["own_ang_vel"] + w_h
        return _pack(x)


def _solve(f, y0: torch.Tensor, t0: float, t1: float, tolerances: tuple[float, float]) -> torch.Tensor:
    """dopri5 from t0 to t1 [s] (the interval itself as the first trial step)."""
    t = torch.tensor([t0, t1], dtype=y0.dtype, device=y0.device)
    rtol, atol = tolerances
    return odeint(f, y0, t, method="dopri5", rtol=rtol, atol=atol, options={"first_step": t1 - t0})[-1]


def _step(scene: _Scene, y: torch.Tensor, grasped: bool, drive: torch.Tensor, t0: float, t1: float, tolerances):
    """One step t0 -> t1 with its event, if any. Returns the state at t1, the regime at t1
    and the event time (None if none)."""
    f = scene.rhs(grasped, drive)
    end = _solve(f, y, t0, t1, tolerances)
    with torch.no_grad():
        switched = bool(scene.event(end, grasped) < 0) != grasped
    if not switched:
        return end, grasped, None
    # Locate the event (no gradient), then link its time and the jump up to the inputs.
    with torch.no_grad():
        event_t, _ = odeint_event(
            f,
            y.detach(),
            torch.tensor(t0, dtype=y.dtype, device=y.device),
            event_fn=lambda t, state: scene.event(state, grasped),
            method="dopri5",
            rtol=tolerances[0],
            atol=tolerances[1],
            options={"first_step": t1 - t0},
        )
    t_event = min(float(event_t), t1)
    before = _solve(f, y, t0, t_event, tolerances) if t_event > t0 else y
    g = scene.rhs(not grasped, drive)
    with torch.enable_grad():
        probe = before.detach().requires_grad_(True)
        (gradient,) = torch.autograd.grad(scene.event(probe, grasped), probe)
    with torch.no_grad():
        f_before = f(t_event, before)
    rate = (gradient * f_before).sum()  # df/dt at the event along the old regime's flow (a constant)
    shift = -scene.event(before, grasped) / rate  # t* - t_event: value ~ 0, gradient -(df/dp) / (df/dt)
    at_event = scene.jump(before + f_before * shift, not grasped, drive)
    with torch.no_grad():
        f_after = g(t_event, at_event)
    after = at_event - f_after * shift  # the new regime, started at t*, as seen from t_event
    end = _solve(g, after, t_event, t1, tolerances) if t1 > t_event else after
    return end, not grasped, t_event


def _scene_rollout(config: PhysicsConfig, inputs: SceneInputs, b: int, steps_per_frame: int, dt: float, tolerances):
    """Frames (dict of (N, ...) tensors) and event times of scene ``b``."""
    pick = lambda name: getattr(inputs, name)[b : b + 1]  # noqa: E731
    scene = _Scene(config, pick("object_size"), (pick("static_pos"), pick("static_rot"), pick("static_size")))
    hand_vel = inputs.hand_vel[b]
    state = {
        "hand_pos": pick("hand_pos0"),
        "hand_rot": pick("hand_rot0"),
        "grasp": pick("grasp0"),
        "object_pos": pick("object_pos0"),
        "object_rot": pick("object_rot0"),
        "own_vel": torch.zeros_like(pick("object_pos0")),  # the object starts at rest
        "own_ang_vel": torch.zeros_like(pick("object_pos0")),
    }
    y = _pack(state)
    grasped = bool(scene.event(y, False) < 0)
    frames = [_frame(scene, y, grasped, hand_vel[0])]
    events = []
    for n in range(hand_vel.shape[0]):
        y, grasped, event_t = _step(scene, y, grasped, hand_vel[n], n * dt, (n + 1) * dt, tolerances)
        if event_t is not None:
            events.append(event_t)
        if (n + 1) % steps_per_frame == 0:
            x = _unpack(y)  # project the rotations back onto SO(3) once a frame
            x["hand_rot"], x["object_rot"] = orthonormalize(x["hand_rot"]), orthonormalize(x["object_rot"])
            y = _pack(x)
            frames.append(_frame(scene, y, grasped, hand_vel[n]))
    return {name: torch.stack([frame[name] for frame in frames]) for name in frames[0]}, events


def _frame(scene: _Scene, y: torch.Tensor, grasped: bool, drive: torch.Tensor) -> dict[str, torch.Tensor]:
    """The Rollout fields of one frame, with the total velocities under the step ``drive``."""
    x = _unpack(y)
    s = 1.0 if grasped else 0.0
    v_h, w_h = drive[None, :3], drive[None, 3:6]
    carried = v_h + torch.linalg.cross(w_h, x["object_pos"] - x["hand_pos"])
    frame = {
        "hand_pos": x["hand_pos"],
        "hand_rot": x["hand_rot"],
        "grasp": x["grasp"],
        "grasped": torch.full_like(x["grasp"], s),
        "tip_distance": tip_distance(x["hand_pos"], x["object_pos"], x["object_rot"], scene.object_size),
        "object_pos": x["object_pos"],
        "object_rot": x["object_rot"],
        "object_vel": s * carried + x["own_vel"],
        "object_ang_vel": s * w_h + x["own_ang_vel"],
    }
    return {name: value[0] for name, value in frame.items()}


def simulate_dopri5(
    inputs: SceneInputs,
    *,
    steps_per_frame: int,
    fps: float,
    config: PhysicsConfig = PhysicsConfig(),
    rtol: float = RTOL,
    atol: float = ATOL,
    events: list | None = None,
) -> Rollout:
    """Roll out B scenes with adaptive dopri5 and the hard grasp switch (same arguments,
    :meth:`~warpskill.engine.records.SceneInputs.check` and :class:`~warpskill.engine.records.Rollout`
    as :func:`warpskill.engine.simulation.simulate`).

    Integrates in float64 whatever the inputs' dtype and returns the inputs' dtype;
    ``grasped`` is the hard switch (0 or 1). Differentiable by autograd.

    Args:
        inputs: the B scenes; ``hand_vel[:, n]`` drives the hand over [n dt, (n + 1) dt) with
            dt = 1 / (fps * steps_per_frame) [s].
        steps_per_frame: hand velocity steps per frame.
        fps: frame rate [1/s].
        config: physics constants (``grasp_tau`` and ``max_dt`` are unused).
        rtol, atol: dopri5's error tolerances (relative; absolute [m, m/s, rad/s]).
        events: if given, a list that receives one list per scene of its event times [s].

    Returns:
        The rollout at the N frames.
    """
    SceneInputs.check(inputs, steps_per_frame=steps_per_frame, fps=fps)
    dtype = inputs.hand_pos0.dtype
    exact = inputs.to(torch.float64)
    dt = 1.0 / (fps * steps_per_frame)
    scenes = []
    for b in range(inputs.hand_pos0.shape[0]):
        frames, times = _scene_rollout(config, exact, b, steps_per_frame, dt, (rtol, atol))
        scenes.append(frames)
        if events is not None:
            events.append(times)
    fields = {name: torch.stack([scene[name] for scene in scenes]).to(dtype) for name in scenes[0]}
    return Rollout(**fields)
