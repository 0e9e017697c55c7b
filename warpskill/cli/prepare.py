"""``warpskill prepare``: one's own video and at most one source of masks to a demonstration file.

Without a mask source the outline is proposed from the video
(:func:`warpskill.data.footage.outline_proposal.propose_outline`) and kept as a polygon file
beside the demonstration, for the user to correct and give back with ``--polygons``; where
the video does not say what to outline, only a picture of what was seen is written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from warpskill import visual  # a lazy package: the contact sheet loads on first use
from warpskill.cli.common import Refused
from warpskill.contract import DemonstrationError
from warpskill.data import MASK_SOURCES, OutlineUnsure, read_recording, write_outline

__all__ = ["add_recording_options", "prepare", "register"]


def register(commands) -> None:
    """Add ``prepare`` to the ``commands`` sub-parsers."""
    parser = commands.add_parser(
        "prepare",
        help="a video and its masks (or one annotated frame, or none) to a demonstration .npz and a contact sheet"
    )
    add_recording_options(parser)
    parser.add_argument("--object-noun", metavar="NOUN",
                        help="what the object is (e.g. mug), saved in the demonstration; without a mask source also "
                             "bounds the proposed outline (its typical size, the hand as a ruler)")
    parser.add_argument("-o", "--out", type=Path, required=True,
                        help="demonstration .npz (docs/formats.md); the contact sheet goes beside it (.png), and "
                             "without a mask source the proposed outline (.outline.json)")
    parser.set_defaults(run=_prepare)


def add_recording_options(parser: argparse.ArgumentParser) -> None:
    """The video, at most one mask source, the contact source, the action, the static object's noun, fps and
    intrinsics (the object's noun is each command's own: ``run`` has it among the optimisation options)."""
    parser.add_argument("video", type=Path,
                        help="the video file (anything OpenCV reads: .mp4, .avi, ...) or numbered frames "
                             "(frames/%%04d.jpg, 12 fps unless --fps)")
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--masks", type=Path, metavar="DIR",
                        help="per-object mask folders DIR/hand/, DIR/object/, DIR/static*/ (one image per frame)")
    source.add_argument("--labels", type=Path, metavar="DIR",
                        help="label images, one per frame (1 hand, 2 object, 3, 4, ... static; DAVIS palette or indices)")
    source.add_argument("--polygons", type=Path, metavar="FRAME.json",
                        help="polygons on one frame (docs/formats.md, or LabelMe), propagated through the video; "
                             "without a hand polygon the hand is found in every frame (extra video)")
    source.add_argument("--boxes", type=Path, metavar="ANNOTS.json", help="Something-Else box annotations")
    parser.add_argument("--video-id", help="the video's id in --boxes (default: the file's only video)")
    parser.add_argument("--frame", type=int, help="the frame --polygons was drawn on (0-based; overrides the file's)")
    contact = parser.add_mutually_exclusive_group()
    contact.add_argument("--contact", type=Path, metavar="CSV", help="per-frame contact, used as given (frame,contact)")
    contact.add_argument("--detections", type=Path, metavar="CSV",
                         help="contact detections (frame,in_contact[,score]), filtered as in the paper")
    parser.add_argument("--action", required=True, help="the action shown (warpskill.ACTIONS), e.g. pick_up")
    parser.add_argument("--static-noun", metavar="NOUN",
                        help="what the (first) static object is (e.g. box), saved in the demonstration; without a "
                             "mask source also bounds the proposed outline (run: --object-noun does the same for "
                             "the object)")
    parser.add_argument("--fps", type=float, help="frame rate (default: the video's)")
    parser.add_argument("--intrinsics", type=float, nargs=4, metavar=("FX", "FY", "CX", "CY"),
                        help="camera intrinsics of the video's frames [px] (default: 80 x 60 deg field of view)")


def prepare(args, demo_path: Path, sheet_path: Path, outline_path: Path | None = None):
    """Read the recording named by ``args``; write the demonstration and its contact sheet (and,
    without a mask source, the proposed outline to ``outline_path``, by default beside the
    demonstration as ``.outline.json``).

    Returns:
        The demonstration and the video's frames.

    Raises:
        Refused: the recording gives no demonstration (its one line names the file and why),
            or finding the hand needs MediaPipe, which is not installed; nothing is written
            but, where the proposed outline is unsure, a picture of what was seen
            (``.unsure.png`` beside the demonstration).
    """
    source = next((name for name in MASK_SOURCES if getattr(args, name) is not None), None)
    try:
        demo, frames, landmarks, proposal = read_recording(
            args.video, masks=args.masks, labels=args.labels, polygons=args.polygons, boxes=args.boxes,
            video_id=args.video_id, contact=args.contact, detections=args.detections, action=args.action,
            fps=args.fps, intrinsics=args.intrinsics, frame=args.frame, object_noun=args.object_noun,
            static_noun=args.static_noun,
        )
    except OutlineUnsure as unsure:
        raise Refused(f"{args.video}: {unsure.line}; what was seen: {_unsure_picture(unsure, demo_path)}") from None
    except (DemonstrationError, ImportError) as error:  # nothing written yet (ImportError: MediaPipe missing)
        raise Refused(str(error)) from None
    demo_path.parent.mkdir(parents=True, exist_ok=True)
    demo.save(demo_path)
    on = demo.contact.nonzero()[0]
    h, w = demo.image_size
    print(f"demonstration: {demo_path} ({demo.action}, {demo.num_frames} frames of {w} x {h} at {demo.fps:g} fps, "
          f"masks from {'--' + source if source else 'the proposed outline'}, {demo.num_static} static; "
          f"contact in {len(on)} frames, {on[0]}..{on[-1]})")
    if proposal is not None:
        outline_path = outline_path or demo_path.with_suffix(".outline.json")
        write_outline(proposal, outline_path)
        print(f"outline: {outline_path} (proposed on frame {proposal.frame}: {', '.join(proposal.polygons)}; "
              f"correct it and give it back with --polygons)")
    if landmarks is not None:
        seen = demo.hand_mask.reshape(demo.num_frames, -1).any(axis=1)
        marked = np.isfinite(landmarks[:, 0, 0])
        print(f"hand: found in {int(seen.sum())} of {demo.num_frames} frames, its landmarks in {int(marked.sum())} "
              f"(MediaPipe's hand landmarker, followed; colour and motion where it sees none)")
    outline = None if proposal is None else (proposal.frame, proposal.polygons)
    print(f"contact sheet: {visual.contact_sheet(demo, frames, sheet_path, landmarks, outline=outline)}")
    return demo, frames


def _unsure_picture(unsure: OutlineUnsure, demo_path: Path) -> Path:
    """What the unsure proposal saw, written beside the demonstration (``.unsure.png``)."""
    picture = demo_path.with_suffix(".unsure.png")
    picture.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(picture), cv2.cvtColor(unsure.picture, cv2.COLOR_RGB2BGR))
    return picture


def _prepare(args) -> int:
    out = args.out if args.out.suffix else args.out.with_suffix(".npz")
    prepare(args, out, out.with_suffix(".png"))
    return 0
