"""Scaling the database: deterministic *synthetic* variants of its clips, for latency versus size.

The paper's database holds about 75 motions; the retrieval's latency is measured on
databases 10, 100 and 1,000 times larger made by :func:`augment` (mirror, actor rescaling,
time warp, feature noise).  These are not new captures (see :func:`augment`).  The variants
of a clip are computed together (one forward kinematics per distinct frame count), so the
1,000x database (4.6 M poses) takes about 24 s of CPU instead of about 25 min one by one
(``repro bench index``).
"""

from __future__ import annotations

import numpy as np

from repro.checks import as_int, as_real, as_real_array, check_alloc, describe
from repro.errors import MotionError
from repro.motion.body.pose_frames import pose_points, root_frames, to_root_frame
from repro.motion.database.clips import MotionDatabase
from repro.motion.core.ops import mirror_joint_map, resample
from repro.motion.core.quaternion import quat_rotate

__all__ = ["augment"]


def augment(db: MotionDatabase, factor: int, seed: int = 0, *, scale_range=(0.85, 1.15), warp_range=(0.85, 1.15),
            noise: float = 0.005, mirror_probability: float = 0.5, pose_dtype=None) -> MotionDatabase:
    """A ``factor`` times larger database of *synthetic* variants, for latency-vs-size.

    "Scaling the database": the paper's database holds about 75 motions; to measure how
    the search time grows with the size of the database, every clip gets ``factor - 1``
    variants (the originals are kept, first), each with parameters drawn from
    ``numpy.random.default_rng(seed)`` in a fixed order (so the result is deterministic):

    * mirrored left/right with probability ``mirror_probability``
      (:func:`mirror_motion`; a punch with the right fist becomes one with the left);
    * the actor rescaled uniformly by a factor in ``scale_range`` (a new, taller or
      smaller actor: every length and ``size_a`` multiplied);
    * time-warped: the number of frames multiplied by a factor in ``warp_range``
      (resampled uniformly, the hit frame moved accordingly);
    * Gaussian noise of ``noise`` metres (std) added to the pose clouds and the hit
      trajectory (as capture noise; the stored motion is not noisy).

    These are not new captures: the variants are strongly correlated with their source,
    which makes the retrieval's job *easier* than on as many real motions would be.  A
    mirrored variant keeps its source's base actor (exact for the left/right symmetric
    synthetic actor; for a captured skeleton such as CMU's the mirrored one has the other
    side's bone lengths, a difference of millimetres that the retrieval ignores).

    ``pose_dtype``: dtype of the result's pose clouds, ``float64`` or ``float32`` (default: the
    base database's, float64).  float32 halves the largest array (4.6 M poses at 1,000x: 0.93 GB
    instead of 1.86 GB) for a rounding of 6e-8 relative; the retrieval's index computes its terms
    in float64 from either (:class:`~repro.motion.search.distance.AlignedPoseIndex`).

    All variants of a clip are computed at once (:func:`_variants_of_clip`); the numbers drawn
    and the arrays are those of building every variant with
    :func:`~repro.motion.core.ops.variant_motion` and :func:`~repro.motion.database.clips.clip_record`
    (the noise identically, the rest to ~1e-15 relative).

    Returns
    -------
    MotionDatabase
        ``factor * n_clips`` clips; the variants store no motion of their own
        (:meth:`MotionDatabase.motion` rebuilds it from the source clip).
    """
    db, factor, seed, scale_range, warp_range, noise, mirror_probability = _checked(
        db, factor, seed, scale_range, warp_range, noise, mirror_probability)
    if factor == 1 and pose_dtype is None:
        return db
    pdt = _pose_dtype(db, pose_dtype)
    mir, sc, wp, nf, pose_points, traj = _drawn(db, factor, seed, scale_range, warp_range, noise,
                                                mirror_probability, pdt)
    v = _variants(db, mir, sc, nf, pose_points, traj)
    arrays = _augmented_arrays(db, factor, noise, mir, sc, wp, nf, v)
    meta = {**db.meta, "augmented": {"factor": factor, "seed": seed, "scale_range": list(scale_range),
                                     "warp_range": list(warp_range), "noise_m": noise,
                                     "mirror_probability": mirror_probability,
                                     "note": "synthetic variants of the original clips, for latency-vs-size only"}}
    return MotionDatabase(fps=db.fps, pose_roles=db.pose_roles, window=db.window, step=db.step, actors=db.actors,
                          motions=db.stored_motions(), arrays=arrays, meta=meta)


