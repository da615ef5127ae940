"""The paper's editing scenarios and the numbers each figure reports about them.

Lewis et al. 2005 illustrate interference and its attenuation with a handful of
slider sessions.  Each :class:`Scenario` is one of them, written with the
paper's slider names so it runs on any model that has those names as shapes or
named combinations (the procedural face and the ICT model both do):

- ``eyelid_then_brow`` (Fig. 1): the eyelids are partially closed, then the
  brows are raised, and the eyelid moves as a side effect.
- ``furrow_then_mouth`` (Figs. 2-3): ``Furrow`` = 0.4 positions the middle of
  the brow; further moves, mostly of the mouth, keep moving it.  Two brow
  vertices are selected (Fig. 3a).
- ``smirk_corners_y`` (Fig. 4): only the y coordinates of the two mouth
  corners are selected; ``SmirkLeft`` and ``SmirkRight`` go to 0.7.
- ``wince_sneer_under_eye`` (Fig. 5): six vertices below the eye are
  selected; ``Wince``, ``SneerLeft``, ``SneerRight`` go to 0.7.

The workflow is Section 5's: the animator reaches ``w_base``, selects, moves
the sliders to ``w_target``; with attenuation on the change ``w_target -
w_base`` is replaced by ``w2`` of Eq. (3).  :func:`evaluate` measures one such
session; :func:`compare_methods` puts attenuation beside the two alternatives
Section 3 rejects; :func:`alpha_sweep` and :func:`axis_table` give the numbers
of Fig. 5 and Fig. 4.

A session needs what it names (the region, the sliders) and something to show:
on a face whose shapes are local (a Ready Player Me head: the mouth shapes
leave the brow exactly still) the further moves may not move the selection at
all, and every ratio to the unattenuated motion would be 0/0.  Such a session
does not apply to the face: :meth:`Scenario.not_applicable` says why, and every
function here raises that reason as a :class:`~repro.errors.ModelError` instead
of returning NaN.  :func:`default_sliders` is what a face offers an animator:
the paper's sliders (:data:`PAPER_SLIDERS`) when it can play one of these
sessions, its own controls (a VRM's expressions, then its shapes) otherwise.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from repro.blendshapes import metrics
from repro.blendshapes.alternatives import edit_orthogonal, edit_zeroed
from repro.blendshapes.attenuation import Attenuator, check_alpha, select_vertices
from repro.checks import as_int, as_real, as_real_array, as_str, describe
from repro.blendshapes.model import AXES, BlendshapeModel
from repro.errors import ModelError

__all__ = [
    "Scenario",
    "SCENARIOS",
    "PAPER_SLIDERS",
    "scenario",
    "default_sliders",
    "evaluate",
    "compare_methods",
    "alpha_sweep",
    "axis_table",
    "interference",
]


@dataclass(frozen=True)
class Scenario:
    """One editing session of the paper: a pose to keep, a selection, further slider moves."""

    key: str
    figure: str
    description: str
    region: str  #: preset vertex region of the model (``model.regions``) to select
    moves: Mapping[str, float]  #: further slider values, added on top of ``base``
    base: Mapping[str, float] = field(default_factory=dict)  #: sliders set before the selection
    axes: str = "xyz"  #: which coordinates of the region's vertices are selected
    #: when > 0, select only this many vertices of the region: those the base pose moved most
    #: (the animator tags what the first move positioned)
    top_moved: int = 0

    def __post_init__(self) -> None:
        for f in ("key", "figure", "description", "region", "axes"):
            as_str(getattr(self, f), f"Scenario.{f}", error=ModelError)
        for f in ("moves", "base"):
            if not isinstance(getattr(self, f), Mapping):
                raise ModelError(f"Scenario.{f} must be a mapping of slider name to value, got {describe(getattr(self, f))}")
            for k, v in getattr(self, f).items():  # a NaN here became NaN weights later
                as_str(k, f"a slider name of Scenario.{f}", error=ModelError)
                as_real(v, f"Scenario.{f}[{k!r}]", error=ModelError)
        as_int(self.top_moved, "Scenario.top_moved", lo=0, error=ModelError)

    def vertices(self, model: BlendshapeModel) -> np.ndarray:
        """Vertex ids this scenario selects on ``model``."""
        _check_model(model)
        if self.region not in model.regions:
            raise ModelError(
                f"scenario {self.key!r} needs region {self.region!r}, which model {model.name!r} "
                f"does not define; its regions are {sorted(model.regions)}"
            )
        verts = np.asarray(model.regions[self.region])
        if self.top_moved:
            moved = np.linalg.norm(model.displacement(model.weights(self.base))[verts], axis=1)
            order = np.lexsort((verts, -moved))  # most moved first; ties by vertex id
            verts = np.sort(verts[order[: self.top_moved]])
        return verts

    def selection(self, model: BlendshapeModel) -> np.ndarray:
        """Rows of ``D`` this scenario selects on ``model``."""
        return select_vertices(self.vertices(model), self.axes, model.n_vertices)

    def weights(self, model: BlendshapeModel) -> tuple[np.ndarray, np.ndarray]:
        """``(w_base, w_target)``: the pose kept, and the sliders after the further moves."""
        _check_model(model)
        w_base = model.weights(self.base)
        return w_base, w_base + model.weights(self.moves)

    def lockable_shapes(self, model: BlendshapeModel) -> np.ndarray:
        """Shapes an animator would lock for orthogonal locking: those that made the base pose."""
        _check_model(model)
        return np.flatnonzero(model.weights(self.base))

    def not_applicable(self, model: BlendshapeModel) -> str | None:
        """Why this session cannot run on ``model``, in words; None when it can.

        It cannot when the face lacks the region or a slider the session names; when the
        first move (``base``) leaves every selected vertex where it was (nothing was
        positioned to keep); when the further moves leave every selected coordinate
        still: there is no interference to attenuate (Figs. 2-3), and the selected motion
        left by Eq. (3), as a fraction of the unattenuated one, would be 0/0; or when they
        move nothing else (the unselected fidelity would be 0/0).
        """
        _check_model(model)
        if self.region not in model.regions:
            return f"it needs region {self.region!r}, which the face does not define; its regions are {sorted(model.regions)}"
        missing = [s for s in (*self.base, *self.moves) if s not in model.slider_names]
        if missing:
            return f"it needs the sliders {missing}, which the face does not have"
        sel = self.selection(model)
        w_base, w_target = self.weights(model)
        d_base, d_target = model.displacement(w_base).ravel(), model.displacement(w_target).ravel()
        if self.base and not d_base.reshape(-1, 3)[np.unique(sel // 3)].any():
            return (f"its first move ({_listed(self.base)}) leaves the selected vertices of {self.region!r} "
                    "where they were: nothing is positioned to keep")
        moved = d_target != d_base
        if not moved[sel].any():
            return (f"its further moves ({_listed(self.moves)}) leave the selected {self.axes} coordinates of "
                    f"{self.region!r} exactly still: there is no interference to attenuate on this face")
        moved[sel] = False
        if not moved.any():
            return (f"its further moves ({_listed(self.moves)}) move only the selected coordinates: "
                    "there is no rest of the face to follow them")
        return None

    def check(self, model: BlendshapeModel) -> None:
        """Raise :class:`~repro.errors.ModelError` with :meth:`not_applicable`'s reason when the session cannot run."""
        why = self.not_applicable(model)
        if why is not None:
            raise ModelError(f"scenario {self.key!r} ({self.figure}) does not apply to model {model.name!r}: {why}")


