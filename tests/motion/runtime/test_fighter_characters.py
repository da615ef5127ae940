"""KungFuFighter takes any humanoid BVH as its character: Z-up, any unit (issue 11, item 4).

What is asserted: a Z-up character in centimetres (the synthetic body on the Unreal-style
rig, renamed to meaningless joint names) and the Z-up pybvh fixture
(``mocap/formats/pybvh/bvh_test1.bvh``, a real file of another tool, unit not stated) are
converted to the fighter's Y-up metres (a UnitWarning says what was inferred), stand on the
floor and punch / kick their targets; :func:`repro.motion.body.units.y_up_metres` is the same
body in the turned world and leaves a Y-up metre character alone.
"""

from __future__ import annotations

import dataclasses
import re
import warnings

import numpy as np
import pytest

from repro import data
from repro.errors import UnitWarning
from repro.motion import read_bvh
from repro.motion.runtime.fighter import KungFuFighter
from repro.motion.body.skeleton import Skeleton
from repro.motion.database.synthetic.conventions import build
from repro.motion.body.units import y_up_metres

PYBVH = "mocap/formats/pybvh/bvh_test1.bvh"


def meaningless(m):
    """``m`` with its joints renamed j0, j1, ... (roles then come from the structure alone)."""
    return dataclasses.replace(m, joint_names=[f"j{i}" for i in range(m.n_joints)])


@pytest.fixture(scope="module")
def z_up_cm():
    return dataclasses.replace(build("unreal", height=1.6)[0].motion(unit_m=1.0).scaled(100.0), unit_m=None)


def _stands_and_strikes(f, up_idx=1):
    g = f.stance.global_positions()
    sk = f.character
    feet = [sk.index(r) for r in ("left_ankle", "right_ankle", "left_toe", "right_toe") if r in sk.roles]  # no toes: DAZ
    assert g[:, sk.index("head"), 1].min() > 0.6 * sk.size  # upright in the Y-up world
    assert -1e-6 < g[:, feet, 1].min() < 0.15
    head = (0.0, 0.85 * sk.size, 0.0)
    f.follow(head, 0.0, snap=True)
    for kind, target in (("punch", head), ("kick", (0.0, 0.55 * sk.size, 0.0))):
        s = f.order(kind, target)
        assert s.motion.joint_names == sk.joint_names
        assert s.reached and s.hit_error < 0.01, (kind, s.hit_error)


def test_y_up_metres_turns_the_same_body(z_up_cm):
    with pytest.warns(UnitWarning) as caught:  # the unit and the up axis (pytest 8 re-emits a warning no `match` took)
        conv = y_up_metres(z_up_cm)
    assert any(re.search("centimetre.*up axis Z", str(w.message)) for w in caught)
    assert conv.unit_m == 1.0 and conv.up == "y"
    g0 = z_up_cm.global_positions() * 0.01
    g1 = conv.global_positions()
    # +Z -> +Y, -Y -> +Z
    np.testing.assert_allclose(g1, np.stack([g0[..., 0], g0[..., 2], -g0[..., 1]], axis=-1), atol=1e-9)
    assert Skeleton.from_motion(conv).size == pytest.approx(1.6, rel=1e-9)
    y = build("mixamo")[0].motion(unit_m=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert y_up_metres(dataclasses.replace(y, up="y")) is not None
    assert y_up_metres(dataclasses.replace(y, up="y")).offsets is y.offsets or np.array_equal(
        y_up_metres(dataclasses.replace(y, up="y")).offsets, y.offsets)


def test_fighter_takes_a_z_up_centimetre_character_with_meaningless_names(synthetic_db, z_up_cm):
    ch = meaningless(z_up_cm)
    with pytest.warns(UnitWarning):
        f = KungFuFighter(synthetic_db, character=ch, seed=0)
    assert f.character.joint_names == ch.joint_names
    assert f.character.unit_m == 1.0 and f.character.size == pytest.approx(1.6, rel=1e-9)
    _stands_and_strikes(f)


@pytest.mark.data("cmu-bvh")  # the formats corpus is staged with the mocap data
def test_fighter_takes_the_z_up_pybvh_fixture(synthetic_db):
    path = data.data_dir() / PYBVH
    if not path.is_file():
        pytest.skip(f"{PYBVH} not staged")
    m = read_bvh(path)
    assert m.unit_m is None
    with pytest.warns(UnitWarning) as caught:  # the unit and the up axis
        f = KungFuFighter(synthetic_db, character=m, seed=0)
    assert any("up axis Z" in str(w.message) for w in caught)
    assert f.character.joint_names == m.joint_names and 1.2 < f.character.size < 2.2
    _stands_and_strikes(f)


#: Real rigs whose hands carry fingers and no End Site (issue 25, item 1): MotionBuilder-style (60 joints),
#: DAZ / Poser and Unity humanoid names
FINGERED = ["mocap/formats/pybvh/bvh_test3.bvh", "mocap/formats/realrigs/threejs_pirouette_daz.bvh",
            "mocap/formats/realrigs/shadermotion_unity_humanoid.bvh"]


@pytest.mark.data("cmu-bvh")  # the formats corpus is staged with the mocap data
@pytest.mark.parametrize("name", FINGERED)
def test_a_hand_with_fingers_punches_with_its_knuckles(synthetic_db, name):
    from repro.motion.body.hit_points import hit_offset

    path = data.data_dir() / name
    if not path.is_file():
        pytest.skip(f"{name} not staged")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)  # the unit and the up axis, inferred
        f = KungFuFighter(synthetic_db, character=read_bvh(path), seed=0)
    sk = f.character
    fist = sk.index("right_fist")
    assert not np.any(sk.end_site_parents == fist) and hit_offset(sk, fist)[1] == "knuckles"
    _stands_and_strikes(f)
