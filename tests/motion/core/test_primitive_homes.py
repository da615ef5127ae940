"""The one home of each motion primitive: the trusted Motion constructor, strict number
tokens, the no-clobber atomic write, the hit-point trajectory and forward kinematics."""

import io

import numpy as np
import pytest

from repro.errors import BVHError
from repro.io import atomic_path
from repro.motion import Motion, read_bvh, write_bvh
from repro.motion.database.annotation import hit_point_trajectory
from repro.motion.core.kinematics import depth_levels, fk_arrays
from repro.motion.io.tokens import finite_float

BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 @off@ 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Spine
  {
    OFFSET 0 1 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 1 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.01
0 1 0 10 20 30 5 6 7
0 2 0 0 0 0 40 50 60
"""


def _motion() -> Motion:
    return read_bvh(io.BytesIO(BVH.replace("@off@", "1").encode()))


def _off_by_ulps(m: Motion) -> np.ndarray:
    """The motion's rotations with every norm a few ulps away from 1 (still unit within 1e-6)."""
    return np.asarray(m.rotations) * (1.0 + 4 * np.finfo(float).eps)


def test_trusted_constructor_keeps_unit_quaternions_bit_for_bit():
    m = _motion()
    rot = _off_by_ulps(m)
    assert not np.array_equal(Motion(**_fields(m, rotations=rot)).rotations, rot)  # re-normalised
    t = Motion.from_unit_rotations(**_fields(m, rotations=rot))
    assert np.array_equal(t.rotations, rot) and not t.rotations.flags.writeable
    assert np.array_equal(m.with_unit_rotations(rot).rotations, rot)
    np.testing.assert_allclose(t.global_positions(), m.global_positions(), atol=1e-12)


def test_trusted_constructor_still_checks():
    m = _motion()
    with pytest.raises(BVHError, match="not unit quaternions"):
        m.with_unit_rotations(np.asarray(m.rotations) * 1.01)
    with pytest.raises(BVHError, match="NaN or inf"):
        m.with_unit_rotations(np.full_like(m.rotations, np.nan))
    with pytest.raises(BVHError, match=r"positions must be"):
        Motion.from_unit_rotations(**_fields(m, positions=np.zeros((1, 2, 3))))
    with pytest.raises(TypeError, match="missing field"):
        Motion.from_unit_rotations(joint_names=m.joint_names)
    with pytest.raises(TypeError, match="unexpected"):
        Motion.from_unit_rotations(**_fields(m), colour="red")


def _fields(m: Motion, **changes) -> dict:
    f = {k: getattr(m, k) for k in ("joint_names", "parents", "offsets", "channels", "frame_time", "rotations",
                                    "positions", "end_site_parents", "end_site_offsets", "unit_m", "source")}
    f.update(changes)
    return f


@pytest.mark.parametrize(("tok", "what"), [("1_0", "not a finite number"), ("inf", "not a finite number"),
                                           ("nan", "not a finite number"), ("\u0661", "not a finite number"),
                                           ("abc", "not a number")])
def test_strict_number_tokens(tok, what):
    with pytest.raises(BVHError, match=f"^here: {tok!r} is {what}$".replace("\\", "\\\\")):
        finite_float(tok, "here:")
    assert finite_float("-1.5e3", "here:") == -1500.0


def test_bvh_offset_refuses_other_scripts_digits():
    # float() reads Arabic-Indic digits; a BVH OFFSET is ASCII (as the ASF reader already required)
    with pytest.raises(BVHError, match=r"\(OFFSET\): '\u0661' is not a finite number"):
        read_bvh(io.BytesIO(BVH.replace("@off@", "\u0661").encode()))


def test_atomic_path_without_replace_never_clobbers(tmp_path):
    p = tmp_path / "a.txt"
    with atomic_path(p, replace=False) as tmp:
        tmp.write_text("one")
    with pytest.raises(FileExistsError), atomic_path(p, replace=False) as tmp:
        tmp.write_text("two")
    assert p.read_text() == "one" and sorted(x.name for x in tmp_path.iterdir()) == ["a.txt"]
    with atomic_path(p) as tmp:
        tmp.write_text("three")
    assert p.read_text() == "three"


def test_write_bvh_refuses_existing_and_leaves_no_temporary(tmp_path):
    m = _motion()
    p = write_bvh(m, tmp_path / "m.bvh")
    before = p.read_bytes()
    with pytest.raises(FileExistsError):
        write_bvh(m.scaled(2.0), p)
    assert p.read_bytes() == before and [x.name for x in tmp_path.iterdir()] == ["m.bvh"]
    write_bvh(m.scaled(2.0), p, overwrite=True)
    assert p.read_bytes() != before


def test_hit_point_trajectory_with_given_positions():
    m = _motion()
    g = m.global_positions()
    assert np.array_equal(hit_point_trajectory(m, "Spine", positions=g), g[:, 1])
    assert np.array_equal(hit_point_trajectory(m, "Spine", "end_site"), m.end_site_positions()[:, 0])
    # a joint without an End Site: the knuckles of the joints below it (repro.motion.body.hit_points), here the
    # end of the Hips' longest path segment
    from repro.motion.body.hit_points import hit_offset
    from repro.motion.core.quaternion import quat_rotate

    gq, gp = m.global_transforms()
    off, src = hit_offset(m, "Hips")
    assert src == "knuckles"
    np.testing.assert_array_equal(hit_point_trajectory(m, "Hips", "end_site"), gp[:, 0] + quat_rotate(gq[:, 0], off[None]))


def test_motion_fk_is_fk_arrays():
    m = _motion()
    gq, gp = fk_arrays(depth_levels(m.parents), m.rotations, m.local_translations())
    mq, mp = m.global_transforms()
    assert np.array_equal(gq, mq) and np.array_equal(gp, mp)
