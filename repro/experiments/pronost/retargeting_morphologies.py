"""Pronost et al. (about 2008), Sections 3.3-3.4: retargeting database clips across morphologies.

"Interactive Animation of Virtual Characters: Application to Virtual Kung-fu Fighting".
The paper animates fighters "selected by the supervisor into a database composed of
various skeletons" (Section 3.1) with clips captured on one actor.  Three things make
that work, and this experiment measures each of them on a sweep of characters (height
1.2-2.2 m; arm and leg proportions +-25 %, and one set whose forearms and shins alone are
25 % longer, which changes the upper/lower ratio of the limbs):

* **Retargeting** (Section 3.4.1).  For every clip and character, five ways of playing
  the clip on the character:

  - ``naive`` -- (a) "people usually apply joint angles from character#1 to
    character#2": local rotations and the root translation copied
    (:func:`repro.motion.retargeting.morphology.naive_retarget`);
  - ``naive_scaled_root`` -- (a') the same with the root translation scaled by the ratio
    of hip heights (``scale_root=True``);
  - ``mi`` -- (b0) the morphology-independent representation of Kulpa et al. 2005,
    :func:`~repro.motion.retargeting.morphology.encode` then
    :func:`~repro.motion.retargeting.morphology.decode` (limb = normalised distal vector + swivel
    angle, root trajectory / hip height), no foot correction;
  - ``mi_feet`` -- (b) the paper's retargeting: the same "and correcting the feet
    artifacts" (``decode(..., fix_feet=True)``);
  - ``mi_feet_adapt`` -- (c) (b), then the constraints solver of Section 3.4.2
    (:func:`repro.motion.adaptation.adapt`, ``t0`` = first frame, ``tc`` = hit frame)
    driving the hit point to the target.

  Measured on the result: the **hit error** at the hit frame -- distance from the hit
  point, in the root reference frame of the clip's first frame (:mod:`repro.motion.database.clips`),
  to the actor's hit position scaled to the character by Eq. 1 read backwards
  (``c = c_a * size_c / size_a``: where this character should hit); the **foot slide**
  on the frames where the *actor's* ankle is planted
  (:func:`~repro.motion.body.feet.foot_contacts` of the source): the largest horizontal
  drift of the ankle from its position at the start of each contact phase, and the mean
  sliding speed (:func:`~repro.motion.body.feet.foot_metrics`); the lowest toe height
  (negative = through the floor); and the **bone-length error** (largest change of a
  joint-to-parent distance from the character's bone length).

* **Eq. 1 in the retrieval** (Section 3.3), ``extra_tables["eq1"]``: small and tall
  characters (uniform proportions) aim at the point where a database clip *j* hits,
  scaled to the character (``c = hit_j * size_c / size_a``, nudged 0.1 % inside the
  clip's box as in ``tests/motion/search/test_retrieval.py``), from the stance of that clip
  (its first frame retargeted to the character).  :meth:`MotionRetriever.search` is run
  with Eq. 1 (``scale_target=True``) and without (``scale_target=False``: ``c_r = c``).
  Reported: the clip chosen, its level (high / middle / low, synthetic database), and its
  **reach error**: the distance from the chosen clip's hit point at its hit frame, placed
  where the system plays it (aligned on the current pose, scaled to the character,
  :meth:`RetrievalResult.align`), to ``c`` -- the correction the constraints solver would
  have to make.

Databases: the embedded synthetic one (always) and the CMU subject-135 takes when the
``cmu-bvh`` dataset is staged (``repro.data.missing_reason("cmu-bvh") is None``).
The full run uses 5 heights x 8 proportion sets, the 24 clips of the 1.75 m synthetic
actor and the 22 CMU lunge punches and kicks (the kata clips, blocks and strikes in all
directions, are left out); ``quick=True`` uses 3 heights x 4 proportion sets and 8
synthetic (+4 CMU) clips.

The main table has one row per database x character x method (means and maxima over
the clips); ``extra_tables["eq1"]`` one row per database x character x target clip x
(with / without Eq. 1).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.experiments.progress import bar
from repro.experiments.registry import Result, experiment
from repro.motion.body.feet import max_foot_slide
from repro.motion.database.annotation import hit_point_trajectory

#: Statures (m) of the characters of the sweep.
HEIGHTS = (1.2, 1.5, 1.75, 2.0, 2.2)
HEIGHTS_QUICK = (1.2, 1.75, 2.2)

#: Proportion sets: name -> (arm_scale, leg_scale, forearm_shin_scale).  The last factor
#: scales only the forearm and the shin (``bone_scales`` of the wrist and ankle joints),
#: which changes the upper/lower ratio of the limbs.
PROPORTIONS: dict[str, tuple[float, float, float]] = {
    "uniform": (1.0, 1.0, 1.0),
    "long arms": (1.25, 1.0, 1.0),
    "short arms": (0.75, 1.0, 1.0),
    "long legs": (1.0, 1.25, 1.0),
    "short legs": (1.0, 0.75, 1.0),
    "long arms, short legs": (1.25, 0.75, 1.0),
    "short arms, long legs": (0.75, 1.25, 1.0),
    "long forearms+shins": (1.0, 1.0, 1.25),
}
PROPORTIONS_QUICK = ("uniform", "long arms, short legs", "short arms, long legs", "long forearms+shins")

#: The methods, in the order of the paper's argument.
METHODS: dict[str, str] = {
    "naive": "(a) joint-angle copy",
    "naive_scaled_root": "(a') joint-angle copy, root scaled",
    "mi": "(b0) morphology-independent, no foot fixing",
    "mi_feet": "(b) morphology-independent + feet (paper)",
    "mi_feet_adapt": "(c) (b) + constraint solving",
}

#: Synthetic clips of the quick sweep (the 1.75 m actor): every kind, both sides, every level.
QUICK_SYNTHETIC = (
    "actor2_punch_left_high", "actor2_punch_right_middle", "actor2_kick_front_left_middle",
    "actor2_kick_front_right_high", "actor2_kick_side_left_low", "actor2_kick_side_right_middle",
    "actor2_kick_round_left_high", "actor2_kick_round_right_low",
)
#: CMU clips of the quick sweep: a lunge punch and one kick of each kind.
QUICK_CMU = ("135_09_h01_right_fist", "135_04_h00_right_foot", "135_07_h00_right_foot", "135_11_h03_left_foot")

#: Characters of the Eq. 1 study (uniform proportions): small and tall.
EQ1_HEIGHTS = (1.2, 1.5, 2.0, 2.2)
EQ1_HEIGHTS_QUICK = (1.2, 2.2)
LEVEL_RANK = {"low": 0, "middle": 1, "high": 2}


# ---------------------------------------------------------------- shared helpers
def first_root_frame(motion, skeleton) -> tuple[float, np.ndarray]:
    """Heading and origin of the root reference frame of a motion's first frame."""
    from repro.motion.body.pose_frames import root_frames

    g = motion.global_positions()[:1]
    th, o = root_frames(g, skeleton.index("pelvis"), skeleton.index("left_hip"), skeleton.index("right_hip"))
    return float(th[0]), o[0]


