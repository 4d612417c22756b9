"""Ctrl-C (and SIGTERM) held off while compiled code runs, and raised once it has returned.

Python runs its SIGINT handler at the next bytecode, and a numba kernel returns through C code (boxing its result
tuple) that does not expect one: a KeyboardInterrupt raised there crashed ``autosar navigate`` (SIGSEGV on urban,
Ctrl-C 1.9-2.0 s in) or ended it with "CPUDispatcher(...) returned a result with an exception set" (exit 1) instead
of "interrupted" (130). Inside :func:`interrupts_held` a Ctrl-C is only noted; it is raised as a KeyboardInterrupt
when the block ends, so the command still stops, after the kernel, with its writers cleaning up as ever. SIGTERM
(a service manager's or ``timeout``'s stop) is a :class:`Terminated`, a KeyboardInterrupt the command tells apart.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType


class Terminated(KeyboardInterrupt):
    """SIGTERM inside a command: it stops as at Ctrl-C, and says "terminated" (exit 143)."""


@contextmanager
def interrupts_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM for the block (main thread only; elsewhere Python delivers none) and raise
    KeyboardInterrupt (:class:`Terminated`) after it where one came. An exception from the block goes on as it is,
    unless a signal came meanwhile: then the signal's KeyboardInterrupt is raised, the block's error as its cause."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []

    def note(signum: int, frame: FrameType | None) -> None:
        came.append(signum)

    previous = {s: signal.signal(s, note) for s in (signal.SIGINT, signal.SIGTERM)}
    failed: Exception | None = None
    try:
        yield
    except Exception as exc:  # noqa: BLE001 - raised again below
        if not came:
            raise
        # a signal came while the block ran and the block failed, likely of it: a process group's SIGTERM also
        # stops the processes the block starts (a LocalCluster's nanny: "Nanny failed to start"), and the command
        # must stop as at that signal (143, "terminated"), not fail with the error it caused
        failed = exc
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    try:
        for signum in (signal.SIGTERM, signal.SIGINT):  # each handled now as it would have been without this block
            if signum in came:
                handler = previous[signum]
                if callable(handler):  # the command's own (cli._stop), Python's default_int_handler: they raise
                    handler(signum, None)
                elif handler == signal.SIG_DFL:
                    if signum == signal.SIGINT:
                        raise KeyboardInterrupt
                    signal.raise_signal(signum)
    except KeyboardInterrupt as stop:
        if failed is not None:
            raise stop from failed
        raise
    if failed is not None:  # the signals that came were ignored (SIG_IGN): the block's error as it was
        raise failed
