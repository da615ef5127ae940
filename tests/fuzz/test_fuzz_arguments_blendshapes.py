"""Hostile arguments to the public API of :mod:`repro.blendshapes` (issue 23, section 8).

The model and its methods, the procedural face, Eq. (3) (``attenuate``, ``Attenuator`` and its
methods, the selection helpers), the bounded solve (``solve_box_qp``, ``bounded_attenuate`` /
``bounded_edit`` / ``clamped_edit``, ``check_bounds``, and its benchmark ``bench_bounded``), direct manipulation, the
rejected alternatives, the metrics and the scenarios: every parameter gets every value of the
table of :mod:`tests.fuzz.arguments`; each call raises a ReproError or returns finite numbers.
(glTF reading and writing and the ICT loader have their own fuzzers: the file readers'.)
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from tests.fuzz.arguments import Case, check

pytestmark = pytest.mark.fuzz


@functools.cache
def _model():
    from repro.blendshapes.faces.procedural import procedural_model

    return procedural_model()


def _att():
    from repro.blendshapes import Attenuator

    return Attenuator(_model())


def _sel():
    from repro.blendshapes import select_vertices

    m = _model()
    return select_vertices(m.regions["brow_middle"], "xyz", m.n_vertices)


def _w(**kw):
    return _model().weights(kw)


def _W1():
    return _w(JawOpen=0.4, Furrow=0.4)


def _dm():
    from repro.blendshapes.manipulation import DirectManipulator

    return DirectManipulator(_model())


def _corner():
    return _model().regions["mouth_corners"][:1]


def _target():
    m = _model()
    return m.pose(m.weights(SmirkLeft=0.7))[_corner()]


def _d():
    return _model().displacement(_W1())


def _d_base():
    return _model().displacement(_w(Furrow=0.4))


def _small_spd():
    return np.array([[2.0, 0.5, 0.0], [0.5, 1.0, 0.0], [0.0, 0.0, 3.0]])


# ------------------------------------------------------------------ model and procedural face
def _ctor():
    from repro.blendshapes import BlendshapeModel

    m = _model()
    return BlendshapeModel, dict(f0=m.f0, D=m.D, names=m.names, faces=m.faces, name="p", units="cm",
                                 sliders=m.sliders, regions=m.regions)


def _from_whole():
    from repro.blendshapes import BlendshapeModel

    m = _model()
    return BlendshapeModel.from_whole_face, dict(B=m.to_whole_face(), faces=m.faces, names=m.names, neutral=0)


def _procedural():
    from repro.blendshapes.faces.procedural import procedural_model

    return procedural_model, dict(n_vertices=2016)


def _grid_shape():
    from repro.blendshapes.faces.procedural import procedural_grid_shape

    return procedural_grid_shape, dict(n_vertices=2016)


def _load_model():
    from repro.blendshapes import load_model

    return load_model, dict(name="procedural")


MODEL = [
    Case("BlendshapeModel", _ctor, {"f0": "array", "D": "array", "names": "any", "faces": "index_array",
                                    "name": "str", "units": "str", "sliders": "mapping", "regions": "mapping"}),
    Case("BlendshapeModel.from_whole_face", _from_whole,
         {"B": "array", "faces": "index_array", "names": "any", "neutral": "int"}),
    Case("procedural_model", _procedural, {"n_vertices": "int"}),
    Case("procedural_grid_shape", _grid_shape, {"n_vertices": "int"}),
    Case("load_model", _load_model, {"name": "choice"}),
    Case("model.shape_index", lambda: (_model().shape_index, dict(name="JawOpen")), {"name": "str"}),
    Case("model.weights", lambda: (_model().weights, dict(values={"Furrow": 0.4})), {"values": "mapping"}),
    Case("model.weights(**kw)", lambda: (lambda JawOpen, Furrow: _model().weights(JawOpen=JawOpen, Furrow=Furrow),
                                         dict(JawOpen=0.4, Furrow=0.2)), {"JawOpen": "real", "Furrow": "real"}),
    Case("model.check_weights", lambda: (_model().check_weights, dict(w=_W1())), {"w": "array"}),
    Case("model.displacement", lambda: (_model().displacement, dict(w=_W1())), {"w": "array"}),
    Case("model.pose", lambda: (_model().pose, dict(w=_W1())), {"w": "array"}),
    Case("BlendshapeModel.whole_face_weights",
         lambda: (type(_model()).whole_face_weights, dict(w=_W1())), {"w": "array"}),
    Case("BlendshapeModel.delta_weights",
         lambda: (type(_model()).delta_weights, dict(c=type(_model()).whole_face_weights(_W1()))), {"c": "array"}),
    Case("model.restrict", lambda: (_model().restrict, dict(vertices=np.arange(0, 2016, 2), name="half")),
         {"vertices": "index_array", "name": "str"}),
]


# ------------------------------------------------------------------ Eq. (3)
def _attenuate():
    from repro.blendshapes import attenuate

    return attenuate, dict(D=_model().D, w1=_W1(), selected=_sel(), alpha=10.0)


def _attenuator():
    from repro.blendshapes import Attenuator

    return Attenuator, dict(model_or_D=_model(), cache_size=4)


ATTENUATION = [
    Case("attenuate", _attenuate, {"D": "array", "w1": "array", "selected": "index_array", "alpha": "real"}),
    Case("Attenuator", _attenuator, {"model_or_D": "array", "cache_size": "int"}),
    Case("Attenuator(D)", lambda: (__import__("repro.blendshapes").blendshapes.Attenuator,
                                   dict(model_or_D=_model().D)), {"model_or_D": "array"}),
    Case("Attenuator.attenuate", lambda: (_att().attenuate, dict(w1=_W1(), selected=_sel(), alpha=None)),
         {"w1": "array", "selected": "index_array", "alpha": "real"}),
    Case("Attenuator()", lambda: (_att(), dict(w1=_W1(), selected=_sel())), {"w1": "array", "selected": "index_array"}),
    Case("Attenuator.edit", lambda: (_att().edit, dict(w_base=_w(Furrow=0.4), w_target=_W1(), selected=_sel(),
                                                       alpha=5.0)),
         {"w_base": "array", "w_target": "array", "selected": "index_array", "alpha": "real"}),
    Case("Attenuator.matrix", lambda: (_att().matrix, dict(selected=_sel(), alpha=5.0)),
         {"selected": "index_array", "alpha": "real"}),
    Case("Attenuator.system", lambda: (_att().system, dict(selected=_sel(), alpha=5.0)),
         {"selected": "index_array", "alpha": "real"}),
    Case("Attenuator.default_alpha", lambda: (_att().default_alpha, dict(selected=_sel())),
         {"selected": "index_array"}),
    Case("Attenuator.selection_gram", lambda: (_att().selection_gram, dict(selected=_sel())),
         {"selected": "index_array"}),
    Case("Attenuator.displacement", lambda: (_att().displacement, dict(w=_W1())), {"w": "array"}),
    Case("Attenuator.pose", lambda: (_att().pose, dict(w=_W1())), {"w": "array"}),
    Case("default_alpha", lambda: (__import__("repro.blendshapes").blendshapes.default_alpha,
                                   dict(n_selected=6, n_rows=6048)), {"n_selected": "int", "n_rows": "int"}),
    Case("check_selection", lambda: (__import__("repro.blendshapes").blendshapes.check_selection,
                                     dict(selected=[0, 4], n_rows=6048)),
         {"selected": "index_array", "n_rows": "int"}),
    Case("select_vertices", lambda: (__import__("repro.blendshapes").blendshapes.select_vertices,
                                     dict(vertices=[3, 7], axes="xy", n_vertices=2016)),
         {"vertices": "index_array", "axes": "choice", "n_vertices": "int"}),
    Case("select_pairs", lambda: (__import__("repro.blendshapes").blendshapes.select_pairs,
                                  dict(pairs=[(3, "y"), (7, 0)], n_vertices=2016)),
         {"pairs": "any", "n_vertices": "int"}),
    Case("select_axis", lambda: (__import__("repro.blendshapes").blendshapes.select_axis,
                                 dict(axis="y", n_vertices=2016)), {"axis": "choice", "n_vertices": "int"}),
]


# ------------------------------------------------------------------ bounded
def _box_qp():
    from repro.blendshapes.bounded import solve_box_qp

    return solve_box_qp, dict(A=_small_spd(), g=np.array([3.0, -1.0, 1.0]), lo=0.0, hi=1.0, x0=None,
                              max_iter=None, method="auto")


def _bounded(fn_name, **extra):
    def setup():
        from repro.blendshapes import bounded

        kw = dict(att=_att(), selected=_sel(), alpha=5.0, lo=0.0, hi=1.0, **extra)
        if fn_name == "bounded_attenuate":
            kw["w1"] = _W1()
        else:
            kw.update(w_base=_w(Furrow=0.4), w_target=_W1())
        return getattr(bounded, fn_name), kw

    return setup


def _check_bounds():
    from repro.blendshapes.bounded import check_bounds

    return check_bounds, dict(lo=0.0, hi=np.ones(3), m=3)


def _bench_bounded():
    from repro.bench.attenuation import bench_bounded

    return bench_bounded, dict(model=_model(), repeats=1)


_BOUNDED_PARAMS = {"att": "any", "selected": "index_array", "alpha": "real", "lo": "array", "hi": "array"}
BOUNDED = [
    Case("solve_box_qp", _box_qp, {"A": "array", "g": "array", "lo": "array", "hi": "array", "x0": "array",
                                   "max_iter": "int", "method": "choice"}),
    Case("bounded_attenuate", _bounded("bounded_attenuate", info=False),
         {**_BOUNDED_PARAMS, "w1": "array", "info": "bool"}),
    Case("bounded_edit", _bounded("bounded_edit", info=True),
         {**_BOUNDED_PARAMS, "w_base": "array", "w_target": "array", "info": "bool"}),
    Case("clamped_edit", _bounded("clamped_edit"), {**_BOUNDED_PARAMS, "w_base": "array", "w_target": "array"}),
    # -inf / inf bounds are documented (one-sided ranges) and come back as they are
    Case("check_bounds", _check_bounds, {"lo": "array", "hi": "array", "m": "int"}, nonfinite_ok=True),
    Case("bench_bounded", _bench_bounded, {"model": "any", "repeats": "int"}),
]


# ------------------------------------------------------------------ direct manipulation
def _dm_ctor():
    from repro.blendshapes.manipulation import DirectManipulator

    return DirectManipulator, dict(model_or_attenuator=_model(), cache_size=4)


def _dm_solve():
    m = _model()
    return _dm().solve, dict(w_current=m.weights(), dragged=_corner(), targets=_target(),
                             pinned=_sel(), mu=1e-3, alpha=100.0, lo=0.0, hi=1.0, info=True)


def _dm_cache():
    """A solve through a manipulator built with the fuzzed cache_size (the issue's KeyError)."""
    from repro.blendshapes.manipulation import DirectManipulator

    def solve(cache_size):
        m = _model()
        return DirectManipulator(m, cache_size=cache_size).solve(m.weights(), _corner(), _target())

    return solve, dict(cache_size=2)


MANIPULATION = [
    Case("DirectManipulator", _dm_ctor, {"model_or_attenuator": "any", "cache_size": "int"}),
    Case("DirectManipulator(cache_size).solve", _dm_cache, {"cache_size": "int"}),
    Case("DirectManipulator.prepare", lambda: (_dm().prepare, dict(dragged=_corner(), pinned=_sel(), mu=1e-3,
                                                                   alpha=100.0)),
         {"dragged": "index_array", "pinned": "index_array", "mu": "real", "alpha": "real"}),
    Case("DirectManipulator.solve", _dm_solve,
         {"w_current": "array", "dragged": "index_array", "targets": "array", "pinned": "index_array",
          "mu": "real", "alpha": "real", "lo": "array", "hi": "array", "info": "bool"}),
    Case("DirectManipulator.positions", lambda: (_dm().positions, dict(w=_W1(), vertices=[1, 2])),
         {"w": "array", "vertices": "index_array"}),
]


# ------------------------------------------------------------------ alternatives and metrics
def _alt(name, **kw):
    def setup():
        from repro.blendshapes import alternatives

        return getattr(alternatives, name), dict(D=_model().D, **kw)

    return setup


def _metric(name, **kw):
    def setup():
        from repro.blendshapes import metrics

        args = {k: (v() if callable(v) else v) for k, v in kw.items()}
        return getattr(metrics, name), args

    return setup


_D_ROWS = {"d": "array"}
ALTERNATIVES_METRICS = [
    Case("zero_rows", _alt("zero_rows", selected=[0, 5]), {"D": "array", "selected": "index_array"}),
    Case("edit_zeroed", lambda: _alt("edit_zeroed", w_base=_w(Furrow=0.4), w_target=_W1(), selected=_sel())(),
         {"D": "array", "w_base": "array", "w_target": "array", "selected": "index_array"}),
    Case("orthogonal_lock", _alt("orthogonal_lock", locked=[0, 3]), {"D": "array", "locked": "index_array"}),
    Case("edit_orthogonal", lambda: _alt("edit_orthogonal", w_base=_w(Furrow=0.4), w_target=_W1(),
                                         locked=[0, 3])(),
         {"D": "array", "w_base": "array", "w_target": "array", "locked": "index_array"}),
    Case("per_vertex_motion", _metric("per_vertex_motion", d=_d, d_ref=_d_base), {"d": "array", "d_ref": "array"}),
    Case("selected_motion", _metric("selected_motion", d=_d, selected=_sel, d_ref=_d_base),
         {"d": "array", "selected": "index_array", "d_ref": "array"}),
    Case("unselected_error", _metric("unselected_error", d=_d, d_intended=_d_base, selected=_sel),
         {"d": "array", "d_intended": "array", "selected": "index_array"}),
    # NaN is its documented answer when the sliders intend no motion of the unselected coordinates
    Case("unselected_fidelity", _metric("unselected_fidelity", d=_d, d_intended=_d_base, selected=_sel, d_ref=None),
         {"d": "array", "d_intended": "array", "selected": "index_array", "d_ref": "array"}, nonfinite_ok=True),
    Case("laplacian_magnitude", _metric("laplacian_magnitude", model=_model, d=_d), {"model": "any", "d": "array"}),
    Case("roughness", _metric("roughness", model=_model, d=_d), {"model": "any", "d": "array"}),
    Case("roughness_near", _metric("roughness_near", model=_model, d=_d, vertices=[3, 4]),
         {"model": "any", "d": "array", "vertices": "index_array"}),
    Case("edge_strain", _metric("edge_strain", model=_model, d=_d), {"model": "any", "d": "array"}),
]


# ------------------------------------------------------------------ scenarios
def _sc(name, **kw):
    def setup():
        from repro.blendshapes import scenarios

        return getattr(scenarios, name), dict(model=_model(), sc="furrow_then_mouth", **kw)

    return setup


def _scenario_ctor():
    from repro.blendshapes.scenarios import Scenario

    return Scenario, dict(key="k", figure="f", description="d", region="brow_middle", moves={"JawOpen": 0.4},
                          base={"Furrow": 0.4}, axes="xyz", top_moved=1)


def _scenario_method(name):
    def setup():
        from repro.blendshapes.scenarios import scenario

        return getattr(scenario("eyelid_then_brow"), name), dict(model=_model())

    return setup


_SC = {"model": "any", "sc": "choice"}
SCENARIOS = [
    Case("scenario", lambda: (__import__("repro.blendshapes.scenarios").blendshapes.scenarios.scenario,
                              dict(key="furrow_then_mouth")), {"key": "choice"}),
    Case("Scenario", _scenario_ctor, {"key": "str", "figure": "str", "description": "str", "region": "choice",
                                      "moves": "mapping", "base": "mapping", "axes": "choice", "top_moved": "int"}),
    Case("evaluate", _sc("evaluate", alpha=None, attenuator=None), {**_SC, "alpha": "real", "attenuator": "any"}),
    Case("compare_methods", _sc("compare_methods", alpha=20.0), {**_SC, "alpha": "real", "attenuator": "any"}),
    Case("alpha_sweep", _sc("alpha_sweep", alphas=[1.0, 100.0]), {**_SC, "alphas": "array", "attenuator": "any"}),
    # alpha is NaN in the rows without attenuation (a table's "not applicable")
    Case("axis_table", _sc("axis_table", alpha=None), {**_SC, "alpha": "real", "attenuator": "any"},
         nonfinite_ok={"alpha"}),
    Case("interference", _sc("interference"), _SC),
    *[Case(f"Scenario.{name}", _scenario_method(name), {"model": "any"})
      for name in ("vertices", "selection", "weights", "lockable_shapes")],
]

CASES = MODEL + ATTENUATION + BOUNDED + MANIPULATION + ALTERNATIVES_METRICS + SCENARIOS


def test_blendshapes_arguments(tmp_path):
    check(__name__, str(tmp_path))
