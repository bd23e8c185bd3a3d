"""FPGA-to-DSP frames on DSP UART1 (IMU frame, MAG frame) and the accelerometer ADC words.

The virtual FPGA strobes the STIM210 external trigger every 5 ms (200 Hz), samples the three
analog accelerometers with a 24-bit ADC on the same edge, latches its free-running 1 MHz
counter on the trigger and on every GNSS PPS rising edge, and packs one IMU frame per
trigger. Layout (little-endian, the C6747's native byte order; ICD section "IMU frame")::

    off  size  field            type   unit / meaning
    0    2     sync             0x55 0xAA
    2    1     msg_type         u8     0x01 = IMU frame
    3    1     payload_len      u8     34 (bytes 4..37)
    4    2     seq              u16    frame sequence, wraps
    6    4     t_trigger_us     u32    FPGA counter at the ExtTrig edge, us (wraps after 71.6 min)
    10   4     t_pps_us         u32    FPGA counter latched at the last PPS rising edge, us
    14   1     pps_count        u8     number of PPS edges seen, wraps
    15   9     gyro             3x s24 STIM words X, Y, Z as received (2^-14 deg/s or 2^-21 deg)
    24   1     gyro_status      u8     STIM STATUS byte
    25   1     gyro_counter     u8     STIM 2000 Hz sample counter (steps by 10 at 200 Hz)
    26   2     gyro_latency_us  u16    STIM latency, us
    28   9     accel            3x s24 ADC codes X, Y, Z (see ADC scale below)
    37   1     fpga_status      u8     bit flags, :class:`FpgaStatus`
    38   2     crc              u16    CRC-16/CCITT-FALSE over bytes 2..37

Accelerometer ADC (documented design values; ICD "Accelerometer acquisition"):
24-bit two's-complement, +-4.096 V differential reference, so ``ADC_VOLTS_PER_LSB`` =
4.096 / 2^23 V. Accelerometers: Colibrys MS9030 on x (+-30 g, +-2.7 V differential output,
90 mV/g, the MS1000/MS9000 family table), and the +-25 g parts on y and z scaled to the
same +-2.7 V swing (108 mV/g). So one code is ``ADC_VOLTS_PER_LSB / ACCEL_VOLTS_PER_G[axis]``
g: 5.43 ug on x, 4.52 ug on y and z (:func:`accel_code_to_g`).

MAG frame (msg_type 0x02, same framing; docs/icd.md), one per magnetometer sample::

    off  size  field            type   unit / meaning
    0    2     sync             0x55 0xAA
    2    1     msg_type         u8     0x02 = MAG frame
    3    1     payload_len      u8     19 (bytes 4..22)
    4    2     seq              u16    frame sequence, wraps
    6    4     t_sample_us      u32    FPGA counter at the magnetometer sample, us
    10   12    field            3x i32 magnetic field, body axes x, y, z, 0.1 nT per LSB
    22   1     status           u8     :class:`MagStatus` bits
    23   2     crc              u16    CRC-16/CCITT-FALSE over bytes 2..22

:class:`ImuFrameFormat` accepts the IMU frame only; :class:`FpgaFrameFormat` accepts both frame types on
one stream.

Both frames are declared once, by their ``construct`` specs; the ``struct`` codecs are derived from them
(:mod:`protocols.codec`, whose 24-bit rule reads each s24 word as a u16 and an s8) and fill the dataclasses
by field name.
"""

from __future__ import annotations

import enum
from binascii import crc_hqx as _crc_hqx
from dataclasses import dataclass

from construct import Array, Const, Int8ul, Int16ul, Int24sl, Int32sl, Int32ul, Struct

from ._fastinit import fast_frozen_init
from .codec import StructCodec, subspec
from .crc import crc16_ccitt
from .stream import BAD_LENGTH, NEED_MORE

