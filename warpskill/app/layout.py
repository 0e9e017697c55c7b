"""The page (Gradio Blocks): a clip in, its outline drawn or proposed, ``warpskill run``, the results out.

Top to bottom: the clip (a video file or its frames) and the frame to outline; the outline
as the polygon file's text beside the frame it is drawn on (two clicks on the frame box the
chosen role; "Propose" fills it, :mod:`warpskill.app.outline`); the action and the nouns; Run,
with a progress bar over ``warpskill run``'s steps (:mod:`warpskill.app.running`); then the
contact sheet, the overlay, the top view, the robot's replay video and the results folder
as a zip. Errors are one line in a toast; nothing already written is lost.
"""

from __future__ import annotations

from pathlib import Path

import gradio as gr

from warpskill import assets
from warpskill.app import files, outline as outlines
from warpskill.app.running import STEPS, RunSettings, record_replay, run_clip
from warpskill.contract import ACTIONS, DemonstrationError
from warpskill.data import OutlineUnsure

__all__ = ["build_page", "serve"]

EXAMPLE_CLIP, EXAMPLE_OUTLINE = (assets.path(f"examples/own_recording/{name}")
                                 for name in ("pick_up.mp4", "pick_up_polygons.json"))
"""The shipped example (a synthetic textured clip) and its outline, offered on the page."""

INTRODUCTION = """# warpskill: a robot skill from one video
Upload a clip, outline the object (and any static object) on one frame: click two corners on
the frame to box the chosen role, or edit the polygons' text; without a hand polygon the hand
is found in every frame (extra `video`). Pick the action and Run: the steps of `warpskill run`.
"""


def build_page(root: Path) -> gr.Blocks:
    """The page; every file it writes goes under ``root`` (:mod:`warpskill.app.files`)."""
    with gr.Blocks(title="warpskill") as page:
        clip = gr.State(None)  # str: the stored clip, a video file or frames/%04d.png
        pending = gr.State(None)  # [x, y]: the first corner of a box being drawn [px]
        gr.Markdown(INTRODUCTION)
        with gr.Row():
            with gr.Column(scale=2):
                uploads = gr.File(label="clip: a video file, or its frames (several images)", file_count="multiple",
                                  file_types=["video", "image"], elem_id="clip")
                frame = gr.Slider(0, 1, value=0, step=1, label="frame to outline", elem_id="frame")
                role = gr.Radio(list(outlines.ROLES), value=outlines.ROLES[0], label="box on the frame (two clicks)",
                                elem_id="role")
                remove = gr.Button("Remove this polygon", size="sm")
                outline = gr.Textbox(label="outline: the polygon file (docs/formats.md) the run reads", lines=7,
                                     elem_id="outline")
            with gr.Column(scale=3):
                preview = gr.Image(label="the outline on the frame", interactive=False, format="png", height=440,
                                   elem_id="preview")
        with gr.Row():
            action = gr.Dropdown(list(ACTIONS), value="pick_up", label="action", elem_id="action")
            object_noun = gr.Textbox(label="object noun (optional)", placeholder="mug", elem_id="object_noun")
            static_noun = gr.Textbox(label="static object noun (optional, for the proposal)", placeholder="box")
            propose = gr.Button("Propose an outline", elem_id="propose")
        proposal_view = gr.Image(label="what the proposal saw", interactive=False, visible=False, format="png",
                                 elem_id="proposal_view")
        gr.Examples([[[str(EXAMPLE_CLIP)], EXAMPLE_OUTLINE.read_text(), "pick_up"]], [uploads, outline, action],
                    [clip, frame, outline], lambda paths, text, _: _load_clip(root, paths, text), run_on_click=True,
                    cache_examples=False, label="or the example: a synthetic clip of a box picked up")
        with gr.Row():
            iterations = gr.Number(0, label="physics iterations (0: the default)", precision=0, minimum=0,
                                   elem_id="iterations")
            fps = gr.Number(0, label="frame rate [1/s] (0: the video's; 12 for images)", minimum=0)
            robot = gr.Checkbox(True, label="plan and replay on the robot (Franka Panda)")
        run = gr.Button("Run", variant="primary", elem_id="run")
        status = gr.Markdown(elem_id="status")
        with gr.Row():
            sheet = gr.Image(label="contact sheet", type="filepath", interactive=False)
            overlay = gr.Image(label="overlay", type="filepath", interactive=False)
            top_view = gr.Image(label="top view", type="filepath", interactive=False)
        with gr.Row():
            replay_video = gr.Video(label="the robot's replay", interactive=False, elem_id="replay")
            replay_picture = gr.Image(label="the robot's replay (paths: no offscreen renderer)", type="filepath",
                                      interactive=False, visible=False, elem_id="replay_picture")
            results = gr.File(label="results folder (zip)", interactive=False, elem_id="results")
        log = gr.Textbox(label="warpskill run's lines", lines=8, max_lines=30, elem_id="log")

        uploads.upload(lambda paths: _load_clip(root, paths), uploads, [clip, frame, outline])
        frame.change(_set_frame, [frame, outline], outline)
        drawn = [clip, frame, outline, pending]
        outline.change(_preview, drawn, preview)
        preview.select(_click, [clip, frame, outline, role, pending], [outline, pending, preview])
        remove.click(lambda text, chosen: outlines.outline_text(outlines.remove_role(_parsed(text), chosen)),
                     [outline, role], outline)
        propose.click(_propose, [clip, action, fps, object_noun, static_noun], [outline, frame, proposal_view])
        run.click(_run, [clip, outline, action, object_noun, iterations, fps, robot],
                  [status, sheet, overlay, top_view, replay_video, replay_picture, results, log])
    return page


