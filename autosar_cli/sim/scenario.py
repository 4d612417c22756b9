"""The drive scenarios: the paper's three tests on a closed road plus a tiny ``ci`` drive.

Each scenario is a rear-axle path (nominal line + smooth lateral offset w(u)), a speed profile and a
scene laid out on the radar side (the right of the direction of travel). The scene is fixed per
scenario; the drive seed only changes sensor errors and noise.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.sim.road import RoadLayout
from autosar_cli.sim.scene import Scene, SceneBuilder, finish_scene, finish_scene_along
from autosar_cli.sim.trajectory import ArcPathMotion, LateralProfile, TruthMotion

SCENARIOS = ("ci", "test1", "test2", "test3", "urban")


def polynomial_profile(coeffs: tuple[float, ...]) -> LateralProfile:
    """w(u) = sum c_k u^k."""
    p = np.polynomial.Polynomial(coeffs)
    derivs = [p, p.deriv(1), p.deriv(2), p.deriv(3)]

    def profile(u: NDArray[np.float64], order: int) -> NDArray[np.float64]:
        return np.asarray(derivs[order](u), dtype=np.float64)

    return profile


def sine_profile(amplitude_m: float, period_m: float) -> LateralProfile:
    """w(u) = A sin(2 pi u / P)."""
    k = 2.0 * np.pi / period_m

    def profile(u: NDArray[np.float64], order: int) -> NDArray[np.float64]:
        u = np.asarray(u, dtype=np.float64)
        return amplitude_m * k**order * np.sin(k * u + order * np.pi / 2)

    return profile


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    motion: TruthMotion
    scene: Scene
    road: RoadLayout = RoadLayout()  # discrete road features the full model drives over


def _scene_rng(name: str) -> np.random.Generator:
    return np.random.default_rng(zlib.crc32(f"scene/{name}".encode()))


def build_scenario(name: str, config: Config) -> Scenario:
    """Build the named scenario for the vehicle and radar of ``config``."""
    try:
        maker = _MAKERS[name]
    except KeyError:
        raise ValueError(f"unknown scenario {name!r}; choose one of {', '.join(SCENARIOS)}") from None
    return maker(config)


def _motion(config: Config, lateral: LateralProfile, length: float, direction: float,
            speed_knots: list[tuple[float, float]]) -> TruthMotion:
    v = config.vehicle
    return TruthMotion(lateral, length, direction, (0.0, 0.0), speed_knots, v.cog_to_rear_axle_m,
                       v.cog_height_m)


def _riders(b: SceneBuilder, config: Config, u0: float) -> SceneBuilder:
    """``b`` with the config's cyclists (simulation.cyclists) added last, their along-track start from ``u0`` (the
    radar's): the other scatterers keep their draws and their order."""
    for i, (du, w, speed) in enumerate(config.simulation.cyclists if config.simulation else ()):
        b.cyclist(u0 + du, w, speed, name=f"cyclist {i + 1}")
    return b


def _radar_u0(config: Config) -> float:
    """Along-track position of the radar when the rear axle is at u = 0."""
    return config.vehicle.cog_to_rear_axle_m + config.radar.mounting.lever_arm_m[0]


def _ci(config: Config) -> Scenario:
    motion = _motion(config, polynomial_profile((0.0, 0.0, 0.006)), 2.4, 0.0,
                     [(0.0, 2.2), (0.6, 2.5), (60.0, 2.5)])
    b = SceneBuilder(_scene_rng("ci"), config.radar.centre_frequency_hz)
    u0 = _radar_u0(config)
    for du, w in ((0.6, -4.0), (1.2, -5.5), (1.8, -7.0)):
        b.corner_reflector(u0 + du, w)
    b.kerb(u0 - 4.0, u0 + 8.0, -2.4)
    b.car(u0 + 0.2, -10.0, name="parked car")
    b.lamp_post(u0 + 1.5, -3.0)
    b.clutter(u0 - 6.0, u0 + 14.0, -2.5, -20.0, 0.4)
    return Scenario("ci", "tiny drive for tests: 2.4 m at ~2.4 m/s, gentle left curve, 3 corner reflectors",
                    motion, finish_scene(_riders(b, config, u0), 0.0, (0.0, 0.0)))