def _pose_dtype(db: MotionDatabase, pose_dtype) -> np.dtype:
    """The result's pose cloud dtype: ``pose_dtype``, float32 or float64 (default: the base's), else
    :class:`MotionError`."""
    try:
        pdt = np.dtype(db.pose_points.dtype if pose_dtype is None else pose_dtype)
    except TypeError:
        pdt = None
    if pdt not in (np.float32, np.float64):
        raise MotionError(f"pose_dtype must be float32 or float64, got {pose_dtype!r}")
    return pdt


def _drawn(db: MotionDatabase, factor: int, seed: int, scale_range, warp_range, noise: float,
           mirror_probability: float, pdt: np.dtype) -> tuple:
    """The variants' parameters ``mir, sc, wp, nf`` (mirrored, scale, warp, frames) and the result's pose
    clouds and trajectory samples: the base's rows, then each variant's noise (zeros without noise).

    Variant ``j = (v - 1) * C + i`` is variant ``v`` of clip ``i``.  One pass over the stream, in the
    historical order (per variant: mirror, scale, warp, then the noise of its trajectory and of its pose
    clouds, whose sizes depend on the warp); the noise is drawn straight into the new rows of buffers
    sized for the longest warp, trimmed at the end.
    """
    C = db.n_clips
    V = (factor - 1) * C
    WP = db.pose_points.shape[1]
    F0 = db.n_frames.astype(np.intp)
    rng = np.random.default_rng(seed)
    mir, sc, wp, nf = np.empty(V, dtype=bool), np.empty(V), np.empty(V), np.empty(V, dtype=np.intp)
    N0, T0 = db.n_poses, db.traj.shape[0]
    nmax = np.maximum(2, np.round((F0 - 1) * max(warp_range)).astype(np.intp) + 1)
    cap = int(nmax.sum()) * (factor - 1)  # every variant of clip i has at most nmax[i] frames
    pose_points = np.empty((N0 + cap, WP, 3), dtype=pdt)
    traj = np.empty((T0 + cap, 3))
    scratch = None if pdt == np.float64 else np.empty((int(nmax.max()) + 1, WP, 3))
    Nv = _draw(rng, V, C, F0, mir, sc, wp, nf, scale_range, warp_range, mirror_probability, noise,
               pose_points[N0:], traj[T0:], scratch)
    # no view of the buffers is left (_draw's died with it): shrink them in place
    pose_points.resize((N0 + Nv, WP, 3), refcheck=False)
    traj.resize((T0 + Nv, 3), refcheck=False)
    pose_points[:N0] = db.pose_points
    traj[:T0] = db.traj
    if noise <= 0:
        pose_points[N0:] = 0.0
        traj[T0:] = 0.0
    return mir, sc, wp, nf, pose_points, traj


