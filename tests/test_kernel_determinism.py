"""A kernel freshly compiled by numba and the same kernel loaded from numba's cache give the same bits."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path


def _simulate_in_fresh_process(output: Path, cache_dir: Path) -> bytes:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir)}
    command = [sys.executable, "-c", "from autosar_cli.cli import main; main()", "simulate", "-o", str(output),
               "--seed", "7"]
    subprocess.run(command, check=True, env=env, capture_output=True)
    return output.read_bytes()


def test_simulated_log_is_identical_with_compiled_and_cached_kernels(tmp_path: Path) -> None:
    cache_dir = tmp_path / "numba_cache"
    (tmp_path / "compiled").mkdir()
    (tmp_path / "cached").mkdir()
    compiled = _simulate_in_fresh_process(tmp_path / "compiled" / "ci.mcap", cache_dir)
    assert any(cache_dir.rglob("*echo*.nbi")), "the first run should have filled the empty cache"
    cached = _simulate_in_fresh_process(tmp_path / "cached" / "ci.mcap", cache_dir)
    assert len(compiled) > 10e6
    assert compiled == cached
