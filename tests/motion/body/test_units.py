"""Length unit and up axis inferred from the stature and the rest pose (issue 11, item 2; issue 25,
item 3: feet, decimetres, ambiguous statures)."""

from __future__ import annotations

import dataclasses
import os
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from repro import data
from repro.errors import BVHError, MotionError, UnitWarning
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, read_bvh
from repro.motion.body.skeleton import Skeleton
from repro.motion.database.synthetic.conventions import CONVENTIONS, build
from repro.motion.body.units import UNITS, infer_unit, infer_units

Z_UP = {"biped", "unreal"}
REALRIGS = "mocap/formats/realrigs"
#: The units of issue 11 (any stature from 1.2 to 2.2 m tells them apart).
FIRST_UNITS = [(n, u) for n, u in UNITS if n in ("metres", "centimetres", "millimetres", "inches")
               or n.startswith("CMU")]


@pytest.mark.parametrize("unit_name, unit_m", FIRST_UNITS + [("feet", 0.3048)])
@pytest.mark.parametrize("height", [1.2, 1.75, 2.2])
def test_unit_from_stature(unit_name, unit_m, height):
    _check_unit(unit_name, unit_m, height)


@pytest.mark.parametrize("height", [1.2, 1.5, 1.75, 2.0])
def test_decimetres_from_stature(height):
    _check_unit("decimetres", 0.1, height)


def _check_unit(unit_name, unit_m, height):
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


def test_every_unit_is_a_candidate():
    names = [n for n, _ in UNITS]
    assert names[:3] == ["metres", "centimetres", "millimetres"]  # the conventional ones first
    assert {"inches", "feet", "decimetres"} <= set(names) and any(n.startswith("CMU") for n in names)
    # Mixamo's and Unreal's 100 units per metre are centimetres: a 1.8 m Mixamo rig is 180 units
    assert infer_unit(180.0) == (0.01, "centimetres")
    assert infer_unit(16.5) == (0.1, "decimetres")  # MakeHuman, 16.4-16.6 units tall
    assert infer_unit(15.2)[1] == "decimetres"  # not CMU units (0.86 m)
    assert infer_unit(5.9) == (0.3048, "feet")


def test_an_ambiguous_stature_takes_the_conventional_unit_and_says_so():
    # 22 units: 2.20 m in decimetres, 1.24 m in CMU units: nearly as close to 1.7 m on a log scale
    u, name = infer_unit(22.0)
    assert u == pytest.approx(CMU_UNIT_M)
    assert name.startswith("CMU") and "ambiguous" in name and "decimetres 2.20 m" in name
    rig, _ = build("mixamo", height=1.24)
    m = rig.transform(scale=1.0 / CMU_UNIT_M).motion(unit_m=None)
    with pytest.warns(UnitWarning, match="ambiguous"):
        assert infer_units(m).unit_m == pytest.approx(CMU_UNIT_M)
    assert "ambiguous" not in infer_unit(28.96)[1]  # CMU subject 135


def test_a_mixamo_cm_rig_with_a_floor_root_fits_centimetres():
    # a Mixamo export in centimetres whose root sits on the floor under the hips: the stature no
    # longer runs through the pelvis role, so a pelvis put on that root does not add the hips'
    # height to the trunk (the sum of the bones from the pelvis up made it 2.65 m: "no unit fits")
    rig, _ = build("mixamo")
    rig.insert_above("mixamorig:Hips", "Armature", 0.0)
    m = rig.transform(scale=100.0).motion(unit_m=None)
    roles = dict(Skeleton.from_motion(dataclasses.replace(m, unit_m=0.01)).roles, pelvis="Armature")
    with pytest.warns(UnitWarning, match="centimetres"):
        sk = Skeleton.from_motion(m, roles=roles)
    assert sk.height == pytest.approx(175.0) and sk.unit_m == 0.01


def test_the_warning_says_how_the_stature_was_measured():
    rig, _ = build("mixamo")
    m = rig.transform(scale=100.0).motion(unit_m=None)
    with pytest.warns(UnitWarning, match="head top from the End Site") as rec:
        infer_units(m)
    assert "stature 175 units" in str(rec[0].message)


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


@pytest.mark.parametrize("name, unit_m, lo, hi", [
    ("freedance_blender_rigify_names.bvh", 0.1, 1.5, 1.8),  # was CMU units, a 0.86 m fighter
    ("makehuman_game_rig_zombiewalk.bvh", 0.1, 1.55, 1.75),  # Z up, 16.4 units tall
    ("mocopi_MCPM_20230410_150228.BVH", 0.01, 1.6, 1.9),
    ("shadermotion_unity_humanoid.bvh", 1.0, 1.7, 1.85),
    ("accad_Male1_C03_Run.bvh", 0.01, 1.7, 1.9),  # was 1.96 m (the pelvis-to-head bones summed)
    ("emretanirgan_matt_happy2.bvh", 0.01, 1.5, 1.7),  # every bone along +X: parts estimated
])
def test_real_rigs_units_and_statures(name, unit_m, lo, hi):
    p = Path(os.environ.get("REPRO_DATA_DIR") or "/nonexistent") / REALRIGS / name
    if not p.is_file():
        pytest.skip(f"{p} not staged (set REPRO_DATA_DIR)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = read_bvh(p)
    with pytest.warns(UnitWarning):
        out = infer_units(m)
    assert out.unit_m == pytest.approx(unit_m)
    assert lo < Skeleton.from_motion(out).size < hi


@pytest.mark.parametrize(("facing", "yaw_deg"), [("-Z", 180.0), ("+X", 90.0), ("-X", -90.0)])
def test_a_rest_pose_facing_another_axis_is_turned_to_face_z(facing, yaw_deg):
    """y_up_metres turns an upright character facing -Z, +X or -X about Y to face +Z (the actors' way)."""
    import warnings

    from scipy.spatial.transform import Rotation

    from repro.errors import UnitWarning
    from repro.motion.body.skeleton import skeleton_of
    from repro.motion.body.units import y_up_metres
    from repro.motion.database.synthetic.conventions import build

    m = dataclasses.replace(build("mixamo")[0].motion(unit_m=1.0), up="y")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # facing +Z, Y-up, metres: nothing to say, nothing to change
        assert y_up_metres(m) is m
    R = Rotation.from_euler("y", yaw_deg, degrees=True).as_matrix()
    sk = skeleton_of(m)
    turned = sk.with_offsets(sk.offsets @ R.T, sk.end_site_offsets @ R.T, unit_m=1.0)
    with pytest.warns(UnitWarning, match=f"facing {re.escape(facing)}"):
        back = y_up_metres(turned)
    np.testing.assert_allclose(back.rest_positions(), sk.rest_positions(), atol=1e-12)
