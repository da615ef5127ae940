"""Retargeting across skeletons (issue 11; issue 25, item 9; Pronost et al. Section 3.4.1, Kulpa et al. 2005).

The paper's database serves "hundreds of characters" with *different skeletons*.  This
figure plays the synthetic database on characters whose bodies and trees differ from the
source actor's (:data:`repro.motion.database.synthetic.conventions.CHARACTERS`: Mixamo, Unreal,
3ds Max Biped, Rigify, MotionBuilder, Second Life, SMPL, Unity and Poser names; arm, leg and
torso proportions 10-25 % off the actor's; T-, A- and N-pose rest poses; 1 to 5 spine joints;
2- and 3-segment fingers with no hand End Site; no toes; twist bones off the limbs and in the
limb chains; zero-length helpers; Y or Z up; metres, centimetres, millimetres, inches) at
statures 1.2-2.2 m, and on real data CMU clips on the Bandai Namco skeleton and the reverse,
through :func:`repro.motion.retarget`.  The field's metrics, per clip and character:

* ``position_error``: the joint-position error of Aberman et al. (2020, "Skeleton-Aware
  Networks for Deep Motion Retargeting", its evaluation): the mean Euclidean distance between
  corresponding joints of the result and the source, divided by the stature.  Corresponding
  joints are those both skeletons have by role (:data:`COMPARED_ROLES`: pelvis, chest, neck,
  head, and per side shoulder, elbow, wrist, hip, knee, ankle, toe); every frame, each skeleton's
  positions are divided by its own stature (:attr:`~repro.motion.body.skeleton.Skeleton.height`:
  a common height of 1), the result's turned into the source's world (the rotation between the
  two rest body frames, :func:`~repro.motion.retargeting.trees.body_frame`) and both root-aligned
  (the pelvis subtracted).  There is no ground truth of the character performing the clip, so
  this measures how far the character's body is from the source's in the same pose: its
  proportions, and anything retargeting gets wrong (a role on the wrong joint);
* ``foot_slide_m`` (the figure: cm per contact frame): mean horizontal displacement per frame
  of the character's ankles on the frames where the source's ankle is planted
  (:func:`repro.motion.body.feet.foot_contacts`);
* ``penetration_m`` (cm): deepest point of the ankles / toes below the floor plane;
* ``eq1_gap_m`` (the figure's hit error at contact, cm): at the annotated hit frame, in the
  clip's first root frame, the distance from the character's striking joint (the wrist of a
  punch, the ankle of a kick: every character has them) to the source's, scaled by the ratio of
  statures (Eq. 1: where a retrieval asks the character to strike); ``hip_ratio_gap_m`` the
  same scaled by the ratio of hip heights (the representation's root path normalisation);
* ``hit_error_m``: at the hit frame, distance from the striking limb's distal joint to the
  representation's target (proximal joint + normalised limb vector x the character's limb
  length); non-zero only where the limb cannot reach;
* ``bone_length_error``: largest relative difference between a bone of the result and the
  character's bone;
* ``limb_angle_deg``: largest angle between a source limb's shoulder->wrist / hip->ankle
  direction (mapped into the character's world) and the result's: the pose reads the same;
* ``roles``: ``"as built"`` when the roles found on the character are the joints it was built
  with (:func:`~repro.motion.database.synthetic.conventions.build_character`), else which
  differ; ``error``: the :class:`~repro.errors.MotionError` of a character retargeting refuses
  (its row's metrics then NaN).

Every case is retargeted twice, ``fix_feet`` False (the representation alone) and True
(planted ankles pinned, no ankle/toe below the floor: ``retarget(..., fix_feet=True)``);
the pinned feet bend the legs away from the source's directions (``limb_angle_deg`` of
a few degrees), and the foot slide and ground penetration fall to zero.

Real data: besides two whole takes (no hit annotation), annotated clips of the CMU +
Bandai Namco database (:func:`repro.motion.database.sources.build_real_database`) give the
hit columns, in the clip's first root frame (where the database keeps hit points):
``eq1_gap_m``, the distance from the retargeted hit point (there: the character's joint of
the clip's ``hit_role``) to the source's hit point scaled by Eq. 1 (``size_c / size_a``),
and ``hip_ratio_gap_m``.
Eq. 1 needs the two rigs' statures measured alike.  The Bandai skeleton has a zero-length head
End Site (no head top) and a rest pose that cannot tell the ankle height; its stature
(:mod:`repro.motion.body.stature`: floor to head top, straightened, with the ankle height and
the head top estimated from Winter 2009 where the rig does not tell) is 1.464 m against CMU's
1.635 m (ratio 1.117), beside a hip-height ratio of 1.156.  The retargeted root path follows
the hip heights and the limbs their lengths, so the hit point lands near the hip-ratio point;
with the statures measured alike the Eq. 1 point is close to it (the Bandai kick on a CMU
character: ``eq1_gap_m`` about 4 cm in the quick run).  Before the stature was measured one
way on every rig, Bandai's came out at 1.298 m (ratio 1.26) and the same kick missed its Eq. 1
point by about 0.2 m.  (Before the rest offsets carried each segment's twist, the Bandai
pelvis also came out turned ~43 deg about the trunk on a CMU character.)

Quick: every character x two statures x two clips; full: every character x five statures
x eight clips; plus the real-data pairs when staged.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pandas as pd

from repro.experiments.progress import bar
from repro.experiments.registry import Result, experiment

HEIGHTS = (1.2, 1.5, 1.75, 2.0, 2.2)
HEIGHTS_QUICK = (1.2, 2.2)
CLIPS = tuple((k, s) for k in ("punch", "kick_front", "kick_side", "kick_round") for s in ("left", "right"))
CLIPS_QUICK = (("punch", "right"), ("kick_round", "left"))
LIMBS = {"arm": ("shoulder", "wrist"), "leg": ("hip", "ankle")}
#: The roles the joint-position error compares (those both skeletons have).
COMPARED_ROLES = ("pelvis", "chest", "neck", "head") + tuple(
    f"{s}_{k}" for s in ("left", "right") for k in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle", "toe"))


def position_error(gs: np.ndarray, gt: np.ndarray, ss, ts, C: np.ndarray) -> float:
    """Aberman et al. (2020)'s joint-position error of the result (positions ``gt``, skeleton
    ``ts``) against the source (``gs``, ``ss``), module docstring: mean distance over frames and
    the :data:`COMPARED_ROLES` both have, each skeleton divided by its stature, root-aligned, in
    the source's world (``C`` maps it onto the character's)."""
    common = [r for r in COMPARED_ROLES if r in ss.roles and r in ts.roles]
    pts = []
    for g, sk, to_src in ((gs, ss, np.eye(3)), (gt, ts, C)):
        p = g[:, [sk.index(r) for r in common]] @ to_src / sk.height
        pts.append(p - p[:, :1])  # the pelvis first
    return float(np.linalg.norm(pts[1] - pts[0], axis=-1).mean())


def _limb_angle(gs, gt, ss, ts, C) -> float:
    worst = 0.0
    for side in ("left", "right"):
        for a, b in LIMBS.values():
            va = (gs[:, ss.index(f"{side}_{b}")] - gs[:, ss.index(f"{side}_{a}")]) @ C.T
            vb = gt[:, ts.index(f"{side}_{b}")] - gt[:, ts.index(f"{side}_{a}")]
            cos = np.sum(va * vb, -1) / np.maximum(np.linalg.norm(va, axis=-1) * np.linalg.norm(vb, axis=-1), 1e-300)
            worst = max(worst, float(np.degrees(np.arccos(np.clip(cos, -1, 1))).max(initial=0.0)))
    return worst


def _hit_error(gs, gt, ss, ts, C, hit_frame: int, hit_role: str) -> float:
    side, stem = hit_role.split("_", 1)
    kind = "arm" if stem in ("fist", "wrist", "hand") else "leg"
    a, b = LIMBS[kind]
    Ls, Lt = ss.limb_lengths[f"{side}_{kind}"], ts.limb_lengths[f"{side}_{kind}"]  # twist joints inside included
    f = int(hit_frame)
    n = (gs[f, ss.index(f"{side}_{b}")] - gs[f, ss.index(f"{side}_{a}")]) @ C.T / Ls
    goal = gt[f, ts.index(f"{side}_{a}")] + n * Lt
    return float(np.linalg.norm(gt[f, ts.index(f"{side}_{b}")] - goal))


def world_map(src, out, ss=None, ts=None) -> np.ndarray:
    """``C``: the rotation taking the source's world onto the result's (their rest body frames,
    :func:`~repro.motion.retargeting.trees.body_frame`)."""
    from repro.motion.body.skeleton import Skeleton, skeleton_of
    from repro.motion.body.units import infer_up
    from repro.motion.retargeting.trees import body_frame

    ss = Skeleton.from_motion(src) if ss is None else ss
    ts = skeleton_of(out) if ts is None else ts
    return body_frame(ts, out.up or infer_up(out, ts)) @ body_frame(ss, src.up or infer_up(src, ss)).T


@dataclasses.dataclass(frozen=True)
class Source:
    """What :func:`measure` reads of a source clip, computed once for all its characters."""

    skeleton: object
    up: str
    positions: np.ndarray
    contacts: np.ndarray

    @classmethod
    def of(cls, src) -> Source:
        from repro.motion.body.feet import foot_contacts
        from repro.motion.body.skeleton import Skeleton
        from repro.motion.body.units import infer_up

        ss = Skeleton.from_motion(src)
        ups, gs = src.up or infer_up(src, ss), src.global_positions()
        return cls(ss, ups, gs, foot_contacts(src, skeleton=ss, global_positions=gs, up_axis=2 if ups == "z" else 1))


def measure(src, out, *, hit_frame: int | None = None, hit_role: str | None = None, gaps: bool = False,
            source: Source | None = None) -> dict:
    """The accuracy columns of one retargeted clip (see the module docstring); metres.

    ``gaps``: with the hit, also ``eq1_gap_m`` and ``hip_ratio_gap_m`` of ``hit_role``
    (:func:`hit_gaps`, the result mapped into the source's world); ``source``: ``Source.of(src)``."""
    from repro.motion.body.skeleton import skeleton_of
    from repro.motion.body.units import infer_up

    source = Source.of(src) if source is None else source
    ss, gs, contacts = source.skeleton, source.positions, source.contacts
    ts = skeleton_of(out)
    upt = out.up or infer_up(out, ts)
    C = world_map(src, out, ss, ts)
    gt = out.global_positions()
    u_m = ts.unit_m or 1.0
    row = {"position_error": position_error(gs, gt, ss, ts, C), "limb_angle_deg": _limb_angle(gs, gt, ss, ts, C)}
    has_hit = hit_frame is not None and hit_role is not None
    row["hit_error_m"] = _hit_error(gs, gt, ss, ts, C, hit_frame, hit_role) * u_m if has_hit else np.nan
    if has_hit and gaps:
        row.update(_gaps((gs * (ss.unit_m or 1.0), ss), ((gt @ C) * u_m, ts), int(hit_frame), hit_role))
    # feet
    k = 2 if upt == "z" else 1
    slide = []
    for s, side in enumerate(("left", "right")):
        p = gt[:, ts.index(f"{side}_ankle")]
        horiz = np.delete(p, k, axis=-1)
        step = np.linalg.norm(np.diff(horiz, axis=0), axis=-1)
        both = contacts[1:, s] & contacts[:-1, s]
        if both.any():
            slide.append(float(step[both].mean()))
    row["foot_slide_m"] = float(np.mean(slide)) * u_m if slide else 0.0
    feet = [ts.index(r) for r in ("left_ankle", "right_ankle", "left_toe", "right_toe") if r in ts.roles]
    row["penetration_m"] = float(max(0.0, -gt[:, feet, k].min())) * u_m
    bl = np.linalg.norm(gt[:, 1:] - gt[:, out.parents[1:]], axis=-1)
    ref = np.linalg.norm(out.offsets[1:], axis=1)
    ok = ref > 0
    row["bone_length_error"] = float(np.abs(bl[:, ok] / ref[ok] - 1).max(initial=0.0))
    return row


def roles_note(character, built: dict[str, str]) -> str:
    """``"as built"``, or the roles found on other joints than the character was built with."""
    from repro.motion.body.skeleton import Skeleton

    found = Skeleton.from_motion(character).roles
    wrong = [f"{r}: {found.get(r)} (built {j})" for r, j in built.items() if found.get(r) != j]
    return "as built" if not wrong else "; ".join(wrong)


def _synthetic_rows(quick: bool, progress: bool = False) -> list[dict]:
    from repro.motion.database.synthetic import synthetic_clip
    from repro.motion.database.synthetic.conventions import CHARACTERS, build_character

    rows = []
    for kind, side in CLIPS_QUICK if quick else CLIPS:
        clip, ann = synthetic_clip(kind, side=side, seed=11)
        source = Source.of(clip)
        hit = {"hit_frame": ann["hit_frame"], "hit_role": f"{side}_{'wrist' if kind == 'punch' else 'ankle'}"}
        for name in bar(tuple(CHARACTERS), desc=f"cross_skeleton: {kind}_{side} on each character", unit="skeleton",
                        progress=progress):
            for h in HEIGHTS_QUICK if quick else HEIGHTS:
                ch, built = build_character(name, height=h)
                case = {"source": "synthetic", "clip": f"{kind}_{side}", "character": name, "height_m": h,
                        "joints": ch.n_joints, "body": CHARACTERS[name].describe()}
                rows += _character_rows(clip, ch, built, case, source, hit)
    return rows


def _character_rows(clip, ch, built: dict[str, str], case: dict, source: Source, hit: dict) -> list[dict]:
    """The rows of one clip on one character, without and with ``fix_feet``; a refusal is a row
    whose ``error`` says why (metrics NaN)."""
    from repro.errors import MotionError
    from repro.motion import retarget

    rows = []
    try:
        note = roles_note(ch, built)
    except MotionError as e:
        return [{**case, "fix_feet": fix, "roles": "", "error": f"{type(e).__name__}: {e}"} for fix in (False, True)]
    for fix in (False, True):
        row = {**case, "fix_feet": fix, "roles": note, "error": ""}
        try:
            out = retarget(clip, ch, fix_feet=fix)
        except MotionError as e:  # a finding: the row says why
            row["error"] = f"{type(e).__name__}: {e}"
        else:
            row.update(measure(clip, out, **hit, gaps=True, source=source))
        rows.append(row)
    return rows


def _real_rows(quick: bool) -> list[dict]:
    from repro import data
    from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, read_bvh, retarget

    if data.missing_reason("cmu-bvh") is not None or data.missing_reason("bandai") is not None:
        return []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cmu = read_bvh(data.fetch("mocap/cmu/135_04.bvh"), unit_m=CMU_UNIT_M)
        bandai = read_bvh(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), unit_m=BANDAI_UNIT_M)
    n = 120 if quick else cmu.n_frames
    cmu = dataclasses.replace(cmu, rotations=cmu.rotations[:n], positions=cmu.positions[:n])
    rows = []
    for name, src, tgt in (("cmu 135_04 -> bandai", cmu, bandai), ("bandai kick -> cmu", bandai, cmu)):
        for fix in (False, True):
            out = retarget(src, tgt, fix_feet=fix)
            row = {"source": name.split(" -> ")[0], "clip": name, "character": name.split(" -> ")[1],
                   "height_m": np.nan, "joints": tgt.n_joints, "fix_feet": fix}
            row.update(measure(src, out))
            rows.append(row)
    return rows + _real_clip_rows(quick)


