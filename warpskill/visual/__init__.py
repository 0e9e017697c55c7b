"""Pictures and recordings of results, to judge them by eye.

Owns the pictures (:mod:`.pictures`: the overlay GIF of :mod:`.overlay`, the top view and
trajectory plots of :mod:`.plots`), a demonstration's contact sheet (:mod:`.sheet`) and the
3D Rerun recording (:mod:`.rerun_view`, extra ``viewer``). Colours and video writers come from
the media leaf (:mod:`warpskill.media`).
May import the contract, the engine's renderers and the media leaf; never the optimiser's
internals, nor the robot (the robot's track comes posed, :func:`warpskill.robot.robot_track`).
Names load on first use.
"""

from warpskill.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, globals(), {
    "pictures": ("save_pictures",),
    "sheet": ("contact_sheet",),
    "overlay": ("overlay_frames", "render_labels"),
    "plots": ("top_view_figure", "trajectories_figure"),
    "rerun_view": ("view", "import_rerun"),
})
