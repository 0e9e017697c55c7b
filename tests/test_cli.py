"""The ``warpskill`` command line, run in-process: outputs, exit statuses and one-line errors."""

import contextlib
import io
import logging
import re
import shutil

import imageio.v3 as iio
import numpy as np
import pytest

import warpskill.synthetic
from warpskill.cli import main
from warpskill.cli.common import hypothesis_lines
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import FIELD_SHAPES, Reconstruction
from warpskill.synthetic import make_demonstration

PICTURES = ("overlay.gif", "top_view.png", "trajectories.png")
SMALL_DEMO = dict(image_size=(60, 107), duration=2.0)


@pytest.fixture(scope="module")
def demo_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("demo") / "demo.npz"
    make_demonstration("pick_up", seed=0, **SMALL_DEMO).save(path)
    return path


@pytest.fixture(scope="module")
def optimized(demo_file, tmp_path_factory):
    """One ``warpskill optimize`` run: (its folder, exit status, stdout, stderr)."""
    out = tmp_path_factory.mktemp("optimized") / "out"
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main(["optimize", str(demo_file), "-o", str(out), "--iterations", "4", "--quiet"])
    return out, status, stdout.getvalue(), stderr.getvalue()


def _snapshot(folder):
    return {path.relative_to(folder): path.read_bytes() for path in folder.rglob("*") if path.is_file()}


def _evaluation_line(stdout: str, action: str, *, replayed: bool = False) -> str:
    """The verdict line of the reconstruction (the first), or of the replay (after ``replay:``)."""
    lines = stdout.splitlines()
    verdicts = [k for k, line in enumerate(lines) if line.startswith(f"{action}: ")]
    replays = [k for k, line in enumerate(lines) if line.startswith("replay: ")]
    assert len(verdicts) == 1 + len(replays), stdout
    if replayed:
        assert replays and verdicts[-1] > replays[-1], stdout
        return lines[verdicts[-1]]
    return lines[verdicts[0]]


@pytest.mark.slow
def test_optimize_writes_the_reconstruction_pictures_and_evaluation(optimized, demo_file):
    out, status, stdout, stderr = optimized
    assert status == 0
    demo = Demonstration.load(demo_file)
    recon = Reconstruction.load(out / "reconstruction.npz")
    assert recon.num_frames == demo.num_frames and tuple(recon.image_size) == demo.image_size
    assert str(recon.action) == "pick_up"
    np.testing.assert_array_equal(recon.camera_K, demo.intrinsics.K)
    assert (out / "checkpoint.pt").is_file()
    assert f"reconstruction: {out / 'reconstruction.npz'}" in stdout.splitlines()
    for name in PICTURES:
        assert f"{name.split('.')[0]}: {out / name}" in stdout.splitlines()
    assert iio.imread(out / "overlay.gif").shape[0] == demo.num_frames
    for name in ("top_view.png", "trajectories.png"):
        image = iio.imread(out / name)
        assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    assert re.fullmatch(r"pick_up: (success|failure \(.+\))", _evaluation_line(stdout, "pick_up"))
    judged = recon.judgements()
    assert sum(item["chosen"] for item in judged) == 1
    assert set(hypothesis_lines(judged)) <= set(stdout.splitlines())
    assert ("hypotheses (fit:" in stdout) == (len(judged) > 1)  # a table only where there was a choice
    assert "initialisation" not in stderr and "physics" not in stderr  # --quiet: no progress bars


