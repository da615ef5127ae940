"""The cross-skeleton accuracy table and figure (issue 11, item 5; issue 25, item 9)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.experiments.pronost.cross_skeleton import PANELS, cross_skeleton, measure
from repro.experiments.registry import registry
from repro.motion import retarget
from repro.motion.database.synthetic import synthetic_clip
from repro.motion.database.synthetic.conventions import CHARACTERS, build


@pytest.fixture(scope="module")
def quick():
    return cross_skeleton(quick=True)


def test_registered():
    assert "cross_skeleton" in registry()


def test_quick_table(quick):
    t = quick.table
    both = t[t.source == "synthetic"]
    syn = both[~both.fix_feet.astype(bool)]  # the representation alone
    assert syn.character.nunique() >= 6
    assert syn.height_m.min() <= 1.2 and syn.height_m.max() >= 2.2
    cols = ("position_error", "hit_error_m", "eq1_gap_m", "foot_slide_m", "penetration_m", "bone_length_error",
            "limb_angle_deg")  # fmt: skip
    for col in cols:
        assert col in t and np.all(np.isfinite(syn[col]))
    assert set(syn.character) == set(CHARACTERS) and (syn.error == "").all()  # no character refused today
    assert syn.bone_length_error.max() < 1e-9
    assert syn.limb_angle_deg.max() < 1e-3
    assert syn.hit_error_m.max() < 1e-6
    # fix_feet: every case again, planted ankles pinned (no slide), nothing below the floor
    fixed = both[both.fix_feet.astype(bool)]
    assert len(fixed) == len(syn) and syn.foot_slide_m.max() > 1e-5
    assert fixed.foot_slide_m.max() < 1e-9 and fixed.penetration_m.max() < 1e-9
    assert fixed.bone_length_error.max() < 1e-9 and fixed.hit_error_m.max() < 1e-6


def test_characters_differ(quick):
    """Other proportions: the joint-position error (% of stature) and the hit error at contact
    are real differences, not round-off, and differ between characters; some sink into the
    floor without fix_feet."""
    syn = quick.table[quick.table.source == "synthetic"]
    plain = syn[~syn.fix_feet.astype(bool)]
    err = plain.groupby("character").position_error.mean()
    assert err.min() > 0.01 and err.max() > 1.5 * err.min()
    hit = plain.groupby("character").eq1_gap_m.mean()
    assert hit.min() > 0.01 and hit.max() > 1.5 * hit.min()
    assert (plain.groupby("character").penetration_m.max() > 1e-3).sum() >= 2
    chain = {n for n, c in CHARACTERS.items() if c.twist == "chain"}
    assert (plain[~plain.character.isin(chain)].roles == "as built").all()


def test_same_body_is_round_off():
    """The synthetic actor renamed and scaled (build: the same body, Y and Z up): no joint-position
    error, nothing below the floor, the hit on its Eq. 1 target."""
    clip, ann = synthetic_clip("kick_round", side="left", seed=11)
    for conv in ("mixamo", "biped", "unreal"):
        out = retarget(clip, build(conv, height=1.5)[0].motion(unit_m=1.0))
        row = measure(clip, out, hit_frame=ann["hit_frame"], hit_role="left_ankle", gaps=True)
        assert row["position_error"] < 1e-9 and row["penetration_m"] < 1e-6 and row["hit_error_m"] < 1e-6
        assert row["eq1_gap_m"] < 1e-9  # statures and hip heights in one ratio: the hit lands on the Eq. 1 target


def test_figure_is_legible(quick):
    """Four panels, text of 8 pt or more inside the figure, no bar at round-off."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    fig = quick.draw()
    try:
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        box = fig.bbox
        texts = [x for x in fig.findobj(plt.Text) if x.get_visible() and x.get_text().strip()]
        assert texts and min(x.get_fontsize() for x in texts) >= 8
        for x in texts:
            e = x.get_window_extent(r)
            assert e.x0 >= box.x0 - 1 and e.x1 <= box.x1 + 1 and e.y0 >= box.y0 - 1 and e.y1 <= box.y1 + 1, x.get_text()
        assert len(fig.axes) == len(PANELS)
        for ax, (_col, k, _unit, _label, _how, floor) in zip(fig.axes, PANELS):
            heights = [p.get_height() for p in ax.patches if isinstance(p, Rectangle) and np.isfinite(p.get_height())]
            assert heights and min(heights) >= floor * k
    finally:
        plt.close(fig)


def test_measure_sees_a_wrong_pose():
    clip, ann = synthetic_clip("punch", seed=2)
    ch = build("smpl", height=1.5)[0].motion(unit_m=1.0)
    out = retarget(clip, ch)
    good = measure(clip, out, hit_frame=ann["hit_frame"], hit_role="right_wrist")
    # the same character, its rotations time-shifted: the limbs no longer point as the source's
    bad_motion = dataclasses.replace(out, rotations=np.roll(out.rotations, 20, axis=0))
    bad = measure(clip, bad_motion, hit_frame=ann["hit_frame"], hit_role="right_wrist")
    assert bad["limb_angle_deg"] > 10 * max(good["limb_angle_deg"], 1e-6)
    # sunk into the floor
    low = dataclasses.replace(out, positions=out.positions - np.array([0, 0.2, 0]))
    assert measure(clip, low)["penetration_m"] > 0.1 > good["penetration_m"]


@pytest.mark.data("cmu-bvh")
@pytest.mark.data("bandai")
def test_real_pairs(quick):
    t = quick.table
    real_all = t[t.source != "synthetic"]
    real = real_all[~real_all.fix_feet.astype(bool)]
    assert set(real.character) == {"bandai", "cmu"}
    assert real.bone_length_error.max() < 1e-9 and real.limb_angle_deg.max() < 1e-3
    fixed = real_all[real_all.fix_feet.astype(bool)]
    assert fixed.foot_slide_m.max() < 1e-9 and fixed.penetration_m.max() < 1e-9
    assert fixed.bone_length_error.max() < 1e-9
    # the annotated clips: at the hit, the representation's target is met; with the statures of both
    # rigs measured alike (repro.motion.body.stature), the Bandai kick on CMU lands near its Eq. 1 point
    # as near its hip-height-scaled one (it missed the Eq. 1 point by 0.20 m when Bandai's stature
    # lacked its head top and ankle height)
    clips = real[real.eq1_gap_m.notna()]
    assert clips.hit_error_m.max() < 1e-6
    kick = clips[(clips.character == "cmu") & clips["clip"].str.contains("kick")].iloc[0]
    assert kick.eq1_gap_m < 0.1 and kick.hip_ratio_gap_m < 0.1
    assert abs(kick.size_ratio - kick.hip_ratio) < 0.05
