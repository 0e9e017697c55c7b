"""The relations scenario: named statics and objects at their nouns' sizes, through the box reader."""

import numpy as np
import pytest

from warpskill.nouns.typical import typical_size
from warpskill.synthetic import make_demonstration
from warpskill.synthetic.relations import CAMERA_ELEVATION, SIZE_SPREAD, relation_case


def _within_spread(size, noun) -> bool:
    typical = typical_size(noun)
    edges = np.array([typical.width, typical.depth, typical.height])
    return bool(np.all(np.abs(np.asarray(size) / edges - 1) <= SIZE_SPREAD + 1e-9))


@pytest.mark.parametrize("seed", [0, 1])
def test_put_onto_case_carries_nouns_sizes_and_ends_on_the_static(seed):
    case = relation_case("put_onto", seed)
    demo = make_demonstration("put_onto", seed=seed, input="boxes", scenarios="relations")
    truth = demo.truth
    assert demo.object_noun == case.object_noun  # the noun reached the demonstration through the reader
    assert _within_spread(truth["object_size"], case.object_noun)
    assert _within_spread(truth["static_size"][0], case.static_noun)
    assert CAMERA_ELEVATION[0] <= float(truth["camera_elevation"]) <= CAMERA_ELEVATION[1]
    # Released over the static, the object rests on its top face: its bottom at the top's height.
    bottom = truth["object_pos"][-1, 2] - truth["object_size"][2] / 2
    assert bottom == pytest.approx(truth["static_size"][0, 2], abs=0.01)


def test_pick_up_lifts_a_flat_object_and_keeps_it_in_view():
    demo = make_demonstration("pick_up", seed=1, input="boxes", scenarios="relations")
    truth = demo.truth
    assert truth["object_size"][2] < 0.02  # a flat object (a card, a phone, a key...)
    assert truth["object_pos"][:, 2].max() - truth["object_pos"][0, 2] > 0.08
    assert demo.object_mask[0].any()


def test_relations_refuse_pushes_with_the_actions_they_take():
    with pytest.raises(ValueError, match="relations.*push_left_to_right"):
        make_demonstration("push_left_to_right", input="boxes", scenarios="relations")
