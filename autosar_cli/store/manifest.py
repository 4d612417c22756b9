"""JSON manifests of run and batch directories: one reader with one kind of error message."""

from __future__ import annotations

import json
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


def read_json_manifest(path: Path, fmt: str, what: str, error: type[Exception]) -> dict[str, Any]:
    """The JSON object in ``path`` if its ``format`` is ``fmt``; else ``error`` naming the file and ``what``."""
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise error(f"{path}: not a readable {what} manifest ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != fmt:
        raise error(f"{path}: not an autosar {what} manifest")
    return manifest
