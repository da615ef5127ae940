"""Which meshes of a glTF file make the face, and the face they make when there are several.

An avatar rarely keeps its face in one mesh: a Ready Player Me avatar carries the same 69 ARKit
and viseme targets on ``Wolf3D_Head``, ``EyeLeft``, ``EyeRight`` and ``Wolf3D_Teeth`` (``jawOpen``
moves the teeth, ``eyeLookUp_L`` the left eyeball), besides glasses, hair and body meshes without
targets.  :func:`choose_face` finds the face without being told:

* the meshes with morph targets are grouped by their set of target names (meshes whose targets
  carry no names, or repeat a name, stay alone);
* each group is scored by its *morph motion*: ``sum_k sum_v |d_k(v)|``, the length (in metres,
  world placement) every vertex travels under every target at weight 1, summed over the group's
  meshes; the group with the most is the face (ties: more vertices, then the earlier mesh);
* the meshes of that group are read as **one** face (:func:`merge`): the vertices concatenated
  in world space (the mesh with the most motion first, so its vertex ids are the model's first
  ones, then the others in file order), the triangles re-indexed, and the deltas put in the
  column of their target's name (the first mesh's order) -- a delta model ``f = f0 + D w``
  (Lewis et al. 2005, Section 3) over the whole head, where one ``jawOpen`` weight opens the jaw
  and moves the teeth.

A group whose deltas are all zero moves nothing and is refused (:class:`~repro.errors.ModelError`
naming its meshes and targets).  What was chosen, with each mesh's motion, and which other meshes
there are, is recorded in words in the model's
:attr:`~repro.blendshapes.model.BlendshapeModel.notes`; a
:class:`~repro.errors.ReproWarning` is issued only when the choice is close (another target set
moves at least :data:`AMBIGUOUS` of the chosen one's motion).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from repro.errors import ModelError, ReproWarning

__all__ = ["MeshPart", "choose_face", "merge", "AMBIGUOUS"]

#: Another target set whose morph motion is at least this fraction of the chosen one's makes the choice ambiguous.
AMBIGUOUS = 0.5


@dataclass
class MeshPart:
    """One mesh read from the file: primitives merged, neutral and deltas in world placement."""

    mi: int  #: glTF mesh index
    label: str  #: the mesh's name (or ``mesh<i>``)
    prims: list[int]
    f0: np.ndarray  #: (n, 3)
    D3: np.ndarray  #: (n, 3, m)
    faces: np.ndarray  #: (F, 3), indexing this mesh's vertices
    names: list[str]
    named: bool  #: the names come from the file (not ``target_k``)

    @property
    def n(self) -> int:
        return len(self.f0)

    @property
    def motion(self) -> float:
        """``sum_k sum_v |d_k(v)|``, metres."""
        return float(np.linalg.norm(self.D3, axis=1).sum())

    @property
    def where(self) -> str:
        return f"{self.label}/{','.join(map(str, self.prims))}"


def choose_face(parts: list[MeshPart], *, without_targets: list[str], auto: bool) -> tuple[list[MeshPart], list[str]]:
    """The meshes that make the face (the one with the most motion first) and notes saying why.

    ``parts`` are the meshes read (every mesh with targets when ``auto``, else the one asked for);
    ``without_targets`` names the file's other meshes, for the notes.
    """
    groups: dict[object, list[MeshPart]] = {}
    for part in parts:
        key = frozenset(part.names) if part.named and len(set(part.names)) == len(part.names) else ("mesh", part.mi)
        groups.setdefault(key, []).append(part)
    motion = {id(g): sum(p.motion for p in g) for g in groups.values()}
    ranked = sorted(groups.values(), key=lambda g: (-motion[id(g)], -sum(p.n for p in g), g[0].mi))
    best = sorted(ranked[0], key=lambda p: (-p.motion, p.mi))
    if not motion[id(ranked[0])] > 0:
        what = "the mesh" if len(parts) == 1 else f"every one of the {len(parts)} meshes with targets"
        shown = ", ".join(repr(s) for s in best[0].names[:6]) + (", ..." if len(best[0].names) > 6 else "")
        raise ModelError(
            f"{what} ({', '.join(p.label for p in parts)}) has morph targets whose deltas are all zero "
            f"({len(best[0].names)} targets: {shown}): they move no vertex, there is no face to read"
        )
    notes = [_chosen(best, auto)]
    others = [g for g in ranked[1:]]
    if others:
        notes.append("other meshes with morph targets, not read: " + "; ".join(
            f"{', '.join(p.label for p in g)} ({len(g[0].names)} targets, motion {motion[id(g)]:.3g} m)" for g in others))
    if without_targets:
        notes.append(f"meshes without morph targets, not read: {', '.join(without_targets)}")
    close = [g for g in others if motion[id(g)] >= AMBIGUOUS * motion[id(ranked[0])]]
    if auto and close:
        warnings.warn(
            f"the face was chosen among meshes whose morph motion is close: {', '.join(p.label for p in best)} "
            f"({motion[id(ranked[0])]:.3g} m) over {', '.join(p.label for p in close[0])} ({motion[id(close[0])]:.3g} m); "
            "pass mesh= to choose", ReproWarning, stacklevel=4)
    return best, notes


def _chosen(best: list[MeshPart], auto: bool) -> str:
    how = "chosen as the target set with the most morph motion" if auto else "asked for"
    each = ", ".join(f"{p.label} {p.n} vertices {p.motion:.3g} m" for p in best)
    if len(best) == 1:
        return f"face: mesh {best[0].label} ({best[0].n} vertices, {len(best[0].names)} targets), {how} (motion {best[0].motion:.3g} m)"
    return (f"face: meshes {', '.join(p.label for p in best)} read as one face, {how}: they share "
            f"{len(best[0].names)} target names (motion = sum over targets and vertices of |delta|: {each})")


def merge(group: list[MeshPart]) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """``(f0, D3, faces, names)`` of the group's meshes as one face (a single mesh as it is, no copy)."""
    first = group[0]
    if len(group) == 1:
        return first.f0, first.D3, first.faces, first.names
    column = {s: k for k, s in enumerate(first.names)}
    n_total = sum(p.n for p in group)
    f0 = np.empty((n_total, 3))
    D3 = np.zeros((n_total, 3, len(first.names)))
    faces, o = [], 0
    for p in group:
        f0[o : o + p.n] = p.f0
        D3[o : o + p.n][:, :, [column[s] for s in p.names]] = p.D3
        faces.append(p.faces + o)
        o += p.n
    return f0, D3, np.concatenate(faces), list(first.names)
