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
from typing import Callable

import numpy as np
import torch
from tqdm.auto import tqdm

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
    render_scene,
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

    Returns:
        The reconstruction, in the world frame of FORMATS.md, at the video's frames.
    """
    config = config or OptimizeConfig()
    if iterations is not None:
        config = replace(config, iterations=int(iterations))
    device = resolve_device(device)
    torch.manual_seed(seed)
    store = _Checkpoint(checkpoint, _fingerprint(demo, config, seed))

    inputs = working_inputs(demo, config, device)
    intrinsics, masks, targets = inputs.intrinsics, inputs.masks, inputs.targets
    contact_signal, contact = inputs.contact_signal, inputs.contact
    weights, sigma = config.weights, config.sigma

    stage_a_loss, initial = float("inf"), None
    for hypothesis in OBJECT_DEPTH_HYPOTHESES:
        guess = initial_guess(masks.cpu().numpy(), contact_signal, intrinsics, demo.num_static, object_depth=hypothesis)
        candidate = InitialParameters(guess).to(device)
        loss = _minimise(
            candidate,
            lambda: initial_objective(candidate.scene(), targets, contact, intrinsics, demo.fps, weights, sigma),
            iterations=config.init_iterations,
            learning_rate=config.init_learning_rate,
            config=config,
            progress=progress,
            label=f"initialisation ({hypothesis})",
            store=store,
        )
        if loss < stage_a_loss:
            stage_a_loss, initial = loss, candidate
    fit = initial.scene().detached()
    if init_only:
        grasp = (2 * contact - 1) * weights.grasp_margin
        distance = box_signed_distance(fit.hand_pos, fit.object_pos, fit.object_rot, fit.object_size)
        grasped = contact * (distance < 0)
        return _reconstruction(demo, fit, grasp, grasped, stage_a_loss)

    scene = make_physical_scene(fit, contact_signal, demo.fps, config).to(device)
    stage_b_loss = _minimise(
        scene,
        lambda: physical_objective(scene(), targets, contact, inputs.object_visible, intrinsics, weights, sigma),
        iterations=config.iterations,
        learning_rate=config.learning_rate,
        config=config,
        progress=progress,
        label="physics",
        store=store,
    )
    with torch.no_grad():
        result = scene()
    return _reconstruction(demo, result.scene, result.rollout.grasp, result.rollout.grasped, stage_b_loss)


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
    targets: MaskTargets,
    contact: torch.Tensor,
    object_visible: torch.Tensor,
    intrinsics,
    weights: LossWeights,
    sigma: float,
) -> dict[str, torch.Tensor]:
    """Stage (b) loss terms: perceptual, velocity regularisation, contact, stability.

    Args:
        result: the simulated scene.
        targets: (N, 2 + K, h, w) masks at the working resolution.
        contact: (N,) contact signal in {0, 1}.
        object_visible: (N,) 1 where the object's mask is not empty.
        intrinsics: working-resolution intrinsics.
        weights: loss weights.
        sigma: soft edge width [px].

    Returns:
        Named weighted terms; the loss is their sum.
    """
    rendered = render_scene(result.scene, intrinsics, sigma)
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
    module: torch.nn.Module,
    objective: Callable[[], dict[str, torch.Tensor]],
    *,
    iterations: int,
    learning_rate: float,
    config: OptimizeConfig,
    progress: bool,
    label: str,
    store: "_Checkpoint",
) -> float:
    """Adam (amsgrad) with reduce-on-plateau; leaves ``module`` at its best parameters.

    ``objective`` returns named loss terms whose sum is minimised.

    Returns:
        The best loss reached.
    """
    optimizer = torch.optim.Adam(module.parameters(), lr=learning_rate, amsgrad=True)
    schedule = torch.optim.lr_scheduler.ReduceLROnPlateau(
        optimizer, factor=config.plateau_factor, patience=config.plateau_patience
    )
    best_loss, best_state, start = float("inf"), _copy_state(module), 0
    saved = store.load(label)
    if saved is not None:
        module.load_state_dict(saved["module"])
        optimizer.load_state_dict(saved["optimizer"])
        schedule.load_state_dict(saved["schedule"])
        best_loss, best_state, start = saved["best_loss"], saved["best_state"], saved["iteration"]

    bar = tqdm(total=iterations, initial=start, desc=label, disable=not progress, leave=False)
    iteration = start
    while iteration < iterations and optimizer.param_groups[0]["lr"] >= learning_rate * config.min_lr_ratio:
        optimizer.zero_grad(set_to_none=True)
        terms = objective()
        loss = sum(terms.values())
        if not torch.isfinite(loss):
            raise FloatingPointError(f"{label}: the loss became {loss.item()} at iteration {iteration}")
        loss.backward()
        value = loss.item()
        if value < best_loss:
            best_loss, best_state = value, _copy_state(module)
        lr_before = optimizer.param_groups[0]["lr"]
        # Warm-up: Adam's first steps move every parameter by about lr, whatever its gradient,
        # which can push the hand out of a grasp that only just holds.
        optimizer.param_groups[0]["lr"] = lr_before * min(1.0, (iteration + 1) / config.warmup_iterations)
        optimizer.step()
        optimizer.param_groups[0]["lr"] = lr_before
        schedule.step(value)
        if optimizer.param_groups[0]["lr"] < lr_before:
            # Back to the best parameters, and forget the momentum that led away from them.
            module.load_state_dict(best_state)
            optimizer.state.clear()
        iteration += 1
        bar.update(1)
        bar.set_postfix(loss=f"{value:.4f}", best=f"{best_loss:.4f}", lr=f"{optimizer.param_groups[0]['lr']:.1e}")
        if iteration % config.checkpoint_every == 0:
            store.save(label, module, optimizer, schedule, best_loss, best_state, iteration)
    bar.close()
    if best_loss == float("inf"):  # no iteration ran: report the loss where the parameters are
        with torch.no_grad():
            best_loss = float(sum(objective().values()))
    module.load_state_dict(best_state)
    store.save(label, module, optimizer, schedule, best_loss, best_state, iterations)
    return best_loss


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

    def save(self, stage, module, optimizer, schedule, best_loss, best_state, iteration) -> None:
        if self.path is None:
            return
        self.stages[stage] = {
            "module": module.state_dict(),
            "optimizer": optimizer.state_dict(),
            "schedule": schedule.state_dict(),
            "best_loss": best_loss,
            "best_state": best_state,
            "iteration": iteration,
        }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        partial = self.path.with_name(self.path.name + ".partial")
        torch.save({"fingerprint": self.fingerprint, "stages": self.stages}, partial)
        os.replace(partial, self.path)


def _fingerprint(demo: Demonstration, config: OptimizeConfig, seed: int) -> str:
    """Identity of a run: a checkpoint resumes only the same demonstration and settings."""
    digest = hashlib.sha256()
    for array in (demo.hand_mask, demo.object_mask, demo.static_mask, demo.contact, demo.intrinsics.K):
        digest.update(np.ascontiguousarray(array).tobytes())
    digest.update(repr((demo.fps, config, seed)).encode())
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
