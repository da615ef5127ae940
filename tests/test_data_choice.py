"""``repro.data.choose``: a notebook's ``DATA`` parameter resolved against the data folder."""

import pytest

from repro import data
from repro.errors import DataError


@pytest.fixture
def empty_data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("REPRO_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("REPRO_OFFLINE", "1")
    yield tmp_path
    data.choose("auto", needs=())  # never leave datasets switched off for later tests


@pytest.fixture
def restore():
    yield
    data.choose("auto", needs=())


def test_auto_without_data_falls_back_to_the_embedded_stand_ins(empty_data_dir):
    c = data.choose("auto")
    assert c.mode == "embedded" and c.real == () and c.embedded == ("ict", "cmu-bvh")
    assert (c.face, c.database) == ("procedural", "synthetic")
    assert "embedded" in c.message and "procedural" in c.message and "not in the data folder" in c.message
    assert str(c) == c.message


def test_real_without_data_is_one_data_error_naming_what_is_missing(empty_data_dir):
    with pytest.raises(DataError, match=r"DATA = 'real' but 2 of the 2 datasets .*'ict'.*'cmu-bvh'") as e:
        data.choose("real")
    assert "repro data fetch ict" in str(e.value)
    with pytest.raises(DataError, match=r"1 of the 1 datasets this notebook needs is missing"):
        data.choose("real", needs=("ict",))


@pytest.mark.parametrize("bad", ["reall", "", "Embedded please", None, 3, ["real"]])
def test_an_unknown_choice_is_one_clear_error(bad, restore):
    with pytest.raises(DataError, match=r"is not a known choice; expected one of 'auto', 'embedded', 'real'"):
        data.choose(bad)


def test_an_unknown_dataset_is_an_error(restore):
    with pytest.raises(DataError, match="unknown dataset 'icct'"):
        data.choose("auto", needs=("icct",))


def test_choices_are_case_and_space_tolerant(empty_data_dir):
    assert data.choose(" Embedded ").requested == "embedded"


@pytest.mark.data("ict")
@pytest.mark.data("cmu-bvh")
def test_auto_and_real_use_the_real_data_when_present(restore):
    for choice in ("auto", "real"):
        c = data.choose(choice)
        assert c.mode == "real" and c.uses("ict") and c.uses("cmu-bvh")
        assert (c.face, c.database) == ("ict", "cmu")
        assert c.message.startswith("Data: real") and "embedded" not in c.message


@pytest.mark.data("ict")
def test_embedded_switches_present_data_off_until_the_next_choice(restore):
    from repro.experiments.lewis.common import models

    c = data.choose("embedded", needs=("ict",))
    assert c.mode == "embedded" and not c.uses("ict") and c.face == "procedural"
    assert "switched off" in data.missing_reason("ict")
    assert [m.name for m in models()] == ["procedural"]  # the figures then run on the embedded face only
    assert data.missing_reason("cmu-bvh") is None or "switched off" not in data.missing_reason("cmu-bvh")
    data.choose("auto", needs=("ict",))
    assert data.missing_reason("ict") is None
    assert [m.name for m in models()] == ["procedural", "ict"]


def test_mixed_when_only_some_data_is_present(monkeypatch, restore):
    real_reason = data.missing_reason
    monkeypatch.setattr(data, "missing_reason", lambda n: None if n == "ict" else real_reason(n) or "absent")
    c = data.choose("auto")
    assert c.mode == "mixed" and c.real == ("ict",) and c.embedded == ("cmu-bvh",)
    assert (c.face, c.database) == ("ict", "synthetic")
    with pytest.raises(DataError, match="1 of the 2 datasets"):
        data.choose("real")


def test_a_notebook_with_no_real_data_needs_says_so(restore):
    for choice in ("auto", "embedded", "real"):
        c = data.choose(choice, needs=())
        assert c.mode == "embedded" and c.message == "Data: this notebook uses only embedded data."
