"""Bounded attenuation (Eq. 2 with lo <= w <= hi): optimality, the fast path, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from repro.blendshapes import Attenuator, load_model, select_vertices
from repro.blendshapes import scenarios as S
from repro.blendshapes.bounded import (
    bounded_attenuate,
    bounded_edit,
    check_bounds,
    clamped_edit,
    solve_box_qp,
)
from repro.blendshapes.metrics import selected_motion
from repro.errors import AttenuationError, SelectionError


@pytest.fixture(scope="module")
def face():
    m = load_model("procedural")
    return m, Attenuator(m)


def objective(A, g, x):
    return 0.5 * x @ A @ x - g @ x


def kkt_violation(A, g, x, lo, hi):
    """Largest violation of the box QP's optimality conditions at x (0 at the minimiser)."""
    grad = A @ x - g
    free = (x > lo) & (x < hi)
    v = np.abs(grad[free]).max(initial=0.0)
    v = max(v, (-grad[(x <= lo) & (lo < hi)]).max(initial=0.0))
    v = max(v, grad[(x >= hi) & (lo < hi)].max(initial=0.0))
    return v


@pytest.mark.parametrize("seed", range(40))
def test_box_qp_matches_lsq_linear_and_kkt(seed):
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 30))
    X = rng.normal(size=(m + int(rng.integers(-min(m - 1, 3), 6)), m))  # some rank-deficient
    A = X.T @ X
    g = X.T @ rng.normal(size=X.shape[0]) * 3  # g in the range of A, as P w1 always is
    lo = -rng.random(m)
    hi = rng.random(m)
    r = solve_box_qp(A, g, lo, hi)
    ref = solve_box_qp(A, g, lo, hi, method="lsq_linear")
    assert (r.x >= lo).all() and (r.x <= hi).all()
    assert objective(A, g, r.x) <= objective(A, g, ref.x) + 1e-9 * (1 + abs(objective(A, g, ref.x)))
    if np.linalg.matrix_rank(A) == m:
        assert kkt_violation(A, g, r.x, lo, hi) < 1e-7 * (1 + np.abs(g).max())
        np.testing.assert_allclose(r.x, ref.x, atol=1e-6)


def test_inside_the_range_is_eq3_exactly(face):
    m, att = face
    sel = select_vertices(m.regions["brow_middle"], n_vertices=m.n_vertices)
    w1 = m.weights(JawOpen=0.3)
    w3 = att.attenuate(w1, sel)
    r = bounded_attenuate(att, w1, sel, lo=-10, hi=10, info=True)
    assert r.method == "unconstrained" and r.iterations == 0
    np.testing.assert_array_equal(r.x, w3)


def test_fig5_scenario_leaves_the_range_and_bounded_keeps_more(face):
    m, att = face
    sc = S.scenario("wince_sneer_under_eye")
    sel = sc.selection(m)
    wb, wt = sc.weights(m)
    w3 = att.edit(wb, wt, sel)
    assert w3.min() < 0 or w3.max() > 1  # the premise: Eq. 3 leaves [0, 1] here
    wbnd = bounded_edit(att, wb, wt, sel)
    wclamp = clamped_edit(att, wb, wt, sel)
    assert wbnd.min() >= 0 and wbnd.max() <= 1
    np.testing.assert_array_equal(wclamp, np.clip(w3, 0, 1))
    d_base = att.displacement(wb)
    motion = {k: selected_motion(att.displacement(w), sel, d_base) for k, w in
              [("eq3", w3), ("bounded", wbnd), ("clamped", wclamp), ("none", wt)]}
    assert motion["bounded"] < motion["clamped"] < motion["none"]
    # Eq. 2's value: Eq. 3 (unconstrained) <= bounded (the in-range minimum) < the clamp
    A, P, _ = att.system(sel)
    g = P @ (wt - wb)
    assert objective(A, g, w3 - wb) <= objective(A, g, wbnd - wb) < objective(A, g, wclamp - wb)


