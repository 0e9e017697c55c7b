"""``optimize``: docs/formats.md output, a physics stage that lowers its loss, determinism, checkpoints, devices."""

import importlib
import subprocess
import sys

import numpy as np
import pytest
import torch

from warpskill.contract.reconstruction import FIELD_SHAPES, Reconstruction
from warpskill.engine.distances import box_signed_distance
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.pipeline import optimize
from warpskill.optimizer.scene import SceneTrajectories
from warpskill.synthetic import make_demonstration

# Every test here runs the optimiser (seconds each).
pytestmark = pytest.mark.slow

# The module itself, for killing a run inside its physics stage (``warpskill.optimize`` may name the function).
optimize_module = importlib.import_module("warpskill.optimizer.pipeline")

SMALL = OptimizeConfig(iterations=8, init_iterations=8)


def _demo(action, seed=0):
    return make_demonstration(action, seed=seed, image_size=(60, 107), duration=2.0)


@pytest.fixture(scope="module")
def pick_up():
    return _demo("pick_up")


@pytest.fixture(scope="module")
def put_onto():
    return _demo("put_onto")


@pytest.fixture(scope="module")
def pick_up_recon(pick_up):
    return optimize(pick_up, config=SMALL, progress=False)


@pytest.fixture(scope="module")
def put_onto_recon(put_onto):
    return optimize(put_onto, config=SMALL, progress=False)


def _kill_physics_at(monkeypatch, iteration: int) -> None:
    """Make the run die in the physics stage's ``iteration``-th objective, as a killed process would."""
    physical_objective = optimize_module.physical_objective
    seen = []

    def dying(*args, **kwargs):
        seen.append(None)
        if len(seen) == iteration:
            raise _Interrupted
        return physical_objective(*args, **kwargs)

    monkeypatch.setattr(optimize_module, "physical_objective", dying)


class _Interrupted(Exception):
    """Stands for a run killed part-way."""


def _assert_same(a: Reconstruction, b: Reconstruction):
    for name in FIELD_SHAPES:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.mark.parametrize("which", ["pick_up", "put_onto"])
def test_reconstruction_has_the_formats_shapes_of_its_demonstration(which, request):
    demo = request.getfixturevalue(which)
    recon = request.getfixturevalue(which + "_recon")
    N, K = demo.num_frames, demo.num_static
    assert K == (1 if which == "put_onto" else 0)
    expected = {
        "t": (N,), "hand_pos": (N, 3), "hand_rot": (N, 3, 3), "grasp": (N,), "grasped": (N,),
        "object_pos": (N, 3), "object_rot": (N, 3, 3), "object_size": (3,),
        "static_pos": (K, 3), "static_rot": (K, 3, 3), "static_size": (K, 3),
        "camera_K": (3, 3), "camera_elevation": (), "camera_height": (), "image_size": (2,),
        "fps": (), "action": (), "object_noun": (), "loss": (), "options": (), "hypotheses": (),
    }
    assert {name: getattr(recon, name).shape for name in FIELD_SHAPES} == expected
    for name in FIELD_SHAPES:
        if name not in ("action", "object_noun", "options", "hypotheses"):
            assert np.all(np.isfinite(getattr(recon, name))), name
    assert sum(judgement["chosen"] for judgement in recon.judgements()) == 1
    np.testing.assert_array_equal(recon.camera_K, demo.intrinsics.K)
    assert tuple(recon.image_size) == demo.image_size == (60, 107)
    assert str(recon.action) == which
    assert float(recon.fps) == demo.fps
    np.testing.assert_allclose(recon.t, np.arange(N) / demo.fps)
    # Rotations are rotations, sizes and the camera physical, statics rest on the ground.
    eye = np.broadcast_to(np.eye(3), (N, 3, 3))
    np.testing.assert_allclose(recon.hand_rot @ recon.hand_rot.swapaxes(1, 2), eye, atol=1e-4)
    np.testing.assert_allclose(recon.object_rot @ recon.object_rot.swapaxes(1, 2), eye, atol=1e-4)
    assert np.all(recon.object_size > 0) and recon.camera_height > 0
    assert np.all((recon.grasped >= 0) & (recon.grasped <= 1))
    np.testing.assert_allclose(recon.static_pos[:, 2], recon.static_size[:, 2] / 2, atol=1e-6)


def test_saving_and_loading_round_trips(pick_up_recon, tmp_path):
    pick_up_recon.save(tmp_path / "recon.npz")
    _assert_same(Reconstruction.load(tmp_path / "recon.npz"), pick_up_recon)


def test_physics_stage_lowers_its_loss(pick_up):
    # With one iteration the stage returns its starting point; the longer run starts there too
    # and reports the best loss it reached, clearly below the start.
    one = optimize(pick_up, config=SMALL, iterations=1, progress=False)
    many = optimize(pick_up, config=SMALL, iterations=30, progress=False)
    assert float(many.loss) < 0.99 * float(one.loss)
    assert not np.allclose(many.object_pos, one.object_pos)


def test_same_seed_gives_identical_results_on_cpu(pick_up, pick_up_recon):
    again = optimize(pick_up, config=SMALL, progress=False, seed=0, device="cpu")
    _assert_same(again, pick_up_recon)


def test_fitting_alike_hypotheses_once_gives_what_fitting_both_gives(monkeypatch):
    # Pulled sideways at one depth: the object's box bottom stays on one row, so "resting
    # depth" and "on the ground" give the same starting scene.
    demo = make_demonstration("pull_right_to_left", seed=1, image_size=(60, 107), duration=2.0)
    alike = optimize(demo, config=SMALL, init_only=True, progress=False)
    # Fitting both gives the same reconstruction (equal losses: the first wins).
    monkeypatch.setattr(SceneTrajectories, "same_as", lambda self, other: False)
    both = optimize(demo, config=SMALL, init_only=True, progress=False)
    _assert_same(alike, both)


