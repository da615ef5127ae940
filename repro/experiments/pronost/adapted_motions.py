"""Pronost et al. (about 2008), Fig. 10 analog: punches and kicks selected into the database and adapted.

"Figure 10. Adaptation of various punches and kicks selected into the database. The
modified posture is depicted in light blue and the target is modeled as a blue sphere."
In the paper the sphere is the tracked head of the user; "the virtual fighter also moves
to stay at a reachable distance".

Here two fighters, 1.5 m and 2.0 m tall (the synthetic actor scaled uniformly), stand in
their fighting stance (frame 0 of ``actor2_punch_left_high`` retargeted to them) and are
ordered three punches and three kicks.  The targets are the same *heights* above the
floor for both fighters (the opponent does not change size), at lateral positions in
metres, and at a depth proportional to the fighter's height (it keeps "a reachable
distance"), in the fighter's root frame (:data:`TARGETS`).  Each order goes through the
whole pipeline: retrieval from the full synthetic database (Section 3.3, Eq. 1), the
paper's retargeting to the fighter (:func:`~repro.motion.retargeting.morphology.retarget` with
``fix_feet=True``, Section 3.4.1), placement on the current pose and the blend with it, and
the constraints solver from the start frame to the hit frame (Section 3.4.2): the one
pipeline, :func:`repro.motion.runtime.strike.strike`.

The figure draws, per fighter and order, the pose at the contact frame before adaptation
(grey) and after (light blue), the hit point's trajectory from the start frame to the
contact (dashed), and the target (blue sphere), in the fighter's root frame.  The table:
the clip chosen, the hit error at contact before and after adaptation, whether it was
reached and the reach level needed (limb / spine / root), how many frames needed CCD, the
largest slide of a planted foot, the bone-length error of the adapted motion and the cost
of the adaptation (:func:`repro.motion.adaptation.cost.adaptation_cost`).

The same orders are given on the CMU karate takes when they are staged (the CMU actor scaled to
1.5 m and 2.0 m, in the guard of its first lunge punch:
:func:`repro.experiments.pronost.databases.fighter_in_stance`); the table's first column is
``database``, so that claim K6 is judged on real motion too.  The figure draws the synthetic
database's orders.

``extra_tables["feet"]``: the feet of played strikes over a whole database (issue 12, item 4;
claim K5).  Every clip of the synthetic database (and of the CMU one when ``cmu-bvh`` is
staged) goes through the pipeline's retarget + adapt path: the clip's foot contacts are
detected once on the clip, it is retargeted with ``fix_feet=True`` to its actor scaled to
:data:`FEET_HEIGHT`, and adapted (``feet="plant"``, ``floor=0``) to a target
:data:`FEET_TARGET_OFFSET` beyond its own hit point at its hit frame.  One row per clip: the
lowest toe during the contact phases and the largest slide of a planted ankle.
``quick=True``: every :data:`FEET_QUICK_STEP`-th clip of each database.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.experiments.progress import bar
from repro.experiments.registry import Result, experiment

#: Fighter statures (m).
HEIGHTS = (1.5, 2.0)
#: (label, semantics, lateral x (m), height y (m), depth z (fraction of the fighter's height)).
TARGETS = (
    ("punch to the head, left", "punch", -0.30, 1.35, 0.45),
    ("punch to the head, centre", "punch", 0.00, 1.25, 0.45),
    ("punch to the chest, right", "punch", 0.30, 1.15, 0.45),
    ("kick to the head, left", "kick", -0.35, 1.20, 0.50),
    ("kick to the body, centre", "kick", 0.00, 0.95, 0.50),
    ("kick to the hip, right", "kick", 0.35, 0.70, 0.50),
)
TARGETS_QUICK = (TARGETS[0], TARGETS[2], TARGETS[3], TARGETS[5])
#: The feet table: character stature (m), target offset from the clip's own hit point (m, root frame
#: of the world: forward), and the quick mode's stride through each database's clips.
FEET_HEIGHT = 1.8
FEET_TARGET_OFFSET = (0.0, 0.0, 0.05)
FEET_QUICK_STEP = 6


def _segments(sk) -> list[tuple[int, int]]:
    """(parent, child) joint index pairs of every bone."""
    return [(int(p), j) for j, p in enumerate(sk.parents) if p >= 0]


def _compute(quick: bool, progress: bool = False):
    """The orders on every database present: the table (first column ``database``) and the synthetic
    database's poses (the figure)."""
    from repro.experiments.pronost.databases import databases

    rows, poses = [], []
    for name, db in databases().items():
        r, p = _orders(name, db, quick, progress)
        rows += r
        poses += p if name == "synthetic" else []
    return pd.DataFrame(rows), tuple(poses)


