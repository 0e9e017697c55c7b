"""Typical object sizes by noun: normalisation, lookup, the size ratio, and the noun carried by a demonstration."""

import numpy as np
import pytest

from test_something_else import _messy, _write
from warpskill.contract.demonstration import Demonstration, DemonstrationError
from warpskill.contract.nouns import HAND_BREADTH, HAND_LENGTH, SIZES, normalise_noun, size_ratio, typical_size
from warpskill.data.box_annotations import read_something_else, something_else_demonstration


@pytest.mark.parametrize("text, noun", [
    ("A Coffee Mug", "coffee mug"), ("cups", "cup"), ("the boxes", "box"), ("Knives", "knife"),
    ("a bottle of water", "bottle"), ("  Remote-Control ", "remote control"), ("batteries", "battery"),
    ("glass", "glass"), ("chopsticks", "chopsticks"),
])
def test_nouns_are_normalised(text, noun):
    assert normalise_noun(text) == noun


@pytest.mark.parametrize("text, key", [
    ("coffee mug", "mug"), ("white coffee mugs", "mug"), ("Mobile Phone", "phone"), ("TV remote", "remote"),
    ("tecup", "teacup"), ("Sun Glasses", "sunglasses"), ("green toy car", "toy car"), ("a bottle of water", "bottle"),
])
def test_compounds_aliases_and_misspellings_find_their_size(text, key):
    assert typical_size(text) is SIZES[key]


def test_every_size_is_plausible_and_sourced():
    for noun, size in SIZES.items():
        assert 0.0005 < size.height < 0.4 and 0.005 < size.depth <= size.width < 0.4, noun
        assert len(size.source) > 20, noun
    assert 0.07 < HAND_BREADTH < 0.1 and 0.16 < HAND_LENGTH < 0.21


def test_size_ratio_is_the_scale_of_the_largest_edge():
    can, pen = SIZES["can"], SIZES["pen"]
    assert size_ratio(2.2 * np.array([can.width, can.height, can.depth]), "cans") == pytest.approx(2.2)
    # a pen drawn from its box comes out thick: only its length is compared
    assert size_ratio(np.array([0.06, 1.5 * pen.width, 0.05]), "pen") == pytest.approx(1.5)
    assert size_ratio(np.array([0.1, 0.1, 0.1]), "allumunium ingot") is None
    with pytest.raises(ValueError, match="3 positive edge lengths"):
        size_ratio(np.array([0.1, 0.0, 0.1]), "can")


def test_the_reader_gives_the_demonstration_its_object_noun_and_the_file_keeps_it(tmp_path):
    demo, _ = something_else_demonstration(read_something_else(*_write(tmp_path, _messy()))["7"])
    assert demo.object_noun == "cup"
    demo.save(tmp_path / "d.npz")
    assert Demonstration.load(tmp_path / "d.npz").object_noun == "cup"
    older = Demonstration.from_arrays(demo.hand_mask, demo.object_mask, demo.contact, demo.fps)
    older.save(tmp_path / "old.npz")
    assert Demonstration.load(tmp_path / "old.npz").object_noun is None
    with pytest.raises(DemonstrationError, match="object_noun"):
        Demonstration.from_arrays(demo.hand_mask, demo.object_mask, demo.contact, demo.fps, object_noun=3)
