"""Length unit and up axis inferred from the stature and the rest pose (issue 11, item 2)."""

from __future__ import annotations

import dataclasses
import warnings

import pytest

from repro import data
from repro.errors import BVHError, MotionError, UnitWarning
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, read_bvh
from repro.motion.body.skeleton import Skeleton
from repro.motion.database.synthetic.conventions import CONVENTIONS, build
from repro.motion.body.units import UNITS, infer_unit, infer_units

Z_UP = {"biped", "unreal"}


@pytest.mark.parametrize("unit_name, unit_m", UNITS)
@pytest.mark.parametrize("height", [1.2, 1.75, 2.2])
def test_unit_from_stature(unit_name, unit_m, height):
    rig, _ = build("mixamo", height=height)
    m = rig.transform(scale=1.0 / unit_m).motion(unit_m=None)
    with pytest.warns(UnitWarning, match=unit_name.split()[0]):
        out = infer_units(m)
    assert out.unit_m == pytest.approx(unit_m)
    assert out.up == "y"
    with pytest.warns(UnitWarning):
        sk = Skeleton.from_motion(m)
    assert sk.unit_m == pytest.approx(unit_m)
    assert sk.size == pytest.approx(height, rel=0.02)


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_every_convention_without_unit(convention):
    rig, _ = build(convention)
    m = rig.transform(scale=100.0).motion(unit_m=None)  # centimetres
    with pytest.warns(UnitWarning) as rec:
        out = infer_units(m)
    assert out.unit_m == pytest.approx(0.01)
    assert out.up == ("z" if convention in Z_UP else "y")
    assert f"up axis {out.up.upper()}" in str(rec[0].message)


def test_explicit_values_win_and_do_not_warn():
    m = build("unreal")[0].motion(unit_m=None)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        out = infer_units(m, unit_m=0.5, up="y")
    assert out.unit_m == 0.5 and out.up == "y"
    m2 = dataclasses.replace(m, unit_m=1.0, up="z")
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        assert infer_units(m2) is m2


def test_uninferable_stature_is_an_error():
    m = build("mixamo")[0].transform(scale=1e5).motion(unit_m=None)
    with pytest.raises(MotionError, match="cannot infer the length unit"):
        infer_units(m)
    for bad in (0.0, -1.0, float("nan"), "tall"):
        with pytest.raises(MotionError, match="stature"):
            infer_unit(bad)
    with pytest.raises(MotionError, match="up must be"):
        infer_units(m, up="x")
    with pytest.raises(MotionError, match="unit_m"):
        infer_units(m, unit_m=-1.0)
    # the skeleton keeps the unit unknown, and its size says so
    sk = Skeleton.from_motion(m)
    assert sk.unit_m is None
    with pytest.raises(MotionError, match="unit"):
        sk.size  # noqa: B018


def test_motion_up_is_validated():
    m = build("mixamo")[0].motion(unit_m=1.0)
    with pytest.raises(BVHError, match="up must be"):
        dataclasses.replace(m, up="sideways")


@pytest.mark.data("cmu-bvh")
def test_real_cmu_unit():
    m = read_bvh(data.fetch("mocap/cmu/135_04.bvh"))
    with pytest.warns(UnitWarning, match="CMU"):
        out = infer_units(m)
    assert out.unit_m == pytest.approx(CMU_UNIT_M) and out.up == "y"


@pytest.mark.data("bandai")
def test_real_bandai_unit_and_up_from_frames():
    # the Bandai Namco rest pose lies along +X: the up axis comes from the frames
    m = read_bvh(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"))
    with pytest.warns(UnitWarning):
        out = infer_units(m)
    assert out.unit_m == pytest.approx(BANDAI_UNIT_M) and out.up == "y"
