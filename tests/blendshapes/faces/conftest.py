"""What the glTF face tests share: the fixture files (tests/data/gltf, made by
scripts/make_gltf_fixtures.py), the face they hold, and the procedural face."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from repro.blendshapes import load_model
from repro.blendshapes.faces.gltf import read_gltf
from tests.conftest import REPO

DATA = REPO / "tests" / "data" / "gltf"
F32 = 1e-6  # float32 rounding of coordinates of a few decimetres, in metres


def _script():
    spec = importlib.util.spec_from_file_location("make_gltf_fixtures", REPO / "scripts" / "make_gltf_fixtures.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def fixtures():
    return _script()


@pytest.fixture(scope="module")
def expected(fixtures):
    return fixtures.fixture_model()


@pytest.fixture(scope="module")
def face():
    return load_model("procedural")


def canonical_faces(faces):
    """Triangles up to a cyclic rotation (meshopt's index codec may rotate them, winding kept)."""
    f = np.asarray(faces)
    k = np.argmin(f, axis=1)
    rolled = np.stack([np.roll(row, -s) for row, s in zip(f, k)])
    return rolled[np.lexsort(rolled.T[::-1])]


@pytest.fixture(scope="module")
def reference():
    return read_gltf(DATA / "face.gltf")
