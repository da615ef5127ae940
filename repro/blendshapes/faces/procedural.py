"""An embedded procedural face: a small delta blendshape model built in code.

Lewis et al. (2005) show their attenuation on a professionally sculpted model
(Landreth's "Bingo", Figs. 2-5) that is not available.  This module builds a
stand-in that needs no data file and exhibits the same *kinds* of blendshape
interference, so every figure of the paper can be reproduced and tested
offline.  The real scanned ICT face model is used separately
(:mod:`repro.blendshapes.faces.ict`).

The face
--------
The neutral face ``f0`` is a height field ``z(x, y)`` over a structured grid of
``n_rows x n_cols`` vertices (48 x 42 = 2,016 by default): a paraboloidal
"head" patch plus smooth Gaussian features - forehead bulge, brow ridge,
glabella, eye sockets with eyelid bulges, nose ridge, tip and wings, cheek
bones, nasolabial grooves, lips with a mouth line, the fold above the chin, and
the chin.  Each grid cell is split into two triangles (diagonals mirrored about
the midline, counter-clockwise seen from +z), so the mesh is one connected
disc that can be rendered and on which edge lengths and Laplacians between
neighbours are meaningful.

Axes and units: the face looks toward **+z**, **+y** is up and **+x** is the
subject's left, so ``...Left`` shapes move the +x side.  Lengths are in
"model units"; one unit is meant as about one centimetre: the patch is 17.5
units wide (x in [-8.75, 8.75]) and 20 units tall (y in [-10, 10], chin to
hairline), eyes at ``x = +-3.2, y = 1.6``, brows at ``y = 3.4``, nose tip at
``y = -2.6``, mouth line at ``y = -5.75`` with corners at ``x = +-2.35``.

The shapes
----------
27 delta shapes (columns of ``D``), each a smooth displacement field: sums of
Gaussian "bumps" times a 3-vector, and for ``JawOpen`` a linearised rotation
of the lower face about a hinge behind the face, blended in with a smooth
mask.  Every bump is at least about one default grid spacing wide, so
neighbouring vertices move together: at 2,016 vertices the displacement
changes along an edge by less than the edge's length, for every shape but
``JawOpen``, which opens the mouth on a mesh without a lip split and so
stretches the row of edges across the mouth line.  ``...Right`` shapes are
exact mirror images of ``...Left`` ones (they are evaluated from the same
formula with ``x -> -x``).  Weight 1 is a full expression; peak displacements
are about 0.5 to 2.3 units.  The shapes are linearly independent (``D`` has
full column rank, condition number about 175).

Sculpted interference (what each overlap is there for)
------------------------------------------------------
* **Fig. 1** (eyelid disturbed by a brow slider): ``BrowUpLeft/Right`` also
  lift the upper eyelid a little, ``BrowDownLeft/Right`` push it down.
* **Figs. 2-3** (brow keeps furrowing as the mouth is posed): ``Furrow`` pulls
  the inner brows down and together; ``JawOpen``, ``MouthStretchLeft/Right``
  and ``SmirkLeft/Right`` each also drag the middle of the brow slightly
  down, the way the skin slides on real scanned shapes.  Region
  ``"brow_middle"`` (two vertices straddling the midline between the brows) is
  the Fig. 3 selection.
* **Fig. 4** (y of the mouth corners held, x free): ``SmirkLeft/Right`` move
  each mouth corner out (x), up (y) and back (z), and push the cheek up.
  ``MouthFrownLeft/Right`` (mostly -y) and ``MouthStretchLeft/Right``
  (mostly x) let the y motion be cancelled while x remains.  Region
  ``"mouth_corners"`` is the Fig. 4 selection.
* **Fig. 5** (six vertices below the eye): ``Wince`` squeezes both eyes and
  lifts the upper cheeks, and ``SneerLeft/Right`` raise the nose wing, the
  upper lip *and the region under the eye* on their side, so together at 0.7
  they move the six vertices of ``"under_left_eye"`` substantially, while
  also moving the mouth.  ``EyeSquintLeft/Right`` act on the same under-eye
  area without touching the mouth, which gives the attenuation room to hold
  the selection while the mouth still moves.  With 2,016 vertices and 6
  selected, the paper's default ``alpha = (2016 - 6) / 6 = 335``.

Measured at 2,016 vertices (and asserted, with margins, by
``tests/blendshapes/faces/test_procedural.py``): ``Furrow`` = 0.4 moves each ``brow_middle``
vertex 0.35 units (0.31 down); then ``JawOpen`` 0.5, ``Smirk*`` 0.4 and
``MouthStretch*`` 0.3 move them 0.14 further down (40% of Furrow's move).
``SmirkLeft`` = ``SmirkRight`` = 0.7 moves the mouth corners 0.55 out and
0.60 up.  ``Wince`` = ``SneerLeft`` = ``SneerRight`` = 0.7 moves the six
``under_left_eye`` vertices 0.59-0.67 units.  Eq. (3) with the default alpha
cuts those selected motions by 95-97% while keeping 95-100% of the mouth
motion (Figs. 3 and 5), and with only the corners' y selected keeps their x
motion (Fig. 4).

Sizes other than 2,016
----------------------
``procedural_model(n)`` builds the same face (same physical size, shapes,
names, sliders and regions) sampled more or less finely, for benchmarks.  The
grid ``n_rows x n_cols`` is chosen with an aspect near 8:7 and as few extra
grid points as possible (exact factorisations are preferred, e.g.
26,712 = 168 x 159); any surplus ``k < n_cols`` grid points are trimmed from
the four corners of the patch (ends of the top and bottom rows), so the vertex
count is always exactly ``n``.  Broad regions are defined by physical areas
and scale with ``n``; the point-like presets keep their meaning: two vertices
at the middle of the brow, the two mouth corners, and exactly six vertices
under the left eye (a 3 x 2 block, spread over the same physical patch as at
2,016 vertices).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from repro.checks import as_int
from repro.blendshapes.model import BlendshapeModel
from repro.errors import ModelError

__all__ = [
    "procedural_model",
    "procedural_grid_shape",
    "PROCEDURAL_SHAPES",
    "PROCEDURAL_REGIONS",
    "DEFAULT_N_VERTICES",
    "MIN_N_VERTICES",
    "MAX_N_VERTICES",
]

#: Default vertex count: 48 x 42, so that 6 selected vertices give alpha = 335 (Fig. 5).
DEFAULT_N_VERTICES = 2016
#: Smallest supported size (25 x 20 vertices, about 0.9 units apart).
MIN_N_VERTICES = 500
#: Largest supported size (D then takes about 650 MB).
MAX_N_VERTICES = 1_000_000

# Physical layout (model units ~ cm).
_WIDTH, _HEIGHT = 17.5, 20.0
_ASPECT = 8.0 / 7.0  # rows : columns, so that 48 x 42 = 2016
_EYE_X, _EYE_Y = 3.2, 1.6
_BROW_Y = 3.4
_MOUTH_Y, _CORNER_X = -5.75, 2.35
_UPPER_LIP_Y, _LOWER_LIP_Y = -5.32, -6.17
_BROW_MIDDLE_Y = 3.2
_UNDER_EYE = (3.2, 0.42)  # centre of the Fig. 5 patch (between two grid rows at 2016)
# default grid spacing: the physical pitch of the point-like regions at any size
_DX0, _DY0 = _WIDTH / 41, _HEIGHT / 47

#: Shape names, in column order of ``D``.
PROCEDURAL_SHAPES = (
    "Furrow",
    "BrowInnerUp",
    "BrowUpLeft",
    "BrowUpRight",
    "BrowDownLeft",
    "BrowDownRight",
    "BlinkLeft",
    "BlinkRight",
    "EyeWideLeft",
    "EyeWideRight",
    "EyeSquintLeft",
    "EyeSquintRight",
    "SneerLeft",
    "SneerRight",
    "Wince",
    "CheekPuff",
    "JawOpen",
    "MouthPucker",
    "MouthFunnel",
    "MouthStretchLeft",
    "MouthStretchRight",
    "SmirkLeft",
    "SmirkRight",
    "MouthFrownLeft",
    "MouthFrownRight",
    "LipUpperUp",
    "LipLowerDown",
)

#: Region presets (vertex-id arrays in the model's ``regions``).
PROCEDURAL_REGIONS = (
    "brow_middle",
    "mouth_corners",
    "under_left_eye",
    "under_right_eye",
    "forehead",
    "brow",
    "left_eye",
    "right_eye",
    "nose",
    "cheeks",
    "mouth",
    "jaw",
)

_SLIDERS = {
    "BrowUp": {"BrowUpLeft": 1.0, "BrowUpRight": 1.0},
    "BrowDown": {"BrowDownLeft": 1.0, "BrowDownRight": 1.0},
    "Blink": {"BlinkLeft": 1.0, "BlinkRight": 1.0},
    "EyeWide": {"EyeWideLeft": 1.0, "EyeWideRight": 1.0},
    "EyeSquint": {"EyeSquintLeft": 1.0, "EyeSquintRight": 1.0},
    "Sneer": {"SneerLeft": 1.0, "SneerRight": 1.0},
    "Smile": {"SmirkLeft": 1.0, "SmirkRight": 1.0},
    "MouthStretch": {"MouthStretchLeft": 1.0, "MouthStretchRight": 1.0},
    "MouthFrown": {"MouthFrownLeft": 1.0, "MouthFrownRight": 1.0},
}


# ---------------------------------------------------------------- the grid
def _check_n(n_vertices) -> int:
    n = as_int(n_vertices, "n_vertices", error=ModelError)
    if not MIN_N_VERTICES <= n <= MAX_N_VERTICES:
        raise ModelError(
            f"n_vertices must be in {MIN_N_VERTICES}..{MAX_N_VERTICES} "
            f"(default {DEFAULT_N_VERTICES}), got {n}"
        )
    return n


def procedural_grid_shape(n_vertices: int = DEFAULT_N_VERTICES) -> tuple[int, int, int]:
    """Grid used for ``n_vertices``: ``(n_rows, n_cols, n_trimmed)``.

    Among column counts within 4% of ``sqrt(n_vertices * 7 / 8)`` (a grid aspect
    near 8:7), the one leaving the fewest
    surplus grid points ``n_trimmed = n_rows * n_cols - n_vertices`` (then the
    aspect closest to 8:7) is chosen; the surplus, always smaller than
    ``n_cols``, is cut from the corners of the patch.

    Parameters
    ----------
    n_vertices : int
        Vertex count, ``MIN_N_VERTICES <= n_vertices <= MAX_N_VERTICES``.

    Returns
    -------
    (int, int, int)
        Rows (along y), columns (along x) and grid points removed.

    Raises
    ------
    ModelError
        If ``n_vertices`` is not an integer in the supported range.

    Examples
    --------
    >>> procedural_grid_shape(2016)
    (48, 42, 0)
    >>> procedural_grid_shape(26712)
    (168, 159, 0)
    """
    n = _check_n(n_vertices)
    c0 = math.sqrt(n / _ASPECT)
    best = None
    for nc in range(max(2, math.floor(0.96 * c0)), math.ceil(1.04 * c0) + 1):
        nr = -(-n // nc)
        k = nr * nc - n
        key = (k, abs(math.log(nr / nc / _ASPECT)))
        if best is None or key < best[0]:
            best = (key, nr, nc, k)
    _, nr, nc, k = best
    return nr, nc, k


def _grid(nr: int, nc: int, k: int):
    """Kept grid points, their (row, col) and the triangles, re-indexed."""
    keep = np.ones((nr, nc), dtype=bool)
    # trim k surplus points from the four corners (bottom-left, bottom-right, top-left, top-right)
    q, rem = divmod(k, 4)
    cut = [q + (i < rem) for i in range(4)]
    if cut[0]:
        keep[-1, : cut[0]] = False
    if cut[1]:
        keep[-1, nc - cut[1] :] = False
    if cut[2]:
        keep[0, : cut[2]] = False
    if cut[3]:
        keep[0, nc - cut[3] :] = False
    new_id = np.full((nr, nc), -1, dtype=np.int64)
    new_id[keep] = np.arange(np.count_nonzero(keep))
    rows, cols = np.nonzero(keep)

    a = new_id[:-1, :-1]  # top-left of each cell
    b = new_id[:-1, 1:]  # top-right
    c = new_id[1:, :-1]  # bottom-left
    d = new_id[1:, 1:]  # bottom-right
    # diagonal a-d on the +x half, b-c on the -x half: the mesh is mirror-symmetric
    # except for the one column of cells straddling x = 0 when nc is even
    cell_x = (np.arange(nc - 1) + 0.5) - (nc - 1) / 2
    ad = np.broadcast_to(cell_x >= 0, a.shape)
    t1 = np.where(ad[..., None], np.stack([a, c, d], -1), np.stack([a, c, b], -1))
    t2 = np.where(ad[..., None], np.stack([a, d, b], -1), np.stack([b, c, d], -1))
    tri = np.concatenate([t1.reshape(-1, 3), t2.reshape(-1, 3)])
    tri = tri[(tri >= 0).all(axis=1)]
    return rows, cols, tri


# --------------------------------------------------------- smooth fields
def _bump(x, y, cx, cy, sx, sy, angle=0.0):
    """Anisotropic Gaussian ``exp(-(u^2/sx^2 + v^2/sy^2)/2)``, axes rotated by ``angle``."""
    dx, dy = x - cx, y - cy
    if angle:
        ca, sa = math.cos(angle), math.sin(angle)
        dx, dy = ca * dx + sa * dy, -sa * dx + ca * dy
    return np.exp(-0.5 * ((dx / sx) ** 2 + (dy / sy) ** 2))


def _smoothstep(e0, e1, t):
    """0 at ``t <= e0``, 1 at ``t >= e1`` (``e1 < e0`` allowed), C1 in between."""
    s = np.clip((t - e0) / (e1 - e0), 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _neutral_z(x, y):
    """Height field of the neutral face."""
    z = 6.0 - x**2 / 16.0 - y**2 / 36.0  # the head
    z += 0.4 * _bump(x, y, 0.0, 6.5, 5.0, 2.5)  # forehead
    z += 0.3 * _bump(x, y, 0.0, 3.0, 0.9, 0.7)  # glabella
    z += 0.5 * _bump(x, y, 0.0, 0.0, 1.4, 4.0)  # bridge/midface mass
    for s in (1.0, -1.0):
        z += 0.6 * _bump(x, y, s * 3.1, _BROW_Y, 2.2, 0.55)  # brow ridge
        z -= 1.3 * _bump(x, y, s * _EYE_X, _EYE_Y, 1.5, 1.1)  # eye socket
        z += 0.75 * _bump(x, y, s * _EYE_X, _EYE_Y, 1.0, 0.6)  # eyeball / lids
        z += 0.8 * _bump(x, y, s * 4.3, -0.6, 1.6, 1.2)  # cheek bone
        z += 0.6 * _bump(x, y, s * 1.15, -3.0, 0.6, 0.5)  # nose wing
        z -= 0.3 * _bump(x, y, s * 2.45, -4.6, 1.4, 0.35, s * 1.05)  # nasolabial groove
    # nose ridge: rises from the bridge to the tip
    ridge = (0.5 + 1.3 * _smoothstep(2.6, -2.6, y)) * _smoothstep(3.6, 2.6, y)
    ridge = ridge * _smoothstep(-3.7, -2.7, y) * np.exp(-0.5 * (x / 0.55) ** 2)
    z += ridge + 0.8 * _bump(x, y, 0.0, -2.6, 0.8, 0.6)  # ridge, tip
    z += 0.5 * _bump(x, y, 0.0, _MOUTH_Y, 2.6, 1.3)  # muzzle
    z += 0.5 * _bump(x, y, 0.0, _UPPER_LIP_Y, 1.9, 0.35)  # upper lip
    z += 0.6 * _bump(x, y, 0.0, _LOWER_LIP_Y, 1.7, 0.4)  # lower lip
    z -= 0.6 * _bump(x, y, 0.0, _MOUTH_Y, 2.2, 0.28)  # mouth line
    z -= 0.25 * _bump(x, y, 0.0, -7.25, 1.6, 0.35)  # fold above the chin
    z += 1.0 * _bump(x, y, 0.0, -8.6, 1.8, 1.0)  # chin
    return z


def _v(*c):
    """A 3-vector as a (1, 3) row, to scale a (n, 1) bump into a displacement field."""
    return np.array(c, dtype=np.float64)[None, :]


def _shapes(x, y, z):
    """Displacement fields (n, 3) of every shape, keyed by name."""
    B = lambda *a: _bump(x, y, *a)[:, None]  # noqa: E731
    out = _brow_shapes(B)
    for s, side in ((1.0, "Left"), (-1.0, "Right")):
        out.update(_side_shapes(B, s, side))
    out.update(_both_sides_shapes(B))
    out["JawOpen"] = _jaw_open(B, x, y, z)
    out["LipUpperUp"] = B(0.0, _UPPER_LIP_Y, 1.6, 0.45) * _v(0, 0.45, 0.1) + (
        B(1.28, _UPPER_LIP_Y, 0.8, 0.5) + B(-1.28, _UPPER_LIP_Y, 0.8, 0.5)
    ) * _v(0, 0.1, 0)
    out["LipLowerDown"] = B(0.0, _LOWER_LIP_Y, 1.5, 0.5) * _v(0, -0.5, 0.1)
    return out


def _brow_drag(B, cx=0.0):
    """Broad skin slide dragging the middle of the brow down (Figs. 2-3)."""
    return B(cx, 2.5, 4.5, 3.5)


def _brow_shapes(B) -> dict[str, np.ndarray]:
    """``Furrow`` (the inner brows down and together) and ``BrowInnerUp``."""
    v = _v
    furrow = B(0.0, 3.0, 0.8, 0.9) * v(0, -0.3, 0.25)  # glabella bunching
    for s in (1.0, -1.0):
        furrow = furrow + B(s * 1.4, 3.3, 1.1, 0.8) * v(-s * 0.45, -0.55, 0.15)
    return {
        "Furrow": furrow,
        "BrowInnerUp": (
            (B(1.3, 3.6, 1.2, 1.3) + B(-1.3, 3.6, 1.2, 1.3)) * v(0, 0.7, 0.05)
            + B(0.0, 5.5, 2.5, 2.0) * v(0, 0.3, 0)
        ),
    }


def _side_shapes(B, s: float, side: str) -> dict[str, np.ndarray]:
    """The shapes of one side (``s`` = 1 the subject's left, -1 the right, its mirror image)."""
    v = _v
    out: dict[str, np.ndarray] = {}
    ex = s * _EYE_X
    upper_lid = B(ex, 1.95, 1.2, 0.6)
    out[f"BrowUp{side}"] = (
        B(s * 3.5, 3.6, 1.9, 1.1) * v(s * 0.05, 0.9, 0.05)
        + B(s * 3.0, 6.0, 2.5, 2.5) * v(0, 0.35, 0)
        + upper_lid * v(0, 0.3, 0)  # Fig. 1: the brow lifts the eyelid
    )
    out[f"BrowDown{side}"] = (
        B(s * 3.3, 3.3, 2.0, 0.9) * v(-s * 0.1, -0.6, 0.1)
        + upper_lid * v(0, -0.2, 0)  # Fig. 1: the brow pushes the eyelid down
    )
    out[f"Blink{side}"] = upper_lid * v(0, -0.8, 0.25) + B(ex, 1.06, 1.1, 0.5) * v(0, 0.15, 0)
    out[f"EyeWide{side}"] = upper_lid * v(0, 0.45, -0.1) + B(s * 3.3, _BROW_Y, 1.6, 0.8) * v(0, 0.15, 0)
    out[f"EyeSquint{side}"] = B(ex, 0.64, 1.4, 0.6) * v(0, 0.45, 0.1) + B(s * 3.8, -0.2, 1.5, 1.0) * v(0, 0.25, 0.15)
    out[f"Sneer{side}"] = (
        B(s * 1.07, -3.19, 0.7, 0.6) * v(s * 0.1, 0.55, 0.15)  # nose wing
        + B(s * 1.07, _UPPER_LIP_Y, 0.9, 0.5) * v(0, 0.5, 0.15)  # upper lip
        + B(s * 2.4, -2.5, 1.2, 1.2) * v(s * 0.05, 0.4, 0.2)  # cheek
        + B(s * 2.9, 0.5, 1.3, 0.9) * v(0, 0.45, 0.2)  # Fig. 5: under the eye
        + B(s * 0.7, -0.5, 0.5, 1.0) * v(0, 0.2, 0.05)  # side of the nose
    )
    corner = lambda sx=0.9, sy=0.7, cy=_MOUTH_Y: B(s * _CORNER_X, cy, sx, sy)  # noqa: E731
    out[f"MouthStretch{side}"] = (
        corner(1.1, 0.8) * v(s * 0.7, -0.3, -0.15)
        + B(s * 1.49, _LOWER_LIP_Y, 1.0, 0.5) * v(s * 0.2, -0.25, 0)
        + B(s * 4.0, -8.0, 2.0, 2.0) * v(0, -0.2, 0)
        + _brow_drag(B, s * 1.5) * v(0, -0.06, 0)  # Fig. 2
    )
    out[f"Smirk{side}"] = (
        corner(1.0, 0.8) * v(s * 0.75, 0.8, -0.35)  # Fig. 4: out and up
        + B(s * 3.6, -3.5, 1.5, 1.3) * v(s * 0.25, 0.4, -0.15)  # cheek pushed back
        + B(ex, 0.6, 1.3, 0.7) * v(0, 0.12, 0.05)
        + _brow_drag(B, s * 1.5) * v(0, -0.05, 0)  # Fig. 2
    )
    out[f"MouthFrown{side}"] = corner(0.9, 0.8, -5.9) * v(s * 0.1, -0.6, 0) + B(s * 2.3, -7.5, 1.0, 1.0) * v(0, -0.2, 0.1)
    return out


def _both_sides_shapes(B) -> dict[str, np.ndarray]:
    """``Wince``, ``CheekPuff``, ``MouthPucker``, ``MouthFunnel``: one shape over both sides of the face."""
    v = _v
    wince = (
        B(0.0, 0.5, 0.8, 1.2) * v(0, 0.25, 0)  # nose wrinkle
        + B(0.0, _UPPER_LIP_Y, 1.8, 0.6) * v(0, 0.35, 0.1)  # upper lip raised
    )
    puff = B(0.0, _MOUTH_Y, 1.6, 0.6) * v(0, 0, 0.2)
    pucker = B(0.0, _MOUTH_Y, 1.8, 0.9) * v(0, 0, 0.8)
    funnel = B(0.0, _UPPER_LIP_Y, 1.4, 0.45) * v(0, 0.3, 0.4) + B(0.0, _LOWER_LIP_Y, 1.4, 0.45) * v(0, -0.35, 0.4)
    for s in (1.0, -1.0):
        wince = wince + (
            B(s * _EYE_X, 1.95, 1.2, 0.6) * v(0, -0.35, 0.1)  # eyes squeezed
            + B(s * 3.1, 0.5, 1.5, 0.9) * v(0, 0.45, 0.2)  # Fig. 5: under the eyes up
            + B(s * 1.6, 3.2, 1.2, 0.8) * v(-s * 0.2, -0.35, 0.05)  # inner brows down
            + B(s * _CORNER_X, _MOUTH_Y, 0.9, 0.7) * v(s * 0.45, -0.15, -0.2)  # grimace
        )
        puff = puff + B(s * 3.4, -4.5, 1.6, 1.4) * v(s * 0.5, 0, 0.6)
        pucker = pucker + B(s * 2.3, _MOUTH_Y, 0.9, 0.7) * v(-s * 0.7, 0, 0.3)
        funnel = funnel + B(s * 2.3, _MOUTH_Y, 0.9, 0.7) * v(-s * 0.4, 0, 0.1)
    return {"Wince": wince, "CheekPuff": puff, "MouthPucker": pucker, "MouthFunnel": funnel}


def _jaw_open(B, x, y, z):
    """``JawOpen``: a linearised rotation about a hinge behind the face, masked to the lower face
    (the transition widens towards the sides), plus skin drag."""
    v = _v
    theta, hinge_y, hinge_z, forward = 0.22, -1.0, -3.0, 0.9
    edge = _MOUTH_Y - 0.15 + 0.25 * (x / 3.0) ** 2
    width = 0.5 + 0.25 * np.abs(x)
    mask = _smoothstep(edge + 0.5 * width, edge - 0.5 * width, y)
    jaw = np.zeros((x.size, 3))
    jaw[:, 1] = -theta * (z - hinge_z)
    jaw[:, 2] = theta * (y - hinge_y) + forward * theta
    jaw *= mask[:, None]
    jaw = jaw + (B(3.5, -3.0, 2.0, 1.5) + B(-3.5, -3.0, 2.0, 1.5)) * v(0, -0.25, 0)
    jaw = jaw + B(0.0, -3.0, 1.0, 0.8) * v(0, -0.1, 0)
    return jaw + _brow_drag(B) * v(0, -0.14, 0)  # Fig. 2


# ---------------------------------------------------------------- regions
def _nearest(x, y, cand, tx, ty):
    """Vertex among ``cand`` nearest to (tx, ty) in the x-y plane (lowest id on ties)."""
    d = (x[cand] - tx) ** 2 + (y[cand] - ty) ** 2
    return int(cand[np.argmin(d)])


def _regions(x, y, rows, cols, nr, nc):
    ids = np.arange(x.size)
    ell = lambda cx, cy, rx, ry: ((x - cx) / rx) ** 2 + ((y - cy) / ry) ** 2 <= 1.0  # noqa: E731
    reg: dict[str, np.ndarray] = {}

    # Fig. 3: two vertices at the middle of the brow, one each side of the midline
    dx = _WIDTH / (nc - 1)
    half = 0.5 * _DX0
    reg["brow_middle"] = np.array(
        [
            _nearest(x, y, ids[x < -1e-9], -half, _BROW_MIDDLE_Y),
            _nearest(x, y, ids[x > 1e-9], half, _BROW_MIDDLE_Y),
        ]
    )
    # Fig. 4: the mouth corners
    reg["mouth_corners"] = np.array(
        [_nearest(x, y, ids, -_CORNER_X, _MOUTH_Y), _nearest(x, y, ids, _CORNER_X, _MOUTH_Y)]
    )
    # Fig. 5: six vertices below the eye, a 3 x 2 block of grid points whose
    # pitch is the default grid spacing (one grid step at 2016 vertices)
    dy = _HEIGHT / (nr - 1)
    sc, sr = max(1, round(_DX0 / dx)), max(1, round(_DY0 / dy))
    grid_id = np.full((nr, nc), -1, dtype=np.int64)
    grid_id[rows, cols] = ids
    for side, s in (("left", 1.0), ("right", -1.0)):
        cx, cy = s * _UNDER_EYE[0], _UNDER_EYE[1]
        c0 = int(round((cx + _WIDTH / 2) / dx))
        r_top = int(math.floor((_HEIGHT / 2 - cy - 0.5 * sr * dy) / dy + 0.5))
        block = grid_id[np.ix_(r_top + sr * np.arange(2), c0 + sc * np.arange(-1, 2))]
        reg[f"under_{side}_eye"] = np.sort(block.ravel())

    reg["forehead"] = ids[(y > _BROW_Y + 1.2) & (np.abs(x) < 7.0)]
    brow = ell(0.0, _BROW_MIDDLE_Y, 1.0, 0.6)
    for s in (1.0, -1.0):
        brow |= ell(s * 3.1, _BROW_Y + 0.1, 2.6, 0.75)
    reg["brow"] = ids[brow]
    reg["left_eye"] = ids[ell(_EYE_X, _EYE_Y, 1.7, 0.95)]
    reg["right_eye"] = ids[ell(-_EYE_X, _EYE_Y, 1.7, 0.95)]
    reg["nose"] = ids[ell(0.0, -0.4, 0.9, 2.9) | ell(0.0, -3.0, 1.9, 0.8)]
    reg["cheeks"] = ids[ell(4.2, -2.6, 1.9, 1.9) | ell(-4.2, -2.6, 1.9, 1.9)]
    reg["mouth"] = ids[ell(0.0, _MOUTH_Y, 3.0, 1.2)]
    reg["jaw"] = ids[y < -6.9]
    return {k: reg[k] for k in PROCEDURAL_REGIONS}


# ---------------------------------------------------------------- builder
def _build(n: int):
    nr, nc, k = procedural_grid_shape(n)
    rows, cols, faces = _grid(nr, nc, k)
    x = -_WIDTH / 2 + cols * (_WIDTH / (nc - 1))
    y = _HEIGHT / 2 - rows * (_HEIGHT / (nr - 1))
    z = _neutral_z(x, y)
    f0 = np.column_stack([x, y, z])
    fields = _shapes(x, y, z)
    D = np.stack([fields[name] for name in PROCEDURAL_SHAPES], axis=-1).reshape(3 * x.size, -1)
    regions = _regions(x, y, rows, cols, nr, nc)
    for a in (f0, D, faces, *regions.values()):
        a.flags.writeable = False
    return f0, D, faces, regions


_build_cached = lru_cache(maxsize=4)(_build)


def procedural_model(n_vertices: int = DEFAULT_N_VERTICES) -> BlendshapeModel:
    """The embedded procedural face as a delta blendshape model.

    A deterministic stand-in for the paper's professionally sculpted model,
    built in code (no data files): a face-like height field over a structured
    grid with 27 smooth shapes whose overlaps reproduce the interference of
    Lewis et al. 2005, Figs. 1-5 (see the module docstring).

    Parameters
    ----------
    n_vertices : int, default 2016
        Exact number of vertices.  2,016 (a 48 x 42 grid) is the paper-sized
        model: 6 selected vertices give ``alpha = (2016 - 6) / 6 = 335``
        (Fig. 5).  Any integer in ``MIN_N_VERTICES..MAX_N_VERTICES`` (500 to
        1,000,000) builds the same face sampled more or less finely (see
        :func:`procedural_grid_shape`), e.g. 26,712 for benchmarks.

    Returns
    -------
    BlendshapeModel
        ``name="procedural"``, ``units="model units"`` (1 unit ~ 1 cm on a
        face 20 units tall and 17.5 wide; +z toward the viewer, +y up, +x the
        subject's left).  ``names`` is :data:`PROCEDURAL_SHAPES`; ``sliders``
        pairs Left/Right shapes (``"Smile"`` = ``SmirkLeft + SmirkRight``,
        ``"BrowUp"``, ``"BrowDown"``, ``"Blink"``, ``"EyeWide"``,
        ``"EyeSquint"``, ``"Sneer"``, ``"MouthStretch"``, ``"MouthFrown"``);
        ``regions`` holds the presets of :data:`PROCEDURAL_REGIONS`:
        ``"brow_middle"`` (2 vertices, Fig. 3), ``"mouth_corners"``
        (2 vertices, right then left, Fig. 4), ``"under_left_eye"`` and
        ``"under_right_eye"`` (exactly 6 vertices each, Fig. 5), and the
        broader ``"forehead"``, ``"brow"``, ``"left_eye"``, ``"right_eye"``,
        ``"nose"``, ``"cheeks"``, ``"mouth"`` and ``"jaw"``.

    Raises
    ------
    ModelError
        If ``n_vertices`` is not an integer (floats and bools are refused) or
        lies outside the supported range.

    Notes
    -----
    The arrays of the most recently used sizes are cached (they are
    read-only); each call returns a new :class:`BlendshapeModel` around them.
    Building the 2,016-vertex model takes a few milliseconds.

    Examples
    --------
    >>> m = procedural_model()
    >>> m.n_vertices, m.n_shapes, m.units
    (2016, 27, 'model units')
    >>> (m.n_vertices - len(m.regions["under_left_eye"])) / len(m.regions["under_left_eye"])
    335.0
    """
    n = _check_n(n_vertices)
    f0, D, faces, regions = (_build_cached if n <= 50_000 else _build)(n)
    return BlendshapeModel(
        f0=f0,
        D=D,
        names=PROCEDURAL_SHAPES,
        faces=faces,
        name="procedural",
        units="model units",
        sliders=_SLIDERS,
        regions=regions,
    )
