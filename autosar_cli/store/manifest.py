"""JSON manifests of run and batch directories: one reader with one kind of error message."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np


def product_status(warnings: list[str]) -> str:
    """A product's ``status`` in its manifest: ``degraded`` when its making warned (a damaged input, dropped data,
    an autofocus not applied), else ``ok`` (run.json, compare.json, metrics.json, batch.json's records)."""
    return "degraded" if warnings else "ok"


def json_default(obj: Any) -> Any:
    """``json.dumps(default=...)``: numpy scalars and arrays become numbers and lists, paths strings."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"value {obj!r} ({type(obj).__name__}) is not JSON-serialisable")


def json_safe(value: Any) -> Any:
    """``value`` with NaN / inf floats replaced by None, tuples as lists, numpy scalars and arrays as Python numbers
    and lists, paths as strings."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def strict_json(value: Any, *, indent: int | None = None) -> str:
    """``value`` as strict JSON (RFC 8259, which has no NaN or Infinity: a figure not measured is null), for every
    manifest and ``--json`` output; see :func:`json_safe`."""
    return json.dumps(json_safe(value), indent=indent, default=json_default, allow_nan=False)


def write_json(path: Path, data: Any, *, overwrite: bool = True) -> Path:
    """Write ``data`` as indented strict JSON, atomically (every manifest autosar writes: run.json, batch.json,
    compare.json, metrics.json)."""
    from autosar_cli.store.atomic import atomic_output

    with atomic_output(path, overwrite) as tmp:
        tmp.write_text(strict_json(data, indent=2) + "\n")
    return path


def read_json_manifest(path: Path, fmt: str, what: str, error: type[Exception]) -> dict[str, Any]:
    """The JSON object in ``path`` if its ``format`` is ``fmt``; else ``error`` naming the file and ``what``."""
    if not path.exists() and path.parent.is_dir():
        raise error(f"{path.parent}: no {path.name}, so not a {what} directory{_what_it_holds(path.parent)}")
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise error(f"{path}: not a readable {what} manifest ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != fmt:
        raise error(f"{path}: not an autosar {what} manifest")
    return manifest


def _what_it_holds(folder: Path) -> str:
    """A hint for a directory given where another kind goes: the run directories a comparison's or a batch's
    directory holds."""
    runs = sorted(str(p.parent) for p in folder.glob("*/run.json"))
    shown = ", ".join(runs[:4]) + (f" and {len(runs) - 4} more" if len(runs) > 4 else "")
    for manifest, kind in (("compare.json", "a comparison"), ("batch.json", "a batch")):
        if (folder / manifest).is_file():
            return f" but {kind} ({manifest})" + (f"; its runs: {shown}" if runs else "")
    return f"; the runs in it: {shown}" if runs else ""