def _variants(db: MotionDatabase, mir, sc, nf, pose_points: np.ndarray, traj: np.ndarray) -> dict:
    """Every clip's variants (:func:`_variants_of_clip`): their rows of ``pose_points`` and ``traj`` filled
    in place, and their per-pose root frames and per-variant annotations, returned."""
    C, N0, T0, V = db.n_clips, db.n_poses, db.traj.shape[0], mir.size
    vstart = np.concatenate([[0], np.cumsum(nf)])  # variant j's rows: N0 + vstart[j] ... N0 + vstart[j + 1]
    Nv = int(vstart[-1])
    heading = np.empty(N0 + Nv)
    heading[:N0] = db.pose_heading
    origin = np.empty((N0 + Nv, 3))
    origin[:N0] = db.pose_origin
    hit_frame = np.empty(V, dtype=np.intp)
    size_v = np.empty(V)
    box_min, box_max, hit_pos = np.empty((V, 3)), np.empty((V, 3)), np.empty((V, 3))
    roles, sides, joints = np.empty(V, dtype=object), np.empty(V, dtype=object), np.empty(V, dtype=object)
    new_p, new_t = pose_points[N0:], traj[T0:]
    for i in range(C if V else 0):
        js = np.arange(i, V, C)  # this clip's variants, in order
        _variants_of_clip(db, i, js, mir, sc, nf, vstart, new_p, new_t, heading[N0:], origin[N0:], hit_frame, size_v,
                          box_min, box_max, hit_pos, roles, sides, joints)
    return {"vstart": vstart, "heading": heading, "origin": origin, "hit_frame": hit_frame, "size": size_v,
            "box_min": box_min, "box_max": box_max, "hit_position": hit_pos, "roles": roles, "sides": sides,
            "joints": joints, "traj": traj, "pose_points": pose_points}


def _augmented_arrays(db: MotionDatabase, factor: int, noise: float, mir, sc, wp, nf, v: dict) -> dict:
    """The result's arrays: the base's clips, then the variants (:func:`_variants`) of each."""
    C, N0, T0 = db.n_clips, db.n_poses, db.traj.shape[0]
    V, vstart = mir.size, v["vstart"]
    Nv = int(vstart[-1])
    src = np.tile(np.arange(C), factor - 1)
    arrays = {
        "names": np.concatenate([db.names, [f"{db.names[j % C]}~v{j // C + 1:03d}" for j in range(V)]]),
        "hit_roles": np.concatenate([db.hit_roles, v["roles"].astype(str)]),
        "sides": np.concatenate([db.sides, v["sides"].astype(str)]),
        "hit_joints": np.concatenate([db.hit_joints, v["joints"].astype(str)]),
        "hit_frame": np.concatenate([db.hit_frame, v["hit_frame"]]),
        "n_frames": np.concatenate([db.n_frames, nf]),
        "scale": np.concatenate([db.scale, db.scale[src] * sc]),
        "size_a": np.concatenate([db.size_a, v["size"]]),
        "source_clip": np.concatenate([db.source_clip, db.source_clip[src]]),
        "mirror": np.concatenate([db.mirror, mir ^ db.mirror[src]]),
        "warp": np.concatenate([db.warp, wp * db.warp[src]]),
        "noise": np.concatenate([db.noise, np.full(V, float(noise))]),
        "box_min": np.concatenate([db.box_min, v["box_min"]]),
        "box_max": np.concatenate([db.box_max, v["box_max"]]),
        "hit_position": np.concatenate([db.hit_position, v["hit_position"]]),
        "traj_start": np.concatenate([db.traj_start, T0 + vstart[1:]]),
        "pose_start": np.concatenate([db.pose_start, N0 + vstart[1:]]),
        "traj": v["traj"], "pose_points": v["pose_points"], "pose_heading": v["heading"], "pose_origin": v["origin"],
        "pose_clip": np.concatenate([db.pose_clip, C + np.repeat(np.arange(V), nf)]),
        "pose_frame": np.concatenate([db.pose_frame, np.arange(Nv) - np.repeat(vstart[:-1], nf)]),
    }
    for k in ("sources", "semantics", "kinds", "levels", "hit_wheres", "source_time", "actor"):
        arrays[k] = np.concatenate([getattr(db, k), getattr(db, k)[src]])
    return arrays


