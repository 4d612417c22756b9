"""Geodesy: the one place that converts between geodetic coordinates, local ENU and UTM (WGS-84)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d
from numpy.typing import ArrayLike, NDArray


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
        """EPSG code of the WGS-84 UTM zone holding the origin."""
        zone = int((self.lon_deg + 180.0) // 6.0) + 1
        return (32600 if self.lat_deg >= 0 else 32700) + zone
