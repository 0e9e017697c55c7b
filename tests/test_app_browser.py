"""``warpskill app``: its outline, files and run helpers, and the page in a headless Chromium: upload
a clip's frames, ask for a proposal (none: no hand in a synthetic clip), box the object with two
clicks, run, and find the robot's replay and the results' zip on the page.

The clip is rendered here (:mod:`warpskill.synthetic.footage`: a synthetic pick-up, textured)
and uploaded as its frames. Needs Gradio and Selenium (extra ``test``) and the OS's
``chromium`` and ``chromedriver`` (``.ci/run`` installs them); skipped without them.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import socket
import time
import urllib.request
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest

from warpskill.app import files, outline
from warpskill.app.running import RunOutcome, RunSettings
from warpskill.contract import Demonstration
from warpskill.data import read_polygons
from warpskill.media import write_mp4
from warpskill.synthetic import make_demonstration
from warpskill.synthetic.footage import clip_outline, textured_frames

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
RUN_TIMEOUT_S = 300.0
KEY_FRAME = 6  # the frame outlined for the run: the hand and the box both in view


# ----------------------------------------------------------------------------- without a browser


def test_a_box_from_two_corners_is_the_polygon_the_run_reads(tmp_path):
    drawn = outline.with_box(outline.draft(3), "object", (30.5, 20.5), (10.5, 5.5))
    drawn = outline.with_box(drawn, "static_1", (2.5, 2.5), (8.5, 6.5))  # past the last static object: added
    path = tmp_path / "outline.json"
    path.write_text(outline.outline_text(drawn))
    read = read_polygons(path, (40, 50))
    assert read.frame == 3 and list(read.masks) == ["object", "static_0"]
    # corners at pixel centres: the box holds both corner pixels (docs/formats.md: (0, 0) the image's corner)
    assert read.masks["object"].sum() == 21 * 16 and read.masks["static_0"].sum() == 7 * 5
    assert "object" not in outline.remove_role(drawn, "object") and outline.remove_role(drawn, "static_0")["static"] == []
    picture = outline.draw_outline(np.zeros((40, 50, 3), np.uint8), drawn, pending=(45.5, 35.5))
    scale = outline.shown_scale((40, 50))
    assert picture.shape == (40 * scale, 50 * scale, 3) and 40 * scale >= outline.SHOWN_HEIGHT_PX > 40 * (scale - 1)
    assert picture[12 * scale, 20 * scale].any() and not picture[30 * scale, 5 * scale].any()  # in a box, outside all
    row, column = int(35.5 * scale), int(45.5 * scale)  # the pending corner's cross, on its pixel's centre
    assert picture[row, column - 2 * scale].all() and not picture[row - 3, column - 2 * scale].any()
    assert outline.shown_to_frame((7 * scale + scale - 1, 2 * scale), (40, 50)) == (7.5, 2.5)
    with pytest.raises(ValueError, match="frame"):
        outline.parse_outline('{"object": []}')


def test_a_clip_is_one_video_or_several_frames(tmp_path):
    images = []
    for k in range(3):
        images.append(tmp_path / f"shot_{k}.jpg")
        cv2.imwrite(str(images[-1]), np.full((8, 10, 3), 60 * k, np.uint8))
    clip = files.store_clip(images[::-1], tmp_path / "page")
    frames, fps = files.clip_frames(clip)
    assert clip.name == "%04d.png" and frames.shape == (3, 8, 10, 3) and fps == files.FRAMES_FPS
    assert abs(int(frames[2, 0, 0, 0]) - 120) <= 2  # in the order of the names
    assert files.new_folder(files.clip_folder(clip), "run").name == "run-1"
    with pytest.raises(ValueError, match="one video file or several images"):
        files.store_clip(images[:1], tmp_path / "page")
    video = write_mp4(tmp_path / "shot.mp4", np.full((4, 16, 16, 3), 90, np.uint8), 10.0)
    clip = files.store_clip([video], tmp_path / "page")
    frames, fps = files.clip_frames(clip)
    assert clip == tmp_path / "page" / "shot-1" / "clip.mp4" and frames.shape == (4, 16, 16, 3) and fps == 10.0


def test_a_run_says_in_one_line_how_it_ended():
    assert RunOutcome(2, "demonstration: ...\nwarpskill: error: polygons.json: object: missing\n").summary \
        == "warpskill: error: polygons.json: object: missing"
    assert RunOutcome(3, "pick_up: success\nplan: p.npz\nreplay: r.npz\npick_up: failure (lifted)\n").summary \
        == "stopped: no robot plan, or the replay fails the action's criteria; pick_up: failure (lifted)"
    assert RunOutcome(1, "Traceback (most recent call last):\n  File x\nKeyError: 'k'\n").summary.startswith(
        "crashed: KeyError: 'k'")
    settings = RunSettings("put_onto", object_noun="mug", iterations=5, fps=24.0, robot=False)
    assert settings.arguments() == ["--action", "put_onto", "--quiet", "--object-noun", "mug", "--iterations", "5",
                                    "--fps", "24.0", "--no-robot"]


# ----------------------------------------------------------------------------- in the browser


@pytest.fixture
def browser():
    if CHROMIUM is None or CHROMEDRIVER is None:
        pytest.skip("needs chromium and chromedriver from the OS (apt-get install chromium chromium-driver)")
    pytest.importorskip("gradio", reason="needs Gradio: pip install -e '.[app]'")
    webdriver = pytest.importorskip("selenium.webdriver", reason="needs Selenium: pip install -e '.[test]'")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1800"):
        options.add_argument(argument)
    driver = webdriver.Chrome(options=options, service=webdriver.ChromeService(executable_path=CHROMEDRIVER))
    driver.set_script_timeout(30)
    yield driver
    driver.quit()


@pytest.fixture
def page(tmp_path):
    os.environ.setdefault("GRADIO_ANALYTICS_ENABLED", "False")
    from warpskill.app import serve

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    served = serve(tmp_path / "page", port=port, block=False)
    yield f"http://127.0.0.1:{port}/", tmp_path / "page"
    served.close()


def _wait(driver, condition, timeout: float, what: str):
    """Poll ``condition(driver)`` until it returns something true; fail naming ``what``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        found = condition(driver)
        if found:
            return found
        error = _text(driver, '[data-testid="toast-body"].error')
        if error:
            raise AssertionError(f"page: an error while waiting for {what}: {error!r}")
        time.sleep(0.25)
    raise AssertionError(f"page: no {what} after {timeout:g} s; status: {_text(driver, '#status')!r}")