@pytest.mark.slow
def test_rerun_in_the_same_folder_resumes_and_no_pictures_skips_them(
    optimized, demo_file, tmp_path, capsys, monkeypatch
):
    monkeypatch.setattr("warpskill.progress.on_terminal", lambda: True)  # the bars are the evidence: drawn into capsys
    out = tmp_path / "out"
    shutil.copytree(optimized[0], out)
    before = Reconstruction.load(out / "reconstruction.npz")
    for name in PICTURES:
        (out / name).unlink()
    status = main(["optimize", str(demo_file), "-o", str(out), "--iterations", "4", "--no-pictures"])
    assert status == 0
    after = Reconstruction.load(out / "reconstruction.npz")
    for name in FIELD_SHAPES:
        np.testing.assert_array_equal(getattr(after, name), getattr(before, name), err_msg=name)
    assert not any((out / name).exists() for name in PICTURES)
    captured = capsys.readouterr()
    assert "| 0/" not in captured.err and "| 4/4 " in captured.err  # progress bars open full: nothing optimised again
    assert "overlay:" not in captured.out
    _evaluation_line(captured.out, "pick_up")


@pytest.mark.slow
def test_init_only_stops_before_the_physics_stage(demo_file, tmp_path, capsys):
    out = tmp_path / "out"
    status = main(["optimize", str(demo_file), "-o", str(out), "--init-only", "--no-pictures", "--quiet"])
    assert status == 0
    recon = Reconstruction.load(out / "reconstruction.npz")
    assert set(np.unique(recon.grasped)) <= {0.0, 1.0}  # from contact, not a soft switch
    assert sorted(path.name for path in out.iterdir()) == ["checkpoint.pt", "reconstruction.npz"]
    _evaluation_line(capsys.readouterr().out, "pick_up")


def test_the_librarys_warnings_show_as_the_commands_lines_while_it_runs(demo_file, tmp_path, capsys):
    argv = ["optimize", str(demo_file), "-o", str(tmp_path), "--init-only", "--no-pictures", "--quiet",
            "--set", "config.init_iterations=2", "--object-noun", "unobtainium brick"]
    assert main(argv) == 0
    assert "object noun 'unobtainium brick': no typical size known, so no size prior\n" in capsys.readouterr().out
    assert logging.getLogger("warpskill").handlers == []  # the command's console goes with it


def _garbage(path):
    path.write_bytes(bytes(range(256)) * 4)


def _no_contact(path, demo_file):
    arrays = dict(np.load(demo_file))
    del arrays["contact"]
    np.savez_compressed(path, **arrays)


