"""``warpskill.optimize``: a demonstration in, physically admissible trajectories out.

The paper's two stages over a list of hypotheses (:mod:`.hypotheses`): the masks and what
they leave open (:func:`~.hypotheses.read_evidence`); stage (a) (:mod:`.stage_a`), a
physics-free fit of per-frame poses from each object-depth guess (:mod:`.guess`), whose
lowest loss wins; stage (b) (:mod:`.stage_b`), which optimises the initial states, the
hand's velocity spline, the sizes and the camera through the Warp engine from the winner
(and any placement on the static box), once per contact signal variant; and the choice of
the simulation that matches the masks best. Both stages use Adam (amsgrad) with a
reduce-on-plateau schedule that returns to the best parameters whenever it lowers the
learning rate (:mod:`.loop`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import replace
from typing import Callable, Mapping, Sequence

import numpy as np
import torch

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.engine.device import resolve_device
from warpskill.engine.distances import box_signed_distance
from warpskill.nouns.typical import typical_size
from warpskill.optimizer.batching import Backend, render_many, simulate_many
from warpskill.optimizer.checkpoint import Checkpoint, fingerprint
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.hypotheses import (
    Candidate,
    Evidence,
    Judgement,
    PhysicsHypothesis,
    judged_simulations,
    kept,
    physics_hypotheses,
    read_evidence,
    rival_groups,
    settled_fit,
    stage_a_candidates,
    stage_a_winners,
    unseen_before_contact,
)
from warpskill.optimizer.inputs import static_box_drift
from warpskill.optimizer.known import check_known
from warpskill.optimizer.loop import minimise
from warpskill.optimizer.losses import MaskTargets, masks_loss
from warpskill.optimizer.options import OptimizeOptions

logger = logging.getLogger(__name__)
from warpskill.optimizer.scene import SceneTrajectories, frame_perceptual_losses
from warpskill.optimizer.stage_a import initial_objective
from warpskill.optimizer.stage_b import PhysicalRollout, make_physical_scene, physical_objective

Objective = Callable[[list[int]], list[dict[str, torch.Tensor]]]


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
            (``device``, ``seed``, ``init_only``, ``known``, ``object_noun``, ``config``), and ``iterations``
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
    config = options.config
    backend = backend or Backend()
    device = resolve_device(options.device)
    options = replace(options, device=str(device))  # saved as it ran: None and "cpu" are one run
    torch.manual_seed(options.seed)
    knowns = _knowns_each(options, known_each, len(demos))
    nouns = [_object_noun(demo, options, known) for demo, known in zip(demos, knowns)]
    store = Checkpoint(checkpoint, _run_id(demos, options, backend, knowns, nouns))
    evidence = [read_evidence(demo, known, config, device, noun) for demo, known, noun in zip(demos, knowns, nouns)]
    for i, demo in enumerate(demos):
        _warn_of_a_moving_camera(demo, i if len(demos) > 1 else None)

    # Stage (a): each object-depth hypothesis; the depth hypotheses of a demonstration are
    # rivals, those clearly behind stop early (``config.rival_rungs``), the lowest loss wins.
    # Its first ``config.coarse_iterations`` at ``config.coarse_scale`` of the working resolution.
    candidates = stage_a_candidates(evidence, config.weights.typical_camera_height, device,
                                    behind=config.behind_placement)
    coarse = [_coarse_evidence(e, config, device) for e in evidence] if config.coarse_iterations > 0 else evidence
    losses = minimise([c.parameters for c in candidates], _stage_a_objective(candidates, evidence, config, backend),
                      iterations=config.init_iterations, learning_rate=config.init_learning_rate, config=config,
                      progress=progress, label="initialisation", store=store, rivals=rival_groups(candidates),
                      rungs=config.rival_rungs,
                      coarse=(config.coarse_iterations, _stage_a_objective(candidates, coarse, config, backend)))
    winners = stage_a_winners(candidates, losses, len(demos))
    if options.init_only:
        return [_stage_a_reconstruction(evidence[i], candidates[j], losses[j], config, options)
                for i, j in enumerate(winners)]

    # Stage (b): the physics from each start and contact signal variant; the simulation
    # that matches the masks best wins.
    hypotheses = physics_hypotheses(evidence, candidates, winners, device)
    _start_physics(hypotheses, evidence, config, backend, device)
    simulate = _physics_simulation(hypotheses, evidence, config, backend)
    losses = minimise([h.scene for h in hypotheses], _stage_b_objective(hypotheses, evidence, simulate),
                      iterations=config.iterations, learning_rate=config.learning_rate, config=config,
                      progress=progress, label="physics", store=store)
    with torch.no_grad():
        results, rendered = simulate(list(range(len(hypotheses))))
        for h, masks in zip(hypotheses, rendered):
            seen = evidence[h.demo]
            h.fit = settled_fit(frame_perceptual_losses(masks, seen.inputs.targets, config.weights),
                                seen.inputs.contact_signal)
    return [_chosen_reconstruction(i, seen, hypotheses, results, losses, options) for i, seen in enumerate(evidence)]


def _knowns_each(options: OptimizeOptions, known_each: Sequence[Mapping[str, float] | None] | None,
                 count: int) -> list[dict[str, float]]:
    """The known lengths [m] of each of ``count`` demonstrations: ``known_each`` (checked) or
    ``options.known`` for all."""
    if known_each is None:
        return [options.known_lengths] * count
    if len(known_each) != count:
        raise ValueError(f"known_each: {len(known_each)} mappings for {count} demonstrations")
    return [check_known(k) for k in known_each]


def _object_noun(demo: Demonstration, options: OptimizeOptions, known: dict[str, float]) -> str | None:
    """The object's noun: ``options.object_noun``, else the demonstration's; one line says so
    when the noun adds no size prior: it has no typical size, or a ``known`` length fixes the
    scale (the run goes on without the prior)."""
    noun = options.object_noun or demo.object_noun
    if noun and typical_size(noun) is None:
        logger.warning("object noun %r: no typical size known, so no size prior", noun)
    elif noun and known:
        logger.warning("object noun %r: the known %s fixes the scale, so no size prior", noun, ", ".join(sorted(known)))
    return noun


MOVING_CAMERA = 0.05
"""[share of the image width] how far the static boxes may wander (:func:`~warpskill.optimizer.inputs.static_box_drift`)
before one line says the camera seems to move: farther than boxes drawn by people jitter."""


def _warn_of_a_moving_camera(demo: Demonstration, index: int | None) -> None:
    """One line when ``demo``'s static boxes wander more than :data:`MOVING_CAMERA` (the
    demonstration's ``index`` among several, else None): the reconstruction's camera is fixed,
    so the fit after a camera move is looser."""
    width = demo.image_size[1]
    drift = static_box_drift(demo.mask_channels()) if demo.num_static else 0.0
    if drift > MOVING_CAMERA * width:
        which = "" if index is None else f"demonstration {index}: "
        logger.warning("%sa static object's box moves %.0f px (%.0f %% of the width) at a steady size: the camera "
                       "seems to move, and warpskill's camera is fixed, so the fit is looser", which, drift,
                       100 * drift / width)


def _run_id(demos: Sequence[Demonstration], options: OptimizeOptions, backend: Backend,
            knowns: Sequence[dict[str, float]], nouns: Sequence[str | None]) -> str:
    """The checkpoint's identity of this run (:func:`~warpskill.optimizer.checkpoint.fingerprint`,
    with the known lengths and the objects' nouns where any is given)."""
    run_id = fingerprint(demos, options.config, options.seed, backend)
    if any(knowns):
        run_id = hashlib.sha256((run_id + repr(knowns)).encode()).hexdigest()
    if any(nouns):
        run_id = hashlib.sha256((run_id + repr(nouns)).encode()).hexdigest()
    return run_id