__all__ = [
    "ACCEL_VOLTS_PER_G",
    "ADC_CODE_MAX",
    "ADC_VOLTS_PER_LSB",
    "ADC_VREF_V",
    "IMU_FRAME_LEN",
    "IMU_FRAME_SPEC",
    "IMU_MSG_TYPE",
    "IMU_SYNC",
    "MAG_FRAME_LEN",
    "MAG_FRAME_SPEC",
    "MAG_LSB_T",
    "MAG_MSG_TYPE",
    "FpgaFrameFormat",
    "FpgaStatus",
    "ImuFrame",
    "ImuFrameFormat",
    "MagFrame",
    "MagStatus",
    "accel_code_to_g",
    "adc_code_to_volts",
    "build_imu_frame",
    "encode_mag_frame",
]

IMU_SYNC = b"\x55\xaa"
IMU_MSG_TYPE = 0x01
IMU_PAYLOAD_LEN = 34
IMU_FRAME_LEN = 40

#: ADC reference, V (full scale is +-ADC_VREF_V).
ADC_VREF_V = 4.096
#: Volts per ADC LSB.
ADC_VOLTS_PER_LSB = ADC_VREF_V / 2**23
#: Largest positive 24-bit code.
ADC_CODE_MAX = 2**23 - 1
#: Accelerometer sensitivity per axis, V/g (x: MS9030 90 mV/g; y, z: +-25 g over +-2.7 V).
ACCEL_VOLTS_PER_G = (0.090, 2.7 / 25.0, 2.7 / 25.0)


MAG_MSG_TYPE = 0x02
MAG_PAYLOAD_LEN = 19
MAG_FRAME_LEN = 25
#: Tesla per LSB of the MAG frame's field words (0.1 nT).
MAG_LSB_T = 1e-10


def adc_code_to_volts(code: int) -> float:
    """Differential input voltage, V, of one 24-bit ADC code."""
    return code * ADC_VOLTS_PER_LSB


def accel_code_to_g(code: int, axis: int) -> float:
    """Specific force, g, of one ADC code on accelerometer ``axis`` (0 = x, 1 = y, 2 = z)."""
    return code * ADC_VOLTS_PER_LSB / ACCEL_VOLTS_PER_G[axis]


class FpgaStatus(enum.IntFlag):
    """``fpga_status`` bits of the IMU frame."""

    GYRO_MISSING = 0x01  #: no valid gyro datagram since the previous trigger (fields repeat the last one)
    GYRO_CRC_ERROR = 0x02  #: at least one gyro datagram failed its CRC since the previous frame
    GYRO_COUNTER_JUMP = 0x04  #: gyro counter did not step by the expected amount
    ADC_OVERRANGE = 0x08  #: an ADC code is at full scale
    PPS_VALID = 0x10  #: a PPS edge was seen within the last 1.5 s


# Field docs are "scale | unit | meaning" (read by protocols.icd for docs/icd.md).
IMU_FRAME_SPEC = Struct(
    "sync" / Const(IMU_SYNC) * " |  | 0x55 0xAA",
    "msg_type" / Const(IMU_MSG_TYPE, Int8ul) * " |  | 0x01 = IMU frame",
    "payload_len" / Const(IMU_PAYLOAD_LEN, Int8ul) * " | bytes | 34 (bytes 4..37)",
    "seq" / Int16ul * "1 |  | frame sequence, wraps",
    "t_trigger_us" / Int32ul * "1 | us | FPGA 1 MHz counter at the ExtTrig edge (wraps after 71.6 min)",
    "t_pps_us" / Int32ul * "1 | us | FPGA counter latched at the last PPS rising edge",
    "pps_count" / Int8ul * "1 |  | PPS edges seen, wraps",
    "gyro" / Array(3, Int24sl)
    * "2^-14 / 2^-21 | deg/s / deg | STIM words X, Y, Z as received (rate / incremental angle)",
    "gyro_status" / Int8ul * " |  | STIM STATUS byte (TS1524 Table 5-23)",
    "gyro_counter" / Int8ul * "1 |  | STIM 2000 Hz sample counter (steps by 10 at 200 Hz)",
    "gyro_latency_us" / Int16ul * "1 | us | STIM latency",
    "accel" / Array(3, Int24sl) * "4.096/2^23 | V | ADC codes X, Y, Z; g = V / ACCEL_VOLTS_PER_G (90 / 108 / 108 mV/g)",
    "fpga_status" / Int8ul * " |  | FpgaStatus bits",
    "crc" / Int16ul * " |  | CRC-16/CCITT-FALSE over bytes 2..37",
)


