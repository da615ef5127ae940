"""The generated characters of repro.motion.database.synthetic.conventions (issue 25, item 9).

What is asserted: each character of ``CHARACTERS`` is what its fields say (stature, unit, up
axis, proportions 10-25 % off the actor's, rest pose, spine joints, fingers and no hand End
Site, toes or none, twist bones, zero-length helpers), is deterministic, and the role finder
puts the roles on the joints it was built with (twist joints inside the limb chains and a
zero-length helper at the shoulder included); the joint-list edits keep the body.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.body.skeleton import Skeleton
from repro.motion.body.units import infer_up
from repro.motion.core.kinematics import rest_positions
from repro.motion.database.synthetic.conventions import (
    CHARACTERS,
    REST_POSE_DEG,
    UNITS_M,
    RigConvention,
    build_character,
)

NAMES = tuple(CHARACTERS)
CHAIN_TWIST = {n for n, c in CHARACTERS.items() if c.twist == "chain"}


def _y_up(m, up: str) -> np.ndarray:
    """Rest positions of joints and End Sites, metres, Y up."""
    p = rest_positions(m.parents, m.offsets)
    pts = np.concatenate([p, p[m.end_site_parents] + m.end_site_offsets]) * m.unit_m
    return pts[:, [0, 2, 1]] * np.array([1.0, 1.0, -1.0]) if up == "z" else pts


def _chain(m, top: str, bottom: str) -> list[str]:
    """Joints strictly between ``bottom`` and its ancestor ``top``."""
    j, out = m.joint_names.index(bottom), []
    while m.joint_names[m.parents[j]] != top:
        j = int(m.parents[j])
        out.append(m.joint_names[j])
    return out[::-1]


def _length(p, a: str, b: str, m) -> float:
    return float(np.linalg.norm(p[m.joint_names.index(b)] - p[m.joint_names.index(a)]))


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("height", [1.2, 2.2])
def test_character_is_what_it_says(name, height):
    spec = CHARACTERS[name]
    m, built = build_character(name, height)
    assert m.unit_m == UNITS_M[spec.unit]
    assert infer_up(m, Skeleton.from_motion(m)) == spec.up
    p = _y_up(m, spec.up)
    assert p[:, 1].min() == pytest.approx(0.0, abs=1e-12)
    assert p[:, 1].max() == pytest.approx(height, rel=1e-12)  # floor to the top of the head
    # proportions: arm and leg lengths against the torso's, the actor's ratios times the factors
    am = RigConvention.synthetic().motion(unit_m=1.0)  # the source actor
    q = rest_positions(am.parents, am.offsets)
    ref = {"arm": _length(q, "LeftArm", "LeftForeArm", am) + _length(q, "LeftForeArm", "LeftHand", am),
           "leg": _length(q, "LeftUpLeg", "LeftLeg", am) + _length(q, "LeftLeg", "LeftFoot", am),
           "torso": _length(q, "Hips", "Neck", am)}
    got = {"arm": _length(p, built["left_shoulder"], built["left_elbow"], m) + _length(p, built["left_elbow"], built["left_wrist"], m),
           "leg": _length(p, built["left_hip"], built["left_knee"], m) + _length(p, built["left_knee"], built["left_ankle"], m),
           "torso": _length(p, built["pelvis"], built["neck"], m)}  # fmt: skip
    want = {"arm": spec.arm, "leg": spec.leg, "torso": spec.torso}
    for k in ("arm", "leg"):
        assert got[k] / got["torso"] == pytest.approx(ref[k] / ref["torso"] * want[k] / want["torso"], rel=1e-9), k
    assert 0.10 <= max(abs(f - 1.0) for f in want.values()) <= 0.25
    # rest pose: the upper arm's angle below horizontal
    u = p[m.joint_names.index(built["left_elbow"])] - p[m.joint_names.index(built["left_shoulder"])]
    deg = np.degrees(np.arcsin(-u[1] / np.linalg.norm(u)))
    assert deg == pytest.approx(30.0 if spec.convention == "unity" else REST_POSE_DEG[spec.rest_pose], abs=1e-6)
    # spine joints, toes, fingers, twist bones, zero-length helpers
    assert len(_chain(m, built["pelvis"], built["neck"])) == spec.spine
    assert ("left_toe" in built) == spec.toes
    for side in ("left", "right"):
        hand = m.joint_names.index(built[f"{side}_wrist"])
        kids = [j for j in range(m.n_joints) if m.parents[j] == hand]
        assert len(kids) == (5 if spec.fingers else 0) + (1 if spec.convention == "smpl" else 0)
        assert (hand in m.end_site_parents) == (not spec.fingers)
        for j in kids[:5] if spec.fingers else ():
            depth = 1
            while (j := next((c for c in range(m.n_joints) if m.parents[c] == j), -1)) >= 0:
                depth += 1
            assert depth == spec.fingers
    twists = [n for n in m.joint_names if "twist" in n.lower()]
    assert (spec.twist != "none") == bool(twists)
    if spec.twist == "chain":
        assert any("twist" in n for n in _chain(m, built["left_shoulder"], built["left_elbow"]))
    assert sum(np.linalg.norm(o) == 0 for o in m.offsets) == spec.helpers


def test_characters_are_deterministic():
    for name in NAMES:
        (a, ra), (b, rb) = build_character(name, 1.6), build_character(name, 1.6)
        assert a.joint_names == b.joint_names and ra == rb
        assert np.array_equal(a.offsets, b.offsets) and np.array_equal(a.end_site_offsets, b.end_site_offsets)


@pytest.mark.parametrize("name", NAMES)
def test_roles_found_where_built(name):
    """Every character, those with twist joints inside the limb chains (and a zero-length helper at
    the shoulder) included: the twist joints lie between the anatomical joints."""
    m, built = build_character(name)
    roles = Skeleton.from_motion(m).roles
    assert {k: roles.get(k) for k in built} == built
    for side in ("left", "right") if name in CHAIN_TWIST else ():
        between = _chain(m, built[f"{side}_shoulder"], built[f"{side}_elbow"])
        assert between and all("twist" in n or "helper" in n for n in between)


def test_refuses_an_unknown_character():
    with pytest.raises(MotionError, match="character"):
        build_character("maya")


def test_joint_list_edits_keep_the_body():
    r = RigConvention.synthetic()
    before = dict(zip(r.names, r.rest_points()))
    r.remove("Spine1")  # the chest's children hang from the spine, where they were
    after = dict(zip(r.names, r.rest_points()))
    assert "Spine1" not in after and r.parents[r.i("Neck")] == "Spine"
    for n, p in after.items():
        np.testing.assert_allclose(p, before[n], atol=1e-15)
    r.remove("LeftToeBase", end_site=True)  # the ankle's End Site at the ball
    np.testing.assert_allclose(r.rest_points()[len(r.names) + list(r.end_sites).index("LeftFoot")],
                               before["LeftToeBase"], atol=1e-15)
    r.fingers("LeftHand", "Left{f}{seg}", 1.0, segments=2)
    assert "LeftIndexIntermediate" in r.names and "LeftIndexDistal" not in r.names
    r.stand(1.5).scale(100.0)
    y = r.rest_points()[:, 1]
    assert y.min() == pytest.approx(0.0, abs=1e-9) and y.max() - y.min() == pytest.approx(150.0)