def _listed(sliders: Mapping[str, float]) -> str:
    return ", ".join(f"{k} {v:g}" for k, v in sliders.items()) or "none"


SCENARIOS: dict[str, Scenario] = {
    s.key: s
    for s in [
        Scenario(
            "eyelid_then_brow", "Fig. 1",
            "eyelids half closed (Blink 0.5), then the brows raised (BrowUp 0.8): the eyelid moves too",
            region="left_eye", top_moved=6, base={"Blink": 0.5}, moves={"BrowUp": 0.8},
        ),
        Scenario(
            "furrow_then_mouth", "Figs. 2-3",
            "Furrow 0.4 positions the brow; mouth moves (JawOpen 0.4, SmirkLeft/Right 0.4, "
            "MouthStretch 0.3) follow; the two brow-middle vertices are selected",
            region="brow_middle", base={"Furrow": 0.4},
            moves={"JawOpen": 0.4, "SmirkLeft": 0.4, "SmirkRight": 0.4, "MouthStretch": 0.3},
        ),
        Scenario(
            "smirk_corners_y", "Fig. 4",
            "the y coordinates of the two mouth corners are selected; SmirkLeft and SmirkRight go to 0.7",
            region="mouth_corners", axes="y", moves={"SmirkLeft": 0.7, "SmirkRight": 0.7},
        ),
        Scenario(
            "wince_sneer_under_eye", "Fig. 5",
            "six vertices below the left eye are selected; Wince, SneerLeft, SneerRight go to 0.7",
            region="under_left_eye", moves={"Wince": 0.7, "SneerLeft": 0.7, "SneerRight": 0.7},
        ),
    ]
}


