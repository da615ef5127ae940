"""repro.checks: the one set of argument validators both papers use at their entries (issue 23, section 6)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from repro import checks
from repro.checks import as_bool, as_choice, as_int, as_names, as_path, as_real, check_alloc
from repro.errors import ArgumentError, MotionError, ReproError


def test_argument_error_is_a_repro_and_value_error():
    assert issubclass(ArgumentError, ReproError) and issubclass(ArgumentError, ValueError)


@pytest.mark.parametrize("bad", ["3", 2.0, 2.5, True, np.bool_(False), None, complex(1, 0), object()])
def test_as_int_refuses_what_is_not_an_integer(bad):
    with pytest.raises(MotionError, match="must be an integer"):
        as_int(bad, "k", error=MotionError)


def test_as_int_range_is_positional_and_says_out_of_range():
    assert as_int(np.int64(3), "k", 1, 3) == 3 and type(as_int(np.int64(3), "k")) is int
    with pytest.raises(ArgumentError, match=r"k must be an integer in 1\.\.3, got 4 \(out of range\)"):
        as_int(4, "k", 1, 3)
    with pytest.raises(ArgumentError, match=r"in -inf\.\.0"):
        as_int(1, "k", None, 0)


def test_as_real_bounds_open_and_closed():
    assert as_real(0, "a", lo=0) == 0.0
    with pytest.raises(ArgumentError, match=r"a must be in \(0, inf\), got 0"):
        as_real(0, "a", lo=0, lo_open=True)
    with pytest.raises(ArgumentError, match=r"in \[0, 1\]"):
        as_real(1.5, "a", lo=0, hi=1)
    with pytest.raises(ArgumentError, match="finite"):
        as_real(math.nan, "a", lo=0, hi=1)
    assert math.isnan(as_real(math.nan, "a", finite=False))
    for bad in ("1", None, True, 1j, [1.0]):
        with pytest.raises(ArgumentError, match="real number"):
            as_real(bad, "a")


@pytest.mark.parametrize("bad", [1, 0, "yes", None, np.array([True])])
def test_as_bool_takes_booleans_only(bad):
    with pytest.raises(ArgumentError, match="must be True or False"):
        as_bool(bad, "flag")
    assert as_bool(np.bool_(True), "flag") is True


def test_as_choice_compares_type_and_value():
    assert as_choice("pin", "feet", ("pin", "plant")) == "pin"
    for bad in ("x", 1, None, np.array(["pin", "pin"]), ["pin"]):
        with pytest.raises(ArgumentError, match=r"feet must be one of 'pin', 'plant'"):
            as_choice(bad, "feet", ("pin", "plant"))
    with pytest.raises(ArgumentError):
        as_choice(True, "level", (1, 2))  # a bool is not the int 1


def test_as_names_refuses_a_lone_string_unless_one():
    assert as_names(["a", "b"], "roles") == ("a", "b")
    assert as_names("a", "roles", one=True) == ("a",)
    with pytest.raises(ArgumentError, match="got the string 'ab'"):
        as_names("ab", "roles")
    with pytest.raises(ArgumentError, match="a role in roles must be a string"):
        as_names(["a", 1], "roles", item="a role")
    with pytest.raises(ArgumentError, match="must name at least one"):
        as_names([], "roles")
    assert as_names([], "roles", nonempty=False) == ()
    with pytest.raises(ArgumentError, match="sequence of names"):
        as_names(3, "roles")


def test_as_path_refuses_other_types_and_nul():
    assert as_path("a/b", "p") == Path("a/b")
    with pytest.raises(ArgumentError, match="must be a path"):
        as_path(3, "p")
    with pytest.raises(ArgumentError, match="NUL"):
        as_path("a\0b", "p")


def test_check_alloc_refuses_above_the_budget_naming_what_asks():
    assert check_alloc(10, "x", budget=10) == 10
    with pytest.raises(MotionError, match=r"factor=10\*\*9 would need about 93.1 GiB.*budget of 1 GiB"):
        check_alloc(100 * 10**9, "factor=10**9", budget=1 << 30, error=MotionError)
    assert checks.MEMORY_BUDGET > 0


def test_memory_budget_from_the_environment(monkeypatch):
    monkeypatch.setenv("REPRO_MEMORY_BUDGET", "1000")
    assert checks._budget_from_env() == 1000
    for bad in ("", "x", "-5", "0"):
        monkeypatch.setenv("REPRO_MEMORY_BUDGET", bad)
        assert checks._budget_from_env() == 8 << 30
