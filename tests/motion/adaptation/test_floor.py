"""The floor during the Section 3.4.2 edit: kicks and punches keep every foot above it (issue 25, item 2).

Pronost et al. keep the feet on the ground while the constraint offset ``d(t)`` moves the
hit point; the paper says nothing of a target lower than the clip's kick, where ``d(t)``
lowers the kicking foot while it is still near the ground.  What is asserted:

* ``adapt`` on a synthetic high kick aimed 30 cm lower: the kicking foot (ankle, toe,
  End Site) never goes below the floor (it went 9 cm through it), the target is still
  reached at the contact, the support foot does not slide;
* a current pose already through the floor (frame ``t0`` never changes) is lifted out over
  ``foot_blend``, not popped up in one frame;
* the fighter on a synthetic Z-up inch character (3ds Max Biped names, unit not stated),
  on a character with twist joints inside its limb chains (Rigify-style, N-pose)
  and on the real rigs of the formats corpus: after the current pose no joint or End Site
  is more than 1 cm below the floor (the joints none at all) and the planted feet slide
  less than 2 cm, for a kick and a punch, which land within 1 cm; the stance itself has no
  joint or End Site more than 1 cm below the floor (a known failure on five rigs: strict xfail).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from repro import data
from repro.errors import BVHWarning, MotionError, UnitWarning
from repro.motion import read_bvh
from repro.motion.adaptation import AdaptOptions, adapt
from repro.motion.body.feet import foot_contacts, max_foot_slide
from repro.motion.database.synthetic import synthetic_clip
from repro.motion.database.synthetic.conventions import build_character
from repro.motion.runtime.fighter import KungFuFighter

#: how far below the floor a point may be (the issue's bound), and the slide bound (m)
FLOOR_TOL = 0.01
SLIDE_TOL = 0.02


def lowest(m, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Per frame from ``first`` on: the lowest joint height and the lowest End Site height."""
    joints = m.global_positions()[first:, :, 1].min(axis=1)
    ends = m.end_site_positions()[first:, :, 1].min(axis=1) if m.end_site_parents.size else joints
    return joints, ends


def foot_below(m, side: str) -> np.ndarray:
    """(F,) lowest height of the ``side`` foot: the ankle, its descendants and their End Sites."""
    from repro.motion.adaptation.rig import rig_of

    rig = rig_of(m)
    return rig.globals[1][:, rig.sk.index(f"{side}_ankle"), 1] + rig.foot_drop(side)


# ------------------------------------------------------------------ adapt itself
@pytest.fixture(scope="module")
def high_kick():
    m, ann = synthetic_clip("kick_front", "right", "high", seed=3)
    return m, ann


def test_a_kick_aimed_lower_keeps_the_kicking_foot_above_the_floor(high_kick):
    m, ann = high_kick
    tc = int(ann["hit_frame"])
    hit = np.asarray(ann["hit_position"])
    target = hit - np.array([0.0, 0.3, 0.0])  # 30 cm lower than the clip's kick
    contacts = foot_contacts(m)
    free = adapt(m, "right_foot", target, 0, tc, contacts=contacts, options=AdaptOptions(floor=None))
    a = adapt(m, "right_foot", target, 0, tc, contacts=contacts)
    assert foot_below(free.motion, "right").min() < -0.05  # without the floor: through it
    assert a.reached and a.residual < 1e-3
    for side in ("left", "right"):
        assert foot_below(a.motion, side).min() >= -1e-9, side
    joints, ends = lowest(a.motion)
    assert min(joints.min(), ends.min()) >= min(-1e-9, lowest(m)[1][0])
    assert max_foot_slide(a.motion, contacts) < 1e-6
    assert a.bone_length_error < 1e-9
    # the floor raised d(t) only where the foot would be below it: the goals still hold
    np.testing.assert_allclose(a.goals, a.original_hit + a.offsets, atol=1e-12)
    assert np.all(a.offsets[:, 1] >= free.offsets[:, 1] - 1e-12)


