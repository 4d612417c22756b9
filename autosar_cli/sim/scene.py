"""Scene of point scatterers: corner reflectors, facade, parked cars, kerb, lamp posts, railings, clutter, and
cyclists riding past.

Objects are laid out in the scenario's path frame (u along the nominal line, w to its left, z up from
the road) and converted to ENU by the scenario. Radar cross sections are in m^2. A scatterer moves at a constant
velocity (m/s, ENU): at drive time t (s from the drive's start) it is at ``position + velocity * t``; all but the
cyclists stand still.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import SPEED_OF_LIGHT

KINDS = ("corner_reflector", "facade", "car", "kerb", "lamp_post", "railing", "clutter", "cyclist")


def trihedral_rcs_m2(edge_m: float, frequency_hz: float) -> float:
    """Peak RCS of a triangular trihedral corner reflector: 4 pi a^4 / (3 lambda^2)."""
    lam = SPEED_OF_LIGHT / frequency_hz
    return 4.0 * np.pi * edge_m**4 / (3.0 * lam**2)


@dataclass
class SceneBuilder:
    """Accumulates scatterers in the path frame (u, w, z)."""

    rng: np.random.Generator
    frequency_hz: float
    uwz: list[NDArray[np.float64]] = field(default_factory=list)
    rcs: list[NDArray[np.float64]] = field(default_factory=list)
    kind: list[NDArray[np.int8]] = field(default_factory=list)
    names: list[str] = field(default_factory=list)
    name_index: list[NDArray[np.int32]] = field(default_factory=list)
    velocity_uw: list[NDArray[np.float64]] = field(default_factory=list)  #: (n, 2) m/s along u and w

    def _add(self, uwz: NDArray[np.float64], rcs: NDArray[np.float64], kind: str, name: str,
             velocity_uw: tuple[float, float] = (0.0, 0.0)) -> None:
        uwz = np.atleast_2d(np.asarray(uwz, dtype=np.float64))
        self.uwz.append(uwz)
        self.velocity_uw.append(np.tile(np.asarray(velocity_uw, dtype=np.float64), (len(uwz), 1)))
        self.rcs.append(np.broadcast_to(np.asarray(rcs, dtype=np.float64), (len(uwz),)).copy())
        self.kind.append(np.full(len(uwz), KINDS.index(kind), dtype=np.int8))
        self.name_index.append(np.full(len(uwz), len(self.names), dtype=np.int32))
        self.names.append(name)

    def _speckle(self, n: int, mean_rcs: float) -> NDArray[np.float64]:
        return self.rng.exponential(mean_rcs, n)

    def corner_reflector(self, u: float, w: float, z: float = 0.5, edge_m: float = 0.10) -> None:
        n = sum(1 for k in self.kind if k.size and k[0] == 0)
        self._add([[u, w, z]], trihedral_rcs_m2(edge_m, self.frequency_hz), "corner_reflector", f"CR{n + 1}")

    def facade(self, u0: float, u1: float, w: float, pillar_spacing: float = 3.0) -> None:
        """Building front: pillars (vertical rows of strong scatterers) and a speckled wall between."""
        pillars_u = np.arange(u0, u1 + 1e-9, pillar_spacing)
        z = np.arange(0.4, 2.81, 0.4)
        pts = np.array([[u, w, zz] for u in pillars_u for zz in z])
        self._add(pts, 0.8 * (1.0 + 0.3 * self.rng.standard_normal(len(pts))) ** 2, "facade", "facade pillars")
        wall_u = np.arange(u0, u1, 0.12)
        wall = np.stack([wall_u + self.rng.uniform(-0.02, 0.02, wall_u.size),
                         np.full(wall_u.size, w - 0.05), self.rng.uniform(0.3, 1.5, wall_u.size)], -1)
        self._add(wall, self._speckle(wall_u.size, 0.03), "facade", "facade wall")

    def car(self, u0: float, w0: float, length: float = 4.5, width: float = 1.8, name: str = "car") -> None:
        """Parked car with its near side at lateral offset w0 (road side), extending away from the road."""
        side = -np.sign(w0) if w0 != 0 else -1.0
        n_side = int(length / 0.15)
        us = np.linspace(u0, u0 + length, n_side)
        near = np.stack([us, np.full(n_side, w0), self.rng.uniform(0.3, 0.9, n_side)], -1)
        ends = np.array([[u0, w0 + side * f * width, 0.5] for f in (0.25, 0.5, 0.75)]
                        + [[u0 + length, w0 + side * f * width, 0.5] for f in (0.25, 0.5, 0.75)])
        wheels = np.array([[u0 + 0.8, w0, 0.3], [u0 + length - 0.9, w0, 0.3]])
        roof = np.stack([np.linspace(u0 + 1.2, u0 + length - 1.0, 8), np.full(8, w0 + side * 0.3),
                         np.full(8, 1.35)], -1)
        self._add(near, self._speckle(n_side, 0.2), "car", name)
        self._add(ends, self._speckle(len(ends), 0.5), "car", name)
        self._add(wheels, np.array([2.0, 2.0]), "car", name)
        self._add(roof, self._speckle(8, 0.1), "car", name)

    def kerb(self, u0: float, u1: float, w: float, spacing: float = 0.10) -> None:
        us = np.arange(u0, u1, spacing)
        pts = np.stack([us, w + self.rng.normal(0, 0.005, us.size), np.full(us.size, 0.12)], -1)
        self._add(pts, self._speckle(us.size, 0.004), "kerb", "kerb")

    def lamp_post(self, u: float, w: float) -> None:
        z = np.arange(0.3, 3.01, 0.3)
        self._add(np.stack([np.full(z.size, u), np.full(z.size, w), z], -1), 0.3, "lamp_post", "lamp post")

    def railing(self, u0: float, u1: float, w: float, post_spacing: float = 2.0) -> None:
        us = np.arange(u0, u1, 0.1)
        rail = np.stack([us, np.full(us.size, w), np.full(us.size, 0.9)], -1)
        self._add(rail, self._speckle(us.size, 0.03), "railing", "railing")
        posts = np.arange(u0, u1 + 1e-9, post_spacing)
        self._add(np.stack([posts, np.full(posts.size, w), np.full(posts.size, 0.5)], -1), 0.4, "railing",
                  "railing posts")

    def clutter(self, u0: float, u1: float, w0: float, w1: float, density_per_m2: float) -> None:
        area = (u1 - u0) * abs(w1 - w0)
        n = int(area * density_per_m2)
        pts = np.stack([self.rng.uniform(u0, u1, n), self.rng.uniform(min(w0, w1), max(w0, w1), n),
                        np.zeros(n)], -1)
        self._add(pts, self._speckle(n, 5e-4), "clutter", "ground clutter")

    def cyclist(self, u0: float, w: float, speed_mps: float, name: str = "cyclist") -> None:
        """A rider on a bicycle at (u0, w) at the drive's start, riding along u at ``speed_mps`` (negative: the
        other way): the wheels' hubs and rims, the frame, the rider's legs, torso and head (2 m^2 in all, a
        bicycle's and its rider's RCS at 77 GHz)."""
        uwz = np.array([[u0 - 0.55, w, 0.35], [u0 + 0.55, w, 0.35], [u0 - 0.55, w, 0.68], [u0 + 0.55, w, 0.68],
                        [u0 - 0.1, w, 0.55], [u0 + 0.3, w, 0.8], [u0, w, 0.75], [u0 + 0.05, w, 1.25],
                        [u0 + 0.1, w, 1.55]])
        rcs = np.array([0.3, 0.3, 0.1, 0.1, 0.3, 0.2, 0.25, 0.35, 0.1])
        self._add(uwz, rcs, "cyclist", name, velocity_uw=(speed_mps, 0.0))


@dataclass(frozen=True)
class Scene:
    """Point scatterers in ENU: position (M, 3) m at the drive's start, rcs (M,) m^2, kind (M,) index into KINDS,
    object (M,) index into names, velocity (M, 3) m/s ENU (None: all stand still), road_height (M,) ENU m of the
    road beneath each (None: 0, a level road)."""

    position: NDArray[np.float64]
    rcs_m2: NDArray[np.float64]
    kind: NDArray[np.int8]
    object_index: NDArray[np.int32]
    names: tuple[str, ...]
    velocity_enu: NDArray[np.float64] | None = None
    road_height: NDArray[np.float64] | None = None

    @property
    def moving(self) -> NDArray[np.bool_]:
        """(M,) whether each scatterer moves."""
        if self.velocity_enu is None:
            return np.zeros(len(self.position), dtype=bool)
        return np.any(self.velocity_enu != 0.0, axis=1)

    @property
    def corner_reflectors(self) -> NDArray[np.intp]:
        return np.flatnonzero(self.retroreflector)

    @property
    def retroreflector(self) -> NDArray[np.bool_]:
        """(M,) whether each scatterer sends a ray back the way it came (a trihedral corner reflector)."""
        return self.kind == KINDS.index("corner_reflector")


def finish_scene(builder: SceneBuilder, direction_rad: float, start_enu: tuple[float, float]) -> Scene:
    """Convert the builder's path-frame points to ENU."""
    uwz = np.concatenate(builder.uwz)
    c, s = np.cos(direction_rad), np.sin(direction_rad)
    enu = np.stack([start_enu[0] + c * uwz[:, 0] - s * uwz[:, 1],
                    start_enu[1] + s * uwz[:, 0] + c * uwz[:, 1], uwz[:, 2]], -1)
    return Scene(enu, np.concatenate(builder.rcs), np.concatenate(builder.kind),
                 np.concatenate(builder.name_index), tuple(builder.names), _velocity_enu(builder, c, s))


