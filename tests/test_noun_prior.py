"""The size prior of the object's noun: its value and gradient, where it applies, and its pull on the scale."""

import argparse

import numpy as np
import pytest
import torch

from warpskill.bench.synthetic import spread_noun
from warpskill.cli.common import add_optimize_options, optimize_options
from warpskill.contract.nouns import SIZES
from warpskill.optimizer import OptimizeOptions, optimize
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.hypotheses import read_evidence
from warpskill.optimizer.scene import noun_size_prior
from warpskill.optimizer.weights import LossWeights
from warpskill.synthetic import make_demonstration

SMALL = dict(image_size=(60, 107), duration=2.0)


def _scene(size: torch.Tensor):
    return type("S", (), {"object_size": size})()


def test_the_noun_prior_is_the_squared_log_of_the_largest_edge_over_the_typical_one():
    weights = LossWeights(object_noun_size=1.0)

    def prior(size, typical):
        return float(noun_size_prior(_scene(torch.tensor(size, dtype=torch.float64)), weights, typical))

    assert prior([0.03, 0.12, 0.07], 0.12) == pytest.approx(0.0, abs=1e-12)  # only the largest edge counts
    assert prior([0.03, 0.24, 0.07], 0.12) == pytest.approx(weights.object_noun_size * np.log(2.0) ** 2)
    assert prior([0.03, 0.24, 0.07], 0.12) == pytest.approx(prior([0.015, 0.06, 0.035], 0.12))  # symmetric in log
    size = torch.tensor([0.06, 0.11, 0.09], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda s: noun_size_prior(_scene(s), weights, 0.2), (size,))


def test_the_noun_prior_is_on_only_for_an_object_with_a_noun_and_no_known_length():
    weights = LossWeights(object_noun_size=1.0)
    for known_length in (False, True):
        for boxes in (False, True):
            for noun in (False, True):
                scene = weights.for_scene(known_length=known_length, object_from_boxes=boxes, noun_size_known=noun)
                on = noun and not known_length
                assert scene.object_noun_size == (weights.object_noun_size if on else 0.0)
                assert scene.camera_height == weights.for_scene(known_length=known_length,
                                                                object_from_boxes=boxes).camera_height


def test_the_evidence_carries_the_typical_edge_only_where_the_prior_applies():
    config, cpu = OptimizeConfig(weights=LossWeights(object_noun_size=1.0)), torch.device("cpu")
    boxes = make_demonstration("pick_up", seed=1, input="boxes", **SMALL)
    masks = make_demonstration("pick_up", seed=0, **SMALL)  # an upright cuboid's silhouette
    assert read_evidence(boxes, {}, config, cpu, "coffee mugs").typical_edge == SIZES["mug"].edges[-1]
    assert read_evidence(boxes, {}, config, cpu, None).typical_edge is None
    assert read_evidence(boxes, {"object_height": 0.1}, config, cpu, "mug").typical_edge is None
    assert read_evidence(masks, {}, config, cpu, "mug").typical_edge == SIZES["mug"].edges[-1]
    assert read_evidence(masks, {"object_height": 0.1}, config, cpu, "mug").typical_edge is None


def test_an_unknown_noun_adds_no_prior_and_says_so_in_one_line(capsys):
    demo = make_demonstration("pick_up", seed=1, input="boxes", **SMALL)
    small = OptimizeConfig(init_iterations=2, rival_rungs=())
    recon = optimize(demo, progress=False, init_only=True, config=small, object_noun="allumunium ingot")
    plain = optimize(demo, progress=False, init_only=True, config=small)
    assert capsys.readouterr().out.strip().splitlines() == [
        "object noun 'allumunium ingot': no typical size known, so no size prior"]
    np.testing.assert_array_equal(recon.object_size, plain.object_size)
    assert OptimizeOptions.from_json(str(recon.options)).object_noun == "allumunium ingot"


def test_a_noun_beside_a_known_length_adds_no_prior_and_says_so_in_one_line(capsys):
    demo = make_demonstration("pick_up", seed=1, input="boxes", **SMALL)
    small = OptimizeConfig(init_iterations=2, rival_rungs=())
    known = {"object_height": 0.1}
    recon = optimize(demo, progress=False, init_only=True, config=small, object_noun="mug", known=known)
    plain = optimize(demo, progress=False, init_only=True, config=small, known=known)
    assert capsys.readouterr().out.strip().splitlines() == [
        "object noun 'mug': the known object_height fixes the scale, so no size prior"]
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
    size = np.array([0.03, 0.115, 0.08])
    assert spread_noun(size, np.random.default_rng(0), spread=0.0) == "mug"  # the nearest typical size
    rng = np.random.default_rng(1)
    ratios = np.log([SIZES[spread_noun(size, rng)].edges[-1] / size.max() for _ in range(400)])
    assert abs(ratios.mean()) < 0.06 and 0.2 < ratios.std() < 0.4
