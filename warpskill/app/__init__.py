"""The page: ``warpskill app`` serves a local web page (Gradio, extra ``app``) that runs
``warpskill run`` on a clip.

The top layer beside the command line: it may import every other layer and the command
line's entry point, nothing imports it. Its modules: :mod:`.layout` (the page and its
handlers), :mod:`.outline` (the outline being drawn: the polygon file as text, boxes, its
picture, the proposal), :mod:`.running` (``warpskill run`` in its own process, its lines as
progress, the replay video) and :mod:`.files` (the uploaded clip, the run folders, the zip).
Names load on first use (Gradio only with the page).
"""

from warpskill.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, globals(), {
    "layout": ("build_page", "serve"),
    "running": ("RunSettings", "run_clip", "record_replay"),
})
