"""How an order is carried out (repro.motion.runtime.options.StrikeOptions): one set of defaults, the
paper's choices apart, and every valid combination of options tested pairwise (issue 24)."""

from __future__ import annotations

import dataclasses
from itertools import combinations

import numpy as np
import pytest

from repro.errors import MotionError, RetrievalError
from repro.motion.adaptation import AdaptOptions
from repro.motion.core.ops import EASINGS
from repro.motion.runtime.options import BLEND_S, REACH_LEVELS, StrikeOptions
from repro.motion.runtime.paper import PAPER
from repro.motion.runtime.strike import one_frame, strike
from repro.motion.search.arguments import METHODS
from tests.pairwise import pairwise

#: targets in the stance's root frame (metres): a punch the limb or spine reaches, a punch that needs
#: the root (or a step), a kick
ORDERS = {"near punch": ([0.0, 1.2, 1.0], "punch"), "far punch": ([0.0, 0.9, 1.2], "punch"),
          "kick": ([0.0, 1.0, 1.1], "kick")}

FACTORS = {
    "method": METHODS,
    "reach": REACH_LEVELS,
    "feet": ("pin", "plant", "track", None),
    "kind": EASINGS,
    "blend_s": (0.0, BLEND_S, 1.0),
    "order": tuple(ORDERS),
    "fix_feet": (False, True),
    "stream": (False, True),
    "early_stop": (False, True),
    "floor": (None, 0.0),
    "release": (None, 0.25),
}
ROWS = pairwise(FACTORS)


def test_the_rows_cover_every_pair_of_values():
    covered = {(a, repr(r[a]), b, repr(r[b])) for r in ROWS for a, b in combinations(FACTORS, 2)}
    for a, b in combinations(FACTORS, 2):
        for va in FACTORS[a]:
            for vb in FACTORS[b]:
                assert (a, repr(va), b, repr(vb)) in covered, (a, va, b, vb)
    assert len(ROWS) >= len(METHODS) * len(REACH_LEVELS)  # the two largest factors, crossed
    assert len(ROWS) < 40  # far below the 9,216 combinations


def test_the_defaults_are_the_librarys_and_the_paper_is_explicit():
    o = StrikeOptions()
    assert o.method == "exact" and o.reach == "root" and o.blend_s == BLEND_S and not o.fix_feet
    assert o.adapt == AdaptOptions() and o.adapt.feet == "plant" and o.adapt.floor == 0.0
    assert PAPER == dataclasses.replace(o, method="pruned", fix_feet=True)
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.method = "pruned"


@pytest.mark.parametrize(("field", "value", "error"), [
    ("method", "best", RetrievalError), ("reach", "all", MotionError), ("blend_s", -0.1, MotionError),
    ("max_root_shift", float("nan"), MotionError), ("fix_feet", 1, MotionError), ("adapt", None, MotionError),
    ("early_stop", "yes", MotionError), ("stream", None, MotionError),
])
def test_a_bad_option_is_refused_when_made(field, value, error):
    with pytest.raises(error, match=field):
        StrikeOptions(**{field: value})


@pytest.fixture(scope="module")
def setup(synthetic_retriever):
    from repro.motion.body.skeleton import scale_skeleton
    from repro.motion.retargeting.morphology import retarget

    r = synthetic_retriever
    db = r.db
    ch = scale_skeleton(db.actors[0], height=1.8)
    names = [str(n) for n in db.names]
    stance = one_frame(retarget(db.motion(names.index("actor2_punch_left_high")), ch), 0)
    q = r.prepare(stance, ch)
    best = {k: r.search_exhaustive(np.array(c, dtype=float), q, ch, sem) for k, (c, sem) in ORDERS.items()}
    return r, ch, stance, q, best


@pytest.mark.parametrize("row", ROWS, ids=[f"row{i}" for i in range(len(ROWS))])
def test_every_pair_of_options_gives_a_sound_strike(setup, row):
    r, ch, stance, q, best = setup
    row = dict(row)
    key = row.pop("order")
    c, sem = ORDERS[key]
    edit = AdaptOptions(**{k: row.pop(k) for k in ("feet", "kind", "floor", "release")})
    options = StrikeOptions(adapt=edit, **row)
    s = strike(r, ch, stance, c, sem, frame="root", query=q, options=options)
    # frame 0 is the current pose (blended into; blend_s=0 cuts to the clip); the bones keep their lengths
    if options.blend_s > 0:
        np.testing.assert_allclose(s.motion.global_positions()[0], stance.global_positions()[0], atol=1e-9)
    assert s.cost["bone_length_error_m"] < 1e-9
    # the levels tried go up in order, no higher than allowed, and the level used is one of them
    allowed = REACH_LEVELS[:REACH_LEVELS.index(options.reach) + 1]
    assert s.levels_tried == allowed[:len(s.levels_tried)] and s.level in s.levels_tried
    if sem == "kick":
        assert "step" not in s.levels_tried
    # the hit: reached means within the solver's tolerance; never further than before the solver by much
    assert np.isfinite(s.hit_error) and (not s.reached or s.hit_error < 1e-3)
    assert s.hit_error <= s.unadapted_error + 1e-6
    # the exact and exhaustive searches find the exhaustive optimum of d (Eq. 1)
    if options.method in ("exact", "exhaustive"):
        assert s.retrieval.d == pytest.approx(best[key].d, rel=1e-9)
    assert s.timings["first_frame"] <= s.timings["order"] + 1e-12 and np.isfinite(s.foot_slide)
