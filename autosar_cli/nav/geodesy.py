"""Geodesy: converting between geodetic coordinates, local ENU and UTM (WGS-84).

The code lives in :mod:`autosar_cli.types` (store/ reads and writes the origin); this is its place in nav/.
"""

from autosar_cli.types import GeodeticOrigin, geodetic_to_utm

__all__ = ["GeodeticOrigin", "geodetic_to_utm"]
