"""The one cache of the motion library: a bounded map, least recently used evicted first.

What a slider move or a new order does not change (role tables, retargeting constants, a
database's retrieval index) is made once and kept here; every cache states its bound where it
is made.  ``functools.lru_cache`` serves where the key is the arguments themselves; this is for
keys built from arrays (their bytes) or objects, and for caches an owner clears.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

from repro.checks import as_int
from repro.errors import MotionError

V = TypeVar("V")

__all__ = ["LRUCache"]


class LRUCache(Generic[V]):
    """At most ``maxsize`` values by key; :meth:`get` makes a missing one and evicts the oldest.

    Thread-safe: concurrent :meth:`get` calls of one key may each make the value (``make`` runs
    outside the lock, so a slow build never blocks other keys); the first one stored is kept.
    """

    def __init__(self, maxsize: int) -> None:
        self.maxsize = as_int(maxsize, "maxsize", 1, 2**31, error=MotionError)
        self._items: OrderedDict[Hashable, V] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Hashable, make: Callable[[], V]) -> V:
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        value = make()
        with self._lock:
            if key in self._items:
                return self._items[key]
            self._items[key] = value
            while len(self._items) > self.maxsize:
                self._items.popitem(last=False)
        return value

    def clear(self) -> None:
        with self._lock:
            self._items.clear()

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, key: Hashable) -> bool:
        return key in self._items
