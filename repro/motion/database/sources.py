"""Where the database's clips come from: files, the real takes, and the named databases.

* :func:`build_database` -- from a folder of BVH files with an optional
  ``manifest.csv`` (the synthetic database of :mod:`repro.motion.database.synthetic`);
* the catalogue of real takes: CMU subject 135 karate (:data:`CMU_TAKES`,
  :func:`build_cmu_database`), Bandai Namco strikes (:data:`BANDAI_TAKES`,
  :func:`build_bandai_database`), both in one database (:func:`build_real_database`), and
  the non-fighting takes used as current poses of queries (:data:`NON_FIGHTING_TAKES`,
  :func:`non_fighting_poses`);
* :func:`load_or_build` (a saved database, or build and save it) and
  :func:`default_database` (``"synthetic"`` or ``"cmu"``, built once per process).

The takes are read in metres and cut around every hit
(:func:`repro.motion.database.annotation.detect_hits`, or the manifest's annotation), resampled to
the database rate on a grid through the hit time (so the hit stays on a frame).
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import io
import math
import os
import re
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from repro import data
from repro.checks import as_choice, as_int, as_names, as_real, as_real_array, as_str, describe
from repro.io import inside, read_bytes
from repro.errors import DataError, MotionError, ReproError, RetrievalError
from repro.motion.database.annotation import (
    HIT_ROLE_OF,
    SEMANTICS,
    Hit,
    check_semantics,
    detect_hits,
    hit_frame_for,
)
from repro.motion.io.bvh import read_bvh
from repro.motion.body.pose_frames import MAX_WINDOW, POSE_ROLES
from repro.motion.database.clips import DATABASE_FPS, Clip, MotionDatabase
from repro.motion.core.cache import LRUCache
from repro.motion.core.motion import BANDAI_UNIT_M, CMU_UNIT_M, Motion
from repro.motion.core.ops import resample
from repro.motion.body.rest_pose import match_rest_pose
from repro.motion.body.skeleton import Skeleton, infer_unit, skeleton_of
from repro.motion.database.synthetic import synthetic_database

__all__ = [
    "CMU_TAKES",
    "CMU_WINDOW",
    "BANDAI_TAKES",
    "NON_FIGHTING_TAKES",
    "REAL_SOURCES",
    "build_database",
    "build_cmu_database",
    "build_bandai_database",
    "build_real_database",
    "load_or_build",
    "default_database",
    "clip_source_dataset",
    "non_fighting_poses",
]

# ================================================================ the catalogue
#: Subject-135 takes of the staged CMU set used by :func:`build_cmu_database`, with the
#: kind of strike they hold (``mocap/cmu/PROVENANCE.md``, "The clips, and strikes found
#: in them").  135_03 (labelled Empi but a 5 m walk with no strike) and 135_08 (the
#: calibration pose) are left out.
CMU_TAKES: dict[str, str] = {
    "135_02": "kata_arm",  # Empi kata
    "135_04": "front_kick",
    "135_05": "kata_arm",  # Gedanbarai (down block)
    "135_06": "kata_arm",  # Heiansyodan kata
    "135_07": "roundhouse_kick",  # Mawashigeri
    "135_09": "lunge_punch",  # Oiduki
    "135_10": "kata_arm",  # Syutouuke (knife-hand block)
    "135_11": "side_kick",  # Yokogeri
}
#: Seconds kept before and after each detected hit when cutting the CMU takes.
CMU_WINDOW: tuple[float, float] = (0.6, 0.3)

# The database is built "from the real clips in ../shared/data/mocap/": CMU subject 135
# (above), the Bandai Namco clips (another skeleton) and walks/runs of other CMU subjects
# for non-fighting poses.

#: Bandai Namco strike takes and their semantics, from the ``semantics`` column of
#: ``mocap/bandai/manifest.csv`` (walk and bow are ``other``: see
#: :data:`NON_FIGHTING_TAKES`).  The kick take also holds arm swings that the punch
#: detector would report ("arm swings 2/3" in ``mocap/bandai/PROVENANCE.md``): as for the
#: CMU drills, only strikes of the take's semantics are searched for.
BANDAI_TAKES: dict[str, str] = {
    "dataset-1_kick_normal_001": "kick",
    "dataset-1_punch_normal_001": "punch",
    "dataset-1_punch_normal_002": "punch",
}

#: Non-fighting takes (``semantics = other`` in the manifests), for "current poses" of
#: retrieval queries: path -> (subject, kind, description).  :class:`MotionDatabase`
#: only holds strikes (:data:`SEMANTICS`; a :class:`Clip` must have a hit), so these
#: are not database clips; :func:`non_fighting_poses` loads them.  Subjects 131, 7 and
#: 9 share the CMU joint tree with subject 135 but neither its bone lengths nor its rest
#: directions (the retrieval retargets them to the 135 actor as they are: the plan's rest step,
#: :class:`~repro.motion.retargeting.morphology.RestStep`; ``non_fighting_poses(rest_like=db)``
#: puts them on the actors' rest directions beforehand, e.g. to draw them); the Bandai walk and bow are on the
#: Bandai joint tree (the bow's file has a 10 cm Head End Site and a slightly different
#: Hips offset, so its skeleton is *not* the one of the other Bandai takes, though its stature
#: measures the same, 1.46 m: :mod:`repro.motion.body.stature`).  135_03 is labelled "Empi" in the CMU index but is a
#: ~5 m walk without any strike (``mocap/cmu/PROVENANCE.md``): subject 135's only walk.
NON_FIGHTING_TAKES: dict[str, tuple[str, str, str]] = {
    "mocap/cmu/131_01.bvh": ("cmu131", "walk", "Start Walk Stop"),
    "mocap/cmu/131_02.bvh": ("cmu131", "walk", "Start Walk Stop"),
    "mocap/cmu/131_09.bvh": ("cmu131", "walk", "Start Walk Left"),
    "mocap/cmu/131_10.bvh": ("cmu131", "walk", "Start Walk Left"),
    "mocap/cmu/131_12.bvh": ("cmu131", "walk", "Start Walk Right"),
    "mocap/cmu/131_13.bvh": ("cmu131", "walk", "Start Walk Right"),
    "mocap/cmu/07_05.bvh": ("cmu07", "walk", "slow walk"),
    "mocap/cmu/09_06.bvh": ("cmu09", "run", "run"),
    "mocap/cmu/135_03.bvh": ("cmu135", "walk", "Empi (index label); a ~5 m walk, no strike"),
    "mocap/bandai/dataset-1_walk_normal_001.bvh": ("bandai", "walk", "walk (style: normal)"),
    "mocap/bandai/dataset-1_bow_normal_001.bvh": ("bandai", "bow", "bow (style: normal)"),
}

#: Sources :func:`build_real_database` can combine.
REAL_SOURCES: tuple[str, ...] = ("cmu135", "bandai")


# ================================================================ reading and cutting
def _cut_around(motion: Motion, hit_time: float, window: tuple[float, float] | None, fps: float):
    """Resample to ``fps`` on a grid through the hit time, keeping ``window`` around it.

    Returns the new motion, the hit frame in it and the start time in the source.
    """
    T = (motion.n_frames - 1) * motion.frame_time
    before, after = (hit_time, T - hit_time) if window is None else window
    k0 = int(math.floor(min(before, hit_time) * fps + 1e-9))
    k1 = int(math.floor(min(after, T - hit_time) * fps + 1e-9))
    times = hit_time + np.arange(-k0, k1 + 1) / fps
    out = resample(motion, frames=times / motion.frame_time, frame_time=1.0 / fps)
    return out, k0, float(times[0])


def _infer_unit(motion: Motion) -> float:
    """Metres per unit from the stature in file units (:func:`repro.motion.body.skeleton.infer_unit`), silently:
    a database build says nothing per file (its clips record ``unit_m``)."""
    h = Skeleton.from_motion(dataclasses.replace(motion, unit_m=1.0)).height  # the stature in file units
    try:
        return infer_unit(h)[0]
    except MotionError as exc:
        raise MotionError(f"cannot guess the length unit of {motion.source!r}: {exc}") from None


def _read(path: Path, unit_m: float | None) -> Motion:
    m = read_bvh(path)
    u = _infer_unit(m) if unit_m is None else float(unit_m)
    return dataclasses.replace(m, unit_m=u).to_metres()


def _clips_from_take(motion: Motion, name: str, *, fps: float, window, hits: Iterable[Hit], kind: str = "",
                     level: str = "", hit_joint: str | None = None, hit_where: str = "joint", tag=True) -> list[Clip]:
    sk = Skeleton.from_motion(motion)
    out = []
    for n, h in enumerate(hits):
        m, k0, t0 = _cut_around(motion, h.frame * motion.frame_time, window, fps)
        cname = f"{name}_h{n:02d}_{h.role}" if tag else name
        out.append(Clip(name=cname, motion=m, semantics=h.semantics, hit_role=h.role,
                        hit_joint=hit_joint or sk.roles[h.role], hit_where=hit_where, hit_frame=k0, kind=kind,
                        side=h.side, source=str(motion.source or name), source_time=t0, level=level))
    return out


def _read_manifest_rows(path: Path) -> list[dict]:
    # a regular file, bounded: a FIFO named manifest.csv would hang open() (issue 23, section 4)
    raw, _ = read_bytes(path, error=MotionError)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MotionError(f"{path}: a manifest is UTF-8 text ({exc})") from None
    return [dict(r) for r in csv.DictReader(io.StringIO(text, newline=""))]


def build_database(source, *, fps: float = DATABASE_FPS, window: tuple[float, float] | None = None,
                   unit_m: float | None = None, manifest: str | None = "manifest.csv",
                   pose_roles: Sequence[str] = POSE_ROLES, pose_window: int = 1, detect_kw: Mapping | None = None
                   ) -> MotionDatabase:
    """Build the database from a folder of BVH files (and its manifest when there is one).

    With a manifest (the columns of :data:`repro.motion.database.synthetic.MANIFEST_COLUMNS`:
    ``file``, ``semantics``, ``side``, ``hit_joint``, ``hit_point`` (``joint`` or
    ``end_site``), ``hit_frame``, ``kind``, ``level``; an optional ``unit_m``) each row
    is one clip, annotated as the manifest says -- rows whose semantics is not a strike
    (``"other"``, the stance clips) are skipped; an empty or negative ``hit_frame`` is
    found with :func:`hit_frame_for`, an empty ``hit_joint`` is the role's joint.  Without
    a manifest every BVH file is searched with :func:`detect_hits` and cut around each
    strike.  Clips are resampled to ``fps`` on a grid that passes through the hit time
    (so the hit stays on a frame).

    Parameters
    ----------
    source : str or os.PathLike
        Folder (or a single manifest file).
    fps : float, default 30
    window : (before, after) seconds, optional
        Cut each clip to this window around its hit; default: the whole clip for manifest
        rows (the manifest's clips *are* the annotated subsequences), (0.6, 0.3) for
        detected strikes.
    unit_m : float, optional
        Metres per file unit; default from the manifest's ``unit_m`` column, else guessed
        from the stature (metres, centimetres or CMU units).
    manifest : str or None, default "manifest.csv"
        Name of the manifest in the folder; None to ignore it.
    pose_roles, pose_window
        Pose representation (:meth:`MotionDatabase.from_clips`).
    detect_kw : mapping, optional
        Thresholds passed to :func:`detect_hits`.

    Raises
    ------
    repro.errors.MotionError
        No clip found, a manifest naming a missing file or bad annotation.
    """
    if isinstance(source, (bytes, bytearray)) or not isinstance(source, (str, os.PathLike)) \
            or "\x00" in str(os.fspath(source)):
        raise MotionError(f"source must be a folder path (str or os.PathLike), got {describe(source)}")
    if manifest is not None:
        manifest = as_str(manifest, "manifest (a file name in the folder, or None)", error=MotionError)
    if window is not None:
        window = _window(window)
    fps, _, pose_roles, pose_window, detect_kw = _build_arguments(fps, None, pose_roles, pose_window, detect_kw)
    if unit_m is not None:
        unit_m = as_real(unit_m, "unit_m (metres per file unit)", lo=0.0, lo_open=True, error=MotionError)
    src = Path(source)
    try:
        is_file = src.is_file()
    except (OSError, ValueError) as exc:  # a NUL byte, a name too long
        raise MotionError(f"source {describe(source)} is not a usable path: {exc}") from None
    folder = src.parent if is_file else src
    mpath = src if is_file else (inside(folder, manifest, error=MotionError, what="manifest") if manifest else None)
    if mpath is not None and mpath.exists() and not mpath.is_file():  # a FIFO, a folder: not silently skipped
        raise MotionError(f"{mpath}: the manifest is not a regular file")
    if mpath is not None and mpath.is_file():
        clips = _manifest_clips(mpath, folder, unit_m=unit_m, fps=fps, window=window, detect_kw=detect_kw)
        how = f"manifest {mpath.name}"
    else:
        clips = _detected_clips(folder, unit_m=unit_m, fps=fps, window=CMU_WINDOW if window is None else window,
                                detect_kw=detect_kw)
        how = "detect_hits"
    if not clips:
        raise MotionError(f"no punch or kick clip found in {src}")
    return MotionDatabase.from_clips(clips, pose_roles=pose_roles, window=pose_window,
                                     meta={"built_from": str(src), "annotations": how, "fps": fps,
                                           "window": None if window is None else list(window)})


def _manifest_clips(mpath: Path, folder: Path, *, unit_m, fps: float, window, detect_kw: Mapping) -> list[Clip]:
    """The clips of a manifest's strike rows, annotated as it says (:func:`build_database`)."""
    clips: list[Clip] = []
    for r in _read_manifest_rows(mpath):
        sem = (r.get("semantics") or "").strip()
        if sem not in SEMANTICS:
            continue
        # a manifest names files of its own folder only (issue 23, section 2)
        f = inside(folder, r["file"], error=MotionError, what=f"{mpath.name}: file")
        if not f.is_file():
            raise MotionError(f"{mpath}: {r['file']} is missing")
        u = unit_m if unit_m is not None else (float(r["unit_m"]) if r.get("unit_m") else None)
        m = _read(f, u)
        side = (r.get("side") or "").strip()
        role = HIT_ROLE_OF.get((sem, side))
        if role is None:
            raise MotionError(f"{mpath}: {r['file']}: side must be left or right, got {side!r}")
        hf = (r.get("hit_frame") or "").strip()
        hf = int(hf) if hf not in ("",) else -1
        if hf < 0:
            hf = hit_frame_for(m, role, **detect_kw)
        where = (r.get("hit_point") or "joint").strip() or "joint"
        hj = (r.get("hit_joint") or "").strip() or None
        hit = Hit(frame=hf, time=hf * m.frame_time, role=role, semantics=sem, side=side, extension=float("nan"),
                  height=float("nan"), start=hf, stop=hf + 1)
        clips += _clips_from_take(m, Path(r["file"]).stem, fps=fps, window=window, hits=[hit],
                                  kind=(r.get("kind") or "").strip(), level=(r.get("level") or "").strip(),
                                  hit_joint=hj, hit_where=where, tag=False)
    return clips


def _detected_clips(folder: Path, *, unit_m, fps: float, window, detect_kw: Mapping) -> list[Clip]:
    """Every BVH file of ``folder`` searched with :func:`detect_hits` and cut around each strike."""
    clips: list[Clip] = []
    for f in sorted(folder.glob("*.bvh")):
        m = _read(f, unit_m)
        hits = detect_hits(m, **detect_kw)
        clips += _clips_from_take(m, f.stem, fps=fps, window=window, hits=hits)
    return clips


#: Highest database frame rate the builders accept (Hz); the takes are captured at 120 Hz or less.
MAX_FPS: float = 1000.0
#: Longest cut around a hit (s) the builders accept, before or after it.
MAX_WINDOW_S: float = 3600.0


def _window(window) -> tuple[float, float]:
    before, after = as_real_array(window, "window (seconds before and after the hit)", error=MotionError,
                                  shape=(2,)).tolist()
    if not (0 <= before <= MAX_WINDOW_S and 0 <= after <= MAX_WINDOW_S):
        raise MotionError(f"window (seconds before and after the hit) must be in [0, {MAX_WINDOW_S:g}], "
                          f"got ({before}, {after})")
    return before, after


def _build_arguments(fps, window, pose_roles, pose_window, detect_kw) -> tuple:
    """The builders' shared arguments checked (:class:`MotionError` naming the bad one)."""
    fps = as_real(fps, "fps", lo=0.0, lo_open=True, hi=MAX_FPS, error=MotionError)
    if window is not None:
        window = _window(window)
    if isinstance(pose_roles, str):
        raise MotionError(f"pose_roles must be a sequence of role names, got the string {pose_roles!r}")
    try:
        pose_roles = tuple(as_str(r, "pose_roles entry", error=MotionError) for r in pose_roles)
    except TypeError:
        raise MotionError(f"pose_roles must be a sequence of role names, got {describe(pose_roles)}") from None
    if not pose_roles:
        raise MotionError("pose_roles must name at least one role")
    pose_window = as_int(pose_window, "pose_window (frames per pose cloud)", 1, MAX_WINDOW, error=MotionError)
    if detect_kw is not None and not isinstance(detect_kw, Mapping):
        raise MotionError(f"detect_kw must be a mapping of detect_hits thresholds, got {describe(detect_kw)}")
    detect_kw = dict(detect_kw or {})
    bad = [k for k in detect_kw if k not in _DETECT_THRESHOLDS]
    if bad:
        raise MotionError(f"detect_kw: unknown threshold(s) {bad}; known: {list(_DETECT_THRESHOLDS)}")
    return fps, window, pose_roles, pose_window, detect_kw


_DETECT_THRESHOLDS = ("arm_extension", "arm_front", "kick_height", "leg_extension", "merge_gap", "min_duration",
                      "peak_tolerance")


# ================================================================ the real takes
def _dataset_of(path: str) -> str:
    return "bandai" if path.startswith("mocap/bandai/") else "cmu-bvh"


def _take_names(takes, name: str):
    """``takes`` as given (None, or a mapping of take name to kind), or a tuple of take names;
    anything else (a number, a lone string, non-string names) is a :class:`MotionError` naming ``name``."""
    if takes is None:
        return None
    if isinstance(takes, Mapping):
        for k, v in takes.items():
            as_str(k, f"a take name in {name}", error=MotionError)
            as_str(v, f"the kind of take {k!r} in {name}", error=MotionError)
        return takes
    return as_names(takes, name, error=MotionError, item="a take name")


def _cmu135_clips(takes, *, fps: float, window, detect_kw) -> tuple[list[Clip], dict]:
    """The clips of :func:`build_cmu_database` (same reading, detection and cutting)."""
    takes = _take_names(takes, "takes (CMU)")
    if takes is None:
        takes = CMU_TAKES
    if not isinstance(takes, Mapping):
        takes = {t: CMU_TAKES.get(t, "") for t in takes}
    clips: list[Clip] = []
    for take, kind in takes.items():
        m = _read(data.fetch(f"mocap/cmu/{take}.bvh"), CMU_UNIT_M)
        m = dataclasses.replace(m, source=f"mocap/cmu/{take}.bvh")
        sem = "kick" if kind.endswith("kick") else "punch"
        hits = detect_hits(m, semantics=sem, **dict(detect_kw or {}))
        clips += _clips_from_take(m, take, fps=fps, window=window, hits=hits, kind=kind)
    return clips, dict(takes)


def _bandai_clips(takes, *, fps: float, window, detect_kw) -> tuple[list[Clip], dict]:
    takes = _take_names(takes, "takes (Bandai)")
    if takes is None:
        takes = BANDAI_TAKES
    if not isinstance(takes, Mapping):
        unknown = [t for t in takes if t not in BANDAI_TAKES]
        if unknown:
            raise MotionError(f"unknown Bandai strike take(s) {unknown}; known: {sorted(BANDAI_TAKES)}")
        takes = {t: BANDAI_TAKES[t] for t in takes}
    clips: list[Clip] = []
    for take, sem in takes.items():
        check_semantics(sem)
        rel = f"mocap/bandai/{take}.bvh"
        m = _read(data.fetch(rel), BANDAI_UNIT_M)
        m = dataclasses.replace(m, source=rel)
        hits = detect_hits(m, semantics=sem, **dict(detect_kw or {}))
        clips += _clips_from_take(m, take, fps=fps, window=window, hits=hits, kind=f"{sem}_normal")
    return clips, dict(takes)


def build_cmu_database(takes: Mapping[str, str] | Sequence[str] | None = None, *, fps: float = DATABASE_FPS,
                       window: tuple[float, float] = CMU_WINDOW, pose_roles: Sequence[str] = POSE_ROLES,
                       pose_window: int = 1, detect_kw: Mapping | None = None) -> MotionDatabase:
    """The database of the real CMU karate takes (subject 135), cut around detected strikes.

    Each take of :data:`CMU_TAKES` is read in metres (:data:`~repro.motion.CMU_UNIT_M`),
    searched with :func:`detect_hits` (kick drills for kicks, the other takes for arm
    strikes), and every hit becomes a clip from ``window[0]`` s before to ``window[1]`` s
    after it, resampled to ``fps``.  Semantics: ``"kick"`` for kicks, ``"punch"`` for
    every arm strike (the lunge punches of 135_09 and the arm strikes and blocks of the
    katas, kind ``"kata_arm"``).  With the default thresholds this gives 14 kicks, 9
    lunge punches and about 50 kata arm strikes (see ``mocap/cmu/PROVENANCE.md``), about
    the 75 motions of the paper.

    Parameters
    ----------
    takes : mapping take -> kind, or sequence of takes, optional
        Default :data:`CMU_TAKES`.
    fps, window, pose_roles, pose_window, detect_kw
        As :func:`build_database`.

    Raises
    ------
    repro.errors.DataError
        If the staged CMU files are missing (:func:`repro.data.fetch`).
    """
    fps, window, pose_roles, pose_window, detect_kw = _build_arguments(fps, window, pose_roles, pose_window, detect_kw)
    clips, takes = _cmu135_clips(takes, fps=fps, window=window, detect_kw=detect_kw)
    return _detected_database(clips, "mocap/cmu", dict(takes), fps, window, pose_roles, pose_window)


def build_bandai_database(takes: Mapping[str, str] | Sequence[str] | None = None, *, fps: float = DATABASE_FPS,
                          window: tuple[float, float] = CMU_WINDOW, pose_roles: Sequence[str] = POSE_ROLES,
                          pose_window: int = 1, detect_kw: Mapping | None = None) -> MotionDatabase:
    """The database of the Bandai Namco strike takes, cut around detected strikes.

    Each take of :data:`BANDAI_TAKES` is read in metres
    (:data:`~repro.motion.BANDAI_UNIT_M`; the 6-channel joints' position channels
    replace their OFFSET, :func:`~repro.motion.read_bvh`), searched with
    :func:`detect_hits` for strikes of the manifest's semantics only, and every hit
    becomes a clip from ``window[0]`` s before to ``window[1]`` s after it, resampled to
    ``fps`` (the files are at 30 fps already).  Kind ``"kick_normal"`` /
    ``"punch_normal"`` (the dataset's "normal" style).  With the default thresholds:
    3 right kicks (``dataset-1_kick_normal_001``), 2 left punches (``punch_normal_001``)
    and 5 right punches (``punch_normal_002``): 10 clips, as counted in
    ``mocap/bandai/PROVENANCE.md``.

    The actor is the Bandai skeleton itself (one base actor): leg 0.80 m, arm 0.47 m,
    ``size_a`` 1.46 m -- the file has no head-top point and its rest pose does not tell the
    ankle height, so both are estimated (:mod:`repro.motion.body.stature`, the same measure as
    the CMU actor's 1.64 m; up to the ``Head`` joint it would be 1.30 m).  Hit points:
    ``Hand_L``/``Hand_R`` (the wrist; no fist point) and ``Toes_L``/``Toes_R``.

    Raises
    ------
    repro.errors.DataError
        If the staged Bandai files are missing (:func:`repro.data.fetch`).
    """
    fps, window, pose_roles, pose_window, detect_kw = _build_arguments(fps, window, pose_roles, pose_window, detect_kw)
    clips, takes = _bandai_clips(takes, fps=fps, window=window, detect_kw=detect_kw)
    if not clips:
        raise MotionError("no strike found in the Bandai takes")
    return _detected_database(clips, "mocap/bandai", takes, fps, window, pose_roles, pose_window,
                              sources={"bandai": len(clips)})


def build_real_database(include: Sequence[str] = REAL_SOURCES, *, cmu_takes=None, bandai_takes=None,
                        fps: float = DATABASE_FPS, window: tuple[float, float] = CMU_WINDOW,
                        pose_roles: Sequence[str] = POSE_ROLES, pose_window: int = 1,
                        detect_kw: Mapping | None = None) -> MotionDatabase:
    """One database of the real strike clips: CMU subject 135 and/or Bandai Namco.

    ``include`` names the sources (:data:`REAL_SOURCES`): ``"cmu135"`` gives exactly the
    clips of :func:`build_cmu_database`, ``"bandai"`` those of
    :func:`build_bandai_database`, in that order.  The two skeletons have different
    joint trees (31 CMU joints, 22 Bandai joints), so the database holds two base actors
    (:attr:`MotionDatabase.actors`, ``actor`` per clip); pose clouds are role-based
    (:data:`~repro.motion.body.pose_frames.POSE_ROLES`) and share one array and one
    clustering (in practice every k-means cluster holds poses of one family only: the
    clouds are divided by sizes that the two rigs measure differently).

    What the retrieval (:class:`repro.motion.search.retrieval.MotionRetriever`) does with it:
    by default (``across_trees=True``) the current pose is retargeted (Section 3.4.1) to
    every actor -- to the actors of the character's joint tree as on one tree, across
    joint trees (:func:`repro.motion.retargeting.dispatch.retarget_to_tree`) to the other family's
    -- so a CMU character can be served a Bandai clip and the reverse (Eq. 1 is then
    applied between the two rigs' statures, measured the same way on both: floor to the top
    of the head, the parts a rig lacks estimated, :mod:`repro.motion.body.stature`).
    With ``MotionRetriever(db, across_trees=False)`` a CMU character (subject 135, its
    :func:`~repro.motion.scale_skeleton` derivatives and subjects 131, 7 and 9, whose other
    rest directions the retargeting plan's rest step takes) retrieves only CMU clips and a Bandai character only
    Bandai clips (clusters without such poses are skipped: the result then says
    ``fallback="neighbour_clusters"``).

    ``"cmu-walks"`` (non-fighting takes) cannot be included: a database clip needs a hit;
    use :func:`non_fighting_poses`.

    Raises
    ------
    repro.errors.MotionError
        Unknown or empty ``include``.
    repro.errors.DataError
        A needed staged file is missing and cannot be downloaded
        (:func:`repro.data.fetch`).
    """
    fps, window, pose_roles, pose_window, detect_kw = _build_arguments(fps, window, pose_roles, pose_window, detect_kw)
    include = as_names(include, f"include (of {list(REAL_SOURCES)})", error=MotionError, one=True,
                       nonempty=False, item="a source")
    bad = [s for s in include if s not in REAL_SOURCES]
    if bad:
        hint = (" (non-fighting takes are not database clips: use non_fighting_poses())"
                if any("walk" in s or "other" in s for s in bad) else "")
        raise MotionError(f"unknown source(s) {bad}; known: {list(REAL_SOURCES)}{hint}")
    if not include:
        raise MotionError("include names no source")
    clips: list[Clip] = []
    counts: dict[str, int] = {}
    takes: dict[str, dict] = {}
    for s in dict.fromkeys(include):
        if s == "cmu135":
            c, t = _cmu135_clips(cmu_takes, fps=fps, window=window, detect_kw=detect_kw)
        else:
            c, t = _bandai_clips(bandai_takes, fps=fps, window=window, detect_kw=detect_kw)
        clips += c
        counts[s] = len(c)
        takes[s] = t
    if not clips:
        raise MotionError(f"no strike found in {list(include)}")
    return _detected_database(clips, ["mocap/cmu" if s == "cmu135" else "mocap/bandai" for s in counts], takes, fps,
                              window, pose_roles, pose_window, sources=counts)


def _detected_database(clips: list[Clip], built_from, takes: dict, fps: float, window, pose_roles, pose_window: int,
                       **more) -> MotionDatabase:
    """The database of clips cut around detected strikes, its metadata saying from what (and ``more``)."""
    return MotionDatabase.from_clips(clips, pose_roles=pose_roles, window=pose_window,
                                     meta={"built_from": built_from, "takes": takes, "annotations": "detect_hits",
                                           "fps": fps, "window": list(window), **more})


# ================================================================ named databases
def load_or_build(path, build=build_cmu_database, **kw) -> MotionDatabase:
    """Load the database saved at ``path``, or ``build(**kw)`` it and save it there.

    For notebooks: the first run builds (about a second for the CMU takes) and saves
    atomically; later runs load.  Delete the file to rebuild (nothing checks that the
    saved database was built with the same ``kw``).
    """
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise MotionError(f"path must be a file path (str or os.PathLike), got {describe(path)}")
    if not callable(build):
        raise MotionError(f"build must be a function returning a MotionDatabase, got {describe(build)}")
    path = Path(path)
    if path.exists():
        return MotionDatabase.load(path)
    try:
        db = build(**kw)
    except ReproError:
        raise
    except Exception as exc:  # a caller's build function failing: said as ours, its traceback chained
        raise MotionError(f"build {describe(build)} failed: {type(exc).__name__}: {exc}") from exc
    if not isinstance(db, MotionDatabase):
        raise MotionError(f"build returned {describe(db)}, not a MotionDatabase")
    db.save(path)
    return db


def default_database(name: str = "synthetic", seed: int = 0) -> MotionDatabase:
    """A ready database by name, built once per process (each call returns its own copy).

    ``"synthetic"``: the embedded set of :func:`repro.motion.database.synthetic.synthetic_database`
    (75 clips written to a temporary folder, built from its manifest), always available; each
    clip's ``source`` is ``synthetic/seed<seed>/<file>.bvh`` (not the removed temporary folder).
    ``"cmu"``: :func:`build_cmu_database` from the staged CMU takes (needs dataset
    ``cmu-bvh``; raises :class:`~repro.errors.DataError` saying how to get it).
    """
    name = as_choice(name, "name (database)", ("synthetic", "cmu"), error=RetrievalError)
    seed = as_int(seed, "seed", 0, None, error=RetrievalError)
    if name == "synthetic":
        key = ("synthetic", seed)
    else:
        reason = data.missing_reason("cmu-bvh")
        if reason:
            raise DataError(reason)
        key = ("cmu", str(data.data_dir()))
    # a copy each call (~20 ms): a caller changing its database cannot change the next caller's
    return copy.deepcopy(_DEFAULT_DATABASES.get(key, lambda: _default_build(name, seed)))


def _default_build(name: str, seed: int) -> MotionDatabase:
    """:func:`default_database`'s build of ``name``."""
    if name == "cmu":
        return build_cmu_database()
    with tempfile.TemporaryDirectory(prefix="repro-synthetic-") as tmp:
        synthetic_database(tmp, seed=seed)
        built = build_database(tmp)
    # the folder is gone: each clip's source names what it is, the generated set and its file
    built.sources = np.array([f"synthetic/seed{int(seed)}/{Path(s).name}" for s in built.sources.tolist()])
    return built


#: :func:`default_database`'s builds, by (name, seed or data folder): each built once per process, the
#: 8 most recently asked kept (the embedded set's database holds about 8 MB: 2.2 MB of arrays, 5.4 MB of motions)
_DEFAULT_DATABASES: LRUCache[MotionDatabase] = LRUCache(8)


def clip_source_dataset(db: MotionDatabase) -> np.ndarray:
    """(C,) ``"cmu135"`` / ``"bandai"`` / ``""`` for every clip, from its source file."""
    if not isinstance(db, MotionDatabase):
        raise MotionError(f"db must be a MotionDatabase, got {describe(db)}")
    out = np.full(db.n_clips, "", dtype=object)
    for i, s in enumerate(db.sources.tolist()):
        if "mocap/bandai/" in s:
            out[i] = "bandai"
        elif re.search(r"mocap/cmu/135_\d+\.bvh", s):
            out[i] = "cmu135"
    return out.astype(str)


def non_fighting_poses(takes: Sequence[str] | None = None, *, fps: float | None = DATABASE_FPS,
                       kinds: Sequence[str] | None = None, rest_like=None) -> dict[str, Motion]:
    """The non-fighting takes as motions in metres, for the current poses of queries.

    Parameters
    ----------
    takes : sequence of str, optional
        Paths relative to the data folder (keys of :data:`NON_FIGHTING_TAKES`); default
        all of them (CMU 131 walks, CMU 7 slow walk, CMU 9 run, CMU 135_03 walk, Bandai
        walk and bow).  Any staged BVH path is accepted (centimetres under
        ``mocap/bandai/``, CMU units elsewhere).
    fps : float or None, default 30
        Resample to this rate (the database's); None keeps the file's (120 Hz for CMU).
    kinds : sequence of str, optional
        Keep only these kinds of :data:`NON_FIGHTING_TAKES` (``"walk"``, ``"run"``,
        ``"bow"``), e.g. ``("walk", "run")``.
    rest_like : MotionDatabase, Skeleton, Motion or sequence of them, optional
        Put every motion that shares the joint tree of one of these skeletons (for a
        database: of one of its :attr:`~MotionDatabase.actors`) on that skeleton's rest
        directions with :func:`match_rest_pose` (bone lengths and joint positions
        kept), the same poses (the CMU subjects 131, 7 and 9 against the CMU 135 actor,
        whose rest directions differ by 12-14 degrees).  Not needed for the retrieval: its
        retargeting takes another rest pose of the same tree itself
        (:class:`~repro.motion.retargeting.morphology.RestStep`).  Motions with no matching
        joint tree are returned unchanged.

    Returns
    -------
    dict
        Take name (file stem) -> :class:`~repro.motion.Motion` in metres
        (``unit_m = 1``), ``source`` the relative path.  Any frame of it is a
        ``current_pose`` for the retrieval with the motion's own skeleton
        (``Skeleton.from_motion``) as the character: as they are, the Bandai walk and bow
        (against the Bandai actor), CMU 135_03 and the other CMU subjects (against the
        CMU 135 actor).

    Raises
    ------
    repro.errors.DataError
        A needed staged file is missing.
    """
    takes = list(NON_FIGHTING_TAKES) if takes is None else list(as_names(takes, "takes", error=MotionError,
                                                                        item="a take path"))
    if fps is not None:
        fps = as_real(fps, "fps", lo=0.0, lo_open=True, hi=MAX_FPS, error=MotionError)
    if kinds is not None:
        kinds = set(as_names(kinds, "kinds", error=MotionError, item="a kind"))
        takes = [t for t in takes if NON_FIGHTING_TAKES.get(t, ("", "", ""))[1] in kinds]
    refs: list[Skeleton] = []
    if rest_like is not None:
        items = rest_like if isinstance(rest_like, (list, tuple)) else [rest_like]
        for it in items:
            if isinstance(it, MotionDatabase):
                refs += list(it.actors)
            else:
                refs.append(skeleton_of(it))
    out: dict[str, Motion] = {}
    for rel in takes:
        unit = BANDAI_UNIT_M if _dataset_of(rel) == "bandai" else CMU_UNIT_M
        m = _read(data.fetch(rel), unit)
        if fps is not None and abs(m.fps - fps) > 1e-9 * fps:
            m = resample(m, fps)
        m = dataclasses.replace(m, source=rel)
        for sk in refs:
            if sk.is_compatible(m):
                m = dataclasses.replace(match_rest_pose(m, sk), source=rel)
                break
        out[Path(rel).stem] = m
    return out
