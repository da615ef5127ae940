"""The embedded procedural face (repro.blendshapes.faces.procedural).

Checks the contracts the figures rely on: the paper-sized vertex count, the
paper's shape names, a valid triangulated face, linear independence, and -
measured - the interference each figure of Lewis et al. 2005 needs (Figs. 2-5),
including that Eq. (3), written out here independently of the library, can
attenuate it.  Thresholds are set below the values measured when the face was
sculpted (quoted next to each), so a change that weakens the interference fails.
"""

import hashlib
import subprocess
import sys

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from repro.blendshapes.model import BlendshapeModel
from repro.blendshapes.faces.procedural import (
    PROCEDURAL_REGIONS,
    PROCEDURAL_SHAPES,
    _build_cached,
    procedural_grid_shape,
    procedural_model,
)
from repro.errors import ModelError

PAPER_NAMES = ("Furrow", "SmirkLeft", "SmirkRight", "Wince", "SneerLeft", "SneerRight")
MOUTH_MOVES = {  # "further slider moves, mostly affecting the mouth" (Fig. 2c)
    "JawOpen": 0.5,
    "SmirkLeft": 0.4,
    "SmirkRight": 0.4,
    "MouthStretchLeft": 0.3,
    "MouthStretchRight": 0.3,
}
FIG5_MOVES = {"Wince": 0.7, "SneerLeft": 0.7, "SneerRight": 0.7}


@pytest.fixture(scope="module")
def face() -> BlendshapeModel:
    return procedural_model()


@pytest.fixture(scope="module")
def big() -> BlendshapeModel:
    return procedural_model(26712)


def coord_rows(vertices, axes=(0, 1, 2)):
    """Rows of D (xyz packing) for the given vertices and axes."""
    return np.array([3 * v + a for v in vertices for a in axes])


def eq3(D, w1, selected_rows, alpha):
    """Eq. (3), w2 = (P + alpha Q)^-1 P w1, from the selected rows of D."""
    mask = np.zeros(D.shape[0], bool)
    mask[selected_rows] = True
    S, Sbar = D[mask], D[~mask]
    P, Q = Sbar.T @ Sbar, S.T @ S
    return np.linalg.solve(P + alpha * Q, P @ w1)


def disp(model, weights, region):
    return model.displacement(model.weights(weights))[model.regions[region]]


# ---------------------------------------------------------------- basics
def test_default_size_names_and_metadata(face):
    assert face.n_vertices == 2016
    assert procedural_grid_shape() == (48, 42, 0)
    assert face.n_shapes >= 20
    assert face.names == PROCEDURAL_SHAPES
    for name in PAPER_NAMES + ("BlinkLeft", "BlinkRight", "BrowUpLeft", "BrowUpRight",
                               "BrowInnerUp", "JawOpen", "MouthPucker", "MouthFunnel",
                               "MouthStretchLeft", "MouthStretchRight", "CheekPuff"):
        assert name in face.names
    assert face.name == "procedural" and face.units == "model units"
    assert set(face.regions) == set(PROCEDURAL_REGIONS)
    # named slider combinations resolve to their two shapes
    w = face.weights(Smile=0.7)
    assert w[face.shape_index("SmirkLeft")] == w[face.shape_index("SmirkRight")] == 0.7
    assert np.count_nonzero(w) == 2


def test_physical_size_and_axes(face):
    x, y, z = face.f0.T
    assert np.isclose(np.ptp(y), 20.0) and np.isclose(np.ptp(x), 17.5)  # ~cm
    # looks toward +z: the nose tip is the most forward point, on the midline, mid-face
    tip = face.f0[np.argmax(z)]
    assert abs(tip[0]) < 0.5 and -3.5 < tip[1] < -1.5
    # every triangle is counter-clockwise seen from +z (normals toward the viewer)
    a, b, c = (face.f0[face.faces[:, i]] for i in range(3))
    cross_z = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    assert (cross_z > 0).all()


