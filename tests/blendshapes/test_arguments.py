"""The blendshape API refuses bad arguments with its own errors and does not depend on the scale of D (issue 9).

Two systematic tests:

- a table of (callable, bad argument) cases -- strings, None, objects, complex
  arrays, booleans, NaN/inf, wrong shapes, negative/huge/non-integer integers --
  each of which must raise a :class:`~repro.errors.ReproError` (never a bare
  ``ValueError``/``TypeError``/``KeyError``/``IndexError``/``OverflowError``/
  ``LinAlgError``, never a warning, never a silently dropped imaginary part);
- Eq. (3) at every scale of ``D`` from 1e-200 to 1e200 gives the same ``w2``.
"""

import math
import warnings

import numpy as np
import pytest
import scipy.linalg

from repro.blendshapes import (
    Attenuator,
    BlendshapeModel,
    attenuate,
    check_selection,
    default_alpha,
    edit_orthogonal,
    edit_zeroed,
    load_model,
    metrics,
    orthogonal_lock,
    scenarios,
    select_axis,
    select_pairs,
    select_vertices,
    zero_rows,
)
from repro.blendshapes import attenuation as attenuation_module
from repro.blendshapes.faces.procedural import procedural_model
from repro.errors import AttenuationError, ModelError, ReproError, SelectionError
from tests.helpers import grid_model

MODEL = grid_model(nx=8, ny=6, m=4, seed=1)  # 48 vertices, 4 shapes "s0".."s3", slider "pair"
N, M = MODEL.n_vertices, MODEL.n_shapes
D = MODEL.D
W = np.array([0.3, -0.2, 0.5, 0.1])
SEL = select_vertices([3, 20])
F0, FACES = MODEL.f0, MODEL.faces
ATT = Attenuator(MODEL)
ATT_D = Attenuator(D)


def model_with(**kw):
    base = dict(f0=F0, D=D, names=MODEL.names, faces=FACES)
    base.update(kw)
    return BlendshapeModel(**base)


class Weird:
    """An arbitrary object."""


CPLX = lambda a: np.asarray(a, dtype=complex) + 1j  # noqa: E731 - same shape, imaginary part 1
RAGGED = [[1.0, 2.0, 3.0], [1.0, 2.0]]

# Bad values for an argument that is a float array of a given valid value.
def bad_real_arrays(good):
    good = np.asarray(good, dtype=float)
    wrong_shape = np.zeros(good.shape[:-1] + (good.shape[-1] + 1,)) if good.ndim else np.zeros(2)
    nan, inf = good.copy(), good.copy()
    nan.flat[0], inf.flat[-1] = np.nan, -np.inf
    return {
        "str": "abc",
        "numeric str": "1.5",
        "None": None,
        "object": Weird(),
        "object array": np.array([Weird()] * max(good.size, 1), dtype=object),
        "complex": CPLX(good),
        "complex zero imag": good.astype(complex),  # still refused: a complex array is not real
        "bool": np.zeros(good.shape, dtype=bool),
        "strings": np.full(good.shape, "x"),
        "ragged": RAGGED,
        "dict": {"a": 1},
        "nan": nan,
        "inf": inf,
        "huge longdouble": np.full(good.shape, np.longdouble("1e4000")) if np.finfo(np.longdouble).max > 1e400 else inf,
        "wrong shape": wrong_shape,
        "scalar": 1.0,
    }


# Bad values for an argument that is an integer index array.
BAD_INDEX_ARRAYS = {
    "str": "abc",
    "None": None,
    "object": Weird(),
    "floats": [1.5, 2.0],
    "integral floats": np.array([1.0, 2.0]),
    "complex": np.array([1 + 0j, 2 + 1j]),
    "bools": [True, False, True],
    "strings": ["1", "2"],
    "ragged": [[1, 2], [3]],
    "negative": [-1, 2],
    "huge": [2**62],
    "uint64 beyond int64": np.array([2**63 + 5], dtype=np.uint64),
    "python int beyond int64": [10**30],
    "2-D": [[1, 2], [3, 4]],
}

