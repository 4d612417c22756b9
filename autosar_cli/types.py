"""The plain records every stage passes on and store/ reads and writes: the ENU frame's geodetic origin,
a focusing grid, a vehicle trajectory.

They live here, below nav/, sar/ and store/, so that the storage layer depends on nothing above it
(docs/ARCHITECTURE.md). Their old homes (:mod:`autosar_cli.nav.geodesy`, :mod:`autosar_cli.sar.grid`,
:mod:`autosar_cli.nav.trajectory`) re-export them.

Geodesy: :class:`GeodeticOrigin` and :func:`geodetic_to_utm` are the one place that converts between
geodetic coordinates, local ENU and UTM (WGS-84).

Focusing grids: Focusing grids: a rectangle of square pixels on the focusing plane (ENU, z = height).

The image array is (rows, cols) = (n_across, n_along). Column index grows along ``along`` (a unit ENU
vector, usually the direction of travel); row index grows along ``across`` (unit vector, away from the
track on the radar side for the automatic grid, south for an explicit east/north box). Pixel (0, 0)'s
centre is ``origin``. Rows of the image are therefore lines of constant ground range for the automatic
grid, which keeps neighbouring pixels of the kernel's pixel order on neighbouring range bins.

A trajectory may carry a :class:`MotionCorrection`: a small ENU offset (mm) of every body point over time that
the radar measured and the navigation could not (residual-motion autofocus, :mod:`autosar_cli.sar.residual_motion`).

Trajectories: a :class:`Trajectory` holds the rear-axle centre, heading, speed and yaw rate at its sample
times. Between samples the vehicle follows CTRV from the preceding sample (exact for the filter's own
model, and the samples are milliseconds apart). Body points are given relative to the CoG (ISO 8855 body
frame); the CoG lies ``cog_to_rear_axle_m`` ahead of the rear axle and ``cog_height_m`` above the road
(ENU z = 0 is the road surface at the origin).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
import pymap3d
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from pyproj import Transformer

Array = NDArray[np.float64]


@dataclass(frozen=True)
class GeodeticOrigin:
    """Origin of a local ENU tangent plane: latitude, longitude (deg), ellipsoidal height (m)."""

    lat_deg: float
    lon_deg: float
    height_m: float

    def to_enu(self, lat_deg: ArrayLike, lon_deg: ArrayLike, height_m: ArrayLike) -> NDArray[np.float64]:
        """Geodetic (deg, deg, m) -> ENU (..., 3) in metres."""
        e, n, u = pymap3d.geodetic2enu(
            np.asarray(lat_deg, dtype=np.float64), np.asarray(lon_deg, dtype=np.float64),
            np.asarray(height_m, dtype=np.float64), self.lat_deg, self.lon_deg, self.height_m,
        )
        return np.stack([e, n, u], axis=-1)

    def to_geodetic(self, enu: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """ENU (..., 3) in metres -> latitude (deg), longitude (deg), ellipsoidal height (m)."""
        p = np.asarray(enu, dtype=np.float64)
        lat, lon, h = pymap3d.enu2geodetic(p[..., 0], p[..., 1], p[..., 2], self.lat_deg, self.lon_deg,
                                           self.height_m)
        return np.asarray(lat), np.asarray(lon), np.asarray(h)

    def utm_epsg(self) -> int:
        """EPSG code of the WGS-84 UTM zone holding the origin (326zz north of the equator, 327zz south of it).

        Zone zz = 1 + floor((lon + 180) / 6), clamped to 1-60: the antimeridian itself, lon = +180 exactly, is zone
        60's east edge (zone "61" would be EPSG:32661/32761, the polar UPS projections).
        """
        zone = min(int((self.lon_deg + 180.0) // 6.0) + 1, 60)
        return (32600 if self.lat_deg >= 0 else 32700) + zone

    def enu_to_utm(self, enu: ArrayLike, epsg: int | None = None) -> NDArray[np.float64]:
        """ENU (..., 3) in metres -> UTM (..., 2) easting, northing in metres (zone ``epsg``, default the origin's)."""
        lat, lon, _ = self.to_geodetic(enu)
        return geodetic_to_utm(lat, lon, self.utm_epsg() if epsg is None else epsg)


@lru_cache(maxsize=8)
def _utm_transformer(epsg: int) -> Transformer:
    from pyproj import Transformer  # imported here: pyproj is only needed by the map products

    return Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True)