def _test1(config: Config) -> Scenario:
    # ~50 m East -> West, slowly turning left (~50 cm across-track drift), speed rising to ~18 km/h.
    length = 50.0
    motion = _motion(config, polynomial_profile((0.0, 0.0, 0.5 / length**2)), length, np.pi,
                     [(0.0, 2.0), (4.0, 3.2), (9.0, 5.0), (120.0, 5.0)])
    b = SceneBuilder(_scene_rng("test1"), config.radar.centre_frequency_hz)
    u0 = _radar_u0(config)
    b.facade(u0 - 2.0, u0 + length + 12.0, -17.0)
    for du, w in ((8.0, -4.0), (16.0, -7.0), (24.0, -10.0), (32.0, -13.0), (40.0, -5.5)):
        b.corner_reflector(u0 + du, w)
    b.kerb(u0 - 4.0, u0 + length + 10.0, -2.3)
    b.car(u0 + 10.5, -3.3, name="parked van", length=5.2, width=2.0)
    b.car(u0 + 18.5, -3.3, name="parked car 1")
    b.car(u0 + 27.0, -3.3, name="mini electric car", length=2.7, width=1.6)
    b.car(u0 + 34.0, -3.3, name="parked car 2")
    for du in (5.0, 20.0, 35.0, 50.0):
        b.lamp_post(u0 + du, -2.8)
    b.clutter(u0 - 6.0, u0 + length + 20.0, -2.5, -16.5, 0.5)
    return Scenario("test1", "paper Test 1: ~50 m E->W, slow left turn (~0.5 m drift), speed up to ~18 km/h",
                    motion, finish_scene(_riders(b, config, u0), np.pi, (0.0, 0.0)))


def _test2(config: Config) -> Scenario:
    # ~120 m West -> East with a double curve of about +-1 m.
    length = 120.0
    motion = _motion(config, sine_profile(1.0, length), length, 0.0,
                     [(0.0, 3.0), (6.0, 4.5), (30.0, 4.8), (200.0, 4.8)])
    b = SceneBuilder(_scene_rng("test2"), config.radar.centre_frequency_hz)
    u0 = _radar_u0(config)
    b.railing(u0 + 5.0, u0 + 70.0, -6.5)
    b.railing(u0 + 60.0, u0 + length + 10.0, -12.0)
    for du, w in ((15.0, -4.0), (40.0, -9.0), (65.0, -5.0), (90.0, -8.0), (110.0, -4.5)):
        b.corner_reflector(u0 + du, w)
    b.kerb(u0 - 4.0, u0 + length + 10.0, -2.3)
    for du in (22.0, 48.0, 75.0, 100.0):
        b.car(u0 + du, -3.3, name=f"parked car at {du:.0f} m")
    for du in range(0, 121, 20):
        b.lamp_post(u0 + du, -2.8)
    b.facade(u0 + 20.0, u0 + length + 10.0, -20.0, pillar_spacing=4.0)
    b.clutter(u0 - 6.0, u0 + length + 20.0, -2.5, -20.0, 0.35)
    return Scenario("test2", "paper Test 2: ~120 m W->E, double curve of +-1 m", motion,
                    finish_scene(_riders(b, config, u0), 0.0, (0.0, 0.0)))


