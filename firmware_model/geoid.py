"""The firmware's own geoid: EGM96 on a 5-degree grid, whole metres, to fill an empty geoid-separation field (D-5.40).

Receivers carry a coarse geoid table of their own to report the separation, and so does gpsd to fill the field
(``geoid.c``, ``wgs84_separation``: 19 x 37 whole metres at 10 degrees, bilinear; docs/icd.md 5.1.3). A receiver
that leaves the GGA/GNS separation field empty reports only the height above MSL, and the firmware then needs ``N``
to get the ellipsoidal height ``h = H_msl + N``.

This table is EGM96 (Lemoine et al. 1998, NASA/TP-1998-206861; NGA's geoid undulations) sampled at the 5-degree
nodes of its 15-arc-minute grid (PROJ's ``egm96_15.gtx``) and rounded to whole metres, one signed byte per node:
37 rows of latitude (-90 .. +90 deg, south first) by 72 columns of longitude (-180 .. +175 deg, east from -180).
Bilinear interpolation between the nodes gives the separation within 1.4 m on average (2.3 m rms) where
``|N| >= 30 m`` and 1.9 m rms over the globe (``tools/make_geoid_table.py --check`` against the full grid); 2.6 KiB.
The table was generated once by ``tools/make_geoid_table.py`` and is data of the firmware, not read from the world's
model at run time.
"""

from __future__ import annotations

import math

__all__ = ["GEOID_STEP_DEG", "geoid_separation_m"]