class MagStatus(enum.IntFlag):
    """``status`` bits of the MAG frame."""

    OVERFLOW = 0x01  #: an axis is at its measurement-range limit
    STALE = 0x02  #: no new magnetometer sample since the previous frame (fields repeat the last one)
    SENSOR_ERROR = 0x04  #: the magnetometer reported an error or did not answer


MAG_FRAME_SPEC = Struct(
    "sync" / Const(IMU_SYNC) * " |  | 0x55 0xAA",
    "msg_type" / Const(MAG_MSG_TYPE, Int8ul) * " |  | 0x02 = MAG frame",
    "payload_len" / Const(MAG_PAYLOAD_LEN, Int8ul) * " | bytes | 19 (bytes 4..22)",
    "seq" / Int16ul * "1 |  | frame sequence, wraps",
    "t_sample_us" / Int32ul * "1 | us | FPGA counter at the magnetometer sample",
    "field" / Array(3, Int32sl) * "0.1 | nT | magnetic field, body axes x, y, z",
    "status" / Int8ul * " |  | MagStatus bits",
    "crc" / Int16ul * " |  | CRC-16/CCITT-FALSE over bytes 2..22",
)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class ImuFrame:
    """One decoded FPGA IMU frame (raw integer fields; see module docstring for units)."""

    seq: int
    t_trigger_us: int
    t_pps_us: int
    pps_count: int
    gyro: tuple[int, int, int]
    gyro_status: int
    gyro_counter: int
    gyro_latency_us: int
    accel: tuple[int, int, int]
    fpga_status: int


_IMU = StructCodec(IMU_FRAME_SPEC, "IMU_FRAME")
#: The CRC-covered body (msg_type .. fpga_status), for the encoder.
_IMU_BODY = StructCodec(subspec(IMU_FRAME_SPEC, "msg_type", "fpga_status"), "IMU_FRAME_BODY")
if _IMU.size != IMU_FRAME_LEN:  # pragma: no cover
    raise AssertionError("IMU_FRAME_LEN disagrees with IMU_FRAME_SPEC")
#: The payload (seq .. fpga_status), for the decoder: the stream has checked sync, type, length and CRC.
_IMU_PAYLOAD = StructCodec(subspec(IMU_FRAME_SPEC, "seq", "fpga_status"), "IMU_FRAME_PAYLOAD")
_decode_imu_payload = _IMU_PAYLOAD.decoder(ImuFrame)

#: The body from the frame's fields as arguments (ImuFrame's order): the FPGA has the values, not an object.
_encode_imu_body = _IMU_BODY.encoder(ImuFrame, convert={
    "seq": (0xFFFF).__and__, "t_trigger_us": (0xFFFFFFFF).__and__, "t_pps_us": (0xFFFFFFFF).__and__,
    "pps_count": (0xFF).__and__, "gyro_status": (0xFF).__and__, "gyro_counter": (0xFF).__and__,
    "gyro_latency_us": (0xFFFF).__and__, "fpga_status": (0xFF).__and__}, from_args=True)


def build_imu_frame(seq: int, t_trigger_us: int, t_pps_us: int, pps_count: int, gyro: tuple[int, int, int],
                    gyro_status: int, gyro_counter: int, gyro_latency_us: int, accel: tuple[int, int, int],
                    fpga_status: int) -> bytes:
    """The frame of ``ImuFrame(seq, t_trigger_us, ...)`` (:meth:`ImuFrameFormat.build`) from its fields, without the
    object (the FPGA's sender, once per trigger)."""
    body: bytes = _encode_imu_body(seq, t_trigger_us, t_pps_us, pps_count, gyro, gyro_status, gyro_counter,
                                   gyro_latency_us, accel, fpga_status)
    return IMU_SYNC + body + crc16_ccitt(body).to_bytes(2, "little")


