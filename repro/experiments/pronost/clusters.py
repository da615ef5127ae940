"""Pronost et al., Sections 3.2.1-3.2.2 and Fig. 4: what the k-means clusters and the hit-trajectory boxes look like.

The database is "organized into clusters in a precomputation process" by k-means of the
poses, compared with the aligned distance of Kovar et al. (Section 3.2.2); each clip
carries "the bounding box of [the hit-point] trajectory" (Section 3.2.1, Fig. 4: the
trajectory as red spots, the constraint ``c_r`` as a green spot), which the search uses
to discard clips (Section 3.3).

The clusters are those :class:`repro.motion.search.retrieval.MotionRetriever` builds by default:
:func:`repro.motion.search.kmeans.cluster_poses` of all poses with the default ``k``
(:func:`~repro.motion.search.kmeans.default_k`) and seed 0.  Poses are clouds of 17 joints in
their own root frame (origin on the floor below the pelvis, y up, z the heading, x the
body's left), divided by the actor's size; the centroids are mean clouds in the same
units, drawn as stick figures seen from the side (z to the right) and from the front
(the actor's left to the right).

``table``: one row per cluster: its size (poses), how many clips it draws from, the poses
of each semantics, the most common kind, the share of poses that can start a motion (before
their clip's hit frame) and the mean time to the hit.  Sizes sum to the number of poses.

``extra_tables["boxes"]``: one row per clip: the box (``box_min``, ``box_max``, metres,
root frame of the clip's first frame), its extents, the hit point, and
``boxes_containing_hit``: how many clips of the same semantics would pass the box test for
a target at this clip's hit point (rescaled to each clip's actor by Eq. 1) -- how much the
box test prunes.  The hit point is where the limb reaches furthest, so it lies on the
box's boundary (``hit_on_box_face``): a target a little beyond the reach fails the test of
the very clip that would reach it best.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.experiments.registry import Result, experiment

#: Stick-figure bones between pose roles (:data:`repro.motion.body.pose_frames.POSE_ROLES`).
BONES: tuple[tuple[str, str], ...] = (
    ("pelvis", "chest"), ("chest", "head"),
    ("chest", "left_shoulder"), ("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"),
    ("chest", "right_shoulder"), ("right_shoulder", "right_elbow"), ("right_elbow", "right_wrist"),
    ("pelvis", "left_hip"), ("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("left_ankle", "left_foot"),
    ("pelvis", "right_hip"), ("right_hip", "right_knee"), ("right_knee", "right_ankle"), ("right_ankle", "right_foot"),
)  # fmt: skip

_AXES = ("x", "y", "z")
#: Font size of the figure's small print (points at the saved size; at least 8, issue 26 item 5).
SMALL_FONT = 8
#: The centroid grid: columns, and each cell's width and height (units of the actor's size).
GRID_COLUMNS, CELL_W, CELL_H = 8, 2.0, 1.6


def cluster_table(name: str, db, clusters) -> pd.DataFrame:
    """One row per cluster (see the module docstring)."""
    rows = []
    pc = db.pose_clip
    to_hit = (db.hit_frame[pc] - db.pose_frame) / db.fps
    for c, m in enumerate(clusters.members):
        kinds, counts = np.unique(db.kinds[pc[m]], return_counts=True)
        j = int(np.argmax(counts))
        rows.append(dict(
            database=name, cluster=c, size=int(m.size), n_clips=int(np.unique(pc[m]).size),
            punch_poses=int(np.sum(db.semantics[pc[m]] == "punch")),
            kick_poses=int(np.sum(db.semantics[pc[m]] == "kick")),
            dominant_kind=str(kinds[j]), dominant_kind_share=float(counts[j] / m.size),
            startable_share=float(np.mean(to_hit[m] > 0)), mean_time_to_hit_s=float(np.mean(to_hit[m])),
            k=clusters.k, n_poses=db.n_poses,
        ))
    return pd.DataFrame(rows)


def box_table(name: str, db) -> pd.DataFrame:
    """One row per clip: box extents, hit point, and how many boxes contain its hit point (Eq. 1)."""
    lo, hi, hit = db.box_min, db.box_max, db.hit_position
    # target at clip i's hit point, for the actor of clip j: hit_i * size_a[j] / size_a[i] (Eq. 1)
    c_r = hit[:, None, :] * (db.size_a[None, :] / db.size_a[:, None])[..., None]  # (i, j, 3)
    inside = np.all((lo[None] <= c_r) & (c_r <= hi[None]), axis=2)
    same = db.semantics[:, None] == db.semantics[None, :]
    tol = 1e-9
    on_face = np.any((np.abs(hit - lo) <= tol) | (np.abs(hit - hi) <= tol), axis=1)
    out = pd.DataFrame({
        "database": name, "clip": np.arange(db.n_clips), "name": db.names, "semantics": db.semantics,
        "kind": db.kinds, "side": db.sides, "level": db.levels, "hit_role": db.hit_roles, "size_a": db.size_a,
        "n_frames": db.n_frames, "hit_frame": db.hit_frame,
    })
    for k, a in enumerate(_AXES):
        out[f"box_min_{a}"] = lo[:, k]
        out[f"box_max_{a}"] = hi[:, k]
    for k, a in enumerate(_AXES):
        out[f"extent_{a}"] = hi[:, k] - lo[:, k]
    out["volume_m3"] = np.prod(hi - lo, axis=1)
    for k, a in enumerate(_AXES):
        out[f"hit_{a}"] = hit[:, k]
    out["hit_on_box_face"] = on_face
    out["boxes_containing_hit"] = np.sum(inside & same, axis=1)
    out["same_semantics_clips"] = np.sum(same, axis=1)
    return out


def example_clips(db, n: int = 3) -> list[int]:
    """Up to ``n`` clips for the Fig. 4 panels: one kind per clip, both semantics, the median-size actor."""
    kinds = list(dict.fromkeys(db.kinds.tolist()))
    first = {s: next((k for k in kinds if db.semantics[db.kinds == k][0] == s), None) for s in ("punch", "kick")}
    chosen = [k for k in first.values() if k is not None]
    chosen += [k for k in kinds if k not in chosen]
    size = np.sort(db.size_a)[db.n_clips // 2]
    out = []
    for k in chosen[:n]:
        cand = np.flatnonzero(db.kinds == k)
        cand = cand[np.argsort(np.abs(db.size_a[cand] - size), kind="stable")]
        right = [i for i in cand if db.sides[i] == "right" and db.size_a[i] == db.size_a[cand[0]]]
        out.append(int(right[0] if right else cand[0]))
    return out


def example_target(db, i: int) -> np.ndarray:
    """A target ``c_r`` inside clip ``i``'s box near its hit point (15% of the way to the box centre)."""
    centre = 0.5 * (db.box_min[i] + db.box_max[i])
    return db.hit_position[i] + 0.15 * (centre - db.hit_position[i])


