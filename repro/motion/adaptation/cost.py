"""The price of an adaptation: how far the played motion departs from the clip it was made from.

"After adaptation the error is 0" can always be bought by bending the body further; the
paper's argument (a small database plus adaptation rather than a huge one) trades
coverage against departure from captured motion.  :func:`adaptation_cost` measures the
departure of an adapted motion from its reference (the retargeted, placed and blended
clip) on the same skeleton:

* ``rotation_change_mean_deg`` / ``rotation_change_max_deg``: the angle between each
  joint's local rotation in the two motions, mean over the frames that changed and every
  joint, and the largest;
* ``added_acceleration_max_mps2``: the largest ``|a_adapted - a_reference|`` of a joint's
  world acceleration (second difference of positions, metres per second squared), and
  ``acceleration_ratio``: the largest joint acceleration of the adapted motion over the
  reference's own (1 = no faster than captured);
* ``bone_length_error_m``: the largest change of a joint-to-parent distance from the
  skeleton's bone length;
* ``joint_limit_violations``: (frame, joint) pairs where a ball joint turned further
  from the reference than its cone limit (:func:`~repro.motion.adaptation.ccd_solver.cone_limits`,
  the wrists and ankles excluded: they keep their world orientation) or an elbow / knee
  bends beyond :data:`~repro.motion.adaptation.ccd_solver.DEFAULT_HINGE_RANGE_DEG`;
* ``root_shift_max_m``: the largest displacement of the root position.
"""

from __future__ import annotations

import numpy as np

from repro.checks import describe
from repro.errors import MotionError
from repro.motion.adaptation.ccd_solver import DEFAULT_HINGE_RANGE_DEG, cone_limits
from repro.motion.core.motion import Motion
from repro.motion.body.skeleton import Skeleton, skeleton_of

__all__ = ["COST_KEYS", "adaptation_cost"]

#: Keys of :func:`adaptation_cost`.
COST_KEYS: tuple[str, ...] = (
    "rotation_change_mean_deg", "rotation_change_max_deg", "added_acceleration_max_mps2", "acceleration_ratio",
    "bone_length_error_m", "joint_limit_violations", "root_shift_max_m",
)


def _angles(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    d = np.abs(np.sum(q0 * q1, axis=-1))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


def _acc(g: np.ndarray, dt: float) -> np.ndarray:
    return (g[2:] - 2.0 * g[1:-1] + g[:-2]) / (dt * dt)


def adaptation_cost(reference: Motion, adapted: Motion, skeleton: Skeleton | None = None, *,
                    frames: slice = slice(None), limits=None) -> dict:
    """The departure of ``adapted`` from ``reference`` (same skeleton and frames), see the module docstring.

    ``frames`` selects the frames measured (e.g. ``slice(1, None)``: after the current
    pose).  Lengths in metres (the motions' ``unit_m``, else metres assumed).
    """
    if not isinstance(reference, Motion) or not isinstance(adapted, Motion):
        raise MotionError("adaptation_cost needs two Motion objects")
    if reference.rotations.shape != adapted.rotations.shape:
        raise MotionError(f"the motions differ in shape: {reference.rotations.shape} vs {adapted.rotations.shape}")
    if not isinstance(frames, slice):
        raise MotionError(f"frames must be a slice of frames (e.g. slice(1, None)), got {describe(frames)}")
    if skeleton is not None and not isinstance(skeleton, Skeleton):
        raise MotionError(f"skeleton must be None or a Skeleton, got {describe(skeleton)}")
    if skeleton is not None and skeleton.n_joints != adapted.n_joints:
        raise MotionError(f"skeleton has {skeleton.n_joints} joints, the motions {adapted.n_joints}")
    sk = skeleton_of(adapted) if skeleton is None else skeleton
    u = adapted.unit_m if adapted.unit_m is not None else 1.0
    r0 = np.asarray(reference.rotations)[frames]
    r1 = np.asarray(adapted.rotations)[frames]
    ang = _angles(r0, r1)  # (n, J)
    g0 = reference.global_positions() * u
    g1 = adapted.global_positions() * u
    moved = np.any(ang > 1e-9, axis=1)
    dt = adapted.frame_time
    if adapted.n_frames >= 3:
        a0, a1 = _acc(g0, dt), _acc(g1, dt)
        added = float(np.linalg.norm(a1 - a0, axis=-1).max())
        peak0 = float(np.linalg.norm(a0, axis=-1).max())
        ratio = float(np.linalg.norm(a1, axis=-1).max() / peak0) if peak0 > 0 else float("nan")
    else:
        added, ratio = 0.0, float("nan")
    par = np.asarray(sk.parents)
    bl = np.linalg.norm(g1[:, 1:] - g1[:, par[1:]], axis=-1)
    bone = float(np.abs(bl - np.asarray(sk.bone_lengths)[None, 1:] * u).max())  # skeleton in the motion's units
    # joint limits: ball joints by cone, hinges by flexion
    cones = cone_limits(adapted)
    hinge = {sk.index(f"{s}_{r}") for s in ("left", "right") for r in ("elbow", "knee") if f"{s}_{r}" in sk.roles}
    free = hinge | {sk.index(f"{s}_{r}") for s in ("left", "right") for r in ("wrist", "ankle") if f"{s}_{r}" in sk.roles}
    ball = np.array([j not in free for j in range(ang.shape[1])])
    viol = int(np.sum((ang > cones[None, :] + 1e-6) & ball[None, :]))
    hi = np.radians(DEFAULT_HINGE_RANGE_DEG[1])
    for j in hinge:
        p, c = int(par[j]), [i for i in range(len(par)) if par[i] == j]
        if p < 0 or not c:
            continue
        u1 = g1[frames, j] - g1[frames, p]
        u2 = g1[frames, c[0]] - g1[frames, j]
        cosf = np.sum(u1 * u2, -1) / np.maximum(np.linalg.norm(u1, axis=-1) * np.linalg.norm(u2, axis=-1), 1e-300)
        flex = np.arccos(np.clip(cosf, -1.0, 1.0))
        viol += int(np.sum(flex > hi + 1e-6))
    root = np.linalg.norm((np.asarray(adapted.positions)[frames, 0] - np.asarray(reference.positions)[frames, 0]) * u,
                          axis=-1)
    return {
        "rotation_change_mean_deg": float(np.degrees(ang[moved].mean())) if moved.any() else 0.0,
        "rotation_change_max_deg": float(np.degrees(ang.max(initial=0.0))),
        "added_acceleration_max_mps2": added,
        "acceleration_ratio": ratio,
        "bone_length_error_m": bone,
        "joint_limit_violations": viol,
        "root_shift_max_m": float(root.max(initial=0.0)),
    }
