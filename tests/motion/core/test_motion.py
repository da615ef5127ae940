"""repro.motion.core.motion: hostile arguments to Motion and its methods get the library's errors (issue 23)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.errors import BVHError, MotionError, ReproError
from repro.motion.core.motion import Motion, UnknownJointError, finite_vector3
from repro.motion.database.synthetic import synthetic_skeleton


@pytest.fixture(scope="module")
def m() -> Motion:
    return synthetic_skeleton()


@pytest.mark.parametrize(
    "field, value",
    [
        ("frame_time", "x"),  # was a bare ValueError from float()
        ("frame_time", None),
        ("frame_time", 1j),
        ("unit_m", "m"),  # was a bare TypeError from np.isfinite
        ("unit_m", -1.0),
        ("rotations", "abc"),
        ("rotations", [[["a", "b", "c", "d"]]]),
        ("positions", None),
        ("offsets", "x"),
        ("end_site_offsets", object()),
        ("channels", 3),
        ("joint_names", "abc"),
        ("up", ["y"]),
    ],
)
def test_a_motion_of_bad_fields_is_a_bvh_error(m, field, value):
    with pytest.raises(BVHError, match=field.split("_")[0]):
        dataclasses.replace(m, **{field: value})


def test_joint_index_is_a_motion_error_and_a_key_error(m):
    with pytest.raises(UnknownJointError, match="no joint 'nope'"):
        m.joint_index("nope")
    with pytest.raises(MotionError, match="string"):
        m.joint_index(["pelvis"])
    assert issubclass(UnknownJointError, KeyError) and issubclass(UnknownJointError, ReproError)


@pytest.mark.parametrize("factor", ["2", None, True, float("nan"), -1.0, 0.0])
def test_scaled_refuses_bad_factors(m, factor):
    with pytest.raises(BVHError, match="scale factor"):
        m.scaled(factor)


def test_scaled_and_to_metres_refuse_bad_units(m):
    with pytest.raises(BVHError, match="unit_m"):
        m.scaled(2.0, unit_m="x")
    with pytest.raises(BVHError, match="unit_m"):
        m.to_metres(unit_m=-1.0)


@pytest.mark.parametrize("value", ["abc", [1j, 0, 0], [True, False, True], None, [0.0, 1.0]])
def test_finite_vector3_refuses_what_is_not_three_real_numbers(value):
    with pytest.raises(MotionError, match="3-vector"):
        finite_vector3(value, "target")


def test_finite_vector3_refuses_coordinates_whose_squares_overflow():
    with pytest.raises(MotionError, match="beyond"):
        finite_vector3([0.0, 1e300, 0.0], "target")
    np.testing.assert_array_equal(finite_vector3([0.0, 1e99, 0.0], "target"), [0.0, 1e99, 0.0])


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("joint_names", np.array(1.0), "joint_names"),  # found by the argument fuzzer: TypeError
        ("joint_names", np.zeros(10**6 + 1), "joints"),  # 10**7 names: minutes
        ("parents", range(10**12), "parents"),  # MemoryError
        ("end_site_parents", range(10**12), "end_site_parents"),
        ("source", float("nan"), "source"),  # a NaN source came back in the Motion
    ],
)
def test_motion_fields_found_by_the_argument_fuzzer(m, field, value, match):
    with pytest.raises(BVHError, match=match):
        dataclasses.replace(m, **{field: value})


def test_a_rebuilt_motion_takes_its_validated_structure_from_the_memo(m):
    """A motion rebuilt on a skeleton already validated (the memo of names and channels) has the
    same fields as one validated from scratch, its own copies of them, and bad input is still refused."""
    from repro.motion.core import motion as motion_module

    again = dataclasses.replace(m, rotations=np.array(m.rotations))
    assert motion_module._structure_key(again.joint_names, again.channels) in motion_module._STRUCTURES
    motion_module._STRUCTURES.clear()
    fresh = dataclasses.replace(m, rotations=np.array(m.rotations))
    for got in (again, fresh):
        assert got.joint_names == m.joint_names and got.channels == m.channels
        assert type(got.joint_names) is list and all(type(n) is str for n in got.joint_names)
        assert np.array_equal(got.position_mask, m.position_mask) and got.rotation_orders == m.rotation_orders
        assert got.joint_names is not m.joint_names and got.position_mask is not m.position_mask
    again.position_mask[0, 0] = not again.position_mask[0, 0]  # its own copy: the next motion is not changed
    assert np.array_equal(dataclasses.replace(m).position_mask, m.position_mask)
    # names equal to validated ones as numpy strings find the memo and come back as str
    named = dataclasses.replace(m, joint_names=[np.str_(n) for n in m.joint_names])
    assert all(type(n) is str for n in named.joint_names) and named.joint_names == m.joint_names
    # the memo holds only what was validated: a repeated name or channel is refused after it
    dup = list(m.joint_names)
    dup[1] = dup[0]
    with pytest.raises(BVHError, match="duplicate joint names"):
        dataclasses.replace(m, joint_names=dup)
    ch = list(m.channels)
    ch[1] = ch[1] + ch[1][-1:]
    with pytest.raises(BVHError, match="repeated channel"):
        dataclasses.replace(m, channels=ch)
    with pytest.raises(BVHError, match="parents"):
        dataclasses.replace(m, parents=np.zeros(m.n_joints, dtype=int))
