"""Channels: their names, a joint's channel layout, and the channel table of a motion.

Part of the motion's representation (a :class:`~repro.motion.core.motion.Motion` keeps each
joint's channels, as BVH files name them): the one place that knows how rotations map to channel
values and back, shared by ``Motion.channel_values`` and the BVH writer (:mod:`~repro.motion.io.bvh`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from repro.errors import BVHError

__all__ = ["POSITION_CHANNELS", "ROTATION_CHANNELS", "channel_layout", "joint_columns", "channel_table"]

#: The BVH position channel names, in axis order x, y, z.
POSITION_CHANNELS: tuple[str, str, str] = ("Xposition", "Yposition", "Zposition")
#: The BVH rotation channel names, in axis order x, y, z.
ROTATION_CHANNELS: tuple[str, str, str] = ("Xrotation", "Yrotation", "Zrotation")


def channel_layout(channels: Sequence[Sequence[str]]) -> tuple[np.ndarray, list[str]]:
    """Position mask (J, 3) and per-joint rotation axis sequence ("ZYX", "" ...)."""
    mask = np.zeros((len(channels), 3), dtype=bool)
    seqs: list[str] = []
    for j, chans in enumerate(channels):
        seq = ""
        for c in chans:
            if c in POSITION_CHANNELS:
                mask[j, POSITION_CHANNELS.index(c)] = True
            elif c in ROTATION_CHANNELS:
                seq += c[0]
            else:
                raise BVHError(f"joint {j}: unknown channel name {c!r}")
        seqs.append(seq)
    return mask, seqs


def joint_columns(motion) -> list[np.ndarray]:
    """Per joint, its (F, n_channels_j) block of channel values (degrees for angles)."""
    F = motion.n_frames
    blocks: list[np.ndarray] = [np.zeros((F, len(c))) for c in motion.channels]
    quats = motion.rotations
    groups: dict[str, list[int]] = {}
    for j, seq in enumerate(motion.rotation_orders):
        groups.setdefault(seq, []).append(j)
    eulers: dict[int, np.ndarray] = {}
    for seq, joints in groups.items():
        q = quats[:, joints].reshape(-1, 4)
        if F == 0:
            for j in joints:
                eulers[j] = np.zeros((0, len(seq)))
            continue
        r = Rotation.from_quat(q)
        if len(seq) == 3:
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message="Gimbal lock")
                ang = r.as_euler(seq, degrees=True)
        else:
            full = seq + "".join(a for a in "XYZ" if a not in seq)
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message="Gimbal lock")
                ang = r.as_euler(full, degrees=True)
            if len(seq) == 2:
                # scipy keeps the middle angle within +-90 deg, so a rotation of the two
                # axes whose second angle is beyond 90 comes out with a third angle of
                # 180: switch to the equivalent triple (a + 180, 180 - b, c + 180)
                flip = np.abs(ang[:, 2]) > 90
                ang[flip, 0] += 180.0
                ang[flip, 1] = 180.0 - ang[flip, 1]
                ang[:, :2] = (ang[:, :2] + 180.0) % 360.0 - 180.0
            ang = ang[:, : len(seq)]
            back = (
                Rotation.from_euler(seq, ang, degrees=True)
                if seq
                else Rotation.identity(len(q))
            )
            err = (back.inv() * r).magnitude()
            if np.any(err > 1e-6):
                i = int(np.argmax(err))
                j = joints[i % len(joints)]
                raise BVHError(
                    f"joint {motion.joint_names[j]!r}: frame {i // len(joints)} has a rotation that its "
                    f"rotation channels ({seq or 'none'}) cannot express (error {np.degrees(err[i]):.3g} deg)"
                )
        ang = ang.reshape(F, len(joints), len(seq))
        for k, j in enumerate(joints):
            eulers[j] = ang[:, k]
    for j, chans in enumerate(motion.channels):
        r = 0
        for c, name in enumerate(chans):
            if name in POSITION_CHANNELS:
                blocks[j][:, c] = motion.positions[:, j, POSITION_CHANNELS.index(name)]
            else:
                blocks[j][:, c] = eulers[j][:, r]
                r += 1
    return blocks


def channel_table(motion) -> np.ndarray:
    blocks = joint_columns(motion)
    return np.concatenate(blocks, axis=1) if blocks else np.zeros((motion.n_frames, 0))
