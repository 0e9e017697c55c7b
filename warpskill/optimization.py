"""``warpskill.optimize``: a demonstration in, physically admissible trajectories out.

Two stages, as in the paper: (a) a physics-free fit of per-frame poses (:mod:`.initialize`),
from each of two hypotheses about the object's depth (the lower loss wins), gives a first
camera and trajectories; (b) the physics stage (:mod:`.physical_scene`)
optimises the initial states, the hand's velocity spline, the sizes and the camera through
the Warp engine. Both use Adam (amsgrad) with a reduce-on-plateau schedule that returns to
the best parameters whenever it lowers the learning rate.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch
from tqdm.auto import tqdm

from .batching import Backend, render_many, simulate_many
from .demonstration import Demonstration
from .distances import box_signed_distance
from .losses import MaskTargets
from .initialize import (
    OBJECT_DEPTH_HYPOTHESES,
    InitialParameters,
    SceneTrajectories,
    initial_guess,
    initial_objective,
    perceptual_loss,
)
from .physical_scene import PhysicalRollout, PhysicalScene
from .physics import PhysicsConfig
from .reconstruction import Reconstruction
from .weights import LossWeights


@dataclass(frozen=True)
class OptimizeConfig:
    """Settings of :func:`optimize`. The defaults are the ones the benchmarks report."""

    iterations: int = 250  #: physics-stage iterations (upper bound; stops early once the lr has decayed)
    init_iterations: int = 150  #: stage (a) iterations
    learning_rate: float = 5e-3  #: physics stage (the paper's)
    init_learning_rate: float = 1e-2  #: stage (a)
    image_scale: float = 0.25  #: working resolution relative to the masks
    sigma: float = 0.35  #: soft edge width [px at the working resolution]: about the edge of area-averaged masks
    knots_per_second: float = 3.0  #: density of the hand's velocity spline
    pre_roll: float = 0.5  #: still time simulated before the video [s]
    post_roll: float = 1.0  #: still time simulated after the video [s]
    plateau_patience: int = 10  #: iterations without improvement before the lr is halved
    plateau_factor: float = 0.5
    min_lr_ratio: float = 0.1  #: stop once the lr falls below this fraction of its start
    warmup_iterations: int = 10  #: the learning rate ramps up linearly over these iterations
    checkpoint_every: int = 25  #: iterations between checkpoint writes
    weights: LossWeights = field(default_factory=LossWeights)
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)


def optimize(
    demo: Demonstration,
    *,
    device: str | torch.device | None = None,
    iterations: int | None = None,
    seed: int = 0,
    progress: bool = True,
    config: OptimizeConfig | None = None,
    init_only: bool = False,
    checkpoint: str | os.PathLike | None = None,
    backend: Backend | None = None,
) -> Reconstruction:
    """Reconstruct physically admissible hand and object trajectories from a demonstration.

    Args:
        demo: the demonstration (masks, contact, fps, camera intrinsics).
        device: torch/Warp device (``"cpu"``, ``"cuda"``, ...); default CPU.
        iterations: physics-stage iterations; default ``config.iterations``.
        seed: seed of torch's generator (results are deterministic per seed and device).
        progress: show progress bars.
        config: optimisation settings; default :class:`OptimizeConfig`.
        init_only: stop after stage (a) (the paper's "initialisation only" ablation).
        checkpoint: a file where the run saves its state and best result as it goes; an
            existing checkpoint of the same demonstration and settings is resumed.
        backend: the rollout and rasterizer (default: the Warp engine).

    Returns:
        The reconstruction, in the world frame of FORMATS.md, at the video's frames.
    """
    return optimize_many([demo], device=device, iterations=iterations, seed=seed, progress=progress, config=config,
                         init_only=init_only, checkpoint=checkpoint, backend=backend)[0]


def optimize_many(
    demos: Sequence[Demonstration],
    *,
    device: str | torch.device | None = None,
    iterations: int | None = None,
    seed: int = 0,
    progress: bool = True,
    config: OptimizeConfig | None = None,
    init_only: bool = False,
    checkpoint: str | os.PathLike | None = None,
    backend: Backend | None = None,
) -> list[Reconstruction]:
    """Reconstruct B demonstrations side by side: :func:`optimize` on each, in shared engine calls.

    Every iteration rolls out all B scenes in one engine call and renders all their frames
    in one raster launch (per group of demonstrations that share the frame rate, the
    intrinsics, the working image size and the number of static objects; see
    :mod:`warpskill.batching`). Each demonstration keeps its own parameters, learning-rate
    schedule, early stop and best result, so each reconstruction is the one
    :func:`optimize` would return, up to floating-point rounding.

    Args:
        demos: the demonstrations.
        device, iterations, seed, progress, config, init_only, backend: as :func:`optimize`.
        checkpoint: one file for the whole batch (resumed only for the same demonstrations
            and settings).

    Returns:
        One reconstruction per demonstration, in order.

    Raises:
        ValueError: no demonstrations.
    """
    if len(demos) == 0:
        raise ValueError("optimize_many needs at least one demonstration")
    config = config or OptimizeConfig()
    if iterations is not None:
        config = replace(config, iterations=int(iterations))
    backend = backend or Backend()
    device = resolve_device(device)
    torch.manual_seed(seed)
    store = _Checkpoint(checkpoint, _fingerprint(demos, config, seed, backend))
    inputs = [working_inputs(demo, config, device) for demo in demos]
    weights, sigma = config.weights, config.sigma

    # Stage (a): every demonstration from each object-depth hypothesis; the lower loss wins.
    owners, candidates = [], []
    for i, (demo, given) in enumerate(zip(demos, inputs)):
        for hypothesis in OBJECT_DEPTH_HYPOTHESES:
            guess = initial_guess(given.masks.cpu().numpy(), given.contact_signal, given.intrinsics, demo.num_static,
                                  object_depth=hypothesis)
            owners.append(i)
            candidates.append(InitialParameters(guess).to(device))

    def stage_a(live: list[int]) -> list[dict[str, torch.Tensor]]:
        scenes = [candidates[j].scene() for j in live]
        rendered = render_many(scenes, [inputs[owners[j]].intrinsics for j in live], sigma, backend.render)
        return [
            initial_objective(scene, masks, inputs[owners[j]].targets, inputs[owners[j]].contact,
                              demos[owners[j]].fps, weights)
            for j, scene, masks in zip(live, scenes, rendered)
        ]

    losses = _minimise(candidates, stage_a, iterations=config.init_iterations,
                       learning_rate=config.init_learning_rate, config=config, progress=progress,
                       label="initialisation", store=store)
    fits, stage_a_losses = [], []
    for i in range(len(demos)):
        j = min((j for j in range(len(owners)) if owners[j] == i), key=lambda j: losses[j])
        fits.append(candidates[j].scene().detached())
        stage_a_losses.append(losses[j])
    if init_only:
        reconstructions = []
        for demo, given, fit, loss in zip(demos, inputs, fits, stage_a_losses):
            grasp = (2 * given.contact - 1) * weights.grasp_margin
            distance = box_signed_distance(fit.hand_pos, fit.object_pos, fit.object_rot, fit.object_size)
            reconstructions.append(_reconstruction(demo, fit, grasp, given.contact * (distance < 0), loss))
        return reconstructions

    # Stage (b): the physics.
    scenes = [make_physical_scene(fit, given.contact_signal, demo.fps, config).to(device)
              for demo, given, fit in zip(demos, inputs, fits)]

    def simulate_scenes(live: list[int]) -> list[PhysicalRollout]:
        rollouts = simulate_many([scenes[b].simulation_inputs() for b in live], backend.simulate)
        return [scenes[b].assemble(rollout) for b, rollout in zip(live, rollouts)]

    def stage_b(live: list[int]) -> list[dict[str, torch.Tensor]]:
        results = simulate_scenes(live)
        rendered = render_many([r.scene for r in results], [inputs[b].intrinsics for b in live], sigma, backend.render)
        return [
            physical_objective(result, masks, inputs[b].targets, inputs[b].contact, inputs[b].object_visible, weights)
            for b, result, masks in zip(live, results, rendered)
        ]

    losses = _minimise(scenes, stage_b, iterations=config.iterations, learning_rate=config.learning_rate,
                       config=config, progress=progress, label="physics", store=store)
    with torch.no_grad():
        results = simulate_scenes(list(range(len(demos))))
    return [
        _reconstruction(demo, result.scene, result.rollout.grasp, result.rollout.grasped, loss)
        for demo, result, loss in zip(demos, results, losses)
    ]


@dataclass
class WorkingInputs:
    """What both stages fit, at the working resolution.

    Attributes:
        intrinsics: the camera at the working resolution.
        masks: (N, 2 + K, h, w) area-averaged masks: hand, object, statics.
        targets: ``masks`` with their moments, for the dIoU.
        contact_signal: (N,) bool, the majority-filtered contact.
        contact: (N,) the same as floats on the device.
        object_visible: (N,) 1 where the object's mask is not empty.
    """

    intrinsics: object
    masks: torch.Tensor
    targets: MaskTargets
    contact_signal: np.ndarray
    contact: torch.Tensor
    object_visible: torch.Tensor


def working_inputs(demo: Demonstration, config: OptimizeConfig, device: torch.device) -> WorkingInputs:
    """The demonstration's masks and contact as the optimiser uses them (see :class:`WorkingInputs`)."""
    h, w = demo.intrinsics.scaled(config.image_scale).image_size
    masks = torch.as_tensor(demo.mask_stack(h, w), device=device)
    contact_signal = majority_filter(demo.contact)
    return WorkingInputs(
        intrinsics=demo.intrinsics.resized(h, w),
        masks=masks,
        targets=MaskTargets(masks),
        contact_signal=contact_signal,
        contact=torch.as_tensor(contact_signal, dtype=torch.float32, device=device),
        object_visible=(masks[:, 1].flatten(1).amax(1) > 0.5).float(),
    )


def make_physical_scene(fit: SceneTrajectories, contact_signal: np.ndarray, fps: float, config: OptimizeConfig) -> PhysicalScene:
    """Stage (b)'s parameters started from the per-frame scene ``fit`` (on the CPU)."""
    return PhysicalScene(
        fit,
        contact_signal,
        fps,
        knots_per_second=config.knots_per_second,
        pre_roll=config.pre_roll,
        post_roll=config.post_roll,
        grasp_level=2.0 * config.weights.grasp_margin,
        physics=config.physics,
    )


def resolve_device(device: str | torch.device | None) -> torch.device:
    """The torch device named by ``device`` (default CPU).

    Raises:
        ValueError: an unknown device, or CUDA when this torch or machine has none.
    """
    try:
        resolved = torch.device(device or "cpu")
    except RuntimeError:
        raise ValueError(f"unknown device {device!r}: use 'cpu' or 'cuda'") from None
    if resolved.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device {device!r}: CUDA is not available to this torch build or machine")
    if resolved.type not in ("cpu", "cuda"):
        raise ValueError(f"device {device!r}: warpskill runs on 'cpu' or 'cuda'")
    return resolved


def majority_filter(signal: np.ndarray, window: int = 5) -> np.ndarray:
    """Per-frame majority vote of a boolean signal over ``window`` frames (the paper's code:
    5 frames, 3 votes), which removes isolated flips. Near the ends the vote is over the
    frames that exist. A signal the vote would erase entirely is returned unchanged.
    """
    signal = np.asarray(signal, dtype=bool)
    kernel = np.ones(window, dtype=int)
    votes = np.convolve(signal.astype(int), kernel, mode="same")
    frames = np.convolve(np.ones(len(signal), dtype=int), kernel, mode="same")
    filtered = 2 * votes > frames
    return filtered if filtered.any() else signal


def physical_objective(
    result: PhysicalRollout,
    rendered: torch.Tensor,
    targets: MaskTargets,
    contact: torch.Tensor,
    object_visible: torch.Tensor,
    weights: LossWeights,
) -> dict[str, torch.Tensor]:
    """Stage (b) loss terms: perceptual, velocity regularisation, contact, stability.

    Args:
        result: the simulated scene.
        rendered: (N, 2 + K, h, w) its soft silhouettes at the working resolution.
        targets: (N, 2 + K, h, w) masks at the working resolution.
        contact: (N,) contact signal in {0, 1}.
        object_visible: (N,) 1 where the object's mask is not empty.
        weights: loss weights.

    Returns:
        Named weighted terms; the loss is their sum.
    """
    rollout = result.rollout
    object_speed = rollout.object_vel.square().sum(-1) + rollout.object_ang_vel.square().sum(-1)
    margin = weights.grasp_margin
    return {
        "perceptual": perceptual_loss(rendered, targets, weights),
        "hand velocity": weights.hand_velocity * result.hand_speed.mean(),
        "hidden object velocity": weights.invisible_object_velocity * ((1 - object_visible) * object_speed).mean(),
        "contact distance": weights.contact_distance
        * (contact * (rollout.tip_distance + margin).clamp_min(0.0) ** 2).mean(),
        "grasp": weights.grasp
        * (
            (contact * (margin - rollout.grasp).clamp_min(0.0) ** 2).mean()
            + ((1 - contact) * (rollout.grasp + margin).clamp_min(0.0) ** 2).mean()
        ),
        "stability": weights.stability * result.still_velocity.mean(),
    }


def _minimise(
    modules: Sequence[torch.nn.Module],
    objective: Callable[[list[int]], list[dict[str, torch.Tensor]]],
    *,
    iterations: int,
    learning_rate: float,
    config: OptimizeConfig,
    progress: bool,
    label: str,
    store: "_Checkpoint",
) -> list[float]:
    """Adam (amsgrad) with reduce-on-plateau, per module; leaves each module at its best parameters.

    ``objective(live)`` returns the named loss terms of the modules ``live`` (indices), whose
    sums are minimised. Each module has its own learning rate and schedule (its own Adam
    parameter group) and stops once its rate has decayed; the others go on.

    Returns:
        The best loss each module reached.
    """
    count = len(modules)
    optimizer = torch.optim.Adam([{"params": list(m.parameters())} for m in modules], lr=learning_rate, amsgrad=True)
    plateaus = [_Plateau(config.plateau_patience, config.plateau_factor) for _ in modules]
    best_loss, best_state, start = [float("inf")] * count, [_copy_state(m) for m in modules], 0
    saved = store.load(label)
    if saved is not None:
        for module, state in zip(modules, saved["modules"]):
            module.load_state_dict(state)
        optimizer.load_state_dict(saved["optimizer"])
        for plateau, state in zip(plateaus, saved["plateaus"]):
            plateau.best, plateau.bad = state
        best_loss, best_state, start = saved["best_loss"], saved["best_state"], saved["iteration"]
    groups = optimizer.param_groups  # after loading: load_state_dict replaces the group dicts

    def save(iteration: int) -> None:
        store.save(label, dict(
            modules=[m.state_dict() for m in modules], optimizer=optimizer.state_dict(),
            plateaus=[(p.best, p.bad) for p in plateaus], best_loss=best_loss, best_state=best_state,
            iteration=iteration,
        ))

    def live() -> list[int]:
        return [b for b in range(count) if groups[b]["lr"] >= learning_rate * config.min_lr_ratio]

    bar = tqdm(total=iterations, initial=start, desc=label, disable=not progress, leave=False)
    iteration = start
    while iteration < iterations and (active := live()):
        optimizer.zero_grad(set_to_none=True)  # modules that have stopped get no gradient: Adam skips them
        losses = torch.stack([sum(terms.values()) for terms in objective(active)])
        values = losses.detach().cpu().tolist()  # the iteration's one device-to-host copy
        for b, value in zip(active, values):
            if not np.isfinite(value):
                which = f" (scene {b})" if count > 1 else ""
                raise FloatingPointError(f"{label}{which}: the loss became {value} at iteration {iteration}")
        losses.sum().backward()
        lr_before = [group["lr"] for group in groups]
        for b, value in zip(active, values):
            if value < best_loss[b]:
                best_loss[b], best_state[b] = value, _copy_state(modules[b])
            # Warm-up: Adam's first steps move every parameter by about lr, whatever its gradient,
            # which can push the hand out of a grasp that only just holds.
            groups[b]["lr"] = lr_before[b] * min(1.0, (iteration + 1) / config.warmup_iterations)
        optimizer.step()
        for b, value in zip(active, values):
            groups[b]["lr"] = lr_before[b]
            if plateaus[b].step(value, groups[b]):
                # Back to the best parameters, and forget the momentum that led away from them.
                modules[b].load_state_dict(best_state[b])
                for parameter in modules[b].parameters():
                    optimizer.state.pop(parameter, None)
        iteration += 1
        bar.update(1)
        bar.set_postfix(loss=f"{sum(values):.4f}", best=f"{sum(best_loss):.4f}", lr=f"{groups[active[0]]['lr']:.1e}",
                        **({"running": f"{len(active)}/{count}"} if count > 1 else {}))
        if iteration % config.checkpoint_every == 0:
            save(iteration)
    bar.close()
    unrun = [b for b in range(count) if best_loss[b] == float("inf")]
    if unrun:  # no iteration ran: report the loss where the parameters are
        with torch.no_grad():
            for b, terms in zip(unrun, objective(unrun)):
                best_loss[b] = float(sum(terms.values()))
    for module, state in zip(modules, best_state):
        module.load_state_dict(state)
    save(iterations)
    return best_loss


class _Plateau:
    """Reduce-on-plateau for one parameter group (``torch.optim.lr_scheduler.ReduceLROnPlateau``'s
    rule: relative threshold 1e-4, no cool-down)."""

    def __init__(self, patience: int, factor: float):
        self.patience, self.factor = patience, factor
        self.best, self.bad = float("inf"), 0

    def step(self, value: float, group: dict) -> bool:
        """Record ``value``; return whether ``group``'s learning rate was lowered."""
        if value < self.best * (1.0 - 1e-4):
            self.best, self.bad = value, 0
        else:
            self.bad += 1
        if self.bad <= self.patience:
            return False
        self.bad = 0
        lowered = group["lr"] * self.factor
        if group["lr"] - lowered <= 1e-8:
            return False
        group["lr"] = lowered
        return True


def _copy_state(module: torch.nn.Module) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


class _Checkpoint:
    """Per-stage optimiser state in one file, written atomically; ignored when ``path`` is None."""

    def __init__(self, path: str | os.PathLike | None, fingerprint: str):
        self.path = Path(path) if path is not None else None
        self.fingerprint = fingerprint
        self.stages: dict = {}
        if self.path is not None and self.path.exists():
            try:
                saved = torch.load(self.path, map_location="cpu", weights_only=True)
            except Exception as error:
                raise ValueError(
                    f"checkpoint {self.path} is not readable ({type(error).__name__}); move it away to start afresh"
                ) from None
            if not (isinstance(saved, dict) and {"fingerprint", "stages"} <= saved.keys()):
                raise ValueError(f"checkpoint {self.path} is not a warpskill checkpoint; move it away to start afresh")
            if saved["fingerprint"] == fingerprint:
                self.stages = saved["stages"]

    def load(self, stage: str) -> dict | None:
        return self.stages.get(stage)

    def save(self, stage: str, state: dict) -> None:
        if self.path is None:
            return
        self.stages[stage] = state
        self.path.parent.mkdir(parents=True, exist_ok=True)
        partial = self.path.with_name(self.path.name + ".partial")
        torch.save({"fingerprint": self.fingerprint, "stages": self.stages}, partial)
        os.replace(partial, self.path)


_CHECKPOINT_FORMAT = 2  # bumped when the saved state's layout changes


def _fingerprint(demos: Sequence[Demonstration], config: OptimizeConfig, seed: int, backend: Backend) -> str:
    """Identity of a run: a checkpoint resumes only the same demonstrations and settings."""
    digest = hashlib.sha256()
    for demo in demos:
        for array in (demo.hand_mask, demo.object_mask, demo.static_mask, demo.contact, demo.intrinsics.K):
            digest.update(np.ascontiguousarray(array).tobytes())
        digest.update(repr(demo.fps).encode())
    digest.update(repr((config, seed, backend.name, _CHECKPOINT_FORMAT)).encode())
    return digest.hexdigest()


def _reconstruction(
    demo: Demonstration, scene: SceneTrajectories, grasp: torch.Tensor, grasped: torch.Tensor, loss: float
) -> Reconstruction:
    """The FORMATS.md reconstruction of a per-frame scene, at the demonstration's full resolution."""
    n = lambda x: x.detach().cpu().double().numpy()  # noqa: E731
    N = demo.num_frames
    return Reconstruction(
        fps=np.float64(demo.fps),
        t=np.arange(N) / demo.fps,
        hand_pos=n(scene.hand_pos),
        hand_rot=n(scene.hand_rot),
        grasp=n(grasp),
        grasped=n(grasped),
        object_pos=n(scene.object_pos),
        object_rot=n(scene.object_rot),
        object_size=n(scene.object_size),
        static_pos=n(scene.static_pos),
        static_rot=n(scene.static_rot),
        static_size=n(scene.static_size),
        camera_K=np.asarray(demo.intrinsics.K, dtype=np.float64),
        camera_elevation=n(scene.camera_elevation),
        camera_height=n(scene.camera_height),
        image_size=np.asarray(demo.image_size, dtype=np.int64),
        action=demo.action or "",
        loss=np.float64(loss),
    )
