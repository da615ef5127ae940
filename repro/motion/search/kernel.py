"""The exact search's branch and bound, compiled (numba).

:meth:`repro.motion.search.exact.ExactSearch.search`, which calls it, states the bounds; this module
runs the same cascade over the clip runs (groups) of one semantics in one compiled call:

1. the query's terms and, per cluster, ``lq = max(D(q_r, m) - r, 0)`` (centroid ``m``, radius ``r``),
   the clusters ordered by ``D(q_r, m)``; per clip, the gap between ``c_hat`` and its
   hit-trajectory box (units of its actor's size);
2. a first best ``d``: the ``batch`` groups of lowest bound among those of the clusters nearest
   ``q_r``, and the ``batch`` groups of lowest bound among those of the clips passing nearest
   ``c_hat`` (the nearest trajectory samples give their exact ``d_cr``; found on a uniform grid of
   the samples, :func:`_nearest_samples`: scipy's k-d tree costs 60-130 us per query here in call
   overhead alone, measured, against a few us in the compiled call);
3. every clip whose bound ``s (w_q min lq + w_c gap)`` can beat it gets its exact ``d_cr``,
   and its groups whose bound ``s w_q lq + w_c d_cr`` can beat it are candidates;
4. the candidates, lowest bound first, scored pose by pose until the next bound exceeds the
   best ``d`` (within :data:`repro.motion.search.results.NEAR_RTOL`, so that every pose the
   exhaustive scan would re-score is scored here too); a group of more than one pose is first
   bounded by its own centroid ``m_g`` and radius ``r_g``, ``s w_q max(D(q_r, m_g) - r_g, 0) +
   w_c d_cr``, and skipped when that exceeds the best ``d`` (measured on CMU at 100x: 912 poses
   scored at the median without it, 310 with it, for about 230 centroid distances).

Why compiled (measured on the CMU database at 100x, 198,207 poses, on a 2-core VM whose speed
varied by 1.5x within the hour): the numpy cascade scores about 1,000 poses and measures about
800 clips per query, yet took 1.7-2.5 ms at the median (about 690 Python-level calls per search,
cProfile) against 10-15 ms for the exhaustive scan, which streams every pose through one matrix
product.  Interleaved in one process, 300 queries: numpy cascade p50 2.5 ms / p99 9.8 ms, this
kernel's first version 1.9 / 3.8 ms; with the query's terms and the cluster bounds moved in
here, 0.8-1.7 ms (``time_search``, by the machine's load).  Later, on a slower VM (exhaustive
17-23 ms), four processes alternating with the commit before the three changes that followed
(``time_search``, 300 queries): 0.81-1.39 ms at the median before them, 0.72-0.95 ms after
them (the clips' group clusters read clip by clip, step 3; the runs' own bound, step 4; the grid
for step 2), 22.9-30.0x faster than the exhaustive scan against 12.6-21.4x.  Where the rest goes, at
the median (stage timers inside the kernel, CMU 100x): ~0.1 ms the query's terms, box gaps and
nearest samples, ~0.2 ms the seeds, ~0.25 ms step 3 (about 690 clips pass the box bound, 600
get their segments measured, 80 are within reach), ~0.2 ms step 4.  The arithmetic is that of the numpy
scoring (the closed form of :meth:`~repro.motion.search.distance.AlignedPoseIndex.distances` for ``D``); sums
round differently in the last bits, which the near-best re-scoring of
:func:`~repro.motion.search.results.select` absorbs: both searches report the same
pose with the same numbers.  Compiled once per machine and source (``cache=True``): about 9 s
on a fresh install, then about 0.3 s to load in a new process, plus about 1 s to import numba,
which only the exact search imports.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["compile_search", "search_first"]


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _pose_distance(M, j, qp, qs, X, Z, H, Y2):  # pragma: no cover - compiled
    """Kovar et al.'s aligned distance of stored pose ``j`` to the query (the closed form of
    :meth:`~repro.motion.search.distance.AlignedPoseIndex.distances`; ``qp`` (3, P) the query's x, y, z:
    the products ``M @ Q`` without the zeros of ``Q``)."""
    P = qp.shape[1]
    r0 = 0.0
    r1 = 0.0
    r2 = 0.0
    for i in range(P):
        mx = M[j, i]
        mz = M[j, P + i]
        r0 += mx * qp[0, i] + mz * qp[2, i]
        r1 += mz * qp[0, i] - mx * qp[2, i]
        r2 += M[j, 2 * P + i] * qp[1, i]
    Xa, Za, Ha, Ya2 = qs[0], qs[1], qs[2], qs[3]
    a = r0 - (Xa * X[j] + Za * Z[j])
    b = r1 - (Xa * Z[j] - Za * X[j])
    d2 = Ya2 - 2.0 * r2 + Y2[j] + Ha + H[j] - 2.0 * np.sqrt(a * a + b * b)
    return np.sqrt(d2) if d2 > 0.0 else 0.0


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _cloud_distance(C, g, qp, qs, w):  # pragma: no cover - compiled
    """The aligned distance of cloud ``C[g]`` (P, 3), float32, to the query: :func:`_pose_distance` with
    the cloud's terms formed on the way (the clip runs' centroids are kept as clouds, not terms)."""
    P = qp.shape[1]
    X = 0.0
    Z = 0.0
    H2 = 0.0
    Y2 = 0.0
    r0 = 0.0
    r1 = 0.0
    r2 = 0.0
    for i in range(P):
        x = np.float64(C[g, i, 0])
        y = np.float64(C[g, i, 1])
        z = np.float64(C[g, i, 2])
        mx = w[i] * x
        mz = w[i] * z
        my = w[i] * y
        X += mx
        Z += mz
        H2 += mx * x + mz * z
        Y2 += my * y
        r0 += mx * qp[0, i] + mz * qp[2, i]
        r1 += mz * qp[0, i] - mx * qp[2, i]
        r2 += my * qp[1, i]
    Xa, Za, Ha, Ya2 = qs[0], qs[1], qs[2], qs[3]
    a = r0 - (Xa * X + Za * Z)
    b = r1 - (Xa * Z - Za * X)
    d2 = Ya2 - 2.0 * r2 + Y2 + Ha + (H2 - (X * X + Z * Z)) - 2.0 * np.sqrt(a * a + b * b)
    return np.sqrt(d2) if d2 > 0.0 else 0.0


@numba.njit(cache=True, nogil=True)
def _clip_dcr(tpts, tstart, tlen, sbox, useg, seg, u, c_hat, limit):  # pragma: no cover - compiled
    """Closest approach of clip ``u``'s trajectory samples (units of size) to ``c_hat`` when it is at
    most ``limit``, else inf.  The samples come in segments of ``seg`` with their boxes
    (``sbox`` (n, 6) low and high corners, ``useg`` the clip's segments): a segment whose box is
    farther than the nearest sample so far (or than ``limit``) is skipped.  The box gap is formed with
    the same roundings as a sample's distance and never exceeds it, so the minimum is exact."""
    m2 = limit * limit
    best = np.inf
    end = tstart[u] + tlen[u]
    for k in range(useg[u], useg[u + 1]):
        g2 = 0.0
        for a in range(3):
            lo = sbox[k, a] - c_hat[a]
            if lo > 0.0:
                g2 += lo * lo
            else:
                hi = c_hat[a] - sbox[k, 3 + a]
                if hi > 0.0:
                    g2 += hi * hi
        if g2 > m2:
            continue
        t0 = tstart[u] + seg * (k - useg[u])
        for t in range(t0, min(t0 + seg, end)):
            dx = tpts[t, 0] - c_hat[0]
            dy = tpts[t, 1] - c_hat[1]
            dz = tpts[t, 2] - c_hat[2]
            v = dx * dx + dy * dy + dz * dz
            if v < best:
                best = v
                if v < m2:
                    m2 = v
    return np.sqrt(best) if best <= limit * limit else np.inf


@numba.njit(cache=True, nogil=True)
def _nearest_samples(c, k, glo, gh, gdims, gcell, gorder, pts, label):  # pragma: no cover - compiled
    """The ``k`` samples nearest ``c`` of a uniform grid (:func:`repro.motion.search.exact.sample_grid`), by increasing distance:
    ``(clip, distance)`` of each (fewer when the grid holds fewer).  Exact: the cells are visited in
    rings of growing Chebyshev index distance ``r`` around the cell of ``c`` (clamped to the grid), and
    a sample of a cell at ``r`` or more is farther than ``(r - 1) gh`` from ``c``, edge cells included
    (they extend to infinity), so the search stops before ring ``r`` once the ``k``-th distance is within
    that.  Ties keep the sample met first."""
    ci = np.empty(3, np.int64)
    rmax = 0
    for a in range(3):
        v = (c[a] - glo[a]) / gh
        i = 0 if v < 0.0 else (gdims[a] - 1 if v >= gdims[a] else int(v))
        ci[a] = min(i, gdims[a] - 1)
        rmax = max(rmax, ci[a], gdims[a] - 1 - ci[a])
    k = min(k, gorder.size)
    bd = np.full(k, np.inf)  # squared distances, ascending
    bc = np.full(k, -1, np.int64)
    if k == 0:
        return bc, bd
    for r in range(rmax + 1):
        if r >= 1 and bd[k - 1] <= ((r - 1) * gh) ** 2:
            break
        # the ring's rows inside the grid only (a far target on a long thin grid would otherwise loop
        # over (2 r + 1)^2 rows a ring, for r up to the grid's length)
        for dz in range(max(-r, -ci[2]), min(r, gdims[2] - 1 - ci[2]) + 1):
            z = ci[2] + dz
            for dy in range(max(-r, -ci[1]), min(r, gdims[1] - 1 - ci[1]) + 1):
                y = ci[1] + dy
                full = abs(dz) == r or abs(dy) == r  # on a face of the ring: the whole row, else its two ends
                step = 1 if full else 2 * r
                for dx in range(-r, r + 1, step):
                    x = ci[0] + dx
                    if x < 0 or x >= gdims[0]:
                        continue
                    cell = (z * gdims[1] + y) * gdims[0] + x
                    for i in range(gcell[cell], gcell[cell + 1]):
                        t = gorder[i]
                        ex = pts[t, 0] - c[0]
                        ey = pts[t, 1] - c[1]
                        ez = pts[t, 2] - c[2]
                        d2 = ex * ex + ey * ey + ez * ez
                        if d2 < bd[k - 1]:
                            j = k - 1
                            while j > 0 and bd[j - 1] > d2:
                                bd[j] = bd[j - 1]
                                bc[j] = bc[j - 1]
                                j -= 1
                            bd[j] = d2
                            bc[j] = label[t]
    n = 0
    while n < k and bc[n] >= 0:
        n += 1
    return bc[:n], np.sqrt(bd[:n])


@numba.njit(cache=True, nogil=True)
def _argsort(keys):  # pragma: no cover - compiled
    """Stable argsort (bottom-up merge sort).  Ours, not ``np.argsort``: numba compiles its sorts in
    about 2.5 s each (measured), this in a fraction of that, for the same order."""
    n = keys.size
    a = np.arange(n)
    b = np.empty(n, np.int64)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j, k = lo, mid, lo
            while i < mid and j < hi:
                if keys[a[j]] < keys[a[i]]:
                    b[k] = a[j]
                    j += 1
                else:
                    b[k] = a[i]
                    i += 1
                k += 1
            while i < mid:
                b[k] = a[i]
                i += 1
                k += 1
            while j < hi:
                b[k] = a[j]
                j += 1
                k += 1
        a, b = b, a
        width *= 2
    return a


@numba.njit(cache=True, nogil=True)
def _lowest(lb, ids, batch):  # pragma: no cover - compiled
    """The ``batch`` ids of lowest ``lb`` (all when fewer), ties to the earlier entry."""
    if ids.size <= batch:
        return ids
    return ids[_argsort(lb)[:batch]]


@numba.njit(cache=True, nogil=True)
def search_first(c_hat, qpts, weights, cM, cX, cZ, cH, cY2, radius, gslot, gcl, gs, gstart, gu, ugroups,
                 ustart, ucl, uslot, ulo, uhi, usize, tpts, tstart, tlen, sbox, useg, seg, M, perm, X, Z, H, Y2, psize,
                 gcent, gci, gradius,
                 wq, wc, near_rtol, near_atol, slack, clstart, glo, gh, gdims, gcell, gorder, tclip, n_near,
                 batch):  # pragma: no cover - compiled
    """The poses scored by the branch and bound (see the module docstring).

    Arrays of one semantics: groups (``gslot`` the query slot of the group's actor, -1 for
    an actor the query does not have; ``gcl`` cluster, ``gs`` actor size, ``gstart``
    offsets of its poses, ``gu`` clip), clips (``ugroups``/``ustart`` their groups,
    ``ulo``/``uhi`` (U, 3) boxes, ``tpts``/``tstart``/``tlen`` trajectory samples in units
    of size and ``sbox``/``useg`` the boxes of their segments of ``seg`` samples (:func:`_clip_dcr`),
    ``usize``; ``ucl`` the cluster of each group of ``ugroups``, ``uslot`` the clip's query slot), poses
    (``M``, ``X``, ``Z``, ``H``, ``Y2`` the index terms at ``perm[p]``, ``psize``), and the groups'
    centroids (``gcent`` (n, P, 3) float32 those of the runs of more than one pose, ``gci`` (G,) int32 a
    group's row in it or -1, ``gradius`` (G,) the radii).  Clusters: ``cM, cX, cZ, cH, cY2`` the index terms of the centroids, ``radius``
    (k,) their radii, ``clstart`` group offsets per cluster.  Query: ``qpts`` (slots, 3, P) the
    query clouds by coordinate (``weights`` (P,) the point weights).  The trajectory samples on a
    grid (``glo, gh, gdims, gcell, gorder``, :func:`repro.motion.search.exact.sample_grid`; ``tclip`` the clip of each sample): the
    ``n_near`` nearest ``c_hat`` seed the search, and the first sample of a clip among them gives its
    exact ``d_cr``.

    Returns ``(pos, d, n_groups, clusters_visited)``: the positions and ``d`` of every pose
    scored, the number of groups scored and of their distinct clusters.
    """
    G = gs.size
    U = usize.size
    S = qpts.shape[0]
    K = radius.size
    # 1. the query's terms (as AlignedPoseIndex.query_matrix), the cluster bounds, clusters by distance
    qscal = np.empty((S, 4))
    for s in range(S):
        xa, ya, za = qpts[s, 0], qpts[s, 1], qpts[s, 2]
        Xa = (xa * weights).sum()
        Za = (za * weights).sum()
        qscal[s, 0] = Xa
        qscal[s, 1] = Za
        qscal[s, 2] = ((xa * xa + za * za) * weights).sum() - (Xa * Xa + Za * Za)
        qscal[s, 3] = (ya * ya * weights).sum()
    lq = np.empty((S, K))
    dmin = np.full(K, np.inf)
    for cl in range(K):
        for s in range(S):
            dc = _pose_distance(cM, cl, qpts[s], qscal[s], cX, cZ, cH, cY2)
            lq[s, cl] = max(dc - radius[cl] - slack, 0.0)
            if clstart[cl + 1] > clstart[cl] and dc < dmin[cl]:
                dmin[cl] = dc
    cl_order = _argsort(dmin)
    gap = np.empty(U)
    for u in range(U):  # the box gap written out, as in _clip_dcr: a helper taking row views measured 15-25 % slower
        g2 = 0.0
        for k in range(3):
            v = max(ulo[u, k] - c_hat[k], c_hat[k] - uhi[u, k])
            if v > 0.0:
                g2 += v * v
        gap[u] = max(np.sqrt(g2) - slack, 0.0)
    dcr = np.zeros(U)
    known = np.zeros(U, np.bool_)
    near_clip, near_dist = _nearest_samples(c_hat, n_near, glo, gh, gdims, gcell, gorder, tpts, tclip)
    near_u = np.empty(near_clip.size, np.int64)
    nn = 0
    for i in range(near_clip.size):
        u = near_clip[i]
        if not known[u]:
            dcr[u] = near_dist[i] * usize[u]
            known[u] = True
            near_u[nn] = u
            nn += 1
    near_u = near_u[:nn]
    scored = np.zeros(G, np.bool_)
    visited = np.zeros(clstart.size - 1, np.bool_)
    cap = 1024
    out_pos = np.empty(cap, np.int64)
    out_d = np.empty(cap)
    n_out = 0
    n_groups = 0
    best = np.inf

    # 2. seeds: the clusters nearest q_r (8 batch groups), then the clips nearest c_hat
    seeds = np.empty(0, np.int64)
    if G <= batch:
        seeds = np.arange(G)
    else:
        n = 0
        for ci in range(cl_order.size):
            cl = cl_order[ci]
            n += clstart[cl + 1] - clstart[cl]
            if n >= 8 * batch:
                break
        ids = np.empty(n, np.int64)
        lb = np.empty(n)
        m = 0
        tot = 0
        for ci in range(cl_order.size):
            cl = cl_order[ci]
            for g in range(clstart[cl], clstart[cl + 1]):
                s = gslot[g]
                if s >= 0:
                    ids[m] = g
                    lb[m] = gs[g] * (wq * lq[s, cl] + wc * gap[gu[g]])
                    m += 1
            tot += clstart[cl + 1] - clstart[cl]
            if tot >= 8 * batch:
                break
        seeds = _lowest(lb[:m], ids[:m], batch)
        n = 0
        for i in range(near_u.size):
            n += ustart[near_u[i] + 1] - ustart[near_u[i]]
        ids = np.empty(n, np.int64)
        lb = np.empty(n)
        m = 0
        for i in range(near_u.size):
            u = near_u[i]
            for a in range(ustart[u], ustart[u + 1]):
                g = ugroups[a]
                s = gslot[g]
                if s >= 0:
                    ids[m] = g
                    lb[m] = gs[g] * wq * lq[s, gcl[g]] + wc * dcr[u]
                    m += 1
        seeds = np.concatenate((seeds, _lowest(lb[:m], ids[:m], batch)))
    cand = np.empty(seeds.size, np.int64)
    nc = 0
    for i in range(seeds.size):
        g = seeds[i]
        if gslot[g] >= 0 and not scored[g]:
            scored[g] = True
            cand[nc] = g
            nc += 1
    for pass_ in range(2):
        if pass_ == 1:
            # 3. the clips within reach of the best d, then their groups
            thr = best + near_rtol * abs(best) + near_atol
            cand = np.empty(G, np.int64)
            clb = np.empty(G)
            nc = 0
            for u in range(U):
                s = uslot[u]
                base = wc * usize[u] * gap[u]
                if s < 0 or base > thr:
                    continue
                # s w_q lq of the clip's groups by clip (ucl): read in order, not through ugroups (cache misses,
                # measured 0.5 ms of 0.85 at CMU 100x); (s w_q) min lq is min (s w_q) lq, rounding being monotone
                sw = usize[u] * wq
                lqm = np.inf
                for a in range(ustart[u], ustart[u + 1]):
                    v = lq[s, ucl[a]]
                    if v < lqm:
                        lqm = v
                lqm = sw * lqm
                if lqm + base > thr:
                    continue
                if not known[u]:  # exact when within reach (with rounding slack), else out of reach
                    reach = _clip_dcr(tpts, tstart, tlen, sbox, useg, seg, u, c_hat,
                                      (thr - lqm) / (wc * usize[u]) * (1.0 + 1e-9) + slack)
                    if reach == np.inf:
                        continue
                    dcr[u] = reach * usize[u]
                    known[u] = True
                if lqm + wc * dcr[u] > thr:
                    continue
                for a in range(ustart[u], ustart[u + 1]):
                    g = ugroups[a]
                    if scored[g]:
                        continue
                    v = sw * lq[s, ucl[a]] + wc * dcr[u]
                    if v <= thr:
                        cand[nc] = g
                        clb[nc] = v
                        nc += 1
            order = _argsort(clb[:nc])
            cand = cand[:nc][order]
            clb = clb[:nc][order]
        # 4. score the groups (the seeds; then the candidates, lowest bound first)
        for i in range(nc):
            g = cand[i]
            if pass_ == 1 and clb[i] > best + near_rtol * abs(best) + near_atol:
                break
            s = gslot[g]
            u = gu[g]
            if not known[u]:
                dcr[u] = _clip_dcr(tpts, tstart, tlen, sbox, useg, seg, u, c_hat, np.inf) * usize[u]
                known[u] = True
            if gci[g] >= 0:  # a run of more than one pose: its own bound (one distance, to its centroid)
                dg = _cloud_distance(gcent, gci[g], qpts[s], qscal[s], weights)
                if gs[g] * wq * max(dg - gradius[g] - slack, 0.0) + wc * dcr[u] > best + near_rtol * abs(best) + near_atol:
                    continue
            n_groups += 1
            visited[gcl[g]] = True
            for p in range(gstart[g], gstart[g + 1]):
                d = wq * (_pose_distance(M, perm[p], qpts[s], qscal[s], X, Z, H, Y2) * psize[p]) + wc * dcr[u]
                if n_out == cap:
                    cap *= 2
                    grow_p = np.empty(cap, np.int64)
                    grow_p[:n_out] = out_pos[:n_out]
                    out_pos = grow_p
                    grow_d = np.empty(cap)
                    grow_d[:n_out] = out_d[:n_out]
                    out_d = grow_d
                out_pos[n_out] = p
                out_d[n_out] = d
                n_out += 1
                if d < best:
                    best = d
    return out_pos[:n_out], out_d[:n_out], n_groups, int(visited.sum())


def compile_search() -> None:
    """Compile :func:`search_first` (or load it from numba's cache) on a one-pose problem, with the
    argument types of :meth:`~repro.motion.search.exact.ExactSearch.search`: the
    first exact search of a process then costs what the others do (the fighter calls it at set-up)."""
    i1, f1, f3 = np.zeros(1, np.intp), np.zeros(1), np.zeros((1, 3))
    search_first(np.zeros(3), np.zeros((1, 3, 1)), np.ones(1), f3, f1, f1, f1, f1, f1, i1, i1, np.ones(1),
                 np.array([0, 1], np.intp), i1, i1, np.array([0, 1], np.intp), i1, i1, f3, f3, np.ones(1), f3, i1,
                 np.ones(1, np.intp), np.zeros((1, 6)), np.array([0, 1], np.intp), 8, f3, i1, f1, f1, f1, f1, np.ones(1), np.zeros((1, 1, 3), np.float32), np.zeros(1, np.int32), f1, 1.0, 1.0, 1e-9, 1e-7, 1e-6,
                 np.array([0, 1], np.intp), np.zeros(3), 1.0, np.ones(3, np.intp), np.array([0, 1], np.intp), i1.astype(np.int32), i1, 64, 32)