def _checked(db, factor, seed, scale_range, warp_range, noise, mirror_probability) -> tuple:
    """:func:`augment`'s arguments checked (:class:`MotionError` naming the bad one), and what
    ``factor`` will allocate against :data:`repro.checks.MEMORY_BUDGET` before anything is.

    ``factor=10**9`` asked numpy for 67-99 GiB (issue 23, section 3), ``"x"`` or NaN raised
    bare ``ValueError``s.
    """
    if not isinstance(db, MotionDatabase):
        raise MotionError(f"db must be a MotionDatabase, got {describe(db)}")
    factor = as_int(factor, "factor", 1, None, error=MotionError)
    seed = as_int(seed, "seed", 0, None, error=MotionError)
    ranges = []
    for name, r in (("scale_range", scale_range), ("warp_range", warp_range)):
        lo, hi = as_real_array(r, name, error=MotionError, shape=(2,)).tolist()
        if not 0 < lo <= hi <= MAX_RANGE:
            raise MotionError(f"{name} must be (lo, hi) with 0 < lo <= hi <= {MAX_RANGE:g}, got ({lo}, {hi})")
        ranges.append((lo, hi))
    noise = as_real(noise, "noise (metres)", lo=0.0, error=MotionError)
    mirror_probability = as_real(mirror_probability, "mirror_probability", lo=0.0, hi=1.0, error=MotionError)
    # the base's arrays factor times, the per-pose ones up to the longest warp (the buffers are sized
    # for it); Python ints, so a huge factor cannot overflow the estimate
    per_clip = sum(getattr(db, k).nbytes for k in ("names",) + _PER_CLIP)
    per_pose = db.pose_points.nbytes + db.traj.nbytes + db.pose_heading.nbytes + db.pose_origin.nbytes
    per_pose += db.pose_clip.nbytes + db.pose_frame.nbytes
    headroom = max(1.0, ranges[1][1]) * (db.n_poses + 2 * db.n_clips) / max(1, db.n_poses)
    check_alloc(factor * per_clip + int(factor * per_pose * headroom) + per_clip + per_pose,
                f"factor={factor} (an augmented database of {factor} x {db.n_clips} clips)", error=MotionError)
    return db, factor, seed, ranges[0], ranges[1], noise, mirror_probability


#: Largest time warp or actor rescaling factor :func:`augment` accepts (a variant 100 times longer
#: or taller than its clip is no longer a variant of it).
MAX_RANGE: float = 100.0

_PER_CLIP = ("hit_frame", "n_frames", "actor", "scale", "size_a", "source_clip", "source_time", "mirror", "warp",
             "noise", "box_min", "box_max", "hit_position", "traj_start", "pose_start", "sources", "semantics",
             "kinds", "levels", "hit_wheres", "hit_roles", "sides", "hit_joints")


def _draw(rng, V, C, F0, mir, sc, wp, nf, scale_range, warp_range, mirror_probability, noise, out_p, out_t,
          scratch) -> int:
    """The parameters of the ``V`` variants into ``mir, sc, wp, nf``, their noise into ``out_p, out_t``; the rows used."""
    a = 0
    for j in range(V):
        i = j % C
        mir[j] = rng.random() < mirror_probability
        sc[j] = rng.uniform(*scale_range)
        wp[j] = rng.uniform(*warp_range)
        n = nf[j] = max(2, int(round((F0[i] - 1) * wp[j])) + 1)
        if noise > 0:
            t = out_t[a:a + n]
            rng.standard_normal(out=t)  # = rng.normal(0.0, noise, (n, 3)): numpy draws loc + scale * z
            t *= noise
            p = out_p[a:a + n] if scratch is None else scratch[:n]
            rng.standard_normal(out=p)
            p *= noise
            if scratch is not None:
                out_p[a:a + n] = p
        a += n
    return a


_M = np.array([-1.0, 1.0, 1.0])


