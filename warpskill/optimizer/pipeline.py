"""``warpskill.optimize``: a demonstration in, physically admissible trajectories out.

Two stages, as in the paper: (a) a physics-free fit of per-frame poses (:mod:`.initialize`),
from each hypothesis about the object's depth (the lower loss wins), gives a first
camera and trajectories; (b) the physics stage (:mod:`.physical_scene`)
optimises the initial states, the hand's velocity spline, the sizes and the camera through
the Warp engine. Both use Adam (amsgrad) with a reduce-on-plateau schedule that returns to
the best parameters whenever it lowers the learning rate.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import replace
from typing import Mapping, Sequence

import numpy as np
import torch

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.engine.device import resolve_device
from warpskill.engine.distances import box_signed_distance
from warpskill.optimizer.batching import Backend, render_many, simulate_many
from warpskill.optimizer.checkpoint import Checkpoint, fingerprint
from warpskill.optimizer.options import OptimizeOptions
from warpskill.optimizer.inputs import cut_by_static, held_after_contact, rests_on_static, working_inputs
from warpskill.optimizer.known import check_known
from warpskill.optimizer.loop import minimise
from warpskill.optimizer.losses import masks_loss
from warpskill.optimizer.scene import SceneTrajectories, ends_behind_static, perceptual_loss
from warpskill.optimizer.stage_a import (
    OBJECT_DEPTH_HYPOTHESES,
    InitialParameters,
    initial_guess,
    initial_objective,
)
from warpskill.optimizer.stage_b import (
    PhysicalRollout,
    make_physical_scene,
    physical_objective,
)


def optimize(
    demo: Demonstration,
    options: OptimizeOptions | None = None,
    *,
    progress: bool = True,
    checkpoint: str | os.PathLike | None = None,
    backend: Backend | None = None,
    **fields,
) -> Reconstruction:
    """Reconstruct physically admissible hand and object trajectories from a demonstration.

    Args:
        demo: the demonstration (masks, contact, fps, camera intrinsics).
        options: what to optimise and how (:class:`OptimizeOptions`); default: all defaults.
        progress: show progress bars.
        checkpoint: a file where the run saves its state and best result as it goes; an
            existing checkpoint of the same demonstration and options is resumed.
        backend: the rollout and rasterizer (default: the Warp engine).
        **fields: fields of :class:`OptimizeOptions` replacing those of ``options``
            (``device``, ``seed``, ``init_only``, ``known``, ``config``), and ``iterations``
            for ``config.iterations``; e.g. ``known={"object_height": 0.10}``.

    Returns:
        The reconstruction, in the world frame of docs/formats.md, at the video's frames,
        with ``options`` saved in it.
    """
    return optimize_many([demo], options, progress=progress, checkpoint=checkpoint, backend=backend, **fields)[0]


def optimize_many(
    demos: Sequence[Demonstration],
    options: OptimizeOptions | None = None,
    *,
    known_each: Sequence[Mapping[str, float] | None] | None = None,
    progress: bool = True,
    checkpoint: str | os.PathLike | None = None,
    backend: Backend | None = None,
    **fields,
) -> list[Reconstruction]:
    """Reconstruct B demonstrations side by side: :func:`optimize` on each, in shared engine calls.

    Every iteration rolls out all B scenes in one engine call and renders all their frames
    in one raster launch (per group of demonstrations that share the frame rate, the
    intrinsics, the working image size and the number of static objects; see
    :mod:`warpskill.optimizer.batching`). Each demonstration keeps its own parameters, learning-rate
    schedule, early stop and best result, so each reconstruction is the one
    :func:`optimize` would return, up to floating-point rounding.

    Args:
        demos: the demonstrations.
        options, progress, backend, fields: as :func:`optimize`.
        known_each: one mapping of known lengths (or None) per demonstration, replacing
            ``options.known`` for that demonstration (e.g. each synthetic scene's true height).
        checkpoint: one file for the whole batch (resumed only for the same demonstrations
            and options).

    Returns:
        One reconstruction per demonstration, in order.

    Raises:
        ValueError: no demonstrations, or ``known_each`` of another length.
    """
    options = OptimizeOptions.build(options, **fields)
    if len(demos) == 0:
        raise ValueError("optimize_many needs at least one demonstration")
    config, seed, init_only = options.config, options.seed, options.init_only
    backend = backend or Backend()
    device = resolve_device(options.device)
    torch.manual_seed(seed)
    if known_each is None:
        knowns = [options.known_lengths] * len(demos)
    else:
        if len(known_each) != len(demos):
            raise ValueError(f"known_each: {len(known_each)} mappings for {len(demos)} demonstrations")
        knowns = [check_known(k) for k in known_each]
    run_id = fingerprint(demos, config, seed, backend)
    if any(knowns):
        run_id = hashlib.sha256((run_id + repr(knowns)).encode()).hexdigest()
    store = Checkpoint(checkpoint, run_id)
    inputs = [working_inputs(demo, config, device) for demo in demos]
    weights, sigma = config.weights, config.sigma
    scene_weights = [weights.for_scene(known_length=bool(k), object_from_boxes=bool(given.targets.boxed[1]))
                     for k, given in zip(knowns, inputs)]
    # Frames after the contact signal's end where the object may still be held: stage (a)
    # leaves them to the masks, stage (b) simulates both endings and the video decides.
    held = [held_after_contact(given.masks.cpu().numpy(), given.contact_signal) for given in inputs]
    uncertain = [torch.as_tensor(h, dtype=torch.float32, device=device) if h.any() else None for h in held]

    # Frames after the release where the object may stand on the static box (or behind it).
    # (At the masks' own resolution: a few pixels tell the object on top from the object behind.)
    # ... and those where it stands behind it, its lower part hidden by the box's top edge.
    resting, behind = [], []
    for demo, given in zip(demos, inputs):
        rest = cut = np.zeros(demo.num_frames, dtype=bool)
        if demo.num_static:
            full = demo.mask_stack(*demo.image_size)
            rest, cut = rests_on_static(full, given.contact_signal), cut_by_static(full, given.contact_signal)
        resting.append(rest)
        behind.append(torch.as_tensor(cut, dtype=torch.float32, device=device) if cut.any() else None)

    # Stage (a): every demonstration from each object-depth hypothesis; the lower loss wins,
    # except that a placement on the static box goes on to the physics beside the winner.
    # The hand's tilt read off its foreshortening starts the hand where the scale is free
    # (54 synthetic mask demonstrations: |scale - 1| 0.115 -> 0.07, 50/54 either way); with
    # a known length it raised the object-centre error (2.9 -> 3.5 cm), so it is left out.
    owners, candidates, supported, guesses = [], [], [], []
    for i, (demo, given) in enumerate(zip(demos, inputs)):
        for hypothesis in OBJECT_DEPTH_HYPOTHESES:
            on_static = hypothesis == "on the static"
            if on_static and not resting[i].any():
                continue
            guess = initial_guess(given.masks.cpu().numpy(), given.contact_signal, given.intrinsics, demo.num_static,
                                  object_depth=hypothesis, resting=resting[i], hand_width=not given.hand_boxed,
                                  hand_tilt=not knowns[i],
                                  carried=given.contact_signal | held[i])
            if any(owner == i and guess.same_as(made) for owner, made in zip(owners, guesses)):
                continue  # placed alike by two hypotheses (the object's box bottom stays on one row): one fit
            guesses.append(guess)
            owners.append(i)
            supported.append(torch.as_tensor(resting[i], dtype=torch.float32, device=device) if on_static else None)
            candidates.append(InitialParameters(guess, knowns[i]).to(device))

    def stage_a(live: list[int]) -> list[dict[str, torch.Tensor]]:
        scenes = [candidates[j].scene() for j in live]
        rendered = render_many(scenes, [inputs[owners[j]].intrinsics for j in live], sigma, backend,
                               [inputs[owners[j]].targets for j in live])
        return [
            initial_objective(scene, masks, inputs[owners[j]].targets, inputs[owners[j]].contact,
                              demos[owners[j]].fps, scene_weights[owners[j]], uncertain[owners[j]],
                              supported[j], behind[owners[j]])
            for j, scene, masks in zip(live, scenes, rendered)
        ]

    # The depth hypotheses of a demonstration are rivals: those clearly behind stop early
    # (``config.rival_rungs``); the placement on the static box is no rival: it always goes
    # on to the physics.
    rivals = [owners[j] if supported[j] is None else None for j in range(len(candidates))]
    losses = minimise(candidates, stage_a, iterations=config.init_iterations,
                       learning_rate=config.init_learning_rate, config=config, progress=progress,
                       label="initialisation", store=store, rivals=rivals, rungs=config.rival_rungs)
    fits, stage_a_losses, placements = [], [], []
    for i in range(len(demos)):
        j = min((j for j in range(len(owners)) if owners[j] == i and supported[j] is None), key=lambda j: losses[j])
        fits.append(candidates[j].scene().detached())
        stage_a_losses.append(losses[j])
        placements.append([(candidates[j].scene().detached(), supported[j]) for j in range(len(owners))
                           if owners[j] == i and supported[j] is not None])
    if init_only:
        reconstructions = []
        for i, (demo, given, fit, loss) in enumerate(zip(demos, inputs, fits, stage_a_losses)):
            grasp = (2 * given.contact - 1) * weights.grasp_margin
            distance = box_signed_distance(fit.hand_pos, fit.object_pos, fit.object_rot, fit.object_size)
            reconstructions.append(_reconstruction(demo, fit, grasp, given.contact * (distance < 0), loss,
                                                   replace(options, known=tuple(knowns[i].items()))))
        return reconstructions

    # Stage (b): the physics, once per contact hypothesis (the signal as given and, where the
    # object may still be held after it ends, the signal extended to the video's end) and per
    # placement (stage (a)'s winner and, where the object may rest on the static box, that
    # placement); the one whose simulation matches the masks best wins.
    physics_owners, contacts, signals, starts, on_static = [], [], [], [], []
    for i, given in enumerate(inputs):
        variants = [given.contact_signal] + ([given.contact_signal | held[i]] if held[i].any() else [])
        for start, support in [(fits[i], None)] + placements[i]:
            for signal in variants:
                physics_owners.append(i)
                signals.append(signal)
                starts.append(start)
                on_static.append(support)
                contacts.append(torch.as_tensor(signal, dtype=torch.float32, device=device))
    def unseen_before_contact(i: int, signal: np.ndarray) -> bool:
        onset = np.flatnonzero(signal)
        return len(onset) > 0 and not bool(inputs[i].object_visible[: onset[0]].any())

    with torch.no_grad():  # how well stage (a) matched each frame's hand: the spline's start weighs by it
        profiles = render_many(starts, [inputs[i].intrinsics for i in physics_owners], sigma, backend,
                               [inputs[i].targets for i in physics_owners])
        hand_losses = [masks_loss(profile, inputs[i].targets)[:, 0].cpu().double().numpy()
                       for i, profile in zip(physics_owners, profiles)]
    scenes = [make_physical_scene(start, signal, demos[physics_owners[b]].fps, config, knowns[physics_owners[b]],
                                  unseen_before_contact(physics_owners[b], signal), hand_losses[b]).to(device)
              for b, (start, signal) in enumerate(zip(starts, signals))]

    def simulate_scenes(live: list[int]) -> list[PhysicalRollout]:
        rollouts = simulate_many([scenes[b].simulation_inputs() for b in live],
                                 [scenes[b].simulation_options() for b in live], backend.simulate)
        return [scenes[b].assemble(rollout) for b, rollout in zip(live, rollouts)]

    def stage_b(live: list[int]) -> list[dict[str, torch.Tensor]]:
        results = simulate_scenes(live)
        rendered = render_many([r.scene for r in results], [inputs[physics_owners[b]].intrinsics for b in live],
                               sigma, backend, [inputs[physics_owners[b]].targets for b in live])
        return [
            physical_objective(result, masks, inputs[physics_owners[b]].targets, contacts[b],
                               inputs[physics_owners[b]].object_visible, scene_weights[physics_owners[b]],
                               on_static[b], behind[physics_owners[b]])
            for b, result, masks in zip(live, results, rendered)
        ]

    losses = minimise(scenes, stage_b, iterations=config.iterations, learning_rate=config.learning_rate,
                       config=config, progress=progress, label="physics", store=store)
    with torch.no_grad():
        everything = list(range(len(scenes)))
        results = simulate_scenes(everything)
        rendered = render_many([r.scene for r in results], [inputs[physics_owners[b]].intrinsics for b in everything],
                               sigma, backend, [inputs[physics_owners[b]].targets for b in everything])
        fit = [float(perceptual_loss(masks, inputs[physics_owners[b]].targets, weights))
               for b, masks in zip(everything, rendered)]
    reconstructions = []
    for i, demo in enumerate(demos):
        own = [b for b in everything if physics_owners[b] == i]
        # Where the masks show the object's bottom inside the static's box after the release,
        # a simulation that ends with the object behind the box contradicts them: the
        # renderer draws the object whole, but the box would hide it there.
        contradicted = [bool(resting[i].any()) and ends_behind_static(results[b].scene) for b in own]
        b = own[best_simulation([fit[b] for b in own], contradicted)]
        result = results[b]
        reconstructions.append(_reconstruction(demo, result.scene, result.rollout.grasp, result.rollout.grasped,
                                               losses[b], replace(options, known=tuple(knowns[i].items()))))
    return reconstructions


def best_simulation(fits: Sequence[float], contradicted: Sequence[bool]) -> int:
    """Index of the simulation with the lowest perceptual loss among those the masks do not
    contradict (among all when every one is)."""
    pool = [k for k in range(len(fits)) if not contradicted[k]] or range(len(fits))
    return min(pool, key=lambda k: fits[k])


def _reconstruction(
    demo: Demonstration, scene: SceneTrajectories, grasp: torch.Tensor, grasped: torch.Tensor, loss: float,
    options: OptimizeOptions,
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
        options=options.to_json(),
    )
