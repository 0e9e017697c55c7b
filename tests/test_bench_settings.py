"""The benchmarks' data folders are settings: an option or an environment variable, never a guessed path."""

import pytest

from warpskill.bench.settings import DEV_DATA_VARIABLE, SettingError, data_folder
from warpskill.bench.speed import speed_cases


def test_a_folder_given_wins_over_the_variable_and_the_variable_is_read_without_one(tmp_path, monkeypatch):
    given, set_ = tmp_path / "given", tmp_path / "set"
    given.mkdir(), set_.mkdir()
    monkeypatch.setenv(DEV_DATA_VARIABLE, str(set_))
    assert data_folder(given, DEV_DATA_VARIABLE, "--folder", "videos") == given
    assert data_folder(None, DEV_DATA_VARIABLE, "--folder", "videos") == set_


def test_a_missing_folder_is_one_line_naming_the_option_and_the_variable(tmp_path, monkeypatch):
    monkeypatch.delenv(DEV_DATA_VARIABLE, raising=False)
    with pytest.raises(SettingError, match=f"give --folder or set \\${DEV_DATA_VARIABLE}"):
        speed_cases("dev")
    with pytest.raises(SettingError, match="no such folder"):
        speed_cases("dev", folder=tmp_path / "nowhere")
