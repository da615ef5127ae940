"""Where a strike lands (repro.motion.body.hit_points): the End Site, else the knuckles, else the joint."""

from __future__ import annotations

import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.body.hit_points import hit_offset


def _rig(joints, end_sites=()):
    """joints: (name, parent name or None, offset); end_sites: (parent name, offset)."""
    names = [n for n, _, _ in joints]
    return SimpleNamespace(
        joint_names=names, parents=np.array([-1 if p is None else names.index(p) for _, p, _ in joints]),
        offsets=np.array([o for _, _, o in joints], dtype=float),
        end_site_parents=np.array([names.index(p) for p, _ in end_sites], dtype=int),
        end_site_offsets=np.array([o for _, o in end_sites], dtype=float).reshape(-1, 3))


def _hand(fingers):
    """A forearm -> hand with ``fingers``: name -> list of offsets along the finger (from the hand)."""
    joints = [("Forearm", None, (0, 0, 0)), ("Hand", "Forearm", (0.26, 0, 0))]
    for name, offs in fingers.items():
        parent = "Hand"
        for k, o in enumerate(offs):
            joints.append((f"{name}{k}", parent, o))
            parent = f"{name}{k}"
    return _rig(joints)


def test_an_end_site_is_the_hit_point():
    rig = _rig([("Forearm", None, (0, 0, 0)), ("Hand", "Forearm", (0.26, 0, 0))], [("Hand", (0.09, 0.01, 0))])
    off, src = hit_offset(rig, "Hand")
    assert src == "end_site" and np.allclose(off, (0.09, 0.01, 0))


def test_fingers_without_metacarpals_land_on_the_knuckles_without_the_thumb():
    # Mixamo / Unity: the proximal phalanx sits a palm's length from the wrist
    rows = {"Index": 0.02, "Middle": 0.0, "Ring": -0.02, "Pinky": -0.04}
    fingers = {n: [(0.09, 0, z), (0.04, 0, 0), (0.03, 0, 0)] for n, z in rows.items()}
    fingers["Thumb"] = [(0.02, -0.01, 0.03), (0.03, 0, 0.02), (0.03, 0, 0.01)]
    off, src = hit_offset(_hand(fingers), "Hand")
    assert src == "knuckles"
    np.testing.assert_allclose(off, (0.09, 0.0, np.mean(list(rows.values()))), atol=1e-12)


def test_metacarpal_joints_do_not_move_the_knuckles():
    # MakeHuman: a short wrist -> metacarpal offset, then the palm's bone; MotionBuilder: one metacarpal
    # carrying two fingers
    mh = {n: [(0.015, 0, z), (0.075, 0, z * 0.5), (0.04, 0, 0)] for n, z in
          {"Index": 0.02, "Middle": 0.0, "Ring": -0.02, "Pinky": -0.04}.items()}
    off, src = hit_offset(_hand(mh), "Hand")
    assert src == "knuckles"
    np.testing.assert_allclose(off, (0.09, 0.0, np.mean([0.03, 0.0, -0.03, -0.06])), atol=1e-12)
    mb = _rig([("Hand", None, (0, 0, 0)),
               ("Ring", "Hand", (0.004, 0, -0.01)), ("Ring1", "Ring", (0.08, 0, 0)), ("Ring2", "Ring1", (0.04, 0, 0)),
               ("Pinky", "Ring", (0.003, 0, -0.01)), ("Pinky1", "Pinky", (0.07, 0, 0)), ("Pinky2", "Pinky1", (0.03, 0, 0)),
               ("Middle1", "Hand", (0.09, 0, 0)), ("Middle2", "Middle1", (0.045, 0, 0))])
    off, _ = hit_offset(mb, "Hand")
    np.testing.assert_allclose(off, np.mean([(0.084, 0, -0.01), (0.077, 0, -0.02), (0.09, 0, 0)], axis=0), atol=1e-12)


def test_a_bare_joint_is_its_own_hit_point_and_bad_input_is_refused():
    rig = _rig([("Forearm", None, (0, 0, 0)), ("Hand", "Forearm", (0.26, 0, 0))])
    off, src = hit_offset(rig, 1)
    assert src == "joint" and not off.any()
    with pytest.raises(MotionError, match="unknown joint"):
        hit_offset(rig, "Foot")
    with pytest.raises(MotionError, match="joint"):
        hit_offset(rig, 7)
    with pytest.raises(MotionError, match="Skeleton or a Motion"):
        hit_offset("rig", 0)


FINGERED = ["formats/pybvh/bvh_test3.bvh", "formats/realrigs/threejs_pirouette_daz.bvh",
            "formats/realrigs/shadermotion_unity_humanoid.bvh",
            "formats/realrigs/freedance_blender_rigify_names.bvh"]  # Rigify f_ring_01_R: was the fist (issue 25)


@pytest.mark.parametrize("name", FINGERED)
def test_real_hands_with_fingers_have_knuckles_a_palm_from_the_wrist(name):
    from repro import data
    from repro.motion import read_bvh
    from repro.motion.body.skeleton import skeleton_of

    path = Path(data.data_dir()) / "mocap" / name
    if not path.is_file():
        pytest.skip(f"{name} is not staged")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sk = skeleton_of(read_bvh(path))
    for side in ("left", "right"):
        assert sk.roles[f"{side}_fist"] == sk.roles[f"{side}_wrist"]  # the hand, not one of its fingers
        hand = sk.index(f"{side}_fist")
        off, src = hit_offset(sk, hand)
        forearm = np.linalg.norm(sk.offsets[sk.index(f"{side}_wrist")])
        assert src == "knuckles"
        assert 0.25 < np.linalg.norm(off) / forearm < 0.6, (side, off, forearm)  # a palm is about 0.4 forearm
