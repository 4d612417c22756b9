"""Loading numba's compiled kernels from its on-disk cache before their first call.

Every kernel is compiled with ``cache=True``; a fresh process still pays, at each kernel's first call, for
reading and linking its cached machine code (~0.1 s for navigation, ~0.3 s for focus on the development
machine). :func:`load_cached_kernels` does that ahead of time, for every specialisation the cache holds that
matches the current source and CPU, so a process with idle time (``autosar run`` while its ingest runs in a
child) can take it out of the later stages. Nothing is compiled: entries of other sources or CPUs are left.
"""

from __future__ import annotations

from types import ModuleType


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
