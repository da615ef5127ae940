"""The Mixamo test motion the Section 3.4.2 solver tests share (metres, arms bent forward)."""

from __future__ import annotations

import dataclasses

import numpy as np

from repro.motion import Motion
from repro.motion.core.quaternion import euler_to_quat, quat_multiply
from tests.motion_fixtures import MIXAMO, MIXAMO_NAMES

PARENTS = np.array([-1 if p is None else MIXAMO_NAMES.index(p) for _, p, _ in MIXAMO])
OFFSETS = np.array([o for _, _, o in MIXAMO], dtype=float)
IDX = {n: i for i, n in enumerate(MIXAMO_NAMES)}


def fixture_motion(n_frames: int = 12, seed: int = 0) -> Motion:
    """The shared Mixamo skeleton (metres, T-pose along X) with the arms bent forward."""
    rng = np.random.default_rng(seed)
    J = len(MIXAMO_NAMES)
    eul = np.zeros((n_frames, J, 3))
    for side, s in (("Right", -1.0), ("Left", 1.0)):
        # upper arm swung forward (about Y), elbow bent about Y (hinge), small noise
        eul[:, IDX[f"{side}Arm"], 1] = -s * (60 + 10 * rng.standard_normal(n_frames))
        eul[:, IDX[f"{side}Arm"], 2] = -s * 20
        eul[:, IDX[f"{side}ForeArm"], 1] = -s * (70 + 20 * rng.random(n_frames))
        eul[:, IDX[f"{side}UpLeg"], 0] = -10
        eul[:, IDX[f"{side}Leg"], 0] = 20
        eul[:, IDX[f"{side}Foot"], 0] = -10
    eul[:, IDX["Spine"], 0] = 5 * rng.standard_normal(n_frames)
    rot = euler_to_quat("ZXY", eul[..., [2, 0, 1]])
    pos = np.broadcast_to(OFFSETS, (n_frames, J, 3)).copy()
    rot_ch = ("Zrotation", "Xrotation", "Yrotation")
    channels = [("Xposition", "Yposition", "Zposition") + rot_ch] + [rot_ch] * (J - 1)
    return Motion(
        joint_names=MIXAMO_NAMES,
        parents=PARENTS,
        offsets=OFFSETS,
        channels=channels,
        frame_time=1 / 30,
        rotations=rot,
        positions=pos,
        end_site_parents=np.array([IDX["RightHand"], IDX["LeftHand"]]),
        end_site_offsets=np.array([[-0.08, 0.0, 0.0], [0.08, 0.0, 0.0]]),
        unit_m=1.0,
    )


def with_rotations(m: Motion, frames, rotations) -> Motion:
    rot = np.array(m.rotations)
    rot[frames] = rotations
    return dataclasses.replace(m, rotations=rot)


def quat_angle(a, b):
    """Angle of the rotation between unit quaternions (precise near 0)."""
    d = quat_multiply(np.asarray(a) * np.array([-1, -1, -1, 1.0]), np.asarray(b))
    return 2 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))
