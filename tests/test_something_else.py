"""Something-Else boxes + phases into demonstrations: the dev annotations, messy and malformed files."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

from warpskill.bench.outcomes import load_outcomes
from warpskill.bench.rulers import hand_ruled_size
from warpskill.cli import main
from warpskill.contract.demonstration import DemonstrationError
from warpskill.contract.reconstruction import Reconstruction
from warpskill.data.boxes.something_else import (
    box_masks,
    read_something_else,
    something_else_demonstration,
)
from warpskill.nouns.typical import SIZES

ROOT = Path(__file__).resolve().parents[1]
DEV = next((p / "data" / "something_else_dev" for p in (ROOT / "shared", ROOT.parent / "shared")
            if (p / "data" / "something_else_dev").is_dir()), None)


def _label(name, box, category="thing"):
    x1, y1, x2, y2 = box
    return {"box2d": {"x1": x1, "y1": y1, "x2": x2, "y2": y2}, "category": category, "gt_annotation": name}


def _write(tmp_path, frames, phases="1-2,3-6,7-8", action="push_left_to_right", vid="7"):
    entries = [{"name": f"{vid}/{k:04d}.jpg", "labels": labels, "gt_placeholders": ["cup", "box"]}
               for k, labels in frames.items()]
    (tmp_path / "a.json").write_text(json.dumps({vid: entries}))
    (tmp_path / "p.csv").write_text(f"video_id,action_id,approach,action,leave\n{vid},1,{phases.replace(',', ',')}\n")
    (tmp_path / "x.csv").write_text(f"video_id,action\n{vid},{action}\n")
    return tmp_path / "a.json", tmp_path / "p.csv", tmp_path / "x.csv"


def _messy():
    hand, cup = (10, 10, 40, 40), (100, 100, 140, 130)
    frames = {k: [_label("object hand", hand, "hand"), _label("object 0", cup, "cup")] for k in range(1, 9)}
    frames[2].append(_label("object hand", (300, 10, 330, 40), "hand"))  # a second hand box, far away
    frames[4] = [_label("object 0", cup, "cup")]  # hand missing in frame 4: interpolated
    del frames[5]  # frame 5 absent from the file: interpolated
    frames[6] = [_label("object hand", hand, "hand"), _label("object x", cup, "cup")]  # object under another name
    frames[7].append(_label("object 9x", (0, 0, 5, 5), "lamp"))  # unknown label and category: dropped
    return frames


def test_messy_annotations_are_handled_and_reported(tmp_path):
    video = read_something_else(*_write(tmp_path, _messy()))["7"]
    demo, notes = something_else_demonstration(video)
    assert demo.num_frames == 8 and demo.action == "push_left_to_right"
    assert demo.contact.astype(int).tolist() == [0, 0, 1, 1, 1, 1, 0, 0]
    assert demo.hand_mask.any(axis=(1, 2)).all()  # frames 4-5 interpolated
    assert not demo.hand_mask[1, :, 250:].any()  # the far second box was not kept
    assert demo.object_mask[5].any()  # 'object x' read as object 0 by its category
    text = "\n".join(notes)
    for expected in ("several boxes in frame(s) 2", "interpolated in frame(s) 4-5", "frame(s) 5 not in the annotations",
                     "'object x' ('cup') read as 'object 0'", "dropped a box labelled 'object 9x'"):
        assert expected in text, (expected, text)


def test_long_gaps_are_not_visible(tmp_path):
    frames = _messy()
    for k in (3, 4, 5, 6):
        frames[k] = [label for label in frames.get(k, []) if label["gt_annotation"] != "object hand"]
    demo, notes = something_else_demonstration(read_something_else(*_write(tmp_path, frames))["7"])
    assert not demo.hand_mask[2:6].any() and "hand: no box in frame(s) 3-6" in "\n".join(notes)


def test_box_shapes():
    boxes = np.array([[10.0, 20.0, 50.0, 40.0], [np.nan] * 4])
    ellipse, rectangle = box_masks(boxes, (60, 80)), box_masks(boxes, (60, 80), "rectangle")
    assert rectangle[0].sum() == 40 * 20 and not ellipse[1].any()
    assert abs(ellipse[0].sum() / rectangle[0].sum() - np.pi / 4) < 0.02
    with pytest.raises(ValueError, match="shape"):
        box_masks(boxes, (60, 80), "star")


@pytest.mark.parametrize("field, value, match", [
    ("phases", "1-2,x-6,7-8", "line 2: phase 'x-6'"),
    ("phases", "1-2,6-3,7-8", "phase '6-3'"),
    ("action", "juggle", "line 2: unknown action|line 2: .*juggle"),
])
def test_malformed_files_name_the_file_and_line(tmp_path, field, value, match):
    paths = _write(tmp_path, _messy(), **{field: value})
    with pytest.raises(DemonstrationError, match=match) as error:
        read_something_else(*paths)
    assert str(tmp_path) in str(error.value)


def test_malformed_json_and_entries(tmp_path):
    paths = _write(tmp_path, _messy())
    paths[0].write_text("{oops")
    with pytest.raises(DemonstrationError, match="a.json: not valid JSON"):
        read_something_else(*paths)
    paths[0].write_text(json.dumps({"7": [{"name": "7/0001.jpg"}]}))
    with pytest.raises(DemonstrationError, match="video 7: frame entry 0: missing key 'labels'"):
        something_else_demonstration(read_something_else(*paths)["7"])
    paths = _write(tmp_path, _messy(), phases="1-8,-,-")
    with pytest.raises(DemonstrationError, match="video 7: no action phase"):
        something_else_demonstration(read_something_else(*paths)["7"])


def test_bench_reports_a_failing_video_and_goes_on(tmp_path, capsys):
    paths = _write(tmp_path, _messy(), phases="1-8,-,-")
    code = main(["bench", "something-else", "--annotations", str(paths[0]), "--phases", str(paths[1]),
                 "--actions", str(paths[2]), "-o", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0 and "ERROR DemonstrationError: video 7: no action phase" in out and "0/1" in out


@pytest.mark.slow
def test_bench_reports_each_videos_reconstruction_time_apart_from_its_pictures(tmp_path, capsys):
    paths = _write(tmp_path, _messy())
    code = main(["bench", "something-else", "--annotations", str(paths[0]), "--phases", str(paths[1]),
                 "--actions", str(paths[2]), "-o", str(tmp_path / "out"), "--iterations", "3"])
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if line.split()[:1] == ["7"])
    total, reconstructing = map(float, re.search(r"([\d.]+) s \(([\d.]+) s reconstructing\)", line).groups())
    assert code == 0 and 0 < reconstructing <= total
    assert (tmp_path / "out" / "7" / "reconstruction.npz").is_file()
    assert f"reconstruction (both stages) per video: median {reconstructing:.1f} s" in out
    # The object's size against its noun's (the placeholder "cup"), from the saved reconstruction.
    largest = Reconstruction.load(tmp_path / "out" / "7" / "reconstruction.npz").object_size.max()
    assert f"object size / its noun's typical size (largest edge): median {largest / SIZES['cup'].edges[-1]:.2f}x" in out
    # ... and against the hand's measure of it (the object's box over the hand's in the touching frames).
    video = read_something_else(*paths)["7"]
    by_hand = largest / hand_ruled_size(something_else_demonstration(video)[0])
    assert f"object size / the hand's measure of it (object box over hand box, a hand 19 cm long): " \
           f"median {by_hand:.2f}x" in out
    assert load_outcomes(tmp_path / "out")["7"].errors["hand_ratio"] == pytest.approx(by_hand)


@pytest.mark.skipif(DEV is None, reason="the shared development data is not next to the repository")
def test_the_development_videos_all_load():
    videos = read_something_else(DEV / "annotations.json", DEV / "phases.csv", DEV / "actions.csv")
    assert len(videos) == 18
    for video in videos.values():
        demo, notes = something_else_demonstration(video)
        assert demo.action == video.action and demo.contact.sum() == np.diff(video.phases["action"]) + 1
        two_objects = video.action.startswith("put")
        assert demo.num_static == int(two_objects)


def test_each_video_is_one_run_case_its_failure_one_line_and_its_traceback_kept_where_it_ran(tmp_path):
    from warpskill.bench.outcomes import CaseFailed
    from warpskill.bench.cases import Reconstructed, run_case
    from warpskill.contract.results_folder import ResultsFolder
    from warpskill.synthetic import make_demonstration

    truth = Reconstruction(**make_demonstration("pick_up", seed=0, noise="none").truth)
    made = run_case("7", "pick_up", tmp_path, lambda: Reconstructed(truth, "done before, 0.1 s, 0 note(s)"))
    assert (made.case, made.action, made.success, made.failed_checks, made.robot) == ("7", "pick_up", True, (), None)

    def unreadable():
        raise DemonstrationError("video 8: frame 3\n  has no box")

    failed = run_case("8", "pick_up", tmp_path, unreadable)
    assert (failed.success, failed.failed_checks) == (False, ("error",))
    assert failed.note == "DemonstrationError: video 8: frame 3 has no box"
    assert "Traceback" in ResultsFolder(tmp_path).error.read_text()

    def failed_in_its_task():  # a Ray task's failure: its reason as it is, recorded where it ran
        raise CaseFailed("OptimizeError: NaN loss")

    (tmp_path / "ray").mkdir()
    assert run_case("9", None, tmp_path / "ray", failed_in_its_task).note == "OptimizeError: NaN loss"
    assert not ResultsFolder(tmp_path / "ray").error.exists()