def _velocity_enu(builder: SceneBuilder, cos_heading: NDArray[np.float64] | float,
                  sin_heading: NDArray[np.float64] | float) -> NDArray[np.float64] | None:
    """The builder's velocities (along u, w) turned into ENU by the path's heading; None where all stand still."""
    vel = np.concatenate(builder.velocity_uw)
    if not np.any(vel != 0.0):
        return None
    return np.stack([cos_heading * vel[:, 0] - sin_heading * vel[:, 1],
                     sin_heading * vel[:, 0] + cos_heading * vel[:, 1], np.zeros(len(vel))], -1)


def finish_scene_along(builder: SceneBuilder,
                       path: Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], ...]]) -> Scene:
    """Convert the builder's points to ENU along a curved path: u is the arc length, w the offset to its left.

    path(s) returns (ENU position (N, 2), tangent heading (N,) rad, ...).
    """
    uwz = np.concatenate(builder.uwz)
    pos, psi = path(uwz[:, 0])[:2]
    enu = np.stack([pos[:, 0] - np.sin(psi) * uwz[:, 1], pos[:, 1] + np.cos(psi) * uwz[:, 1], uwz[:, 2]], -1)
    # a mover keeps the heading of the path where it starts (a straight line: cyclists ride past, not round corners)
    return Scene(enu, np.concatenate(builder.rcs), np.concatenate(builder.kind),
                 np.concatenate(builder.name_index), tuple(builder.names), _velocity_enu(builder, np.cos(psi),
                                                                                         np.sin(psi)))
