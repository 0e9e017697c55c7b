"""Pictures and recordings of results, to judge them by eye.

Owns the overlay GIF, top view and trajectory plots (:mod:`.pictures`), video writing
(:mod:`.media`) and the 3D Rerun recording (:mod:`.rerun_view`, extra ``viewer``). May
import the contract and the engine's renderers; never the optimiser's internals.
"""

from warpskill.visual.media import write_video
from warpskill.visual.pictures import save_pictures

__all__ = ["save_pictures", "write_video"]
