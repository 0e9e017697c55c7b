"""Readers of the files people have for a recording, NumPy and OpenCV only.

Owns the mask files (:mod:`.mask_files`: label images and per-object mask folders, and a
video with its masks as a demonstration), the video frames (:mod:`.video`), the outline
drawn on one frame (:mod:`.polygons`: the polygon file or LabelMe) and the contact files
(:mod:`.contact_files`: a detector's detections, or the contact signal itself).
May import :mod:`warpskill.contract`, mask clean-up (:mod:`warpskill.data.masks`) and
contact estimation (:mod:`warpskill.data.contact`); never the box annotations
(:mod:`warpskill.data.boxes`), the footage path (:mod:`warpskill.data.footage`) or the
recording that joins them.
"""
