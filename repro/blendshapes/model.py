"""The delta blendshape model of Lewis et al. 2005, Section 3.

A model is a neutral face ``f0`` (n vertices x 3) plus a delta basis ``D``
(3n x m) whose columns are the blendshapes minus the neutral, ``d_k = b_k - f0``.
A pose is ``f = f0 + D w`` (Section 3).  Vertices are packed *xyzxyz...*: row
``3*v + axis`` of ``D`` is coordinate ``axis`` (0 = x, 1 = y, 2 = z) of vertex
``v``.  This is the packing the attenuation code (Section 4) and the coordinate
selections use throughout.

The whole-face form of Section 3 (``f = B c``, weights summing to one) is
available through :meth:`BlendshapeModel.to_whole_face` and
:meth:`BlendshapeModel.from_whole_face`; the paper's remark that the two forms
are "identical in power" is what the round-trip tests check.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from repro.errors import ModelError

__all__ = ["BlendshapeModel", "AXES"]

#: Axis names in the order of the xyz packing of ``D``.
AXES = ("x", "y", "z")


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class BlendshapeModel:
    """A delta blendshape face ``f = f0 + D w`` (Lewis et al. 2005, Section 3).

    Parameters
    ----------
    f0 : (n, 3) array
        Neutral vertex positions.
    D : (3n, m) array
        Delta basis, row ``3*v + axis`` (xyz packing), one column per shape.
    names : sequence of str
        The ``m`` shape (slider) names, unique.
    faces : (F, 3) int array
        Triangles indexing the ``n`` vertices (used for rendering and for the
        smoothness metric).
    name : str
        A short label for figures ("procedural", "ict").
    units : str
        Length unit of ``f0`` and ``D`` ("cm" for the ICT model).
    sliders : mapping of str to mapping of str to float
        Named combinations of shapes, e.g. the paper's ``Furrow`` on a model
        that has ``browDown_L`` and ``browDown_R``:
        ``{"Furrow": {"browDown_L": 1.0, "browDown_R": 1.0}}``.
    regions : mapping of str to int array
        Named vertex sets (e.g. ``"brow_middle"``), used as selection presets.

    All arrays are copied and made read-only, so caches keyed on a model stay
    valid.
    """

    f0: np.ndarray
    D: np.ndarray
    names: tuple[str, ...]
    faces: np.ndarray
    name: str = "model"
    units: str = "model units"
    sliders: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    regions: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        f0 = np.asarray(self.f0, dtype=np.float64)
        D = np.asarray(self.D, dtype=np.float64)
        if f0.ndim != 2 or f0.shape[1] != 3 or f0.shape[0] == 0:
            raise ModelError(f"f0 must have shape (n, 3) with n >= 1, got {f0.shape}")
        n = f0.shape[0]
        if D.ndim != 2 or D.shape[0] != 3 * n:
            raise ModelError(
                f"D must have shape (3n, m) = ({3 * n}, m) for n = {n} vertices "
                f"(xyz packing, row 3*v + axis), got {D.shape}"
            )
        names = tuple(str(s) for s in self.names)
        if len(names) != D.shape[1]:
            raise ModelError(f"{len(names)} shape names for {D.shape[1]} columns of D")
        if len(set(names)) != len(names):
            dup = sorted({s for s in names if names.count(s) > 1})
            raise ModelError(f"shape names must be unique; repeated: {dup}")
        if not np.isfinite(f0).all():
            raise ModelError(f"f0 has {np.count_nonzero(~np.isfinite(f0))} NaN/inf values")
        if not np.isfinite(D).all():
            bad = np.unique(np.nonzero(~np.isfinite(D))[1])
            raise ModelError(f"D has NaN/inf values in shapes {[names[i] for i in bad]}")
        faces = np.asarray(self.faces)
        if faces.size == 0:
            faces = np.zeros((0, 3), dtype=np.int64)
        if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
            raise ModelError(f"faces must be an (F, 3) integer array, got {faces.shape} {faces.dtype}")
        if faces.size and (faces.min() < 0 or faces.max() >= n):
            raise ModelError(
                f"faces index vertices {faces.min()}..{faces.max()}, outside 0..{n - 1}"
            )
        sliders = {}
        for slider, combo in dict(self.sliders).items():
            if slider in names:
                raise ModelError(f"slider {slider!r} has the name of a shape")
            unknown = [s for s in combo if s not in names]
            if unknown:
                raise ModelError(f"slider {slider!r} combines unknown shapes {unknown}")
            sliders[str(slider)] = {str(s): float(c) for s, c in combo.items()}
        regions = {}
        for region, verts in dict(self.regions).items():
            v = np.asarray(verts, dtype=np.int64).ravel()
            if v.size == 0 or v.min() < 0 or v.max() >= n:
                raise ModelError(f"region {region!r} must list vertices in 0..{n - 1}")
            regions[str(region)] = _frozen(v)
        set_ = object.__setattr__
        set_(self, "f0", _frozen(f0))
        set_(self, "D", _frozen(D))
        set_(self, "names", names)
        set_(self, "faces", _frozen(faces.astype(np.int64)))
        set_(self, "sliders", sliders)
        set_(self, "regions", regions)

    # ------------------------------------------------------------------ sizes
    @property
    def n_vertices(self) -> int:
        """Number of vertices ``n``."""
        return self.f0.shape[0]

    @property
    def n_shapes(self) -> int:
        """Number of delta shapes ``m`` (columns of ``D``)."""
        return self.D.shape[1]

    def __repr__(self) -> str:
        return (
            f"BlendshapeModel({self.name!r}: {self.n_vertices} vertices, "
            f"{self.n_shapes} shapes, {len(self.faces)} triangles, units={self.units!r})"
        )

    # ---------------------------------------------------------------- weights
    @property
    def slider_names(self) -> tuple[str, ...]:
        """Every name :meth:`weights` accepts: shapes, then named combinations."""
        return self.names + tuple(self.sliders)

    def shape_index(self, name: str) -> int:
        """Column of ``D`` holding shape ``name``."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ModelError(
                f"unknown shape {name!r} in model {self.name!r}; shapes are {list(self.names)}"
            ) from None

    def weights(self, values: Mapping[str, float] | None = None, **kw: float) -> np.ndarray:
        """Weight vector ``w`` (m,) from slider values given by name.

        Names may be shapes or named combinations (:attr:`sliders`); values of
        names that resolve to the same shape add up.  ``model.weights(Furrow=0.4)``
        and ``model.weights({"Furrow": 0.4})`` are the same.
        """
        items = dict(values or {})
        items.update(kw)
        w = np.zeros(self.n_shapes)
        for key, value in items.items():
            value = float(value)
            if not np.isfinite(value):
                raise ModelError(f"slider {key!r} has a non-finite value {value}")
            if key in self.sliders:
                for shape, coef in self.sliders[key].items():
                    w[self.names.index(shape)] += coef * value
            elif key in self.names:
                w[self.names.index(key)] += value
            else:
                raise ModelError(
                    f"unknown slider {key!r} in model {self.name!r}; "
                    f"known: {list(self.slider_names)}"
                )
        return w

    def check_weights(self, w) -> np.ndarray:
        """``w`` as a finite float vector of length m, or a :class:`ModelError`."""
        if isinstance(w, Mapping):
            return self.weights(w)
        w = np.asarray(w, dtype=np.float64)
        if w.shape != (self.n_shapes,):
            raise ModelError(f"weights must have shape ({self.n_shapes},), got {w.shape}")
        if not np.isfinite(w).all():
            raise ModelError(f"weights contain NaN/inf at shapes {list(np.flatnonzero(~np.isfinite(w)))}")
        return w

    # ------------------------------------------------------------------ poses
    def displacement(self, w) -> np.ndarray:
        """Per-vertex displacement ``D w`` reshaped to (n, 3)."""
        return (self.D @ self.check_weights(w)).reshape(-1, 3)

    def pose(self, w) -> np.ndarray:
        """Posed vertices ``f = f0 + D w`` (Section 3) as an (n, 3) array."""
        return self.f0 + self.displacement(w)

    # -------------------------------------------------- whole-face <-> delta
    def to_whole_face(self) -> np.ndarray:
        """Whole-face basis ``B`` (3n x (m+1)) equivalent to this delta model.

        Section 3: "set b_1 = f0, and set b_k to f0 + d_{k-1} for k = 2...m".
        A delta pose ``w`` is then ``B @ whole_face_weights(w)``.
        """
        f = self.f0.reshape(-1, 1)
        return np.hstack([f, f + self.D])

    @staticmethod
    def whole_face_weights(w) -> np.ndarray:
        """Whole-face weights ``(1 - sum(w), w_1, w_2, ...)`` of a delta pose (Section 3)."""
        w = np.asarray(w, dtype=np.float64)
        return np.concatenate([[1.0 - w.sum()], w])

    @staticmethod
    def delta_weights(c) -> np.ndarray:
        """Delta weights of a whole-face pose: drop ``c_1``; the inverse of :meth:`whole_face_weights`.

        Whole-face weights must sum to one (the "barycentric" constraint of
        Section 3), otherwise the pose scales the face and has no delta form.
        """
        c = np.asarray(c, dtype=np.float64)
        if c.ndim != 1 or c.size < 1:
            raise ModelError(f"whole-face weights must be a non-empty vector, got shape {c.shape}")
        if not np.isclose(c.sum(), 1.0, rtol=0, atol=1e-9):
            raise ModelError(
                f"whole-face weights must sum to 1 (Section 3), got sum {c.sum():.12g}"
            )
        return c[1:].copy()

    @classmethod
    def from_whole_face(
        cls, B, faces, names, *, neutral: int = 0, **kw
    ) -> "BlendshapeModel":
        """Delta model from a whole-face basis ``B`` (3n x M): ``d_k = b_k - b_neutral``.

        ``names`` names the ``M - 1`` non-neutral columns, in order.
        """
        B = np.asarray(B, dtype=np.float64)
        if B.ndim != 2 or B.shape[0] % 3 or B.shape[1] < 1:
            raise ModelError(f"B must have shape (3n, M) with M >= 1, got {B.shape}")
        if not 0 <= neutral < B.shape[1]:
            raise ModelError(f"neutral column {neutral} outside 0..{B.shape[1] - 1}")
        f0 = B[:, neutral]
        D = np.delete(B, neutral, axis=1) - f0[:, None]
        return cls(f0=f0.reshape(-1, 3), D=D, names=tuple(names), faces=faces, **kw)

    def to_gltf(self, path, weights=None, animation=None, **kw):
        """Write this face as glTF 2.0 (``.glb``/``.gltf``); see :func:`repro.blendshapes.gltf.write_gltf`."""
        from repro.blendshapes.gltf import write_gltf

        return write_gltf(self, path, weights, animation, **kw)

    # --------------------------------------------------------------- topology
    @cached_property
    def edges(self) -> np.ndarray:
        """Unique undirected mesh edges (E, 2), sorted, from :attr:`faces`."""
        if not len(self.faces):
            return np.zeros((0, 2), dtype=np.int64)
        e = np.concatenate([self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]])
        e.sort(axis=1)
        return np.unique(e, axis=0)

    @cached_property
    def laplacian(self):
        """Uniform graph Laplacian ``L = I - A_norm`` (n x n, scipy CSR) of the mesh edges.

        ``(L @ x)[i] = x[i] - mean of x over the neighbours of i``; isolated
        vertices get a zero row.  Used by the smoothness metric.
        """
        import scipy.sparse as sp

        n = self.n_vertices
        e = self.edges
        A = sp.coo_matrix(
            (np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)
        ).tocsr()
        deg = np.asarray(A.sum(axis=1)).ravel()
        inv = np.divide(1.0, deg, out=np.zeros(n), where=deg > 0)
        return (sp.diags((deg > 0).astype(float)) - sp.diags(inv) @ A).tocsr()

    def restrict(self, vertices, *, name: str | None = None) -> "BlendshapeModel":
        """The model on a subset of its vertices (e.g. the ICT face area).

        Triangles with a vertex outside the subset are dropped and the rest
        re-indexed; shapes that become all-zero are kept (their columns are zero).
        """
        v = np.asarray(vertices, dtype=np.int64).ravel()
        if v.size == 0 or v.min() < 0 or v.max() >= self.n_vertices or np.unique(v).size != v.size:
            raise ModelError(
                f"restrict() needs distinct vertex ids in 0..{self.n_vertices - 1}, got {v.size} ids"
            )
        new_id = np.full(self.n_vertices, -1, dtype=np.int64)
        new_id[v] = np.arange(v.size)
        keep = (new_id[self.faces] >= 0).all(axis=1)
        rows = (3 * v[:, None] + np.arange(3)).ravel()
        regions = {}
        for r, verts in self.regions.items():
            mapped = new_id[verts]
            if (mapped >= 0).any():
                regions[r] = mapped[mapped >= 0]
        return BlendshapeModel(
            f0=self.f0[v],
            D=self.D[rows],
            names=self.names,
            faces=new_id[self.faces[keep]],
            name=name or self.name,
            units=self.units,
            sliders=self.sliders,
            regions=regions,
        )
