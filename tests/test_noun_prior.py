"""The size prior of the object's noun: its value and gradient, where it applies, and its pull on the scale."""

import argparse

import numpy as np
import pytest
import torch

from warpskill.bench.synthetic import spread_noun
from warpskill.cli.common import add_optimize_options, optimize_options
from warpskill.nouns.typical import SIZES
from warpskill.optimizer import OptimizeOptions, optimize
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.hypotheses import read_evidence
from warpskill.optimizer.scene import MIN_OBJECT_SIZE, MIN_STATIC_SIZE, noun_size_prior, static_noun_size_prior
from warpskill.optimizer.weights import LossWeights
from warpskill.synthetic import make_demonstration

SMALL = dict(image_size=(60, 107), duration=2.0)


def _scene(size: torch.Tensor):
    return type("S", (), {"object_size": size})()


def test_the_noun_prior_sums_the_squared_logs_of_the_sorted_edges_over_the_typical_ones():
    weights = LossWeights(object_noun_size=1.0)
    typical = (0.03, 0.07, 0.12)

    def prior(size, edges=typical):
        return float(noun_size_prior(_scene(torch.tensor(size, dtype=torch.float64)), weights, edges))

    assert prior([0.03, 0.12, 0.07]) == pytest.approx(0.0, abs=1e-12)  # whatever the axes
    assert prior([0.03, 0.24, 0.07]) == pytest.approx(np.log(2.0) ** 2)  # the longest edge twice as long
    assert prior([0.06, 0.24, 0.14]) == pytest.approx(3 * np.log(2.0) ** 2)  # every edge twice as long
    assert prior([0.06, 0.24, 0.14]) == pytest.approx(prior([0.015, 0.06, 0.035]))  # symmetric in log
    assert prior([0.07, 0.12, 0.07]) > prior([0.03, 0.12, 0.07])  # a thick fork costs more than a thin one
    size = torch.tensor([0.06, 0.11, 0.09], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda s: noun_size_prior(_scene(s), weights, typical), (size,))


