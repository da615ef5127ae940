"""Forward kinematics of repro.motion.Motion on hand-made BVH files with known answers."""

from __future__ import annotations

import dataclasses
import io

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from repro.errors import BVHError, ReproError
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, Motion, read_bvh
from repro.motion.core.quaternion import euler_to_quat, quat_multiply, quat_rotate

# Two joints and an End Site; the answers below are worked out by hand.
TINY = """HIERARCHY
ROOT hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT knee
\t{
\t\tOFFSET 0 -2 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 -3 0
\t\t}
\t}
}
MOTION
Frames: 3
Frame Time: 0.5
1 2 3 0 0 0 0 0 0
0 0 0 90 0 0 0 0 0
10 0 0 0 0 90 90 0 0
"""


def _read(text: str) -> Motion:
    return read_bvh(io.StringIO(text))


def test_tiny_bvh_by_hand():
    m = _read(TINY)
    assert m.joint_names == ["hips", "knee"]
    assert m.parents.tolist() == [-1, 0]
    assert m.n_frames == 3 and m.n_joints == 2 and m.n_channels == 9
    assert m.frame_time == 0.5 and m.fps == 2.0 and m.duration == 1.5
    assert m.channels[1] == ("Zrotation", "Xrotation", "Yrotation")
    assert m.rotation_orders == ["ZXY", "ZXY"]
    np.testing.assert_array_equal(m.offsets, [[0, 0, 0], [0, -2, 0]])
    assert len(m.end_sites) == 1 and m.end_sites[0][0] == 1
    np.testing.assert_array_equal(m.end_sites[0][1], [0, -3, 0])

    g = m.global_positions()
    e = m.end_site_positions()[:, 0]
    # frame 0: pure translation (1, 2, 3)
    np.testing.assert_allclose(g[0], [[1, 2, 3], [1, 0, 3]], atol=1e-12)
    np.testing.assert_allclose(e[0], [1, -3, 3], atol=1e-12)
    # frame 1: root Rz(90) maps (x, y, z) -> (-y, x, z): knee (0,-2,0) -> (2,0,0), tip (0,-5,0) -> (5,0,0)
    np.testing.assert_allclose(g[1], [[0, 0, 0], [2, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(e[1], [5, 0, 0], atol=1e-12)
    # frame 2: root at (10,0,0) with Ry(90): (x, y, z) -> (z, y, -x); knee Rz(90):
    # knee at (10,-2,0); tip offset (0,-3,0) -Rz90-> (3,0,0) -Ry90-> (0,0,-3)
    np.testing.assert_allclose(g[2], [[10, 0, 0], [10, -2, 0]], atol=1e-12)
    np.testing.assert_allclose(e[2], [10, -2, -3], atol=1e-12)
    np.testing.assert_allclose(m.root_positions, [[1, 2, 3], [0, 0, 0], [10, 0, 0]])

    gq, gp = m.global_transforms()
    np.testing.assert_allclose(gp, g)
    # world rotation of the knee in frame 2 is Ry(90) Rz(90)
    expect = Rotation.from_euler("y", 90, degrees=True) * Rotation.from_euler("z", 90, degrees=True)
    np.testing.assert_allclose(Rotation.from_quat(gq[2, 1]).as_matrix(), expect.as_matrix(), atol=1e-12)


def test_channel_order_is_intrinsic_in_listed_order():
    # root "Zrotation Xrotation Yrotation" = 90 90 0 means R = Rz(90) Rx(90), not Rx(90) Rz(90)
    text = TINY.replace("1 2 3 0 0 0 0 0 0", "0 0 0 90 90 0 0 0 0")
    g = _read(text).global_positions()[0, 1]
    Rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    np.testing.assert_allclose(g, Rz @ Rx @ [0, -2, 0], atol=1e-12)  # = (0, 0, -2)
    np.testing.assert_allclose(g, [0, 0, -2], atol=1e-12)


def _axis_matrix(axis: str, deg: np.ndarray) -> np.ndarray:
    """Elementary rotation matrices built by hand (not scipy), shape (F, 3, 3)."""
    t = np.radians(deg)
    c, s = np.cos(t), np.sin(t)
    o, z = np.ones_like(t), np.zeros_like(t)
    rows = {
        "X": [[o, z, z], [z, c, -s], [z, s, c]],
        "Y": [[c, z, s], [z, o, z], [-s, z, c]],
        "Z": [[c, -s, z], [s, c, z], [z, z, o]],
    }[axis]
    return np.moveaxis(np.array(rows), (0, 1), (-2, -1))


MIXED = """HIERARCHY
ROOT pelvis
{
  OFFSET 0.5 1 -0.5
  CHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation
  JOINT spine
  {
    OFFSET 0.1 1.2 0.3
    CHANNELS 3 Yrotation Xrotation Zrotation
    JOINT neck
    {
      OFFSET -0.2 0.9 0.1
      CHANNELS 3 Xrotation Zrotation Yrotation
      JOINT head
      {
        OFFSET 0 0.7 0.2
        CHANNELS 2 Xrotation Zrotation
        End Site
        {
          OFFSET 0 0.3 0
        }
      }
    }
  }
  JOINT leg
  {
    OFFSET 0.4 -0.3 0
    CHANNELS 1 Yrotation
  }
}
MOTION
Frames: {F}
Frame Time: 0.01
{DATA}
"""


def test_other_channel_orders_against_explicit_matrix_products():
    rng = np.random.default_rng(7)
    F = 25
    vals = rng.uniform(-180, 180, size=(F, 6 + 3 + 3 + 2 + 1))
    vals[:, :3] = rng.uniform(-5, 5, size=(F, 3))
    text = MIXED.replace("{F}", str(F)).replace("{DATA}", "\n".join(" ".join(f"{v:.17g}" for v in r) for r in vals))
    m = _read(text)
    assert m.rotation_orders == ["XYZ", "YXZ", "XZY", "XZ", "Y"]

    # expected: 4x4-free explicit chain, R in listed order, p = p_parent + R_parent offset
    Rroot = _axis_matrix("X", vals[:, 3]) @ _axis_matrix("Y", vals[:, 4]) @ _axis_matrix("Z", vals[:, 5])
    Rsp = _axis_matrix("Y", vals[:, 6]) @ _axis_matrix("X", vals[:, 7]) @ _axis_matrix("Z", vals[:, 8])
    Rnk = _axis_matrix("X", vals[:, 9]) @ _axis_matrix("Z", vals[:, 10]) @ _axis_matrix("Y", vals[:, 11])
    Rhd = _axis_matrix("X", vals[:, 12]) @ _axis_matrix("Z", vals[:, 13])
    p_root = vals[:, :3]  # position channels replace the root OFFSET
    G_sp = Rroot @ Rsp
    p_sp = p_root + Rroot @ [0.1, 1.2, 0.3]
    G_nk = G_sp @ Rnk
    p_nk = p_sp + G_sp @ [-0.2, 0.9, 0.1]
    G_hd = G_nk @ Rhd
    p_hd = p_nk + G_nk @ [0, 0.7, 0.2]
    p_leg = p_root + Rroot @ [0.4, -0.3, 0]
    tip = p_hd + G_hd @ [0, 0.3, 0]

    g = m.global_positions()
    np.testing.assert_allclose(g, np.stack([p_root, p_sp, p_nk, p_hd, p_leg], axis=1), atol=1e-10)
    np.testing.assert_allclose(m.end_site_positions()[:, 0], tip, atol=1e-10)
    gq, _ = m.global_transforms()
    np.testing.assert_allclose(Rotation.from_quat(gq[:, 3]).as_matrix(), G_hd, atol=1e-10)


def test_position_channels_replace_offset_components():
    # Bandai-style: every joint has 6 channels whose positions replace (not add to) OFFSET;
    # a joint with only Yposition keeps the other two OFFSET components.
    text = """HIERARCHY
ROOT base
{
  OFFSET 100 100 100
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT arm
  {
    OFFSET 7 8 9
    CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
    JOINT slider
    {
      OFFSET 1 2 3
      CHANNELS 1 Yposition
      End Site
      {
        OFFSET 0 0 0
      }
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 0 0 0 0 0 3 4 5 0 0 0 -6
1 1 1 0 0 0 3 4 5 90 0 0 10
"""
    m = _read(text)
    assert m.position_mask.tolist() == [[True] * 3, [True] * 3, [False, True, False]]
    np.testing.assert_allclose(m.local_translations()[0], [[0, 0, 0], [3, 4, 5], [1, -6, 3]])
    g = m.global_positions()
    np.testing.assert_allclose(g[0], [[0, 0, 0], [3, 4, 5], [4, -2, 8]], atol=1e-12)
    # frame 1: arm Rz(90) turns slider's (1, 10, 3) into (-10, 1, 3)
    np.testing.assert_allclose(g[1], [[1, 1, 1], [4, 5, 6], [-6, 6, 9]], atol=1e-12)


def test_euler_to_quat_matches_scipy_for_all_orders():
    rng = np.random.default_rng(0)
    for seq in ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX", "xyz", "zyx", "yxz", "ZX", "xz", "Y", "z", "XYX", "zxz"]:
        ang = rng.uniform(-400, 400, size=(50, len(seq)))
        ours = euler_to_quat(seq, ang)
        ref = Rotation.from_euler(seq, ang, degrees=True).as_quat()
        np.testing.assert_allclose(np.abs(np.sum(ours * ref, axis=-1)), 1.0, atol=1e-12, err_msg=seq)
    with pytest.raises(ValueError):
        euler_to_quat("Xy", np.zeros(2))
    with pytest.raises(ValueError):
        euler_to_quat("XYZ", np.zeros(2))


def test_quaternion_helpers_match_matrices():
    rng = np.random.default_rng(1)
    a, b = Rotation.random(20, random_state=2), Rotation.random(20, random_state=3)
    v = rng.normal(size=(20, 3))
    ab = quat_multiply(a.as_quat(), b.as_quat())
    np.testing.assert_allclose(Rotation.from_quat(ab).as_matrix(), (a * b).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(quat_rotate(a.as_quat(), v), a.apply(v), atol=1e-12)


def test_units_scaled_and_to_metres():
    m = _read(TINY)
    with pytest.raises(BVHError, match="unit"):
        m.to_metres()
    assert CMU_UNIT_M == pytest.approx(0.056444, abs=1e-6) and BANDAI_UNIT_M == 0.01
    mm = read_bvh(io.StringIO(TINY), unit_m=CMU_UNIT_M)
    metres = mm.to_metres()
    assert metres.unit_m == 1.0
    np.testing.assert_allclose(metres.global_positions(), m.global_positions() * CMU_UNIT_M, atol=1e-12)
    np.testing.assert_allclose(metres.end_site_positions(), m.end_site_positions() * CMU_UNIT_M, atol=1e-12)
    s = m.scaled(2.0)
    np.testing.assert_allclose(s.global_positions(), 2 * m.global_positions(), atol=1e-12)
    np.testing.assert_array_equal(s.rotations, m.rotations)
    with pytest.raises(BVHError):
        m.scaled(0.0)
    with pytest.raises(BVHError):
        m.scaled(float("nan"))


def test_motion_is_immutable_and_validated():
    m = _read(TINY)
    with pytest.raises(ValueError):
        m.rotations[0, 0, 0] = 2.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.frame_time = 1.0
    assert m.joint_index("knee") == 1
    with pytest.raises(KeyError, match="knee"):
        m.joint_index("nope")

    bad = {
        "parents": dict(parents=np.array([0, 0])),
        "cycle": dict(parents=np.array([-1, 1])),
        "names": dict(joint_names=["a", "a"]),
        "offsets": dict(offsets=np.zeros((3, 3))),
        "nan offset": dict(offsets=np.array([[0, 0, np.nan], [0, 0, 0]])),
        "zero quat": dict(rotations=np.zeros((3, 2, 4))),
        "rot shape": dict(rotations=np.zeros((3, 2, 3))),
        "pos shape": dict(positions=np.zeros((2, 2, 3))),
        "frame time": dict(frame_time=0.0),
        "channels": dict(channels=[("Xposition",), ("Wrotation",)]),
        "repeat channel": dict(channels=[("Xposition", "Xposition"), ()]),
        "end site": dict(end_site_parents=np.array([5]), end_site_offsets=np.zeros((1, 3))),
        "unit": dict(unit_m=-1.0),
    }
    for label, change in bad.items():
        with pytest.raises(BVHError) as info:
            dataclasses.replace(m, **change)
        assert isinstance(info.value, ReproError) and isinstance(info.value, ValueError), label


def test_zero_frames_and_rest_pose():
    text = TINY.split("MOTION")[0] + "MOTION\nFrames: 0\nFrame Time: 0.5\n"
    m = _read(text)
    assert m.n_frames == 0
    assert m.global_positions().shape == (0, 2, 3)
    assert m.end_site_positions().shape == (0, 1, 3)
