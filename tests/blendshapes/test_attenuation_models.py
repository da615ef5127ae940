"""Eq. (3) on the real and the embedded face: the cached Attenuator equals the direct formula."""

import numpy as np
import pytest

from repro.blendshapes import Attenuator, attenuate, load_model, select_vertices


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
