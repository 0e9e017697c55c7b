"""Something-Else box annotations to masks, and how well masks sit on people's boxes.

Owns the Something-Else files (:mod:`.something_else`: boxes, phases and actions to a
demonstration, the box labels and the roles they stand for), the real-footage folders of
clips boxed the same way (:mod:`.clips`) and the box IoU of a mask (:mod:`.overlap`).
May import :mod:`warpskill.contract`, the readers (:mod:`warpskill.data.readers`: a clip's
frames) and the shared steps of :mod:`warpskill.data`; never the footage path
(:mod:`warpskill.data.footage`) or the recording.
"""
