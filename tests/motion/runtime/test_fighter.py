"""The interactive fighter (repro.motion.runtime.fighter), Sections 3-4 (its panel: tests/ui/test_fighter_panel.py).

What is asserted (no timing is asserted, only that the timings exist):

* a strike reaches a reachable target within 1 cm at the contact frame, measured
  independently by forward kinematics of the hit point of the retrieved clip, for
  punches at standing head heights and kicks at crouched ones, on several characters;
  an unreachable target is a best effort flagged ``reached=False`` whose residual is the
  real distance, not an exception;
* the retrieved clip has the ordered semantics; the strike starts exactly at the
  current pose (continuity), is on the character's skeleton, keeps planted feet;
* the stage timings exist, are positive and add up to order -> first frame;
* following keeps the fighter at striking distance of a walking, crouching head and
  facing it;
* the simulated user is deterministic, stays in the 3 m x 3 m area and crouches;
* bad orders, targets and characters raise the library's errors.
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from repro.errors import MotionError, RetrievalError
from repro.motion.runtime.fighter import (
    AREA,
    KungFuFighter,
    Strike,
    character_from,
    simulated_user,
)
from repro.motion.runtime.paper import REACTION_BUDGET_S
from repro.motion.body.skeleton import Skeleton, scale_skeleton
from repro.motion.search.retrieval import MotionRetriever
from repro.motion.database.annotation import hit_point_trajectory

TIMING_KEYS = ("prepare", "search", "load_convert", "retarget", "adapt", "solver", "first_frame",
               "adapt_per_frame", "retarget_adapt_per_frame")


@pytest.fixture(scope="module")
def fighter():
    return KungFuFighter("synthetic", seed=0)


def fresh(fighter, **kw):
    """A new fighter sharing the (expensive) retriever of the module's one."""
    return KungFuFighter(fighter.db, retriever=fighter.retriever, **kw)


def fk_hit(strike: Strike, db) -> np.ndarray:
    """The hit point at the contact frame, by forward kinematics of the strike's motion (not the solver's report)."""
    i = strike.retrieval.clip
    return hit_point_trajectory(strike.motion, str(db.hit_joints[i]), str(db.hit_wheres[i]))[strike.tc]


# ------------------------------------------------------------------ strikes
@pytest.mark.parametrize("kind, head", [
    ("punch", (0.0, 1.65, 0.0)),
    ("punch", (0.8, 1.75, 0.6)),
    ("punch", (-1.0, 1.5, -0.5)),
    ("kick", (0.3, 1.3, 0.2)),
    ("kick", (-0.6, 1.1, 1.0)),
])
def test_strike_reaches_a_reachable_target_within_1cm(fighter, kind, head):
    f = fresh(fighter)
    f.follow(head, 0.0, snap=True)
    s = f.order(kind, head)
    assert s.reached, s.summary()
    assert s.hit_error < 0.01
    assert np.linalg.norm(fk_hit(s, f.db) - np.asarray(head)) < 0.01
    assert s.semantics == kind and s.kind == kind
    assert str(f.db.semantics[s.retrieval.clip]) == kind
    # the solver had something to do: the retrieved clip alone misses
    assert s.unadapted_error > s.hit_error


@pytest.mark.parametrize("height, arm, leg", [(1.5, 1.0, 1.0), (2.0, 1.2, 1.1), (1.3, 1.25, 0.75)])
def test_other_morphologies_reach_a_target_at_their_own_height(fighter, height, arm, leg):
    f = fresh(fighter, height=height, arm_scale=arm, leg_scale=leg)
    assert f.character.size == pytest.approx(height, rel=1e-9)
    head = (0.2, 0.85 * height, 0.1)
    f.follow(head, 0.0, snap=True)
    s = f.punch(head)
    assert s.reached and np.linalg.norm(fk_hit(s, f.db) - np.asarray(head)) < 0.01
    # the motion is on the character: bone lengths are the character's
    g = s.motion.global_positions()
    p = s.motion.parents
    bones = np.linalg.norm(g[:, 1:] - g[:, p[1:]], axis=-1)
    np.testing.assert_allclose(bones, np.broadcast_to(np.linalg.norm(f.character.offsets[1:], axis=1), bones.shape),
                               atol=1e-9)


def test_unreachable_target_is_a_flagged_best_effort(fighter):
    f = fresh(fighter, position=(0.0, -1.4), heading=0.0)
    head = (0.0, 1.7, 1.5)  # 2.9 m in front of the fighter: no limb reaches
    s = f.order("punch", head)
    assert not s.reached
    assert s.hit_error > 1.0
    assert s.hit_error == pytest.approx(np.linalg.norm(fk_hit(s, f.db) - np.asarray(head)), abs=1e-9)
    assert s.semantics == "punch"


