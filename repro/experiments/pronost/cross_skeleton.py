"""Retargeting across skeletons (issue 11; Pronost et al. Section 3.4.1, Kulpa et al. 2005).

The paper's database serves "hundreds of characters" with *different skeletons*.  This
figure plays the synthetic database on characters in other tools' conventions
(:mod:`repro.motion.synthetic.conventions`: Mixamo, MotionBuilder, Poser/DAZ, Second
Life, 3ds Max Biped, SMPL, Unreal, Unity -- extra spine joints, twist bones, fingers, face
joints, zero-length helpers, A-pose, Z-up) at statures 1.2-2.2 m, and on real data CMU
clips on the Bandai Namco skeleton and the reverse, through
:func:`repro.motion.retarget`.  Columns, per clip and character:

* ``hit_error_m``: at the annotated hit frame, distance from the striking limb's distal
  joint to the representation's target (proximal joint + normalised limb vector x the
  character's limb length); non-zero only where the limb cannot reach;
* ``foot_slide_m``: mean horizontal displacement per frame of the character's ankles on
  the frames where the source's ankle is planted (:func:`repro.motion.feet.foot_contacts`);
* ``penetration_m``: deepest point of the ankles / toes below the floor plane;
* ``bone_length_error``: largest relative difference between a bone of the result and the
  character's bone;
* ``limb_angle_deg``: largest angle between a source limb's shoulder->wrist / hip->ankle
  direction (mapped into the character's world) and the result's: the pose reads the same.

Quick: six conventions x two statures x two clips; full: every convention x five statures
x eight clips, plus the real-data pairs when staged.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pandas as pd

from repro.experiments.progress import bar
from repro.experiments.registry import Result, experiment

CONVENTIONS_QUICK = ("mixamo", "motionbuilder", "secondlife", "biped", "smpl", "unreal")
HEIGHTS = (1.2, 1.5, 1.75, 2.0, 2.2)
HEIGHTS_QUICK = (1.2, 2.2)
CLIPS = tuple((k, s) for k in ("punch", "kick_front", "kick_side", "kick_round") for s in ("left", "right"))
CLIPS_QUICK = (("punch", "right"), ("kick_round", "left"))
LIMBS = {"arm": ("shoulder", "wrist"), "leg": ("hip", "ankle")}


def measure(src, out, *, hit_frame: int | None = None, hit_role: str | None = None) -> dict:
    """The accuracy columns of one retargeted clip (see the module docstring); metres."""
    from repro.motion.feet import foot_contacts
    from repro.motion.retarget_tree import body_frame
    from repro.motion.skeleton import Skeleton, skeleton_of
    from repro.motion.units import infer_up

    ss, ts = Skeleton.from_motion(src), skeleton_of(out)
    ups, upt = src.up or infer_up(src, ss), out.up or infer_up(out, ts)
    C = body_frame(ts, upt) @ body_frame(ss, ups).T
    gs, gt = src.global_positions(), out.global_positions()
    u_m = ts.unit_m or 1.0
    row = {}
    # limb directions and the representation's target at the hit
    worst = 0.0
    for side in ("left", "right"):
        for kind, (a, b) in LIMBS.items():
            va = (gs[:, ss.index(f"{side}_{b}")] - gs[:, ss.index(f"{side}_{a}")]) @ C.T
            vb = gt[:, ts.index(f"{side}_{b}")] - gt[:, ts.index(f"{side}_{a}")]
            cos = np.sum(va * vb, -1) / np.maximum(np.linalg.norm(va, axis=-1) * np.linalg.norm(vb, axis=-1), 1e-300)
            worst = max(worst, float(np.degrees(np.arccos(np.clip(cos, -1, 1))).max(initial=0.0)))
    row["limb_angle_deg"] = worst
    if hit_frame is not None and hit_role is not None:
        side, stem = hit_role.split("_", 1)
        kind = "arm" if stem in ("fist", "wrist", "hand") else "leg"
        a, b = LIMBS[kind]
        mid = "elbow" if kind == "arm" else "knee"
        Ls = ss.bone_length(f"{side}_{mid}") + ss.bone_length(f"{side}_{b}")
        Lt = ts.bone_length(f"{side}_{mid}") + ts.bone_length(f"{side}_{b}")
        f = int(hit_frame)
        n = (gs[f, ss.index(f"{side}_{b}")] - gs[f, ss.index(f"{side}_{a}")]) @ C.T / Ls
        goal = gt[f, ts.index(f"{side}_{a}")] + n * Lt
        row["hit_error_m"] = float(np.linalg.norm(gt[f, ts.index(f"{side}_{b}")] - goal)) * u_m
    else:
        row["hit_error_m"] = np.nan
    # feet
    contacts = foot_contacts(src, skeleton=ss, global_positions=gs, up_axis=2 if ups == "z" else 1)
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


def _synthetic_rows(quick: bool, progress: bool = False) -> list[dict]:
    from repro.motion import retarget
    from repro.motion.synthetic import synthetic_clip
    from repro.motion.synthetic.conventions import CONVENTIONS, build

    rows = []
    convs = CONVENTIONS_QUICK if quick else tuple(c for c in CONVENTIONS if c != "unsided")
    for kind, side in CLIPS_QUICK if quick else CLIPS:
        clip, ann = synthetic_clip(kind, side=side, seed=11)
        hit_role = f"{side}_{'fist' if kind == 'punch' else 'foot'}"
        hit_role = hit_role if kind == "punch" else f"{side}_ankle"
        for conv in bar(convs, desc=f"cross_skeleton: {kind}_{side} on each convention", unit="skeleton",
                        progress=progress):
            for h in HEIGHTS_QUICK if quick else HEIGHTS:
                ch = build(conv, height=h)[0].motion(unit_m=1.0)
                out = retarget(clip, ch)
                row = {"source": "synthetic", "clip": f"{kind}_{side}", "character": conv, "height_m": h,
                       "joints": ch.n_joints}
                row.update(measure(clip, out, hit_frame=ann["hit_frame"], hit_role=hit_role.replace("fist", "wrist")))
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
        out = retarget(src, tgt)
        row = {"source": name.split(" -> ")[0], "clip": name, "character": name.split(" -> ")[1],
               "height_m": np.nan, "joints": tgt.n_joints}
        row.update(measure(src, out))
        rows.append(row)
    return rows


def draw(table: pd.DataFrame):
    import matplotlib.pyplot as plt

    syn = table[table.source == "synthetic"]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, col, lab in zip(axes, ("limb_angle_deg", "foot_slide_m", "bone_length_error"),
                            ("limb direction angle (deg), max", "foot slide while planted (m/frame)",
                             "bone length error (relative), max")):
        g = syn.groupby("character")[col].max()
        ax.bar(range(len(g)), g.values, color="tab:blue")
        ax.set_xticks(range(len(g)), g.index, rotation=45, ha="right", fontsize=8)
        ax.set_ylabel(lab, fontsize=8)
        ax.grid(alpha=0.3, axis="y")
    heights = ", ".join(f"{h:g}" for h in sorted(set(syn.height_m)))
    fig.suptitle(f"Synthetic database retargeted onto other skeletons (statures {heights} m)")
    fig.tight_layout()
    return fig


@experiment(
    "cross_skeleton",
    "Retargeting across joint trees: the synthetic database on characters of other conventions "
    "(1.2-2.2 m) and CMU <-> Bandai Namco; hit error, foot slide, penetration, bone lengths, limb directions",
    paper="pronost2008",
    data=("cmu-bvh", "bandai"),
)
def cross_skeleton(quick: bool = False, progress: bool = False) -> Result:
    table = pd.DataFrame(_synthetic_rows(bool(quick), bool(progress)) + _real_rows(bool(quick)))
    return Result(table=table, draw=lambda: draw(table))


def summary(result) -> str:
    """Markdown: per source and character convention, the worst of each accuracy column."""
    from repro.experiments.summaries import bullets, num

    t = result.table
    lines = []
    for (source, character), g in t.groupby(["source", "character"], sort=False):
        lines.append(f"{source} onto *{character}* ({int(g.joints.iloc[0])} joints, {len(g)} clips x statures): limb-direction "
                     f"angle up to {num(g.limb_angle_deg.max(), 2)} deg, hit error {num(g.hit_error_m.max(), 2)} m, foot slide "
                     f"{num(g.foot_slide_m.max(), 2)} m, ground penetration {num(g.penetration_m.max(), 2)} m, bone-length "
                     f"error {num(g.bone_length_error.max(), 2)} m")
    return bullets(lines)
