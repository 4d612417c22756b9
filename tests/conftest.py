"""Shared fixtures: simulated drives (made once per test session) and the real third-party files."""

from __future__ import annotations

import fcntl
import json
import os
import pickle
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from autosar_cli.config import load_config
from autosar_cli.sim.simulate import SimulationResult, simulate

REPO = Path(__file__).resolve().parents[1]
REALDATA = REPO.parent / "shared" / "realdata"


def realdata(*parts: str) -> Path:
    """Path to a real third-party file under ../shared/realdata, or skip the test if it is absent."""
    p = REALDATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"real-data file {p} is absent (a fresh clone has no ../shared/realdata)")
    return p


@pytest.fixture(scope="session")
def sim_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where the session's simulated drives are kept: under pytest-xdist, one folder for all its workers."""
    if "PYTEST_XDIST_WORKER" not in os.environ:
        return tmp_path_factory.mktemp("sim")
    shared = tmp_path_factory.getbasetemp().parent / "sim"
    shared.mkdir(exist_ok=True)
    return shared


_CACHE: dict[tuple[str, str, int, float | None], SimulationResult] = {}

#: the radar's pulse rate of a drive made for the navigation alone: its other sensors' samples are the same as at the
#: full rate (the simulator draws each sensor's noise from its own stream), and test2 is simulated ~15x faster
NAV_ONLY_PRF_HZ = 20.0