def _with_known(options: OptimizeOptions, known: dict[str, float]) -> OptimizeOptions:
    """``options`` as saved with one demonstration's reconstruction: with its own known lengths."""
    return replace(options, known=tuple(known.items()))


def _coarse_evidence(seen: Evidence, config: OptimizeConfig, device: torch.device) -> Evidence:
    """``seen`` with its masks (and their intrinsics) at ``config.coarse_scale`` of the working
    resolution; the contact and what was read of the masks stay the working resolution's."""
    given = seen.inputs
    h, w = seen.demo.intrinsics.scaled(config.image_scale * config.coarse_scale).image_size
    masks = torch.as_tensor(seen.demo.mask_stack(h, w), device=device)
    targets = MaskTargets(masks, given.targets.boxed, given.targets.absent)
    return replace(seen, inputs=replace(given, intrinsics=seen.demo.intrinsics.resized(h, w), masks=masks,
                                        targets=targets))


def _stage_a_objective(candidates: Sequence[Candidate], evidence: Sequence[Evidence], config: OptimizeConfig,
                       backend: Backend) -> Objective:
    """Stage (a)'s loss terms of the live candidates, their frames rendered in shared launches."""

    def objective(live: list[int]) -> list[dict[str, torch.Tensor]]:
        scenes = [candidates[j].parameters.scene() for j in live]
        seen = [evidence[candidates[j].demo] for j in live]
        rendered = render_many(scenes, [e.inputs.intrinsics for e in seen], config.sigma, backend,
                               [e.inputs.targets for e in seen])
        return [
            initial_objective(scene, masks, e.inputs.targets, e.inputs.contact, e.demo.fps, e.weights, e.uncertain,
                              *e.placement_priors(candidates[j].placement), e.typical_edges,
                              e.static_typical_edges)
            for j, scene, masks, e in zip(live, scenes, rendered, seen)
        ]

    return objective


