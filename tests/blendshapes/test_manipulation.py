"""Direct manipulation (Lewis and Anjyo 2010) on the Attenuator's Gram form."""

from __future__ import annotations

import numpy as np
import pytest

from repro.blendshapes import Attenuator, BlendshapeModel, load_model, select_vertices
from repro.blendshapes.manipulation import DirectManipulator
from repro.errors import AttenuationError, SelectionError


@pytest.fixture(scope="module")
def face():
    m = load_model("procedural")
    return m, DirectManipulator(m)


def most_moved(m, w, k):
    return np.argsort(-np.linalg.norm(m.displacement(w), axis=1), kind="stable")[:k]


def test_reachable_target_is_reached(face):
    m, dm = face
    w0 = m.weights()
    wt = m.weights(SmirkLeft=0.7)
    v = most_moved(m, wt, 2)
    target = dm.positions(wt, v)
    r = dm.solve(w0, v, target, mu=1e-9, info=True)
    scale = np.linalg.norm(target - dm.positions(w0, v), axis=1).max()
    assert r.dragged_error < 1e-5 * scale
    np.testing.assert_allclose(m.pose(r.w)[v], target, atol=1e-5 * scale)


def test_enough_dragged_vertices_recover_the_weights(face):
    m, dm = face
    rng = np.random.default_rng(3)
    w_true = rng.random(m.n_shapes)
    v = rng.choice(m.n_vertices, size=400, replace=False)  # 1,200 coordinates for 27 shapes
    w = dm.solve(np.zeros(m.n_shapes), v, dm.positions(w_true, v), mu=1e-12)
    np.testing.assert_allclose(w, w_true, atol=1e-5)


def test_order_of_dragged_vertices_follows_targets(face):
    m, dm = face
    wt = m.weights(JawOpen=0.5)
    v = most_moved(m, wt, 3)
    a = dm.solve(m.weights(), v, dm.positions(wt, v))
    b = dm.solve(m.weights(), v[::-1], dm.positions(wt, v)[::-1])
    np.testing.assert_allclose(a, b, atol=1e-12)


def test_regularisation_pulls_towards_current_weights(face):
    m, dm = face
    w0 = m.weights(Blink=0.3)
    wt = w0 + m.weights(SmirkLeft=0.7)
    v = most_moved(m, m.weights(SmirkLeft=0.7), 2)
    target = dm.positions(wt, v)
    changes, errors = [], []
    for mu in (1e-6, 1e-3, 1e-1, 10.0, 1e3):
        r = dm.solve(w0, v, target, mu=mu, info=True)
        changes.append(np.linalg.norm(r.w - w0))
        errors.append(r.dragged_error)
    assert np.all(np.diff(changes) < 0) and np.all(np.diff(errors) > 0)
    assert changes[-1] < 1e-2 * changes[0]
    # no drag at all (target = where the vertices are): nothing changes
    np.testing.assert_allclose(dm.solve(w0, v, dm.positions(w0, v)), w0, atol=1e-12)


def test_pin_keeps_the_pinned_region(face):
    m, dm = face
    w0 = m.weights()
    wt = m.weights(SmirkLeft=0.7, Wince=0.5)
    v = m.regions["mouth_corners"]
    pin = select_vertices(m.regions["under_left_eye"], n_vertices=m.n_vertices)
    target = dm.positions(wt, v)
    free = dm.solve(w0, v, target, info=True)
    pinned = dm.solve(w0, v, target, pinned=pin, alpha=1e4, info=True)
    eye = m.regions["under_left_eye"]
    slider_motion = np.linalg.norm(m.displacement(wt)[eye], axis=1).max()
    free_motion = np.linalg.norm(m.displacement(free.w)[eye], axis=1).max()
    assert pinned.pinned_motion < 0.02 * slider_motion
    assert pinned.pinned_motion < free_motion
    assert pinned.dragged_error < 0.05 * np.linalg.norm(target - dm.positions(w0, v), axis=1).max()


def test_bounds(face):
    m, dm = face
    v = m.regions["mouth_corners"]
    target = dm.positions(m.weights(SmirkLeft=0.7), v) + np.array([0.0, 0.3, 0.0])  # beyond any slider pose
    w_free = dm.solve(m.weights(), v, target)
    r = dm.solve(m.weights(), v, target, lo=0.0, hi=1.0, info=True)
    assert w_free.min() < 0 or w_free.max() > 1
    assert r.w.min() >= 0 and r.w.max() <= 1 and r.method in ("active-set", "unconstrained")