@experiment("clusters", "What the k-means pose clusters and the hit-trajectory boxes look like (Sections 3.2.1-3.2.2, "
            "Fig. 4 analog)", paper="pronost2008")
def clusters(quick: bool = False) -> Result:
    from repro.experiments.pronost.databases import databases
    from repro.motion.search.kmeans import cluster_poses

    made = [(name, db, cluster_poses(db.pose_points, None, seed=0)) for name, db in databases().items()]
    table = pd.concat([cluster_table(n, db, cl) for n, db, cl in made], ignore_index=True)
    boxes = pd.concat([box_table(n, db) for n, db, _ in made], ignore_index=True)
    return Result(table=table, draw=lambda: draw(made, table, boxes), extra_tables={"boxes": boxes})


# ------------------------------------------------------------------ drawing
def _stick(ax, pts, roles, ox, oy, horiz, mirror=1.0):
    """Draw one pose cloud (P, 3) projected on (horiz, y), offset by (ox, oy)."""
    idx = {r: i for i, r in enumerate(roles)}
    for a, b in BONES:
        if a in idx and b in idx:
            pa, pb = pts[idx[a]], pts[idx[b]]
            side = "left" if "left" in b else "right" if "right" in b else ""
            color = {"left": "C0", "right": "C3", "": "0.2"}[side]
            ax.plot([ox + mirror * pa[horiz], ox + mirror * pb[horiz]], [oy + pa[1], oy + pb[1]], "-", color=color,
                    lw=1.1, solid_capstyle="round")
    if "head" in idx:
        h = pts[idx["head"]]
        ax.plot(ox + mirror * h[horiz], oy + h[1], "o", color="0.2", ms=2.5)


