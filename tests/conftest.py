"""Shared test set-up.

- Tests never touch the network: ``REPRO_OFFLINE=1``.
- The data folder defaults to the staged copy beside the checkout
  (``../shared/data``) when ``REPRO_DATA_DIR`` is not set.
- ``@pytest.mark.data("ict")`` skips a test with the data layer's own reason when
  that dataset is really absent; with ``REPRO_REQUIRE_DATA=1`` (CI) absence is an
  error instead, so CI cannot go green by skipping.
- ``@pytest.mark.render`` (and every notebook that uses pyvista) is probed once
  in a subprocess (VTK segfaults without an OpenGL, which would take pytest
  down); skipped with the reason, or an error with ``REPRO_REQUIRE_RENDER=1``.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

os.environ["REPRO_OFFLINE"] = "1"
_staged = REPO.parent / "shared" / "data"
if not os.environ.get("REPRO_DATA_DIR") and _staged.is_dir():
    os.environ["REPRO_DATA_DIR"] = str(_staged)
os.environ.setdefault("MPLBACKEND", "Agg")

from hypothesis import settings  # noqa: E402

# shared 2-core machines are noisy: no per-example deadline, fixed derandomised runs
settings.register_profile("repro", deadline=None, derandomize=True, max_examples=60)
settings.load_profile("repro")


def pytest_configure(config):
    config.addinivalue_line("markers", "render: needs VTK off-screen rendering")
    config.addinivalue_line("markers", "data(name): needs staged dataset NAME")


def pytest_collection_modifyitems(config, items):
    from repro import data

    require_data = os.environ.get("REPRO_REQUIRE_DATA") == "1"
    for item in items:
        for mark in item.iter_markers("data"):
            for name in mark.args:
                reason = data.missing_reason(name)
                if reason is None:
                    continue
                if require_data:
                    raise pytest.UsageError(f"REPRO_REQUIRE_DATA=1 but {reason}")
                item.add_marker(pytest.mark.skip(reason=reason))

    for item in items:
        if item.path.suffix == ".ipynb" and "pyvista" in item.path.read_text():
            item.add_marker(pytest.mark.render)
    if any(i.get_closest_marker("render") for i in items):
        from repro.render import render_unavailable_reason

        reason = render_unavailable_reason()
        if reason:
            if os.environ.get("REPRO_REQUIRE_RENDER") == "1":
                raise pytest.UsageError(f"REPRO_REQUIRE_RENDER=1 but {reason}")
            for item in items:
                if item.get_closest_marker("render"):
                    item.add_marker(pytest.mark.skip(reason=reason))
