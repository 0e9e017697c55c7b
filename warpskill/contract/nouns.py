"""Typical sizes of the objects named in Something-Else annotations, and of an adult hand.

A prior on the scene's scale: a reconstructed object can be compared with the typical size
of what the annotation calls it (``Demonstration.object_noun``). Sizes are (height, width,
depth) [m] of the object in its usual resting pose: height vertical, width the longer and
depth the shorter horizontal edge. They are typical, rounded values; each entry names where
such a size is published. Nouns are matched after :func:`normalise_noun` (case, articles,
plurals, annotators' misspellings, compounds such as ``coffee mug`` -> ``mug``).
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np


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
cm, women's 17.4 cm (Pheasant and Haslegrave, *Bodyspace*, 3rd ed., 2006; ANSUR II, 2014)."""

SIZES: dict[str, TypicalSize] = {
    "bottle": TypicalSize(0.21, 0.065, 0.065, "0.5 l PET water bottle, retailers' product pages: about 21 x 6.5 cm"),
    "bowl": TypicalSize(0.065, 0.16, 0.16, "IKEA 365+ bowl, product page (16 cm diameter)"),
    "box": TypicalSize(0.10, 0.15, 0.10, "ISO 3394 package sub-module 150 x 100 mm (height taken as the short side)"),
    "book": TypicalSize(0.025, 0.23, 0.15, "Wikipedia, 'Book size': US trade / octavo 6 x 9 in; 2.5 cm thick"),
    "calculator": TypicalSize(0.014, 0.16, 0.08, "Casio fx-82 series scientific calculator, manufacturer"),
    "can": TypicalSize(0.122, 0.066, 0.066, "Wikipedia, 'Drink can': 355 ml can, 122 mm high, 66 mm diameter"),
    "card": TypicalSize(0.00076, 0.0856, 0.054, "ISO/IEC 7810 ID-1 card: 85.60 x 53.98 x 0.76 mm"),
    "chopsticks": TypicalSize(0.01, 0.24, 0.02, "Wikipedia, 'Chopsticks': 20-27 cm long (pair lying side by side)"),
    "coin": TypicalSize(0.00233, 0.02325, 0.02325, "European Central Bank, 1 euro coin: 23.25 mm diameter, 2.33 mm"),
    "comb": TypicalSize(0.005, 0.18, 0.04, "Wikipedia, 'Comb': a pocket / hair comb, about 18 x 4 cm"),
    "cup": TypicalSize(0.10, 0.085, 0.085, "12 US fl oz (355 ml) paper hot cup, manufacturers' catalogues (Dart/Solo)"),
    "fork": TypicalSize(0.02, 0.19, 0.025, "Wikipedia, 'Fork': a table fork, about 19 cm long"),
    "glass": TypicalSize(0.10, 0.075, 0.075, "Wikipedia, 'Old fashioned glass' / tumbler, 180-300 ml"),
    "glove": TypicalSize(0.02, 0.24, 0.11, "EN 420 (EN ISO 21420) glove size 8: minimum length 240 mm (lying flat)"),
    "key": TypicalSize(0.003, 0.06, 0.025, "Kwikset KW1 / Yale house key blanks, manufacturers: about 6 x 2.5 cm"),
    "keys": TypicalSize(0.02, 0.08, 0.05, "a ring of a few house keys (Kwikset KW1 / Yale blanks, about 6 cm each)"),
    "knife": TypicalSize(0.015, 0.23, 0.02, "Wikipedia, 'Table knife': about 23 cm long"),
    "ladle": TypicalSize(0.08, 0.30, 0.08, "Wikipedia, 'Ladle (spoon)': soup ladle, about 30 cm with an 8 cm bowl"),
    "lighter": TypicalSize(0.014, 0.081, 0.025, "BIC J26 Maxi pocket lighter, manufacturer: about 8.1 x 2.5 x 1.4 cm"),
    "marker": TypicalSize(0.015, 0.14, 0.015, "Sharpie Fine Point permanent marker, manufacturer: about 14 cm long"),
    "mouse": TypicalSize(0.039, 0.099, 0.06, "Logitech M185 wireless mouse, technical specifications: 99 x 60 x 39 mm"),
    "mug": TypicalSize(0.095, 0.115, 0.082, "11 US fl oz ceramic mug blank (sublimation industry standard): "
                       "3.75 in high, 3.25 in diameter; the handle adds about 3 cm"),
    "pen": TypicalSize(0.008, 0.149, 0.008, "BIC Cristal ballpoint pen, manufacturer: 14.9 cm long"),
    "pencil": TypicalSize(0.007, 0.19, 0.007, "Wikipedia, 'Pencil': a standard pencil, 19 cm long"),
    "phone": TypicalSize(0.0077, 0.147, 0.0715, "Apple iPhone 13 technical specifications: 146.7 x 71.5 x 7.65 mm"),
    "plate": TypicalSize(0.02, 0.26, 0.26, "IKEA 365+ / FÄRGRIK dinner plate, product page (26-27 cm diameter)"),
    "remote": TypicalSize(0.025, 0.20, 0.05, "Samsung BN59-series TV remote, retailers' listings: about 20 x 5 cm"),
    "spoon": TypicalSize(0.02, 0.19, 0.04, "Wikipedia, 'Spoon': a table spoon, about 19 cm long"),
    "stapler": TypicalSize(0.05, 0.13, 0.035, "Rapid / Swingline half-strip desk stapler, manufacturers' listings"),
    "sunglasses": TypicalSize(0.045, 0.14, 0.05, "Ray-Ban Wayfarer RB2140 (50 mm), manufacturer: about 14 cm wide"),
    "teacup": TypicalSize(0.065, 0.11, 0.09, "Wikipedia, 'Teacup': 150-250 ml, about 6.5 cm high, 9 cm wide"),
    "toothbrush": TypicalSize(0.02, 0.19, 0.02, "Oral-B manual toothbrush, manufacturer: about 19 cm long"),
    "toy car": TypicalSize(0.03, 0.075, 0.03, "Matchbox / Hot Wheels 1:64 die-cast car, manufacturers: about 7.5 cm"),
    "tube": TypicalSize(0.035, 0.19, 0.05, "75 ml toothpaste tube, retailers' product dimensions (about 19 x 5 cm)"),
    "usb modem": TypicalSize(0.0115, 0.088, 0.028, "Huawei E3372 USB modem, manufacturer: 88 x 28 x 11.5 mm"),
    "wallet": TypicalSize(0.02, 0.115, 0.09, "bifold wallet of ISO/IEC 7810 ID-1 cards (85.6 x 54 mm): 11.5 x 9 cm"),
}
"""Noun (normalised) -> its typical size."""