def test_a_current_pose_through_the_floor_is_lifted_out_over_the_foot_blend(high_kick):
    m, ann = high_kick
    sunk = dataclasses.replace(m, positions=m.positions - np.array([0.0, 0.03, 0.0]))  # 3 cm through the floor
    tc = int(ann["hit_frame"])
    contacts = foot_contacts(m)
    t0 = 2
    o = AdaptOptions()
    a = adapt(sunk, "right_foot", np.asarray(ann["hit_position"]) - [0.0, 0.03, 0.0], t0, tc, contacts=contacts,
              options=o)
    n_blend = int(round(o.foot_blend / m.frame_time))
    low = foot_below(a.motion, "left")  # the support foot, planted all along
    np.testing.assert_array_equal(a.motion.rotations[: t0 + 1], sunk.rotations[: t0 + 1])
    assert low[t0] < -0.02
    assert np.all(low[t0 + n_blend + 1:] >= -1e-9)
    step = np.diff(low[t0: t0 + n_blend + 2])
    assert np.all(step > 0) and step.max() < 0.03 / (n_blend + 1) * 1.5  # risen over the blend, not popped


# ------------------------------------------------------------------ the fighter on other rigs
def _strikes(db, character):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)  # the unit and the up axis, inferred
        f = KungFuFighter(db, character=character, seed=0)
    size = f.character.size
    f.follow((0.0, 0.85 * size, 0.0), 0.0, snap=True)
    kick = f.kick((0.0, 0.55 * size, 0.0))
    punch = f.punch((0.0, 0.85 * size, 0.0))
    return f, {"kick": kick, "punch": punch}


def _check_floor(f, s, n_blend: int) -> None:
    """After the current pose (frame 0: the fighter's stance), nothing is lower than the floor's bound."""
    joints, ends = lowest(s.motion)
    joints0, ends0 = lowest(s.original)
    assert joints[1:].min() >= -FLOOR_TOL and joints[1:].min() >= -1e-9, (s.kind, joints[1:].min(), joints0.min())
    # End Sites: a stance already through the floor at frame 0 is lifted out over the foot blend
    assert ends[n_blend + 1:].min() >= -FLOOR_TOL, (s.kind, ends[n_blend + 1:].min(), ends0.min())
    assert ends[1:].min() >= min(ends[0], 0.0) - 1e-9, s.kind


def _n_blend(s) -> int:
    return int(round(AdaptOptions().foot_blend / s.motion.frame_time))


@pytest.fixture(scope="module")
def z_up_inch(synthetic_db):
    """A Z-up character in inches (3ds Max Biped names, its own proportions), its unit not stated."""
    m, _ = build_character("biped_inch")
    return _strikes(synthetic_db, dataclasses.replace(m, unit_m=None))


@pytest.mark.parametrize("kind", ["kick", "punch"])
def test_a_z_up_inch_character_keeps_its_feet_above_the_floor(z_up_inch, kind):
    f, strikes = z_up_inch
    s = strikes[kind]
    assert f.character.unit_m == 1.0 and s.reached
    _check_floor(f, s, _n_blend(s))
    joints, ends = lowest(s.motion)
    assert min(joints.min(), ends.min()) >= -1e-9  # this stance stands on the floor: none below it at all
    assert max_foot_slide(s.motion, s.contacts, skeleton=f.character) < SLIDE_TOL


@pytest.fixture(scope="module")
def twist_character(synthetic_db):
    """A Z-up character with twist joints halfway along each limb bone and a zero-length helper at
    the shoulder (Rigify-style names, N-pose), its unit not stated."""
    m, built = build_character("rigify_n")
    return _strikes(synthetic_db, dataclasses.replace(m, unit_m=None)), built


@pytest.mark.parametrize("kind", ["kick", "punch"])
def test_a_character_with_twist_joints_in_its_limbs_strikes_and_keeps_its_feet(twist_character, kind):
    """Twist joints inside the limb chains (issue 25): the roles are the anatomical joints, the limb IK
    carries the twist joints along; the strike lands within 1 cm, nothing goes through the floor,
    the planted feet slide less than 2 cm."""
    (f, strikes), built = twist_character
    assert {k: f.character.roles[k] for k in built} == built
    s = strikes[kind]
    assert s.reached and s.hit_error < 0.01, s.hit_error
    _check_floor(f, s, _n_blend(s))
    assert max_foot_slide(s.motion, s.contacts, skeleton=f.character) < SLIDE_TOL
    twists = [j for j, n in enumerate(s.motion.joint_names) if "twist" in n]
    np.testing.assert_array_equal(s.motion.rotations[:, twists], s.original.rotations[:, twists])  # carried along


