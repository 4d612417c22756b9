"""autosar: navigation-aided automotive SAR, from drive logs to centimetre-accurate radar maps."""

from __future__ import annotations

__version__ = "0.1.0"


def exit_interrupted(signum: int, frame: object) -> None:
    """SIGINT and SIGTERM handler of the ``autosar`` command outside a command's body (while it imports, parses its
    arguments, or has finished): "interrupted" (SIGINT, exit 130) or "terminated" (SIGTERM, 143), no traceback. A
    command's body (``cli._errors``) raises a KeyboardInterrupt instead (:mod:`autosar_cli.interrupts`), so that
    its writers stop and remove their partial files."""
    import os
    import signal

    os.write(2, b"error: terminated\n" if signum == signal.SIGTERM else b"error: interrupted\n")
    os._exit(128 + signum)


def _quiet_interrupt_while_starting() -> None:
    """Install :func:`exit_interrupted` for the console script (a library import leaves the signals alone)."""
    import os
    import sys

    if os.path.basename(sys.argv[0]) in ("autosar", "autosar.exe") or sys.argv[0].endswith(
            os.path.join("autosar_cli", "cli.py")):  # a process `python -m autosar_cli.cli` spawns runs it by path
        install_interrupt_handlers()


def install_interrupt_handlers() -> None:
    """:func:`exit_interrupted` for SIGINT and SIGTERM where Python's defaults are in place, as the command's (the
    console script at its import, ``python -m autosar_cli.cli`` before it runs). A process the command spawns
    (batch's Dask workers) ignores SIGINT and SIGTERM: a terminal's Ctrl-C or a service manager's stop reaches the
    whole process group, and the command stops its workers itself (each printed a traceback of whatever it was
    importing, and the scheduler its lost connections; their nanny kills one that does not stop when asked)."""
    import signal
    import sys

    mp = sys.modules.get("multiprocessing")
    if mp is not None and mp.current_process().name != "MainProcess":  # named before the script is run in it
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        return
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, exit_interrupted)
    if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:  # a service manager's or `timeout`'s stop
        signal.signal(signal.SIGTERM, exit_interrupted)


_quiet_interrupt_while_starting()


def _prefer_wide_vectors() -> None:
    """Let numba emit 512-bit vectors on AVX-512 CPUs.

    LLVM prefers 256-bit vectors there by default (to spare the clock); the back-projection kernel, pure
    FMA work on 16 float32 lanes, runs markedly faster with 512-bit ones (docs/FOCUS.md). Only done when
    numba is not imported yet and the user has not chosen CPU features (set AUTOSAR_NO_AVX512=1 to skip).
    """
    import os
    import sys

    if "numba" in sys.modules or "NUMBA_CPU_FEATURES" in os.environ or os.environ.get("AUTOSAR_NO_AVX512"):
        return
    try:
        import llvmlite.binding as llvm

        features = llvm.get_host_cpu_features()
        if not features.get("avx512f", False):
            return
        os.environ["NUMBA_CPU_NAME"] = llvm.get_host_cpu_name()
        os.environ["NUMBA_CPU_FEATURES"] = features.flatten() + ",-prefer-256-bit"
    except Exception:  # noqa: BLE001 - an optimisation only; numba's defaults work everywhere
        return


def _two_threads_per_cpu() -> None:
    """Start numba with two threads per CPU unless the user chose a number (NUMBA_NUM_THREADS).

    Numba hands each thread of a parallel loop an equal, fixed share. When one CPU is busy with something
    else for a while (another process, focus's own read-ahead thread), the loop waits for the thread stuck on
    it; two threads per CPU let the OS even that out. On the 2-CPU development VM, with another process
    keeping one CPU busy, a test1 block's back-projection took 0.79 of the time with 4 threads as with 2
    (quartiles of paired rounds 0.73-0.91); on an idle machine 1.04, and focus() of test1 was as fast or
    faster in 8 of 11 interleaved runs (docs/FOCUS.md).
    """
    import os
    import sys

    if "numba" in sys.modules or "NUMBA_NUM_THREADS" in os.environ:
        return
    try:
        n_cpu = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n_cpu = os.cpu_count() or 1
    os.environ["NUMBA_NUM_THREADS"] = str(2 * max(1, n_cpu))


def _writable_kernel_cache() -> None:
    """A temporary directory for numba's cache where neither the install nor the home can hold it (numba
    would otherwise refuse to define the kernels); see autosar_cli.kernel_cache."""
    import sys

    if "numba" in sys.modules:
        return
    from autosar_cli.kernel_cache import ensure_cache_dir

    ensure_cache_dir()


_prefer_wide_vectors()
_two_threads_per_cpu()
_writable_kernel_cache()

from autosar_cli.config import Config, ConfigError, load_config  # noqa: E402

__all__ = ["Config", "ConfigError", "load_config", "__version__"]