def _test3(config: Config) -> Scenario:
    # Zig-zag at moderate speed, South -> North.
    length = 80.0
    motion = _motion(config, sine_profile(0.8, 25.0), length, np.pi / 2,
                     [(0.0, 2.5), (5.0, 3.8), (200.0, 3.8)])
    b = SceneBuilder(_scene_rng("test3"), config.radar.centre_frequency_hz)
    u0 = _radar_u0(config)
    b.facade(u0 - 2.0, u0 + length + 10.0, -16.0, pillar_spacing=3.5)
    for du, w in ((10.0, -5.0), (25.0, -8.0), (40.0, -11.0), (55.0, -6.0), (70.0, -9.5)):
        b.corner_reflector(u0 + du, w)
    b.kerb(u0 - 4.0, u0 + length + 10.0, -3.0)
    for du in (15.0, 33.0, 62.0):
        b.car(u0 + du, -4.0, name=f"parked car at {du:.0f} m")
    for du in (0.0, 25.0, 50.0, 75.0):
        b.lamp_post(u0 + du, -3.4)
    b.clutter(u0 - 6.0, u0 + length + 20.0, -3.2, -15.5, 0.4)
    return Scenario("test3", "paper Test 3: ~80 m zig-zag S->N (+-0.8 m, 25 m period), ~14 km/h", motion,
                    finish_scene(_riders(b, config, u0), np.pi / 2, (0.0, 0.0)))


def _urban(config: Config) -> Scenario:
    # ~200 m through a town, starting East-bound: straight, a right turn at a junction (10 m radius), an S-bend,
    # a stop of 6 s and go, a speed bump, cobbles; the radar (right side) sees the junction's inner corner.
    # Top speed 18 km/h: the radar images unambiguously up to ~19.5 km/h (docs/SIMULATION.md, Scenarios).
    length = 200.0
    v = config.vehicle
    turn = (40.0, 40.0 + 0.5 * np.pi * 10.0, -0.1)
    s_bend = [(85.0, 97.0, 0.04), (97.0, 109.0, -0.04)]
    motion = ArcPathMotion([turn, *s_bend], 3.0, length, 0.0, (0.0, 0.0),
                           [(0.0, 2.0), (5.0, 4.5), (9.0, 4.5), (12.0, 3.0), (16.0, 3.0), (21.0, 5.0), (26.0, 5.0),
                            (30.0, 0.0), (36.0, 0.0), (41.0, 4.0), (45.0, 3.0), (48.0, 5.0), (90.0, 5.0)],
                           v.cog_to_rear_axle_m, v.cog_height_m)
    b = SceneBuilder(_scene_rng("urban"), config.radar.centre_frequency_hz)
    u0 = _radar_u0(config)
    b.facade(u0 - 2.0, u0 + 36.0, -9.0)  # the junction's corner building, both streets
    b.facade(u0 + 62.0, u0 + 84.0, -9.0, pillar_spacing=3.5)
    b.facade(u0 + 112.0, u0 + length + 8.0, -11.0, pillar_spacing=4.0)
    crs = (10.0, 30.0, 48.0, 52.0, 70.0, 91.0, 103.0, 125.0, 150.0, 175.0, 195.0)
    for i, du in enumerate(crs):
        b.corner_reflector(u0 + du, -4.0 if i % 2 == 0 else -6.0)
    b.kerb(u0 - 4.0, u0 + length + 8.0, -2.3)
    for du in (14.0, 22.0, 64.0, 72.0, 118.0, 140.0, 160.0, 182.0):
        b.car(u0 + du, -3.3, name=f"parked car at {du:.0f} m")
    for du in range(0, 201, 25):
        b.lamp_post(u0 + du, -2.8)
    b.clutter(u0 - 6.0, u0 + length + 10.0, -2.5, -7.5, 0.35)
    road = RoadLayout(bumps=((128.0, 3.7, 0.07),), kerb_ramps=((20.0, 3.0, 0.06),),
                      rough_sections=((145.0, 175.0, "C"),))
    return Scenario("urban", "~200 m town drive: straight, right turn at a junction, S-bend, 6 s stop, speed bump,"
                    " cobbles; 2-18 km/h", motion, finish_scene_along(_riders(b, config, u0), motion.path), road)


_MAKERS: dict[str, Callable[[Config], Scenario]] = {
    "ci": _ci, "test1": _test1, "test2": _test2, "test3": _test3, "urban": _urban,
}