def character(base, height: float, proportions: str = "uniform"):
    """A character of the sweep: ``base`` with the named proportions, ``height`` metres tall."""
    from repro.motion.body.skeleton import scale_skeleton

    arm, leg, distal = PROPORTIONS[proportions]
    bones = None
    if distal != 1.0:
        bones = {base.roles[f"{s}_{r}"]: distal for s in ("left", "right") for r in ("wrist", "ankle")}
    return scale_skeleton(base, height=height, arm_scale=arm, leg_scale=leg, bone_scales=bones)


def bone_length_error(motion, skeleton, *, globals_=None) -> float:
    """Largest ``| |g_j - g_parent(j)| - bone length_j |`` over frames and joints (m)."""
    g = motion.global_positions() if globals_ is None else globals_
    par = np.asarray(skeleton.parents)
    d = np.linalg.norm(g[:, 1:] - g[:, par[1:]], axis=-1)
    return float(np.abs(d - skeleton.bone_lengths[None, 1:]).max())


def _measure(mo, ch, db, i: int, c: np.ndarray, contacts: np.ndarray) -> dict:
    """Hit error (vs ``c``, first-frame root frame), feet and bone measures of a motion on ``ch``."""
    from repro.motion.body.pose_frames import root_frames, to_root_frame

    g = mo.global_positions()  # forward kinematics once
    th, o = root_frames(g[:1], ch.index("pelvis"), ch.index("left_hip"), ch.index("right_hip"))
    f = int(db.hit_frame[i])
    joint, where = str(db.hit_joints[i]), str(db.hit_wheres[i])
    hp = g[f, mo.joint_index(joint)] if where == "joint" else hit_point_trajectory(mo, joint, where)[f]
    hp = to_root_frame(hp, th[0], o[0])
    ank = g[:, [ch.index("left_ankle"), ch.index("right_ankle")]][..., [0, 2]]
    both = contacts[1:] & contacts[:-1]
    step = np.linalg.norm(np.diff(ank, axis=0), axis=-1)
    toe = g[:, [ch.index("left_foot"), ch.index("right_foot")], 1]
    return {
        "hit_error_m": float(np.linalg.norm(hp - c)),
        "foot_slide_m": max_foot_slide(mo, contacts, skeleton=ch, global_positions=g),
        # as repro.motion.body.feet.foot_metrics: mean horizontal ankle speed over planted frame pairs
        "slide_speed_mps": float(step[both].sum() / max(both.sum(), 1) / mo.frame_time),
        "min_toe_height_m": float(toe.min()),
        "bone_length_error_m": bone_length_error(mo, ch, globals_=g),
    }


