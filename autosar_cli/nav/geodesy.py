"""Geodesy: the one place that converts between geodetic coordinates, local ENU and UTM (WGS-84)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
import pymap3d
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from pyproj import Transformer


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