def test_strike_starts_at_the_current_pose_and_keeps_feet_planted(fighter):
    f = fresh(fighter)
    head = (0.4, 1.6, 0.3)
    f.follow(head, 0.0, snap=True)
    f.advance(0.5)  # somewhere in the stance loop
    before = f.current_pose().global_positions()[0]
    s = f.order("kick", (0.4, 1.3, 0.3), commit=False)
    np.testing.assert_allclose(s.motion.global_positions()[0], before, atol=1e-9)
    np.testing.assert_allclose(s.original.global_positions()[0], before, atol=1e-9)
    assert s.foot_slide < 1e-6
    assert s.motion.frame_time == pytest.approx(1.0 / f.db.fps)
    assert 0 < s.tc < s.n_frames
    # commit=False leaves the fighter alone
    assert not f.strikes
    np.testing.assert_allclose(f.current_pose().global_positions()[0], before)


def test_commit_records_the_strike_and_moves_the_clock(fighter):
    f = fresh(fighter)
    head = (0.0, 1.6, 0.0)
    f.follow(head, 0.0, snap=True)
    t = f.time
    s = f.punch(head)
    assert f.strikes == [s]
    assert f.time == pytest.approx(t + (s.n_frames - 1) / f.db.fps)


def test_target_is_expressed_in_the_root_frame_and_eq1_applies(fighter):
    f = fresh(fighter)
    head = np.array([0.5, 1.6, -0.2])
    f.follow(head, 0.0, snap=True)
    s = f.order("punch", head, commit=False)
    r = s.retrieval
    # c in the root frame of the current pose, at the striking distance horizontally
    assert np.hypot(s.target_local[0], s.target_local[2]) == pytest.approx(f.striking_distance, abs=0.02)
    assert s.target_local[1] == pytest.approx(head[1])
    np.testing.assert_allclose(r.c_r, s.target_local * r.size_a / f.character.size, atol=1e-12)


def test_every_order_retrieves_its_semantics(fighter):
    f = fresh(fighter)
    user = simulated_user(3, 20.0, 30.0)
    rng = np.random.default_rng(0)
    for _ in range(6):
        head = user[int(rng.integers(len(user)))]
        kind = str(rng.choice(["punch", "kick"]))
        f.follow(head, 0.0, snap=True)
        s = f.order(kind, head)
        assert s.semantics == kind
        assert s.effector.split("_")[1] in (("fist", "hand", "wrist") if kind == "punch" else ("foot", "toe", "ankle"))
        assert math.isfinite(s.hit_error) and math.isfinite(s.foot_slide)


def test_stage_timings_are_present_positive_and_add_up(fighter):
    f = fresh(fighter)
    f.follow((0, 1.6, 0), 0.0, snap=True)
    s = f.punch((0, 1.6, 0))
    t = s.timings
    assert set(TIMING_KEYS) <= set(t)
    assert all(t[k] > 0 for k in TIMING_KEYS)
    total = t["prepare"] + t["search"] + t["load_convert"] + t["adapt"]
    # the whole order is the sum of the stages; the first adapted frame comes before the
    # rest of the clip is solved (streamed: adapt = up to the first frame + rest)
    assert t["order"] == pytest.approx(total, rel=1e-9)
    assert t["first_frame"] == pytest.approx(total - t["rest"], rel=1e-9)
    assert 0 <= t["rest"] <= t["adapt"] and t["first_frame"] <= t["order"]
    assert t["retarget"] <= t["load_convert"] and t["solver"] <= t["adapt"]
    assert t["adapt_per_frame"] == pytest.approx(t["adapt"] / s.n_frames)
    assert s.budget_s == REACTION_BUDGET_S == pytest.approx(1 / 30)
    assert s.within_budget == (t["first_frame"] <= 1 / 30)
    summ = s.summary()
    assert {"clip", "d", "d_qr", "d_cr", "hit_error_m", "first_frame_ms", "within_budget"} <= set(summ)
    assert "first_frame_ms" not in s.summary(timings=False)
    assert f.setup_timings["retriever"] >= 0 and f.setup_timings["character"] > 0