def test_face_features_visible_in_geometry(face):
    def z_at(px, py):
        i = np.argmin((face.f0[:, 0] - px) ** 2 + (face.f0[:, 1] - py) ** 2)
        return face.f0[i, 2]

    for s in (1, -1):
        eye = z_at(s * 3.2, 1.6)
        assert z_at(s * 3.2, 3.4) > eye + 0.3  # brow ridge over the eye socket
        assert z_at(s * 4.3, -0.6) > z_at(s * 4.3, 1.6)  # cheekbone
        assert z_at(s * 6.0, 1.6) < eye  # the face curves back at the sides
    assert z_at(0, -2.6) > z_at(0, 1.0) + 1.0  # nose tip over the bridge
    assert z_at(0, -6.17) > z_at(0, -5.75) + 0.2  # lower lip over the mouth line
    # the fold between lower lip and chin is a concavity; the chin then curves back
    assert z_at(0, -7.25) < 0.5 * (z_at(0, -6.17) + z_at(0, -8.6)) - 0.2
    assert z_at(0, -8.6) > z_at(0, -10.0) + 0.5
    assert z_at(0, 9.0) < z_at(0, 5.0)  # forehead slopes back


def test_mesh_is_one_manifold_disc(face):
    n, faces, edges = face.n_vertices, face.faces, face.edges
    assert faces.min() >= 0 and faces.max() < n
    assert np.unique(faces).size == n  # every vertex used by a triangle
    assert (np.diff(np.sort(faces, axis=1), axis=1) > 0).all()  # no degenerate triangles
    ncomp, _ = connected_components(
        coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    )
    assert ncomp == 1
    # every edge borders one (boundary) or two (interior) triangles
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert set(counts.tolist()) == {1, 2}
    assert n - len(edges) + len(faces) == 1  # Euler characteristic of a disc
    # boundary = the rim of the 48 x 42 grid
    assert np.count_nonzero(counts == 1) == 2 * (47 + 41)


def test_deterministic_across_processes(face):
    def digest(m):
        h = hashlib.sha256()
        for a in (m.f0, m.D, m.faces, *(m.regions[k] for k in sorted(m.regions))):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()

    code = (
        "import hashlib, numpy as np\n"
        "from repro.blendshapes.faces.procedural import procedural_model\n"
        "m = procedural_model()\n"
        "h = hashlib.sha256()\n"
        "for a in (m.f0, m.D, m.faces, *(m.regions[k] for k in sorted(m.regions))):\n"
        "    h.update(np.ascontiguousarray(a).tobytes())\n"
        "print(h.hexdigest())\n"
    )
    other = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    _build_cached.cache_clear()
    rebuilt = procedural_model()
    assert digest(face) == digest(rebuilt) == other
    assert rebuilt is not face and rebuilt.regions is not face.regions


def test_model_is_read_only_and_fresh_per_call(face):
    with pytest.raises(ValueError):
        face.D[0, 0] = 1.0
    with pytest.raises(ValueError):
        face.regions["brow_middle"][0] = 0
    other = procedural_model()
    other.regions.pop("jaw")  # a caller mutating its dict must not affect later models
    assert "jaw" in procedural_model().regions


def test_build_is_cached():
    # speed is measured by benchmarks (ratios in one process), never asserted here: the build
    # runs once, later calls reuse it
    _build_cached.cache_clear()
    procedural_model()
    procedural_model()
    info = _build_cached.cache_info()
    assert info.misses == 1 and info.hits >= 1


def test_left_right_shapes_are_mirror_images(face):
    # mirror vertex map on the symmetric 48 x 42 grid: column c <-> 41 - c
    r, c = np.divmod(np.arange(2016), 42)
    mirror = r * 42 + (41 - c)
    assert np.allclose(face.f0[mirror] * [-1, 1, 1], face.f0)
    flip = np.array([-1.0, 1.0, 1.0])
    for left in [s for s in face.names if s.endswith("Left")]:
        right = left[: -len("Left")] + "Right"
        dl = face.D[:, face.shape_index(left)].reshape(-1, 3)
        dr = face.D[:, face.shape_index(right)].reshape(-1, 3)
        assert np.allclose(dr, dl[mirror] * flip, atol=1e-12), left
        # ...Left moves the subject's left (+x) side more than the right side
        nl = np.linalg.norm(dl, axis=1)
        assert nl[face.f0[:, 0] > 0].sum() > 2 * nl[face.f0[:, 0] < 0].sum(), left