def geodetic_to_utm(lat_deg: ArrayLike, lon_deg: ArrayLike, epsg: int) -> NDArray[np.float64]:
    """WGS-84 latitude, longitude (deg) -> (..., 2) easting, northing (m) in the UTM CRS ``EPSG:<epsg>``."""
    e, n = _utm_transformer(int(epsg)).transform(np.asarray(lon_deg, dtype=np.float64),
                                                 np.asarray(lat_deg, dtype=np.float64))
    return np.stack([np.asarray(e, dtype=np.float64), np.asarray(n, dtype=np.float64)], axis=-1)


@dataclass(frozen=True)
class FocusGrid:
    origin: tuple[float, float]  #: ENU (x, y) of pixel (0, 0)'s centre, m
    along: tuple[float, float]  #: unit ENU vector of increasing column index
    across: tuple[float, float]  #: unit ENU vector of increasing row index
    pixel_m: float
    n_along: int  #: columns
    n_across: int  #: rows
    height_m: float  #: focusing plane height (ENU z), m

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape (rows, cols)."""
        return (self.n_across, self.n_along)

    @property
    def size(self) -> int:
        return self.n_across * self.n_along

    def pixel_enu(self, rows: ArrayLike, cols: ArrayLike) -> Array:
        """ENU positions (..., 3) of (fractional) pixel indices."""
        r = np.asarray(rows, dtype=np.float64)
        c = np.asarray(cols, dtype=np.float64)
        o, a, x = np.asarray(self.origin), np.asarray(self.along), np.asarray(self.across)
        xy = o + (c[..., None] * a + r[..., None] * x) * self.pixel_m
        z = np.full(xy.shape[:-1] + (1,), self.height_m)
        return np.concatenate([xy, z], axis=-1)

    def positions(self) -> Array:
        """ENU positions (rows, cols, 3) of every pixel centre."""
        rows, cols = np.meshgrid(np.arange(self.n_across), np.arange(self.n_along), indexing="ij")
        return self.pixel_enu(rows, cols)

    def enu_to_pixel(self, xy: ArrayLike) -> tuple[Array, Array]:
        """Fractional (row, col) of ENU points (..., 2 or 3)."""
        d = np.asarray(xy, dtype=np.float64)[..., :2] - np.asarray(self.origin)
        return d @ np.asarray(self.across) / self.pixel_m, d @ np.asarray(self.along) / self.pixel_m

    def corners_enu(self) -> Array:
        """ENU (4, 2) of the outer pixel edges: (0,0) corner, along end, far corner, across end."""
        h = -0.5
        r = np.array([h, h, self.n_across + h, self.n_across + h])
        c = np.array([h, self.n_along + h, self.n_along + h, h])
        return self.pixel_enu(r, c)[:, :2]

    def to_attrs(self) -> dict[str, object]:
        return {"origin_enu_m": np.asarray(self.origin), "along": np.asarray(self.along),
                "across": np.asarray(self.across), "pixel_m": self.pixel_m, "n_along": self.n_along,
                "n_across": self.n_across, "height_m": self.height_m}

    @classmethod
    def from_attrs(cls, attrs: dict[str, object]) -> FocusGrid:
        def pair(key: str) -> tuple[float, float]:
            v = np.asarray(attrs[key], dtype=np.float64)
            return (float(v[0]), float(v[1]))

        return cls(pair("origin_enu_m"), pair("along"), pair("across"), float(attrs["pixel_m"]),  # type: ignore[arg-type]
                   int(attrs["n_along"]), int(attrs["n_across"]), float(attrs["height_m"]))  # type: ignore[arg-type]


@dataclass(frozen=True)
class MotionCorrection:
    """An ENU offset of every body point over time, linearly interpolated between its samples and held beyond
    them: the radar's motion as the body rolls and pitches (SAR-MIN with a 6-DoF IMU, ``nav.attitude``), plus what
    the radar itself measured and the navigation could not (residual-motion autofocus)."""

    t_ns: NDArray[np.int64]  #: (M,) sample times, ns since the Unix epoch, strictly increasing
    offset_enu: Array  #: (M, 3) m, added to the navigated position of every body point
    std_enu: Array  #: (M, 3) m, its 1-sigma uncertainty per ENU axis

    def at(self, t_ns: ArrayLike) -> Array:
        """Offset (N, 3) (ENU m) at times ``t_ns`` (N,) (ns)."""
        return self._interpolated(t_ns, self.offset_enu)

    def std_at(self, t_ns: ArrayLike) -> Array:
        """The offset's 1-sigma (N, 3) (ENU m) at times ``t_ns`` (N,) (ns), interpolated as the offset is."""
        return self._interpolated(t_ns, self.std_enu)

    def _interpolated(self, t_ns: ArrayLike, values: Array) -> Array:
        t = (np.asarray(t_ns, dtype=np.int64) - self.t_ns[0]).astype(np.float64)
        knots = (self.t_ns - self.t_ns[0]).astype(np.float64)
        return np.stack([np.interp(t, knots, values[:, i]) for i in range(3)], axis=-1)