#: The sliders the paper names (Figs. 2-5): those its scenarios move, in the order a panel shows them.
PAPER_SLIDERS = (
    "Furrow", "SmirkLeft", "SmirkRight", "Wince", "SneerLeft", "SneerRight",
    "JawOpen", "Blink", "BrowUp", "MouthStretch",
)


def default_sliders(model: BlendshapeModel) -> tuple[str, ...]:
    """The sliders ``model`` offers an animator first (Section 5's panel), in order.

    The paper's sliders the face has (:data:`PAPER_SLIDERS`), when it can play one of the
    paper's sessions (:meth:`Scenario.not_applicable` is None for one of :data:`SCENARIOS`).
    Otherwise those few cannot move the face, and its own controls follow: its other named
    sliders in their order (a VRM avatar's expressions), then every shape that no slider
    offered so far moves (a target no expression binds), so that all of the face can move.
    """
    _check_model(model)
    paper = tuple(s for s in PAPER_SLIDERS if s in model.slider_names)
    if any(sc.not_applicable(model) is None for sc in SCENARIOS.values()):
        return paper
    offered = paper + tuple(s for s in model.sliders if s not in paper)
    reached = {s for s in offered if s in model.names}
    reached.update(shape for s in offered if s in model.sliders for shape, c in model.sliders[s].items() if c)
    return offered + tuple(s for s in model.names if s not in reached)


def scenario(key: str) -> Scenario:
    """The scenario named ``key`` (see :data:`SCENARIOS`)."""
    if isinstance(key, str) and key in SCENARIOS:
        return SCENARIOS[key]
    raise ModelError(f"unknown scenario {describe(key)}; known: {sorted(SCENARIOS)}")


def _scenario(sc) -> Scenario:
    if isinstance(sc, Scenario):
        return sc
    if isinstance(sc, str):
        return scenario(sc)
    raise ModelError(f"expected a Scenario or a scenario name, got {describe(sc)}; known: {sorted(SCENARIOS)}")


def _check_model(model) -> BlendshapeModel:
    if not isinstance(model, BlendshapeModel):
        raise ModelError(f"expected a BlendshapeModel, got {describe(model)}")
    return model


def _alpha(att: Attenuator, sel: np.ndarray, alpha) -> float:
    return att.default_alpha(sel) if alpha is None else check_alpha(alpha, sel.size, att.n_rows)


def _attenuator(model: BlendshapeModel, att: Attenuator | None) -> Attenuator:
    _check_model(model)
    if att is not None and not isinstance(att, Attenuator):
        raise ModelError(f"attenuator must be an Attenuator or None, got {describe(att)}")
    if att is None:
        return Attenuator(model)
    if att.model is not model:
        raise ModelError("the Attenuator given was built for another model")
    return att