def _centroids_panel(ax, name, db, cl, table):
    P = len(db.pose_roles)
    ncol, cw, rh = GRID_COLUMNS, CELL_W, CELL_H
    sub = table[table.database == name].set_index("cluster")
    for c in range(cl.k):
        pts = cl.centroids[c][-P:]  # the current frame of the window
        r, col = divmod(c, ncol)
        ox, oy = col * cw, -r * rh
        ax.plot([ox - 0.45, ox + 1.55], [oy, oy], color="0.8", lw=0.6)  # floor
        _stick(ax, pts, db.pose_roles, ox, oy, horiz=2)  # side view: z (forward) to the right
        _stick(ax, pts, db.pose_roles, ox + 1.1, oy, horiz=0)  # front view: x (actor's left) to the right
        s = sub.loc[c]
        ax.text(ox + 0.55, oy + 1.1, f"#{c}: {s['size']} poses\n{s.dominant_kind} {s.dominant_kind_share:.0%}",
                ha="center", va="bottom", fontsize=SMALL_FONT)
    rows = -(-cl.k // ncol)
    ax.set_xlim(-0.6, ncol * cw - 0.3)
    ax.set_ylim(-(rows - 1) * rh - 0.1, rh)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(f"{name}: the k = {cl.k} centroid poses (side view, forward to the right | front view; "
                 "blue = left limbs, red = right; units of the actor's size)", fontsize=9)


def _sizes_panel(ax, name, db, cl):
    pc = db.pose_clip
    kinds = list(dict.fromkeys(db.kinds.tolist()))
    bottom = np.zeros(cl.k)
    for n, k in enumerate(kinds):
        h = np.array([np.sum(db.kinds[pc[m]] == k) for m in cl.members])
        ax.bar(np.arange(cl.k), h, bottom=bottom, color=f"C{n}", label=k, width=0.8)
        bottom += h
    ax.set_xlabel("cluster")
    ax.set_ylabel("poses")
    ax.set_title(f"{name}: cluster sizes ({db.n_poses:,} poses in {cl.k} clusters),\nby kind of clip", fontsize=9)
    ax.legend(fontsize=SMALL_FONT, ncol=3, loc="upper center", bbox_to_anchor=(0.5, 0), borderaxespad=4.5,
              frameon=False)  # under the x label (4.5 font sizes), not over the bars
    ax.set_xticks(np.arange(cl.k)[:: max(1, cl.k // 12)])


def _box_edges(lo, hi):
    import itertools

    corners = np.array(list(itertools.product(*zip(lo, hi))))
    for a, b in itertools.combinations(range(8), 2):
        if np.sum(corners[a] != corners[b]) == 1:
            yield corners[a], corners[b]


def _fig4_panel(ax, name, db, examples):
    """3D: example trajectories (red dots), their boxes, a target c_r inside each (green); y up."""
    for n, i in enumerate(examples):
        tr = db.trajectory(i)
        # matplotlib 3D has z up: plot (x, z, y) so that the actor's y is up
        ax.scatter(tr[:, 0], tr[:, 2], tr[:, 1], color="red", s=6, depthshade=False)
        for a, b in _box_edges(db.box_min[i], db.box_max[i]):
            ax.plot([a[0], b[0]], [a[2], b[2]], [a[1], b[1]], color=f"C{n}", lw=0.9)
        c = example_target(db, i)
        ax.scatter([c[0]], [c[2]], [c[1]], color="limegreen", s=40, edgecolor="k", depthshade=False)
        ax.plot([], [], "-", color=f"C{n}", label=str(db.names[i]))
    from matplotlib.ticker import MaxNLocator

    ax.legend(fontsize=SMALL_FONT, loc="upper left")
    for axis, label, pad in ((ax.xaxis, "x (left, m)", 8), (ax.yaxis, "z (forward, m)", 8),
                             (ax.zaxis, "y (up, m)", 6)):
        axis.set_major_locator(MaxNLocator(4))  # few ticks: legible at 8 pt
        axis.set_label_text(label, fontsize=SMALL_FONT)
        axis.labelpad = pad
    ax.tick_params(labelsize=SMALL_FONT, pad=1)
    ax.view_init(elev=18, azim=-60)
    ax.set_box_aspect(None, zoom=0.85)  # room inside the panel for the axis labels
    ax.set_title(f"{name}: Fig. 4 analog: hit trajectories (red),\nboxes, a target c_r (green)", fontsize=9)


def _all_boxes_panel(ax, name, db, examples, boxes):
    from matplotlib.patches import Rectangle

    colors = {"punch": "C0", "kick": "C1"}
    for i in range(db.n_clips):
        lo, hi = db.box_min[i], db.box_max[i]
        ax.add_patch(Rectangle((lo[2], lo[1]), hi[2] - lo[2], hi[1] - lo[1], fc=colors[db.semantics[i]], alpha=0.06,
                               ec=colors[db.semantics[i]], lw=0.5))
    for n, i in enumerate(examples):
        tr = db.trajectory(i)
        ax.plot(tr[:, 2], tr[:, 1], ".", color="red", ms=3)
        lo, hi = db.box_min[i], db.box_max[i]
        ax.add_patch(Rectangle((lo[2], lo[1]), hi[2] - lo[2], hi[1] - lo[1], fill=False, ec=f"C{n}", lw=1.2))
        c = example_target(db, i)
        ax.plot(c[2], c[1], "o", color="limegreen", mec="k", ms=6)
    b = boxes[boxes.database == name]
    for s, c in colors.items():
        ax.plot([], [], "s", color=c, alpha=0.4, label=f"{s} boxes")
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("z (forward, m)")
    ax.set_ylabel("y (up, m)")
    ax.grid(alpha=0.3)
    frac = (b.boxes_containing_hit / b.same_semantics_clips).median()
    ax.set_title(f"{name}: all {db.n_clips} boxes, side view\n(examples outlined)", fontsize=9)
    # the key and the numbers under the axes, not over the boxes
    ax.legend(fontsize=SMALL_FONT, ncol=2, loc="upper center", bbox_to_anchor=(0.5, 0), borderaxespad=4.5,
              frameon=False,
              title=f"a target at a clip's hit point passes the box test of a median {frac:.0%}\nof the clips of its "
                    "semantics; the hit point is on its own box's face\n"
                    f"for {b.hit_on_box_face.mean():.0%} of the clips",
              title_fontsize=SMALL_FONT, alignment="center")


def draw(made, table: pd.DataFrame, boxes: pd.DataFrame):
    import matplotlib.pyplot as plt

    heights = [(-(-cl.k // GRID_COLUMNS)) * CELL_H + 0.6 for _, _, cl in made]  # centroid grid height (~inches)
    fig = plt.figure(figsize=(16, sum(h + 6.0 for h in heights)), layout="constrained")
    subs = np.atleast_1d(fig.subfigures(len(made), 1, height_ratios=[h + 6.0 for h in heights]))
    for sf, (name, db, cl), h in zip(subs, made, heights):
        ax = sf.subplot_mosaic([["cent", "cent", "cent"], ["sizes", "box3d", "boxes"]], height_ratios=[h, 6.0],
                               per_subplot_kw={"box3d": {"projection": "3d"}})
        ex = example_clips(db)
        _centroids_panel(ax["cent"], name, db, cl, table)
        _sizes_panel(ax["sizes"], name, db, cl)
        _fig4_panel(ax["box3d"], name, db, ex)
        _all_boxes_panel(ax["boxes"], name, db, ex, boxes)
    return fig


def summary(result) -> str:
    """Markdown: per database, the largest clusters, how pure the others are, and how hard the box test prunes."""
    from repro.experiments.summaries import bullets, num, pct

    t, boxes = result.table, result.extra_tables["boxes"]
    lines = []
    for name, g in t.groupby("database", sort=False):
        big = g.nlargest(3, "size")
        rest = g.drop(big.index)
        top_kind = g.dominant_kind.value_counts()
        lines.append(f"*{name}*: k = {int(g.k.iloc[0])} clusters of {int(g.n_poses.iloc[0]):,} poses; the three largest "
                     f"hold {', '.join(f'{int(s):,}' for s in big['size'])} poses from {int(big.n_clips.min())}-"
                     f"{int(big.n_clips.max())} clips; the others' median dominant-kind share is "
                     f"{pct(rest.dominant_kind_share.median())}; the most common dominant kind is "
                     f"{top_kind.index[0]} ({top_kind.iloc[0]} of {len(g)} clusters)")
        b = boxes[boxes.database == name]
        per = ", ".join(f"{num(s.boxes_containing_hit.median(), 2)} of the {int(s.same_semantics_clips.iloc[0])} {sem}es"
                        if sem == "punch" else
                        f"{num(s.boxes_containing_hit.median(), 2)} of the {int(s.same_semantics_clips.iloc[0])} {sem}s"
                        for sem, s in b.groupby("semantics"))
        lines.append(f"*{name}*: a target at a clip's own hit point falls in the boxes of a median of {per}; the hit "
                     f"lies on its own box's boundary for {pct(b.hit_on_box_face.mean())} of the {len(b)} clips")
    return bullets(lines)
