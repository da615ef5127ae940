"""Section 3's rejected alternatives (zeroed rows, orthogonal locking), measured against attenuation."""

import numpy as np
import pytest

from repro.blendshapes import (
    Attenuator,
    edit_orthogonal,
    edit_zeroed,
    orthogonal_lock,
    select_vertices,
    zero_rows,
)
from repro.blendshapes import metrics
from repro.errors import AttenuationError, SelectionError
from tests.helpers import grid_model


@pytest.fixture(scope="module")
def model():
    return grid_model(nx=16, ny=14, m=6, seed=3)


def test_zero_rows_freezes_selection_exactly(model):
    sel = select_vertices([40, 41])
    Dz = zero_rows(model.D, sel)
    assert np.all(Dz[sel] == 0) and np.count_nonzero(Dz) == np.count_nonzero(model.D) - np.count_nonzero(model.D[sel])
    w0 = model.weights(s0=0.4)
    d = edit_zeroed(model.D, w0, w0 + 0.7, sel)
    # selected coordinates did not move after the selection was made
    assert metrics.selected_motion(d, sel, model.D @ w0) == 0.0


def test_zeroing_rows_tears_the_surface_attenuation_does_not(model):
    """Section 3: 'the adjustment of slider 2 will move vertex 2 away from its neighbour vertex 1'."""
    v = 5 * 16 + 7  # an interior vertex
    sel = select_vertices([v])
    w_base = np.zeros(model.n_shapes)
    w_target = np.full(model.n_shapes, 0.7)
    intended = model.D @ w_target
    zeroed = edit_zeroed(model.D, w_base, w_target, sel)
    att = Attenuator(model)
    attenuated = model.D @ att.edit(w_base, w_target, sel, 1e3)
    r_int = metrics.roughness(model, intended)
    r_zero = metrics.roughness(model, zeroed)
    r_att = metrics.roughness(model, attenuated)
    assert r_zero > 3 * r_int  # a spike at the frozen vertex
    assert r_att < 0.5 * r_zero  # attenuation stays in the span of D: no tear
    assert np.argmax(metrics.laplacian_magnitude(model, zeroed)) == v
    assert metrics.edge_strain(model, zeroed).max() > metrics.edge_strain(model, intended).max()


def test_orthogonal_lock_projects_free_columns(model):
    Do = orthogonal_lock(model.D, [0, 2])
    np.testing.assert_array_equal(Do[:, [0, 2]], model.D[:, [0, 2]])
    np.testing.assert_allclose(model.D[:, [0, 2]].T @ Do[:, [1, 3, 4, 5]], 0, atol=1e-10)
    # projecting twice changes nothing
    np.testing.assert_allclose(orthogonal_lock(Do, [0, 2]), Do, atol=1e-12)


def test_orthogonal_locking_underconstrains_vertices(model):
    """Section 3: whole-face orthogonality 'does not sufficiently constrain the movement of particular vertices'."""
    w_base = model.weights(s0=0.6)
    w_target = w_base + np.r_[0.0, np.full(model.n_shapes - 1, 0.7)]
    d = edit_orthogonal(model.D, w_base, w_target, [0])
    # the change is orthogonal to the locked shape as a whole-face vector ...
    assert abs(model.D[:, 0] @ (d - model.D @ w_base)) < 1e-9
    # ... yet the vertex the locked shape moved most still moves
    v = int(np.argmax(np.linalg.norm(model.D[:, 0].reshape(-1, 3), axis=1)))
    moved = np.linalg.norm((d - model.D @ w_base).reshape(-1, 3)[v])
    assert moved > 0.05 * np.linalg.norm(model.D[:, 0].reshape(-1, 3)[v]) * 0.6


def test_alternatives_bad_input(model):
    with pytest.raises(AttenuationError, match="locked"):
        orthogonal_lock(model.D, [])
    with pytest.raises(AttenuationError, match="every shape"):
        orthogonal_lock(model.D, np.arange(model.n_shapes))
    with pytest.raises(AttenuationError, match="distinct"):
        orthogonal_lock(model.D, [1, 1])
    with pytest.raises(SelectionError):
        zero_rows(model.D, [])