def _variants_of_clip(db, i, js, mir, sc, nf, vstart, new_p, new_t, heading, origin, hit_frame, size_v, box_min,
                      box_max, hit_pos, roles, sides, joints) -> None:
    """Every variant ``js`` of clip ``i`` at once: one forward kinematics per distinct frame count.

    A variant is the clip resampled to ``nf[j]`` frames, rescaled by ``sc[j]`` and mirrored if
    ``mir[j]`` (:func:`~repro.motion.core.ops.variant_motion`).  Forward kinematics commutes with
    the last two: the rescaled motion's joints are at ``s p_j`` and the mirrored one's at
    ``M p_pi(j)`` (:func:`~repro.motion.core.ops.mirror_motion`, ``M = diag(-1, 1, 1)``), so one
    forward kinematics of the clip resampled to ``n`` frames serves every variant of ``n``
    frames (equal to a per-variant one to rounding, ~1e-15 relative; at 1,000x a clip's 999
    variants share about 40 frame counts).  The pose clouds and the trajectory rows already hold the
    variants' noise; this adds the motion to them, as :func:`~repro.motion.database.clips.clip_record`.
    """
    base = db.motion(i)
    sk = db.actor_skeleton(i)
    F = int(db.n_frames[i])
    lens = nf[js]
    # the variants share few frame counts (the warp rounds to whole frames): one resampling and one
    # forward kinematics per distinct count, then every variant gathers its frames
    un, inv = np.unique(lens, return_inverse=True)
    u = np.concatenate([np.linspace(0.0, F - 1, int(n)) for n in un])
    gq, gp = resample(base, frames=u).global_transforms()
    ustart = np.concatenate([[0], np.cumsum(un)[:-1]])
    seg = np.concatenate([[0], np.cumsum(lens)])
    first = np.repeat(seg[:-1], lens)
    fr = np.repeat(ustart[inv], lens) + (np.arange(seg[-1]) - first)  # each variant frame's row of gp
    idx = np.array([sk.index(r) for r in db.pose_roles] + [sk.index("pelvis"), sk.index("left_hip"),
                                                           sk.index("right_hip")], dtype=np.intp)
    hj, where = base.joint_index(str(db.hit_joints[i])), str(db.hit_wheres[i])
    if where == "joint":
        hit_u = gp[:, hj]
    else:
        sites = np.flatnonzero(base.end_site_parents == hj)
        if sites.size == 0:
            raise MotionError(f"joint {db.hit_joints[i]!r} has no End Site")
        e = int(sites[0])
        par = base.end_site_parents[e]
        hit_u = gp[:, par] + quat_rotate(gq[:, par], base.end_site_offsets[e][None])
    del gq
    mf = np.repeat(mir[js], lens)  # per frame: mirrored
    s_f = np.repeat(sc[js], lens)[:, None, None]
    g = gp[:, idx][fr]
    hit = hit_u[fr]
    role, side, joint = str(db.hit_roles[i]), str(db.sides[i]), str(db.hit_joints[i])
    if mf.any():
        pi = mirror_joint_map(base.joint_names, base.parents)
        g[mf] = gp[:, pi[idx]][fr[mf]] * _M
        hit[mf] *= _M
        m_role = role.replace("left", "@").replace("right", "left").replace("@", "right")
        m_side = {"left": "right", "right": "left"}.get(side, side)
        m_joint = base.joint_names[pi[hj]]
    del gp
    g *= s_f
    hit *= s_f[:, 0]
    P = len(db.pose_roles)
    K = P  # pelvis, left hip, right hip follow the pose joints in g
    theta, org = root_frames(g, K, K + 1, K + 2)
    pts = pose_points(g, range(P), K, K + 1, K + 2, window=db.window, step=db.step, first=first)
    del g
    rows = np.concatenate([np.arange(vstart[j], vstart[j + 1]) for j in js])
    size = db.size_a[i] * sc[js]
    pts += new_p[rows]
    pts /= np.repeat(size, lens)[:, None, None]
    new_p[rows] = pts
    hit += new_t[rows]
    new_t[rows] = to_root_frame(hit, theta[first], org[first])
    heading[rows], origin[rows] = theta, org
    tr = new_t[rows]
    box_min[js] = np.minimum.reduceat(tr, seg[:-1], axis=0)
    box_max[js] = np.maximum.reduceat(tr, seg[:-1], axis=0)
    hf = np.minimum(np.round(db.hit_frame[i] * (lens - 1) / (F - 1)).astype(np.intp), lens - 1)
    hit_frame[js] = hf
    hit_pos[js] = tr[seg[:-1] + hf]
    size_v[js] = size
    m = mir[js]
    roles[js] = np.where(m, m_role if m.any() else role, role)
    sides[js] = np.where(m, m_side if m.any() else side, side)
    joints[js] = np.where(m, m_joint if m.any() else joint, joint)