# ------------------------------------------------------------------ following
def test_following_keeps_striking_distance_of_a_moving_head(fighter):
    f = fresh(fighter, position=(0.0, -2.0), heading=math.pi)  # starts far away, facing away
    user = simulated_user(1, 30.0, 30.0)
    dist, bearing = [], []
    for i, head in enumerate(user):
        st = f.follow(head, 1 / 30)
        if i >= 90:  # after 3 s to catch up
            dist.append(st.distance)
            bearing.append(abs(st.bearing_error))
    assert np.max(np.abs(np.array(dist) - f.striking_distance)) < 0.05
    assert np.degrees(np.max(bearing)) < 5.0
    assert f.time == pytest.approx(len(user) / 30, rel=1e-9)
    # and from there, a punch at the head lands
    head = user[-1]
    s = f.punch(head)
    assert s.reached or head[1] > 0.95 * f.character.size


def test_follow_is_rate_limited_and_snap_is_not(fighter):
    f = fresh(fighter, position=(0.0, -1.5), heading=0.0)
    st = f.follow((0.0, 1.7, 1.5), 0.1)
    assert 3.0 - st.distance == pytest.approx(0.2, abs=1e-9)  # MAX_SPEED 2 m/s x 0.1 s
    st = f.follow((0.0, 1.7, 1.5), 0.0, snap=True)
    assert st.distance == pytest.approx(f.striking_distance)
    assert f.striking_distance == pytest.approx(0.46 * f.character.size, rel=0.05)


# ------------------------------------------------------------------ the user
def test_simulated_user_is_deterministic_and_stays_in_the_area():
    a = simulated_user(7, 30.0, 30.0)
    b = simulated_user(7, 30.0, 30.0)
    c = simulated_user(8, 30.0, 30.0)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.shape == (901, 3)
    for k, (lo, hi) in enumerate(AREA):
        assert a[:, k].min() >= lo and a[:, k].max() <= hi
    assert a[:, 1].max() <= 1.8 and a[:, 1].min() >= 1.5 - 0.45
    assert a[:, 1].min() < 1.45  # it crouched at least once in 30 s
    speed = np.linalg.norm(np.diff(a[:, [0, 2]], axis=0), axis=1) * 30
    assert speed.max() < 1.6  # walking
    assert not a.flags.writeable
    assert simulated_user(0, 1.0, 60.0).shape == (61, 3)


# ------------------------------------------------------------------ errors
def test_bad_inputs_raise_the_librarys_errors(fighter):
    f = fresh(fighter)
    with pytest.raises(RetrievalError, match="unknown order"):
        f.order("headbutt", (0, 1.6, 0))
    with pytest.raises(RetrievalError, match="NaN"):
        f.order("punch", (0, float("nan"), 0))
    with pytest.raises(RetrievalError, match="outside the user's area"):
        f.order("kick", (2.5, 1.6, 0))
    with pytest.raises(RetrievalError, match="outside the user's area"):
        f.order("kick", (0, 3.0, 0))
    with pytest.raises(RetrievalError, match="3-vector"):
        f.order("punch", (0, 1.6))
    with pytest.raises(RetrievalError):
        f.follow((0, float("inf"), 0))
    with pytest.raises(MotionError):
        character_from(height=-1.0)
    with pytest.raises(MotionError):
        character_from(arm_scale=float("nan"))
    sk = f.db.actors[0]  # another joint tree: the same body with a joint renamed
    other = Skeleton(joint_names=[("Chest" if n == "Spine1" else n) for n in sk.joint_names], parents=sk.parents,
                     offsets=sk.offsets, channels=sk.channels, end_site_parents=sk.end_site_parents,
                     end_site_offsets=sk.end_site_offsets, unit_m=1.0)
    single = KungFuFighter(f.db, retriever=MotionRetriever(f.db, seed=0, across_trees=False))
    with pytest.raises(MotionError):
        single.set_character(other)
    with pytest.raises(MotionError):
        simulated_user(0, duration=0.0)
    with pytest.raises(MotionError):
        f.place((0.0, float("nan")))
    with pytest.raises(RetrievalError):
        KungFuFighter(database=42)
    assert not f.strikes  # nothing was committed


def test_set_character_changes_the_fighter(fighter):
    f = fresh(fighter)
    d = f.striking_distance
    f.set_character(character_from(2.0, base=f.db.actors[0]))
    assert f.character.size == pytest.approx(2.0)
    assert f.striking_distance == pytest.approx(d * 2.0 / 1.75, rel=1e-6)
    assert f.stance.joint_names == f.character.joint_names
    big = scale_skeleton(f.db.actors[0], height=1.9, leg_scale=1.2)
    f.set_character(big)
    assert f.current_pose().global_positions().shape[1] == len(big.joint_names)


@pytest.mark.data("cmu-bvh")
def test_fighter_on_the_cmu_database():
    f = KungFuFighter("cmu")
    head = (0.0, 0.85 * f.character.size, 0.0)
    f.follow(head, 0.0, snap=True)
    s = f.punch(head)
    assert s.semantics == "punch" and s.reached and s.hit_error < 0.01
    assert all(s.timings[k] > 0 for k in TIMING_KEYS)


