"""Scatterers that move, which the processor does not model (it takes the scene as still): cyclists riding past
leave the autofocus as it was; where the only points move along the road, the autofocus refuses and says why."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

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
    manifest, out = _run(tmp_path, "carried", scene=_ci_scene((1.0, 0.0, 0.0)))  # ci drives east
    stage = manifest["stages"]["autofocus"]
    assert not stage["applied"] and stage["method"] == "sar-min"
    assert "behave as stationary point scatterers" in stage["reason"], stage["reason"]
    assert any("behave as stationary point scatterers" in w for w in manifest["warnings"]), manifest["warnings"]
    traj = read_trajectory(out / "trajectory.h5", covariance=False)
    assert traj.method == "sar-min" and traj.correction is None


def _ci_scene(reflector_velocity_enu: tuple[float, float, float]):
    """The ci scene, its parked car and lamp post taken away, its corner reflectors moving at
    ``reflector_velocity_enu`` (m/s)."""
    scene = build_scenario("ci", CFG).scene
    keep = (scene.kind != KINDS.index("car")) & (scene.kind != KINDS.index("lamp_post"))
    velocity = np.zeros((len(scene.position), 3))
    velocity[scene.corner_reflectors] = reflector_velocity_enu
    return replace(scene, position=scene.position[keep], rcs_m2=scene.rcs_m2[keep], kind=scene.kind[keep],
                   object_index=scene.object_index[keep], velocity_enu=velocity[keep])


def test_autofocus_leaves_out_points_that_cross_the_beam(tmp_path: Path) -> None:
    """A scatterer crossing the beam at a constant speed is, to second order, a still one further along, so its
    phases fit one; its two channels (the virtual array's ends, along the road) see it off that direction. The ci
    drive's corner reflectors walking towards the road at 0.5 m/s, and nothing else bright (taken as still, on the
    full vehicle, they put 4.46 mm RMS into the track): each one's channels' phase is over 0.5 rad (2.7-3.0), so
    they are left out and the autofocus refuses, naming them. Their channels agree with one another, but as a ramp
    along the array, which the channel gains' measurement leaves to them."""
    # ci drives east, the radar looks right: towards the road is +y
    manifest, out = _run(tmp_path, "walking", scene=_ci_scene((0.0, 0.5, 0.0)))
    stage = manifest["stages"]["autofocus"]
    assert not stage["applied"] and stage["method"] == "sar-min", stage["summary"]
    moving = stage["moving_points"]
    assert len(moving) >= 2 and all(abs(m["channel_phase_rad"]) > 0.5 for m in moving), moving
    assert "moving point(s) left out" in stage["reason"] and "cross the beam" in stage["reason"]
    assert any("cross the beam" in w for w in manifest["warnings"]), manifest["warnings"]
    assert stage["moving_points_mounting_yaw_deg"] is None and "boresight" not in stage["reason"]
    assert read_trajectory(out / "trajectory.h5", covariance=False).correction is None
    # their common phase along the array, a ramp, is not taken for the channels' gains
    gains = stage["channel_gains"]
    assert not gains["applied"] and "ramp along the array" in gains["reason"], gains


def _run_with_radar_turned(tmp_path: Path, off_deg: float) -> dict:
    """``run --autofocus`` (into ``tmp_path / "turned"``), told the config's mounting, of the ci drive recorded by a
    radar whose boresight is ``off_deg`` further forward than that: the run's autofocus stage."""
    m = CFG.radar.mounting
    turned = replace(CFG, radar=replace(CFG.radar, mounting=replace(m, yaw_deg=m.yaw_deg + off_deg)))
    log = tmp_path / "turned.mcap"
    simulate("ci", log, seed=7, config=turned, dynamics="kinematic")
    return run([log], tmp_path / "turned", CFG, autofocus=True)["stages"]["autofocus"]


@pytest.mark.parametrize("off_deg", [3.0, -3.0])
def test_a_radar_mounted_off_its_stated_boresight_is_measured_not_taken_for_movers(tmp_path: Path,
                                                                                  off_deg: float) -> None:
    """The ci drive recorded by a radar whose boresight is 3 deg further forward (or back) than
    ``radar.mounting.yaw_deg`` says: the virtual array's ends, turned with it, see every still point off its
    direction, as if each crossed the beam, so along the stated boresight every point is left out. They agree on one
    boresight, within 0.5 deg of the true one (measured -42.1 for -42, -48.2 for -48); along it they fit as still
    points, and the run takes it: the autofocus corrects the track, its trajectory carries that boresight, and the
    image is focused along it."""
    stage = _run_with_radar_turned(tmp_path, off_deg)
    print(stage["summary"])
    assert stage["applied"] and stage["method"] == "sar-min+af", stage["summary"]
    yaw = stage["radar_mounting_yaw_deg"]
    assert yaw is not None and abs(yaw - (CFG.radar.mounting.yaw_deg + off_deg)) < 0.5, yaw
    assert "boresight taken at yaw" in stage["summary"]
    trajectory = read_trajectory(tmp_path / "turned" / "trajectory.h5", covariance=False)
    assert trajectory.info["radar_mounting_yaw_deg"] == yaw
    assert read_image(tmp_path / "turned" / "image.h5").params["radar_mounting_yaw_deg"] == yaw


