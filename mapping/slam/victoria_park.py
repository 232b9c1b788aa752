"""Loader of the Victoria Park data set (Guivant & Nebot, ACFR; slam-ekf.txt §5.1).

Reads the three MATLAB files of ``shared/data/victoria_park`` with ``scipy.io.loadmat``:

- ``aa3_dr.mat``: dead reckoning at 40 Hz, ``time`` (ms), ``speed`` (m/s at the rear left
  wheel encoder), ``steering`` (rad);
- ``VictoriaParkSinSincronizar.mat``: tree detections per laser scan, ``TLsr`` (s) and
  ``zt{k}`` = 3 x n (range m, bearing rad in 0..pi with pi/2 straight ahead, diameter m);
- ``aa3_gpsx.mat``: GPS in a local metric frame, ``timeGps`` (ms), ``Lo_m`` (x, east) and
  ``La_m`` (y, north).

All times are returned in seconds on the common data-set clock. The conversion to
messages (``VehicleControl``, ``LandmarkScan``, ``GpsFix``) stamps them as integer
nanoseconds of that clock. Reading files is the only I/O here; no clocks, no globals.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.io

from msgs.landmarks import LandmarkScan, VehicleControl
from msgs.sensors import GpsFix

DR_FILE = "aa3_dr.mat"
LASER_FILE = "VictoriaParkSinSincronizar.mat"
GPS_FILE = "aa3_gpsx.mat"
#: Duration of the data set used for real-time factors (s).
DURATION_S = 1549.0
#: Where the data set comes from, for the errors about a missing folder or file.
WHERE_FROM = (
    "The data set is ACFR's Victoria Park (J. Guivant and E. Nebot, University of Sydney); "
    f"its folder holds {DR_FILE}, {GPS_FILE} and {LASER_FILE}. A hilnav clone finds it in "
    "the shared data folder beside the clone (../shared/data/victoria_park; "
    "shared/data/README.md describes it and victoria_park/PROVENANCE.txt says where each "
    "file was taken from). Without that folder, get the files from ACFR's Victoria Park "
    "page (www-personal.acfr.usyd.edu.au/nebot/victoria_park.htm) or from the public "
    "EKF-SLAM repositories that carry them (tzuyichiu/EKF-SLAM-2D on GitHub has "
    f"{DR_FILE} and {GPS_FILE}, Mrstarr/Applied-Estimation-project has {LASER_FILE} in "
    "Victoria_data/), put them in one folder and pass that folder."
)


class VictoriaParkError(ValueError):
    """A Victoria Park file is missing or does not hold the expected variables."""


@dataclass(frozen=True)
class VictoriaParkData:
    """The whole data set as numpy arrays (seconds, metres, radians)."""

    dr_time_s: np.ndarray
    speed_mps: np.ndarray
    steering_rad: np.ndarray
    scan_time_s: np.ndarray
    scans: list[np.ndarray] = field(repr=False)
    gps_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gps_x_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gps_y_m: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def detections(self) -> int:
        """Total number of tree detections over all scans."""
        return int(sum(z.shape[1] for z in self.scans))

    def controls(self) -> Iterator[VehicleControl]:
        """The dead reckoning as :class:`VehicleControl` messages."""
        for t, v, s in zip(self.dr_time_s, self.speed_mps, self.steering_rad, strict=True):
            yield VehicleControl(_ns(t), float(v), float(s))

    def landmark_scans(self) -> Iterator[LandmarkScan]:
        """The detections as :class:`LandmarkScan` messages (bearing_zero="y")."""
        for t, z in zip(self.scan_time_s, self.scans, strict=True):
            yield LandmarkScan(
                _ns(t),
                tuple(float(v) for v in z[0]),
                tuple(float(v) for v in z[1]),
                tuple(float(v) for v in z[2]),
                bearing_zero="y",
                sensor="laser",
            )

    def gps_fixes(self) -> Iterator[GpsFix]:
        """The GPS as :class:`GpsFix` messages carrying only east_m/north_m (mode 2)."""
        for t, x, y in zip(self.gps_time_s, self.gps_x_m, self.gps_y_m, strict=True):
            yield GpsFix(_ns(t), mode=2, quality=1, east_m=float(x), north_m=float(y))


def _ns(t_s: float) -> int:
    return int(round(float(t_s) * 1e9))


def _load(path: Path) -> dict:
    if not path.is_file():
        raise VictoriaParkError(
            f"Victoria Park file missing: {path} (expected {DR_FILE}, {LASER_FILE} and "
            f"{GPS_FILE} in {path.parent}). {WHERE_FROM}"
        )
    try:
        return scipy.io.loadmat(str(path))
    except Exception as exc:  # scipy raises several types for corrupt files
        raise VictoriaParkError(f"cannot read {path} as a MATLAB file: {exc}") from exc


def _vector(mat: dict, name: str, path: Path) -> np.ndarray:
    if name not in mat:
        keys = sorted(k for k in mat if not k.startswith("__"))
        raise VictoriaParkError(f"{path.name} has no variable {name!r} (it has {keys})")
    return np.asarray(mat[name], dtype=float).ravel()


def _scan(cell: np.ndarray, k: int, path: Path) -> np.ndarray:
    z = np.asarray(cell, dtype=float)
    if z.size == 0:
        return np.zeros((3, 0))
    if z.ndim != 2 or z.shape[0] != 3:
        raise VictoriaParkError(f"{path.name}: zt{{{k + 1}}} has shape {z.shape}, expected 3 x n")
    return z


def load_victoria_park(directory: str | Path) -> VictoriaParkData:
    """Load the data set from ``directory`` (the folder holding the three .mat files).

    Raises :class:`VictoriaParkError` naming the missing file or variable.
    """
    d = Path(directory)
    if not d.is_dir():
        raise VictoriaParkError(f"Victoria Park directory not found: {d}. {WHERE_FROM}")
    dr_path, laser_path, gps_path = d / DR_FILE, d / LASER_FILE, d / GPS_FILE
    dr, laser, gps = _load(dr_path), _load(laser_path), _load(gps_path)

    dr_time = _vector(dr, "time", dr_path) / 1000.0
    speed = _vector(dr, "speed", dr_path)
    steering = _vector(dr, "steering", dr_path)
    if not (len(dr_time) == len(speed) == len(steering)):
        raise VictoriaParkError(f"{dr_path.name}: time, speed, steering differ in length")

    scan_time = _vector(laser, "TLsr", laser_path)
    if "zt" not in laser:
        raise VictoriaParkError(f"{laser_path.name} has no variable 'zt'")
    cells = np.asarray(laser["zt"], dtype=object).ravel()
    if len(cells) != len(scan_time):
        raise VictoriaParkError(
            f"{laser_path.name}: {len(cells)} scans in zt but {len(scan_time)} times in TLsr"
        )
    scans = [_scan(c, k, laser_path) for k, c in enumerate(cells)]

    gps_time = _vector(gps, "timeGps", gps_path) / 1000.0
    gps_x = _vector(gps, "Lo_m", gps_path)
    gps_y = _vector(gps, "La_m", gps_path)
    if not (len(gps_time) == len(gps_x) == len(gps_y)):
        raise VictoriaParkError(f"{gps_path.name}: timeGps, Lo_m, La_m differ in length")

    return VictoriaParkData(
        dr_time_s=dr_time,
        speed_mps=speed,
        steering_rad=steering,
        scan_time_s=scan_time,
        scans=scans,
        gps_time_s=gps_time,
        gps_x_m=gps_x,
        gps_y_m=gps_y,
    )
