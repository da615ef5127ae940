"""Progress bars of the figures: plain tqdm on stderr, shown only when asked (``progress=True``, as the CLI asks).

Off by default, so a figure computed from code or in a notebook prints nothing, however long
it takes (``tests/test_progress_quiet.py``); shown after one second, so short steps stay quiet.
"""

from __future__ import annotations

import sys

__all__ = ["bar"]


def bar(iterable=None, *, desc: str, total: int | None = None, unit: str = "it", progress: bool = False):
    """A ``tqdm`` bar on stderr over ``iterable`` (or ``total`` steps, advanced with ``update``); disabled
    unless ``progress``.  Not left on screen when done (the CLI's ``figures`` bar stays)."""
    from tqdm import tqdm  # plain bar on stderr, never a notebook widget

    return tqdm(iterable, total=total, desc=desc, unit=unit, delay=1.0, disable=not progress, file=sys.stderr,
                leave=False, dynamic_ncols=True)
