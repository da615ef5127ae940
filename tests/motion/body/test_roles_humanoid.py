"""Humanoid or not (issue 25, item 4): a skeleton that is not one is refused up front by
find_roles, saying which test failed, whatever its up axis, unit and rest pose."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from repro.errors import BVHError, MotionError
from repro.motion import read_bvh
from repro.motion.body.humanoid import check_humanoid
from repro.motion.body.roles import find_roles
from repro.motion.database.synthetic.conventions import CONVENTIONS, build
from tests.motion.body.test_roles_real_rigs import cmu_without_head, makehuman_default, makehuman_game, rig, sided


def quadruped(spine: float = 1.6, z_up: bool = True, horse_link: bool = False, legs_on: str = "Bip01 Pelvis"):
    """A four-legged animal named like a 3ds Max Biped (an elephant in metres): hind legs off
    ``legs_on``, fore legs (``UpperArm``, ``Forearm``, ``Hand``) off the chest, all four on the
    floor, a horizontal spine of two ``spine``-long links, a head ahead with a trunk hanging
    from it and a tail; facing +Z.  ``horse_link``: Biped's three-link hind legs (``Thigh``,
    ``Calf``, ``HorseLink``, ``Foot``)."""
    j = [("Bip01", None, (0, 0, 0)), ("Bip01 Pelvis", "Bip01", (0, 2.6, 0)),
         ("Bip01 Spine", "Bip01 Pelvis", (0, 0.1, 0.4)), ("Bip01 Spine1", "Bip01 Spine", (0, 0.15, spine)),
         ("Bip01 Spine2", "Bip01 Spine1", (0, 0.1, spine)), ("Bip01 Neck", "Bip01 Spine2", (0, 0.1, 0.5)),
         ("Bip01 Head", "Bip01 Neck", (0, 0.2, 0.5)), ("Bip01 Ponytail1", "Bip01 Head", (0, -0.5, 0.5)),
         ("Bip01 Ponytail11", "Bip01 Ponytail1", (0, -1.0, 0.1)), ("Bip01 Tail", "Bip01 Pelvis", (0, 0, -0.3)),
         ("Bip01 Tail1", "Bip01 Tail", (0, -0.6, -0.2))]
    legs = [("Bip01 {} Thigh", "=" + legs_on, (0.5, -0.1, 0)), ("Bip01 {} Calf", "Bip01 {} Thigh", (0, -1.1, 0.1)),
            ("Bip01 {} Foot", "Bip01 {} Calf", (0, -1.0, -0.05)), ("Bip01 {} Toe0", "Bip01 {} Foot", (0, -0.35, 0.2))]
    if horse_link:
        legs[1:3] = [("Bip01 {} Calf", "Bip01 {} Thigh", (0, -0.8, 0.1)),
                     ("Bip01 {} HorseLink", "Bip01 {} Calf", (0, -0.6, -0.1)),
                     ("Bip01 {} Foot", "Bip01 {} HorseLink", (0, -0.7, 0.05))]
    arms = [("Bip01 {} Clavicle", "=Bip01 Spine2", (0.3, -0.1, 0)),
            ("Bip01 {} UpperArm", "Bip01 {} Clavicle", (0.3, -0.2, 0)),
            ("Bip01 {} Forearm", "Bip01 {} UpperArm", (0, -1.05, 0)), ("Bip01 {} Hand", "Bip01 {} Forearm", (0, -0.95, 0)),
            ("Bip01 {} Finger0", "Bip01 {} Hand", (0, -0.4, 0.15))]
    return rig(j + sided(legs, "L", "R") + sided(arms, "L", "R"), z_up=z_up)


def turned(names, par, off, seed: int):
    """The rig under a random rotation and scale (another up axis, another unit)."""
    rng = np.random.default_rng(seed)
    return names, par, Rotation.random(random_state=rng).apply(off) * float(rng.uniform(0.01, 100.0))


@pytest.mark.parametrize("seed", [None, 0, 1, 2])
@pytest.mark.parametrize("kw", [{}, {"horse_link": True}, {"legs_on": "Bip01 Spine"}])
def test_an_elephant_named_like_a_biped_is_refused_by_its_trunk(seed, kw):
    names, par, off = quadruped(**kw)
    if seed is not None:
        names, par, off = turned(names, par, off, seed)
    with pytest.raises(MotionError, match=r"not a humanoid skeleton: its trunk .* is 1\.\d\d times its legs"):
        find_roles(names, par, offsets=off)


@pytest.mark.parametrize("seed", [None, 3, 4])
@pytest.mark.parametrize("kw", [{"z_up": True}, {"z_up": False}, {"horse_link": True}, {"legs_on": "Bip01 Spine"}])
def test_a_short_quadruped_is_refused_for_standing_on_its_arms(kw, seed):
    names, par, off = quadruped(spine=0.7, **kw)
    if seed is not None:
        names, par, off = turned(names, par, off, seed)
    with pytest.raises(MotionError, match=r"not a humanoid skeleton: its (left|right) arm stands on the floor like a "
                                          r"leg: the wrist is 0\.\d\d leg lengths above the ankles"):
        find_roles(names, par, offsets=off)


def test_a_tracker_set_is_refused():
    # a VR headset and two controllers under a dummy root: no limb at all
    names, par, off = rig([("__0", None, (0, 0, 0)), ("head", "__0", (0, 1.61, 0)), ("hand_l", "__0", (-1, 1, -1)),
                           ("hand_r", "__0", (1, 1.09, -1))])
    for required in (None, ()):
        kw = {} if required is None else {"required": required}
        with pytest.raises(MotionError, match=r"not a humanoid skeleton: its tree is 1 bone\(s\) deep: no room for a "
                                              r"limb .*roles found: \['head'"):
            find_roles(names, par, offsets=off, **kw)


def _mixamo():
    m = build("mixamo")[0].motion(1.0)
    return list(m.joint_names), np.asarray(m.parents), np.array(m.offsets, dtype=float)


def test_limbs_that_are_not_mirror_images_are_refused():
    names, par, off = _mixamo()
    off[names.index("mixamorig:LeftForeArm")] *= 3.0  # a left upper arm three times as long
    with pytest.raises(MotionError, match=r"its arms are not mirror images: left .*, right .* units long, \d+ % apart"):
        find_roles(names, par, offsets=off)


def test_arms_far_longer_than_legs_are_refused():
    names, par, off = _mixamo()
    for s in ("Left", "Right"):
        for b in ("ForeArm", "Hand"):
            off[names.index(f"mixamorig:{s}{b}")] *= 2.8
    with pytest.raises(MotionError, match=r"its arms are 1\.\d\d times as long as its legs .* a human's are about 0\.7"):
        find_roles(names, par, offsets=off)


def test_a_head_below_the_pelvis_is_refused():
    names, par, off = _mixamo()
    for n in ("mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Neck", "mixamorig:Head"):
        off[names.index(n)] *= np.array([1.0, -0.4, 1.0])  # the trunk hanging down (shortened: legs still lowest)
    with pytest.raises(MotionError, match="its head is not above its pelvis"):
        check_humanoid(names, par, off, find_roles(names, par, required=()))


def test_a_leg_that_does_not_reach_the_floor_is_refused():
    names, par, off = _mixamo()
    off[names.index("mixamorig:LeftLeg")] *= np.array([1.0, -1.0, 1.0])  # the left knee folded up: shin pointing up
    roles = find_roles(names, par, required=())
    with pytest.raises(MotionError, match="its left leg does not reach the lowest point of the rest pose"):
        check_humanoid(names, par, off, roles)


def _rest_poses():
    """Humanoid rigs in every rest pose and up axis the tests take: the conventions (T, A, Z up),
    MakeHuman's two rigs, the CMU-style rig without a head with its arms down, a lying one."""
    out = {c: build(c)[0].motion(1.0) for c in CONVENTIONS}
    out = {c: (list(m.joint_names), np.asarray(m.parents), np.array(m.offsets, dtype=float)) for c, m in out.items()}
    out.update(makehuman_default=makehuman_default(), makehuman_n=makehuman_default(85.0),
               makehuman_game=makehuman_game(), cmu_no_head=cmu_without_head(True))
    names, par, off = _mixamo()
    lying = np.zeros_like(off)
    lying[:, 0] = np.linalg.norm(off, axis=1)  # every bone along +X (a lying skeleton, as some exporters write)
    out["lying"] = (names, par, lying)
    return out


