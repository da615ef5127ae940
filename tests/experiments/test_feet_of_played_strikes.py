"""adapted_motions' feet table (issue 12, item 4): the feet of played strikes over every clip, read by claim K5."""

import numpy as np

from repro import data
from repro.claims import pronost
from repro.claims.ledger import evaluate
from repro.experiments.pronost import adapted_motions as am
from repro.experiments.pronost.databases import databases


def _expected_clips(db, quick):
    return [str(db.names[i]) for i in (range(0, db.n_clips, am.FEET_QUICK_STEP) if quick else range(db.n_clips))]


def test_the_quick_feet_table_covers_its_subset_of_every_database_and_keeps_the_limits(quick_figures):
    feet = quick_figures("adapted_motions").extra_tables["feet"]
    dbs = databases()
    assert set(feet.database) == set(dbs)
    assert ("cmu" in dbs) == (data.missing_reason("cmu-bvh") is None)
    for name, db in dbs.items():
        assert feet[feet.database == name]["clip"].tolist() == _expected_clips(db, quick=True)
    assert (feet.contact_frames > 0).all() and np.isfinite(feet.min_toe_height_m).all()
    assert feet.min_toe_height_m.min() >= pronost.PLAYED_TOE_FLOOR_M
    assert feet.max_foot_slide_m.max() < pronost.PLAYED_FOOT_SLIDE_M


def test_the_full_feet_table_covers_every_clip_and_keeps_the_limits():
    feet = am.feet_table(quick=False)
    for name, db in databases().items():
        part = feet[feet.database == name]
        assert part["clip"].tolist() == _expected_clips(db, quick=False) and len(part) == db.n_clips
    assert feet.min_toe_height_m.min() >= pronost.PLAYED_TOE_FLOOR_M
    assert feet.max_foot_slide_m.max() < pronost.PLAYED_FOOT_SLIDE_M


def test_the_measure_fails_when_the_feet_are_not_planted(monkeypatch):
    """The measure can fail: the old pin mode (no floor) lets toes dip through the floor."""
    import dataclasses

    from repro.motion import adaptation

    real = adaptation.adapt

    def pin(*a, **k):
        k["options"] = dataclasses.replace(k.get("options") or adaptation.AdaptOptions(), feet="pin", floor=None)
        return real(*a, **k)

    monkeypatch.setattr(adaptation, "adapt", pin)
    db = databases()["synthetic"]
    feet = am.feet_of_played_strikes(db, "synthetic", range(12))
    assert feet.min_toe_height_m.min() < pronost.PLAYED_TOE_FLOOR_M


def test_k5_reads_the_feet_table(quick_figures):
    k5 = next(c for c in pronost.LEDGER if c.id == "K5")
    assert "adapted_motions" in k5.figures
    row = evaluate([k5], quick_figures)[0]
    assert "played_min_toe_height_m=" in row["embedded_values"]
    assert "played_max_foot_slide_m=" in row["embedded_values"]
    assert "the played strikes" in row["embedded_why"] and "the decoder alone" in row["embedded_why"]

    # the verdict follows the table: a toe 1 cm under the floor makes the played strikes fail the limit
    def bad(name):
        r = quick_figures(name)
        if name == "adapted_motions":
            r.extra_tables["feet"].loc[0, "min_toe_height_m"] = -0.01
        return r

    worse = evaluate([k5], bad)[0]
    assert worse["embedded_verdict"] != "reproduced" and "limits" in worse["embedded_why"]


def test_summary_mentions_the_feet(quick_figures):
    text = am.summary(quick_figures("adapted_motions"))
    assert "feet of the played clips, synthetic" in text and "lowest toe during contacts" in text


def test_feet_table_is_deterministic():
    db = databases()["synthetic"]
    a = am.feet_of_played_strikes(db, "synthetic", range(0, db.n_clips, 24))
    b = am.feet_of_played_strikes(db, "synthetic", range(0, db.n_clips, 24))
    assert a.equals(b)