def _text(driver, selector: str) -> str:
    return driver.execute_script(f"const e = document.querySelector('{selector}'); return e ? e.innerText : '';")


def _outline_text(driver) -> str:
    return driver.execute_script("return document.querySelector('#outline textarea').value;")


def _type_into(driver, selector: str, value: str) -> None:
    """Set an input's value as typing does (Gradio listens to input events)."""
    driver.execute_script(
        "const e = document.querySelector(arguments[0]);"
        "const proto = e.tagName === 'TEXTAREA' ? HTMLTextAreaElement.prototype : HTMLInputElement.prototype;"
        "Object.getOwnPropertyDescriptor(proto, 'value').set.call(e, arguments[1]);"
        "e.dispatchEvent(new Event('input', {bubbles: true})); e.dispatchEvent(new Event('change', {bubbles: true}));"
        "e.dispatchEvent(new Event('blur'));", selector, value)


def _click_pixel(driver, x: int, y: int, image_size: tuple[int, int]) -> None:
    """Click the shown frame, of (H, W) ``image_size``, on the centre of its pixel (x, y). The page
    shows the picture centred in its element, shrunk to fit, never enlarged (CSS object-fit: scale-down)."""
    from selenium.webdriver import ActionChains

    image = driver.find_element("css selector", "#preview img")
    driver.execute_script("arguments[0].scrollIntoView({block: 'center', behavior: 'instant'});", image)
    width, height = image.size["width"], image.size["height"]
    natural = driver.execute_script("return [arguments[0].naturalWidth, arguments[0].naturalHeight];", image)
    shown = min(width / natural[0], height / natural[1], 1.0) * natural[0] / image_size[1]  # element px per frame px
    dx = (width - shown * image_size[1]) / 2 + (x + 0.5) * shown - width / 2
    dy = (height - shown * image_size[0]) / 2 + (y + 0.5) * shown - height / 2
    ActionChains(driver).move_to_element_with_offset(image, round(dx), round(dy)).click().perform()