def _measure(model, d, d_base, d_target, sel) -> dict:
    selected_vertices = np.unique(sel // 3)
    motion = metrics.per_vertex_motion(d, d_base)[selected_vertices]
    return {
        "selected_motion": metrics.selected_motion(d, sel, d_base),
        "selected_max_vertex_motion": float(motion.max()),
        "unselected_fidelity": metrics.unselected_fidelity(d, d_target, sel, d_base),
        "unselected_error": metrics.unselected_error(d, d_target, sel),
        "roughness": metrics.roughness(model, d) if len(model.faces) else float("nan"),
        # the tear Section 3 predicts for zeroed rows: roughness of the motion since the
        # selection, at the selected vertices and their neighbours
        "roughness_at_selection": (
            metrics.roughness_near(model, d - d_base, selected_vertices) if len(model.faces) else float("nan")
        ),
    }


def evaluate(model: BlendshapeModel, sc: Scenario | str, alpha=None, *, attenuator: Attenuator | None = None) -> dict:
    """Numbers of one session with and without attenuation (Figs. 3-5).

    Returns a flat dict: the selection size, the ``alpha`` used (Section 5's
    default when None), and for ``none`` (no attenuation) and ``attenuated``:
    ``selected_motion`` (``||S (d - d_base)||`` since the selection),
    ``selected_max_vertex_motion``, ``unselected_fidelity`` (1 = the rest moves
    as the sliders intend), ``unselected_error``, ``roughness`` (largest
    Laplacian magnitude of the displacement) and ``roughness_at_selection``
    (the same, of the motion since the selection, at the selected vertices and
    their neighbours; both NaN for a model without triangles).  ``reduction`` is
    attenuated over unattenuated selected motion.  A session that does not apply
    to the face (:meth:`Scenario.not_applicable`) is a :class:`~repro.errors.ModelError`
    saying why, here and in the other functions of this module.
    """
    sc = _scenario(sc)
    att = _attenuator(model, attenuator)
    sc.check(model)
    sel = sc.selection(model)
    w_base, w_target = sc.weights(model)
    a = _alpha(att, sel, alpha)
    w2 = att.edit(w_base, w_target, sel, a)
    d_base, d_target, d_att = att.displacement(w_base), att.displacement(w_target), att.displacement(w2)
    out = {
        "model": model.name,
        "scenario": sc.key,
        "figure": sc.figure,
        "n_selected_vertices": int(np.unique(sel // 3).size),
        "n_selected_coordinates": int(sel.size),
        "alpha": a,
        "default_alpha": att.default_alpha(sel),
    }
    none = _measure(model, d_target, d_base, d_target, sel)
    attd = _measure(model, d_att, d_base, d_target, sel)
    out.update({f"none_{k}": v for k, v in none.items()})
    out.update({f"attenuated_{k}": v for k, v in attd.items()})
    out["reduction"] = attd["selected_motion"] / none["selected_motion"]  # > 0: sc.check
    return out


def compare_methods(model: BlendshapeModel, sc: Scenario | str, alpha=None, *, attenuator: Attenuator | None = None) -> list[dict]:
    """Attenuation beside Section 3's rejected alternatives, on one session.

    Methods: ``none`` (the sliders as moved), ``attenuation`` (Eq. 3),
    ``zeroed_rows`` (the selected rows of D set to zero) and
    ``orthogonal_lock`` (the shapes that made the base pose locked, the others
    projected orthogonal to them; not applicable when the base pose is empty).
    Each row has the metrics of :func:`evaluate` for that method.
    """
    sc = _scenario(sc)
    att = _attenuator(model, attenuator)
    sc.check(model)
    sel = sc.selection(model)
    w_base, w_target = sc.weights(model)
    d_base, d_target = att.displacement(w_base), att.displacement(w_target)
    a = _alpha(att, sel, alpha)
    candidates = {
        "none": d_target,
        "attenuation": att.displacement(att.edit(w_base, w_target, sel, a)),
        "zeroed_rows": edit_zeroed(model.D, w_base, w_target, sel),
    }
    locked = sc.lockable_shapes(model)
    rows = []
    for method, d in candidates.items():
        rows.append({"model": model.name, "scenario": sc.key, "method": method, "applicable": True,
                     **_measure(model, d, d_base, d_target, sel)})
    if locked.size and locked.size < model.n_shapes:
        d = edit_orthogonal(model.D, w_base, w_target, locked)
        rows.append({"model": model.name, "scenario": sc.key, "method": "orthogonal_lock", "applicable": True,
                     **_measure(model, d, d_base, d_target, sel)})
    else:
        rows.append({"model": model.name, "scenario": sc.key, "method": "orthogonal_lock", "applicable": False,
                     **{k: float("nan") for k in _measure(model, d_target, d_base, d_target, sel)}})
    return rows


def alpha_sweep(model: BlendshapeModel, sc: Scenario | str, alphas: Iterable[float], *, attenuator: Attenuator | None = None) -> list[dict]:
    """Selected motion and unselected fidelity for each alpha (Section 5, Fig. 5).

    Also ``w_change_vs_w1`` = ``||w2 - w1|| / ||w1||`` and
    ``selected_motion_fraction`` (= :func:`evaluate`'s ``reduction``), the two
    quantities whose limits Section 5 discusses: alpha -> 0 gives w2 -> w1,
    alpha -> infinity gives S w2 -> 0.
    """
    sc = _scenario(sc)
    att = _attenuator(model, attenuator)
    if isinstance(alphas, (str, bytes)) or not isinstance(alphas, Iterable) or (
        isinstance(alphas, np.ndarray) and alphas.ndim == 0  # iterable by type, not by value
    ):
        raise ModelError(f"alphas must be an iterable of numbers > 0, got {describe(alphas)}")
    if not isinstance(alphas, np.ndarray):
        alphas = list(alphas)  # a generator, once
    # numbers, all of them before the first solve (each is then checked as Eq. 2's alpha)
    alphas = as_real_array(alphas, "alphas", ndim=1, finite=False, error=ModelError)
    sc.check(model)
    sel = sc.selection(model)
    w_base, w_target = sc.weights(model)
    w1 = w_target - w_base
    d_base, d_target = att.displacement(w_base), att.displacement(w_target)
    none = metrics.selected_motion(d_target, sel, d_base)
    w1_norm = float(np.linalg.norm(w1))
    rows = []
    for a in alphas:
        w2 = att.attenuate(w1, sel, a)
        d = d_base + att.displacement(w2)
        m = _measure(model, d, d_base, d_target, sel)
        rows.append({
            "model": model.name, "scenario": sc.key, "alpha": float(a),
            "default_alpha": att.default_alpha(sel),
            "selected_motion": m["selected_motion"],
            "selected_motion_fraction": m["selected_motion"] / none,  # none > 0 and w1_norm > 0: sc.check
            "unselected_fidelity": m["unselected_fidelity"],
            "unselected_error": m["unselected_error"],
            "w_change_vs_w1": float(np.linalg.norm(w2 - w1) / w1_norm),
        })
    return rows


def axis_table(model: BlendshapeModel, sc: Scenario | str, alpha=None, *, attenuator: Attenuator | None = None) -> list[dict]:
    """x/y/z displacement of each selected vertex with and without attenuation (Fig. 4)."""
    sc = _scenario(sc)
    att = _attenuator(model, attenuator)
    sc.check(model)
    sel = sc.selection(model)
    w_base, w_target = sc.weights(model)
    a = _alpha(att, sel, alpha)
    d_base = att.displacement(w_base).reshape(-1, 3)
    poses = {
        "none": att.displacement(w_target).reshape(-1, 3),
        "attenuated": att.displacement(att.edit(w_base, w_target, sel, a)).reshape(-1, 3),
    }
    selected_axes = {AXES[r % 3] for r in sel}
    rows = []
    for v in np.unique(sel // 3):
        for method, d in poses.items():
            delta = d[v] - d_base[v]
            rows.append({"model": model.name, "scenario": sc.key, "vertex": int(v), "method": method,
                         "alpha": a if method == "attenuated" else float("nan"),
                         "dx": delta[0], "dy": delta[1], "dz": delta[2],
                         "selected_axes": "".join(sorted(selected_axes))})
    return rows


def interference(model: BlendshapeModel, sc: Scenario | str) -> dict:
    """How far the further moves drag the region the first move positioned (Figs. 1-2).

    ``drift`` is the per-vertex motion (n,) caused by the further moves alone;
    the returned numbers compare the drift of the selected vertices with the
    motion the first move gave them, so a session without a first move
    (``base``), or one that does not apply to the face (:meth:`Scenario.check`),
    is a :class:`~repro.errors.ModelError`.
    """
    sc = _scenario(sc)
    _check_model(model)
    if not sc.base:
        raise ModelError(f"scenario {sc.key!r} ({sc.figure}) has no first move (base): interference is the drag "
                         "of what a first move positioned; its sessions are those with a base pose")
    sc.check(model)
    sel = sc.selection(model)
    verts = np.unique(sel // 3)
    w_base, w_target = sc.weights(model)
    d_base = (model.D @ w_base).reshape(-1, 3)
    d_target = (model.D @ w_target).reshape(-1, 3)
    drift = np.linalg.norm(d_target - d_base, axis=1)
    first = np.linalg.norm(d_base, axis=1)
    first_move = float(first[verts].mean())
    return {
        "model": model.name,
        "scenario": sc.key,
        "figure": sc.figure,
        "units": model.units,
        "first_move_selected": first_move,
        "drift_selected_mean": float(drift[verts].mean()),
        "drift_selected_max": float(drift[verts].max()),
        "drift_selected_dy": float((d_target - d_base)[verts, 1].mean()),
        "drift_relative": float(drift[verts].mean() / first_move),  # first_move > 0: sc.check
        "drift": drift,
    }

