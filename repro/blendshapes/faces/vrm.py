"""VRM avatars' expressions as named sliders of the face (a delta model, Lewis et al. 2005, Section 3).

A ``.vrm`` file is a binary glTF (GLB) whose face carries ordinary morph targets; what makes it a
VRM is a JSON extension that names *expressions*, each a weighted combination of those targets.
That is exactly the paper's notion of a named slider over a delta basis (a combination such as
``Furrow = browDown_L + browDown_R``), so :func:`vrm_expressions` turns every expression into a
:class:`~repro.blendshapes.model.BlendshapeModel` slider ``{shape name: coefficient}``.

Both versions of the extension:

* **VRM 0.x** (``extensions.VRM``): ``blendShapeMaster.blendShapeGroups[]`` with ``name``,
  ``presetName`` (``neutral``, ``a i u e o``, ``blink``, ``joy``, ``angry``, ``sorrow``, ``fun``,
  ``lookup``/``lookdown``/``lookleft``/``lookright``, ``blink_l``/``blink_r``, or ``unknown`` for a
  custom one) and ``binds[] {mesh, index, weight}``: ``mesh`` is the glTF mesh index, ``index``
  the morph target, ``weight`` on a 0-100 scale (a coefficient of ``weight / 100``).  The slider
  is named after ``presetName``, or after ``name`` for a custom (``unknown``) group.
* **VRM 1.0** (``extensions.VRMC_vrm``): ``expressions.preset`` (``happy``, ``angry``, ``sad``,
  ``relaxed``, ``surprised``, ``aa ih ou ee oh``, ``blink``, ``blinkLeft``/``blinkRight``,
  ``lookUp``/``lookDown``/``lookLeft``/``lookRight``, ``neutral``) and ``expressions.custom``, each
  ``{morphTargetBinds[] {node, index, weight}}``: ``node`` is a glTF node index (its ``mesh`` is
  bound), ``weight`` on 0-1.

When a file has both, the 1.0 extension is read.  Binds to the same target add up.  What is not
geometry is left out: material and texture binds (``materialValues``, ``materialColorBinds``,
``textureTransformBinds``), ``isBinary`` (a slider is continuous; a runtime rounds a binary one)
and the ``override*`` flags.

Nothing in the extension can make the read fail: an expression or a bind that cannot be used (a
missing or malformed field, a mesh or node that is not part of the face read, a target index out
of range, a weight that is not a finite number in range) is skipped and the reason recorded in
the returned notes (the model's :attr:`~repro.blendshapes.model.BlendshapeModel.notes`); an
expression without a usable morph-target bind (``neutral`` usually has none) is not a slider.
A slider named like a shape of the face is not made when it is that shape at weight 1, and is
named ``<name>_expression`` otherwise.

The blink expressions (``blink_l``/``blink_r``, ``blinkLeft``/``blinkRight``) are also handed to
:func:`~repro.blendshapes.faces.arkit.arkit_rig` as ARKit's ``eyeBlink_L``/``eyeBlink_R``
(:data:`ARKIT_ALIASES`), so a VRM face gets the paper's ``Blink`` slider and its eye regions.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from repro.errors import ModelError

__all__ = ["vrm_expressions", "VrmExpressions", "ARKIT_ALIASES", "MAX_BINDS"]

#: VRM expressions that mean an ARKit shape (for :func:`~repro.blendshapes.faces.arkit.arkit_rig`).
ARKIT_ALIASES = {"blink_l": "eyeBlink_L", "blink_r": "eyeBlink_R", "blinkLeft": "eyeBlink_L", "blinkRight": "eyeBlink_R"}
#: Morph-target binds read over all expressions of one file, at most (a real avatar has tens to hundreds).
MAX_BINDS = 20_000


@dataclass
class VrmExpressions:
    """A VRM file's expressions as sliders of the face read, and what was skipped."""

    version: str | None = None  #: "0.x", "1.0", or None when the file has no VRM extension
    sliders: dict[str, dict[str, float]] = field(default_factory=dict)
    aliases: dict[str, dict[str, float]] = field(default_factory=dict)  #: ARKit name -> combination
    notes: list[str] = field(default_factory=list)


def vrm_expressions(
    extensions, mesh_targets: Mapping[int, Sequence[str]], node_meshes: Sequence, shape_names: Sequence[str]
) -> VrmExpressions:
    """The expressions of a glTF document's VRM extension as sliders over the face's shapes.

    Parameters
    ----------
    extensions : dict or None
        The document's top-level ``extensions`` (parsed JSON).
    mesh_targets : mapping of int to sequence of str
        For each glTF mesh index read into the face, the face's shape name of each of its targets.
    node_meshes : sequence
        For each glTF node, its ``mesh`` index (or None): VRM 1.0 binds name nodes.
    shape_names : sequence of str
        Every shape of the face (a slider must not take a shape's name).

    Returns
    -------
    VrmExpressions
        ``version`` None (and nothing else) for a file without a VRM extension.
    """
    out = VrmExpressions()
    if not isinstance(extensions, Mapping):
        return out
    if "VRMC_vrm" in extensions:
        out.version = "1.0"
        if "VRM" in extensions:
            out.notes.append("VRM: the file has both the VRM 0.x and 1.0 extensions; the 1.0 expressions are read")
        raw = _expressions_1(extensions["VRMC_vrm"], out.notes)
    elif "VRM" in extensions:
        out.version = "0.x"
        raw = _expressions_0(extensions["VRM"], out.notes)
    else:
        return out
    if sum(len(binds) for _, binds, _ in raw) > MAX_BINDS:
        raise ModelError(f"the VRM {out.version} extension has more than {MAX_BINDS} morph-target binds; refusing")
    shapes = set(shape_names)
    for name, binds, scale in raw:
        combo = _combo(name, binds, scale, mesh_targets, node_meshes, out)
        if combo is None:
            continue
        if name in shapes:
            if combo == {name: 1.0}:
                out.notes.append(f"VRM expression {name!r} is the shape {name!r} at weight 1: no separate slider")
                continue
            out.notes.append(f"VRM expression {name!r} has the name of a shape: its slider is {name + '_expression'!r}")
            name = name + "_expression"
        if name in out.sliders:
            out.notes.append(f"VRM expression {name!r} appears twice: the second is skipped")
            continue
        out.sliders[name] = combo
        if name in ARKIT_ALIASES:
            out.aliases.setdefault(ARKIT_ALIASES[name], combo)
    return out