def serve(root: Path, *, host: str = "127.0.0.1", port: int | None = None, open_browser: bool = False,
          block: bool = True) -> gr.Blocks:
    """Serve the page at ``http://host:port`` (port None: Gradio's first free one from 7860),
    its files under ``root``; ``block`` False returns once it is up."""
    page = build_page(root)
    page.launch(server_name=host, server_port=port, inbrowser=open_browser,
                allowed_paths=[str(root), str(EXAMPLE_CLIP.parent)],
                prevent_thread_lock=not block, quiet=not block)
    return page


def _parsed(text: str) -> dict:
    try:
        return outlines.parse_outline(text or "")
    except ValueError as error:
        raise gr.Error(str(error)) from None


def _frames(clip: str | None):
    if clip is None:
        raise gr.Error("upload a clip first: a video file or its frames")
    return files.clip_frames(Path(clip))


def _load_clip(root: Path, paths: list[str] | None, text: str | None = None):
    """Store the uploaded clip; its outline is ``text`` (the example's) or a new one on the middle frame."""
    if not paths:
        return None, gr.update(), text or ""
    try:
        clip = files.store_clip(paths, root)
        frames, _ = files.clip_frames(clip)
    except (DemonstrationError, FileNotFoundError) as error:
        raise gr.Error(str(error)) from None
    drawn = outlines.draft(len(frames) // 2) if text is None else _parsed(text)
    return str(clip), gr.update(maximum=len(frames) - 1, value=drawn["frame"]), outlines.outline_text(drawn)


def _set_frame(index: float, text: str) -> str:
    drawn = _parsed(text)
    drawn["frame"] = int(index)
    return outlines.outline_text(drawn)


def _preview(clip: str | None, index: float, text: str, pending):
    if clip is None:
        return None
    frames, _ = files.clip_frames(Path(clip))
    try:
        drawn = outlines.parse_outline(text or "")
    except ValueError:  # being typed: the frame alone until it parses
        drawn = outlines.draft(int(index))
    return outlines.draw_outline(frames[min(drawn["frame"], len(frames) - 1)], drawn, pending)


def _click(clip: str | None, index: float, text: str, role: str, pending, event: gr.SelectData):
    """A box's first corner, or its second: then the role's polygon is that box."""
    drawn = _parsed(text)
    corner = list(outlines.shown_to_frame(event.index, _frames(clip)[0].shape[1:3]))
    if pending is None:
        return text, corner, _preview(clip, index, text, corner)
    text = outlines.outline_text(outlines.with_box(drawn, role, pending, corner))
    return text, None, _preview(clip, index, text, None)


def _propose(clip: str | None, action: str, fps: float | None, object_noun: str, static_noun: str):
    """The proposed outline; where the clip does not say what to outline, its line and what it saw."""
    frames, clip_fps = _frames(clip)
    path = files.clip_folder(Path(clip)) / "proposed_outline.json"
    try:
        proposed = outlines.propose(frames, action, fps or clip_fps, path, object_noun=object_noun.strip() or None,
                                    static_noun=static_noun.strip() or None)
    except OutlineUnsure as unsure:
        gr.Warning(unsure.line)
        return gr.update(), gr.update(), gr.update(value=unsure.picture, visible=True)
    except ImportError:
        raise gr.Error("finding the hand needs MediaPipe: pip install -e \".[video]\"; or box the object") from None
    except DemonstrationError as error:  # an unknown action, a static noun for an action without a static object
        raise gr.Error(str(error)) from None
    return outlines.outline_text(proposed), gr.update(value=proposed["frame"]), gr.update(value=None, visible=False)


def _run(clip: str | None, text: str, action: str, object_noun: str, iterations: float | None, fps: float | None,
         robot: bool, progress=gr.Progress()):
    """``warpskill run`` in a new folder beside the clip, then the replay video and the zip."""
    _frames(clip)
    _parsed(text)
    if action not in ACTIONS:
        raise gr.Error(f"unknown action {action!r}: choose one of {', '.join(ACTIONS)}")
    out = files.new_folder(files.clip_folder(Path(clip)), "run")
    (out / "outline.json").write_text(text)
    settings = RunSettings(action, object_noun.strip() or None, int(iterations) if iterations else None,
                           fps or None, robot)
    outcome = run_clip(Path(clip), out / "outline.json", out, settings, lambda done, step: progress(done, desc=step))
    if robot:
        progress(len(STEPS) / (len(STEPS) + 1), desc="video: the robot's replay rendered")
    replay = record_replay(out) if robot else None
    plotted = replay is not None and replay.suffix != ".mp4"  # no offscreen renderer: the paths' plot
    shown = {name: str(out / name) if (out / name).is_file() else None
             for name in ("demo.png", "overlay.gif", "top_view.png")}
    return (f"**{outcome.summary}** ({out})", shown["demo.png"], shown["overlay.gif"], shown["top_view.png"],
            gr.update(value=None if replay is None or plotted else str(replay), visible=not plotted),
            gr.update(value=str(replay) if plotted else None, visible=plotted),
            str(files.zip_folder(out)), outcome.log)
