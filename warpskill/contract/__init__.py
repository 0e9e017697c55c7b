"""The data contract (``docs/formats.md``): the files warpskill reads and writes, in NumPy only.

Owns the demonstration and reconstruction files (:class:`Demonstration`,
:class:`Reconstruction`, their ``.npz`` I/O and checks), the action names, the camera
intrinsics, the contact-signal filter, the frames the optimiser fits of a fast video
(:func:`at_optimiser_rate`), the paper's success criteria (:func:`evaluate`), the
skill and layout records (:class:`Skill`, :class:`Layout`) and the scene's vocabulary
(:mod:`.vocabulary`: the masks' role names, the model hand's size).
May import NumPy and the standard library only: loading a file, judging a reconstruction
or reading annotations never pulls in torch or Warp.
"""

from warpskill.contract.actions import ACTIONS, check_action, has_static_object
from warpskill.contract.camera import Intrinsics, default_intrinsics
from warpskill.contract.demonstration import Demonstration, DemonstrationError
from warpskill.contract.evaluation import Evaluation, evaluate, success_table
from warpskill.contract.frame_rate import at_optimiser_rate, frame_stride
from warpskill.contract.reconstruction import Reconstruction, ReconstructionError
from warpskill.contract.replay import Replay
from warpskill.contract.results_folder import ResultsFolder, ResultsFolderError
from warpskill.contract.signals import majority_filter
from warpskill.contract.skill import Layout, LayoutError, Skill, SkillError

__all__ = [
    "ACTIONS",
    "Demonstration",
    "DemonstrationError",
    "Evaluation",
    "Intrinsics",
    "Layout",
    "LayoutError",
    "Reconstruction",
    "ReconstructionError",
    "Replay",
    "ResultsFolder",
    "ResultsFolderError",
    "Skill",
    "SkillError",
    "at_optimiser_rate",
    "check_action",
    "default_intrinsics",
    "evaluate",
    "frame_stride",
    "has_static_object",
    "majority_filter",
    "success_table",
]