def test_the_static_noun_prior_sums_over_the_named_statics_and_its_gradient_checks():
    weights = LossWeights(static_noun_size=1.0)
    book, box = (0.025, 0.15, 0.23), (0.1, 0.1, 0.15)

    def prior(sizes, edges):
        scene = type("S", (), {"static_size": torch.tensor(sizes, dtype=torch.float64)})()
        return float(static_noun_size_prior(scene, weights, edges))

    assert prior([[0.23, 0.15, 0.025], [0.3, 0.3, 0.3]], (book, None)) == pytest.approx(0.0, abs=1e-12)
    assert prior([[0.23, 0.15, 0.05], [0.1, 0.15, 0.1]], (book, box)) == pytest.approx(np.log(2.0) ** 2)
    sizes = torch.tensor([[0.2, 0.1, 0.04], [0.12, 0.08, 0.2]], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(
        lambda s: static_noun_size_prior(type("S", (), {"static_size": s})(), weights, (book, box)), (sizes,))


def test_the_evidence_carries_the_statics_typical_edges_from_their_nouns_where_the_prior_is_on():
    config, cpu = OptimizeConfig(weights=LossWeights(static_noun_size=2.0)), torch.device("cpu")
    demo = make_demonstration("put_onto", seed=0, input="boxes", scenarios="relations")
    edges = read_evidence(demo, {}, config, cpu, demo.object_noun).static_typical_edges
    typical = sorted(max(edge, MIN_STATIC_SIZE) for edge in SIZES[demo.static_nouns[0]].edges)
    assert len(edges) == 1 and edges[0] == pytest.approx(typical)
    assert read_evidence(demo, {"object_height": 0.1}, config, cpu, demo.object_noun).static_typical_edges == ()
    unnamed = make_demonstration("put_onto", seed=0, input="boxes", **SMALL)
    assert read_evidence(unnamed, {}, config, cpu, None).static_typical_edges == ()
    assert read_evidence(demo, {}, OptimizeConfig(), cpu, demo.object_noun).static_typical_edges == ()  # off by default


def test_the_noun_prior_is_on_only_for_an_object_with_a_noun_and_no_known_length():
    weights = LossWeights(object_noun_size=1.0)
    for known_length in (False, True):
        for boxes in (False, True):
            for noun in (False, True):
                scene = weights.for_scene(known_length=known_length, object_from_boxes=boxes, noun_size_known=noun)
                on = noun and not known_length
                share = 1.0 if boxes else weights.masks_noun_share  # a silhouette's hand width measures the scale
                assert scene.object_noun_size == (weights.object_noun_size * share if on else 0.0)
                assert scene.camera_height == weights.for_scene(known_length=known_length,
                                                                object_from_boxes=boxes).camera_height


def test_the_evidence_carries_the_typical_edges_only_where_the_prior_applies():
    config, cpu = OptimizeConfig(weights=LossWeights(object_noun_size=1.0)), torch.device("cpu")
    boxes = make_demonstration("pick_up", seed=1, input="boxes", **SMALL)
    masks = make_demonstration("pick_up", seed=0, **SMALL)  # an upright cuboid's silhouette
    mug = tuple(SIZES["mug"].edges)
    assert read_evidence(boxes, {}, config, cpu, "coffee mugs").typical_edges == pytest.approx(mug)
    assert read_evidence(boxes, {}, config, cpu, None).typical_edges is None
    assert read_evidence(boxes, {"object_height": 0.1}, config, cpu, "mug").typical_edges is None
    assert read_evidence(masks, {}, config, cpu, "mug").typical_edges == pytest.approx(mug)
    assert read_evidence(masks, {"object_height": 0.1}, config, cpu, "mug").typical_edges is None
    paper = read_evidence(boxes, {}, config, cpu, "sheet of paper").typical_edges  # 0.1 mm thick
    assert paper[0] == MIN_OBJECT_SIZE and paper[1:] == pytest.approx(tuple(SIZES["paper"].edges[1:]))


def test_an_unknown_noun_adds_no_prior_and_says_so_in_one_line(caplog):
    demo = make_demonstration("pick_up", seed=1, input="boxes", **SMALL)
    small = OptimizeConfig(init_iterations=2, rival_rungs=())
    recon = optimize(demo, progress=False, init_only=True, config=small, object_noun="unobtainium brick")
    plain = optimize(demo, progress=False, init_only=True, config=small)
    assert caplog.messages == ["object noun 'unobtainium brick': no typical size known, so no size prior"]
    np.testing.assert_array_equal(recon.object_size, plain.object_size)
    assert OptimizeOptions.from_json(str(recon.options)).object_noun == "unobtainium brick"


def test_a_noun_beside_a_known_length_adds_no_prior_and_says_so_in_one_line(caplog):
    demo = make_demonstration("pick_up", seed=1, input="boxes", **SMALL)
    small = OptimizeConfig(init_iterations=2, rival_rungs=())
    known = {"object_height": 0.1}
    recon = optimize(demo, progress=False, init_only=True, config=small, object_noun="mug", known=known)
    plain = optimize(demo, progress=False, init_only=True, config=small, known=known)
    assert caplog.messages == ["object noun 'mug': the known object_height fixes the scale, so no size prior"]
    np.testing.assert_array_equal(recon.object_size, plain.object_size)


def test_the_command_line_noun_reaches_the_options():
    parser = argparse.ArgumentParser()
    add_optimize_options(parser)
    assert optimize_options(parser.parse_args(["--object-noun", "mug"])).object_noun == "mug"
    assert optimize_options(parser.parse_args([])).object_noun is None
    with pytest.raises(TypeError, match="object_noun must be a string"):
        OptimizeOptions(object_noun=3)


@pytest.mark.slow
def test_a_given_noun_pulls_a_box_fit_toward_its_typical_size():
    # Boxes leave the scale open; stage (a) with a noun far larger than the object (a ladle)
    # and with one far smaller (a coin) against the fit without a noun.
    demo = make_demonstration("pick_up", seed=1, input="boxes", **SMALL)
    config = OptimizeConfig(init_iterations=60, weights=LossWeights(object_noun_size=1.0))

    def largest(noun):
        return float(optimize(demo, progress=False, init_only=True, config=config, object_noun=noun).object_size.max())

    plain = largest(None)
    assert largest("ladle") > 1.2 * plain
    assert largest("coin") < plain / 1.2


def test_synthetic_nouns_are_right_on_average_and_spread_like_real_objects():
    size = np.array([0.095, 0.115, 0.082])
    assert spread_noun(size, np.random.default_rng(0), spread=0.0) == "mug"  # the nearest typical size
    rng = np.random.default_rng(1)
    ratios = np.log([SIZES[spread_noun(size, rng)].edges[-1] / size.max() for _ in range(400)])
    assert abs(ratios.mean()) < 0.1 and 0.2 < ratios.std() < 0.45


@pytest.mark.slow
def test_a_long_thin_object_lying_flat_comes_out_flat_and_long_with_its_noun():
    # A pen-like object pushed across the table, seen through boxes (which show neither its
    # depth nor how thin it is): its noun's three edges make the first stage's cuboid lie flat
    # and long, as it is; without a noun the same boxes give a short block.
    demo = make_demonstration("push_left_to_right", seed=1, input="boxes", scenarios="flat", image_size=(120, 214))
    truth = np.sort(demo.truth["object_size"])
    assert truth[0] < 0.03 and truth[2] > 3 * truth[1]

    def edges(noun):
        return np.sort(optimize(demo, progress=False, init_only=True, object_noun=noun).object_size)

    pen, plain = edges("pen"), edges(None)
    assert pen[0] < 0.02 and pen[2] > 3 * pen[1] and abs(np.log(pen[2] / truth[2])) < 0.25
    assert plain[2] < 2 * plain[1]  # without the noun: no longer than a block