def _orders(name: str, db, quick: bool, progress: bool):
    from repro.experiments.pronost.databases import fighter_in_stance
    from repro.motion.body.pose_frames import to_root_frame
    from repro.motion.search.retrieval import MotionRetriever
    from repro.motion.runtime.paper import PAPER
    from repro.motion.runtime.strike import strike

    retriever = MotionRetriever(db, seed=0)
    rows, poses = [], []
    for H in bar(HEIGHTS, desc=f"adapted_motions: statures, {name}", unit="fighter", progress=progress):
        ch, stance = fighter_in_stance(db, H)
        q = retriever.prepare(stance, ch)
        for label, sem, x, y, zf in (TARGETS_QUICK if quick else TARGETS):
            c = np.array([x, y, zf * ch.size])
            s = strike(retriever, ch, stance, c, sem, frame="root", query=q, options=PAPER)
            r, a = s.retrieval, s.adaptation
            rows.append({
                "database": name, "height_m": H, "order": label, "semantics": sem, "target_x_m": x,
                "target_y_m": y, "target_z_m": float(c[2]), "clip": r.name, "start_frame": r.start_frame,
                "hit_frame": r.hit_frame, "fallback": r.fallback,
                "before_m": s.unadapted_error, "after_m": s.hit_error,
                "reached": s.reached, "level": s.level, "frames_ccd": int(np.sum(a.solver == "ccd")),
                "max_foot_slide_m": s.foot_slide, "bone_length_error_m": a.bone_length_error,
                **s.cost,
            })

            def to_char(P):  # world -> the fighter's root frame (at the order)
                return to_root_frame(P, q.heading, q.origin)

            tc, sl = s.tc, slice(0, s.tc + 1)
            poses.append({
                "height_m": H, "order": label, "target": c, "segments": _segments(ch),
                "original": to_char(s.original.global_positions()[tc]), "adapted": to_char(s.motion.global_positions()[tc]),
                "traj_original": to_char(s.original_hit_positions()[sl]), "traj_adapted": to_char(s.hit_positions()[sl]),
                "before_m": s.unadapted_error, "after_m": s.hit_error, "clip": r.name,
            })
    return rows, poses


def feet_of_played_strikes(db, name: str, clips=None, *, progress: bool = False) -> pd.DataFrame:
    """One row per clip of ``db`` (or of ``clips``): its feet once played (module docstring, the feet table)."""
    from repro.motion.adaptation import AdaptOptions, adapt
    from repro.motion.database.annotation import hit_point_trajectory
    from repro.motion.body.feet import foot_contacts, max_foot_slide, min_toe_height
    from repro.motion.retargeting.morphology import retarget
    from repro.motion.body.skeleton import scale_skeleton
    from repro.motion.runtime.strike import clip_effector

    rows = []
    for i in bar(range(db.n_clips) if clips is None else clips, desc=f"adapted_motions: feet, {name} clips", unit="clip",
                 progress=progress):
        i = int(i)
        m = db.motion(i)
        ch = scale_skeleton(db.actor_skeleton(i), height=FEET_HEIGHT)
        contacts = foot_contacts(m)  # once, on the retrieved clip, carried through
        mc = retarget(m, ch, fix_feet=True)
        tc, where = int(db.hit_frame[i]), str(db.hit_wheres[i])
        X = hit_point_trajectory(mc, str(db.hit_joints[i]), where)[tc] + np.asarray(FEET_TARGET_OFFSET)
        a = adapt(mc, clip_effector(db, i, ch), X, 0, tc, options=AdaptOptions(hit_point=where, feet="plant", floor=0.0),
                  contacts=contacts)
        g = a.motion.global_positions()
        rows.append({
            "database": name, "clip": str(db.names[i]), "semantics": str(db.semantics[i]),
            "frames": int(m.n_frames), "contact_frames": int(contacts.any(axis=1).sum()),
            "min_toe_height_m": min_toe_height(a.motion, contacts, skeleton=ch, global_positions=g),
            "max_foot_slide_m": max_foot_slide(a.motion, contacts, skeleton=ch, global_positions=g),
            "reached": bool(a.reached),
        })
    return pd.DataFrame(rows)


def feet_table(quick: bool, progress: bool = False) -> pd.DataFrame:
    """The feet table over every database present (every clip; every ``FEET_QUICK_STEP``-th when quick)."""
    from repro.experiments.pronost.databases import databases

    parts = []
    for name, db in databases().items():
        clips = range(0, db.n_clips, FEET_QUICK_STEP) if quick else None
        parts.append(feet_of_played_strikes(db, name, clips, progress=progress))
    return pd.concat(parts, ignore_index=True)