# Bad values for an argument that is one integer.
BAD_INTS = {
    "str": "3",
    "None": None,
    "object": Weird(),
    "float": 3.0,
    "numpy float": np.float64(2.0),
    "nan": float("nan"),
    "bool": True,
    "numpy bool": np.bool_(False),
    "complex": 1j,
    "negative": -1,
    "huge": 10**30,
    "list": [3],
}

# Bad values for one real number (alpha, slider values, slider coefficients).
BAD_REALS = {
    "str": "abc",
    "numeric str": "5",
    "None": None,
    "object": Weird(),
    "complex": 1 + 2j,
    "numpy complex": np.complex128(1.0),
    "nan": float("nan"),
    "inf": float("inf"),
    "-inf": -np.inf,
    "bool": True,
    "list": [1.0],
    "huge int": 10**400,
}


def case(cases, label, fn):
    cases.append(pytest.param(fn, id=label))


CASES: list = []

# --------------------------------------------------------------- the model
for k, v in bad_real_arrays(F0).items():
    case(CASES, f"model-f0-{k}", lambda v=v: model_with(f0=v))
for k, v in bad_real_arrays(D).items():
    case(CASES, f"model-D-{k}", lambda v=v: model_with(D=v))
for k, v in {"None": None, "str": "abcd", "ints": [0, 1, 2, 3], "objects": [Weird()] * 4,
             "object": Weird(), "too few": ["a"], "repeated": ["a", "a", "b", "c"]}.items():
    case(CASES, f"model-names-{k}", lambda v=v: model_with(names=v))
for k, v in {**BAD_INDEX_ARRAYS, "wrong width": [[0, 1]], "out of range": [[0, 1, N]],
             "(F,3) floats": FACES.astype(float)}.items():
    if k == "2-D":
        continue  # (2, 2) is reported as a wrong width by "wrong width"
    case(CASES, f"model-faces-{k}", lambda v=v: model_with(faces=v))
for k, v in {"None": None, "int": 3, "bytes": b"x", "object": Weird()}.items():
    case(CASES, f"model-name-{k}", lambda v=v: model_with(name=v))
    case(CASES, f"model-units-{k}", lambda v=v: model_with(units=v))
for k, v in BAD_REALS.items():
    case(CASES, f"model-slider-coef-{k}", lambda v=v: model_with(sliders={"S": {"s0": v}}))
for k, v in {"None": None, "str": "abc", "list": [("S", {"s0": 1.0})], "object": Weird()}.items():
    case(CASES, f"model-sliders-{k}", lambda v=v: model_with(sliders=v))
    case(CASES, f"model-slider-combo-{k}", lambda v=v: model_with(sliders={"S": v}))
    case(CASES, f"model-regions-{k}", lambda v=v: model_with(regions=v))
case(CASES, "model-slider-unknown-shape", lambda: model_with(sliders={"S": {"nope": 1.0}}))
case(CASES, "model-slider-nonstr-shape", lambda: model_with(sliders={"S": {0: 1.0}}))
case(CASES, "model-slider-nonstr-name", lambda: model_with(sliders={1: {"s0": 1.0}}))
case(CASES, "model-slider-shape-name", lambda: model_with(sliders={"s0": {"s1": 1.0}}))
case(CASES, "model-region-nonstr-name", lambda: model_with(regions={1: [0, 1]}))
for k, v in {**BAD_INDEX_ARRAYS, "empty": [], "out of range": [N]}.items():
    case(CASES, f"model-region-{k}", lambda v=v: model_with(regions={"r": v}))

# ----------------------------------------------------------- model methods
for k, v in {**bad_real_arrays(W), "mapping of bad": {"s0": "x"}}.items():
    case(CASES, f"pose-{k}", lambda v=v: MODEL.pose(v))
    case(CASES, f"displacement-{k}", lambda v=v: MODEL.displacement(v))
    case(CASES, f"check_weights-{k}", lambda v=v: MODEL.check_weights(v))
for k, v in BAD_REALS.items():
    case(CASES, f"weights-shape-value-{k}", lambda v=v: MODEL.weights(s0=v))
    case(CASES, f"weights-slider-value-{k}", lambda v=v: MODEL.weights({"pair": v}))
for k, v in {"str": "abc", "list": [("s0", 1.0)], "object": Weird(), "int": 3}.items():
    case(CASES, f"weights-values-{k}", lambda v=v: MODEL.weights(v))
