"""The synthetic demonstration: a scripted scene simulated, ray cast into exact masks, then spoiled."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace
from typing import Sequence

import numpy as np

from warpskill.contract.actions import ACTIONS, check_action
from warpskill.contract.camera import Intrinsics
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import FIELD_SHAPES
from warpskill.data.boxes.something_else import something_else_demonstration
from warpskill.data.masks import clean_masks
from warpskill.engine.primitives import scene_cuboids
from warpskill.engine.raycast import raycast_masks
from warpskill.engine.simulation import simulate
from warpskill.geometry import is_held
from warpskill.synthetic.relations import RELATION_ACTIONS, relation_case
from warpskill.synthetic.scripts import (
    ASKEW_OBJECT_YAW,
    TURNED_STATIC_YAW,
    Script,
    Variant,
    draw_variant,
    flat_long_size,
    make_script,
    scripted_inputs,
    static_rotations,
    tall_thin_size,
)
from warpskill.synthetic.spoil import (
    NOISE_LEVELS,
    SPOILERS,
    Noise,
    as_annotations,
    box_channels,
    noisy_channels,
    noisy_contact,
    phase_contact,
    visible_boxes,
)

INPUTS = ("masks", "boxes")
"""What a synthetic demonstration's masks are: the true silhouettes spoiled, then cleaned as the
readers clean a segmenter's (``"masks"``, :func:`~warpskill.data.masks.clean_masks`), or
the ellipses inscribed in per-frame boxes of them, as the Something-Else reader makes them
(``"boxes"``; contact from annotator-like phases, scenes with the real videos' situations)."""


SCENARIOS = ("none", "real", "narrow", "turned", "flat", "askew", "relations")
"""Which situations a ``"boxes"`` demonstration adds: the default ones only, also the held-out
real videos' (:func:`real_scenarios`), a static box narrower than the object
(:data:`~warpskill.synthetic.scripts.NARROW_STATIC`) or one turned by up to
:data:`~warpskill.synthetic.scripts.TURNED_STATIC_YAW` (both put actions only), or named objects
on a table filmed low (:mod:`~warpskill.synthetic.relations`: pick-ups and put actions only)."""

STATIC_SCENARIOS = ("narrow", "turned")
"""The scenarios that change the static box: put actions only."""

REAL_SCENARIOS = {
    "stops_early": ("pick_up",),
    "enters_view": ("put_behind", "put_in_front_of", "put_next_to", "put_onto"),
    "static_cut_by_frame": ("put_behind", "put_in_front_of", "put_next_to", "put_onto"),
    "hand_partly_seen": ACTIONS,
    "tall_thin": ("pick_up", "put_behind", "put_in_front_of", "put_next_to", "put_onto"),
}
"""Each real situation and the actions it is mixed into (``tall_thin``: the object is tall
and thin, :data:`~warpskill.synthetic.scripts.TALL_THIN`; the others: :data:`SPOILERS`)."""

MIX_RATE = 0.3
"""Probability of each applicable situation besides the one the seed picks."""


def check_scenarios(scenarios: str, input: str, actions: Sequence[str]) -> None:
    """Refuse ``scenarios`` that cannot apply: an unknown name, any but ``"none"`` without
    box input, :data:`STATIC_SCENARIOS` for an action without a static box.

    Raises:
        ValueError: naming the scenario and what it needs.
    """
    if scenarios not in SCENARIOS or (scenarios != "none" and input != "boxes"):
        raise ValueError(f"scenarios: expected one of {SCENARIOS} (other than 'none' only with input='boxes'), "
                         f"got {scenarios!r} with input={input!r}")
    unplaced = [action for action in actions if not action.startswith("put_")]
    if scenarios in STATIC_SCENARIOS and unplaced:
        raise ValueError(f"scenarios {scenarios!r} changes the static box of put actions; without one: "
                         f"{', '.join(unplaced)} (give put actions only)")
    unrelated = [action for action in actions if action not in RELATION_ACTIONS]
    if scenarios == "relations" and unrelated:
        raise ValueError(f"scenarios 'relations' relates the object to a static or lifts it; not for "
                         f"{', '.join(unrelated)} (give {', '.join(RELATION_ACTIONS)})")


def real_scenarios(action: str, seed: int) -> tuple[str, ...]:
    """The real situations of one demonstration: the applicable one at ``seed`` modulo their
    number, and each other applicable one with probability :data:`MIX_RATE` (seeded)."""
    applicable = [name for name, actions in REAL_SCENARIOS.items() if action in actions]
    rng = np.random.default_rng([seed, ACTIONS.index(action), 2])
    draws = rng.random(len(applicable))
    return tuple(name for i, name in enumerate(applicable) if i == seed % len(applicable) or draws[i] < MIX_RATE)


def make_demonstration(
    action: str,
    *,
    seed: int = 0,
    noise: str | Noise = "moderate",
    image_size: tuple[int, int] = (240, 427),
    fps: float = 12.0,
    duration: float = 4.0,
    input: str = "masks",
    scenarios: str = "none",
) -> Demonstration:
    """A synthetic demonstration of ``action`` with its ground truth in ``demo.truth``.

    Args:
        action: one of :data:`warpskill.contract.actions.ACTIONS`.
        seed: scene randomness (sizes, placements, camera, noise).
        noise: a name in :data:`NOISE_LEVELS` or a :class:`Noise`.
        image_size: (H, W) of the masks [px].
        fps: frame rate [1/s].
        duration: video length [s].
        input: one of :data:`INPUTS`. ``"masks"``: the true silhouettes spoiled by ``noise``
            (jitter, spurious blobs, lost frames), then cleaned as the readers clean a
            segmenter's masks. ``"boxes"``: each channel's mask is the ellipse
            inscribed in the box of its true visible silhouette (box edges jittered by up to
            ``noise.jitter`` px), rasterised by :func:`warpskill.data.boxes.something_else.box_masks`
            as for Something-Else; the contact is an annotator's action phase (from the
            grasp onset to the release; a pick-up's ends once the lift is done or the
            object leaves the view, while the hand still holds it); and the scenes add
            the real videos' situations (:data:`PICK_UP_ENDINGS`, a hand that enters
            through the border, wide static boxes cut by the frame; a put behind leaves
            the moved object partly or wholly hidden by the static box).
        scenarios: one of :data:`SCENARIOS` (``input="boxes"`` only). ``"narrow"`` makes a
            put action's static box narrower than the object and deep, ``"turned"`` turns it by
            up to :data:`~warpskill.synthetic.scripts.TURNED_STATIC_YAW`, ``"flat"`` makes the
            object long, thin and lying flat (:data:`~warpskill.synthetic.scripts.FLAT_LONG`,
            a pen or a fork on the table), ``"askew"`` as well at a yaw of up to
            :data:`~warpskill.synthetic.scripts.ASKEW_OBJECT_YAW`. ``"real"`` mixes in
            the held-out real videos' situations, chosen by :func:`real_scenarios` (a
            deterministic function of action and seed): the spoilers of
            :data:`warpskill.synthetic.spoil.SPOILERS` and tall thin objects; the boxes and
            phases then reach the demonstration through the real reader
            (:func:`~warpskill.data.boxes.something_else.something_else_demonstration`).
            ``"relations"``: named objects and statics at their nouns' sizes, a low camera,
            the spoilers of :data:`~warpskill.synthetic.relations.RELATION_SPOILERS`, through
            the real reader with the nouns as the boxes' categories
            (:func:`~warpskill.synthetic.relations.relation_case`).
    """
    check_action(action)
    if input not in INPUTS:
        raise ValueError(f"input: expected one of {INPUTS}, got {input!r}")
    check_scenarios(scenarios, input, [action])
    chosen = real_scenarios(action, seed) if scenarios == "real" else ()
    relation = relation_case(action, seed) if scenarios == "relations" else None
    noise = NOISE_LEVELS[noise] if isinstance(noise, str) else noise
    rng = np.random.default_rng([seed, ACTIONS.index(action)])
    boxes = input == "boxes"
    variant_rng = np.random.default_rng([seed, ACTIONS.index(action), 1])
    intrinsics = Intrinsics.default(*image_size)
    for attempt in range(50):
        variant = _variant(action, seed, scenarios, chosen, variant_rng) if boxes and not relation else None
        if relation and attempt == 25:  # a static moved out of view that leaves no room for the relation: back in
            relation = replace(relation, variant=replace(relation.variant, static_away=0.0))
        script = make_script(action, rng, duration, relation.variant if relation else variant)
        if relation:
            script = replace(script, camera_elevation=relation.camera_elevation)
        truth = _simulate(script, fps, duration)
        masks = _render(truth, intrinsics)
        if _in_view(masks, partly=boxes, seen=0.5 if relation else 0.8) and (
                not relation or _relation_seen(masks, truth, action)):
            break
    else:  # pragma: no cover - the scripts are built to stay in view
        raise RuntimeError(f"could not place a {action} scene in view")
    truth["action"] = np.array(action)
    truth["camera_K"] = intrinsics.K
    truth["image_size"] = np.array(image_size)
    if boxes:
        contact = noisy_contact(phase_contact(script, truth, masks), replace(noise, contact_flips=0), rng)
        if relation:
            nouns = (relation.object_noun, relation.static_noun)
            return _annotated(visible_boxes(masks, noise, rng), contact, relation.spoilers, rng, fps, action, truth,
                              nouns)
        if chosen:
            return _annotated(visible_boxes(masks, noise, rng), contact, chosen, rng, fps, action, truth)
        hand, obj, static = box_channels(masks, noise, rng)
    else:
        contact = noisy_contact(is_held(truth["grasped"]), noise, rng)
        hand, obj, static = _cleaned(*noisy_channels(masks, noise, rng))
    return Demonstration.from_arrays(
        hand, obj, contact, fps, static_mask=static, camera_K=intrinsics.K, action=action, truth=truth
    )


def _variant(action: str, seed: int, scenarios: str, chosen: tuple[str, ...],
             rng: np.random.Generator) -> Variant:
    """The situations of a ``"boxes"`` scene: drawn (:func:`draw_variant`), then those of ``scenarios``
    and of the real videos' ``chosen`` (:func:`real_scenarios`)."""
    variant = draw_variant(action, seed, rng)
    if "tall_thin" in chosen:
        variant = replace(variant, object_size=tall_thin_size(rng))
    if scenarios == "narrow":
        variant = replace(variant, narrow_static=True, wide_static=0.0)
    if scenarios == "turned":
        variant = replace(variant, static_yaw=TURNED_STATIC_YAW)
    if scenarios in ("flat", "askew"):
        variant = replace(variant, object_size=flat_long_size(rng))
    if scenarios == "askew":
        variant = replace(variant, object_yaw=ASKEW_OBJECT_YAW)
    return variant


def _annotated(boxes, contact, chosen, rng, fps: float, action: str, truth: dict,
               nouns: tuple[str | None, ...] = ()) -> Demonstration:
    """The spoilers in ``chosen`` applied to the boxes (C, N, 4) and action phase (N,), read back
    through the Something-Else reader (the boxes labelled with ``nouns``: object, statics), with
    the ground truth attached."""
    image_size = tuple(int(v) for v in truth["image_size"])
    for name in chosen:
        if name in SPOILERS:
            boxes, contact = SPOILERS[name](boxes, contact, rng, image_size)
    annotations = as_annotations(boxes, contact, action=action, nouns=nouns)
    demo, _ = something_else_demonstration(annotations, image_size=image_size)
    return replace(demo, fps=fps, truth=_first_frames(truth, demo.num_frames))


def _cleaned(hand: np.ndarray, obj: np.ndarray, static: np.ndarray | None):
    """Spoiled masks as the readers hand a segmenter's to the optimiser (:func:`clean_masks`)."""
    statics = None if static is None else np.stack([clean_masks(mask) for mask in static])
    return clean_masks(hand), clean_masks(obj), statics


def _first_frames(truth: dict, n: int) -> dict:
    """The ground truth of the first ``n`` frames (the reader ends a demonstration where its
    annotations stop)."""
    return {key: value[:n] if FIELD_SHAPES[key][:1] == ("N",) else value for key, value in truth.items()}


def _simulate(script: Script, fps: float, duration: float) -> dict[str, np.ndarray]:
    """Run the engine on a script; returns the ground truth reconstruction fields."""
    inputs, options = scripted_inputs(script, fps, duration)
    out = simulate(inputs, **options)
    num_frames = out.hand_pos.shape[1]
    K = len(script.static_pos)
    n = lambda x: x[0].detach().numpy()  # noqa: E731
    return {
        "fps": np.array(fps),
        "t": np.arange(num_frames) / fps,
        "hand_pos": n(out.hand_pos),
        "hand_rot": n(out.hand_rot),
        "grasp": n(out.grasp),
        "grasped": n(out.grasped),
        "object_pos": n(out.object_pos),
        "object_rot": n(out.object_rot),
        "object_size": script.object_size,
        "static_pos": script.static_pos.reshape(K, 3),
        "static_rot": static_rotations(script),
        "static_size": script.static_size.reshape(K, 3),
        "camera_elevation": np.array(script.camera_elevation),
        "camera_height": np.array(script.camera_height),
        "loss": np.array(0.0),
    }


def _render(truth: dict[str, np.ndarray], intrinsics: Intrinsics) -> np.ndarray:
    """Exact visible masks (N, 2 + K, H, W) of the true scene."""
    cuboid_pos, cuboid_rot, cuboid_size = scene_cuboids(SimpleNamespace(**truth))
    return raycast_masks(
        truth["hand_pos"],
        truth["hand_rot"],
        cuboid_pos,
        cuboid_rot,
        cuboid_size,
        float(truth["camera_height"]),
        float(truth["camera_elevation"]),
        intrinsics,
    )


def _relation_seen(masks: np.ndarray, truth: dict, action: str, margin: int = 2) -> bool:
    """Whether a relations scene shows what its action is judged by: the object seen in at
    least half the first half of the frames the hand holds it (a small object can vanish behind
    the model hand; a pick-up may then carry it out of view), and a put action's object ending
    inside the image (its last visible mask keeps ``margin`` px from the border; behind a
    static it may be wholly hidden)."""
    seen = masks[:, 1].reshape(len(masks), -1).any(1)
    held = np.flatnonzero(is_held(truth["grasped"]))
    if len(held) and seen[held[: max(1, len(held) // 2)]].mean() < 0.5:
        return False
    if action == "pick_up":
        return True
    last = masks[-1, 1]
    inner = np.zeros(last.shape, bool)
    inner[margin:-margin, margin:-margin] = True
    return not (last & ~inner).any() and (action == "put_behind" or last.any())


def _in_view(masks: np.ndarray, margin: int = 2, *, partly: bool = False, seen: float = 0.8) -> bool:
    """Whether every cuboid stays inside the image (not touching its border) and is seen.

    ``seen``: the share of frames (the first third where ``partly``) the object must be seen in.
    ``partly``: the object need only be inside the image until it is grasped (it may then
    leave the view with the hand), and static boxes may be cut by the frame.
    """
    cuboids = masks[:, 1:]
    border = np.zeros(masks.shape[-2:], bool)
    border[:margin], border[-margin:], border[:, :margin], border[:, -margin:] = True, True, True, True
    if partly:
        cuboids = cuboids[: max(1, len(cuboids) // 3), :1]
    touches = (cuboids & border).any()
    visible = cuboids.reshape(*cuboids.shape[:2], -1).any(-1)
    return not touches and visible[:, 0].mean() > seen and masks[:, 0].any()