# -------------------------------------------------------------------- the sweep
def _clip_indices(name: str, db, quick: bool) -> list[int]:
    names = [str(n) for n in db.names]
    if quick:
        wanted = QUICK_SYNTHETIC if name == "synthetic" else QUICK_CMU
        return [names.index(n) for n in wanted if n in names]
    if name == "synthetic":
        return [i for i, n in enumerate(names) if n.startswith("actor2_")]
    # CMU: the lunge punches and the kicks (the kata clips are blocks and strikes in all directions)
    return [i for i in range(db.n_clips) if db.hit_frame[i] > 0 and db.kinds[i] != "kata_arm"]


def _methods(motion, ch, i, db, c):
    """Yield (method, motion, extra) for one clip on one character."""
    from repro.motion.adaptation import AdaptOptions, adapt
    from repro.motion.body.pose_frames import from_root_frame
    from repro.motion.retargeting.morphology import decode, encode, naive_retarget
    from repro.motion.runtime.strike import clip_effector

    yield "naive", naive_retarget(motion, ch), {}
    yield "naive_scaled_root", naive_retarget(motion, ch, scale_root=True), {}
    mi = encode(motion)
    yield "mi", decode(mi, ch), {}
    b = decode(mi, ch, fix_feet=True)
    yield "mi_feet", b, {}
    th, o = first_root_frame(b, ch)
    X = from_root_frame(c, th, o)
    ad = adapt(b, clip_effector(db, i, ch), X, 0, int(db.hit_frame[i]),
               options=AdaptOptions(hit_point=str(db.hit_wheres[i]), feet="pin", floor=None))
    yield "mi_feet_adapt", ad.motion, {"reached": ad.reached}


def _sweep_rows(name: str, db, quick: bool, progress: bool = False) -> list[dict]:
    from repro.motion.body.feet import foot_contacts

    heights = HEIGHTS_QUICK if quick else HEIGHTS
    props = PROPORTIONS_QUICK if quick else tuple(PROPORTIONS)
    rows = []
    clips = _clip_indices(name, db, quick)
    b = bar(total=len(clips) * len(heights) * len(props), desc=f"retargeting_morphologies: {name} clips x morphologies",
            unit="character", progress=progress)
    for i in clips:
        m = db.motion(i)
        actor = db.actor_skeleton(i)
        contacts = foot_contacts(m)
        for h in heights:
            for p in props:
                b.update()
                ch = character(actor, h, p)
                c = db.hit_position[i] * ch.size / db.size_a[i]  # Eq. 1 backwards: where this character should hit
                for method, mo, extra in _methods(m, ch, i, db, c):
                    rows.append({
                        "database": name, "clip": str(db.names[i]), "semantics": str(db.semantics[i]),
                        "height_m": h, "proportions": p, "method": method,
                        **_measure(mo, ch, db, i, c, contacts),
                        "reached": extra.get("reached", np.nan),
                    })
    b.close()
    return rows


