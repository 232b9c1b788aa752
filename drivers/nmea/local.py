"""Local east/north metres about a datum (lat0, lon0), on the WGS84 ellipsoid.

A local tangent-plane approximation with the ellipsoid's meridian and prime-vertical radii
of curvature at the datum: exact to millimetres within a few kilometres, which is the scale
a ground robot works at. ``to_local`` and ``to_geodetic`` are exact inverses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)


@dataclass(frozen=True)
class Datum:
    lat_deg: float
    lon_deg: float

    def __post_init__(self) -> None:
        m, n = self.radii
        # the radii and cos(lat), computed once (to_local multiplies in the same order)
        object.__setattr__(self, "_m", m)
        object.__setattr__(self, "_n", n)
        object.__setattr__(self, "_cos", math.cos(math.radians(self.lat_deg)))

    @property
    def radii(self) -> tuple[float, float]:
        """(meridian radius M, prime-vertical radius N) in metres at the datum."""
        s = math.sin(math.radians(self.lat_deg))
        w = 1.0 - WGS84_E2 * s * s
        n = WGS84_A / math.sqrt(w)
        m = WGS84_A * (1.0 - WGS84_E2) / (w * math.sqrt(w))
        return m, n

    def to_local(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """(east, north) metres of a point."""
        dlon = (lon_deg - self.lon_deg + 180.0) % 360.0 - 180.0
        east = math.radians(dlon) * self._n * self._cos  # type: ignore[attr-defined]
        north = math.radians(lat_deg - self.lat_deg) * self._m  # type: ignore[attr-defined]
        return east, north

    def to_geodetic(self, east_m: float, north_m: float) -> tuple[float, float]:
        """(lat, lon) degrees of a local point."""
        m, n = self.radii
        lat = self.lat_deg + math.degrees(north_m / m)
        lon = self.lon_deg + math.degrees(east_m / (n * math.cos(math.radians(self.lat_deg))))
        lon = (lon + 180.0) % 360.0 - 180.0
        return lat, lon