def test_shapes_smooth_and_full_rank(face):
    D = face.D
    assert np.linalg.matrix_rank(D) == face.n_shapes
    sv = np.linalg.svd(D, compute_uv=False)
    assert sv[0] / sv[-1] < 1e3  # measured ~176
    # Neighbours move together.  Along every edge the change of displacement is
    # at most 60% of the shape's peak and smaller than the edge itself (so no
    # triangle can fold over).  JawOpen is the exception by design: it opens the
    # mouth, and this mesh has no lip split, so it stretches the one row of edges
    # across the mouth line (measured: 4.5 x the edge length there) - but only
    # stretches it, never folds it.
    e = face.edges
    length = np.linalg.norm(face.f0[e[:, 0]] - face.f0[e[:, 1]], axis=1)
    for k, name in enumerate(face.names):
        d = D[:, k].reshape(-1, 3)
        peak = np.linalg.norm(d, axis=1).max()
        assert 0.3 < peak < 2.5, name
        jump = np.linalg.norm(d[e[:, 0]] - d[e[:, 1]], axis=1)
        if name == "JawOpen":
            continue
        assert jump.max() < 0.6 * peak, (name, jump.max() / peak)  # measured <= 0.58
        assert (jump / length).max() < 1.0, name  # measured <= 0.91 (BlinkLeft/Right)
    jaw = face.pose(face.weights(JawOpen=1.0))
    a, b, c = (jaw[face.faces[:, i]] for i in range(3))
    assert (((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]) > 0).all()


@pytest.mark.parametrize("region", PROCEDURAL_REGIONS)
def test_P_nonsingular_for_every_preset(face, region):
    """Deleting a preset's rows keeps D full rank: P = Sbar^T Sbar is well conditioned."""
    D = face.D
    mask = np.zeros(D.shape[0], bool)
    mask[coord_rows(face.regions[region])] = True
    Sbar = D[~mask]
    lam_P = np.linalg.eigvalsh(Sbar.T @ Sbar)[0]
    lam_D = np.linalg.eigvalsh(D.T @ D)[0]
    assert lam_P > 0.3 * lam_D  # measured >= 0.52 ("brow"), ~0.99 for the point presets


# --------------------------------------------------------------- regions
def test_region_presets(face):
    R, f0 = face.regions, face.f0
    assert len(R["brow_middle"]) == 2 and len(R["mouth_corners"]) == 2
    assert len(R["under_left_eye"]) == len(R["under_right_eye"]) == 6
    for k, v in R.items():
        assert np.unique(v).size == v.size > 0, k
    bm = f0[R["brow_middle"]]
    assert np.allclose(bm[:, 0], [-0.5 * 17.5 / 41, 0.5 * 17.5 / 41])  # straddle the midline
    assert np.allclose(bm[:, 1], 3.2, atol=0.25)
    mc = f0[R["mouth_corners"]]
    assert mc[0, 0] < 0 < mc[1, 0] and np.allclose(mc[:, 0], [-2.35, 2.35], atol=0.1)
    ule = f0[R["under_left_eye"]]
    # a 3 x 2 block of neighbouring vertices on the +x side, below the eye (y = 1.6)
    assert np.unique(ule[:, 0].round(6)).size == 3 and np.unique(ule[:, 1].round(6)).size == 2
    assert (ule[:, 0] > 2.5).all() and (ule[:, 0] < 4.0).all()
    assert (ule[:, 1] < 1.0).all() and (ule[:, 1] > 0.0).all()
    assert np.allclose(f0[R["under_right_eye"]][:, 0].mean(), -ule[:, 0].mean())
    # the broad regions sit where their names say
    assert (f0[R["left_eye"], 0] > 0).all() and (f0[R["right_eye"], 0] < 0).all()
    assert (f0[R["forehead"], 1] > f0[R["brow"], 1].max()).all()
    assert f0[R["jaw"], 1].max() < f0[R["mouth"], 1].min() + 1.0
    assert np.isin(R["mouth_corners"], R["mouth"]).all()
    assert np.isin(R["brow_middle"], R["brow"]).all()
    assert not np.isin(R["under_left_eye"], R["left_eye"]).any()  # below, not on, the eye