def hit_gaps(src, out, hit_frame: int, hit_role: str) -> dict:
    """``eq1_gap_m`` and ``hip_ratio_gap_m`` of one retargeted clip (module docstring); metres."""
    from repro.motion.body.skeleton import Skeleton, skeleton_of

    ss, ts = Skeleton.from_motion(src), skeleton_of(out)
    return _gaps((src.global_positions() * (ss.unit_m or 1.0), ss), (out.global_positions() * (ts.unit_m or 1.0), ts),
                 hit_frame, hit_role)


def _gaps(source, result, hit_frame: int, hit_role: str) -> dict:
    """:func:`hit_gaps` of (metre positions, skeleton) pairs, both in one world."""
    from repro.motion.body.pose_frames import root_frames, to_root_frame

    out_m = {}
    for key, (g, sk) in (("s", source), ("t", result)):
        th, o = root_frames(g, sk.index("pelvis"), sk.index("left_hip"), sk.index("right_hip"))
        out_m[key] = (to_root_frame(g[hit_frame, sk.index(hit_role)], th[0], o[0]), sk)
    (ps, ss), (pt, ts) = out_m["s"], out_m["t"]
    return {"eq1_gap_m": float(np.linalg.norm(pt - ps * ts.size / ss.size)),
            "hip_ratio_gap_m": float(np.linalg.norm(pt - ps * ts.hip_height * ts.unit_m / (ss.hip_height * ss.unit_m))),
            "size_ratio": ts.size / ss.size, "hip_ratio": ts.hip_height * ts.unit_m / (ss.hip_height * ss.unit_m)}


