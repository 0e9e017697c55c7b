"""Real recordings to a :class:`~warpskill.contract.Demonstration`: NumPy and OpenCV only.

Owns the readers of label images, mask folders and videos (:mod:`.readers`), the
Something-Else box annotations (:mod:`.box_annotations`), mask clean-up (:mod:`.masks`),
contact estimation and the paper's filter (:mod:`.contact`), the propagation of one
annotated frame through a video (:mod:`.propagation`), a phone video outlined without the
hand (:mod:`.footage`: the hand found by :mod:`.hand_landmarks` and :mod:`.hand_regions`,
chosen and masked by :mod:`.hands`, the objects followed by :mod:`.following`), and one's
own recording (a video and one source of masks) to a demonstration with its contact sheet
(:mod:`.recording`). May import :mod:`warpskill.contract`; never torch, Warp, the engine or
the optimiser (MediaPipe, the ``video`` extra, only when the hand is to be found).
"""

from warpskill.data.box_annotations import (
    SomethingElseVideo,
    read_box_annotations,
    read_something_else,
    something_else_demonstration,
)
from warpskill.data.contact import estimate_contact, filter_contact, read_detections
from warpskill.data.following import follow_objects
from warpskill.data.footage import footage_masks
from warpskill.data.hand_landmarks import find_hands
from warpskill.data.masks import clean_masks
from warpskill.data.propagation import propagate_masks, read_labelme, read_polygons
from warpskill.data.readers import (
    read_label_images,
    read_mask_folders,
    read_masks,
    read_video,
    read_video_demonstration,
)
from warpskill.data.recording import contact_sheet, prepare_recording, read_contact, read_recording

__all__ = [
    "SomethingElseVideo",
    "clean_masks",
    "contact_sheet",
    "estimate_contact",
    "filter_contact",
    "find_hands",
    "follow_objects",
    "footage_masks",
    "prepare_recording",
    "propagate_masks",
    "read_contact",
    "read_detections",
    "read_label_images",
    "read_labelme",
    "read_mask_folders",
    "read_masks",
    "read_polygons",
    "read_recording",
    "read_box_annotations",
    "read_something_else",
    "read_video",
    "read_video_demonstration",
    "something_else_demonstration",
]