case(CASES, "weights-nonstr-key", lambda: MODEL.weights({0: 1.0}))
case(CASES, "weights-unknown", lambda: MODEL.weights(nope=1.0))
case(CASES, "weights-overflow", lambda: MODEL.weights(s0=1e308, pair=1e308))
BIG = model_with(D=D * 1e10)  # |D w| ~ 1e310 for w ~ 1e300
W_BIG = np.where(D[np.argmax(np.abs(D).sum(1))] >= 0, 1e300, -1e300)  # all terms of one row add up
case(CASES, "pose-overflow", lambda: BIG.pose(W_BIG))
case(CASES, "displacement-overflow", lambda: BIG.displacement(W_BIG))
for k, v in bad_real_arrays(W).items():
    if k in ("wrong shape", "scalar"):
        continue  # any vector length is a valid delta pose
    case(CASES, f"whole_face_weights-{k}", lambda v=v: BlendshapeModel.whole_face_weights(v))
for k, v in bad_real_arrays([0.5, 0.25, 0.25]).items():
    if k in ("wrong shape",):
        continue
    case(CASES, f"delta_weights-{k}", lambda v=v: BlendshapeModel.delta_weights(v))
B = MODEL.to_whole_face()
for k, v in bad_real_arrays(B).items():
    if k == "wrong shape":
        v = B[:-1]  # 3n - 1 rows
    case(CASES, f"from_whole_face-B-{k}", lambda v=v: BlendshapeModel.from_whole_face(v, FACES, MODEL.names))
for k, v in {**BAD_INTS, "1.5": 1.5, "too large": M + 1}.items():
    case(CASES, f"from_whole_face-neutral-{k}",
         lambda v=v: BlendshapeModel.from_whole_face(B, FACES, MODEL.names, neutral=v))
case(CASES, "from_whole_face-overflow",
     lambda: BlendshapeModel.from_whole_face(np.column_stack([-np.full(3 * N, 1.7e308), np.full(3 * N, 1.7e308)]),
                                             FACES, ["a"]))
for k, v in {**BAD_INDEX_ARRAYS, "empty": []}.items():
    case(CASES, f"restrict-{k}", lambda v=v: MODEL.restrict(v))
case(CASES, "restrict-name", lambda: MODEL.restrict([0, 1, 2], name=3))

# ------------------------------------------------------------- selections
for k, v in {**BAD_INDEX_ARRAYS, "empty": [], "repeated": [1, 1], "out of range": [N]}.items():
    case(CASES, f"select_vertices-{k}", lambda v=v: select_vertices(v, n_vertices=N))
    case(CASES, f"check_selection-{k}", lambda v=v, k=k: check_selection(v if k != "out of range" else [3 * N], 3 * N))
for k, v in {"None": None, "object": Weird(), "bad letter": "w", "int 3": [3], "bool": [True], "empty": "",
             "repeated": "xx", "int": 1, "float": [1.0]}.items():
    case(CASES, f"select_vertices-axes-{k}", lambda v=v: select_vertices([1], axes=v))
    if k not in ("int", "repeated"):  # select_axis takes one axis: 1 is "y"; "xx" is not an axis either
        case(CASES, f"select_axis-axis-{k}", lambda v=v: select_axis(v, N))
for k, v in {**BAD_INTS, "zero": 0}.items():
    if k == "list":
        continue
    if v is not None:  # None: no upper bound known
        case(CASES, f"select_vertices-n_vertices-{k}", lambda v=v: select_vertices([1], n_vertices=v))
        case(CASES, f"select_pairs-n_vertices-{k}", lambda v=v: select_pairs([(1, "x")], n_vertices=v))
    case(CASES, f"select_axis-n_vertices-{k}", lambda v=v: select_axis("x", v))
    if k != "huge":  # a huge row count is a valid (if unusual) size for pure index checks
        case(CASES, f"check_selection-n_rows-{k}", lambda v=v: check_selection([0], v))
        case(CASES, f"default_alpha-n_rows-{k}", lambda v=v: default_alpha(3, v))
    case(CASES, f"default_alpha-n_selected-{k}", lambda v=v: default_alpha(v, 30))