def _eq1_rows(name: str, db, quick: bool) -> list[dict]:
    from repro.motion.retargeting.morphology import retarget
    from repro.motion.search.retrieval import MotionRetriever
    from repro.motion.runtime.strike import one_frame

    retriever = MotionRetriever(db, seed=0)
    rows = []
    idx = _clip_indices(name, db, quick)
    for h in (EQ1_HEIGHTS_QUICK if quick else EQ1_HEIGHTS):
        for j in idx:
            actor = db.actor_skeleton(j)
            ch = character(actor, h)
            stance = one_frame(retarget(db.motion(j), ch), 0)
            inside = 0.999 * db.hit_position[j] + 0.001 * (db.box_min[j] + db.box_max[j]) / 2
            c = inside * ch.size / db.size_a[j]
            q = retriever.prepare(stance, ch)
            for scale in (True, False):
                r = retriever.search(c, q, semantics=str(db.semantics[j]), scale_target=scale)
                k = ch.size / r.size_a
                placed = k * r.align(hit_point_trajectory(db.motion(r.clip), str(db.hit_joints[r.clip]),
                                                          str(db.hit_wheres[r.clip]))[r.hit_frame])
                lt, lc = str(db.levels[j]), str(db.levels[r.clip])
                rows.append({
                    "database": name, "height_m": h, "size_c_m": ch.size, "target_clip": str(db.names[j]),
                    "semantics": str(db.semantics[j]), "target_level": lt, "eq1": scale,
                    "chosen_clip": str(db.names[r.clip]), "chosen_kind": str(db.kinds[r.clip]), "chosen_level": lc,
                    "same_clip": bool(r.clip == j),
                    "level_shift": (LEVEL_RANK[lc] - LEVEL_RANK[lt]) if lt in LEVEL_RANK and lc in LEVEL_RANK else np.nan,
                    "reach_error_m": float(np.linalg.norm(placed - c)),
                    "reach_dy_m": float(placed[1] - c[1]),
                    "d_cr_char_m": r.d_cr * k,
                    "start_frame": r.start_frame, "fallback": r.fallback,
                })
    return rows


def _compute(quick: bool, progress: bool = False):
    from repro.experiments.pronost.databases import databases

    dbs = databases()
    sweep = pd.DataFrame([r for name, db in dbs.items() for r in _sweep_rows(name, db, quick, progress)])
    eq1 = pd.DataFrame([r for name, db in dbs.items() for r in _eq1_rows(name, db, quick)])
    keys = ["database", "height_m", "proportions", "method"]
    g = sweep.groupby(keys, sort=False)
    table = g.agg(
        n_clips=("clip", "size"),
        hit_error_mean_m=("hit_error_m", "mean"),
        hit_error_max_m=("hit_error_m", "max"),
        foot_slide_mean_m=("foot_slide_m", "mean"),
        foot_slide_max_m=("foot_slide_m", "max"),
        slide_speed_mean_mps=("slide_speed_mps", "mean"),
        min_toe_height_m=("min_toe_height_m", "min"),
        bone_length_error_max_m=("bone_length_error_m", "max"),
        reached_fraction=("reached", "mean"),
    ).reset_index()
    table.insert(list(table.columns).index("method") + 1, "method_label", table.method.map(METHODS))
    return table, eq1


