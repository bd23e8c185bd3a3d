"""Print the firmware's geoid table (firmware_model/geoid.py ``_TABLE``) from proj-data's EGM96 grid.

Run once when the table is (re)generated: ``.venv/bin/python tools/make_geoid_table.py``. The nodes are the
5-degree nodes of ``egm96_15.gtx`` (emulator.devices.geoid reads it), rounded to whole metres, one signed byte each.
"""

from __future__ import annotations

from emulator.devices.geoid import egm96_separation_m


def main() -> None:
    for k in range(37):
        lat = -90.0 + 5.0 * k
        row = bytes(round(egm96_separation_m(lat, -180.0 + 5.0 * c)) & 0xFF for c in range(72)).hex()
        print(f'    "{row[:72]}"\n    "{row[72:]}"')


if __name__ == "__main__":
    main()
