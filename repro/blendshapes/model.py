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

Every argument of the blendshape package is checked by the helpers of this
package (:mod:`repro.checks`): real arrays
must hold real numbers (no strings, ``None``, objects, booleans, complex values,
NaN/inf), indices and counts must be integers (numpy integers accepted; bools,
floats and strings refused) in range, and the error names the argument.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from repro.checks import abs_max, as_int, as_real, as_real_array, as_str, describe, read_only
from repro.errors import ModelError

__all__ = ["BlendshapeModel", "AXES"]

#: Axis names in the order of the xyz packing of ``D``.
AXES = ("x", "y", "z")


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
    notes : sequence of str
        What a reader decided about the source file, in words (which of its meshes
        make the face, expressions it skipped and why); empty for a model built in code.

    All arrays are copied and made read-only, so caches keyed on a model stay
    valid.

    Raises
    ------
    ModelError
        For a non-numeric, complex, boolean or non-finite ``f0``/``D``, wrong
        shapes, names that are not distinct strings, faces that are not integer
        vertex ids in range, slider coefficients that are not finite real
        numbers or combine unknown shapes, and regions that are not integer
        vertex ids in range.
    """

    f0: np.ndarray
    D: np.ndarray
    names: tuple[str, ...]
    faces: np.ndarray
    name: str = "model"
    units: str = "model units"
    sliders: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    regions: Mapping[str, np.ndarray] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        f0 = as_real_array(self.f0, "f0", finite=False, error=ModelError)
        D = as_real_array(self.D, "D", finite=False, error=ModelError)
        if f0.ndim != 2 or f0.shape[1] != 3 or f0.shape[0] == 0:
            raise ModelError(f"f0 must have shape (n, 3) with n >= 1, got {f0.shape}")
        n = f0.shape[0]
        if D.ndim != 2 or D.shape[0] != 3 * n:
            raise ModelError(
                f"D must have shape (3n, m) = ({3 * n}, m) for n = {n} vertices "
                f"(xyz packing, row 3*v + axis), got {D.shape}"
            )
        if isinstance(self.names, (str, bytes)) or not isinstance(self.names, Iterable) or (
            isinstance(self.names, np.ndarray) and self.names.ndim == 0  # iterable by type, not by value
        ):
            raise ModelError(f"names must be a sequence of strings, got {describe(self.names)}")
        names = tuple(self.names)
        bad = [s for s in names if not isinstance(s, str)]
        if bad:
            raise ModelError(f"shape names must be strings, got {describe(bad[0])}")
        names = tuple(str(s) for s in names)  # np.str_ -> str
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
        as_str(self.name, "name", error=ModelError)
        as_str(self.units, "units", error=ModelError)
        faces = as_real_array(self.faces, "faces", integer=True, error=ModelError)
        if faces.size == 0:
            faces = np.zeros((0, 3), dtype=np.int64)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ModelError(f"faces must be an (F, 3) integer array, got shape {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= n):
            raise ModelError(
                f"faces index vertices {faces.min()}..{faces.max()}, outside 0..{n - 1}"
            )
        if not isinstance(self.sliders, Mapping):
            raise ModelError(f"sliders must be a mapping of name to {{shape: coefficient}}, got {describe(self.sliders)}")
        sliders = {}
        for slider, combo in self.sliders.items():
            as_str(slider, "a slider name", error=ModelError)
            if slider in names:
                raise ModelError(f"slider {slider!r} has the name of a shape")
            if not isinstance(combo, Mapping):
                raise ModelError(f"slider {slider!r} must map shape names to coefficients, got {describe(combo)}")
            unknown = [s for s in combo if not isinstance(s, str) or s not in names]
            if unknown:
                raise ModelError(f"slider {slider!r} combines unknown shapes {unknown}")
            sliders[str(slider)] = {
                str(s): as_real(c, f"coefficient of {s!r} in slider {slider!r}", error=ModelError) for s, c in combo.items()
            }
        if not isinstance(self.regions, Mapping):
            raise ModelError(f"regions must be a mapping of name to vertex ids, got {describe(self.regions)}")
        regions = {}
        for region, verts in self.regions.items():
            as_str(region, "a region name", error=ModelError)
            v = as_real_array(verts, f"region {region!r}", integer=True, error=ModelError)
            if v.ndim > 1:
                raise ModelError(f"region {region!r} must be a 1-D array of vertex ids, got shape {v.shape}")
            v = v.ravel()
            if v.size == 0 or v.min() < 0 or v.max() >= n:
                raise ModelError(f"region {region!r} must list vertices in 0..{n - 1}")
            regions[str(region)] = read_only(v)
        set_ = object.__setattr__
        set_(self, "f0", read_only(f0))
        set_(self, "D", read_only(D))
        set_(self, "names", names)
        set_(self, "faces", read_only(faces.astype(np.int64)))
        set_(self, "sliders", sliders)
        set_(self, "regions", regions)
        if isinstance(self.notes, (str, bytes)) or not isinstance(self.notes, Iterable):
            raise ModelError(f"notes must be a sequence of strings, got {describe(self.notes)}")
        set_(self, "notes", tuple(as_str(s, "a note", error=ModelError) for s in self.notes))

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
        if values is None:
            items = {}
        elif isinstance(values, Mapping):
            items = dict(values)
        else:
            raise ModelError(f"slider values must be a mapping of name to value, got {describe(values)}")
        items.update(kw)
        w = np.zeros(self.n_shapes)
        with np.errstate(over="ignore", invalid="ignore"):
            self._accumulate(w, items)
        if not np.isfinite(w).all():
            raise ModelError(
                f"slider values {items} overflow float64 at shapes "
                f"{[self.names[i] for i in np.flatnonzero(~np.isfinite(w))]}"
            )
        return w

    def _accumulate(self, w: np.ndarray, items: dict) -> None:
        for key, value in items.items():
            value = as_real(value, f"slider {key!r}", finite=False, error=ModelError)
            if not math.isfinite(value):
                raise ModelError(f"slider {key!r} has a non-finite value {value}")
            if not isinstance(key, str):
                raise ModelError(f"slider names must be strings, got {describe(key)}")
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

    def check_weights(self, w) -> np.ndarray:
        """``w`` as a finite float vector of length m, or a :class:`ModelError`."""
        if isinstance(w, Mapping):
            return self.weights(w)
        w = as_real_array(w, "weights", shape=(self.n_shapes,), finite=False, error=ModelError)
        if not np.isfinite(w).all():
            raise ModelError(f"weights contain NaN/inf at shapes {list(np.flatnonzero(~np.isfinite(w)))}")
        return w

    # ------------------------------------------------------------------ poses
    @cached_property
    def abs_max(self) -> tuple[float, float]:
        """``(max |D|, max |f0|)``: bounds that tell cheaply when ``f0 + D w`` cannot overflow."""
        return abs_max(self.D), abs_max(self.f0)

    def _posed(self, w, with_f0: bool) -> np.ndarray:
        """``D w`` (or ``f0 + D w``) as (n, 3); refuses a result that overflows float64."""
        w = self.check_weights(w)
        dmax, fmax = self.abs_max
        if dmax * float(np.abs(w).max(initial=0.0)) * w.size + fmax < 1e300:  # cannot overflow
            d = (self.D @ w).reshape(-1, 3)
            return self.f0 + d if with_f0 else d
        with np.errstate(over="ignore", invalid="ignore"):
            d = (self.D @ w).reshape(-1, 3)
            if with_f0:
                d = self.f0 + d
        if not np.isfinite(d).all():
            what = "the pose f0 + D w" if with_f0 else "the displacement D w"
            raise ModelError(f"{what} overflows float64 for weights with max |w| = {np.abs(w).max():.3g}")
        return d

    def displacement(self, w) -> np.ndarray:
        """Per-vertex displacement ``D w`` reshaped to (n, 3)."""
        return self._posed(w, with_f0=False)

    def pose(self, w) -> np.ndarray:
        """Posed vertices ``f = f0 + D w`` (Section 3) as an (n, 3) array."""
        return self._posed(w, with_f0=True)

    # -------------------------------------------------- whole-face <-> delta
    def to_whole_face(self) -> np.ndarray:
        """Whole-face basis ``B`` (3n x (m+1)) equivalent to this delta model.

        Section 3: "set b_1 = f0, and set b_k to f0 + d_{k-1} for k = 2...m".
        A delta pose ``w`` is then ``B @ whole_face_weights(w)``.
        """
        f = self.f0.reshape(-1, 1)
        with np.errstate(over="ignore", invalid="ignore"):
            B = np.hstack([f, f + self.D])
        if sum(self.abs_max) >= 1e300 and not np.isfinite(B).all():
            raise ModelError("the whole-face basis f0 + d_k overflows float64")
        return B

    @staticmethod
    def whole_face_weights(w) -> np.ndarray:
        """Whole-face weights ``(1 - sum(w), w_1, w_2, ...)`` of a delta pose (Section 3)."""
        w = as_real_array(w, "delta weights", ndim=1, error=ModelError)
        return np.concatenate([[1.0 - w.sum()], w])

    @staticmethod
    def delta_weights(c) -> np.ndarray:
        """Delta weights of a whole-face pose: drop ``c_1``; the inverse of :meth:`whole_face_weights`.

        Whole-face weights must sum to one (the "barycentric" constraint of
        Section 3), otherwise the pose scales the face and has no delta form.
        """
        c = as_real_array(c, "whole-face weights", finite=False, error=ModelError)
        if c.ndim != 1 or c.size < 1:
            raise ModelError(f"whole-face weights must be a non-empty vector, got shape {c.shape}")
        if not np.isfinite(c).all():
            raise ModelError(f"whole-face weights contain NaN/inf at {np.flatnonzero(~np.isfinite(c)).tolist()}")
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
        B = as_real_array(B, "B", error=ModelError)
        if B.ndim != 2 or B.shape[0] % 3 or B.shape[0] == 0 or B.shape[1] < 1:
            raise ModelError(f"B must have shape (3n, M) with n >= 1 and M >= 1, got {B.shape}")
        neutral = as_int(neutral, "neutral (column of B)", lo=0, hi=B.shape[1] - 1, error=ModelError)
        f0 = B[:, neutral]
        with np.errstate(over="ignore", invalid="ignore"):
            D = np.delete(B, neutral, axis=1) - f0[:, None]
        if not np.isfinite(D).all():
            raise ModelError("B - b_neutral overflows float64: the whole-face basis is too large to subtract")
        return cls(f0=f0.reshape(-1, 3), D=D, names=names, faces=faces, **kw)

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
        v = as_real_array(vertices, "restrict() vertices", integer=True, error=ModelError)
        if v.ndim > 1:
            raise ModelError(f"restrict() needs a 1-D array of vertex ids, got shape {v.shape}")
        v = v.ravel()
        if name is not None:
            as_str(name, "name", error=ModelError)
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
            notes=self.notes,
        )