def test_default_alpha_is_335(face):
    k = len(face.regions["under_left_eye"])
    assert k == 6
    assert (face.n_vertices - k) / k == 335


# ------------------------------------------------- sculpted interference
def test_fig2_mouth_moves_keep_furrowing_the_brow(face):
    furrow = disp(face, {"Furrow": 0.4}, "brow_middle")
    assert (furrow[:, 1] < -0.25).all()  # measured -0.31
    after = disp(face, {"Furrow": 0.4, **MOUTH_MOVES}, "brow_middle")
    extra = after - furrow
    assert (extra[:, 1] < 0).all()  # the brow keeps moving down
    ratio = np.linalg.norm(extra, axis=1) / np.linalg.norm(furrow, axis=1)
    assert (ratio > 0.25).all(), ratio  # measured 0.40 (0.139 of 0.345 units)
    for shape in ("JawOpen", "MouthStretchLeft", "MouthStretchRight", "SmirkLeft", "SmirkRight"):
        dy = disp(face, {shape: 1.0}, "brow_middle")[:, 1]
        assert (dy < -0.03).all(), (shape, dy)  # measured -0.046 .. -0.137
    # ...while these shapes are mostly about the mouth
    d = face.displacement(face.weights(MOUTH_MOVES))
    assert np.linalg.norm(d[face.regions["mouth"]], axis=1).max() > 5 * np.abs(extra).max()


def test_fig3_attenuation_can_hold_the_brow(face):
    w0, w1 = face.weights(Furrow=0.4), face.weights({"Furrow": 0.4, **MOUTH_MOVES})
    sel = coord_rows(face.regions["brow_middle"])
    alpha = (face.n_vertices - 2) / 2
    dw = eq3(face.D, w1 - w0, sel, alpha)
    d1, d2 = face.D @ (w1 - w0), face.D @ dw
    mask = np.zeros(d1.size, bool)
    mask[sel] = True
    assert np.linalg.norm(d2[sel]) < 0.1 * np.linalg.norm(d1[sel])  # measured 0.03
    assert np.linalg.norm(d2[~mask]) > 0.95 * np.linalg.norm(d1[~mask])  # measured 0.999


def test_fig4_smirks_move_mouth_corners_in_x_and_y(face):
    d = disp(face, {"SmirkLeft": 0.7, "SmirkRight": 0.7}, "mouth_corners")
    right, left = d
    assert left[0] > 0.4 and right[0] < -0.4  # stretched out: measured +-0.55
    assert (d[:, 1] > 0.4).all()  # up: measured 0.60
    # y alone can be held while x stays free (Eq. 3 on the two y coordinates)
    w1 = face.weights(Smile=0.7)
    w2 = eq3(face.D, w1, coord_rows(face.regions["mouth_corners"], axes=(1,)), 1007.0)
    d2 = face.displacement(w2)[face.regions["mouth_corners"]]
    assert (np.abs(d2[:, 1]) < 0.05 * d[:, 1]).all()  # measured 0.009 of 0.60
    assert (np.abs(d2[:, 0]) > 0.9 * np.abs(d[:, 0])).all()  # measured 0.56 vs 0.55


def test_fig5_wince_and_sneers_move_under_the_eye(face):
    d = disp(face, FIG5_MOVES, "under_left_eye")
    norms = np.linalg.norm(d, axis=1)
    assert (norms > 0.45).all(), norms  # measured 0.59 .. 0.67 units
    assert (d[:, 1] > 0).all()  # pushed up
    for shape in ("Wince", "SneerLeft"):  # each contributes
        assert (disp(face, {shape: 0.7}, "under_left_eye")[:, 1] > 0.15).all(), shape
    assert (disp(face, {"SneerRight": 0.7}, "under_right_eye")[:, 1] > 0.15).all()
    # the same moves pose the mouth, which attenuation leaves largely alone
    w1 = face.weights(FIG5_MOVES)
    sel = coord_rows(face.regions["under_left_eye"])
    d1 = face.D @ w1
    mouth = coord_rows(face.regions["mouth"])
    assert np.linalg.norm(d1[mouth]) > np.linalg.norm(d1[sel])
    d2 = face.D @ eq3(face.D, w1, sel, 335.0)
    assert np.linalg.norm(d2[sel]) < 0.15 * np.linalg.norm(d1[sel])  # measured 0.05
    assert np.linalg.norm(d2[mouth]) > 0.85 * np.linalg.norm(d1[mouth])  # measured 0.95


