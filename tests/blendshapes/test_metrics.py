"""The metrics that compare attenuation with the rejected alternatives (selected motion, fidelity, roughness, strain)."""

import numpy as np
import pytest

from repro.blendshapes import BlendshapeModel, edit_zeroed, metrics, select_vertices
from repro.errors import ModelError
from tests.helpers import grid_model


@pytest.fixture(scope="module")
def model():
    return grid_model(nx=16, ny=14, m=6, seed=3)


def test_metrics_values(model):
    sel = select_vertices([0, 1])
    d_int = model.D @ np.full(model.n_shapes, 0.5)
    assert metrics.unselected_fidelity(d_int, d_int, sel) == pytest.approx(1.0)
    assert metrics.unselected_fidelity(np.zeros_like(d_int), d_int, sel) == pytest.approx(0.0)
    assert metrics.unselected_fidelity(0.5 * d_int, d_int, sel) == pytest.approx(0.5)
    assert metrics.unselected_error(d_int, d_int, sel) == 0.0
    assert metrics.selected_motion(d_int, sel) == pytest.approx(np.linalg.norm(d_int[sel]))
    pv = metrics.per_vertex_motion(d_int.reshape(-1, 3))
    assert pv.shape == (model.n_vertices,) and pv[0] == pytest.approx(np.linalg.norm(d_int[:3]))
    assert np.isnan(metrics.unselected_fidelity(d_int, np.zeros_like(d_int), sel))


def test_metrics_bad_input(model):
    sel = select_vertices([0])
    with pytest.raises(ModelError, match="3n"):
        metrics.selected_motion(np.zeros(7), sel)
    with pytest.raises(ModelError, match="NaN"):
        metrics.selected_motion(np.full(9, np.nan), sel)
    with pytest.raises(ModelError, match="coordinates"):
        metrics.unselected_error(np.zeros(9), np.zeros(12), sel)
    with pytest.raises(ModelError, match="vertices"):
        metrics.roughness(model, np.zeros(9))
    no_faces = BlendshapeModel(f0=np.zeros((3, 3)), D=np.zeros((9, 1)), names=["a"], faces=np.zeros((0, 3), int))
    with pytest.raises(ModelError, match="no faces"):
        metrics.roughness(no_faces, np.zeros(9))


def test_roughness_near_looks_only_at_the_selection_and_its_ring(model):
    v = 5 * 16 + 7
    sel = select_vertices([v])
    zeroed = edit_zeroed(model.D, np.zeros(model.n_shapes), np.full(model.n_shapes, 0.7), sel)
    near = metrics.roughness_near(model, zeroed, [v])
    assert near == pytest.approx(metrics.roughness(model, zeroed))  # the spike is at the frozen vertex
    far = metrics.roughness_near(model, zeroed, [0])  # a corner, far from it
    assert far < 0.5 * near
    with pytest.raises(ModelError, match="ids"):
        metrics.roughness_near(model, zeroed, [10_000])


def test_intended_displacement_is_required(model):
    """``d_intended=None`` was taken as zero motion: a NaN fidelity instead of an error (issue 23)."""
    d = np.ones(3 * model.n_vertices)
    with pytest.raises(ModelError, match="intended displacement is required"):
        metrics.unselected_fidelity(d, None, [0, 1])
    with pytest.raises(ModelError, match="intended displacement is required"):
        metrics.unselected_error(d, None, [0, 1])


def test_edge_strain_overflow_is_an_error():
    """A displacement with one 1e308 coordinate: strain = ~1e308 / edge length (< 1) overflowed (RuntimeWarning, inf)."""
    from repro.blendshapes.faces.procedural import procedural_model

    model = procedural_model()
    d = np.zeros(3 * model.n_vertices)
    d[3 * model.n_vertices // 2] = 1e308
    with pytest.raises(ModelError, match="edge strain overflows"):
        metrics.edge_strain(model, d)
    assert np.isfinite(metrics.edge_strain(model, d * 1e-300)).all()
