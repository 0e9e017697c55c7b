"""Typical object sizes by noun: the table, normalisation, lookup and fallbacks, coverage of the annotated clips,
the size ratio, and the noun carried by a demonstration."""

import json
from pathlib import Path

import numpy as np
import pytest
from test_something_else import _label, _messy, _write

from warpskill.contract.demonstration import Demonstration, DemonstrationError
from warpskill.data.boxes.something_else import (
    read_something_else,
    something_else_demonstration,
)
from warpskill.nouns.table import CATEGORIES
from warpskill.nouns.typical import (
    ALIASES,
    HAND_BREADTH,
    HAND_LENGTH,
    SIZES,
    normalise_noun,
    size_ratio,
    typical_size,
)

SHARED = Path(__file__).resolve().parents[2] / "shared"
"""The shared data: the development and real clips' annotations (absent on a bare checkout)."""


@pytest.mark.parametrize("text, noun", [
    ("A Coffee Mug", "coffee mug"), ("cups", "cup"), ("the boxes", "box"), ("Knives", "knife"),
    ("a bottle of water", "bottle"), ("  Remote-Control ", "remote control"), ("batteries", "battery"),
    ("glass", "glass"), ("chopsticks", "chopsticks"), ("the two tomatoes", "tomato"), ("box with pens", "box"),
    ("Headphones", "headphones"), ("T-Shirts", "t shirt"),
])
def test_nouns_are_normalised(text, noun):
    assert normalise_noun(text) == noun


@pytest.mark.parametrize("text, key", [
    ("pen", "pen"), ("apple", "apple"), ("eyeliner", "eyeliner"),  # direct
    ("Mobile Phone", "phone"), ("tecup", "teacup"), ("Sun Glasses", "sunglasses"), ("sharpie", "marker"),  # alias
    ("bananas", "banana"), ("pairs of jeans", "jeans"), ("eggs", "egg"), ("batteries", "battery"),  # plural
    ("an orange", "orange"), ("the remote", "remote"),  # article
    ("a bottle of water", "bottle"), ("piece of paper", "paper"), ("bunch of keys", "keys"),  # 'of'
    ("pair of glasses", "eyeglasses"), ("bar of soap", "soap"), ("deck of cards", "deck of cards"),
    ("water flask", "flask"), ("plastic container", "container"), ("white coffee mugs", "mug"),  # head noun
    ("TV remote", "remote"), ("green toy car", "toy car"), ("allumunium ingot", "ingot"), ("mobile charger", "charger"),
])
def test_nouns_find_their_size_directly_by_alias_or_by_their_head(text, key):
    assert typical_size(text) is SIZES[key]


@pytest.mark.parametrize("text", ["xyzzy", "allumunium", "motorcycle", "case for glasses", "", None])
def test_an_unknown_noun_has_no_typical_size(text):
    assert typical_size(text) is None


def test_every_entry_is_well_formed_and_found_by_its_own_name():
    assert len(SIZES) >= 300 and sum(map(len, CATEGORIES.values())) == len(SIZES)  # no noun in two categories
    for noun, size in SIZES.items():
        assert 0 < size.depth <= size.width and size.height > 0, noun
        assert 5e-5 < size.edges[0] and 0.01 <= size.edges[-1] <= 2.0, noun  # a sheet of paper .. a necktie
        assert 0.001 <= size.depth, noun
        assert size.source.strip(), noun
        assert typical_size(noun) is size, noun
    for alias, noun in ALIASES.items():
        assert alias not in SIZES and noun in SIZES, alias
        assert typical_size(alias) is SIZES[noun], alias
    assert 0.07 < HAND_BREADTH < 0.1 and 0.16 < HAND_LENGTH < 0.21


def test_a_thin_object_has_thin_edges():
    assert SIZES["pen"].edges[0] < 0.02 and SIZES["pen"].edges[-1] > 0.1
    assert SIZES["card"].edges[0] < 0.001 and SIZES["paper"].edges[0] < 0.001
    assert SIZES["plate"].height < 0.03 < SIZES["plate"].depth


@pytest.mark.parametrize("clips", ["something_else_dev", "real_footage"])
def test_every_annotated_noun_of_the_shared_clips_has_a_typical_size(clips):
    path = SHARED / "data" / clips / "annotations.json"
    if not path.exists():
        pytest.skip(f"no shared annotations at {path}")
    nouns = {}
    for video, frames in json.loads(path.read_text()).items():
        placeholders = frames[0].get("gt_placeholders") or [
            label["category"] for label in frames[0]["labels"] if label["gt_annotation"] == "object 0"]
        nouns[video] = placeholders[0]
    assert nouns and [noun for noun in nouns.values() if typical_size(noun) is None] == []


def test_size_ratio_is_the_scale_of_the_largest_edge():
    can, pen = SIZES["can"], SIZES["pen"]
    assert size_ratio(2.2 * np.array([can.width, can.height, can.depth]), "cans") == pytest.approx(2.2)
    # a pen drawn from its box comes out thick: only its length is compared
    assert size_ratio(np.array([0.06, 1.5 * pen.width, 0.05]), "pen") == pytest.approx(1.5)
    assert size_ratio(np.array([0.1, 0.1, 0.1]), "unobtainium") is None
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


def test_the_reader_names_each_static_and_the_file_keeps_it(tmp_path):
    frames = _messy()
    for k in (1, 2, 3):
        frames[k].append(_label("object 1", (200, 100, 260, 140), "book"))
    video = read_something_else(*_write(tmp_path, frames))["7"]
    demo, _ = something_else_demonstration(video)
    assert demo.static_nouns == ("box",)  # the video label's second placeholder, "box"
    for entry in video.frames:
        entry.pop("gt_placeholders")
    assert something_else_demonstration(video)[0].static_nouns == ("book",)  # else its boxes' category
    demo.save(tmp_path / "d.npz")
    assert Demonstration.load(tmp_path / "d.npz").static_nouns == ("box",)
    unnamed = Demonstration.from_arrays(demo.hand_mask, demo.object_mask, demo.contact, demo.fps,
                                        static_mask=demo.static_mask)
    unnamed.save(tmp_path / "unnamed.npz")
    assert Demonstration.load(tmp_path / "unnamed.npz").static_nouns == ()
    with pytest.raises(DemonstrationError, match="static_nouns: 2 noun"):
        Demonstration.from_arrays(demo.hand_mask, demo.object_mask, demo.contact, demo.fps,
                                  static_mask=demo.static_mask, static_nouns=("book", "tray"))