def test_init_only_derives_grasped_from_contact_and_the_tip_inside_the_object(pick_up):
    recon = optimize(pick_up, config=SMALL, init_only=True, progress=False)
    assert recon.num_frames == pick_up.num_frames and np.isfinite(recon.loss)
    # The grasp signal is +-margin by the contact signal the run used (the demo's, maybe filtered).
    margin = SMALL.weights.grasp_margin
    np.testing.assert_allclose(np.abs(recon.grasp), margin, rtol=1e-6)
    contact = (recon.grasp > 0).astype(float)
    assert np.mean(contact == pick_up.contact) >= 0.8
    # Grasped: in contact and the hand tip inside the object.
    assert set(np.unique(recon.grasped)) <= {0.0, 1.0}
    assert np.all(recon.grasped <= contact)
    tensors = (torch.as_tensor(a) for a in (recon.hand_pos, recon.object_pos, recon.object_rot, recon.object_size))
    distance = box_signed_distance(*tensors).numpy()
    clear = np.abs(distance) > 1e-5  # float32 in the run, float64 here
    np.testing.assert_array_equal(recon.grasped[clear], (contact * (distance < 0))[clear])
    assert recon.grasped.sum() > 0  # the fit puts the tip in the object in some contact frame


def test_checkpoint_is_written_and_a_finished_run_resumes_without_work(pick_up, pick_up_recon, tmp_path, capsys,
                                                                      monkeypatch):
    monkeypatch.setattr("warpskill.progress.on_terminal", lambda: True)  # the bars are the evidence: drawn into capsys
    path = tmp_path / "ck.pt"
    first = optimize(pick_up, config=SMALL, progress=False, checkpoint=path)
    assert path.is_file() and not path.with_name("ck.pt.partial").exists()
    _assert_same(first, pick_up_recon)  # checkpointing changes nothing
    capsys.readouterr()
    resumed = optimize(pick_up, config=SMALL, progress=True, checkpoint=path)
    _assert_same(resumed, first)
    # Both stages' progress bars open full: nothing is optimised again.
    bars = capsys.readouterr().err
    assert f"| {SMALL.init_iterations}/{SMALL.init_iterations} " in bars and "| 0/" not in bars


def test_an_interrupted_run_resumes_where_its_checkpoint_left_off(pick_up, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("warpskill.progress.on_terminal", lambda: True)  # the bars are the evidence: drawn into capsys
    config = OptimizeConfig(iterations=10, init_iterations=6, checkpoint_every=4)
    reference = optimize(pick_up, config=config, progress=False)
    path = tmp_path / "ck.pt"
    with monkeypatch.context() as patch:
        _kill_physics_at(patch, 7)  # killed in the 7th physics iteration: saved after the 4th
        with pytest.raises(_Interrupted):
            optimize(pick_up, config=config, progress=False, checkpoint=path)
    capsys.readouterr()
    resumed = optimize(pick_up, config=config, progress=True, checkpoint=path)
    # The physics stage's bar opens at the saved iteration, stage (a)'s full, and the run
    # ends where the uninterrupted one ended, bit for bit.
    bars = capsys.readouterr().err
    assert "| 4/10 " in bars and "| 6/6 " in bars and "| 0/" not in bars
    _assert_same(resumed, reference)


def test_checkpoint_of_another_demonstration_is_not_resumed(pick_up, put_onto, put_onto_recon, tmp_path):
    path = tmp_path / "ck.pt"
    optimize(pick_up, config=SMALL, progress=False, checkpoint=path)
    other = optimize(put_onto, config=SMALL, progress=False, checkpoint=path)
    _assert_same(other, put_onto_recon)  # a fresh run's result, not the pick-up's


@pytest.mark.parametrize("damage", ["garbage", "truncated"])
def test_corrupt_checkpoint_is_a_value_error_naming_the_file(damage, pick_up, tmp_path):
    path = tmp_path / "ck.pt"
    if damage == "garbage":
        path.write_bytes(b"\x00not a checkpoint\xff" * 8)
    else:
        optimize(pick_up, config=OptimizeConfig(iterations=1, init_iterations=1), progress=False, checkpoint=path)
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    content = path.read_bytes()
    with pytest.raises(ValueError, match=str(path)):
        optimize(pick_up, config=SMALL, progress=False, checkpoint=path)
    assert path.read_bytes() == content  # and leaves the file for the user to inspect


def test_foreign_torch_file_as_checkpoint_is_a_value_error(pick_up, tmp_path):
    path = tmp_path / "weights.pt"
    torch.save(torch.zeros(3), path)
    with pytest.raises(ValueError, match=str(path)):
        optimize(pick_up, config=SMALL, progress=False, checkpoint=path)


def test_unknown_device_is_refused_naming_it(pick_up):
    with pytest.raises(ValueError, match="tpu7"):
        optimize(pick_up, config=SMALL, progress=False, device="tpu7")


def test_zero_physics_iterations_return_the_initialised_scene(pick_up):
    recon = optimize(pick_up, config=SMALL, iterations=0, progress=False)
    assert np.isfinite(recon.loss) and recon.loss > 0


def test_package_functions_are_not_shadowed_by_their_modules():
    # A fresh interpreter: in this one, whether the name is the module depends on import order.
    code = (
        "import warpskill, warpskill.contract.evaluation, warpskill.optimizer.pipeline\n"
        "print(callable(warpskill.evaluate), callable(warpskill.optimize))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    assert result.stdout.split() == ["True", "True"]