#: Real rigs of the formats corpus that the fighter takes (every humanoid file of ``pybvh`` and ``realrigs``)
RIGS = ["pybvh/bvh_test1.bvh", "pybvh/bvh_test2.bvh", "pybvh/bvh_test3.bvh", "pybvh/standard_skeleton.bvh",
        "realrigs/accad_Male1_C03_Run.bvh", "realrigs/emretanirgan_jump_no_end_sites.bvh",
        "realrigs/freedance_blender_rigify_names.bvh", "realrigs/makehuman_default_rig_tpose.bvh",
        "realrigs/makehuman_game_rig_zombiewalk.bvh", "realrigs/shadermotion_unity_humanoid.bvh",
        "realrigs/threejs_pirouette_daz.bvh", "realrigs/mocopi_MCPM_20230410_150228.BVH",
        "realrigs/woosub_coda02_woman.bvh", "realrigs/emretanirgan_matt_happy2.bvh"]

#: Rigs whose rest pose faces -Z or +X once Y-up (their clips faced away from their stance, and the
#: blend turned the body round, until y_up_metres turned them to face +Z as the actors do)
TURNED = {"pybvh/bvh_test1.bvh", "pybvh/standard_skeleton.bvh", "realrigs/emretanirgan_jump_no_end_sites.bvh"}

_CACHE: dict = {}


def _rig_strikes(db, name):
    if name not in _CACHE:
        path = data.data_dir() / "mocap/formats" / name
        if not path.is_file():
            pytest.skip(f"{name} not staged")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", BVHWarning)  # woosub's two short lines (tests/motion/io)
                m = read_bvh(path)
            _CACHE[name] = _strikes(db, m)
        except MotionError as e:  # roles not found on this rig yet: another item of the issue
            _CACHE[name] = str(e)
    if isinstance(_CACHE[name], str):
        pytest.skip(f"the fighter does not take {name}: {_CACHE[name]}")
    return _CACHE[name]


@pytest.mark.data("cmu-bvh")  # the formats corpus is staged with the mocap data
@pytest.mark.parametrize("name", RIGS)
def test_real_rigs_keep_every_joint_above_the_floor(synthetic_db, name):
    f, strikes = _rig_strikes(synthetic_db, name)
    for s in strikes.values():
        _check_floor(f, s, _n_blend(s))


@pytest.mark.data("cmu-bvh")
@pytest.mark.parametrize("name", RIGS)
def test_real_rigs_stance_stands_on_the_floor(synthetic_db, name):
    """The fighter's stance on the character (its current pose before any order): no joint, no End Site
    more than 1 cm below the floor (issue 25: 'no joint below the floor by more than 1 cm, on every rig')."""
    f, _ = _rig_strikes(synthetic_db, name)
    joints, ends = lowest(f.stance)
    assert min(joints.min(), ends.min()) >= -FLOOR_TOL, (joints.min(), ends.min())


@pytest.mark.data("cmu-bvh")
@pytest.mark.parametrize("name", RIGS)
def test_real_rigs_strikes_land_within_1_cm(synthetic_db, name):
    """The kick and the punch reach their targets on every real rig (the issue's bound: 1 cm)."""
    _, strikes = _rig_strikes(synthetic_db, name)
    for s in strikes.values():
        assert s.reached and s.hit_error < 0.01, (s.kind, s.hit_error)


@pytest.mark.data("cmu-bvh")
@pytest.mark.parametrize("name", RIGS)
def test_real_rigs_planted_feet_slide_under_2_cm(synthetic_db, name):
    f, strikes = _rig_strikes(synthetic_db, name)
    for s in strikes.values():
        assert max_foot_slide(s.motion, s.contacts, skeleton=f.character) < SLIDE_TOL, s.kind


@pytest.mark.data("cmu-bvh")
@pytest.mark.parametrize("name", sorted(TURNED))
def test_a_character_facing_away_is_turned_to_face_z(name):
    """The fighter's character faces +Z in its rest pose, as the databases' actors do (y_up_metres)."""
    from repro.motion.body.skeleton import skeleton_of
    from repro.motion.body.units import y_up_metres

    path = data.data_dir() / "mocap" / "formats" / name
    if not path.is_file():
        pytest.skip(f"{name} not staged")
    with pytest.warns(UnitWarning) as caught:  # the unit, and the turn (pytest 8 re-emits what no `match` took)
        sk = skeleton_of(y_up_metres(read_bvh(path)))
    assert any("turned to face +Z" in str(w.message) for w in caught)
    p = sk.rest_positions()
    lateral = p[sk.index("left_hip")] - p[sk.index("right_hip")]
    forward = np.array([-lateral[2], 0.0, lateral[0]])
    assert forward[2] > 0.9 * np.linalg.norm(forward)
