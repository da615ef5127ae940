"""Shared test set-up.

- Tests never touch the network: ``REPRO_OFFLINE=1``.
- The data folder defaults to the staged copy beside the checkout
  (``../shared/data``) when ``REPRO_DATA_DIR`` is not set.
- ``@pytest.mark.data("ict")`` skips a test with the data layer's own reason when
  that dataset is really absent; with ``REPRO_REQUIRE_DATA=1`` (CI) absence is an
  error instead, so CI cannot go green by skipping.
- A notebook declares what it needs in its metadata, ``"repro": {"needs_data":
  ["ict"], "needs_render": true}``, and gets the same markers (its stored
  outputs were made with that data, so without it nbval could only fail).
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


def _notebook_needs(path: Path) -> dict:
    """A notebook's ``metadata.repro`` block: ``{"needs_data": [...], "needs_render": bool}``."""
    import json

    try:
        return json.loads(path.read_text()).get("metadata", {}).get("repro", {})
    except (OSError, ValueError):
        return {}


def pytest_collection_modifyitems(config, items):
    from repro import data

    for item in items:
        if item.path.suffix == ".ipynb":
            needs = _notebook_needs(item.path)
            if needs.get("needs_data"):
                item.add_marker(pytest.mark.data(*needs["needs_data"]))
            if needs.get("needs_render") or "pyvista" in item.path.read_text():
                item.add_marker(pytest.mark.render)

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

    if any(i.get_closest_marker("render") for i in items):
        from repro.render import render_unavailable_reason

        reason = render_unavailable_reason()
        if reason:
            if os.environ.get("REPRO_REQUIRE_RENDER") == "1":
                raise pytest.UsageError(f"REPRO_REQUIRE_RENDER=1 but {reason}")
            for item in items:
                if item.get_closest_marker("render"):
                    item.add_marker(pytest.mark.skip(reason=reason))