@pytest.mark.parametrize("seed", [None, 5])
@pytest.mark.parametrize("which", sorted(_rest_poses()))
def test_humanoids_in_any_rest_pose_and_up_axis_are_accepted(which, seed):
    names, par, off = _rest_poses()[which]
    if seed is not None:
        names, par, off = turned(names, par, off, seed)
    roles = find_roles(names, par, offsets=off, required=())
    check_humanoid(names, par, off, roles)


# ------------------------------------------------------------------ every real rig we have
def _real_files():
    root = Path(os.environ.get("REPRO_DATA_DIR") or "/nonexistent") / "mocap"
    return sorted(p for sub in ("cmu", "bandai", "formats/pybvh", "formats/realrigs") if (root / sub).is_dir()
                  for p in (root / sub).iterdir() if p.suffix.lower() == ".bvh")


#: Files that are no humanoid: a VR tracker set, and two pybvh fixtures of two or four joints.
NOT_HUMANOID = {"godot_vr_trackers_prop.bvh", "full_precision_frame_time.bvh", "rotation_first_root.bvh"}


def test_every_real_humanoid_rig_is_accepted_and_the_others_refused():
    files = _real_files()
    if not files:
        pytest.skip("no mocap staged (set REPRO_DATA_DIR)")
    accepted = 0
    for p in files:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = read_bvh(p)
        except BVHError:
            continue  # a file the reader cannot read yet (End Site spellings): not this test's business
        args = (m.joint_names, m.parents)
        kw = {"offsets": m.offsets, "end_site_parents": m.end_site_parents}
        if p.name in NOT_HUMANOID:
            with pytest.raises(MotionError, match="not a humanoid skeleton"):
                find_roles(*args, **kw)
        else:
            find_roles(*args, **kw)
            accepted += 1
    assert accepted >= 1
