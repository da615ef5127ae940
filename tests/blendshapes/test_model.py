"""BlendshapeModel: the delta form, the whole-face form (Section 3), validation."""

import numpy as np
import pytest

from repro.blendshapes import BlendshapeModel
from repro.errors import ModelError, ReproError
from tests.helpers import grid_model


@pytest.fixture(scope="module")
def model():
    return grid_model()


def test_pose_is_f0_plus_Dw_with_xyz_packing(model):
    w = np.linspace(-0.5, 1.0, model.n_shapes)
    f = model.pose(w)
    assert f.shape == (model.n_vertices, 3)
    # row 3*v + axis of D is coordinate axis of vertex v
    v, axis = 17, 2
    assert f[v, axis] == pytest.approx(model.f0[v, axis] + model.D[3 * v + axis] @ w)


def test_whole_face_round_trip(model):
    """Section 3: b1 = f0, b_k = f0 + d_{k-1}; weights (1 - sum w, w1, w2, ...)."""
    rng = np.random.default_rng(1)
    B = model.to_whole_face()
    assert B.shape == (3 * model.n_vertices, model.n_shapes + 1)
    np.testing.assert_array_equal(B[:, 0], model.f0.ravel())
    for _ in range(5):
        w = rng.normal(size=model.n_shapes)
        c = model.whole_face_weights(w)
        assert c.sum() == pytest.approx(1.0)
        assert c[0] == pytest.approx(1 - w.sum())
        np.testing.assert_allclose(B @ c, model.pose(w).ravel(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(model.delta_weights(c), w, rtol=0, atol=1e-15)
    back = BlendshapeModel.from_whole_face(B, model.faces, model.names)
    np.testing.assert_allclose(back.D, model.D, atol=1e-12)
    np.testing.assert_array_equal(back.f0, model.f0)


def test_whole_face_to_delta_any_neutral_column():
    rng = np.random.default_rng(2)
    B = rng.normal(size=(30, 4))
    m = BlendshapeModel.from_whole_face(B, np.zeros((0, 3), int), ["a", "b", "c"], neutral=2)
    c = np.array([0.2, 0.3, 0.1, 0.4])  # sums to 1, neutral is column 2
    w = np.delete(c, 2)
    np.testing.assert_allclose(m.pose(w).ravel(), B @ c, atol=1e-12)


def test_whole_face_weights_must_sum_to_one():
    with pytest.raises(ModelError, match="sum to 1"):
        BlendshapeModel.delta_weights([0.5, 0.2])


def test_weights_by_name_and_named_combinations(model):
    w = model.weights({"s2": 0.3}, pair=2.0)
    assert w[2] == pytest.approx(0.3) and w[0] == pytest.approx(2.0) and w[1] == pytest.approx(1.0)
    np.testing.assert_array_equal(model.pose({"s2": 0.3}), model.pose(model.weights(s2=0.3)))
    with pytest.raises(ModelError, match="unknown slider 'nope'"):
        model.weights(nope=1)
    with pytest.raises(ModelError, match="non-finite"):
        model.weights(s1=float("nan"))


def test_arrays_are_read_only(model):
    with pytest.raises(ValueError):
        model.D[0, 0] = 1.0


def test_laplacian_annihilates_constants_and_restrict_reindexes(model):
    L = model.laplacian
    np.testing.assert_allclose(L @ np.ones(model.n_vertices), 0, atol=1e-12)
    sub = model.restrict(np.arange(24))
    assert sub.n_vertices == 24 and sub.faces.max() < 24
    np.testing.assert_array_equal(sub.D, model.D[: 3 * 24])
    assert set(sub.regions) == {"corner"}


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(f0=np.zeros((4, 2))), "f0 must have shape"),
        (dict(D=np.zeros((11, 2))), "D must have shape"),
        (dict(names=["a"]), "1 shape names for 2 columns"),
        (dict(names=["a", "a"]), "unique"),
        (dict(f0=np.full((4, 3), np.nan)), "NaN"),
        (dict(D=np.full((12, 2), np.inf)), "NaN/inf"),
        (dict(faces=np.array([[0, 1, 9]])), "outside 0..3"),
        (dict(faces=np.array([[0.0, 1.0, 2.0]])), "integer"),
        (dict(sliders={"x": {"zz": 1}}), "unknown shapes"),
        (dict(regions={"r": [7]}), "region 'r'"),
    ],
)
def test_bad_models_raise_model_error(kwargs, message):
    base = dict(f0=np.zeros((4, 3)), D=np.zeros((12, 2)), names=["a", "b"], faces=np.array([[0, 1, 2]]))
    base.update(kwargs)
    with pytest.raises(ModelError, match=message) as info:
        BlendshapeModel(**base)
    assert isinstance(info.value, ReproError) and isinstance(info.value, ValueError)


def test_bad_weights(model):
    with pytest.raises(ModelError, match="shape"):
        model.pose(np.zeros(model.n_shapes + 1))
    with pytest.raises(ModelError, match="NaN"):
        model.pose(np.full(model.n_shapes, np.nan))
