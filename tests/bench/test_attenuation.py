"""The bounded-solve benchmark (repro.bench.attenuation.bench_bounded): its arguments, and what it reports."""

import pytest

from repro.bench.attenuation import bench_bounded
from repro.blendshapes import load_model
from repro.errors import AttenuationError


def test_bench_bounded_arguments_are_checked():
    m = load_model("procedural")
    for repeats in (0, -1, 10**12, "x", None, 1.5):  # 0 gave NaN timings, 10**12 ran forever
        with pytest.raises(AttenuationError, match="repeats"):
            bench_bounded(m, repeats=repeats)
    with pytest.raises(AttenuationError, match="model must be a BlendshapeModel"):
        bench_bounded("procedural", repeats=1)
    assert bench_bounded(m, repeats=1)["n_shapes"] == m.n_shapes