#: half-span (s) of :meth:`Trajectory.travel_velocity`'s average: of the order of the processed apertures
#: (5-130 ms at 4 cm resolution and 5 m/s), long enough to smooth a filter's sample-to-sample jitter
TRAVEL_HALF_SPAN_S = 0.05


@dataclass
class Trajectory:
    method: str
    t_ns: NDArray[np.int64]  #: (K,) sample times, ns since the Unix epoch, strictly increasing
    rear_axle_enu: Array  #: (K, 2) m
    heading: Array  #: (K,) rad, ENU (from East, CCW), unwrapped
    speed: Array  #: (K,) m/s of the rear-axle centre
    yaw_rate: Array  #: (K,) rad/s
    origin: GeodeticOrigin
    cog_to_rear_axle_m: float
    cog_height_m: float
    state: Array | None = None  #: (K, n) full filter state (method sar-min)
    state_names: list[str] = field(default_factory=list)
    covariance: Array | None = None  #: (K, n, n)
    info: dict[str, Any] = field(default_factory=dict)
    correction: MotionCorrection | None = None  #: residual motion added to every body point (autofocus)
    #: the body's yaw is the heading plus this times speed x yaw rate (rad per m/s^2 of lateral acceleration): the
    #: rear tyres' slip angle, where the heading is the rear axle's direction of motion (SAR-MIN); 0: no slip
    rear_slip_gain: float = 0.0

    @property
    def t(self) -> Array:
        """Seconds since the first sample."""
        return (self.t_ns - self.t_ns[0]) / 1e9

    @property
    def cog_enu(self) -> Array:
        """(K, 3) ENU position of the CoG (body-frame origin)."""
        return self.body_points(self.t_ns, np.zeros((1, 3)))[:, 0]

    def pose(self, t_ns: ArrayLike) -> tuple[Array, Array]:
        """Rear-axle ENU (M, 2) and heading (M,) at arbitrary times, by CTRV from the preceding sample."""
        t_ns = np.asarray(t_ns, dtype=np.int64)
        return self._pose_from(self._segment(t_ns), t_ns)

    def _segment(self, t_ns: NDArray[np.int64]) -> NDArray[np.intp]:
        """Index of the sample each time propagates from (the preceding one; the first before the start)."""
        return np.clip(np.searchsorted(self.t_ns, t_ns, side="right") - 1, 0, len(self.t_ns) - 1)

    def _pose_from(self, k: NDArray[np.intp], t_ns: NDArray[np.int64]) -> tuple[Array, Array]:
        dt = (t_ns - self.t_ns[k]) / 1e9
        v, psi, w = self.speed[k], self.heading[k], self.yaw_rate[k]
        half = 0.5 * w * dt
        chord = v * dt * np.sinc(half / np.pi)
        xy = self.rear_axle_enu[k] + np.stack([chord * np.cos(psi + half), chord * np.sin(psi + half)], axis=-1)
        return xy, psi + w * dt

    def body_heading(self, t_ns: ArrayLike) -> Array:
        """Heading (M,) (rad, ENU) of the body's x-axis at times ``t_ns`` (M,): the course plus the rear tyres' slip."""
        t_ns = np.asarray(t_ns, dtype=np.int64)
        k = self._segment(t_ns)
        return self._pose_from(k, t_ns)[1] + self._slip(k)

    def body_points(self, t_ns: ArrayLike, lever_arms: ArrayLike) -> Array:
        """ENU positions (M, A, 3) of body points ``lever_arms`` (A, 3) (m, from the CoG) at times ``t_ns`` (M,),
        with the :attr:`correction` where there is one."""
        t_ns = np.asarray(t_ns, dtype=np.int64)
        k = self._segment(t_ns)
        xy, psi = self._pose_from(k, t_ns)
        points = self._place(xy, psi + self._slip(k), lever_arms)
        if self.correction is not None:
            points += self.correction.at(np.asarray(t_ns).reshape(-1))[:, None, :]
        return points

    def on_radar_clock(self, late_ns: int) -> Trajectory:
        """The same motion with every instant ``late_ns`` (ns) later: the track as a radar whose frame stamps run
        that late reads it, at its stamps. Its ``info["radar_clock_offset_s"]`` adds up the shifts; the wheel gaps'
        and standstills' times move with it."""
        info = dict(self.info)
        if "wheel_gaps" in info:
            info["wheel_gaps"] = [{**g, "start_ns": g["start_ns"] + late_ns, "end_ns": g["end_ns"] + late_ns}
                                  for g in info["wheel_gaps"]]
        if "standstill_ns" in info:
            info["standstill_ns"] = [[a + late_ns, b + late_ns] for a, b in info["standstill_ns"]]
        info["radar_clock_offset_s"] = info.get("radar_clock_offset_s", 0.0) + late_ns / 1e9
        c = self.correction
        return replace(self, t_ns=self.t_ns + late_ns, info=info,
                       correction=None if c is None else replace(c, t_ns=c.t_ns + late_ns))

    def height_offset(self, t_ns: ArrayLike) -> Array:
        """How far (M,) (m) the body rises above its planar track at times ``t_ns`` (M,): the vertical part of the
        :attr:`correction` (the road's grade, the body's tilt; SAR-MIN's ``navigation.radar_height``), 0 without
        one. The focusing surface lies ``height_m`` above the planar plane raised by this at each pixel's closest
        approach (sar.focus), so that the radar's height above it is the planar one there."""
        t_ns = np.asarray(t_ns, dtype=np.int64)
        if self.correction is None:
            return np.zeros(t_ns.shape)
        return self.correction.at(t_ns.reshape(-1))[:, 2].reshape(t_ns.shape)

    def travel_velocity(self, t_ns: ArrayLike, lever_arms: ArrayLike,
                        half_span_s: float = TRAVEL_HALF_SPAN_S) -> Array:
        """Velocity (M, A, 3) (ENU m/s) of body points ``lever_arms`` (A, 3) (m, from the CoG) averaged over
        ``t_ns`` (M,) +- ``half_span_s``, clamped to the trajectory's span: the direction a synthetic aperture
        travels, along which focus's stripmap beam is pointed.

        The average is that of the trajectory's own motion (speed, heading, yaw rate: the CTRV segments
        between samples joined end to end), not a difference of its positions, so the steps between
        samples (a filter's updates, an INS's GNSS resets) do not tilt it. A 1 ms difference of SAR-MIN's
        positions on test1 jittered by 1.1 mrad RMS (4.5 mrad at most, against a processed half-beam of
        12 mrad); this average over +-50 ms by 0.09 mrad, and an INS's by 0.2 mrad where its 1 ms position
        differences jittered by 129 mrad (docs/FOCUS.md).
        """
        t_ns = np.asarray(t_ns, dtype=np.int64)
        h = int(round(half_span_s * 1e9))
        t_a = np.clip(t_ns - h, self.t_ns[0], self.t_ns[-1])
        t_b = np.clip(t_ns + h, self.t_ns[0], self.t_ns[-1])
        t_b = np.maximum(t_b, t_a + 1)  # a single sample, or a time beyond the span: the motion there (1 ns)
        lever = np.asarray(lever_arms, dtype=np.float64).reshape(-1, 3)
        # each segment's displacement under its own motion model, summed: the continuous path at every sample
        every = np.arange(len(self.t_ns))
        samples = self._place(self.rear_axle_enu, self.heading + self._slip(every), lever)
        xy_end, psi_end = self._pose_from(every[:-1], self.t_ns[1:])
        ends = self._place(xy_end, psi_end + self._slip(every[:-1]), lever)
        at_sample = np.concatenate([np.zeros((1, *samples.shape[1:])), np.cumsum(ends - samples[:-1], axis=0)])

        def path(t: NDArray[np.int64]) -> Array:
            k = self._segment(t)
            xy, psi = self._pose_from(k, t)
            return at_sample[k] + self._place(xy, psi + self._slip(k), lever) - samples[k]

        return (path(t_b) - path(t_a)) / ((t_b - t_a) * 1e-9)[:, None, None]

    def _slip(self, k: NDArray[np.intp]) -> Array | float:
        """Body yaw minus heading (rad) over the segments ``k``: the rear tyres' slip angle (0 without a gain)."""
        return self.rear_slip_gain * self.speed[k] * self.yaw_rate[k] if self.rear_slip_gain else 0.0

    def _place(self, xy: Array, psi: Array, lever_arms: ArrayLike) -> Array:
        """Body points (M, A, 3) of rear-axle positions xy (M, 2) and headings psi (M,)."""
        lever = np.asarray(lever_arms, dtype=np.float64).reshape(-1, 3)
        lx = lever[:, 0] + self.cog_to_rear_axle_m
        c, s = np.cos(psi)[:, None], np.sin(psi)[:, None]
        x = xy[:, :1] + c * lx - s * lever[:, 1]
        y = xy[:, 1:] + s * lx + c * lever[:, 1]
        z = np.broadcast_to(self.cog_height_m + lever[:, 2], x.shape)
        return np.stack([x, y, z], axis=-1)
