"""What the ipywidgets panels of both papers share (``repro.ui.face_panel``, ``repro.ui.fighter_panel``):
guarded callbacks, batched updates and the reading back of a numbers line."""

from __future__ import annotations

import re
from collections.abc import Collection, Mapping
from contextlib import contextmanager


class PanelCallbacks:
    """Guarded callbacks and batched updates for a widget panel.

    A subclass sets ``self._batch_depth = 0`` and implements :meth:`_show_error`
    (shows an error in the panel) and :meth:`_flush` (applies the update deferred
    while a batch was open).
    """

    _batch_depth = 0

    def _show_error(self, exc: BaseException) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _flush(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _guarded(self, func):
        """A widget callback that shows an error in the panel instead of raising."""

        def callback(*args):
            try:
                func(*args)
            except Exception as exc:  # noqa: BLE001 - a callback must not raise into the kernel's log
                self._show_error(exc)

        return callback

    @contextmanager
    def _batch(self):
        """Defer updates until the outermost batch ends (one update for several widget changes)."""
        self._batch_depth += 1
        try:
            yield
        finally:
            self._batch_depth -= 1
            if self._batch_depth == 0:
                self._flush()


def parse_numbers_line(text: str, fields: Mapping[str, str], text_fields: Collection[str], *, pattern: str,
                       panel: str) -> dict:
    """A panel's numbers line (``label: value | label: value ...``) back as a dict.

    ``pattern`` matches one ``label: value`` part (the label its first group, the value its second);
    ``fields`` maps each label to its key, every one of which must be present; a value is a float
    unless its key is in ``text_fields``.  Raises ``ValueError`` naming ``panel`` for anything else.
    """
    out = {}
    for part in text.strip().split(" | "):
        m = re.fullmatch(pattern, part.strip())
        if not m or m.group(1) not in fields:
            raise ValueError(f"not a numbers line of {panel}: {text!r}")
        key = fields[m.group(1)]
        out[key] = m.group(2) if key in text_fields else float(m.group(2))
    if set(out) != set(fields.values()):
        raise ValueError(f"not a numbers line of {panel}: {text!r}")
    return out
