"""Vertices picked on the face's 3D view (Lewis et al. 2005, Section 5: the animator "selects vertices").

The paper's animator marks the vertices that must stay; the panel's preset regions and x/y/z
boxes stay, and picking adds a selection of the user's own: in the browser view
(:class:`repro.ui.webview.MeshWebView`) a click adds the nearest visible vertex, a drag brushes
every visible vertex it passes over (in pick mode, or with Shift held), and the ``c`` or
``Delete`` key (or the view's "clear" button) empties the selection.  The picked vertices
are the panel's region :data:`PICKED`, selected through the same ``select_vertices`` as the
presets, so they are Eq. 3's ``S`` exactly as a preset would be.

Transport: the page writes each pick into a hidden ``ipywidgets.Text`` of the view (its
``change`` event sends the value to the kernel), one message per stroke part:
``"<seq> add <v> <v> ..."`` or ``"<seq> clear"``, ``seq`` increasing (the page's clock in
ms).  :func:`parse_pick` reads one; the view's next frame carries the ``seq`` handled, so the
page stops drawing its own marks for the picks the kernel has drawn.
"""

from __future__ import annotations

import re
from typing import NamedTuple

import numpy as np

from repro.errors import SelectionError

__all__ = ["PICKED", "Pick", "VertexPicks", "parse_pick"]

#: The region name of the picked vertices in the panel's region chooser.
PICKED = "picked on the face"

_MESSAGE = re.compile(r"(\d{1,16}) (?:(clear)|add((?: \d{1,9})+))")
#: The longest message read (a brush over every vertex of the ICT face takes about 170 KB).
MAX_MESSAGE = 1 << 20


class Pick(NamedTuple):
    """One message of the page: its sequence number, ``"add"`` or ``"clear"``, the vertex ids added."""

    seq: int
    action: str
    vertices: np.ndarray


def parse_pick(text: str, n_vertices: int) -> Pick:
    """A pick message of the page (``"<seq> add <v> ..."`` or ``"<seq> clear"``); SelectionError for anything else."""
    m = _MESSAGE.fullmatch(text.strip()) if isinstance(text, str) and len(text) <= MAX_MESSAGE else None
    if m is None:
        raise SelectionError(f"not a pick message of the face view: {str(text)[:80]!r}")
    if m.group(2):
        return Pick(int(m.group(1)), "clear", np.zeros(0, dtype=np.int64))
    v = np.unique(np.array(m.group(3).split(), dtype=np.int64))
    if v.max() >= n_vertices:
        raise SelectionError(f"picked vertex {int(v.max())} is not on the face (vertices 0..{n_vertices - 1})")
    return Pick(int(m.group(1)), "add", v)


class VertexPicks:
    """The picked vertices of a face of ``n_vertices``: a sorted set of ids, and the last message handled."""

    def __init__(self, n_vertices: int):
        self.n_vertices = int(n_vertices)
        self.vertices = np.zeros(0, dtype=np.int64)
        self.seq = 0

    def add(self, vertices, start=None) -> None:
        """Add vertex ids; ``start`` (e.g. the preset region shown when picking began) replaces the set first."""
        v = np.asarray(vertices, dtype=np.int64).ravel()
        if v.size and (v.min() < 0 or v.max() >= self.n_vertices):
            raise SelectionError(f"picked vertices must be ids in 0..{self.n_vertices - 1}")
        base = self.vertices if start is None else np.asarray(start, dtype=np.int64).ravel()
        self.vertices = np.union1d(base, v)

    def clear(self) -> None:
        self.vertices = np.zeros(0, dtype=np.int64)

    def take(self, text: str) -> Pick | None:
        """Read a message of the page; None for one already handled (an older ``seq``)."""
        pick = parse_pick(text, self.n_vertices)
        if pick.seq <= self.seq:
            return None
        self.seq = pick.seq
        return pick
