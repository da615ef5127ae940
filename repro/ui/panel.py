"""What the ipywidgets panels of both papers share (``repro.ui.face_panel``, ``repro.ui.fighter_panel``)."""

from __future__ import annotations

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