#: Colours of the figure (the paper's Fig. 10: "the modified posture is depicted in light blue and the target is
#: modeled as a blue sphere").
ORIGINAL_COLOR, ADAPTED_COLOR, TARGET_COLOR = "#8a8a8a", "#7ec8ff", "#1f4fe0"
PATH_ORIGINAL_COLOR, PATH_ADAPTED_COLOR = "#5a5a5a", "#2f8fd6"


def _grid(poses):
    heights = sorted({p["height_m"] for p in poses})
    orders = list(dict.fromkeys(p["order"] for p in poses))
    return heights, orders, [[next(p for p in poses if p["height_m"] == H and p["order"] == o) for o in orders]
                             for H in heights]


def _panel_title(p) -> str:
    return (f"{p['height_m']:.1f} m fighter: {p['order']}\n{p['clip']}\nhit error before {p['before_m']:.3f} m, "
            f"after {p['after_m']:.3f} m")


def draw(poses, renderer: str = "auto"):
    """The figure: pyvista renders when off-screen VTK works here, else matplotlib 3D stick figures.

    ``renderer``: ``"auto"`` (probe :func:`repro.ui.render.render_unavailable_reason`), ``"pyvista"`` or
    ``"matplotlib"``.  The figure's title says which renderer drew it.
    """
    from repro.ui.render import render_unavailable_reason

    if renderer not in ("auto", "pyvista", "matplotlib"):
        raise ValueError(f"renderer must be 'auto', 'pyvista' or 'matplotlib', not {renderer!r}")
    reason = render_unavailable_reason() if renderer != "matplotlib" else "matplotlib requested"
    if renderer == "pyvista" or (renderer == "auto" and reason is None):
        return _draw_pyvista(poses)
    return _draw_matplotlib(poses, reason)


def _draw_pyvista(poses):
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from repro.ui.render import skeleton_images

    heights, orders, grid = _grid(poses)
    flat = [p for row in grid for p in row]
    images = skeleton_images(
        [[p["original"], p["adapted"]] for p in flat], flat[0]["segments"],
        colors=[ORIGINAL_COLOR, ADAPTED_COLOR], bone_radius=[0.011, 0.017], joint_radius=[0.016, 0.024],
        targets=[p["target"] for p in flat], target_color=TARGET_COLOR, target_radius=0.05,
        paths=[[p["traj_original"], p["traj_adapted"]] for p in flat],
        path_colors=[PATH_ORIGINAL_COLOR, PATH_ADAPTED_COLOR], window_size=(420, 460),
        azimuth=-50.0, elevation=12.0)  # from in front, on the side the fighter faces: targets in view
    nrows, ncols = len(heights), len(orders)
    head = 1.05  # inches above the panels' titles: title and legend
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.4 * ncols, 4.2 * nrows + head), squeeze=False)
    for ax, img, p in zip(axes.ravel(), images, flat):
        ax.imshow(img)
        ax.set_axis_off()
        ax.set_title(_panel_title(p), fontsize=8.5)
    handles = [Line2D([], [], color=ORIGINAL_COLOR, lw=2, label="retrieved clip, pose at contact"),
               Line2D([], [], color=ADAPTED_COLOR, lw=4, label="adapted pose at contact"),
               Line2D([], [], color=TARGET_COLOR, marker="o", ls="", ms=9, label="target"),
               Line2D([], [], color=PATH_ORIGINAL_COLOR, lw=1, label="hit point's path, retrieved"),
               Line2D([], [], color=PATH_ADAPTED_COLOR, lw=1, label="hit point's path, adapted")]
    h = fig.get_figheight()
    fig.suptitle("Fig. 10 analog: punches and kicks selected into the database and adapted to targets\n"
                 "rendered with pyvista (off-screen VTK); the same camera for every panel, in the fighter's root "
                 "frame, start frame to contact", fontsize=10, y=1 - 0.06 / h, va="top")
    fig.legend(handles=handles, loc="upper center", ncol=5, fontsize=8.5, frameon=False,
               bbox_to_anchor=(0.5, 1 - 0.5 / h))
    fig.subplots_adjust(left=0.005, right=0.995, bottom=0.005, top=1 - (head + 0.5) / h, wspace=0.02, hspace=0.16)
    return fig