def _stage_a_reconstruction(seen: Evidence, winner: Candidate, loss: float, config: OptimizeConfig,
                            options: OptimizeOptions) -> Reconstruction:
    """The reconstruction of stage (a) alone (the paper's "initialisation only"): the winner's
    per-frame scene, the grasp signal at the contact's margin, grasped where the tip is inside."""
    fit = winner.parameters.scene().detached()
    given = seen.inputs
    grasp = (2 * given.contact - 1) * config.weights.grasp_margin
    distance = box_signed_distance(fit.hand_pos, fit.object_pos, fit.object_rot, fit.object_size)
    grasped = given.contact * (distance < 0)
    return _reconstruction(seen.demo, fit, grasp, grasped, loss, _with_known(options, seen.known))


def _start_physics(hypotheses: Sequence[PhysicsHypothesis], evidence: Sequence[Evidence], config: OptimizeConfig,
                   backend: Backend, device: torch.device) -> None:
    """Set each hypothesis's physics parameters, its hand spline weighing the frames by how
    well its start matched their hand masks (stage (a)'s hand dIoU per frame)."""
    seen = [evidence[h.demo] for h in hypotheses]
    with torch.no_grad():
        profiles = render_many([h.start for h in hypotheses], [e.inputs.intrinsics for e in seen], config.sigma,
                               backend, [e.inputs.targets for e in seen])
        hand_losses = [masks_loss(profile, e.inputs.targets)[:, 0].cpu().double().numpy()
                       for e, profile in zip(seen, profiles)]
    for h, e, hand_loss in zip(hypotheses, seen, hand_losses):
        h.scene = make_physical_scene(h.start, h.signal, e.demo.fps, config, e.known,
                                      unseen_before_contact(e, h.signal), hand_loss).to(device)


def _physics_simulation(
    hypotheses: Sequence[PhysicsHypothesis], evidence: Sequence[Evidence], config: OptimizeConfig, backend: Backend,
) -> Callable[[list[int]], tuple[list[PhysicalRollout], list[torch.Tensor]]]:
    """``simulate(live)``: the live hypotheses' rollouts in one engine call and their frames
    rendered in shared launches."""

    def simulate(live: list[int]) -> tuple[list[PhysicalRollout], list[torch.Tensor]]:
        scenes = [hypotheses[b].scene for b in live]
        rollouts = simulate_many([s.simulation_inputs() for s in scenes], [s.simulation_options() for s in scenes],
                                 backend.simulate)
        results = [scene.assemble(rollout) for scene, rollout in zip(scenes, rollouts)]
        seen = [evidence[hypotheses[b].demo] for b in live]
        rendered = render_many([r.scene for r in results], [e.inputs.intrinsics for e in seen], config.sigma,
                               backend, [e.inputs.targets for e in seen])
        return results, rendered

    return simulate


def _stage_b_objective(hypotheses: Sequence[PhysicsHypothesis], evidence: Sequence[Evidence],
                       simulate: Callable[[list[int]], tuple[list[PhysicalRollout], list[torch.Tensor]]]) -> Objective:
    """Stage (b)'s loss terms of the live hypotheses."""

    def objective(live: list[int]) -> list[dict[str, torch.Tensor]]:
        results, rendered = simulate(live)
        terms = []
        for b, result, masks in zip(live, results, rendered):
            h, e = hypotheses[b], evidence[hypotheses[b].demo]
            terms.append(physical_objective(result, masks, e.inputs.targets, h.contact, e.inputs.object_visible,
                                            e.weights, *e.placement_priors(h.placement), e.typical_edges,
                                            e.static_typical_edges))
        return terms

    return objective


def _chosen_reconstruction(demo: int, seen: Evidence, hypotheses: Sequence[PhysicsHypothesis],
                           results: Sequence[PhysicalRollout], losses: Sequence[float],
                           options: OptimizeOptions) -> Reconstruction:
    """The reconstruction of demonstration ``demo`` from its chosen simulation among the final
    ``results``, with every simulation's judgement (:func:`~warpskill.optimizer.hypotheses.judged_simulations`)."""
    own = [b for b, h in enumerate(hypotheses) if h.demo == demo]
    judged = judged_simulations(seen, [hypotheses[b] for b in own], [results[b] for b in own])
    b = own[kept(judged)]
    result = results[b]
    return _reconstruction(seen.demo, result.scene, result.rollout.grasp, result.rollout.grasped, losses[b],
                           _with_known(options, seen.known), judged)


def _reconstruction(
    demo: Demonstration, scene: SceneTrajectories, grasp: torch.Tensor, grasped: torch.Tensor, loss: float,
    options: OptimizeOptions, judged: Sequence[Judgement] = (),
) -> Reconstruction:
    """The docs/formats.md reconstruction of a per-frame scene, at the demonstration's full
    resolution, recording the ``judged`` simulations it was chosen from."""
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
        object_noun=options.object_noun or demo.object_noun or "",
        loss=np.float64(loss),
        options=options.to_json(),
        hypotheses=json.dumps([judgement.as_dict() for judgement in judged]) if judged else "",
    )