def test_per_slider_bounds_and_one_sided(face):
    m, att = face
    sc = S.scenario("wince_sneer_under_eye")
    sel = sc.selection(m)
    w1 = sc.weights(m)[1]
    lo = np.full(m.n_shapes, -0.1)
    lo[0] = 0.0
    w = bounded_attenuate(att, w1, sel, lo=lo, hi=np.inf)
    assert (w >= lo).all()
    w3 = att.attenuate(w1, sel)
    assert np.isclose(bounded_attenuate(att, w1, sel, lo=-np.inf, hi=np.inf), w3).all()
    fixed = bounded_attenuate(att, w1, sel, lo=0.25, hi=0.25)
    np.testing.assert_array_equal(fixed, np.full(m.n_shapes, 0.25))


def test_request_outside_the_range_is_allowed(face):
    m, att = face
    sel = select_vertices(m.regions["brow_middle"], n_vertices=m.n_vertices)
    w = bounded_edit(att, np.full(m.n_shapes, 1.5), np.full(m.n_shapes, -0.5), sel)
    assert w.min() >= 0 and w.max() <= 1


def test_rank_deficient_model():
    m = load_model("procedural")
    D = np.column_stack([m.D, m.D[:, 0] + m.D[:, 1], np.zeros(m.D.shape[0])])
    att = Attenuator(D)
    sel = select_vertices(m.regions["under_left_eye"], n_vertices=m.n_vertices)
    w1 = np.zeros(D.shape[1])
    w1[:6] = 0.8
    r = bounded_attenuate(att, w1, sel, info=True)
    assert att.rank < D.shape[1]
    assert (r.x >= 0).all() and (r.x <= 1).all()
    A, P, _ = att.system(sel)
    ref = solve_box_qp(A, P @ w1, np.zeros(D.shape[1]), np.ones(D.shape[1]), method="lsq_linear")
    assert objective(A, P @ w1, r.x) <= objective(A, P @ w1, ref.x) + 1e-9


@pytest.mark.parametrize(
    "lo, hi, match",
    [(1.0, 0.0, "lo > hi"), (np.nan, 1.0, "NaN"), (0.0, "1", "string"), (np.zeros(3), 1.0, "shape"),
     (np.inf, np.inf, "empty"), (0.0, -np.inf, "empty"), (None, 1.0, "real numbers")],
)
def test_bad_bounds(face, lo, hi, match):
    m, att = face
    sel = select_vertices(m.regions["brow_middle"], n_vertices=m.n_vertices)
    with pytest.raises(AttenuationError, match=match):
        bounded_attenuate(att, m.weights(JawOpen=0.3), sel, lo=lo, hi=hi)


def test_bad_weights_selection_attenuator(face):
    m, att = face
    sel = select_vertices(m.regions["brow_middle"], n_vertices=m.n_vertices)
    w = m.weights(JawOpen=0.3)
    with pytest.raises(AttenuationError, match="NaN"):
        bounded_attenuate(att, np.full(m.n_shapes, np.nan), sel)
    with pytest.raises(AttenuationError, match="shape"):
        bounded_edit(att, w[:-1], w, sel)
    with pytest.raises(SelectionError):
        bounded_attenuate(att, w, [])
    with pytest.raises(AttenuationError, match="alpha"):
        bounded_attenuate(att, w, sel, alpha=-1)
    with pytest.raises(AttenuationError, match="Attenuator"):
        bounded_attenuate(m.D, w, sel)
    with pytest.raises(AttenuationError, match="method"):
        solve_box_qp(np.eye(2), np.ones(2), np.zeros(2), np.ones(2), method="magic")
    lo, hi = check_bounds(0, 1, 3)
    assert lo.tolist() == [0, 0, 0] and hi.tolist() == [1, 1, 1]