ALIASES = {
    "cell phone": "phone", "cellphone": "phone", "mobile": "phone", "mobile phone": "phone", "smartphone": "phone",
    "iphone": "phone", "remote control": "remote", "controller": "remote", "tecup": "teacup", "tea cup": "teacup",
    "laddle": "ladle", "sun glass": "sunglasses", "spectacles": "sunglasses", "computer mouse": "mouse",
    "pastry fork": "fork", "ballpoint": "pen", "toy vehicle": "toy car", "tumbler": "glass", "carton": "box",
    "tin": "can", "notebook": "book", "purse": "wallet", "matchbox car": "toy car",
}
"""Other names (and annotators' misspellings) -> the noun of :data:`SIZES`."""

_ARTICLES = ("a ", "an ", "the ", "some ", "one ")
_IRREGULAR = {"knives": "knife", "glasses": "glass", "sunglasses": "sunglasses", "chopsticks": "chopsticks",
              "keys": "keys", "scissors": "scissors", "boxes": "box", "dishes": "dish"}


def normalise_noun(text: str) -> str:
    """A noun as annotated, in the form of :data:`SIZES`' keys: lower case, no article or
    surrounding punctuation, single spaces, the head before ``of`` (``a bottle of water`` ->
    ``bottle``), the last word singular (``cups`` -> ``cup``)."""
    noun = re.sub(r"[^a-z0-9 ]+", " ", text.lower())
    noun = " ".join(noun.split())
    for article in _ARTICLES:
        if noun.startswith(article):
            noun = noun[len(article):]
    noun = noun.split(" of ")[0]
    words = noun.split()
    if words:
        words[-1] = _singular(words[-1])
    return " ".join(words)


def typical_size(noun: str | None) -> TypicalSize | None:
    """The typical size of an annotated noun, or None when the table has none.

    Tries the whole normalised noun, then ever shorter endings of it (``white coffee mug`` ->
    ``coffee mug`` -> ``mug``), each directly and through :data:`ALIASES`.
    """
    if not noun:
        return None
    words = normalise_noun(noun).split()
    for start in range(len(words)):
        candidate = " ".join(words[start:])
        candidate = ALIASES.get(candidate, candidate)
        if candidate in SIZES:
            return SIZES[candidate]
    return None


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


def _singular(word: str) -> str:
    """An English plural's singular, by the common rules (irregular ones listed)."""
    if word in _IRREGULAR:
        return _IRREGULAR[word]
    if word.endswith("ies") and len(word) > 4:
        return word[:-3] + "y"
    if word.endswith(("ches", "shes", "xes", "sses")):
        return word[:-2]
    if word.endswith("s") and not word.endswith(("ss", "us")) and len(word) > 3:
        return word[:-1]
    return word
