"""numba's on-disk cache of compiled kernels: where it lives, and loading from it before a kernel's first call.

Every kernel is compiled with ``cache=True``. numba keeps the cache beside the package's sources, else in the
user's cache directory (``~/.cache/numba``); where neither is writable (a read-only install and no writable
home) it refuses to define the kernels at all ("no locator available"), so :func:`ensure_cache_dir` points
``NUMBA_CACHE_DIR`` at a directory under the system's temporary directory before numba is imported.

Every kernel is compiled with ``cache=True``; a fresh process still pays, at each kernel's first call, for
reading and linking its cached machine code (~0.1 s for navigation, ~0.3 s for focus on the development
machine). :func:`load_cached_kernels` does that ahead of time, for every specialisation the cache holds that
matches the current source and CPU, so a process with idle time (``autosar run`` while its ingest runs in a
child) can take it out of the later stages. Nothing is compiled: entries of other sources or CPUs are left.

A kernel with a parallel loop is, for numba, two functions: the loop's body is compiled on its own and a copy of
it is linked into the kernel. A fresh compile runs the first; the cache keeps the copy, optimised once more, and
under fastmath the two round differently, so the process that compiled such a kernel made an image that differed
in the last bits from every later one's (the same drive and options). :func:`compile_in_child` has a child process
compile it into the cache, so that every process runs the cached machine code.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile
from collections.abc import MutableMapping
from pathlib import Path
from types import ModuleType
from typing import Any


def fallback_cache_dir(package_dir: Path, env: MutableMapping[str, str]) -> Path | None:
    """The cache directory to use when numba would find none writable (``env`` has no NUMBA_CACHE_DIR, the
    package's ``__pycache__`` and the user cache directory cannot be written); None when numba finds one."""
    if env.get("NUMBA_CACHE_DIR"):
        return None
    if _writable(package_dir / "__pycache__"):
        return None
    home = Path(env["HOME"]) if env.get("HOME") else Path.home()
    user_cache = Path(env.get("XDG_CACHE_HOME") or home / ".cache") / "numba"
    if _writable(user_cache):
        return None
    uid = os.getuid() if hasattr(os, "getuid") else 0
    return Path(tempfile.gettempdir()) / f"autosar-numba-cache-{uid}"


def ensure_cache_dir(env: MutableMapping[str, str] = os.environ) -> Path | None:
    """Set NUMBA_CACHE_DIR to :func:`fallback_cache_dir` where needed (before numba's import); returns it."""
    fallback = fallback_cache_dir(Path(__file__).resolve().parent, env)
    if fallback is not None:
        env["NUMBA_CACHE_DIR"] = str(fallback)
    return fallback


def _writable(folder: Path) -> bool:
    """Whether ``folder`` is, or could be created as, a directory this process can write in."""
    for p in (folder, *folder.parents):
        if p.exists():
            return p.is_dir() and os.access(p, os.W_OK | os.X_OK)
    return False


def load_cached_kernels(*modules: ModuleType) -> int:
    """Load the cached specialisations of the numba dispatchers defined in ``modules``; returns how many.

    Only an optimisation: numba's cache internals differ between versions, so any failure loads nothing more.
    """
    from numba.core.registry import CPUDispatcher

    loaded = 0
    for module in modules:
        for obj in list(vars(module).values()):
            if not isinstance(obj, CPUDispatcher) or getattr(obj, "_cache", None) is None:
                continue
            try:
                cache = obj._cache
                codegen = obj.targetctx.codegen()
                for key in list(cache._cache_file._load_index()):
                    # the same source, closure and CPU: compile() then reads it from the cache
                    if cache._index_key(key[0], codegen) == key:
                        obj.compile(key[0])
                        loaded += 1
            except Exception:  # noqa: BLE001 - an optimisation only
                continue
    return loaded


#: The child of :func:`compile_in_child`: argv = the package's parent folder, module, dispatcher, pickled signature.
_COMPILE = """
import importlib, pickle, sys
sys.path.insert(0, sys.argv[1])
dispatcher = getattr(importlib.import_module(sys.argv[2]), sys.argv[3])
dispatcher.compile(pickle.loads(bytes.fromhex(sys.argv[4])))
"""


def compile_in_child(dispatcher: Any, args: tuple[Any, ...]) -> bool:
    """Have a child process compile ``dispatcher`` (a numba kernel with ``cache=True``) for the types of ``args``
    into the cache, unless this process holds that specialisation already or the cache does; then this process's
    call loads it from the cache. Returns whether a child compiled it.

    Where the child fails (or numba's cache internals differ from what this expects), nothing is done and the
    call compiles in this process as numba always does.
    """
    try:
        signature = tuple(dispatcher.typeof_pyval(a) for a in args)
        if signature in dispatcher.overloads:
            return False
        cache = dispatcher._cache
        key = cache._index_key(signature, dispatcher.targetctx.codegen())
        if key in cache._cache_file._load_index():
            return False
        pickled = pickle.dumps(signature).hex()
    except Exception:  # noqa: BLE001 - numba's internals: the call compiles as usual
        return False
    if not sys.executable or getattr(sys, "frozen", False):  # an embedded or frozen interpreter: no Python to run
        return False
    env = dict(os.environ)
    if "NUMBA_CPU_FEATURES" not in env:  # this process's numba uses the CPU's defaults: the child must too
        env["AUTOSAR_NO_AVX512"] = "1"
    package_parent = str(Path(__file__).resolve().parent.parent)
    try:  # in this process's folder: a relative NUMBA_CACHE_DIR or PYTHONPATH means the same there
        child = subprocess.run([sys.executable, "-c", _COMPILE, package_parent, dispatcher.py_func.__module__,
                                dispatcher.py_func.__name__, pickled], env=env, capture_output=True)
    except OSError:  # no process to start (out of processes, no executable): the call compiles here
        return False
    return child.returncode == 0