@pytest.mark.slow
def test_the_page_runs_an_uploaded_clip_to_the_robots_replay(browser, page, tmp_path):
    from selenium.webdriver.common.by import By

    start = time.perf_counter()
    url, root = page
    truth = make_demonstration("pick_up", seed=1, image_size=(96, 128), duration=2.0, noise="none")
    frames = textured_frames(truth)
    uploads = []
    for k, frame in enumerate(frames):
        uploads.append(tmp_path / f"frame_{k:04d}.png")
        cv2.imwrite(str(uploads[-1]), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))

    browser.get(url)
    _wait(browser, lambda d: d.find_elements(By.CSS_SELECTOR, "#clip input[type=file]"), 30, "clip upload")
    browser.find_element(By.CSS_SELECTOR, "#clip input[type=file]").send_keys("\n".join(map(str, uploads)))
    middle = len(frames) // 2
    _wait(browser, lambda d: f'"frame": {middle}' in _outline_text(d), 60, "draft outline on the middle frame")
    _wait(browser, lambda d: d.execute_script(
        "const e = document.querySelector('#preview img'); return e && e.naturalWidth > 0;"), 30, "frame to outline")

    browser.find_element(By.CSS_SELECTOR, "#propose").click()  # no hand on a synthetic clip: the proposal says so
    warning = _wait(browser, lambda d: _text(d, '[data-testid="toast-body"].warning'), 60, "proposal's warning")
    assert f"no hand in any of the {len(frames)} frames" in warning, warning
    _wait(browser, lambda d: d.find_elements(By.CSS_SELECTOR, "#proposal_view img"), 10, "what the proposal saw")

    ys, xs = np.nonzero(truth.object_mask[middle])
    _click_pixel(browser, xs.min(), ys.min(), frames.shape[1:3])  # the object's box: its corner pixels
    _wait(browser, lambda d: d.execute_script("return document.querySelector('#preview img').naturalWidth > 0;"), 10,
          "the first corner drawn")
    _click_pixel(browser, xs.max(), ys.max(), frames.shape[1:3])
    boxed = _wait(browser, lambda d: '"object"' in _outline_text(d) and _outline_text(d), 30, "boxed object")
    x0, y0, x1, y1 = xs.min() + 0.5, ys.min() + 0.5, xs.max() + 0.5, ys.max() + 0.5
    assert json.loads(boxed)["object"] == [[x0, y0], [x1, y0], [x1, y1], [x0, y1]], boxed  # on the pixels' centres

    drawn = clip_outline(truth, KEY_FRAME)  # the hand too: no MediaPipe hand on a synthetic clip
    _type_into(browser, "#outline textarea", outline.outline_text(drawn))
    _type_into(browser, "#iterations input", "10")
    browser.find_element(By.CSS_SELECTOR, "#run").click()

    video_element = _wait(browser, lambda d: d.find_elements(By.CSS_SELECTOR, "#replay video[src], #replay_picture img"),
                          RUN_TIMEOUT_S, "robot replay")[0]
    assert "finished; pick_up: success" in _text(browser, "#status")
    source = video_element.get_attribute("src")
    with urllib.request.urlopen(source) as response:
        replay = response.read()
    assert len(replay) > 10_000 and (replay[4:8] == b"ftyp" or replay[:4] == b"\x89PNG")  # an MP4, or the paths plot

    [run] = root.glob("*/run-1")
    assert json.loads((run / "outline.json").read_text()) == json.loads(outline.outline_text(drawn))  # as shown
    demo = Demonstration.load(run / "demonstration.npz")
    assert demo.num_frames == len(frames) and demo.fps == files.FRAMES_FPS
    link = _wait(browser, lambda d: d.find_elements(By.CSS_SELECTOR, "#results a[href]"), 10, "results zip")[0]
    with urllib.request.urlopen(link.get_attribute("href")) as response:
        names = zipfile.ZipFile(io.BytesIO(response.read())).namelist()
    assert {"run-1/reconstruction.npz", "run-1/replay.npz", "run-1/outline.json"} <= set(names), names
    print(f"page: upload to replay in {time.perf_counter() - start:.1f} s")
