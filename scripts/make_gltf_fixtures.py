"""Write the small glTF test faces of tests/data/gltf/ from the procedural face.

    python scripts/make_gltf_fixtures.py              # (re)writes tests/data/gltf/* (ours)
    python scripts/make_gltf_fixtures.py --gltfpack  # and face_gltfpack.glb with npm's gltfpack

Each file holds the same face, :func:`fixture_model` (a 108-vertex patch of the
500-vertex procedural face -- brows to chin -- with five shapes under
ARKit names, deltas below 2% of each shape's peak set to exactly zero so that a
sparse file is sparse), in metres, written by :func:`repro.blendshapes.faces.gltf_write.write_gltf`
with one storage feature each.  The tests only read the committed results and
compare them with :func:`fixture_model`; this script is not needed at test time.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "tests" / "data" / "gltf"

#: procedural shape -> ARKit name, the shapes the fixture face keeps
SHAPES = {
    "BrowDownLeft": "browDown_L",
    "BrowDownRight": "browDown_R",
    "SmirkLeft": "mouthSmile_L",
    "SmirkRight": "mouthSmile_R",
    "JawOpen": "jawOpen",
}
#: the "node" fixture's node transform: stored in centimetres, placed by scale 0.01 and a translation
NODE_MATRIX = np.array([[0.01, 0, 0, 0.0], [0, 0.01, 0, 1.6], [0, 0, 0.01, 0.05], [0, 0, 0, 1]])


def fixture_model():
    """The fixture face (metres), the expected content of every fixture file."""
    from repro.blendshapes import BlendshapeModel, load_model
    from repro.blendshapes.faces.arkit import arkit_rig

    full = load_model("procedural", n_vertices=500)
    x, y = full.f0[:, 0], full.f0[:, 1]
    patch = full.restrict(np.flatnonzero((np.abs(x) <= 3.7) & (y >= -7.0) & (y <= 3.6)))
    cols = [patch.names.index(s) for s in SHAPES]
    D = patch.D[:, cols].reshape(patch.n_vertices, 3, -1) * 0.01
    motion = np.linalg.norm(D, axis=1)
    D[np.broadcast_to((motion < 0.02 * motion.max(axis=0))[:, None, :], D.shape)] = 0.0
    D = D.reshape(-1, len(cols))
    f0 = patch.f0 * 0.01
    names = tuple(SHAPES.values())
    sliders, regions = arkit_rig(f0, D, names)
    return BlendshapeModel(f0=f0, D=D, names=names, faces=patch.faces, name="fixture-face", units="m",
                           sliders=sliders, regions=regions)


def eye_mesh():
    """An octahedron "eye" (metres) in front of the left brow, a mesh without targets."""
    c, r = np.array([0.028, 0.016, 0.066]), 0.008
    v = c + r * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    t = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return ("eye_L", v, np.array(t))


#: file name -> write_gltf keywords
FIXTURES = {
    "face.glb": {},
    "face.gltf": {},  # + face.bin beside it
    "face_quantized.glb": {"quantize": True},
    "face_meshopt.glb": {"quantize": True, "meshopt": True},  # as gltfpack -cc writes them
    "face_meshes.glb": {"extra_meshes": "eye"},
    "face_node.glb": {"node_matrix": NODE_MATRIX},
    "face_sparse.glb": {"sparse": True},
}


#: third-party writer: gltfpack (meshoptimizer's glTF packer, npm package ``gltfpack``), run on
#: face.glb with ``-cc``: its own quantisation (unnormalised 16-bit positions under a TRS node with
#: a parent), vertex reordering and meshopt compression.  Only with ``--gltfpack``, since it needs
#: node/npx and the npm registry (or its cache); the committed result is what the tests read.
GLTFPACK = ("npx", "--yes", "gltfpack@1.3.0")


def run_gltfpack() -> None:
    import subprocess

    cmd = [*GLTFPACK, "-i", str(OUT / "face.glb"), "-o", str(OUT / "face_gltfpack.glb"), "-cc"]
    subprocess.run(cmd, check=True, cwd=OUT)


def main(argv=None) -> int:
    sys.path.insert(0, str(REPO))
    from repro.blendshapes import write_gltf

    argv = sys.argv[1:] if argv is None else argv
    model = fixture_model()
    OUT.mkdir(parents=True, exist_ok=True)
    for name, kw in FIXTURES.items():
        kw = dict(kw)
        if kw.get("extra_meshes") == "eye":
            kw["extra_meshes"] = [eye_mesh()]
        write_gltf(model, OUT / name, **kw)
    if "--gltfpack" in argv:
        run_gltfpack()
    for p in sorted(OUT.iterdir()):
        print(f"{p.relative_to(REPO)}: {p.stat().st_size} bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