class ImuFrameFormat:
    """:class:`~protocols.stream.FrameFormat` of the FPGA IMU frame."""

    name = "imu"
    sync = IMU_SYNC

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        if len(buf) - start < 4:
            return NEED_MORE
        if buf[start + 2] != IMU_MSG_TYPE or buf[start + 3] != IMU_PAYLOAD_LEN:
            return BAD_LENGTH
        return IMU_FRAME_LEN

    def check(self, frame: bytes) -> bool:
        return crc16_ccitt(frame[2:38]) == (frame[38] | (frame[39] << 8))

    def parse(self, frame: bytes) -> ImuFrame:
        f: ImuFrame = _decode_imu_payload(frame, 4)
        return f

    def build(self, f: ImuFrame) -> bytes:
        """Encode ``f`` (counters wrap to their width; a gyro or accel word outside s24 raises ``ValueError``)."""
        return build_imu_frame(f.seq, f.t_trigger_us, f.t_pps_us, f.pps_count, f.gyro, f.gyro_status, f.gyro_counter,
                               f.gyro_latency_us, f.accel, f.fpga_status)

    encode = build


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class MagFrame:
    """One decoded FPGA MAG frame: ``field`` in 0.1 nT (body x, y, z); times in FPGA us."""

    seq: int
    t_sample_us: int
    field: tuple[int, int, int]
    status: int


_MAG = StructCodec(MAG_FRAME_SPEC, "MAG_FRAME")
_MAG_BODY = StructCodec(subspec(MAG_FRAME_SPEC, "msg_type", "status"), "MAG_FRAME_BODY")
if _MAG.size != MAG_FRAME_LEN:  # pragma: no cover
    raise AssertionError("MAG_FRAME_LEN disagrees with MAG_FRAME_SPEC")
_MAG_PAYLOAD = StructCodec(subspec(MAG_FRAME_SPEC, "seq", "status"), "MAG_FRAME_PAYLOAD")
_decode_mag_payload = _MAG_PAYLOAD.decoder(MagFrame)

_encode_mag_body = _MAG_BODY.encoder(MagFrame, convert={
    "seq": (0xFFFF).__and__, "t_sample_us": (0xFFFFFFFF).__and__, "status": (0xFF).__and__})


def encode_mag_frame(f: MagFrame) -> bytes:
    """Whole MAG frame for ``f`` (seq and time wrap like the FPGA counters; a field word outside i32 raises
    ``ValueError``)."""
    body = _encode_mag_body(f)
    return IMU_SYNC + body + crc16_ccitt(body).to_bytes(2, "little")


class FpgaFrameFormat:
    """:class:`~protocols.stream.FrameFormat` of every FPGA-to-DSP frame on UART1 (IMU and MAG)."""

    name = "fpga"
    sync = IMU_SYNC

    def __init__(self) -> None:
        self._imu = ImuFrameFormat()

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        if len(buf) - start < 4:
            return NEED_MORE
        t, n = buf[start + 2], buf[start + 3]
        if t == IMU_MSG_TYPE and n == IMU_PAYLOAD_LEN:
            return IMU_FRAME_LEN
        if t == MAG_MSG_TYPE and n == MAG_PAYLOAD_LEN:
            return MAG_FRAME_LEN
        return BAD_LENGTH

    def check(self, frame: bytes) -> bool:
        return _crc_hqx(frame[2:-2], 0xFFFF) == (frame[-2] | (frame[-1] << 8))  # crc16_ccitt, one call less

    def parse(self, frame: bytes) -> ImuFrame | MagFrame:
        f: ImuFrame | MagFrame = (_decode_imu_payload if frame[2] == IMU_MSG_TYPE else _decode_mag_payload)(frame, 4)
        return f

    def build(self, f: ImuFrame | MagFrame) -> bytes:
        """Encode either frame type."""
        if isinstance(f, MagFrame):
            return encode_mag_frame(f)
        return self._imu.build(f)

    encode = build
