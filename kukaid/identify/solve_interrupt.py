"""Ctrl-C during an IPOPT solve stops the command as Ctrl-C does everywhere else.

CasADi checks Python's signals between IPOPT's iterations; on Ctrl-C it swallows the
KeyboardInterrupt, prints ``CasADi - ... WARNING("KeyboardInterruptException")`` on stderr and ends
the solve with status ``NonIpopt_Exception_Thrown`` (or raises a RuntimeError from a Python
callback), so a fit cut short by the user would say it "did not converge" and exit 1.
:func:`interruptible_solve` remembers a SIGINT that arrives during the solve, keeps CasADi's line
about it off stderr and raises KeyboardInterrupt once the solve has returned (the CLI: ``kukaid:
error: interrupted``, exit status 130). Nothing else changes: the solve, its result and any other
output on stderr are as without it.
"""
from __future__ import annotations

import contextlib
import io
import signal
import sys
import threading
from typing import Iterator


@contextlib.contextmanager
def interruptible_solve() -> Iterator[None]:
    """Run the solve in the ``with`` block; a SIGINT during it raises KeyboardInterrupt after it.

    Outside the main thread (a signal handler can only be set there), or when SIGINT is ignored or
    left to its default action, the block runs as it is."""
    prev = signal.getsignal(signal.SIGINT)
    if threading.current_thread() is not threading.main_thread() or not callable(prev):
        yield
        return
    hits: list[int] = []

    def on_sigint(signum, frame):
        hits.append(signum)
        prev(signum, frame)  # Python's default handler raises KeyboardInterrupt, which CasADi catches

    err = io.StringIO()
    signal.signal(signal.SIGINT, on_sigint)
    try:
        with contextlib.redirect_stderr(err):
            try:
                yield
            except (RuntimeError, KeyboardInterrupt):
                if not hits:
                    raise
    finally:
        signal.signal(signal.SIGINT, prev)
        if not hits:
            sys.stderr.write(err.getvalue())  # what the solve printed, when it was not about Ctrl-C
    if hits:
        raise KeyboardInterrupt
