"""Real recordings to a :class:`~warpskill.contract.Demonstration`: NumPy and OpenCV only.

Three pipelines, one subpackage each, over two shared steps:

- :mod:`.readers`: the files people have: label images and mask folders, videos, the
  outline polygons drawn on one frame, contact and detection files;
- :mod:`.boxes`: Something-Else box annotations (and real clips boxed the same way) to
  masks, and how well masks sit on boxes;
- :mod:`.footage`: a phone video outlined on one frame: the hand found (landmarks,
  regions), the objects followed, the contact read off the fingertips, or an outline
  with the hand propagated by optical flow; and, with no outline at all, one proposed
  from the video (:mod:`.footage.outline_proposal`);
- shared by all three: mask clean-up (:mod:`.masks`) and contact estimation with the
  paper's filter (:mod:`.contact`);
- :mod:`.recording`: one's own recording (a video and at most one source of masks) to a
  demonstration, joining the three.

May import :mod:`warpskill.contract` and the nouns leaf; never torch, Warp, the engine or
the optimiser (MediaPipe, the ``video`` extra, only when the hand is to be found). The
names below are the package's public API; the subpackages' modules hold the rest.
"""

from warpskill.data.boxes.something_else import (
    SomethingElseVideo,
    read_box_annotations,
    read_something_else,
    something_else_demonstration,
)
from warpskill.data.contact import estimate_contact, filter_contact
from warpskill.data.footage.clip_masks import footage_masks
from warpskill.data.footage.following import follow_objects
from warpskill.data.footage.hand_landmarks import find_hands
from warpskill.data.footage.outline_proposal import OutlineProposal, OutlineUnsure, propose_outline, write_outline
from warpskill.data.footage.propagation import propagate_masks
from warpskill.data.masks import clean_masks
from warpskill.data.readers.contact_files import read_contact, read_detections
from warpskill.data.readers.mask_files import (
    read_label_images,
    read_mask_folders,
    read_masks,
    read_video_demonstration,
)
from warpskill.data.readers.polygons import read_labelme, read_polygons
from warpskill.data.readers.video import is_image_sequence, read_video
from warpskill.data.recording import IMAGE_SEQUENCE_FPS, MASK_SOURCES, prepare_recording, read_recording

__all__ = [
    "IMAGE_SEQUENCE_FPS",
    "MASK_SOURCES",
    "OutlineProposal",
    "OutlineUnsure",
    "SomethingElseVideo",
    "clean_masks",
    "estimate_contact",
    "filter_contact",
    "find_hands",
    "follow_objects",
    "footage_masks",
    "is_image_sequence",
    "prepare_recording",
    "propagate_masks",
    "propose_outline",
    "read_box_annotations",
    "read_contact",
    "read_detections",
    "read_label_images",
    "read_labelme",
    "read_mask_folders",
    "read_masks",
    "read_polygons",
    "read_recording",
    "read_something_else",
    "read_video",
    "read_video_demonstration",
    "something_else_demonstration",
    "write_outline",
]