def _real_clip_rows(quick: bool) -> list[dict]:
    """Annotated CMU and Bandai Namco clips onto the other skeleton, with the hit columns."""
    from repro.motion.retargeting.dispatch import retarget_to_tree
    from repro.motion.database.sources import build_real_database, clip_source_dataset

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        db = build_real_database()
    fam = clip_source_dataset(db)
    actor_of = {f: db.actors[int(db.actor[int(np.flatnonzero(fam == f)[0])])] for f in ("cmu135", "bandai")}
    rows = []
    for f, other, name in (("cmu135", "bandai", "cmu"), ("bandai", "cmu135", "bandai")):
        for sem in ("kick", "punch"):
            idx = np.flatnonzero((fam == f) & (db.semantics == sem))[: 1 if quick else 3]
            for j in idx.tolist():
                src, hf, role = db.motion(j), int(db.hit_frame[j]), str(db.hit_roles[j])
                side, stem = role.split("_", 1)
                m_role = f"{side}_{'wrist' if stem in ('fist', 'hand', 'wrist') else 'ankle'}"
                for fix in (False, True):
                    out = retarget_to_tree(src, actor_of[other], fix_feet=fix)  # the database world, Y up
                    row = {"source": name, "clip": str(db.names[j]), "character": "cmu" if other == "cmu135" else other,
                           "height_m": np.nan, "joints": actor_of[other].n_joints, "fix_feet": fix}
                    row.update(measure(src, out, hit_frame=hf, hit_role=m_role))
                    row.update(hit_gaps(src, out, hf, role))
                    rows.append(row)
    return rows


