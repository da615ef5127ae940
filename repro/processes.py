"""Child processes that end with the process that started them (Linux's parent-death signal).

``repro run``'s workers (:mod:`repro.experiments.registry`), ``repro app``'s Voilà server
(:mod:`repro.ui.app`) and the off-screen render probe (:mod:`repro.ui.render`) ask for it as they
start, so a parent killed by SIGKILL leaves none of them running.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys

__all__ = ["parent_death_signal", "die_with_parent"]

#: prctl's option number for the parent-death signal (linux/prctl.h)
PR_SET_PDEATHSIG = 1


def parent_death_signal(signum: int = signal.SIGKILL) -> bool:
    """Ask Linux to send ``signum`` to this process when its parent dies (``prctl(PR_SET_PDEATHSIG)``);
    whether that was granted (False elsewhere, where the caller watches its parent itself).

    The signal fires when the parent's *thread* that started this process ends.
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return False
    return prctl(PR_SET_PDEATHSIG, ctypes.c_ulong(signum), ctypes.c_ulong(0), ctypes.c_ulong(0),
                 ctypes.c_ulong(0)) == 0


def die_with_parent(parent: int, signum: int = signal.SIGKILL) -> bool:
    """:func:`parent_death_signal`, then end at once (exit status 1) if ``parent``, the pid of the process
    that started this one, is already gone (it died before the signal was asked for: the race prctl leaves
    open); whether the signal was granted.
    """
    granted = parent_death_signal(signum)
    if os.getppid() != parent:
        os._exit(1)
    return granted
