"""Generate tests/vectors/sky/queen_pyskylumos.json with pyskylumos' QuEEN sky (run in a Python >= 3.12 side
environment; the project's own Python does not need pyskylumos)::

    ~/.pyenv/versions/3.12.1/bin/python -m venv /tmp/sky312
    /tmp/sky312/bin/pip install pyskylumos==0.1.3
    /tmp/sky312/bin/python tests/vectors/sky/make_queen_vectors.py > tests/vectors/sky/queen_pyskylumos.json

The sun is given explicitly (no ephemeris); for each sun (elevation, azimuth) the DOP and the AOP of the QuEEN sky
(world chart: ``arg(omega exp(-2 i alpha_s)) / 2``, the chart's real axis at azimuth 0, north, the imaginary
axis at azimuth 90 deg, east) on a grid of view directions, and the neutral points' positions from the quartic's
roots. tests/emulator/world/test_sky_queen.py compares emulator.world.sky's ``queen`` model with them.
"""

from __future__ import annotations

import json
import sys
import warnings

import numpy as np
import pyskylumos
from astropy.coordinates import AltAz, EarthLocation, SkyCoord
from astropy.time import Time
from astropy.units import deg, m
from pyskylumos.sky_models.QuEEN import QuEEN

SUNS_DEG = [(5.0, 120.0), (20.0, 200.0), (27.0, 250.0), (40.0, 135.0), (60.0, 300.0)]  # (elevation, azimuth)
DOP_MAX = 0.8


def main() -> None:
    loc = EarthLocation(lat=39.979 * deg, lon=116.339 * deg, height=50.0 * m)
    times = Time(["2019-09-18T08:14:00"])
    az = np.arange(0.0, 360.0, 30.0) + 7.0
    alt = np.arange(5.0, 90.0, 10.0)
    azg, altg = np.meshgrid(az, alt)
    out = {"generator": f"pyskylumos {pyskylumos.__version__} QuEEN, dop_max {DOP_MAX}",
           "command": "/tmp/sky312/bin/python tests/vectors/sky/make_queen_vectors.py", "dop_max": DOP_MAX,
           "view_az_deg": azg.ravel().tolist(), "view_alt_deg": altg.ravel().tolist(), "suns": []}
    for el, sa in SUNS_DEG:
        sky = QuEEN(times, loc, azg, altg, dop_max=DOP_MAX, out_of_range="ignore")
        frame = AltAz(location=loc, obstime=times[0])
        sun = SkyCoord(alt=el * deg, az=sa * deg, frame=frame)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = sky.simulate_sky(cie_sky_type=12, sun_position=sun)
        dop, aop = np.asarray(res[0]).ravel(), np.asarray(res[1]).ravel()
        out["suns"].append({
            "sun_el_deg": el, "sun_az_deg": sa, "dop": dop.tolist(), "aop_rad": aop.tolist(),
            "above_sun_az_el_rad": [float(np.ravel(res[6])[0]), float(np.ravel(res[7])[0])],
            "below_sun_az_el_rad": [float(np.ravel(res[8])[0]), float(np.ravel(res[9])[0])]})
    json.dump(out, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
