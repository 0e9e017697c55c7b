"""The hypotheses the pipeline tries, one record each, and the rules that make and choose them.

One view leaves some things open (the paper's Fig. 1): where the object is after it was
first seen (:class:`~warpskill.optimizer.guess.ObjectDepth`), whether the hand
still holds it after the contact signal ends, and whether it was put on the static box or
behind it (a :class:`Placement` each). :func:`warpskill.optimize` fits each hypothesis and
keeps the one the masks support best after the release:

1. :func:`read_evidence`: per demonstration, the masks and what they say of those questions;
2. :func:`stage_a_candidates`: one :class:`Candidate` per object-depth hypothesis;
3. :func:`stage_a_winners`: per demonstration, the rival with the lowest stage (a) loss;
4. :func:`physics_hypotheses`: one :class:`PhysicsHypothesis` per start (the winner, and
   each placement against the static box) and contact signal variant;
5. :func:`judged_simulations`: each simulation judged, and the one that matches the masks best chosen.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, replace
from functools import cached_property
from typing import Sequence

import numpy as np
import torch

from warpskill.contract.demonstration import Demonstration
from warpskill.engine.distances import box_signed_distance
from warpskill.nouns.typical import typical_size
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.guess import ObjectDepth, initial_guess
from warpskill.optimizer.inputs import (
    WorkingInputs,
    below_static_top_face,
    covers_static_top,
    cut_by_static,
    held_after_contact,
    rests_on_static,
    working_inputs,
)
from warpskill.optimizer.scene import (
    MIN_OBJECT_SIZE,
    MIN_STATIC_SIZE,
    SceneTrajectories,
    ends_behind_static,
    final_bottom,
)
from warpskill.optimizer.stage_a import InitialParameters
from warpskill.optimizer.stage_b import PhysicalRollout, PhysicalScene
from warpskill.optimizer.weights import LossWeights

logger = logging.getLogger(__name__)


def _on(device: torch.device, frames: np.ndarray) -> torch.Tensor | None:
    """(N,) bool frames as floats on ``device``; None when there are none."""
    return torch.as_tensor(frames, dtype=torch.float32, device=device) if frames.any() else None


@dataclass
class Evidence:
    """One demonstration as both stages fit it.

    Attributes:
        demo: the demonstration.
        inputs: its masks and contact at the working resolution.
        known: lengths known in advance [m] (:data:`~warpskill.optimizer.known.KNOWN_LENGTHS`).
        weights: the loss weights for this scene (:meth:`LossWeights.for_scene`).
        held: (N,) bool, frames after the contact signal's end where the object may still be
            held (:func:`~warpskill.optimizer.inputs.held_after_contact`): stage (a) leaves
            them to the masks, stage (b) simulates both endings and the video decides.
        uncertain: ``held`` as (N,) floats on the device; None when there are none.
        resting: (N,) bool, frames after the release where the object may stand on the
            static box (:func:`~warpskill.optimizer.inputs.rests_on_static`, read at the
            masks' own resolution: a few pixels tell the object on top from the object behind).
        behind: (N,) 1 in frames where the static box hides the object's lower part
            (:func:`~warpskill.optimizer.inputs.cut_by_static`); None when there are none.
        covering: (N,) bool, the frames of ``behind`` where the object's box spans the
            static's (:func:`~warpskill.optimizer.inputs.covers_static_top`).
        below_top_face: (N,) bool, frames after the release where the object's bottom lies
            deeper in the static's box than its top face reaches, within its columns
            (:func:`~warpskill.optimizer.inputs.below_static_top_face`): no box hides it there.
        typical_shape: [m] the typical size of the object's noun as (height, width, depth)
            where its size prior applies (``weights.object_noun_size`` on; a long object's
            first guess lies in its proportions, :func:`~warpskill.optimizer.guess.initial_guess`);
            None elsewhere.
        static_typical_shapes: the same per static object, from ``demo.static_nouns``, where
            its prior applies (``weights.static_noun_size`` on); empty elsewhere.
    """

    demo: Demonstration
    inputs: WorkingInputs
    known: dict[str, float]
    weights: LossWeights
    held: np.ndarray
    uncertain: torch.Tensor | None
    resting: np.ndarray
    behind: torch.Tensor | None
    covering: np.ndarray
    below_top_face: np.ndarray
    typical_shape: tuple[float, float, float] | None = None
    static_typical_shapes: tuple[tuple[float, float, float] | None, ...] = ()

    @property
    def static_typical_edges(self) -> tuple[tuple[float, float, float] | None, ...]:
        """[m] per static, its noun's typical edges, ascending, each at least
        :data:`~warpskill.optimizer.scene.MIN_STATIC_SIZE`; None where no prior applies."""
        return tuple(None if shape is None else tuple(max(edge, MIN_STATIC_SIZE) for edge in sorted(shape))
                     for shape in self.static_typical_shapes)

    @property
    def typical_edges(self) -> tuple[float, float, float] | None:
        """[m] ``typical_shape``'s edges, ascending, each at least
        :data:`~warpskill.optimizer.scene.MIN_OBJECT_SIZE` (no cuboid is thinner, as in the
        paper): what the size prior compares; None where it does not apply."""
        if self.typical_shape is None:
            return None
        return tuple(max(edge, MIN_OBJECT_SIZE) for edge in sorted(self.typical_shape))

    @cached_property
    def hand_seen(self) -> np.ndarray:
        """(N,) bool, the frames where the hand has a mask (read once)."""
        return (self.inputs.masks[:, 0] > 0.5).flatten(1).any(1).cpu().numpy()

    @property
    def placement(self) -> np.ndarray:
        """(N,) bool, the frames where the object may stand on the static box's top: where
        it may rest on it, else where it covers the box's top edge (``covering``)."""
        return self.resting if self.resting.any() else self.covering

    def placement_priors(self, placement: Placement | None) -> tuple[torch.Tensor | None, torch.Tensor | None]:
        """The frames (N,) in which a hypothesis with ``placement`` has the object stand on the
        static box and those in which it stands behind it (each None where none): a placement's
        own frames, else, with no placement, ``behind``."""
        if placement is None:
            return None, self.behind
        return (placement.frames, None) if placement.depth is ObjectDepth.STATIC else (None, placement.frames)


def read_evidence(demo: Demonstration, known: dict[str, float], config: OptimizeConfig,
                  device: torch.device, noun: str | None = None) -> Evidence:
    """The :class:`Evidence` of one demonstration with its ``known`` lengths and the object's
    ``noun`` (:func:`~warpskill.nouns.typical.typical_size`; None: no noun)."""
    inputs = working_inputs(demo, config, device)
    typical = typical_size(noun)
    statics = [typical_size(noun) for noun in demo.static_nouns]
    weights = config.weights.for_scene(known_length=bool(known), object_from_boxes=bool(inputs.targets.boxed[1]),
                                       noun_size_known=typical is not None,
                                       static_noun_known=any(size is not None for size in statics))
    typical_shape = None
    if typical is not None and weights.object_noun_size > 0:
        typical_shape = (typical.height, typical.width, typical.depth)
    static_shapes = ()
    if weights.static_noun_size > 0:
        static_shapes = tuple(None if size is None else (size.height, size.width, size.depth) for size in statics)
    full = demo.mask_channels()
    held = held_after_contact(full, inputs.contact_signal)
    rest = cut = covering = below = np.zeros(demo.num_frames, dtype=bool)
    if demo.num_static:
        rest, cut = rests_on_static(full, inputs.contact_signal), cut_by_static(full, inputs.contact_signal)
        covering = covers_static_top(full, inputs.contact_signal)
        below = below_static_top_face(full, inputs.contact_signal)
    return Evidence(demo, inputs, known, weights, held, _on(device, held), rest, _on(device, cut), covering, below,
                    typical_shape, static_shapes)


@dataclass(frozen=True)
class Placement:
    """Where a hypothesis puts the object against the first static box after the release.

    Attributes:
        depth: :attr:`ObjectDepth.STATIC` (on its top) or :attr:`ObjectDepth.BEHIND` (on the
            ground behind it).
        frames: (N,) 1 in the frames where it stands there (:attr:`Evidence.placement`).
    """

    depth: ObjectDepth
    frames: torch.Tensor


@dataclass
class Candidate:
    """A stage (a) hypothesis: one demonstration started from one object-depth guess.

    Attributes:
        demo: the demonstration's index.
        guess: the first scene (:func:`~warpskill.optimizer.guess.initial_guess`).
        placement: where the object stands against the static box (such a hypothesis goes on
            to the physics whatever its loss); None for the depth hypotheses that are rivals
            (the lowest loss wins).
        parameters: stage (a)'s parameters, started at ``guess``.
    """

    demo: int
    guess: SceneTrajectories
    placement: Placement | None
    parameters: InitialParameters


def stage_a_candidates(evidence: Sequence[Evidence], typical_camera_height: float,
                       device: torch.device, *, behind: bool = False) -> list[Candidate]:
    """Every demonstration from each object-depth hypothesis, demonstration by demonstration.

    "On the static" and, where the action is a put behind (with ``behind``: any action),
    "behind the static" are tried only where the object may stand on the static box's top
    (:attr:`Evidence.placement`): the same boxes fit a flat deep box with the object on it and
    a tall thin one with the object behind it. The action names the relation the person
    made, so it says which placement is worth a physics run; which one happened is still for
    the masks to say. Tried for every action, "behind" broke put onto where the real videos'
    situations are generated (docs/results-history.md). A guess equal to an earlier
    one of the same demonstration (the object's box bottom stays on one row) is fitted once.
    The hand's tilt read off its foreshortening starts the hand only where the scale is free:
    with a known length it was a worse start.
    """
    candidates: list[Candidate] = []
    for i, seen in enumerate(evidence):
        given = seen.inputs
        for hypothesis in ObjectDepth:
            placed = seen.placement
            if (hypothesis.placed and not placed.any()) or (
                    hypothesis is ObjectDepth.BEHIND and not (behind or seen.demo.action == "put_behind")):
                continue
            guess = initial_guess(given.masks.cpu().numpy(), given.contact_signal, given.intrinsics,
                                  seen.demo.num_static, object_depth=hypothesis, resting=placed,
                                  hand_width=not given.hand_boxed, hand_tilt=not seen.known,
                                  carried=given.contact_signal | seen.held,
                                  typical_camera_height=typical_camera_height, object_shape=seen.typical_shape)
            if any(c.demo == i and guess.same_as(c.guess) for c in candidates):
                continue
            placement = None
            if hypothesis.placed:
                placement = Placement(hypothesis, torch.as_tensor(placed, dtype=torch.float32, device=device))
            candidates.append(Candidate(i, guess, placement, InitialParameters(guess, seen.known).to(device)))
    return candidates


def rival_groups(candidates: Sequence[Candidate]) -> list[int | None]:
    """Each candidate's group of rivals (its demonstration), None for a placement against the static box."""
    return [c.demo if c.placement is None else None for c in candidates]


def stage_a_winners(candidates: Sequence[Candidate], losses: Sequence[float], num_demos: int) -> list[int]:
    """Per demonstration, the index of its rival candidate with the lowest stage (a) loss."""
    return [min((j for j, c in enumerate(candidates) if c.demo == i and c.placement is None), key=lambda j: losses[j])
            for i in range(num_demos)]


@dataclass
class PhysicsHypothesis:
    """A stage (b) hypothesis: one start and one contact signal of a demonstration.

    Attributes:
        demo: the demonstration's index.
        start: stage (a)'s per-frame scene it starts from.
        signal: (N,) bool, the contact signal variant: as given, or extended to the video's
            end where the object may still be held.
        contact: ``signal`` as (N,) floats on the device.
        placement: where the object is to stand against the static box (the start is that
            placement); None for stage (a)'s winner.
        scene: its physics parameters (set by the pipeline, which weighs the spline's start
            by how well stage (a) matched each frame's hand).
        fit: the perceptual loss of its final simulation where the object is left to the
            physics (:func:`settled_fit`; set by the pipeline).
    """

    demo: int
    start: SceneTrajectories
    signal: np.ndarray
    contact: torch.Tensor
    placement: Placement | None
    scene: PhysicalScene | None = None
    fit: float | None = None


def physics_hypotheses(evidence: Sequence[Evidence], candidates: Sequence[Candidate], winners: Sequence[int],
                       device: torch.device) -> list[PhysicsHypothesis]:
    """Per demonstration, each start (stage (a)'s winner and each placement against the static box)
    with each contact signal (as given and, where the object may still be held after it
    ends, extended to the video's end)."""
    hypotheses = []
    for i, seen in enumerate(evidence):
        signal = seen.inputs.contact_signal
        variants = [signal] + ([signal | seen.held] if seen.held.any() else [])
        starts = [(candidates[winners[i]], None)] + [(c, c.placement) for c in candidates
                                                     if c.demo == i and c.placement is not None]
        for candidate, placement in starts:
            start = candidate.parameters.scene().detached()
            for variant in variants:
                contact = torch.as_tensor(variant, dtype=torch.float32, device=device)
                hypotheses.append(PhysicsHypothesis(i, carried_start(start, signal, variant, seen.hand_seen), variant,
                                                    contact, placement))
    return hypotheses


def carried_start(start: SceneTrajectories, signal: np.ndarray, variant: np.ndarray,
                  hand_seen: np.ndarray) -> SceneTrajectories:
    """``start`` with the hand carrying the object in the frames that the contact ``variant``
    (N,) adds to ``signal`` (N,).

    Stage (a) leaves hand and object apart there (neither the contact nor the resting priors
    apply), each on its own mask's rays but at depths that need not agree; a held object moves
    with the hand, so the physics starts from the two keeping their offset at the signal's
    last frame. Where the hand has a mask (``hand_seen``, (N,) bool) the object goes with the
    hand (the hand's mask is the larger and surer: a small object's may be a few pixels);
    where it has none, the hand goes with the object.
    """
    added = np.asarray(variant, bool) & ~np.asarray(signal, bool)
    if not added.any():
        return start
    end = int(np.flatnonzero(signal)[-1])
    offset = start.hand_pos[end] - start.object_pos[end]
    seen = torch.as_tensor(np.flatnonzero(added & np.asarray(hand_seen, bool)), device=start.hand_pos.device)
    unseen = torch.as_tensor(np.flatnonzero(added & ~np.asarray(hand_seen, bool)), device=start.hand_pos.device)
    hand_pos, object_pos = start.hand_pos.clone(), start.object_pos.clone()
    object_pos[seen] = start.hand_pos[seen] - offset
    hand_pos[unseen] = start.object_pos[unseen] + offset
    return replace(start, hand_pos=hand_pos, object_pos=object_pos)


def settled_fit(frame_losses: torch.Tensor, contact: np.ndarray) -> float:
    """The mean of a simulation's perceptual ``frame_losses`` (N,) over the frames outside the
    ``contact`` signal (N,) as given (over all where it has none outside).

    There the hypotheses of one demonstration differ in what they claim (where the object
    rests: on the static box or behind it, in the hand or dropped); during the contact each
    follows the hand the same way, and how closely its simulated grasp keeps up says nothing
    of where the object was put.
    """
    free = torch.as_tensor(~np.asarray(contact, bool), device=frame_losses.device)
    return float(frame_losses[free].mean() if free.any() else frame_losses.mean())


def unseen_before_contact(seen: Evidence, signal: np.ndarray) -> bool:
    """Whether the object's mask is empty in every frame before ``signal``'s (N,) onset."""
    onset = np.flatnonzero(signal)
    return len(onset) > 0 and not bool(seen.inputs.object_visible[: onset[0]].any())


DROP = 0.05
"""[m] how much lower than stage (a) a simulation may end the object before a release it
assumes is contradicted (:func:`judged_simulations`)."""


@dataclass(frozen=True)
class Judgement:
    """One simulated hypothesis of a demonstration as :func:`judged_simulations` saw it (the
    reconstruction's ``hypotheses`` record, docs/formats.md).

    Attributes:
        start: where its physics started: ``"stage (a)"`` (the rivals' winner) or its
            placement (``"on the static"``, ``"behind the static"``).
        contact_frames: frames in its contact signal (more than given: held to the end).
        fit: its perceptual loss after the contact (:func:`settled_fit`; lower fits better).
        ends_behind_static: whether its object ends behind the first static box; None without one.
        contradicted: whether the masks rule it out (:func:`judged_simulations` says when).
        chosen: whether it is the simulation kept.
    """

    start: str
    contact_frames: int
    fit: float
    ends_behind_static: bool | None
    contradicted: bool
    chosen: bool

    def as_dict(self) -> dict:
        """This judgement as JSON-ready values."""
        return asdict(self)


def judged_simulations(seen: Evidence, own: Sequence[PhysicsHypothesis],
                       results: Sequence[PhysicalRollout]) -> list[Judgement]:
    """One :class:`Judgement` per hypothesis of ``own`` (one demonstration's hypotheses, with
    their final ``results``), exactly one of them chosen: the best fit (:func:`settled_fit`)
    among those the masks do not contradict. The object on the static box and the object
    behind it are compared by their fits: the renderer hides what the box hides, and an
    object's bottom edge inside the box's rows may be that of an object behind it where the
    box's outline dips (a turned box's far edge). Deeper than the box's top face reaches,
    within its columns (:attr:`Evidence.below_top_face`), no box can hide it: a simulation
    that ends with the object behind the box contradicts the masks there.

    Where the object may still be held after the contact signal ends, a simulation of the
    signal as given (the object released) contradicts them too where it ends the object more
    than :data:`DROP` lower than stage (a) does (stage (a) fits each frame's masks without
    physics, and an object it leaves in the air at the end, which the release drops, was
    held), or where its hand stays off the object while the masks show it on it
    (:func:`hovers_off_a_held_object`).
    """
    unhidden = bool(seen.below_top_face.any())
    behind = [ends_behind_static(result.scene) if seen.demo.num_static else None for result in results]
    contradicted = [bool((unhidden and ends_behind) or drops_a_held_object(seen, h, result)
                         or hovers_off_a_held_object(seen, h, result))
                    for h, result, ends_behind in zip(own, results, behind)]
    chosen = best_simulation([h.fit for h in own], contradicted)
    judged = [Judgement("stage (a)" if h.placement is None else h.placement.depth.value, int(h.signal.sum()),
                        float(h.fit), ends_behind, against, k == chosen)
              for k, (h, ends_behind, against) in enumerate(zip(own, behind, contradicted))]
    for judgement in judged:
        logger.debug("%s", judgement)
    return judged


def kept(judged: Sequence[Judgement]) -> int:
    """Index of the chosen one among ``judged``."""
    return next(k for k, judgement in enumerate(judged) if judgement.chosen)


def chosen_simulation(seen: Evidence, own: Sequence[PhysicsHypothesis], results: Sequence[PhysicalRollout]) -> int:
    """Index into ``own`` of the simulation to keep (:func:`judged_simulations` says which)."""
    return kept(judged_simulations(seen, own, results))


def drops_a_held_object(seen: Evidence, hypothesis: PhysicsHypothesis, result: PhysicalRollout) -> bool:
    """Whether ``result`` releases a possibly held object (:func:`releases_a_held_object`) and
    ends it more than :data:`DROP` below stage (a)'s last frame."""
    return (releases_a_held_object(seen, hypothesis)
            and final_bottom(hypothesis.start) - final_bottom(result.scene) > DROP)


HOVER = 0.08
"""[m] how far from the object's box a released hand's tip may stay on average, over the
frames after the contact signal where the masks show the hand on the object, before the
release is contradicted (:func:`hovers_off_a_held_object`): twice the hand's diameter."""


def hovers_off_a_held_object(seen: Evidence, hypothesis: PhysicsHypothesis, result: PhysicalRollout) -> bool:
    """Whether ``result`` releases a possibly held object (:func:`releases_a_held_object`) and
    keeps its hand's tip on average more than :data:`HOVER` from the object's box over the
    frames after the signal where the hand has a mask. The masks show the hand's box on the
    object's there to the video's end (:func:`~warpskill.optimizer.inputs.held_after_contact`);
    a hand that let go and stayed that far away, hidden along the camera's rays, is a
    coincidence that holding the object explains (a lift read as a slide away on the ground).
    """
    if not releases_a_held_object(seen, hypothesis):
        return False
    frames = torch.as_tensor(np.flatnonzero(seen.held & seen.hand_seen), device=result.scene.hand_pos.device)
    if len(frames) == 0:
        return False
    scene = result.scene
    gap = box_signed_distance(scene.hand_pos[frames], scene.object_pos[frames], scene.object_rot[frames],
                              scene.object_size).clamp_min(0.0)
    return float(gap.mean()) > HOVER


def releases_a_held_object(seen: Evidence, hypothesis: PhysicsHypothesis) -> bool:
    """Whether ``hypothesis`` has the contact signal as given (the object let go at its end)
    where ``seen`` has frames in which the object may still be held."""
    return bool(seen.held.any()) and np.array_equal(hypothesis.signal, seen.inputs.contact_signal)


def best_simulation(fits: Sequence[float], contradicted: Sequence[bool]) -> int:
    """Index of the simulation with the lowest perceptual loss among those the masks do not
    contradict (among all when every one is)."""
    pool = [k for k in range(len(fits)) if not contradicted[k]] or range(len(fits))
    return min(pool, key=lambda k: fits[k])
