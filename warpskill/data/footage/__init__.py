"""The phone-video path: an outline on one frame to masks and contact for the whole clip.

Owns, stage by stage: the hand's landmarks found and followed (:mod:`.hand_landmarks`,
MediaPipe), a hand it missed found by colour and motion (:mod:`.hand_regions`), one hand
chosen per frame and its mask (:mod:`.hands`), the outlined objects followed
(:mod:`.following`) with the sparse corners and every tracking setting
(:mod:`.tracking`), the contact read off the fingertips (:mod:`.touch`), the model hand
drawn along the found hand (:mod:`.model_hand`), the stages chained (:mod:`.clip_masks`),
for an outline that includes the hand, its propagation by dense optical flow
(:mod:`.propagation`), and, without any outline, the outline proposed from the clip
(:mod:`.outline_proposal`, with the frame where no hand hides a touched object,
:mod:`.unhidden_proposal`, and what the hand brought to a release, :mod:`.release_proposal`).
May import :mod:`warpskill.contract`, the nouns leaf (a hand's
size), the readers and the shared steps of :mod:`warpskill.data`; never the box
annotations (:mod:`warpskill.data.boxes`) or the recording.
"""