def test_box_qp_bad_input():
    ok = (np.eye(2), np.ones(2), np.zeros(2), np.ones(2))
    assert solve_box_qp(*ok).x.tolist() == [1.0, 1.0]
    with pytest.raises(AttenuationError, match="A must have shape"):
        solve_box_qp(np.eye(3), *ok[1:])
    with pytest.raises(AttenuationError, match="NaN"):
        solve_box_qp(np.full((2, 2), np.nan), *ok[1:])
    with pytest.raises(AttenuationError, match="g must be a 1-D"):
        solve_box_qp(ok[0], np.ones((2, 1)), *ok[2:])
    with pytest.raises(AttenuationError, match="x0 must have shape"):
        solve_box_qp(*ok, x0=np.ones(3))
    with pytest.raises(AttenuationError, match="max_iter"):
        solve_box_qp(*ok, max_iter=0)
    with pytest.raises(AttenuationError, match="lo > hi"):
        solve_box_qp(ok[0], ok[1], np.ones(2), np.zeros(2))


def test_box_qp_refuses_an_indefinite_matrix():
    """Issue 23 section 5: -I on [0, 1]^3 gave x = 0 (objective 0) where x = 1 gives -4.5, and
    diag(1, -1, 2) on [-1, 1] gave -0.25 where -2.25 is available: the solver is for PSD matrices only."""
    with pytest.raises(AttenuationError, match="positive semi-definite.*smallest eigenvalue is -1"):
        solve_box_qp(-np.eye(3), np.ones(3), 0, 1)
    with pytest.raises(AttenuationError, match="positive semi-definite"):
        solve_box_qp(np.diag([1.0, -1.0, 2.0]), np.ones(3), -1, 1)
    with pytest.raises(AttenuationError, match="symmetric"):
        solve_box_qp(np.array([[1.0, 2.0], [0.0, 1.0]]), np.ones(2), 0, 1)
    with pytest.raises(AttenuationError, match="positive semi-definite"):  # scaled first: no overflow
        solve_box_qp(np.diag([1e300, -1e300]), np.ones(2), 0, 1)
    # PSD matrices are still solved: singular, zero, near the float64 limit, with rounding noise
    assert solve_box_qp(np.zeros((3, 3)), np.zeros(3), 0, 1).x.tolist() == [0.0, 0.0, 0.0]
    assert solve_box_qp(np.diag([1e300, 0.0]), np.array([2e300, 0.0]), 0, 1).x[0] == 1.0
    X = np.random.default_rng(0).normal(size=(4, 6))
    A = X.T @ X  # rank 4 of 6: eigenvalues of order -1e-15
    assert np.linalg.eigvalsh(A)[0] < 1.0
    assert solve_box_qp(A, X.T @ np.ones(4), -1, 1).x.shape == (6,)


def test_box_qp_empty_problem_and_checked_arguments():
    r = solve_box_qp(np.zeros((0, 0)), np.zeros(0), 0, 1)  # a LAPACK error before
    assert r.x.shape == (0,) and r.method == "unconstrained"
    ok = (np.eye(2), np.ones(2), 0.0, 1.0)
    for method in (np.zeros(2), None, ["auto"]):  # an array used to fail in `not in` with a bare ValueError
        with pytest.raises(AttenuationError, match="method must be one of"):
            solve_box_qp(*ok, method=method)
    with pytest.raises(AttenuationError, match="max_iter"):
        solve_box_qp(*ok, max_iter=10**30)
    for m in ("x", None, -1, 1.5, np.nan):  # numpy's TypeError/ValueError before
        with pytest.raises(AttenuationError, match="m \\(number of shapes\\)"):
            check_bounds(0, 1, m)
    with pytest.raises(AttenuationError, match="MEMORY_BUDGET|budget"):  # 7 TiB asked of numpy before
        check_bounds(0, 1, 10**12)


def test_bounded_flags_are_checked(face):
    m, att = face
    sel = select_vertices(m.regions["brow_middle"], n_vertices=m.n_vertices)
    w = m.weights(JawOpen=0.3)
    for info in (np.zeros(2), "yes", 1, None):  # an array was used as a truth value (bare ValueError)
        with pytest.raises(AttenuationError, match="info must be True or False"):
            bounded_attenuate(att, w, sel, info=info)
        with pytest.raises(AttenuationError, match="info must be True or False"):
            bounded_edit(att, w, w, sel, info=info)
