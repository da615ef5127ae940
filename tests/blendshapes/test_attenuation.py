"""Eq. (3) of Lewis et al. 2005: the direct formula, the cached Attenuator, limits, bad input."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from repro.blendshapes import (
    Attenuator,
    attenuate,
    check_selection,
    default_alpha,
    load_model,
    select_axis,
    select_pairs,
    select_vertices,
)
from repro.errors import AttenuationError, ReproError, SelectionError
from tests.helpers import grid_model


def reference_w2(D, w1, selected, alpha):
    """Eq. (3) from explicit selection matrices: S = E_S D, Sbar = E_Sbar D (independent of the library)."""
    n = D.shape[0]
    I = np.eye(n)
    mask = np.zeros(n, bool)
    mask[selected] = True
    S, Sbar = I[mask] @ D, I[~mask] @ D
    P, Q = Sbar.T @ Sbar, S.T @ S
    return np.linalg.solve(P + alpha * Q, P @ w1)


def random_problem(seed, n_vertices=40, m=7, k_vertices=3):
    rng = np.random.default_rng(seed)
    D = rng.normal(size=(3 * n_vertices, m))
    w1 = rng.normal(size=m)
    sel = select_vertices(rng.choice(n_vertices, size=k_vertices, replace=False))
    return D, w1, sel


def close(a, b, rtol=1e-9):
    a, b = np.asarray(a), np.asarray(b)
    assert np.linalg.norm(a - b) <= rtol * max(np.linalg.norm(b), 1e-300), (a, b)


# --------------------------------------------------------------- correctness
@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("alpha", [None, 1e-3, 1.0, 25.0, 3000.0])
def test_direct_and_cached_equal_explicit_reference(seed, alpha):
    D, w1, sel = random_problem(seed)
    a = default_alpha(sel.size, D.shape[0]) if alpha is None else alpha
    ref = reference_w2(D, w1, sel, a)
    close(attenuate(D, w1, sel, alpha), ref)
    close(Attenuator(D).attenuate(w1, sel, alpha), ref)


def test_large_selection_path_equals_reference():
    """More than half the rows selected: the Attenuator forms P from Sbar directly."""
    D, w1, _ = random_problem(3, n_vertices=30, m=5)
    sel = select_vertices(np.arange(25))  # 75 of 90 rows
    close(Attenuator(D).attenuate(w1, sel, 2.0), reference_w2(D, w1, sel, 2.0))


def test_default_alpha_is_unselected_over_selected():
    # the paper's Fig. 5: 6 of 2,016 vertices -> alpha = 335
    assert default_alpha(18, 3 * 2016) == pytest.approx(335.0)
    assert default_alpha(6, 3 * 2016) == pytest.approx((3 * 2016 - 6) / 6)
    D, w1, sel = random_problem(0)
    att = Attenuator(D)
    assert att.default_alpha(sel) == pytest.approx((D.shape[0] - sel.size) / sel.size)
    close(att.attenuate(w1, sel), att.attenuate(w1, sel, att.default_alpha(sel)))


def test_solution_minimises_eq2():
    """w2 is a minimum of alpha ||S w||^2 + ||Sbar (w - w1)||^2: any perturbation raises it."""
    D, w1, sel = random_problem(11)
    alpha = 7.0
    w2 = attenuate(D, w1, sel, alpha)
    mask = np.zeros(D.shape[0], bool)
    mask[sel] = True

    def energy(w):
        return alpha * np.sum((D[mask] @ w) ** 2) + np.sum((D[~mask] @ (w - w1)) ** 2)

    rng = np.random.default_rng(0)
    e2 = energy(w2)
    for _ in range(20):
        assert energy(w2 + 1e-3 * rng.normal(size=w2.size)) > e2


def test_attenuation_reduces_selected_motion_on_grid_model():
    model = grid_model()
    sel = select_vertices(model.regions["corner"])
    w1 = np.full(model.n_shapes, 0.7)
    att = Attenuator(model)
    before = np.linalg.norm(model.D[sel] @ w1)
    assert np.linalg.norm(model.D[sel] @ att.attenuate(w1, sel)) < 0.9 * before
    assert np.linalg.norm(model.D[sel] @ att.attenuate(w1, sel, 1e4)) < 0.1 * before


# ------------------------------------------------------------------ caching
def test_cache_reuses_and_bounds():
    D, w1, sel = random_problem(1)
    att = Attenuator(D, cache_size=2)
    M1 = att.matrix(sel, 5.0)
    assert att.matrix(sel, 5.0) is M1  # cached
    assert att.matrix(list(sel[::-1]), 5.0) is M1  # same selection, other order
    M2 = att.matrix(sel, 6.0)
    assert M2 is not M1
    att.matrix(select_vertices([0]), 5.0)
    assert len(att._M) == 2  # LRU bound holds
    with pytest.raises(ValueError):
        M2[0, 0] = 1.0  # cached results are read-only


def test_edit_attenuates_the_change_only():
    D, w1, sel = random_problem(4)
    att = Attenuator(D)
    w_base = np.linspace(0, 1, D.shape[1])
    w_final = att.edit(w_base, w_base + w1, sel, 3.0)
    close(w_final - w_base, reference_w2(D, w1, sel, 3.0))


def test_pose_needs_model_and_uses_f0():
    model = grid_model()
    att = Attenuator(model)
    w = np.full(model.n_shapes, 0.2)
    np.testing.assert_allclose(att.pose(w), model.pose(w))
    with pytest.raises(AttenuationError, match="BlendshapeModel"):
        Attenuator(model.D).pose(w)


# --------------------------------------------------------------- properties
problems = st.tuples(
    st.integers(0, 10_000),  # seed
    st.integers(8, 30),  # vertices
    st.integers(2, 9),  # shapes
    st.integers(1, 3),  # selected vertices (k rows = 3k < m sometimes, >= m sometimes)
)


@given(problems)
def test_alpha_to_zero_gives_w1(p):
    seed, n, m, k = p
    D, w1, sel = random_problem(seed, n, m, k)
    w2 = Attenuator(D).attenuate(w1, sel, 1e-9)
    assert np.linalg.norm(w2 - w1) <= 1e-5 * np.linalg.norm(w1)


@given(problems)
def test_alpha_to_infinity_drives_selected_motion_to_zero(p):
    seed, n, m, k = p
    D, w1, sel = random_problem(seed, n, m, k)
    if 3 * k >= m:  # S has no nullspace: S w2 -> 0 only as w2 -> 0; use a larger model
        D, w1, sel = random_problem(seed, n, 3 * k + 2, k)
    att = Attenuator(D)
    s1 = np.linalg.norm(D[sel] @ w1)
    s_big = np.linalg.norm(D[sel] @ att.attenuate(w1, sel, 1e9))
    assert s_big <= 1e-6 * s1
    # and the unselected part still moves: w2 is not simply zero
    assert np.linalg.norm(att.attenuate(w1, sel, 1e9)) > 1e-3 * np.linalg.norm(w1)


@given(problems)
def test_selected_motion_non_increasing_in_alpha(p):
    seed, n, m, k = p
    D, w1, sel = random_problem(seed, n, m, k)
    att = Attenuator(D)
    alphas = np.logspace(-3, 6, 25)
    motion = [np.linalg.norm(D[sel] @ att.attenuate(w1, sel, a)) for a in alphas]
    for lo, hi in zip(motion, motion[1:]):
        assert hi <= lo * (1 + 1e-9) + 1e-12


@given(problems, st.floats(1e-3, 1e6))
def test_untouched_selection_leaves_w1_unchanged(p, alpha):
    seed, n, m, k = p
    D, w1, sel = random_problem(seed, n, m, k)
    D[sel] = 0.0  # no shape touches the selected coordinates
    close(Attenuator(D).attenuate(w1, sel, alpha), w1, rtol=1e-8)
    close(attenuate(D, w1, sel, alpha), w1, rtol=1e-8)


# ------------------------------------------------------------- degenerate D
def test_rank_deficient_D_gives_least_squares_face():
    """Duplicate shape: many w2 solve Eq. (3); the face D w2 is unique and matches the reduced model."""
    D, w1, sel = random_problem(5, m=5)
    Dd = np.column_stack([D, D[:, 0]])  # column 5 duplicates column 0
    w1d = np.append(w1, 0.3)
    att = Attenuator(Dd)
    w2 = att.attenuate(w1d, sel, 4.0)
    assert att.rank == 5
    w1_reduced = w1.copy()
    w1_reduced[0] += 0.3
    face_ref = D @ reference_w2(D, w1_reduced, sel, 4.0)
    np.testing.assert_allclose(Dd @ w2, face_ref, atol=1e-9 * np.linalg.norm(face_ref))
    np.testing.assert_allclose(Dd @ attenuate(Dd, w1d, sel, 4.0), face_ref, atol=1e-9 * np.linalg.norm(face_ref))
    assert w2[0] == pytest.approx(w2[5])  # minimum-norm splits the duplicate evenly


def test_shape_supported_only_on_selection_is_suppressed():
    """P singular (a shape with no support outside the selection): solution still unique, that shape held."""
    D, w1, sel = random_problem(6, m=4)
    mask = np.zeros(D.shape[0], bool)
    mask[sel] = True
    D[~mask, 0] = 0.0  # shape 0 moves only selected coordinates
    w1 = np.array([1.0, 0, 0, 0])
    w2 = Attenuator(D).attenuate(w1, sel, 1.0)
    np.testing.assert_allclose(w2, 0.0, atol=1e-12)  # moving it would only move the selection


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "selected, message",
    [
        ([], "empty"),
        ([3, 3], "repeated"),
        ([-1], "outside"),
        ([10_000], "outside"),
        ([1.5], "integer"),
        ([[1, 2]], "1-D"),
        (np.zeros(120, bool), "boolean mask"),
        (np.arange(120), "every coordinate"),
    ],
)
def test_bad_selections(selected, message):
    D, w1, _ = random_problem(0)
    for call in (lambda: attenuate(D, w1, selected), lambda: Attenuator(D).attenuate(w1, selected)):
        with pytest.raises(SelectionError, match=message):
            call()


@pytest.mark.parametrize("alpha", [0, -1.0, float("nan"), float("inf"), "big"])
def test_bad_alpha(alpha):
    D, w1, sel = random_problem(0)
    with pytest.raises(AttenuationError, match="alpha"):
        attenuate(D, w1, sel, alpha)
    with pytest.raises(AttenuationError, match="alpha"):
        Attenuator(D).attenuate(w1, sel, alpha)


@pytest.mark.parametrize(
    "D, w1, message",
    [
        (np.zeros((10, 3)), np.zeros(3), "3n rows"),
        (np.zeros(12), np.zeros(3), "3n x m"),
        (np.full((12, 3), np.nan), np.zeros(3), "NaN"),
        (np.ones((12, 3)), np.zeros(4), r"shape \(3,\)"),
        (np.ones((12, 3)), np.array([0, np.nan, 0]), "NaN"),
    ],
)
def test_bad_D_and_w1(D, w1, message):
    with pytest.raises(AttenuationError, match=message) as info:
        attenuate(D, w1, [0])
    assert isinstance(info.value, ReproError)


# ---------------------------------------------------------------- selection helpers
def test_selection_helpers():
    np.testing.assert_array_equal(select_vertices([2, 0]), [0, 1, 2, 6, 7, 8])
    np.testing.assert_array_equal(select_vertices([2, 0], axes="y"), [1, 7])
    np.testing.assert_array_equal(select_vertices(5, axes=["x", "z"]), [15, 17])
    np.testing.assert_array_equal(select_pairs([(4, "y"), (1, 0), (1, "Z")]), [3, 5, 13])
    np.testing.assert_array_equal(select_axis("z", 3), [2, 5, 8])
    np.testing.assert_array_equal(check_selection([5, 1], 9), [1, 5])
    with pytest.raises(SelectionError, match="unknown axis 'w'"):
        select_vertices([1], axes="w")
    with pytest.raises(SelectionError, match="repeated"):
        select_vertices([1, 1])
    with pytest.raises(SelectionError, match="outside"):
        select_vertices([7], n_vertices=5)
    with pytest.raises(SelectionError, match="repeated"):
        select_pairs([(1, "x"), (1, 0)])
    with pytest.raises(SelectionError, match="pairs"):
        select_pairs([1, 2])
    with pytest.raises(SelectionError, match="empty"):
        select_pairs([])


# ------------------------------------------ on the real and the embedded face: the cached Attenuator equals the direct formula
def _scenarios(model):
    """The paper's three selections (Figs. 3, 4, 5) with their slider moves."""
    return [
        (select_vertices(model.regions["brow_middle"]), model.weights(Furrow=0.4), model.weights(Furrow=0.4, SmirkLeft=0.5, SmirkRight=0.5)),
        (select_vertices(model.regions["mouth_corners"], axes="y"), np.zeros(model.n_shapes), model.weights(SmirkLeft=0.7, SmirkRight=0.7)),
        (select_vertices(model.regions["under_left_eye"]), np.zeros(model.n_shapes), model.weights(Wince=0.7, SneerLeft=0.7, SneerRight=0.7)),
    ]


def _check(model):
    att = Attenuator(model)
    for sel, w_base, w_target in _scenarios(model):
        w1 = w_target - w_base
        for alpha in (None, 25.0, 3000.0):
            direct = attenuate(model.D, w1, sel, alpha)
            cached = att.attenuate(w1, sel, alpha)
            assert np.linalg.norm(cached - direct) <= 1e-9 * np.linalg.norm(direct)
            # and attenuation does what Eq. (2) is for: the selection moves less
            assert np.linalg.norm(model.D[sel] @ cached) < np.linalg.norm(model.D[sel] @ w1)


def test_procedural_face():
    model = load_model("procedural")
    assert Attenuator(model).default_alpha(select_vertices(model.regions["under_left_eye"])) == pytest.approx(335.0)
    _check(model)


@pytest.mark.data("ict")
def test_ict_face():
    _check(load_model("ict"))
