"""The test hook that kills a process at a named point of a write (``SLIPPULSE_KILL_AT=POINT:N``:
SIGKILL the N-th time POINT is reached), so that crash-safety tests and the robustness probe
kill a writer at defined moments of its own progress instead of after a wall-clock delay."""
from __future__ import annotations

import os
import signal

_counts: dict = {}


def kill_point(name: str) -> None:
    """Do nothing unless ``SLIPPULSE_KILL_AT`` names ``name``; then SIGKILL this process the
    N-th time (default 1st) it gets here."""
    spec = os.environ.get("SLIPPULSE_KILL_AT")
    if not spec:
        return
    point, _, n = spec.partition(":")
    if point != name:
        return
    _counts[name] = _counts.get(name, 0) + 1
    if _counts[name] == int(n or 1):
        os.kill(os.getpid(), signal.SIGKILL)