def test_importing_the_fighter_does_not_import_widget_or_plot_libraries():
    code = ("import sys, repro.motion.runtime.fighter, repro.experiments\n"
            "bad = [m for m in ('ipywidgets', 'matplotlib') if m in sys.modules]\n"
            "assert not bad, bad\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr


def test_a_second_order_while_a_strike_plays_is_refused_and_keeps_the_target(fighter):
    f = fresh(fighter)
    head = (0.4, 1.6, 0.3)
    f.follow(head, 0.0, snap=True)
    s = f.order("punch", head, commit="play")
    assert f.playing is s and f.strikes == []
    stored = s.target.copy()
    with pytest.raises(MotionError, match="playing"):
        f.order("kick", (0.0, 1.0, 0.0))
    np.testing.assert_array_equal(s.target, stored)  # the stored target is not refreshed
    pos = f.position.copy()
    f.follow((1.0, 1.5, 1.0), 1.0 / 30)  # no following while the strike plays
    np.testing.assert_array_equal(f.position, pos)
    f.advance((s.n_frames - 1) / f.db.fps)
    assert f.playing is None and f.strikes == [s]
    f.follow(head, 0.0, snap=True)
    assert f.order("kick", head).kind == "kick"  # accepted once the strike is over
    with pytest.raises(MotionError, match="commit"):
        f.order("kick", head, commit="later")


# ------------------------------------------------------------------ every argument checked (issue 23)
@pytest.mark.parametrize(
    "call, match",
    [
        (lambda f: f.place("ab"), "position"),
        (lambda f: f.place((0, 0), "x"), "heading"),
        (lambda f: f.place((0, 0), float("inf")), "heading"),
        (lambda f: f.place((0, 0, 0)), "position"),
        (lambda f: f.advance("x"), "dt"),
        (lambda f: f.advance(None), "dt"),
        (lambda f: f.advance(-1.0), "dt"),
        (lambda f: f.advance(1e300), "dt"),
        (lambda f: f.follow((0.0, 1.6, 0.5), dt="x"), "dt"),
        (lambda f: f.follow((0.0, 1.6, 0.5), snap="yes"), "snap"),
        (lambda f: f.current_pose("a"), "frames"),
        (lambda f: f.current_pose(float("nan")), "frames"),
        (lambda f: f.current_pose(0), "frames"),
        (lambda f: f.current_pose(10**6), "frames"),  # used to raise MemoryError
        (lambda f: f.current_pose(10**18), "frames"),
        (lambda f: f.order(["punch"], (0.0, 1.6, 0.5)), "unknown order"),
        (lambda f: f.order("punch", (0.0, 1.6, 0.5), commit=np.array([True, False])), "commit"),
    ],
)
def test_fighter_methods_refuse_bad_arguments_with_motion_errors(fighter, call, match):
    f = fresh(fighter)
    with pytest.raises((MotionError, RetrievalError), match=match):
        call(f)
    assert not f.strikes and f.time == 0.0  # nothing changed


@pytest.mark.parametrize(
    "kw, match",
    [({"seed": -1}, "seed"), ({"seed": "x"}, "seed"), ({"position": "ab"}, "position"),
     ({"heading": "x"}, "heading"), ({"across_trees": "yes"}, "across_trees"), ({"height": "tall"}, "height")],
)
def test_fighter_constructor_checks_its_arguments_first(fighter, kw, match):
    with pytest.raises(MotionError, match=match):
        KungFuFighter(fighter.db, retriever=fighter.retriever, **kw)


def test_current_pose_is_bounded_by_the_memory_budget(fighter, monkeypatch):
    """check_alloc refuses what a frame count would allocate beyond the stated budget."""
    import repro.checks

    monkeypatch.setattr(repro.checks, "MEMORY_BUDGET", 1 << 20)
    f = fresh(fighter)
    assert f.current_pose(10).n_frames == 10
    with pytest.raises(MotionError, match="budget"):
        f.current_pose(100_000)


@pytest.mark.parametrize(
    "kw, match",
    [({"seed": -1}, "seed"), ({"duration": float("inf")}, "duration"), ({"duration": 1e12}, "duration"),
     ({"fps": "30"}, "fps"), ({"heights": "ab"}, "heights"), ({"crouch_depth": (0.1,)}, "crouch_depth"),
     ({"margin": None}, "margin")],
)
def test_simulated_user_checks_its_arguments(kw, match):
    with pytest.raises(MotionError, match=match):
        simulated_user(**kw)