for k, v in {"None": None, "str": "ab", "int": 3, "object": Weird(), "bad pair": [(1,)],
             "bool vertex": [(True, "x")], "float vertex": [(1.0, "x")], "str vertex": [("1", "x")],
             "huge vertex": [(10**30, "x")], "bad axis": [(1, "q")], "empty": [], "repeated": [(1, "x"), (1, "x")]}.items():
    case(CASES, f"select_pairs-{k}", lambda v=v: select_pairs(v))
case(CASES, "check_selection-every-row", lambda: check_selection(np.arange(3 * N), 3 * N))

# ------------------------------------------------------------- attenuation
for k, v in bad_real_arrays(D).items():
    if k == "wrong shape":
        v = D[:-1]  # not 3n rows
    case(CASES, f"attenuate-D-{k}", lambda v=v: attenuate(v, W, SEL))
    case(CASES, f"Attenuator-D-{k}", lambda v=v: Attenuator(v))
    case(CASES, f"zero_rows-D-{k}", lambda v=v: zero_rows(v, SEL))
    case(CASES, f"orthogonal_lock-D-{k}", lambda v=v: orthogonal_lock(v, [0]))
for k, v in bad_real_arrays(W).items():
    case(CASES, f"attenuate-w1-{k}", lambda v=v: attenuate(D, v, SEL))
    case(CASES, f"Attenuator.attenuate-w1-{k}", lambda v=v: ATT.attenuate(v, SEL))
    case(CASES, f"Attenuator.edit-w_base-{k}", lambda v=v: ATT.edit(v, W, SEL))
    case(CASES, f"Attenuator.edit-w_target-{k}", lambda v=v: ATT.edit(W, v, SEL))
    case(CASES, f"Attenuator.displacement-{k}", lambda v=v: ATT.displacement(v))
    case(CASES, f"Attenuator.pose-{k}", lambda v=v: ATT.pose(v))
    case(CASES, f"edit_zeroed-w_target-{k}", lambda v=v: edit_zeroed(D, W, v, SEL))
    case(CASES, f"edit_orthogonal-w_base-{k}", lambda v=v: edit_orthogonal(D, v, W, [0]))
for k, v in {**BAD_INDEX_ARRAYS, "empty": [], "mask": np.zeros(3 * N, bool), "every row": np.arange(3 * N)}.items():
    case(CASES, f"attenuate-selected-{k}", lambda v=v: attenuate(D, W, v))
    case(CASES, f"Attenuator.matrix-selected-{k}", lambda v=v: ATT_D.matrix(v))
    case(CASES, f"zero_rows-selected-{k}", lambda v=v: zero_rows(D, v))
    case(CASES, f"metrics.selected_motion-selected-{k}", lambda v=v: metrics.selected_motion(D @ W, v))
for k, v in {**BAD_REALS, "zero": 0.0, "negative": -1.0, "0-d complex": np.array(1j)}.items():
    if v is None:
        continue  # None is the default alpha
    case(CASES, f"attenuate-alpha-{k}", lambda v=v: attenuate(D, W, SEL, v))
    case(CASES, f"Attenuator.attenuate-alpha-{k}", lambda v=v: ATT.attenuate(W, SEL, v))
    case(CASES, f"scenarios.evaluate-alpha-{k}", lambda v=v: scenarios.evaluate(FACE, "furrow_then_mouth", v))
for k, v in {**BAD_INTS, "too large": 10**6}.items():
    if k == "huge":
        continue  # covered by "too large"
    case(CASES, f"Attenuator-cache_size-{k}", lambda v=v: Attenuator(D, cache_size=v))
case(CASES, "Attenuator-cache_size-huge", lambda: Attenuator(D, cache_size=10**30))
case(CASES, "Attenuator.pose-without-model", lambda: ATT_D.pose(W))
case(CASES, "Attenuator.edit-overflowing-change", lambda: ATT.edit(np.full(M, -1e308), np.full(M, 1e308), SEL))
case(CASES, "Attenuator.displacement-overflow", lambda: Attenuator(BIG).displacement(W_BIG))
case(CASES, "Attenuator.pose-overflow", lambda: Attenuator(BIG).pose(W_BIG))
case(CASES, "attenuate-alpha-overflows-P-plus-alpha-Q", lambda: attenuate(D * 1e10, W, SEL, 1e300))
for k, v in {**BAD_INDEX_ARRAYS, "empty": [], "all": np.arange(M), "repeated": [0, 0], "too large": [M]}.items():
    case(CASES, f"orthogonal_lock-locked-{k}", lambda v=v: orthogonal_lock(D, v))
    case(CASES, f"edit_orthogonal-locked-{k}", lambda v=v: edit_orthogonal(D, W, W, v))

