"""python-can's MF4 support, loaded when the first .mf4 log is opened instead of at start-up.

python-can imports asammdf for its MF4 reader as soon as it is itself imported, and asammdf imports pandas:
``import cantools`` (which imports python-can for its tester) took 0.40-0.52 s with it and 0.09-0.11 s without
(3 processes each, measured). Every ``autosar ingest`` and ``autosar run`` decodes CAN with cantools, but only
.mf4 logs need asammdf. The command-line entry point therefore calls :func:`defer` before anything imports
python-can, and the CAN log reader calls :func:`ensure` before it opens an .mf4 file. Library users who call
neither get python-can exactly as installed.

This module imports nothing heavy itself, so calling :func:`defer` costs nothing.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Sequence
from importlib.abc import MetaPathFinder
from importlib.machinery import ModuleSpec
from types import ModuleType


def _importing_can_mf4() -> bool:
    """True while python-can's ``can.io.mf4`` runs its module code (its reader class is not defined yet)."""
    module = sys.modules.get("can.io.mf4")
    return module is not None and not hasattr(module, "MF4Reader")


class _DeferAsammdf(MetaPathFinder):
    """Fails ``import asammdf`` made by ``can.io.mf4`` at import time; any other import of asammdf is untouched."""

    def find_spec(self, fullname: str, path: Sequence[str] | None = None,
                  target: ModuleType | None = None) -> ModuleSpec | None:
        if fullname == "asammdf" and _importing_can_mf4():
            # python-can catches the ImportError and leaves MF4 support off until ensure() reloads the module
            raise ModuleNotFoundError("asammdf deferred until an .mf4 log is opened", name=fullname)
        return None


_FINDER = _DeferAsammdf()


def defer() -> None:
    """Keep asammdf out of python-can's import (does nothing if python-can is imported already)."""
    if "can" not in sys.modules and _FINDER not in sys.meta_path:
        sys.meta_path.insert(0, _FINDER)


def ensure() -> None:
    """Give python-can its MF4 support if :func:`defer` kept it out (a no-op otherwise, or without asammdf,
    where python-can's MF4 reader then reports the missing package itself)."""
    if _FINDER in sys.meta_path:
        sys.meta_path.remove(_FINDER)
    import can.io.mf4

    if can.io.mf4.asammdf is None and importlib.util.find_spec("asammdf") is not None:
        # Re-running the module defines its asammdf globals in the same namespace, which the reader classes
        # python-can already exported (can.MF4Reader) look their names up in.
        importlib.reload(can.io.mf4)