def _expressions_0(ext, notes: list[str]) -> list[tuple[str, list, float]]:
    """VRM 0.x ``blendShapeGroups`` as ``(slider name, binds, weight scale)``; binds ``(mesh, index, weight, what)``."""
    groups = ext.get("blendShapeMaster", {}).get("blendShapeGroups") if isinstance(ext, Mapping) and isinstance(
        ext.get("blendShapeMaster"), Mapping) else None
    if not isinstance(groups, list):
        notes.append("VRM 0.x: no blendShapeMaster.blendShapeGroups list: no expressions")
        return []
    raw = []
    for i, g in enumerate(groups):
        if not isinstance(g, Mapping):
            notes.append(f"VRM 0.x blendShapeGroups[{i}] is not an object: skipped")
            continue
        preset, name = g.get("presetName"), g.get("name")
        key = preset if isinstance(preset, str) and preset and preset != "unknown" else name
        if not isinstance(key, str) or not key:
            notes.append(f"VRM 0.x blendShapeGroups[{i}] has no presetName or name: skipped")
            continue
        binds = g.get("binds")
        if not isinstance(binds, list):
            binds = [] if binds is None else [binds]
        raw.append((key, [(b.get("mesh"), b.get("index"), b.get("weight"), "mesh") if isinstance(b, Mapping)
                          else (None, None, None, "mesh") for b in binds], 100.0))
    return raw


def _expressions_1(ext, notes: list[str]) -> list[tuple[str, list, float]]:
    """VRM 1.0 ``expressions.preset`` and ``.custom`` as ``(slider name, binds, weight scale)``."""
    expressions = ext.get("expressions") if isinstance(ext, Mapping) else None
    if not isinstance(expressions, Mapping):
        notes.append("VRM 1.0: no expressions object: no expressions")
        return []
    raw = []
    for section in ("preset", "custom"):
        items = expressions.get(section)
        if items is None:
            continue
        if not isinstance(items, Mapping):
            notes.append(f"VRM 1.0 expressions.{section} is not an object: skipped")
            continue
        for key, e in items.items():
            if not isinstance(e, Mapping) or not key:
                notes.append(f"VRM 1.0 expressions.{section}.{key} is not an expression object: skipped")
                continue
            binds = e.get("morphTargetBinds")
            if not isinstance(binds, list):
                binds = [] if binds is None else [binds]
            raw.append((str(key), [(b.get("node"), b.get("index"), b.get("weight"), "node") if isinstance(b, Mapping)
                                   else (None, None, None, "node") for b in binds], 1.0))
    return raw


def _combo(name, binds, scale, mesh_targets, node_meshes, out: VrmExpressions) -> dict[str, float] | None:
    """One expression's binds as ``{shape: coefficient}``; None (and a note) when none is usable."""
    combo: dict[str, float] = {}
    skipped: list[str] = []
    for ref, index, weight, kind in binds:
        mesh = ref
        if kind == "node":
            if not _is_index(ref) or ref >= len(node_meshes):
                skipped.append(f"node {ref!r} is not a node of the file")
                continue
            mesh = node_meshes[ref]
        if not _is_index(mesh) or mesh not in mesh_targets:
            skipped.append(f"{kind} {ref!r} is not part of the face read" + (f" (mesh {mesh})" if kind == "node" else ""))
            continue
        targets = mesh_targets[mesh]
        if not _is_index(index) or index >= len(targets):
            skipped.append(f"target index {index!r} of mesh {mesh} (it has {len(targets)} targets)")
            continue
        if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not math.isfinite(weight) \
                or not 0 <= weight <= scale:
            skipped.append(f"weight {weight!r} of target {index} is not a number in 0..{scale:g}")
            continue
        shape = targets[index]
        combo[shape] = combo.get(shape, 0.0) + float(weight) / scale
    if skipped:
        more = f" (and {len(skipped) - 1} more)" if len(skipped) > 1 else ""
        out.notes.append(f"VRM expression {name!r}: {len(skipped)} bind(s) skipped: {skipped[0]}{more}")
    if not combo:
        out.notes.append(f"VRM expression {name!r} has no usable morph-target bind: not a slider")
        return None
    if not any(combo.values()):
        out.notes.append(f"VRM expression {name!r} binds its targets at weight 0 only: not a slider")
        return None
    return combo


def _is_index(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool) and x >= 0
