"""Loss weights of both optimisation stages, in one place."""

from __future__ import annotations

from dataclasses import dataclass, replace


@dataclass(frozen=True)
class LossWeights:
    """Weights of the optimisation losses (the paper's defaults where it gives them).

    Perceptual weights multiply a per-frame mean dIoU; the others multiply per-frame means
    of squared quantities in SI units (m, m/s, rad/s).
    """

    hand: float = 1.0  #: perceptual, hand
    object: float = 10.0  #: perceptual, manipulated object
    static: float = 2.0  #: perceptual, each static object
    hand_velocity: float = 1e-3  #: |v_h|^2 + |w_h|^2 per frame
    invisible_object_velocity: float = 1.0  #: |V_o|^2 + |W_o|^2 in frames without an object mask
    contact_distance: float = 1e4  #: tip outside the object in contact frames [m^-2]
    grasp: float = 1e3  #: grasp signal of the wrong sign [m^-2]
    grasp_margin: float = 0.008  #: [m] depth of the tip in the object, and |g|, asked for (8 tau: s > 0.9996)
    stability: float = 1.0  #: object speed before and after the video
    smoothness: float = 1e-4  #: stage (a): squared accelerations
    resting: float = 0.1  #: stage (a): object speed without contact
    penetration: float = 1e3  #: stage (a): below-ground depth
    camera_height: float = 0.5  #: log(camera height / typical_camera_height)^2, both stages (see :meth:`for_scene`)
    typical_camera_height: float = 0.45  #: [m] a table filmed by a person standing or sitting at it
    object_footprint: float = 0.5  #: log(object depth / width)^2, both stages (see :meth:`for_scene`)
    #: sum over the object's edges, sorted, of log(edge / its noun's typical edge)^2
    #: (dimensionless: ratios of lengths), both stages, for an object drawn from boxes (see
    #: :meth:`for_scene`); 2 is a log-normal prior of spread 0.5 per edge, four times the
    #: camera-height prior it pulls against: objects of one name differ by about 0.3 in log,
    #: camera heights far more (docs/results-history.md).
    object_noun_size: float = 2.0
    #: the same for each static object whose noun is known (a book, a box): boxes show
    #: neither its depth nor, where the frame cuts it, its hidden extent. Off by default: at
    #: 2 it brings the statics to their size (relations set: 2.9 -> 1.4 cm median error) but
    #: moves the object no nearer its truth and lost a development video's put onto
    #: (docs/results-history.md); ``--set config.weights.static_noun_size=2`` turns it on
    static_noun_size: float = 0.0
    #: the share of ``object_noun_size`` kept where the masks are true silhouettes: there
    #: the hand's apparent width measures the scale, and the noun only backs it up
    masks_noun_share: float = 0.25

    def for_scene(self, *, known_length: bool, object_from_boxes: bool, noun_size_known: bool = False,
                  static_noun_known: bool = False) -> "LossWeights":
        """These weights with each prior on only where it has something to decide.

        Camera height (``camera_height``, around ``typical_camera_height`` [m]): the masks
        leave the scene's scale open, and this prior decides it. It is off where a known
        length fixes the scale, unless the object is drawn from boxes: a box shows nothing
        of the object's depth, so with its height fixed a deeper, wider object farther away
        draws the same box, and the scale is open again.

        Object footprint (``object_footprint``, depth about equal to width): on only for an
        object drawn from boxes with a known length, where the box fixes neither the
        object's depth nor, through it, its distance. A true silhouette shows the depth
        through the top face, and without a known length the camera-height prior already
        holds the scale; there the footprint prior only pulls real objects away from their
        shape (docs/results-history.md has the measurements behind both rules).

        Object noun size (``object_noun_size``, the edges about its noun's typical ones,
        :mod:`warpskill.nouns.typical`): on wherever no length is known, the images
        then leaving the scale open; at ``masks_noun_share`` of its weight where the masks
        are true silhouettes, whose hand width measures the scale. The camera-height prior
        stays on beside it, weaker: together they pull toward the scale both make likely. A
        known length fixes the scale better than a typical size. Static noun size
        (``static_noun_size``): the same rule for the statics whose noun has a typical size.

        Args:
            known_length: a length of the scene is known (``known=``).
            object_from_boxes: the object's masks are drawn from boxes.
            noun_size_known: the object's noun has a typical size.
            static_noun_known: some static object's noun has a typical size.
        """
        share = 1.0 if object_from_boxes else self.masks_noun_share
        return replace(self, camera_height=0.0 if known_length and not object_from_boxes else self.camera_height,
                       object_footprint=self.object_footprint if known_length and object_from_boxes else 0.0,
                       object_noun_size=0.0 if known_length or not noun_size_known else self.object_noun_size * share,
                       static_noun_size=0.0 if known_length or not static_noun_known else self.static_noun_size * share)
