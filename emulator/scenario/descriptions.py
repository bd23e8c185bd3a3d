"""Descriptions of scenario properties whose field declares none (applied by :class:`.base.Model`).

Keyed ``"Model.field"``. A field's own ``Field(description=...)`` always wins; a field holding another section
without an entry here takes that section's docstring. Kept apart from the section modules so that adding a
description never touches a field's line.
"""

from __future__ import annotations

__all__ = ["DESCRIPTIONS"]

DESCRIPTIONS: dict[str, str] = {
    "Scenario.name": "the scenario's name: run directories, reports and goldens are named after it",
    "Scenario.description": "one line on what the scenario shows",
    "Scenario.seed": "random seed of every sensor and fault model (same seed + mem:// links: identical bytes)",
    "Scenario.epoch": "UTC date and time of t = 0 (ISO 8601); places the Sun and the sky",
    "Scenario.duration_s": "simulated duration of the run, s",
    "Scenario.mode": "fast (virtual time) or realtime (wall clock); --fast / --realtime override it",
    "Scenario.speed": "real-time scale factor in realtime mode (2 = twice as fast as the wall clock)",
    "Scenario.origin": "start position (WGS-84 latitude, longitude, ellipsoidal height)",
    "Scenario.attitude": "start attitude: heading clockwise from true north, pitch nose-up, roll right-wing-down, deg",
    "Scenario.sky": "the sky polarization model the camera and the compass see",
    "Scenario.sensors": "the modelled sensors: IMU, GNSS receiver, polarization camera or compass, magnetometer",
    "Scenario.links": "the external ports by URL (mem://, pty://, serial://, zenoh://, can://) and their lines",
    "Scenario.fpga": "the virtual FPGA: routing of ports to DSP UARTs, acquisition and monitor settings",
    "Scenario.dsp": "the virtual DSP: clock, UART FIFOs, watchdog",
    "Scenario.firmware": "the firmware: filter variant, precision, output rate, alignment and measurement settings",
    "Sensors.imu": "the STIM210 gyro and the accelerometers (or a recorded IMU file)",
    "Sensors.gnss": "the GNSS receiver (NMEA/UBX at 1 Hz with PPS), or a recorded fix file",
    "Sensors.camera": "the polarization camera (IMX250MZR); needs links.psns",
    "Sensors.compass": "a multi-unit polarization compass instead of the camera; needs links.psns",
    "Sensors.magnetometer": "a magnetometer sampled by the FPGA (MAG frames on UART1)",
    "Links.gyro": "the STIM210 gyro port (RS422, 460800 baud by default)",
    "Links.gnss": "the GNSS receiver port (RS422, 9600 baud by default)",
    "Links.psns": "the polarization sensor port (RS232, 115200 baud by default); required by a camera or compass",
    "Links.host": "the host port: navigation frames out, commands in (RS422, 460800 baud by default)",
    "DspSpec.clock_hz": "DSP clock, Hz (the C6747 runs at 300 MHz): cycles become time at this rate",
    "DspSpec.uarts": "per DSP UART (uart0..uart3): FIFO depth and trigger level",
    "DspSpec.watchdog": "the DSP watchdog: resets the firmware after a long overrun",
    "ImuSpec.preset": "named IMU preset whose figures the fields below override",
    "ImuSpec.format": "STIM210 datagram content code (s, e, j..p: the datasheet's datagram types), "
                      "as the gyro is configured",
    "ImuSpec.output": "what the gyro datagram carries: angular rate or integrated angle",
    "ImuSpec.rate_hz": "IMU output rate, Hz (the FPGA triggers the gyro at this rate)",
    "ImuSpec.gyro": "gyro error model (noise, bias, scale factor)",
    "ImuSpec.accel": "accelerometer error model (bias, scale factor, noise)",
    "ImuSpec.temperature": "IMU temperature profile (drives temperature-dependent errors)",
    "ImuSpec.recorded": "IMU samples from a CSV file instead of the model",
    "GnssSpec.enabled": "whether the receiver is present (false: no fixes, no PPS)",
    "GnssSpec.preset": "named receiver preset whose figures the fields below override",
    "GnssSpec.rate_hz": "fix rate, Hz",
    "GnssSpec.latency_s": "delay from the PPS edge to the first sentence, s",
    "GnssSpec.talker": "NMEA talker id (GP, GN, ...)",
    "GnssSpec.geoid_sep_m": "geoid separation reported in GGA, m",
    "GnssSpec.fix_quality": "GGA fix quality to report (default: from the fix)",
    "GnssSpec.num_sats": "satellites in use reported in GGA",
    "GnssSpec.hdop": "horizontal dilution of precision reported in GGA",
    "GnssSpec.errors": "fix error model (position and velocity noise, bias)",
    "GnssSpec.outages": "time windows without fixes",
    "GnssSpec.glitches": "time windows with a position step",
    "GnssSpec.recorded": "fixes from a CSV or NMEA file instead of the model",
    "FirmwareSpec.filter": "the filter variant (docs/variants.md): base, dual_vector, kmeans_3d, federated, "
                           "sun_elevation",
    "FirmwareSpec.precision": "floating-point precision of the filter (float32 as the C674x, or float64)",
    "FirmwareSpec.output_rate_hz": "NAV_SOLUTION rate on the host port, Hz",
    "FirmwareSpec.kf_predict_every": "Kalman time update every N IMU ticks",
    "FirmwareSpec.alignment": "coarse and fine alignment settings",
    "FirmwareSpec.psns": "solar-vector measurement settings",
    "FirmwareSpec.variants": "parameters of the filter variants and their mode manager",
}
