"""A pairwise covering set of option combinations (issue 24: options tested pairwise, not one flag at a time).

:func:`pairwise` returns rows (one value per factor) in which every pair of values of every two
factors occurs at least once: greedy and deterministic, a few more rows than the optimum (the
package ``allpairspy`` does the same; twenty lines here save a dependency).
"""

from __future__ import annotations

from itertools import combinations


def _pairs(names: list[str], row: dict) -> set:
    return {(a, repr(row[a]), b, repr(row[b])) for a, b in combinations(names, 2)}


def pairwise(factors: dict[str, tuple]) -> list[dict]:
    """Rows covering every pair of values of every two factors (``factors``: name -> values)."""
    names = list(factors)
    todo = set()
    for a, b in combinations(names, 2):
        todo |= {(a, repr(va), b, repr(vb)) for va in factors[a] for vb in factors[b]}
    rows = []
    while todo:
        a, _, b, _ = min(todo)
        va, vb = next((va, vb) for va in factors[a] for vb in factors[b] if (a, repr(va), b, repr(vb)) in todo)
        row = {a: va, b: vb}
        for n in names:
            if n not in row:  # the value that covers the most pairs still to cover with the values chosen
                row[n] = max(factors[n], key=lambda v: sum(_key(names, m, row[m], n, v) in todo for m in row))
        rows.append({n: row[n] for n in names})
        todo -= _pairs(names, row)
    return rows


def _key(names: list[str], m: str, vm, n: str, vn) -> tuple:
    """The pair ``(m = vm, n = vn)`` as :func:`pairwise` stores it (factors in their given order)."""
    if names.index(m) < names.index(n):
        return (m, repr(vm), n, repr(vn))
    return (n, repr(vn), m, repr(vm))