def simulated(sim_dir: Path, scenario: str, fmt: str, seed: int, *, prf_hz: float | None = None) -> SimulationResult:
    """A kinematic drive (the motion the navigation models: in-model accuracy), simulated once per session: the
    first worker to ask makes it under a lock of its own, and the others load its result. ``prf_hz``: the radar's
    pulse rate, if not the config's (:data:`NAV_ONLY_PRF_HZ` for a drive only navigated)."""
    key = (scenario, fmt, seed, prf_hz)
    if key not in _CACHE:
        ext = {"mcap": ".mcap", "ros1": ".bag", "ros2": ""}[fmt]
        rate = "" if prf_hz is None else f"_prf{prf_hz:g}"
        log = sim_dir / f"{scenario}_{fmt}_s{seed}{rate}{ext}"
        made = log.with_name(log.name + ".result.pickle")
        with open(log.with_name(log.name + ".lock"), "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if made.exists():
                _CACHE[key] = pickle.loads(made.read_bytes())
            else:
                config = load_config()
                if prf_hz is not None:
                    config = replace(config, radar=replace(config.radar, prf_hz=prf_hz))
                _CACHE[key] = simulate(scenario, log, fmt=fmt, seed=seed, config=config, dynamics="kinematic")
                made.write_bytes(pickle.dumps(_CACHE[key]))
    return _CACHE[key]


@pytest.fixture(scope="session")
def test1_drive(sim_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any]:
    """test1 seed 1 (kinematic; the paper comparison's drive) ingested, and its truth (``Truth``) in the drive's
    frame."""
    from autosar_cli.evaluate.evaluation import load_truth
    from autosar_cli.ingest.pipeline import ingest
    from autosar_cli.nav.inputs import load_inputs
    from autosar_cli.store.drive import Drive

    cfg = load_config()
    sim = simulated(sim_dir, "test1", "mcap", 1)
    drive = tmp_path_factory.mktemp("test1_drive") / "drive.h5"
    ingest([sim.log_path], drive, config=cfg)
    with Drive(drive) as d:
        origin = load_inputs(d, cfg).origin
    return drive, load_truth(sim.truth_path, origin, cfg)


@pytest.fixture(scope="session")
def ci_mcap(sim_dir: Path) -> SimulationResult:
    return simulated(sim_dir, "ci", "mcap", 7)


@pytest.fixture(scope="session")
def ci_run(ci_mcap: SimulationResult, sim_dir: Path) -> Path:
    """`autosar run --json` of the ci drive through the CLI (sar-min), once per session: the first worker to ask
    runs it under a lock, as :func:`simulated` does; its console (stdout, stderr) is :func:`ci_run_console`. Tests
    only read it."""
    from typer.testing import CliRunner

    from autosar_cli.cli import app

    out = sim_dir / (ci_mcap.log_path.name + ".run")
    console = out.with_name(out.name + ".console.json")
    with open(out.with_name(out.name + ".lock"), "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not console.exists():
            r = CliRunner().invoke(app, ["run", str(ci_mcap.log_path), "-o", str(out), "--json"])
            assert r.exit_code == 0, r.output
            console.write_text(json.dumps({"stdout": r.stdout, "stderr": r.stderr}))
    return out


def ci_run_console(run_dir: Path) -> dict[str, str]:
    """The stdout and stderr of the :func:`ci_run` that made ``run_dir``."""
    return json.loads(run_dir.with_name(run_dir.name + ".console.json").read_text())


@pytest.fixture(scope="session")
def ci_ros1(sim_dir: Path) -> SimulationResult:
    return simulated(sim_dir, "ci", "ros1", 7)


@pytest.fixture(scope="session")
def ci_ros2(sim_dir: Path) -> SimulationResult:
    return simulated(sim_dir, "ci", "ros2", 7)


def stop_and_go(brake_mps2: float = 1.7, drive_mps2: float = 1.25, slip_std: float = 0.0025):
    """A straight drive east at 5 m/s that brakes at ``brake_mps2`` to a 3 s stop from t = 8 s and pulls away at
    ``drive_mps2`` back to 5 m/s, sampled at 200 Hz for 30 s; its navigation stated every slip gain at 0 ±
    ``slip_std`` (per m/s^2). Returns the trajectory and its speed's closed form v(t) (m/s, t in s)."""
    import numpy as np

    from autosar_cli.nav.geodesy import GeodeticOrigin
    from autosar_cli.types import Trajectory

    t_stop = 8.0 + 5.0 / brake_mps2

    def speed(t):
        t = np.asarray(t, dtype=np.float64)
        return np.select([t < 8.0, t < t_stop, t < t_stop + 3.0],
                         [np.full_like(t, 5.0), 5.0 - brake_mps2 * (t - 8.0), np.zeros_like(t)],
                         np.minimum(drive_mps2 * (t - t_stop - 3.0), 5.0))

    t = np.arange(0.0, 30.0, 0.005)
    v = speed(t)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    gains = ("front_drive", "front_brake", "rear_drive", "rear_brake")
    info = {"wheel_radii": {"slip_gain": dict.fromkeys(gains, 0.0), "slip_gain_std": dict.fromkeys(gains, slip_std),
                            "applied": dict.fromkeys(gains, 0.0)}}
    traj = Trajectory("sar-min", np.round(t * 1e9).astype(np.int64) + 10**18, np.column_stack([x, np.zeros_like(x)]),
                      np.zeros_like(t), v, np.zeros_like(t), GeodeticOrigin(45.0, 9.0, 100.0), 1.4, 0.5, info=info)
    return traj, speed


def full_car_drive(tmp_path: Path, scenario: str, sensors: dict[str, Any] | None = None, seed: int = 0
                   ) -> tuple[Path, SimulationResult, Any]:
    """``scenario`` by the simulator's full car, its sensors those of the config with ``sensors`` (name: SensorConfig)
    put in for the simulator alone, ingested: the drive.h5, the simulation and the config that navigates it (the
    radar at 20 Hz: navigation only)."""
    from autosar_cli.ingest.pipeline import ingest

    base = load_config()
    cfg = replace(base, radar=replace(base.radar, prf_hz=20.0))
    sim = simulate(scenario, tmp_path / f"{scenario}.mcap", seed=seed,
                   config=replace(cfg, sensors={**cfg.sensors, **(sensors or {})}), dynamics="full")
    drive = tmp_path / f"{scenario}.h5"
    ingest([sim.log_path], drive, config=cfg)
    return drive, sim, cfg


def with_gnss_errors(**changes: Any) -> dict[str, Any]:
    """The config's ``gnss_cog`` sensor with ``changes`` to its error table, for :func:`full_car_drive`."""
    gnss = load_config().sensors["gnss_cog"]
    assert gnss.gnss is not None
    return {"gnss_cog": replace(gnss, gnss=replace(gnss.gnss, **changes))}
