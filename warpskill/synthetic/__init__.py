"""Synthetic demonstrations with ground truth, for the tests, the benchmarks and the demo.

A scripted hand (minimum-jerk moves between waypoints, a grasp signal that rises at the
contact onset and falls at the release; :mod:`.scripts`) drives warpskill's own physics
engine, so the true trajectories obey the same approximate physics the optimiser assumes.
The scene is ray cast into exact masks, then spoiled with the errors real inputs have
(:mod:`.spoil`): jittered boundaries, spurious blobs, missing frames, a contact signal off
by a frame, or per-frame boxes as annotators draw them (:mod:`.generator`). May import the
engine, the contract and the data layer's box masks; never the optimiser.
"""

from warpskill.synthetic.generator import INPUTS, SCENARIOS, check_scenarios, make_demonstration, real_scenarios
from warpskill.synthetic.relations import RELATION_ACTIONS, relation_case
from warpskill.synthetic.scripts import (
    GRASP_LEVEL,
    PICK_UP_ENDINGS,
    TIP_DEPTH,
    scripted_inputs,
    scripted_scene,
)
from warpskill.synthetic.spoil import NOISE_LEVELS, SPOILERS, Noise

__all__ = [
    "GRASP_LEVEL",
    "INPUTS",
    "NOISE_LEVELS",
    "PICK_UP_ENDINGS",
    "RELATION_ACTIONS",
    "SCENARIOS",
    "SPOILERS",
    "TIP_DEPTH",
    "Noise",
    "check_scenarios",
    "make_demonstration",
    "real_scenarios",
    "relation_case",
    "scripted_inputs",
    "scripted_scene",
]
