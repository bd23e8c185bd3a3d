"""Print the firmware's geoid table (firmware_model/geoid.py ``_TABLE``) from proj-data's EGM96 grid.

Run once when the table is (re)generated: ``.venv/bin/python tools/make_geoid_table.py``; ``--check`` prints the
table's error against the full grid (docs/icd.md 5.1.2 quotes it). The nodes are the
5-degree nodes of ``egm96_15.gtx`` (emulator.devices.geoid reads it), rounded to whole metres, one signed byte each.
"""

from __future__ import annotations

from emulator.devices.geoid import egm96_separation_m


def main() -> None:
    for k in range(37):
        lat = -90.0 + 5.0 * k
        row = bytes(round(egm96_separation_m(lat, -180.0 + 5.0 * c)) & 0xFF for c in range(72)).hex()
        print(f'    "{row[:72]}"\n    "{row[72:]}"')




def check(n: int = 20000, seed: int = 2) -> None:
    """Print the table's error against the full grid at ``n`` random points (|lat| <= 85 deg): all, |N| >= 30 m."""
    import math

    import numpy as np

    from firmware_model.geoid import geoid_separation_m

    rng = np.random.default_rng(seed)
    pts = zip(rng.uniform(-85.0, 85.0, n), rng.uniform(-180.0, 180.0, n), strict=True)
    full, err = [], []
    for lat, lon in pts:
        ref = egm96_separation_m(lat, lon)
        full.append(ref)
        err.append(geoid_separation_m(math.radians(lat), math.radians(lon)) - ref)
    e, big = np.array(err), np.abs(np.array(full)) >= 30.0
    print(f"all: rms {np.sqrt(np.mean(e ** 2)):.2f} m, max {np.abs(e).max():.1f} m; |N| >= 30 m ({big.sum()} points): "
          f"mean |e| {np.abs(e[big]).mean():.2f} m, rms {np.sqrt(np.mean(e[big] ** 2)):.2f} m, "
          f"p95 {np.percentile(np.abs(e[big]), 95):.2f} m")


if __name__ == "__main__":
    import sys

    check() if sys.argv[1:] == ["--check"] else main()
