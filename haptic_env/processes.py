"""Child processes that end with their parent: the one owner of Linux's ``PR_SET_PDEATHSIG``."""

from __future__ import annotations

import os
import signal
import sys

__all__ = ["die_with_parent"]


def die_with_parent(parent: int | None = None, sig: int = signal.SIGTERM) -> None:
    """In a child process: have the kernel send it ``sig`` when its parent dies (Linux ``PR_SET_PDEATHSIG``; elsewhere
    nothing), so that a parent killed alone (SIGKILL) leaves no child running. For a subprocess's ``preexec_fn`` and a
    process pool's ``initializer`` (``initargs=(os.getpid(),)``: a parent that died before this call is caught too)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, sig)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if parent is not None and os.getppid() != parent:
        os.kill(os.getpid(), sig)