def test_fig1_brow_slider_disturbs_the_eyelid(face):
    lid = np.flatnonzero(
        (np.abs(face.f0[:, 0] - 3.2) < 0.3) & (np.abs(face.f0[:, 1] - 1.95) < 0.25)
    )
    assert lid.size
    up = face.displacement(face.weights(BrowUpLeft=1.0))[lid, 1]
    down = face.displacement(face.weights(BrowDownLeft=1.0))[lid, 1]
    assert (up > 0.1).all() and (down < -0.1).all()


# ----------------------------------------------------------- other sizes
def test_scaled_model_same_face(face, big):
    assert big.n_vertices == 26712
    assert procedural_grid_shape(26712) == (168, 159, 0)
    assert big.names == face.names and big.sliders == face.sliders
    assert set(big.regions) == set(face.regions)
    for k in ("brow_middle", "mouth_corners", "under_left_eye", "under_right_eye"):
        assert len(big.regions[k]) == len(face.regions[k]), k
        # same place on the face (within half a default grid step)
        assert np.allclose(big.f0[big.regions[k], :2].mean(0),
                           face.f0[face.regions[k], :2].mean(0), atol=0.22), k
    # broad regions cover the same area: counts scale with the vertex density
    scale = big.n_vertices / face.n_vertices
    for k in ("forehead", "brow", "nose", "cheeks", "mouth", "jaw"):
        assert 0.8 < len(big.regions[k]) / (scale * len(face.regions[k])) < 1.25, k
    peak = lambda m: np.linalg.norm(m.D.reshape(-1, 3, m.n_shapes), axis=1).max(0)  # noqa: E731
    rel = peak(big) / peak(face)
    assert np.all(np.abs(rel - 1) < 0.1), dict(zip(face.names, rel.round(3)))  # measured <= 4.1%
    # the displacement fields agree where the vertices (nearly) coincide
    near = np.argmin(
        (big.f0[None, :, 0] - face.f0[::7, None, 0]) ** 2
        + (big.f0[None, :, 1] - face.f0[::7, None, 1]) ** 2,
        axis=1,
    )
    a = big.D.reshape(-1, 3, big.n_shapes)[near]
    b = face.D.reshape(-1, 3, face.n_shapes)[::7]
    assert np.linalg.norm(a - b) < 0.05 * np.linalg.norm(b)
    assert np.linalg.matrix_rank(big.D) == big.n_shapes


@pytest.mark.parametrize("n", [500, 501, 1000, 2017, 5003])
def test_any_size_in_range_is_exact_and_valid(n):
    m = procedural_model(n)
    nr, nc, k = procedural_grid_shape(n)
    assert m.n_vertices == n == nr * nc - k and 0 <= k < nc
    assert np.unique(m.faces).size == n
    assert n - len(m.edges) + len(m.faces) == 1  # still one disc after trimming corners
    assert np.linalg.matrix_rank(m.D) == m.n_shapes
    assert len(m.regions["under_left_eye"]) == 6 and len(m.regions["brow_middle"]) == 2
    # the Fig. 4 interference survives resampling
    d = m.displacement(m.weights(Smile=0.7))[m.regions["mouth_corners"]]
    assert (np.abs(d[:, 0]) > 0.35).all() and (d[:, 1] > 0.35).all()


def test_numpy_integer_accepted():
    assert procedural_model(np.int64(2016)).n_vertices == 2016


@pytest.mark.parametrize(
    "bad", [0, -1, -2016, 499, 1_000_001, 2016.0, 2016.5, "2016", None, True, [2016]]
)
def test_bad_n_raises_model_error(bad):
    with pytest.raises(ModelError, match="n_vertices"):
        procedural_model(bad)
    with pytest.raises(ModelError):
        procedural_grid_shape(bad)
