"""Small deterministic models for tests that must not depend on the procedural face."""

import numpy as np

from repro.blendshapes import BlendshapeModel


def grid_model(nx: int = 12, ny: int = 10, m: int = 6, seed: int = 0) -> BlendshapeModel:
    """A flat nx x ny grid with m smooth random Gaussian-bump shapes (full column rank)."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float))
    f0 = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    cols = []
    for _ in range(m):
        cx, cy = rng.uniform(0, nx - 1), rng.uniform(0, ny - 1)
        s = rng.uniform(1.5, 3.5)
        bump = np.exp(-((f0[:, 0] - cx) ** 2 + (f0[:, 1] - cy) ** 2) / (2 * s * s))
        direction = rng.normal(size=3)
        cols.append((bump[:, None] * direction[None, :]).ravel())
    D = np.column_stack(cols)
    names = [f"s{i}" for i in range(m)]
    return BlendshapeModel(f0=f0, D=D, names=names, faces=faces, name="grid",
                           sliders={"pair": {"s0": 1.0, "s1": 0.5}},
                           regions={"corner": np.array([0, 1, nx])})


def refusal_failures(calls, error) -> list[str]:
    """For a table of ``(name, call)`` that must each raise ``error``: the ones that did not
    (another exception, or accepted), as lines for the assertion message."""
    failures = []
    for name, call in calls:
        try:
            call()
        except error:
            continue
        except Exception as e:  # noqa: BLE001 - what the table is about
            failures.append(f"{name}: {type(e).__name__}: {e}")
        else:
            failures.append(f"{name}: accepted")
    return failures