#: The figure's panels: (column, scale to the plotted unit, the unit, label, aggregate, round-off floor in the column's unit).
PANELS = (
    ("position_error", 100.0, "%", "joint-position error (% of stature)\n(Aberman et al. 2020), mean", "mean", 1e-9),
    ("foot_slide_m", 100.0, "cm", "foot skate (cm per contact frame), mean", "mean", 1e-8),
    ("penetration_m", 100.0, "cm", "ground penetration (cm), deepest", "max", 1e-8),
    ("eq1_gap_m", 100.0, "cm", "hit error at contact (cm), mean\n(striking joint vs the Eq. 1 target)", "mean", 1e-8),
)


def _figure_groups(table: pd.DataFrame) -> pd.DataFrame:
    """The table with a ``group`` column: the synthetic characters, then the real pairs."""
    t = table.copy()
    real = t.source != "synthetic"
    t["group"] = t.character
    t.loc[real, "group"] = [f"real: {s.split()[0]} -> {c}" for s, c in zip(t.source[real], t.character[real])]
    return t


def _panel(ax, t: pd.DataFrame, groups: list, labels: list, col: str, k: float, unit: str, label: str, how: str,
           floor: float) -> None:
    width = 0.4
    notes = []
    for off, fix, color in ((-width / 2, False, "tab:blue"), (width / 2, True, "tab:orange")):
        sub = t[t.fix_feet.astype(bool) == fix]
        v = sub.groupby("group")[col].agg(how).reindex(groups)
        if v.notna().any() and (v.dropna() < floor).all():
            notes.append(f"{'with' if fix else 'without'} fix_feet: round-off (< {floor * k:g} {unit}) on every character")
            continue
        x = np.arange(len(groups)) + off
        drawn = v.where(v >= floor)
        ax.bar(x, drawn.values * k, width, color=color, label=f"fix_feet={fix}")
        for xi, vi in zip(x, v.values):
            if np.isfinite(vi) and vi < floor:
                ax.text(xi, 0, "0" if vi == 0 else "~0", ha="center", va="bottom", fontsize=8, color=color)
            elif not np.isfinite(vi) and len(sub):
                ax.text(xi, 0, "n/a", ha="center", va="bottom", fontsize=8, rotation=90, color=color)
    ax.set_xticks(range(len(groups)), labels, rotation=35, ha="right", fontsize=8)
    ax.tick_params(axis="y", labelsize=8)
    ax.set_ylabel(label, fontsize=9)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8, loc="upper left")
    ax.set_ylim(0, ax.get_ylim()[1] * 1.15)
    if notes:
        ax.text(0.99, 0.97, "\n".join(notes), transform=ax.transAxes, ha="right", va="top", fontsize=8)


