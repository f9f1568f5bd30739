"""The BLAS libraries' threads for a block: one, for the same bits on any machine (`blas_threads`).

The transport's few dense operations (the AMG hierarchy's coarsest pseudo-inverse) and the mechanics' factorisations
run on the threads they are given here, not on as many as the BLAS library would take.  threadpoolctl's
`threadpool_limits` looks for the loaded libraries on every call (it walks every shared library of the process:
~3-4 ms with what a run has loaded); a run limits them at every output, so a small 2-D case of a sweep (0.2 s)
spent a sixth of its time looking.  The libraries found are kept and looked for again only once a module has been
imported since (`sys.modules` grew): a BLAS is loaded by importing its module (numpy, scipy, pypardiso's MKL).
"""
from __future__ import annotations

import os
import sys
import threading

from threadpoolctl import ThreadpoolController

_found: tuple[int, ThreadpoolController] | None = None
_looking = threading.Lock()


def _unlocked_in_child() -> None:
    """A process forked while another thread looked has the lock held by nobody: a new one (what was found stays:
    the libraries are the parent's)."""
    global _looking
    _looking = threading.Lock()


os.register_at_fork(after_in_child=_unlocked_in_child)


def _controller() -> ThreadpoolController:
    """The loaded BLAS libraries, looked for again when a module has been imported since the last look."""
    global _found
    with _looking:
        if _found is None or _found[0] != len(sys.modules):
            loaded = len(sys.modules)
            _found = (loaded, ThreadpoolController())
        return _found[1]


def blas_threads(limits: int | None = 1):
    """A context manager: the BLAS libraries on `limits` threads inside the block (None: as they are), as
    ``threadpool_limits(limits, user_api="blas")``; the libraries' own settings back after it."""
    return _controller().limit(limits=limits, user_api="blas")