#: node spacing of the table, deg
GEOID_STEP_DEG = 5.0
_ROWS, _COLS = 37, 72
_TABLE = bytes.fromhex(
    "e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2"
    "e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2e2"
    "dbd8d9d7d6d6d5d7d8dadadbdededee2e3e5e6e3e2e4e7eae7e7e7e7edefedeeeff0f0f0"
    "f1f0f0f2f2f3f5f6f7f6f6f6f6f6f5f4f2f0eeeceae8e6e3e0dedddcdcdbdcdbdcdcdadd"
    "cbcbcbcbcccbcdced0d2d6d7d9dadbdfe4e7eaeae7e9eaebebeaecefeeefeff1f3f4f6f7"
    "f9fbfdff0103040204050608080505060401fef8f2ede8e2ded9d7d4cfcececdcacccdcd"
    "c2c1c1c1c0c1c2cad0d4d6dadcdde2e5e7ebedeff1f4faf7f6f6f7f9fcfdfeffff040a0b"
    "090b0d0f101110100f10100f0d0d0908070602fbf5efe7e1dcd9d5d0cdc9c6c6c8c6c5c5"
    "c2c0c1c2c3c4c7c9ccd1d4d8dbdddfe1e6e7ebf4f6fc040d05010002030201020204090b"
    "0e0f0e1110151515151b1b1b1a1c1111100d0803faf3eee8e3e0dbd6d4cdc9c8c8c7c5c5"
    "cccdcdcecfd1d2d5d6d7dadde0e2e4e7e9ecf1f5fa00060f12130d0e0e0d0c0a0909090b"
    "0e111114131315181a1c1e1e1c1b1814100d0703fff7efece3dfddd9d4d3d2d4d4d1cecc"
    "d2d3d5d8dbdee0e1e2e3e5e7e8e9e9eceff2f5f9fc020911141414101617180a1513110f"
    "0f111418191b1d2022222121211f1d1b19110903fdf8f2ece7e4e1dfdfe1e2e1ddd8d4d1"
    "dedee0e2e5e7e9eaeceeeef1f3f3f3f3f5f6fafd02030d0c110f0f101015080f1416181b"
    "1b1a181b202223272c2c29272523232119130d0700faf4eeeae7e7e8e9ebeae9e6e5e2df"
    "efededeeeeeef0f0efeef0f4f6f6f5f6f7f9fd00050d0b0b0c08020303060b1014191b1b"
    "1919191e212326292d2d2d2b262828211b140d06fef7f1ece9e8eaecedefefeff2f4f6f4"
    "0300faf7f8f8f4f3f1f1f2f4f5f6f6f7f9fcff03070d110c0900fdfdfbfe070f161a1a18"
    "15161a1c2021222c2e2e2d2a24201f1b150f08fff7efe9e5e5e5e8eceff1f4f7f9fd0806"
    "150d060301fef9f6f4f3f3f4f3f4f6f7f9fdff01070a170f0e05fdfaf9fe060e15181714"
    "1114191c1d222121262b28231d1a17120d06fef4ebe4dfdedee1e5ebf1fefe02050c130d"
    "1c19110a0500fcf8f6f5f5f5f4f5f6f8fafcfe01070d1e14110d00faf9fd070c11131112"
    "12141819201a1a1d1a211f1e16150f0a04faf1e8e0d8d9dddddfe4f5010a140f131a2026"
    "301f170e0601fffaf7f4f3f5f6f7f8fafcfe0103080f2518120b03f9f70003060a0e0f11"
    "15171a2022201e140e130e0f0f0a0600f7eee7e0dad9d8e3e9eef2000d16201d21242c2d"
    "321c190e0802fdf9f5f3f5f6f9fbfbfdfe0002040811241d150604faf5f9fbff040a0d10"
    "141a18201c18150b030801010000fbf2e8e0dad5d6dadeeef7fc030d1a222e2b30303534"
    "32341a0f0904fffaf7f5f5f7fafdfefdfcfdff010810222a1404f8f9f9f8fafaff070c0d"
    "1013171a160d07fcf6faf5f5f6f4ebe0d8d1d0d0d2dde6f4040e18212e373937393b403d"
    "312a1a0e090601fdf9f6f6f7f9fcfdfbf9f9fafd071e2f1a10fef7f3f5f5f9fa00070b0d"
    "0d0e10160d04f8f4ece6f1eae8e1d7ccc7c3c6cfd8e4f2ff0f20273036413f3f403b413a"
    "231b150f0b0705fffdfaf7f6f5f6f8f7f4f5f7fcff1b1b1203f6edf0f4f4f6fa040a0d0d"
    "0b0a0d1106fbf3f1e5dfe0dedacdc3b7b4b9bfd1e5fafe0b2421343f45474e473f3a3329"
    "181311110e0c0a0601fbf6f2f0f0f2f2f2f2f6fe110f1406f8ece8e7f4f9fbff070f1211"
    "11090602f6eff1ede2d6d5d7cabeb2a6a3adc0d6ed0d1c2b363837444c4652403b2f271f"
    "15120f0f10100d0801f9f3ede9e9eceef2f5fc010e140efef3e7e6e9edf8020a0d131313"
    "111009ffefedf6f0e5d5cfccc1b5a79c99a7c1def90e22363a334d4848453f3b31292019"
    "100f0c0e100e0903fcf3ece6e2e2e6edf3f9ff060d17fef7eddedce1eefc070c11141b1a"
    "14151409f8f6f5f3ebdecfcac2b2a29b96a6c4d6f303172c3e404644423f37342d221c16"
    "0d0a0c0f0a0601fcf5ebe3dcd9dbe3ecf4fb010a01fbf5e4d6d3d5e0f0f9030b111e211c"
    "1717160d02fffbfcf6ece0cdc6b4a59fa0a8c1d2e7f70b2034413b3c3d372d29231c1913"
    "0908080a0501fcf6efe6dcd6d3d7e0ebf5f60203faeee2d8c9cfdae6effb0814171f1e1c"
    "1615140e0a090400fcf8ebdecabdafada9adc0cedeebfd12292a303234372c231d17100c"
    "04050909080cf9f1e9e1d9d3d0d5deebf9edf5f1ede5d1c1d1d5dfeef602111719221e1b"
    "1f1b1b140e0e0a0602f6e1dbd5c9c3bdbcc1c4cddbe4f3051521262a312f291c160e0905"
    "fd00070403fef5efe7dfd7d2d1d5ddebf0e0e5e5e4d5cccdcfd7e6f8010912161f22261e"
    "1b232119160f0d0c0afee5dfe0d6d2ccc4c2cacdd9e0ebfc0f1c21252e261c130a03fffc"
    "f8f9fbfaf7f4f0ebe4ded8d5d6dde2e8e9e3e5e3e0d2ccd3d7dfee0110191e1e22282b2e"
    "231a1c1e1a1510110afceefaf1e5d9d2dde4dedae0d6e8f507171e242a1e130b03fcf9f9"
    "f6f4f3f3f1efeae5dfdad8d7dee2e8eae4e0e4e1e0d5d3d9e1e9f8091b292c2b292e2b2c"
    "3225252217140713140606f7efeae0e4e7ddd8d6d8d9e0f004141e2422170f05fef7f4f6"
    "f3f4f5f5f3f0ebe6e1dddbdee9edeeefe7e0dfdedededddee5f10110202e3b3a34303136"
    "332d2e2e222827221d14f0f1e4dcd7ddc8bebdc5c9d3e3f50311171e26111106fef8f5f4"
    "fafbfdfdfcf8f3eee8e5e6e5edf2f9f1e9e5dedddbe0e6eaf1fe111c27333d413d39332d"
    "2f33272e2c251f160d01f5ece3dbd6d1d8c1c5cbcfd4e0f1000b171d1c1a0e0c05fdfdf9"
    "faff0509070500fbf4efeeeff0f2efede8e2ddd8d8dce6e9f30818202d363e3f3e393a35"
    "2d2f302d28201b100b00f4efede3dfdad3d5d6d2d6d8e2edfb090f151613141806050301"
    "ff050910110a0b0600f9f9f6f1ede7e3dfd8d3d2d4dbe6f0f80d1927323c3c3d3d3a3a37"
    "2e2928221b1813100b0602faf6ece6dfdcdbdadad8dee2eef700090f10101315160105fe"
    "0006090c0f0f0d0c0b0700f9f0e8e1dcd6d0d1d3d6e2e9f805111d293138403f3d3c3736"
    "302d281d131210100b0a0600fcf1ebe6e1e0dedfdee1e4e6effa01050c0e10100e0d09fe"
    "05050407090a0b0c0b0802f5f0eae4ded8d8dbdde0e7f3fe101a21302c383b4043423c35"
    "332c2820191212110d080600fff6f2eeecebe9e7e8eaedeeeff0fc00040907080a0b0906"
    "03000100ff00fffefdfcf8f5f1eee7e4e4e6e6eaeef8030a171c1e272e36393a3c3b3833"
    "312d2a261e18140f0b0703fffdf9f7f6f3f2f3f2f1f3f7f5f7f6fafdff00020203040404"
    "02020300fefbfcfcf9f7fcf6f4f5f3f2f5f9fc02060e12121319202325292d2e2c2e2e2d"
    "2c2c29281f1a15110c08040201fdfbfaf9f9f9f7f7f7fafbfcfefeff0001010102020302"
    "04040302010000fffefefdfeff03040203080b080f0d070b12181c1f22252421201f2022"
    "222323211e1b181612100d0b0907040402010202020200ffff00ffff0002030201010202"
    "0809090a0a0a0a0a0b0b0b0c0d0d0e0e0f1010111213141516161515161818191a1a1919"
    "191919191818171514131211100f0e0e0d0d0c0c0c0b0b0a090908070909070706060707"
    "0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e"
    "0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e0e"
)
if len(_TABLE) != _ROWS * _COLS:  # pragma: no cover
    raise AssertionError("geoid table size")


def _node(i: int, j: int) -> int:
    v = _TABLE[i * _COLS + j % _COLS]
    return v - 256 if v > 127 else v


def geoid_separation_m(lat_rad: float, lon_rad: float) -> float:
    """EGM96 geoid height N (m, above the WGS-84 ellipsoid) at a geodetic position (rad), bilinear in the table."""
    lat = min(max(math.degrees(lat_rad), -90.0), 90.0)
    y = (lat + 90.0) / GEOID_STEP_DEG
    x = ((math.degrees(lon_rad) + 180.0) % 360.0) / GEOID_STEP_DEG
    i = min(int(y), _ROWS - 2)
    j = int(x)
    fy, fx = y - i, x - j
    return ((1.0 - fy) * ((1.0 - fx) * _node(i, j) + fx * _node(i, j + 1))
            + fy * ((1.0 - fx) * _node(i + 1, j) + fx * _node(i + 1, j + 1)))
