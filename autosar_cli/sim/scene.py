"""Scene of point scatterers: corner reflectors, facade, parked cars, kerb, lamp posts, railings, clutter.

Objects are laid out in the scenario's path frame (u along the nominal line, w to its left, z up from
the road) and converted to ENU by the scenario. Radar cross sections are in m^2.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import SPEED_OF_LIGHT

KINDS = ("corner_reflector", "facade", "car", "kerb", "lamp_post", "railing", "clutter")


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

    def _add(self, uwz: NDArray[np.float64], rcs: NDArray[np.float64], kind: str, name: str) -> None:
        uwz = np.atleast_2d(np.asarray(uwz, dtype=np.float64))
        self.uwz.append(uwz)
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


@dataclass(frozen=True)
class Scene:
    """Point scatterers in ENU: position (M, 3) m, rcs (M,) m^2, kind (M,) index into KINDS,
    object (M,) index into names."""

    position: NDArray[np.float64]
    rcs_m2: NDArray[np.float64]
    kind: NDArray[np.int8]
    object_index: NDArray[np.int32]
    names: tuple[str, ...]

    @property
    def corner_reflectors(self) -> NDArray[np.intp]:
        return np.flatnonzero(self.kind == KINDS.index("corner_reflector"))


def finish_scene(builder: SceneBuilder, direction_rad: float, start_enu: tuple[float, float]) -> Scene:
    """Convert the builder's path-frame points to ENU."""
    uwz = np.concatenate(builder.uwz)
    c, s = np.cos(direction_rad), np.sin(direction_rad)
    enu = np.stack([start_enu[0] + c * uwz[:, 0] - s * uwz[:, 1],
                    start_enu[1] + s * uwz[:, 0] + c * uwz[:, 1], uwz[:, 2]], -1)
    return Scene(enu, np.concatenate(builder.rcs), np.concatenate(builder.kind),
                 np.concatenate(builder.name_index), tuple(builder.names))


def finish_scene_along(builder: SceneBuilder,
                       path: Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], ...]]) -> Scene:
    """Convert the builder's points to ENU along a curved path: u is the arc length, w the offset to its left.

    path(s) returns (ENU position (N, 2), tangent heading (N,) rad, ...).
    """
    uwz = np.concatenate(builder.uwz)
    pos, psi = path(uwz[:, 0])[:2]
    enu = np.stack([pos[:, 0] - np.sin(psi) * uwz[:, 1], pos[:, 1] + np.cos(psi) * uwz[:, 1], uwz[:, 2]], -1)
    return Scene(enu, np.concatenate(builder.rcs), np.concatenate(builder.kind),
                 np.concatenate(builder.name_index), tuple(builder.names))