# ----------------------------------------------------------------- metrics
for k, v in bad_real_arrays(D @ W).items():
    if k == "scalar":
        v = np.zeros(3 * N + 1)
    case(CASES, f"metrics.per_vertex_motion-{k}", lambda v=v: metrics.per_vertex_motion(v))
    if v is not None:  # d_ref=None is the neutral face
        case(CASES, f"metrics.selected_motion-d_ref-{k}", lambda v=v: metrics.selected_motion(D @ W, SEL, v))
    case(CASES, f"metrics.unselected_fidelity-{k}", lambda v=v: metrics.unselected_fidelity(v, D @ W, SEL))
    case(CASES, f"metrics.roughness-{k}", lambda v=v: metrics.roughness(MODEL, v))
    case(CASES, f"metrics.edge_strain-{k}", lambda v=v: metrics.edge_strain(MODEL, v))
for k, v in {**BAD_INDEX_ARRAYS, "empty": []}.items():
    if k == "2-D":
        continue  # vertex ids are a set: any shape is flattened
    case(CASES, f"metrics.roughness_near-vertices-{k}", lambda v=v: metrics.roughness_near(MODEL, D @ W, v))
for k, v in {"None": None, "D": D, "str": "grid"}.items():
    case(CASES, f"metrics.roughness-model-{k}", lambda v=v: metrics.roughness(v, D @ W))
case(CASES, "metrics.per_vertex_motion-overflow", lambda: metrics.per_vertex_motion(np.full(3 * N, 1.7e308),
                                                                                   np.full(3 * N, -1.7e308)))
case(CASES, "metrics.selected_motion-norm-overflow", lambda: metrics.selected_motion(np.full(3 * N, 1.7e308), SEL))

# --------------------------------------------------------------- scenarios
FACE = procedural_model()
for k, v in {"None": None, "list": [], "int": 3, "object": Weird(), "unknown": "nope"}.items():
    case(CASES, f"scenarios.scenario-{k}", lambda v=v: scenarios.scenario(v))
    case(CASES, f"scenarios.evaluate-sc-{k}", lambda v=v: scenarios.evaluate(FACE, v))
    case(CASES, f"scenarios.interference-sc-{k}", lambda v=v: scenarios.interference(FACE, v))
for k, v in {"None": None, "D": FACE.D, "str": "procedural"}.items():
    case(CASES, f"scenarios.evaluate-model-{k}", lambda v=v: scenarios.evaluate(v, "furrow_then_mouth"))
    case(CASES, f"scenarios.interference-model-{k}", lambda v=v: scenarios.interference(v, "furrow_then_mouth"))
for k, v in {"None": None, "str": "abc", "int": 3, "bad item": [1.0, "x"], "zero": [0.0]}.items():
    case(CASES, f"scenarios.alpha_sweep-alphas-{k}", lambda v=v: scenarios.alpha_sweep(FACE, "furrow_then_mouth", v))
case(CASES, "scenarios.evaluate-attenuator-object", lambda: scenarios.evaluate(FACE, "furrow_then_mouth", attenuator=3))
for k, v in {"top_moved str": dict(top_moved="2"), "top_moved -1": dict(top_moved=-1), "top_moved 1.5": dict(top_moved=1.5),
             "moves list": dict(moves=[("JawOpen", 1.0)]), "region None": dict(region=None), "axes int": dict(axes=1)}.items():
    kw = dict(key="k", figure="f", description="d", region="brow_middle", moves={"JawOpen": 0.5})
    kw.update(v)
    case(CASES, f"scenarios.Scenario-{k}", lambda kw=kw: scenarios.Scenario(**kw))

# -------------------------------------------------------------- procedural
for k, v in {**BAD_INTS, "too small": 10, "too large": 10**7}.items():
    case(CASES, f"procedural_model-n_vertices-{k}", lambda v=v: procedural_model(v))