def draw(table: pd.DataFrame, eq1: pd.DataFrame):
    import matplotlib.pyplot as plt

    colors = {"naive": "tab:red", "naive_scaled_root": "tab:orange", "mi": "tab:olive", "mi_feet": "tab:blue",
              "mi_feet_adapt": "tab:green"}
    dbs = list(dict.fromkeys(table.database))
    fig, axes = plt.subplots(1, 4, figsize=(19, 5.4), layout="constrained")
    styles = dict(zip(dbs, ("-", "--")))
    for col, (metric, label) in enumerate((("hit_error_mean_m", "hit error at contact (m)"),
                                          ("foot_slide_mean_m", "foot slide while planted (m)"))):
        ax = axes[col]
        for d in dbs:
            t = table[table.database == d]
            for m in METHODS:
                s = t[t.method == m].groupby("height_m")[metric].mean()
                ax.plot(s.index, s.values, styles[d], marker="o", ms=4, color=colors[m])
        ax.set_xlabel("character height (m)")
        ax.set_ylabel(label + ", mean")
        ax.set_title(label.split(" (")[0] + " vs stature\n(mean over clips and proportion sets)")
        ax.grid(alpha=0.3)
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=colors[m], marker="o", label=METHODS[m]) for m in METHODS]
    handles += [Line2D([], [], color="k", ls=styles[d], label=f"{d} database") for d in dbs]
    # the key of the two curve panels under the row, not over the curves
    fig.legend(handles=handles, fontsize=8, loc="outside lower center", ncol=len(handles), frameon=False)
    ax = axes[2]
    t = table[table.database == dbs[0]]
    props = list(dict.fromkeys(t.proportions))
    w = 0.8 / len(METHODS)
    for k, m in enumerate(METHODS):
        s = t[t.method == m].groupby("proportions", sort=False).hit_error_mean_m.mean().reindex(props)
        ax.bar(np.arange(len(props)) + (k - 2) * w, s.values, w, color=colors[m], label=METHODS[m])
    ax.set_xticks(np.arange(len(props)), props, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("hit error at contact (m), mean over heights")
    ax.set_title(f"hit error by proportion set [{dbs[0]}]")
    ax.grid(alpha=0.3, axis="y")
    ax = axes[3]
    e = eq1[eq1.database == dbs[0]]
    hs = sorted(set(e.height_m))
    for k, (flag, lab, colr) in enumerate(((True, "with Eq. 1", "tab:green"), (False, "without Eq. 1 (c_r = c)", "tab:red"))):
        s = e[e.eq1 == flag].groupby("height_m").reach_error_m.mean().reindex(hs)
        ax.bar(np.arange(len(hs)) + (k - 0.5) * 0.4, s.values, 0.4, color=colr, label=lab)
        lv = e[e.eq1 == flag].groupby("height_m").level_shift.mean().reindex(hs)
        for x, (v, l) in enumerate(zip(s.values, lv.values)):
            if np.isfinite(l):
                ax.text(x + (k - 0.5) * 0.4, v, f"{l:+.2f}", ha="center", va="bottom", fontsize=8, color=colr)
    ax.set_xticks(np.arange(len(hs)), [f"{h:g} m" for h in hs])
    ax.set_ylabel("reach error of the chosen clip (m), mean")
    ax.set_title(f"Eq. 1 in the retrieval [{dbs[0]}]\n(labels: mean level shift, chosen - target)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    fig.suptitle("Retargeting across morphologies (Pronost et al., Sections 3.3-3.4)")
    return fig


@experiment(
    "retargeting_morphologies",
    "Retargeting across morphologies: hit error, foot slide and bone lengths for joint-angle copy, the "
    "morphology-independent representation and constraint solving; Eq. 1 in the retrieval",
    paper="pronost2008",
)
def retargeting_morphologies(quick: bool = False, progress: bool = False) -> Result:
    table, eq1 = _compute(bool(quick), bool(progress))
    return Result(table=table, draw=lambda: draw(table, eq1), extra_tables={"eq1": eq1})


def summary(result) -> str:
    """Markdown: per database and method, hit error, foot slide, toes and reach over the sweep; Eq. 1 on and off."""
    from repro.experiments.summaries import bullets, num, pct

    t, eq1 = result.table, result.extra_tables["eq1"]
    lines = []
    for (name, method), g in t.groupby(["database", "method"], sort=False):
        lines.append(f"*{name}*, `{method}`: hit error {num(g.hit_error_mean_m.mean())} m on average (at most "
                     f"{num(g.hit_error_max_m.max(), 2)} m); planted feet slide {num(100 * g.foot_slide_mean_m.mean(), 2)} cm "
                     f"on average (at most {num(100 * g.foot_slide_max_m.max(), 2)} cm); lowest toe "
                     f"{num(100 * g.min_toe_height_m.min(), 2)} cm; bone lengths kept to {num(g.bone_length_error_max_m.max(), 1)} m"
                     + (f"; {pct(g.reached_fraction.mean())} of the targets reached" if g.reached_fraction.notna().any() else ""))
    for (name, height, on), g in eq1.groupby(["database", "height_m", "eq1"], sort=True):
        lines.append(f"*{name}*, {num(height, 2)} m fighter, Eq. 1 {'on' if on else 'off'}: the query's own clip in "
                     f"{int(g.same_clip.sum())} of {len(g)} queries; reach error {num(g.reach_error_m.mean(), 2)} m on "
                     f"average (at most {num(g.reach_error_m.max(), 2)} m), vertical {num(g.reach_dy_m.mean(), 2)} m")
    return bullets(lines)
