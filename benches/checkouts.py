"""Running a bench's trials with another checkout's package beside this one's (``--against DIR``, a
``git worktree add DIR REV``), and naming the revision each ran."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any


def revision(root: Path) -> str:
    """The checkout's commit (short), with "+" where its package differs from it."""
    def git(*cmd: str) -> str:
        return subprocess.run(["git", "-C", str(root), *cmd], capture_output=True, text=True).stdout.strip()
    return git("rev-parse", "--short", "HEAD") + ("+" if git("status", "--porcelain", "--", "autosar_cli") else "")


def in_checkout(script: str, root: Path, args: list[str], out: Path) -> Any:
    """``script`` run as ``script --worker OUT ARGS`` in a process of its own, ``root``'s package first on its path:
    the JSON it wrote to ``out``."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    subprocess.run([sys.executable, str(Path(script).resolve()), "--worker", str(out), *args], env=env, check=True,
                   cwd=root)
    return json.loads(out.read_text())
