"""Motions on the Mixamo-named T-pose skeleton of tests.motion_fixtures, for the tests of the
morphology-independent representation (representation, decoding, planted_feet, morphology)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from repro.motion import Motion
from repro.motion.body.skeleton import Skeleton
from tests.motion_fixtures import MIXAMO, MIXAMO_NAMES as NAMES

__all__ = ["CHANNELS", "NAMES", "OFFSETS", "PARENTS", "all_points", "fk_bone_lengths", "make_motion", "random_motion",
           "rest_skeleton", "same_rotation"]

PARENTS = np.array([-1 if p is None else NAMES.index(p) for _, p, _ in MIXAMO])


OFFSETS = np.array([o for _, _, o in MIXAMO])


ROT = ("Zrotation", "Xrotation", "Yrotation")


CHANNELS = [("Xposition", "Yposition", "Zposition") + ROT] + [ROT] * (len(NAMES) - 1)


ES_PARENTS = np.array([NAMES.index("Head"), NAMES.index("LeftHand"), NAMES.index("RightHand")])


ES_OFFSETS = np.array([[0, 0.18, 0], [0.18, 0, 0], [-0.18, 0, 0]])


def make_motion(rotations, root, offsets=OFFSETS, names=NAMES, parents=PARENTS) -> Motion:
    F = rotations.shape[0]
    pos = np.broadcast_to(offsets, (F, len(names), 3)).copy()
    pos[:, 0] = root
    return Motion(
        joint_names=names,
        parents=parents,
        offsets=offsets,
        channels=CHANNELS,
        frame_time=1 / 30,
        rotations=rotations,
        positions=pos,
        end_site_parents=ES_PARENTS,
        end_site_offsets=ES_OFFSETS,
        unit_m=1.0,
    )


def random_motion(seed: int, F: int = 12, max_angle: float = np.pi) -> Motion:
    """Random local rotations (angles up to ``max_angle``) and root positions."""
    rng = np.random.default_rng(seed)
    J = len(NAMES)
    rv = rng.normal(size=(F, J, 3))
    rv *= (rng.uniform(0, max_angle, size=(F, J)) / np.linalg.norm(rv, axis=-1))[..., None]
    q = Rotation.from_rotvec(rv.reshape(-1, 3)).as_quat().reshape(F, J, 4)
    root = rng.normal(scale=[1.0, 0.1, 1.0], size=(F, 3)) + [0, 0.9, 0]
    return make_motion(q, root)


def rest_skeleton() -> Skeleton:
    return Skeleton.from_motion(make_motion(np.tile([0, 0, 0, 1.0], (1, len(NAMES), 1)), [[0, 0.98, 0]]))


def all_points(m: Motion) -> np.ndarray:
    return np.concatenate([m.global_positions(), m.end_site_positions()], axis=1)


def same_rotation(a, b) -> float:
    """Largest ``1 - |<a, b>|`` between unit quaternions (0 = same rotation)."""
    return float(np.max(1.0 - np.abs(np.sum(a * b, axis=-1))))


def fk_bone_lengths(m: Motion) -> np.ndarray:
    g = m.global_positions()
    return np.linalg.norm(g[:, 1:] - g[:, m.parents[1:]], axis=-1)