def draw(table: pd.DataFrame):
    import matplotlib.pyplot as plt

    t = _figure_groups(table)
    syn = t[t.source == "synthetic"]
    groups = list(dict.fromkeys(syn.group)) + sorted(set(t.group) - set(syn.group))
    wrong = syn[syn.get("roles", pd.Series("as built", index=syn.index)).fillna("as built") != "as built"]
    failed = syn[syn.get("error", pd.Series("", index=syn.index)).fillna("") != ""]
    fig, axes = plt.subplots(2, 2, figsize=(13, 9))
    labels = [g + (" *" if g in set(wrong.character) else "") + (" (refused)" if g in set(failed.character) else "")
              for g in groups]
    for ax, panel in zip(axes.flat, PANELS):
        _panel(ax, t, groups, labels, *panel)
    heights = ", ".join(f"{h:g}" for h in sorted(set(syn.height_m)))
    fig.suptitle(f"Synthetic clips retargeted onto characters of other bodies and trees (statures {heights} m), "
                 "and CMU <-> Bandai Namco", fontsize=11)
    built = syn[~syn.character.isin(wrong.character)].hit_error_m.max()
    herr = f"up to {built:.0e} m" + (" (round-off)" if built < 1e-6 else "")
    if len(wrong) and wrong.hit_error_m.max() > built:
        herr += f"; * up to {wrong.hit_error_m.max():.0e} m"
    foot = [f"~0: round-off (below the panel's floor); 0: exactly none. Distance to the representation's own target "
            f"at the hit (hit_error_m): {herr}."]
    for name, g in wrong.groupby("character"):
        foot.append(f"* {name}: roles found on other joints than built ({g.roles.iloc[0].split(';')[0]}; ...): "
                    "its errors are the role finder's")
    for name, g in failed.groupby("character"):
        foot.append(f"{name}: retargeting refused: {g.error.iloc[0][:110]}")
    fig.text(0.01, 0.005, "\n".join(foot), fontsize=8, ha="left", va="bottom")
    fig.tight_layout(rect=(0, 0.025 * len(foot) + 0.01, 1, 1))
    return fig