def test_prepared_drags_are_cached_and_shared(face):
    m, dm = face
    v = [10, 20]
    assert dm.prepare(v) is dm.prepare([10, 20])
    assert dm.prepare(v, mu=0.1) is not dm.prepare(v)
    att = Attenuator(m)
    dm2 = DirectManipulator(att)
    assert dm2.attenuator is att


def test_scale_does_not_change_the_weights(face):
    m, dm = face
    big = BlendshapeModel(m.f0 * 2.0**200, m.D * 2.0**200, m.names, m.faces)
    dmb = DirectManipulator(big)
    wt = m.weights(JawOpen=0.4)
    v = most_moved(m, wt, 2)
    a = dm.solve(m.weights(), v, dm.positions(wt, v))
    b = dmb.solve(m.weights(), v, dmb.positions(wt, v))
    np.testing.assert_allclose(a, b, atol=1e-9)


def test_bad_input(face):
    m, dm = face
    w0 = m.weights()
    t = np.zeros((2, 3))
    with pytest.raises(AttenuationError, match=r"shape \(2, 3\)"):
        dm.solve(w0, [1, 2], np.zeros((3, 3)))
    with pytest.raises(AttenuationError, match="NaN"):
        dm.solve(w0, [1, 2], np.full((2, 3), np.nan))
    with pytest.raises(AttenuationError, match="w_current"):
        dm.solve(w0[:-1], [1, 2], t)
    with pytest.raises(SelectionError, match="repeated"):
        dm.solve(w0, [1, 1], t)
    with pytest.raises(SelectionError):
        dm.solve(w0, [1, m.n_vertices], t)
    with pytest.raises(SelectionError, match="both dragged and pinned"):
        dm.solve(w0, [1, 2], t, pinned=select_vertices([2, 3]))
    with pytest.raises(AttenuationError, match="mu"):
        dm.solve(w0, [1, 2], t, mu=0)
    with pytest.raises(AttenuationError, match="alpha"):
        dm.solve(w0, [1, 2], t, alpha=np.nan)
    with pytest.raises(AttenuationError, match="both lo and hi"):
        dm.solve(w0, [1, 2], t, lo=0)
    with pytest.raises(AttenuationError, match="lo > hi"):
        dm.solve(w0, [1, 2], t, lo=1, hi=0)
    with pytest.raises(AttenuationError, match="BlendshapeModel"):
        DirectManipulator(m.D)
    with pytest.raises(AttenuationError, match="neutral"):
        DirectManipulator(Attenuator(m.D))
    D = np.array(m.D)
    D[:3] = 0.0  # vertex 0 moves in no shape
    with pytest.raises(SelectionError, match="cannot be dragged"):
        DirectManipulator(BlendshapeModel(m.f0, D, m.names, m.faces)).solve(w0, [0], np.zeros((1, 3)))


def test_cache_size_is_validated_as_the_attenuators(face):
    """Issue 23 section 6: cache_size=-1 raised KeyError in solve(), "x" / None ValueError / TypeError."""
    m, _ = face
    v = m.regions["mouth_corners"][:1]
    target = m.pose(m.weights(SmirkLeft=0.7))[v]
    for bad in (-1, "x", None, 1.5, np.nan, True, 10**12):
        with pytest.raises(AttenuationError, match="cache_size must be an integer"):
            DirectManipulator(m, cache_size=bad)
        with pytest.raises(AttenuationError, match="cache_size must be an integer"):
            Attenuator(m, cache_size=bad)  # one validator for both
    dm = DirectManipulator(m, cache_size=0)  # keeps nothing, still solves
    w = dm.solve(m.weights(), v, target)
    assert np.isfinite(w).all() and len(dm._drags) == 0
    assert DirectManipulator(m, cache_size=np.int64(2))._cache_size == 2


def test_solve_flags_and_overflowing_targets_are_refused(face):
    m, dm = face
    v = m.regions["mouth_corners"][:1]
    for info in (np.zeros(2), "yes", None):
        with pytest.raises(AttenuationError, match="info must be True or False"):
            dm.solve(m.weights(), v, m.f0[v], info=info)
    # a target at 1e300 gave dragged_error = inf (np.linalg.norm squares 1e300): the distances are finite
    r = dm.solve(m.weights(), v, np.full((1, 3), 1e300), lo=0.0, hi=1.0, info=True)
    assert r.dragged_error == pytest.approx(np.sqrt(3) * 1e300, rel=1e-9)
    assert np.isfinite(dm.solve(m.weights(), v, np.full((1, 3), 1e300), info=True).dragged_error)
    with pytest.raises(AttenuationError, match="overflow"):  # the first weight that cannot be represented
        dm.solve(m.weights(), v, np.full((1, 3), 1.7e308), lo=-np.inf, hi=np.inf)
