"""Typical sizes of the objects named in Something-Else annotations, and of an adult hand.

A prior on the scene's scale: a reconstructed object can be compared with the typical size
of what the annotation calls it (``Demonstration.object_noun``). Sizes are (height, width,
depth) [m] of the object in its usual resting pose: height vertical, width the longer and
depth the shorter horizontal edge. They are typical, rounded values of several hundred
everyday nouns (:mod:`warpskill.nouns.table`, by category); each entry names where
such a size is published. Nouns are matched after :func:`normalise_noun` (case, articles,
plurals), through :data:`ALIASES` (synonyms, annotators' misspellings) and by their head noun
(``water flask`` -> ``flask``, ``piece of paper`` -> ``paper``); an unknown noun has none.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np

from warpskill.nouns.table import ALIASES, CATEGORIES, OPEN_TOPPED


@dataclasses.dataclass(frozen=True)
class TypicalSize:
    """A typical object size and where it comes from.

    Attributes:
        height, width, depth: edges [m] in the usual resting pose (width >= depth).
        source: the publication the size is taken from.
    """

    height: float
    width: float
    depth: float
    source: str

    @property
    def edges(self) -> np.ndarray:
        """(3,) the edges [m], sorted ascending (a cuboid's axes may be permuted)."""
        return np.sort([self.height, self.width, self.depth])


HAND_BREADTH = 0.085
"""[m] typical adult hand breadth (across the knuckles), rounded: men's median 8.7 cm, women's
7.6 cm (S. Pheasant, C. M. Haslegrave, *Bodyspace*, 3rd ed., CRC Press 2006, table of British
adults' hand dimensions; the US Army's ANSUR II survey, Gordon et al. 2014, agrees within 0.5 cm)."""

HAND_LENGTH = 0.19
"""[m] typical adult hand length (wrist crease to middle fingertip), rounded: men's median 18.9
cm, women's 17.4 cm (Pheasant and Haslegrave, *Bodyspace*, 3rd ed., 2006; ANSUR II, 2014).
A real hand; the model's hand cylinder (with the forearm) is
:data:`warpskill.contract.vocabulary.MODEL_HAND_LENGTH`."""

SIZES: dict[str, TypicalSize] = {
    noun: TypicalSize(height / 100, width / 100, depth / 100, source)
    for table in CATEGORIES.values() for noun, (height, width, depth, source) in table.items()
}
"""Noun (normalised) -> its typical size (:data:`~warpskill.nouns.table.CATEGORIES`, in metres)."""

_ARTICLES = re.compile(r"^(?:(?:a|an|the|some|one|two|three|few|several|this|that|these|those|my|your) )+")
_LINK = re.compile(r" (of|with|for) ")
_IRREGULAR = {"knives": "knife", "glasses": "glass", "boxes": "box", "dishes": "dish", "mice": "mouse",
              "tomatoes": "tomato", "potatoes": "potato", "mangoes": "mango", "dominoes": "domino",
              "cookies": "cookie", "loaves": "loaf", "scarves": "scarf", "lenses": "lens"}
_PLURAL_NOUNS = {"sunglasses", "eyeglasses", "chopsticks", "keys", "scissors", "tweezers", "pliers", "tongs",
                 "headphones", "earbuds", "jeans", "pants", "trousers", "shorts", "dice", "lens", "thermos"}
"""Nouns ending in ``s`` that are their own singular (pair nouns, collections)."""


def normalise_noun(text: str) -> str:
    """A noun as annotated, in the form of :data:`SIZES`' keys: lower case, no article or
    surrounding punctuation, single spaces, the head before ``of`` / ``with`` / ``for``
    (``a bottle of water`` -> ``bottle``), the last word singular (``cups`` -> ``cup``)."""
    return _singular_phrase(_LINK.split(_clean(text), maxsplit=1)[0])


def table_noun(noun: str | None) -> str | None:
    """The noun of the table (:data:`SIZES`' key) an annotated noun stands for, or None.

    Tries, each directly and through :data:`ALIASES`: a whole ``X of Y`` phrase (``deck of
    cards``), then ever shorter endings of the head noun (``white coffee mug`` -> ``coffee
    mug`` -> ``mug``, ``water flask`` -> ``flask``), then those of what an ``X of Y`` is made
    of (``piece of paper`` -> ``paper``).
    """
    if not noun:
        return None
    head, link, tail = (_LINK.split(_clean(noun), maxsplit=1) + ["", ""])[:3]
    candidates = [f"{_singular_phrase(head)} of {tail}"] if link == "of" else []
    candidates += _endings(_singular_phrase(head)) + (_endings(normalise_noun(tail)) if link == "of" else [])
    for candidate in candidates:
        candidate = ALIASES.get(candidate, candidate)
        if candidate in SIZES:
            return candidate
    return None


def typical_size(noun: str | None) -> TypicalSize | None:
    """The typical size of an annotated noun (:func:`table_noun`), or None when the table has none."""
    key = table_noun(noun)
    return None if key is None else SIZES[key]


def is_open_topped(noun: str | None) -> bool:
    """Whether an annotated noun names an open vessel held by its rim (:data:`~warpskill.nouns.table.OPEN_TOPPED`:
    a cup, a mug, a bowl ...); False for an unknown noun."""
    return table_noun(noun) in OPEN_TOPPED


def size_ratio(size: np.ndarray, noun: str | None) -> float | None:
    """How many times larger a reconstructed object (edges (3,) [m]) is than its noun's typical
    size: the ratio of the largest edges, as the noun size prior compares them (an object drawn
    from boxes fills its box, so a thin one comes out thick: only its length is measured);
    None for a noun without a typical size."""
    typical = typical_size(noun)
    if typical is None:
        return None
    edges = np.asarray(size, dtype=float)
    if edges.shape != (3,) or not (edges > 0).all():
        raise ValueError(f"size: expected 3 positive edge lengths [m], got {edges}")
    return float(edges.max() / typical.edges[-1])


def _clean(text: str) -> str:
    """Lower case, letters and digits only, single spaces, no leading article."""
    return _ARTICLES.sub("", " ".join(re.sub(r"[^a-z0-9 ]+", " ", text.lower()).split()))


def _singular_phrase(phrase: str) -> str:
    """A phrase with its last word singular."""
    words = phrase.split()
    return " ".join(words[:-1] + [_singular(words[-1])]) if words else ""


def _endings(phrase: str) -> list[str]:
    """A phrase's endings, longest first (``white coffee mug``, ``coffee mug``, ``mug``)."""
    words = phrase.split()
    return [" ".join(words[start:]) for start in range(len(words))]


def _singular(word: str) -> str:
    """An English plural's singular, by the common rules (irregular ones listed)."""
    if word in _PLURAL_NOUNS:
        return word
    if word in _IRREGULAR:
        return _IRREGULAR[word]
    if word.endswith("ies") and len(word) > 4:
        return word[:-3] + "y"
    if word.endswith(("ches", "shes", "xes", "sses")):
        return word[:-2]
    if word.endswith("s") and not word.endswith(("ss", "us")) and len(word) > 3:
        return word[:-1]
    return word