def test_a_radar_mounted_further_off_than_a_mounting_error_is_named_and_refused(tmp_path: Path) -> None:
    """The ci drive recorded by a radar whose boresight is 7 deg further forward than stated: its points agree on
    a boresight ~7 deg off, beyond the 5 deg the autofocus takes for a mounting error (a column of points crossing
    the beam alike agrees too, at 2.7-3.0 rad, ~9 deg), so it refuses, keeps SAR-MIN's track, and its reason names
    that boresight and the bound."""
    stage = _run_with_radar_turned(tmp_path, 7.0)
    assert not stage["applied"] and stage["method"] == "sar-min", stage["summary"]
    assert stage["radar_mounting_yaw_deg"] is None
    yaw = stage["moving_points_mounting_yaw_deg"]
    assert yaw is not None and abs(yaw - 7.0) < 0.6, yaw
    assert f"boresight at radar.mounting.yaw_deg {yaw:+.1f} deg, beyond the 5 deg" in stage["reason"], stage["reason"]
    assert read_trajectory(tmp_path / "turned" / "trajectory.h5", covariance=False).correction is None


def test_the_mounting_the_moving_points_agree_on() -> None:
    """Their median, robust to one point of another kind; none where fewer than two or where they scatter by more
    than 0.5 deg. Agreeing beyond 5 deg (points crossing the beam alike) is for the autofocus to refuse (above)."""
    from autosar_cli.sar.autofocus_stage import mounting_yaw_agreed

    assert mounting_yaw_agreed(np.array([2.9, 3.0, 3.1, 3.0, 4.8])) == pytest.approx(3.0)
    assert mounting_yaw_agreed(np.array([3.0, np.nan])) is None
    assert mounting_yaw_agreed(np.array([1.0, 2.5, 4.0])) is None
    assert mounting_yaw_agreed(np.array([-9.1, -9.0, -8.9])) == pytest.approx(-9.0)


@pytest.mark.long
def test_a_walker_among_test1s_reflectors_is_left_out(tmp_path: Path) -> None:
    """test1 seed 1 (the full vehicle) with a corner reflector's worth of scatterer 1 m beyond its second reflector,
    walking away from the road at 0.5 m/s: taken as still it was one of 6 points and moved that reflector from 0.27
    to 0.39 cm; left out (its channels' phase 2.1 rad; the reflectors' <= 0.09), the correction is the one without
    it."""
    from autosar_cli.sim.scene import trihedral_rcs_m2

    scene = build_scenario("test1", CFG).scene
    cr = scene.position[scene.corner_reflectors]
    side = np.sign(cr[1, 1])  # test1 drives west: the reflectors lie north
    walker = np.array([[cr[1, 0] - 4.0, cr[1, 1] - side, 0.5]])
    velocity = np.zeros((len(scene.position) + 1, 3))
    velocity[-1] = [0.0, 0.5 * side, 0.0]
    walked = replace(scene, position=np.concatenate([scene.position, walker]),
                     rcs_m2=np.append(scene.rcs_m2, trihedral_rcs_m2(0.1, 77e9) / 4),
                     kind=np.append(scene.kind, np.int8(KINDS.index("cyclist"))),
                     object_index=np.append(scene.object_index, np.int32(len(scene.names))),
                     names=(*scene.names, "walker"), velocity_enu=velocity)
    runs = {}
    for name, sc in (("still", None), ("walker", walked)):
        log = tmp_path / f"{name}.mcap"
        simulate("test1", log, seed=1, config=CFG, scene=sc)
        runs[name] = run([log], tmp_path / name, CFG, autofocus=True)["stages"]["autofocus"]
    a, b = runs["still"], runs["walker"]
    assert a["applied"] and b["applied"] and not a["moving_points"]
    assert len(b["moving_points"]) == 1 and abs(b["moving_points"][0]["channel_phase_rad"]) > 1.0, b["moving_points"]
    assert b["points_used"] == a["points_used"]
    ca, cb = (read_trajectory(tmp_path / n / "trajectory.h5", covariance=False).correction for n in runs)
    assert np.sqrt(np.mean(np.sum((cb.offset_enu - ca.offset_enu) ** 2, axis=1))) < 1e-4  # 0.1 mm
