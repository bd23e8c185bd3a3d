"""The geoid separation a receiver reports: EGM96 from proj-data's 15-arc-minute grid (``egm96_15.gtx``).

Source: the EGM96 geopotential model (Lemoine et al. 1998, NASA/TP-1998-206861) as gridded by NGA and shipped by
PROJ (Debian package ``proj-data``, ``/usr/share/proj/egm96_15.gtx``; docs/sensors.md "GNSS receiver: geoid and message
sets"). GTX layout (NOAA
VDatum): a 40-byte big-endian header -- lower-left latitude and longitude, latitude and longitude spacing (float64,
degrees), rows and columns (int32) -- then ``rows * cols`` float32 big-endian heights of the geoid above the WGS-84
ellipsoid (m), row by row from the south, west to east. The value at a point is the bilinear interpolation of the
four surrounding nodes, as PROJ's ``vgridshift`` computes it (``tests/emulator/devices/test_geoid.py`` checks the
two against each other). This is the world's model of the receiver's geoid: the firmware carries its own, coarser
table (:mod:`firmware_model.geoid`) and never reads this one.
"""

from __future__ import annotations

import functools
import math
import os
from pathlib import Path

import numpy as np

from ..errors import ScenarioError

__all__ = ["EGM96_GTX", "egm96_separation_m"]

#: where Debian's proj-data puts the grid (PROJ_DATA / PROJ_LIB directories are searched first)
EGM96_GTX = "egm96_15.gtx"
_DIRS = ("/usr/share/proj", "/usr/local/share/proj")


def _grid_path() -> Path:
    dirs = [d for v in ("PROJ_DATA", "PROJ_LIB") for d in os.environ.get(v, "").split(os.pathsep) if d]
    for d in (*dirs, *_DIRS):
        p = Path(d) / EGM96_GTX
        if p.is_file():
            return p
    raise ScenarioError(f"{EGM96_GTX} not found in {[*dirs, *_DIRS]}: install Debian's proj-data "
                      "(apt-get install proj-data) or set the scenario's sensors.gnss.geoid_sep_m")


@functools.cache
def _grid() -> tuple[float, float, float, float, np.ndarray]:
    raw = _grid_path().read_bytes()
    lat0, lon0, dlat, dlon = np.frombuffer(raw, ">f8", 4, 0)
    rows, cols = (int(x) for x in np.frombuffer(raw, ">i4", 2, 32))
    g = np.frombuffer(raw, ">f4", rows * cols, 40).astype(np.float64).reshape(rows, cols)
    return float(lat0), float(lon0), float(dlat), float(dlon), g


def egm96_separation_m(lat_deg: float, lon_deg: float) -> float:
    """EGM96 geoid height N (m) above the WGS-84 ellipsoid at a geodetic position (deg): ``h = H_msl + N``."""
    lat0, lon0, dlat, dlon, g = _grid()
    rows, cols = g.shape
    y = (min(max(lat_deg, -90.0), 90.0) - lat0) / dlat
    x = ((lon_deg - lon0) % 360.0) / dlon
    i = min(math.floor(y), rows - 2)
    j = math.floor(x) % cols
    fy, fx = y - i, x - math.floor(x)
    j1 = (j + 1) % cols  # the grid wraps in longitude
    return float((1 - fy) * ((1 - fx) * g[i, j] + fx * g[i, j1]) + fy * ((1 - fx) * g[i + 1, j] + fx * g[i + 1, j1]))
