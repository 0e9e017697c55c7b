"""Pictures and recordings of results, to judge them by eye.

Owns the pictures (:mod:`.pictures`: the overlay GIF of :mod:`.overlay`, the top view and
trajectory plots of :mod:`.plots`, colours in :mod:`.palette`), video writing
(:mod:`.media`) and the 3D Rerun recording (:mod:`.rerun_view`, extra ``viewer``). May
import the contract and the engine's renderers; never the optimiser's internals. Names load
on first use, so the media writers come without torch.
"""

from warpskill.lazy import lazy_exports

_EXPORTS = {
    "figure": "media",
    "save_figure": "media",
    "write_video": "media",
    "save_pictures": "pictures",
    "overlay_frames": "overlay",
    "render_labels": "overlay",
    "top_view_figure": "plots",
    "trajectories_figure": "plots",
    "view": "rerun_view",
    "view_folder": "rerun_view",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