for k, v in {"None": None, "list": ["procedural"], "unknown": "nope"}.items():
    case(CASES, f"load_model-name-{k}", lambda v=v: load_model(v))
case(CASES, "load_model-unknown-keyword", lambda: load_model("procedural", n_vertex=600))


@pytest.mark.parametrize("call", CASES)
def test_bad_input_raises_a_repro_error(call):
    """Every bad argument gives a ReproError with a message, and no warning on the way."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. numpy's ComplexWarning, overflow RuntimeWarnings
        with pytest.raises(ReproError) as info:
            call()
    assert isinstance(info.value, (ModelError, SelectionError, AttenuationError)), type(info.value)
    assert str(info.value), "the error must say what is wrong"


def test_the_table_is_systematic():
    assert len(CASES) > 600


# ---------------------------------------------------------- named defects
def test_nan_slider_coefficient_is_refused():
    """Before: accepted, and weights(S=1) was NaN."""
    with pytest.raises(ModelError, match="coefficient of 's0' in slider 'S'"):
        model_with(sliders={"S": {"s0": float("nan")}})


def test_complex_parts_are_not_dropped():
    with pytest.raises(ModelError, match="complex"):
        MODEL.pose(W + 0.5j)
    with pytest.raises(AttenuationError, match="complex"):
        attenuate(D.astype(complex), W, SEL)


def test_cache_size_and_neutral_are_checked():
    with pytest.raises(AttenuationError, match="cache_size must be an integer in 0.."):
        Attenuator(D, cache_size=-1)
    with pytest.raises(ModelError, match="neutral"):
        BlendshapeModel.from_whole_face(B, FACES, MODEL.names, neutral=1.5)
    att = Attenuator(D, cache_size=0)  # 0 keeps nothing, and still works
    np.testing.assert_allclose(att.attenuate(W, SEL, 2.0), attenuate(D, W, SEL, 2.0), rtol=1e-12)
    assert len(att._M) == 0


def test_integer_likes_are_accepted():
    """numpy integers and 0-d integer arrays are integers; numpy floats are real numbers."""
    assert Attenuator(D, cache_size=np.int32(3))._cache_size == 3
    m = BlendshapeModel.from_whole_face(B, FACES.astype(np.int32), list(MODEL.names), neutral=np.int64(0))
    np.testing.assert_allclose(m.D, D, atol=1e-12)
    np.testing.assert_array_equal(select_vertices(np.array([3, 1], dtype=np.uint16), n_vertices=np.int64(N)),
                                  select_vertices([1, 3]))
    assert MODEL.weights(s0=np.float32(0.5))[0] == 0.5
    assert MODEL.weights(s0=np.array(2))[0] == 2.0
    assert attenuate(D, W.astype(np.float32), SEL, np.float32(2.0)).dtype == np.float64
    assert model_with(faces=[]).faces.shape == (0, 3)  # an empty face list is fine


def test_singular_system_raises_attenuation_error_not_linalg_error(monkeypatch):
    def broken(*a, **k):
        raise np.linalg.LinAlgError("SVD did not converge")

    Dd = np.column_stack([D, D[:, 0]])  # rank deficient: the pseudo-inverse path
    monkeypatch.setattr(scipy.linalg, "pinvh", broken)
    with pytest.raises(AttenuationError, match="singular"):
        attenuate(Dd, np.append(W, 0.1), SEL, 2.0)
    with pytest.raises(AttenuationError, match="singular"):
        Attenuator(Dd).attenuate(np.append(W, 0.1), SEL, 2.0)


# -------------------------------------------------------- scale invariance
SCALES = [1e-200, 1e-160, 1e-100, 1e-30, 1e-3, 1.0, 7.0, 1e30, 1e100, 1e155, 1e200]


def rel(a, b):
    return np.linalg.norm(np.asarray(a) - b) / np.linalg.norm(b)


@pytest.fixture(scope="module")
def reference():
    sel_small = SEL
    sel_large = select_vertices(np.arange(30))  # most rows selected: the Attenuator's Sbar path
    out = {"small": sel_small, "large": sel_large}
    for key, sel in (("small", sel_small), ("large", sel_large)):
        out[f"attenuate-{key}"] = attenuate(D, W, sel)
        out[f"Attenuator-{key}"] = Attenuator(D).attenuate(W, sel)
    return out


@pytest.mark.parametrize("scale", SCALES, ids=lambda s: f"{s:.0e}")
def test_eq3_does_not_depend_on_the_scale_of_D(scale, reference):
    """Before: 1e-160 gave NaN, 1e-200 a wrong answer and 1e155 numpy's LinAlgError."""
    Ds = D * scale
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for key in ("small", "large"):
            sel = reference[key]
            for alpha in (None, 1e-3, 3.0, 1e4):
                ref = attenuate(D, W, sel, alpha)
                assert rel(attenuate(Ds, W, sel, alpha), ref) < 1e-9
                assert rel(Attenuator(Ds).attenuate(W, sel, alpha), ref) < 1e-9
            assert rel(attenuate(Ds, W, sel), reference[f"attenuate-{key}"]) < 1e-9
            assert rel(Attenuator(Ds).edit(W, 2 * W, sel), reference[f"Attenuator-{key}"] + W) < 1e-9
        # the rejected alternatives: orthogonal locking projects, whatever the scale
        assert rel(orthogonal_lock(Ds, [0, 2]) / scale, orthogonal_lock(D, [0, 2])) < 1e-9
        assert rel(edit_orthogonal(Ds, W, 2 * W, [1]) / scale, edit_orthogonal(D, W, 2 * W, [1])) < 1e-9
        assert rel(edit_zeroed(Ds, W, 2 * W, SEL) / scale, edit_zeroed(D, W, 2 * W, SEL)) < 1e-12
        # the metrics of a scaled displacement scale with it (no overflow/underflow in the norms)
        d = D @ W
        assert math.isclose(metrics.selected_motion(d * scale, SEL) / scale, metrics.selected_motion(d, SEL), rel_tol=1e-12)
        assert math.isclose(metrics.unselected_fidelity(d * scale, 2 * d * scale, SEL),
                            metrics.unselected_fidelity(d, 2 * d, SEL), rel_tol=1e-9)
        np.testing.assert_allclose(metrics.per_vertex_motion(d * scale) / scale, metrics.per_vertex_motion(d), rtol=1e-12)