@experiment(
    "cross_skeleton",
    "Retargeting across joint trees and bodies: the synthetic clips on characters of other conventions and "
    "proportions (1.2-2.2 m) and CMU <-> Bandai Namco, with and without fix_feet; height-normalised joint-position "
    "error (Aberman et al. 2020), foot skate, ground penetration, hit error at contact",
    paper="pronost2008",
    data=("cmu-bvh", "bandai"),
)
def cross_skeleton(quick: bool = False, progress: bool = False) -> Result:
    table = pd.DataFrame(_synthetic_rows(bool(quick), bool(progress)) + _real_rows(bool(quick)))
    return Result(table=table, draw=lambda: draw(table))


def summary(result) -> str:
    """Markdown: per source and character, the figure's metrics and the worst of the other columns."""
    from repro.experiments.summaries import bullets, num

    t = result.table
    lines = []
    for (source, character, fix), g in t.groupby(["source", "character", "fix_feet"], sort=False):
        feet = ", fix_feet" if fix else ""
        refused = g["error"].fillna("").ne("") if "error" in g else pd.Series(False, index=g.index)
        if refused.any():
            lines.append(f"{source} onto *{character}*{feet}: refused ({g['error'][refused].iloc[0]})")
            continue
        hit = f", hit error at contact (Eq. 1 target) {num(g.eq1_gap_m.mean() * 100, 2)} cm" if g.eq1_gap_m.notna().any() else ""
        lines.append(f"{source} onto *{character}*{feet} ({int(g.joints.iloc[0])} joints, {len(g)} clips x statures): joint-position "
                     f"error {num(g.position_error.mean() * 100, 2)} % of stature{hit}, foot skate "
                     f"{num(g.foot_slide_m.mean() * 100, 2)} cm per contact frame, ground penetration "
                     f"{num(g.penetration_m.max() * 100, 2)} cm; limb-direction angle up to {num(g.limb_angle_deg.max(), 2)} deg, "
                     f"representation's hit error {num(g.hit_error_m.max(), 2)} m, bone-length error {num(g.bone_length_error.max(), 2)}")
    if "roles" in t:
        for character, g in t[t.roles.fillna("as built") != "as built"].groupby("character"):
            lines.append(f"*{character}*: roles found on other joints than built ({g.roles.iloc[0]})")
    if "eq1_gap_m" in t:
        kicks = t[t.eq1_gap_m.notna() & t["clip"].str.contains("kick") & (t.character == "cmu")]
        for _, r in kicks.head(1).iterrows():
            lines.append(f"Bandai kick on the CMU skeleton: the hit point lands {num(r.hip_ratio_gap_m, 2)} m from the source's "
                         f"scaled by the hip heights ({num(r.hip_ratio, 3)}) but {num(r.eq1_gap_m, 2)} m from its Eq. 1 "
                         f"point (statures {num(r.size_ratio, 3)}: the Bandai rig has no head top and no ankle height)")
    return bullets(lines)