def _draw_matplotlib(poses, reason: str | None = None):
    import textwrap

    import matplotlib.pyplot as plt

    heights, orders, grid = _grid(poses)
    fig = plt.figure(figsize=(3.3 * len(orders), 3.9 * len(heights)))
    u, v = np.mgrid[0:2 * np.pi:16j, 0:np.pi:9j]
    for row, H in enumerate(heights):
        for col, order in enumerate(orders):
            p = grid[row][col]
            ax = fig.add_subplot(len(heights), len(orders), row * len(orders) + col + 1, projection="3d")
            for key, color, lw in (("adapted", ADAPTED_COLOR, 2.8), ("original", "0.4", 1.1)):
                P = p[key]
                for a, b in p["segments"]:  # plot axes: x lateral, z forward (depth), y up
                    ax.plot([P[a, 0], P[b, 0]], [P[a, 2], P[b, 2]], [P[a, 1], P[b, 1]], color=color, lw=lw)
            for key, color in (("traj_adapted", "#3a9ad9"), ("traj_original", "0.45")):
                T = p[key]
                ax.plot(T[:, 0], T[:, 2], T[:, 1], "--", color=color, lw=0.9)
            c, rad = p["target"], 0.05
            ax.plot_surface(c[0] + rad * np.cos(u) * np.sin(v), c[2] + rad * np.sin(u) * np.sin(v),
                            c[1] + rad * np.cos(v), color="tab:blue", alpha=0.8, linewidth=0)
            ax.set_xlim(0.8, -0.8)  # (x, depth, up) is left-handed: flip x, or the fighters are mirrored
            ax.set_ylim(-0.6, 1.2)
            ax.set_zlim(0.0, 2.1)
            ax.set_box_aspect((1.6, 1.8, 2.1))
            ax.view_init(elev=12, azim=-58)
            ax.set_xticks([-0.5, 0.0, 0.5])
            ax.set_yticks([0.0, 0.5, 1.0])
            ax.set_zticks([0.0, 0.5, 1.0, 1.5, 2.0])
            ax.tick_params(labelsize=6, pad=0)
            ax.set_title(_panel_title(p), fontsize=7.5)
    how = ("drawn with matplotlib" if reason == "matplotlib requested" else
           f"drawn with matplotlib, the fallback renderer: {reason or 'pyvista not used'}")
    fig.suptitle("Fig. 10 analog: punches and kicks selected into the database and adapted -- grey: retrieved clip "
                 "at contact, light blue: adapted, blue sphere: target (fighter's root frame, metres)\n"
                 + textwrap.fill(how, 170), fontsize=9.5, y=0.995, va="top")
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.02, top=0.85, wspace=0.02, hspace=0.18)
    return fig


@experiment(
    "adapted_motions",
    "Fig. 10 analog: punches and kicks selected into the database and adapted to targets, for a 1.5 m and a "
    "2.0 m fighter (original pose grey, adapted light blue, target as a sphere)",
    paper="pronost2008",
    data=("cmu-bvh",),  # the orders and the feet table: CMU too when staged (the figure: the synthetic orders)
)
def adapted_motions(quick: bool = False, progress: bool = False) -> Result:
    table, poses = _compute(bool(quick), bool(progress))
    return Result(table=table, draw=lambda: draw(poses), extra_tables={"feet": feet_table(bool(quick), bool(progress))})


def summary(result) -> str:
    """Markdown: how many orders are reached, what adaptation costs the body, and the misses."""
    from repro.experiments.summaries import bullets, num

    lines = []
    for name, t in result.table.groupby("database", sort=False):
        reached = t[t.reached]
        lines += [f"*{name}*: {len(reached)} of the {len(t)} orders are reached; pinned feet slide at most "
                  f"{num(1000 * t.max_foot_slide_m.max(), 2)} mm, bone lengths change at most "
                  f"{num(t.bone_length_error_m.max(), 2)} m",
                  f"*{name}*: correction (hit error before adaptation): {num(t.before_m.min(), 2)} to "
                  f"{num(t.before_m.max(), 2)} m"]
        for r in t.itertuples():
            lines.append(f"*{name}*, {num(r.height_m, 2)} m fighter, {r.order}: `{r.clip}` from frame {r.start_frame}, "
                         f"{num(r.before_m, 2)} m off before adaptation, {num(r.after_m, 2)} m after"
                         + ("" if r.reached else " (**missed**)"))
    feet = result.extra_tables.get("feet")
    if feet is not None and len(feet):
        for name, g in feet.groupby("database", sort=False):
            lines.append(f"feet of the played clips, {name} ({len(g)} clips): lowest toe during contacts "
                         f"{num(1000 * g.min_toe_height_m.min(), 2)} mm, planted feet slide at most "
                         f"{num(1000 * g.max_foot_slide_m.max(), 2)} mm")
    return bullets(lines)