def test_scaled_model_attenuates_like_the_original():
    """A BlendshapeModel in tiny units (e.g. a face in light years) attenuates the same."""
    for scale in (1e-200, 1e200):
        m = model_with(f0=F0 * scale, D=D * scale)
        np.testing.assert_allclose(Attenuator(m).attenuate(W, SEL), ATT.attenuate(W, SEL), rtol=1e-9)
        assert Attenuator(m).scale_exponent != 0 and ATT.scale_exponent == 0


def test_widely_scaled_gram_is_accumulated_in_blocks(monkeypatch):
    """The scaled Gram matrix is built in row blocks (no full copy of D); blocks change nothing."""
    monkeypatch.setattr(attenuation_module, "_GRAM_BLOCK", 7)
    Ds = D * 1e200
    np.testing.assert_allclose(Attenuator(Ds).attenuate(W, SEL), ATT.attenuate(W, SEL), rtol=1e-9)


def test_zero_d_arrays_and_huge_ranges_are_refused():
    """Found by tests/fuzz/test_fuzz_arguments_blendshapes.py: a 0-d array is an ``Iterable`` by type
    that raises TypeError when iterated; ``range(10**12)`` made numpy allocate 8 TB (MemoryError)."""
    with pytest.raises(ModelError, match="names must be a sequence of strings"):
        BlendshapeModel(f0=MODEL.f0, D=MODEL.D, names=np.array(1.0), faces=MODEL.faces)
    with pytest.raises(SelectionError, match="axes must be"):
        select_vertices([1, 2], axes=np.array(1.0))
    with pytest.raises(SelectionError, match="pairs"):
        select_pairs(np.array(1.0))
    for call in (lambda: select_vertices(range(10**12)), lambda: attenuate(D, W, range(10**12)),
                 lambda: MODEL.restrict(range(10**30))):
        with pytest.raises(ReproError, match="MEMORY_BUDGET|budget"):
            call()
    assert select_vertices(range(2), n_vertices=N).tolist() == [0, 1, 2, 3, 4, 5]  # a small range is fine
