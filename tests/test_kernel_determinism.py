"""A kernel freshly compiled by numba and the same kernel loaded from numba's cache give the same bits."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np


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


#: Back-projection of random profiles (8 channels of a 3 Tx x 4 Rx array, every pulse for every pixel) in a fresh
#: process; prints the sums' bytes as hex.
_BACKPROJECT = """
import numpy as np
from autosar_cli.sar.backprojection import backproject
rng = np.random.default_rng(1)
n_ch, n_bins, n_pulses, n_pix = 8, 64, 600, 500
prof = (rng.standard_normal((n_ch, n_bins, n_pulses)) + 1j * rng.standard_normal((n_ch, n_bins, n_pulses)))
ant = np.zeros((7, n_pulses, 3))
ant[:, :, 0] = np.linspace(0.0, 3.0, n_pulses)
ant[:, :, 1] = np.arange(7)[:, None] * 0.002
channels = [[c % 3, 3 + c % 4] for c in range(n_ch)]
pix = np.stack([rng.uniform(0.0, 3.0, n_pix), rng.uniform(3.0, 5.0, n_pix), np.zeros(n_pix)], axis=1)
out = backproject(prof.astype(np.complex64), ant, channels, pix, np.tile([0, n_pulses], (n_pix, 1)), range0_m=5.0,
                  bin_m=0.12, cycles_per_m=2 * 77e9 / 299792458.0)
print(out.tobytes().hex())
"""


def _backproject_in_fresh_process(cache_dir: Path) -> bytes:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir)}
    run = subprocess.run([sys.executable, "-c", _BACKPROJECT], check=True, env=env, capture_output=True, text=True)
    return bytes.fromhex(run.stdout.strip().splitlines()[-1])


def test_backprojection_is_identical_with_compiled_and_cached_kernel(tmp_path: Path) -> None:
    """A freshly compiled kernel summed some pixels differently from the cached one in the last bits (numba's
    parallel loop body, optimised once more in the copy the cache keeps): one drive, two images."""
    cache_dir = tmp_path / "numba_cache"
    compiled = _backproject_in_fresh_process(cache_dir)
    assert any(cache_dir.rglob("*_tdbp*.nbi")), "the first run should have filled the empty cache"
    cached = _backproject_in_fresh_process(cache_dir)
    sums = np.frombuffer(compiled, np.complex64)
    assert len(sums) == 500 and np.count_nonzero(sums) == 500
    assert compiled == cached
