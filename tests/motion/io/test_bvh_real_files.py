"""Forward kinematics on the real CMU and Bandai Namco BVH files, checked against the
independent reader ``bvhio`` (test-only dependency) and against the sizes recorded in
the datasets' PROVENANCE.md."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro import data
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, read_bvh

bvhio = pytest.importorskip("bvhio")


def _bvhio_world_positions(path, frames):
    """World joint positions from bvhio (glm, float32), joints in bvhio's layout order."""
    root = bvhio.readAsHierarchy(str(path))
    layout = root.layout()
    names = [joint.Name for joint, _, _ in layout]
    out = []
    for f in frames:
        root.loadPose(int(f))
        out.append([list(joint.PositionWorld) for joint, _, _ in layout])
    return names, np.array(out, dtype=float)


def _check_against_bvhio(rel_path, n_samples):
    path = data.fetch(rel_path)
    m = read_bvh(path)
    frames = np.unique(np.linspace(0, m.n_frames - 1, n_samples).round().astype(int))
    names, ref = _bvhio_world_positions(path, frames)
    assert names == m.joint_names
    ours = m.global_positions()[frames]
    scale = np.abs(ref).max()
    # bvhio computes in float32: agreement is ~1e-7 relative; require 1e-4
    assert np.abs(ours - ref).max() <= 1e-4 * scale
    return m


@pytest.mark.data("cmu-bvh")
@pytest.mark.parametrize("take", ["135_04", "07_05"])
def test_cmu_fk_matches_bvhio(take):
    m = _check_against_bvhio(f"mocap/cmu/{take}.bvh", 12)
    assert m.n_joints == 31 and m.n_channels == 96


@pytest.mark.data("bandai")
def test_bandai_fk_matches_bvhio():
    _check_against_bvhio("mocap/bandai/dataset-1_kick_normal_001.bvh", 12)


@pytest.mark.data("bandai")
def test_bandai_position_channels_replace_offsets():
    m = read_bvh(data.fetch("mocap/bandai/dataset-1_walk_normal_001.bvh"), unit_m=BANDAI_UNIT_M)
    assert m.n_joints == 22 and m.frame_time == pytest.approx(1 / 30, rel=1e-5)
    assert all(len(c) == 6 for c in m.channels) and m.position_mask.all()
    # PROVENANCE: below Hips the position channels are constant and equal to the OFFSET
    below = [m.joint_index(n) for n in m.joint_names if n not in ("joint_Root", "Hips")]
    np.testing.assert_allclose(m.positions[:, below], np.broadcast_to(m.offsets[below], (m.n_frames, len(below), 3)), atol=1e-4)
    # Hips carries the root translation (it moves during a walk)
    hips = m.joint_index("Hips")
    assert np.ptp(m.positions[:, hips, 2]) > 50 or np.ptp(m.positions[:, hips, 0]) > 50
    # sizes from PROVENANCE (metres): leg UpperLeg->Foot 0.80, arm UpperArm->Hand 0.47,
    # Head 1.34-1.41 above the lowest joint in the first frame; adding instead of
    # replacing the offsets would double them
    g = m.to_metres().global_positions()

    def length(chain):
        idx = [m.joint_index(n) for n in chain]
        return np.linalg.norm(np.diff(g[0, idx], axis=0), axis=-1).sum()

    assert length(["UpperLeg_L", "LowerLeg_L", "Foot_L"]) == pytest.approx(0.80, abs=0.01)
    assert length(["UpperArm_R", "LowerArm_R", "Hand_R"]) == pytest.approx(0.47, abs=0.01)
    assert 1.34 <= g[0, m.joint_index("Head"), 1] - g[0, :, 1].min() <= 1.41


@pytest.mark.data("cmu-bvh")
@pytest.mark.parametrize("take, units, metres", [("135_08", 28.15, 1.589), ("131_01", 26.25, 1.482), ("09_06", 27.84, 1.571)])
def test_cmu_rest_pose_height_matches_provenance(take, units, metres):
    # PROVENANCE: height = head top to toe tip in the rest pose (all rotations zero),
    # e.g. subject 135: 28.15 units = 1.589 m
    m = read_bvh(data.fetch(f"mocap/cmu/{take}.bvh"), unit_m=CMU_UNIT_M)
    rest = np.zeros((1, m.n_joints, 4))
    rest[..., 3] = 1.0
    still = dataclasses.replace(m, rotations=rest, positions=m.positions[:1])
    names = [m.joint_names[p] for p in m.end_site_parents]
    assert sorted(names) == ["head", "lfingers", "lthumb", "ltoes", "rfingers", "rthumb", "rtoes"]

    def height(mo):
        y = np.concatenate([mo.end_site_positions()[0], mo.global_positions()[0]])[:, 1]
        return y.max() - y.min()

    assert height(still) == pytest.approx(units, abs=0.01)
    assert height(still.to_metres()) == pytest.approx(metres, abs=0.001)
    assert still.end_site_positions()[0, names.index("head"), 1] == (
        still.end_site_positions()[0].max(axis=0)[1]
    )  # the head top is the highest point


@pytest.mark.data("cmu-bvh")  # the formats corpus is staged with the mocap data
def test_makehuman_position_channels_are_displacements():
    """MakeHuman's default rig writes six channels on 143 joints below the root, all about zero (its
    exporter's pose matrices are relative to the rest pose): its frame is its rest pose, not a point."""
    m = read_bvh(data.data_dir() / "mocap/formats/realrigs/makehuman_default_rig_tpose.bvh")
    below = [j for j in range(m.n_joints) if m.parents[j] >= 0 and m.position_mask[j].any()]
    assert len(below) == 143
    np.testing.assert_allclose(m.positions[0, below], m.offsets[below], atol=5e-4)  # displacements of 1e-6..1.2e-4
    g = m.global_positions()[0]
    ankle, head = m.joint_index("foot.L"), m.joint_index("head")
    assert 6.0 < g[head, 2] - g[ankle, 2] < 16.6  # Z-up decimetres: the head well above the ankle