@pytest.mark.parametrize(
    "problem, expected",
    [
        ("missing", "No such file"),
        ("garbage", "not a readable .npz archive"),
        ("zip_garbage", "not a readable .npz archive"),
        ("no_contact", "missing required key(s) contact"),
    ],
)
def test_bad_demonstration_is_one_error_line_and_keeps_the_output_folder(
    problem, expected, demo_file, tmp_path, capsys
):
    path = tmp_path / f"{problem}.npz"
    if problem == "garbage":
        _garbage(path)
    elif problem == "zip_garbage":
        path.write_bytes(b"PK\x03\x04" + b"garbage" * 20)
    elif problem == "no_contact":
        _no_contact(path, demo_file)
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "reconstruction.npz").write_bytes(b"an earlier result")
    before = _snapshot(out)
    status = main(["optimize", str(path), "-o", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert status == 1
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("warpskill: error: ")
    assert str(path) in lines[0] and expected in lines[0]
    assert _snapshot(out) == before


def test_unknown_device_is_one_error_line(demo_file, tmp_path, capsys):
    status = main(["optimize", str(demo_file), "-o", str(tmp_path / "out"), "--device", "tpu7", "--quiet"])
    err = capsys.readouterr().err
    assert status == 1 and err.startswith("warpskill: error: ") and "tpu7" in err


@pytest.fixture(scope="module")
def truth_files(tmp_path_factory):
    """A pick_up demonstration's ground truth as a reconstruction, and one that never lifts."""
    folder = tmp_path_factory.mktemp("truth")
    truth = Reconstruction(**make_demonstration("pick_up", seed=0, **SMALL_DEMO).truth)
    truth.save(folder / "truth.npz")
    dropped = Reconstruction(**{name: getattr(truth, name) for name in FIELD_SHAPES})
    dropped.object_pos = truth.object_pos[::-1].copy()  # ends where it started: on the ground
    dropped.save(folder / "dropped.npz")
    unnamed = Reconstruction(**{name: getattr(truth, name) for name in FIELD_SHAPES} | {"action": ""})
    unnamed.save(folder / "unnamed.npz")
    return folder


@pytest.mark.parametrize("action_args", [["--action", "pick_up"], []])
def test_evaluate_prints_every_check_and_succeeds_on_the_truth(action_args, truth_files, capsys):
    assert main(["evaluate", str(truth_files / "truth.npz"), *action_args]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split("  (")[0] for line in lines] == [
        "  ok   above_ground", "  ok   lifted", "  ok   started_on_ground", "pick_up: success"]
    assert all(float(line.split("(")[1].split()[0]) >= 0 for line in lines[:3])  # passed: room to the limit


def test_evaluate_prints_a_failed_checks_negative_margin(truth_files, capsys):
    assert main(["evaluate", str(truth_files / "dropped.npz"), "--action", "pick_up"]) == 3
    lifted = next(line for line in capsys.readouterr().out.splitlines() if "lifted" in line)
    assert lifted.startswith("  FAIL lifted") and float(lifted.split("(")[1].split()[0]) < 0


def test_evaluate_returns_3_on_failure(truth_files, capsys):
    assert main(["evaluate", str(truth_files / "dropped.npz"), "--action", "pick_up"]) == 3
    lines = [line.split("  (")[0] for line in capsys.readouterr().out.splitlines()]
    assert "  FAIL lifted" in lines and "  ok   above_ground" in lines
    assert lines[-1] == "pick_up: failure"


@pytest.mark.parametrize(
    "name, args, expected",
    [
        ("unnamed.npz", [], "pass --action"),
        ("truth.npz", ["--action", "throw"], "unknown action 'throw'"),
        ("truth.npz", ["--action", "put_onto"], "needs a static object"),
        ("absent.npz", ["--action", "pick_up"], "No such file"),
    ],
)
def test_evaluate_errors_are_one_line(name, args, expected, truth_files, capsys):
    assert main(["evaluate", str(truth_files / name), *args]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("warpskill: error: ") and expected in lines[0]


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["--help"], ["demo", "optimize", "evaluate", "bench"]),
        (["bench", "kernels", "--help"], ["--device", "--repeats"]),
    ],
)
def test_help(argv, expected, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: warpskill")
    for word in expected:
        assert word in out


def test_no_command_prints_usage_and_returns_2(capsys):
    assert main([]) == 2
    assert capsys.readouterr().out.startswith("usage: warpskill")


def test_optimize_without_an_output_folder_is_a_usage_error(demo_file, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["optimize", str(demo_file)])
    assert exit_info.value.code == 2
    assert "-o/--out" in capsys.readouterr().err


@pytest.mark.slow
def test_demo_synthesises_reconstructs_and_reports(tmp_path, monkeypatch, capsys):
    # The command's own pipeline, on a small synthetic video (its default size is slow here).
    real = warpskill.synthetic.make_demonstration
    small = lambda action, **kwargs: real(action, **kwargs, **SMALL_DEMO)  # noqa: E731
    monkeypatch.setattr(warpskill, "make_demonstration", small)  # the public name the command uses
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--iterations", "4", "--quiet"]) == 0
    demo = Demonstration.load(out / "demonstration.npz")
    assert demo.action == "put_onto" and demo.num_static == 1 and demo.truth
    recon = Reconstruction.load(out / "reconstruction.npz")
    assert recon.num_frames == demo.num_frames and recon.num_static == 1
    assert all((out / name).is_file() for name in PICTURES)
    stdout = capsys.readouterr().out
    assert f"demonstration: {out / 'demonstration.npz'} (put_onto, {demo.num_frames} frames)" in stdout.splitlines()
    assert re.fullmatch(r"put_onto: (success|failure \(.+\))", _evaluation_line(stdout, "put_onto"))


@pytest.mark.slow
def test_optimize_several_demonstrations_side_by_side(demo_file, tmp_path, capsys):
    other = tmp_path / "push.npz"
    make_demonstration("push_left_to_right", seed=1, **SMALL_DEMO).save(other)
    out = tmp_path / "out"
    status = main(["optimize", str(demo_file), str(other), "-o", str(out), "--iterations", "3", "--quiet",
                   "--no-pictures"])
    assert status == 0
    for name, action in ((demo_file.stem, "pick_up"), ("push", "push_left_to_right")):
        recon = Reconstruction.load(out / name / "reconstruction.npz")
        assert str(recon.action) == action
    printed = capsys.readouterr().out
    _evaluation_line(printed, "pick_up")
    _evaluation_line(printed, "push_left_to_right")
    assert (out / "checkpoint.pt").is_file()


def test_optimize_refuses_two_demonstrations_of_one_name(demo_file, tmp_path, capsys):
    twin = tmp_path / "again" / demo_file.name
    twin.parent.mkdir()
    shutil.copy(demo_file, twin)
    assert main(["optimize", str(demo_file), str(twin), "-o", str(tmp_path / "out")]) == 1
    assert "different names" in capsys.readouterr().err


@pytest.mark.slow
def test_optimize_workers_without_ray_says_how_to_install_it_and_runs_serially(demo_file, tmp_path, capsys,
                                                                              monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # as if not installed: find_spec("ray") is None
    out = tmp_path / "out"
    status = main(["optimize", str(demo_file), "-o", str(out), "--workers", "2", "--iterations", "2", "--quiet",
                   "--no-pictures"])
    assert status == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == ('--workers needs Ray, which is not installed (pip install -e ".[cluster]"): '
                          "optimising serially")
    assert (out / "reconstruction.npz").is_file()  # the serial layout, as without --workers


@pytest.mark.slow
def test_optimize_on_ray_workers_each_into_its_folder_and_a_rerun_skips_them(demo_file, tmp_path, capsys):
    pytest.importorskip("ray")
    other = tmp_path / "push.npz"
    make_demonstration("push_left_to_right", seed=1, **SMALL_DEMO).save(other)
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"not an archive")
    out = tmp_path / "out"
    argv = ["optimize", str(demo_file), str(other), str(broken), "-o", str(out), "--workers", "1",
            "--iterations", "2", "--quiet", "--no-pictures"]
    assert main(argv) == 1  # one demonstration failed: the others are done
    printed = capsys.readouterr().out
    for name, action in ((demo_file.stem, "pick_up"), ("push", "push_left_to_right")):
        assert str(Reconstruction.load(out / name / "reconstruction.npz").action) == action
        assert (out / name / "checkpoint.pt").is_file()
        _evaluation_line(printed, action)
    assert "broken: failed (DemonstrationError" in printed and "2 done, 1 failed" in printed
    assert main(argv[:3] + argv[4:]) == 0  # without the broken one: both done before, nothing runs
    printed = capsys.readouterr().out
    assert f"{demo_file.stem}: done before" in printed and "push: done before" in printed


def test_the_hypotheses_table_marks_the_one_kept_and_those_ruled_out():
    judged = [{"start": "stage (a)", "contact_frames": 21, "fit": 2.7846, "ends_behind_static": True,
               "contradicted": True, "chosen": False},
              {"start": "on the static", "contact_frames": 33, "fit": 3.0328, "ends_behind_static": False,
               "contradicted": False, "chosen": True}]
    heading, ruled_out, kept = hypothesis_lines(judged)
    assert heading.startswith("hypotheses (fit:")
    assert ruled_out.split() == ("stage (a) contact 21 frames fit 2.785 ends behind the static "
                                 "(ruled out by the masks)").split()
    assert kept.split() == "on the static contact 33 frames fit 3.033 ends not behind the static (chosen)".split()
    assert hypothesis_lines(judged[1:]) == []  # one simulation: nothing was chosen between
