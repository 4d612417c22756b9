"""Scatterers that move, which the processor does not model (it takes the scene as still): cyclists riding past
leave the autofocus as it was; where the only points move along the road, the autofocus refuses and says why."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from autosar_cli.config import load_config
from autosar_cli.run import run
from autosar_cli.sim.scenario import build_scenario
from autosar_cli.sim.scene import KINDS
from autosar_cli.sim.simulate import simulate
from autosar_cli.store.image import read_image
from autosar_cli.store.trajectory import read_trajectory

CFG = load_config()


def _run(tmp_path: Path, name: str, config=CFG, scene=None) -> tuple[dict, Path]:
    """`run --autofocus` of the ci drive (seed 7, kinematic), with the config's riders or the scene given."""
    log = tmp_path / f"{name}.mcap"
    simulate("ci", log, seed=7, config=config, scene=scene, dynamics="kinematic")
    return run([log], tmp_path / name, config, autofocus=True), tmp_path / name


def test_cyclists_riding_past_leave_the_autofocus_as_it_was(tmp_path: Path) -> None:
    """Two riders, one each way at 3 m/s, 5 and 8 m out among the corner reflectors (4-7 m): their echoes are in
    the image, and the autofocus takes the same points and the same correction (measured: 0.71 mm RMS both, the
    reflectors 0.27-0.34 cm from the truth either way, on the full vehicle)."""
    riders = replace(CFG, simulation=replace(CFG.simulation, cyclists=((-1.0, -5.0, 3.0), (4.0, -8.0, -3.0))))
    still, still_dir = _run(tmp_path, "still")
    passed, passed_dir = _run(tmp_path, "riders", riders)
    a, b = still["stages"]["autofocus"], passed["stages"]["autofocus"]
    assert a["applied"] and b["applied"], (a["summary"], b["summary"])
    np.testing.assert_allclose(b["points_enu"], a["points_enu"], atol=1e-9)
    assert b["points_used"] == a["points_used"]
    ca = read_trajectory(still_dir / "trajectory.h5", covariance=False).correction
    cb = read_trajectory(passed_dir / "trajectory.h5", covariance=False).correction
    assert ca is not None and cb is not None
    assert np.sqrt(np.mean(np.sum((cb.offset_enu - ca.offset_enu) ** 2, axis=1))) < 5e-5  # 0.05 mm
    image, ridden = (read_image(d / "image.h5").image for d in (still_dir, passed_dir))
    # the riders are there: smeared by their motion, up to 3.4 % of the brightest reflector's peak (measured)
    assert np.abs(ridden - image).max() > 0.01 * np.abs(image).max()


def test_autofocus_refuses_where_its_only_points_move_along_the_road(tmp_path: Path) -> None:
    """The ci drive's corner reflectors carried along the road at 1 m/s (the parked car and the lamp post taken
    away): each one's phases follow no still point, so the autofocus refuses, says why, and the run keeps the
    navigated track."""
    scene = build_scenario("ci", CFG).scene
    keep = (scene.kind != KINDS.index("car")) & (scene.kind != KINDS.index("lamp_post"))
    velocity = np.zeros((len(scene.position), 3))
    velocity[scene.corner_reflectors] = [1.0, 0.0, 0.0]  # ci drives east
    carried = replace(scene, position=scene.position[keep], rcs_m2=scene.rcs_m2[keep], kind=scene.kind[keep],
                      object_index=scene.object_index[keep], velocity_enu=velocity[keep])
    manifest, out = _run(tmp_path, "carried", scene=carried)
    stage = manifest["stages"]["autofocus"]
    assert not stage["applied"] and stage["method"] == "sar-min"
    assert "behave as stationary point scatterers" in stage["reason"], stage["reason"]
    assert any("behave as stationary point scatterers" in w for w in manifest["warnings"]), manifest["warnings"]
    traj = read_trajectory(out / "trajectory.h5", covariance=False)
    assert traj.method == "sar-min" and traj.correction is None
