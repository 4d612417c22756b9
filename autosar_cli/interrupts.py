"""Ctrl-C held off while compiled code runs, and raised once it has returned.

Python runs its SIGINT handler at the next bytecode, and a numba kernel returns through C code (boxing its result
tuple) that does not expect one: a KeyboardInterrupt raised there crashed ``autosar navigate`` (SIGSEGV on urban,
Ctrl-C 1.9-2.0 s in) or ended it with "CPUDispatcher(...) returned a result with an exception set" (exit 1) instead
of "interrupted" (130). Inside :func:`interrupts_held` a Ctrl-C is only noted; it is raised as a KeyboardInterrupt
when the block ends, so the command still stops, after the kernel, with its writers cleaning up as ever.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType


@contextmanager
def interrupts_held() -> Iterator[None]:
    """Hold SIGINT for the block (main thread only; elsewhere Python delivers none) and raise KeyboardInterrupt
    after it where one came. An exception from the block itself goes on as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []

    def note(signum: int, frame: FrameType | None) -> None:
        came.append(signum)

    previous = signal.signal(signal.SIGINT, note)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if came:
        raise KeyboardInterrupt
