"""The firmware's build/run-time configuration: :class:`FirmwareConfig`, the UART map and the build's filter table.

UART map (docs/architecture.md, the system being emulated): UART0 host (navigation out, commands in), UART1 IMU
frames from the FPGA, UART2 PSNS (POLARIZATION_OBS / SOLAR_VECTOR / COMPASS frames), UART3 GNSS (the FPGA's
16550 core, read over EMIFA).

:data:`FILTER_VARIANTS` is the table of filter variants built into this firmware. It lives here, below the
filters, because the configuration validates ``FirmwareConfig.filter`` against it while every filter takes a
:class:`FirmwareConfig`; :func:`firmware_model.filters.interface.register_filter` fills it (the base filter and the
variants of :mod:`firmware_model.variants`, which :mod:`firmware_model.firmware` imports).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from protocols.imu_frame import ACCEL_VOLTS_PER_G

from .errors import FirmwareError
from .psns_geometry import CameraGeometry
from .variants.params import VariantParams

__all__ = ["FILTER_VARIANTS", "NMEA_NAV_SENTENCES", "UART_GNSS", "UART_HOST", "UART_IMU", "UART_PSNS",
           "FirmwareConfig"]

UART_HOST, UART_IMU, UART_PSNS, UART_GNSS = 0, 1, 2, 3
#: NMEA sentences the firmware can write on the host UART: position/velocity/time, then heading and attitude
NMEA_NAV_SENTENCES = ("GGA", "RMC", "VTG", "ZDA", "HDT", "THS", "PASHR")

#: The filter variants of this build by ``FirmwareConfig.filter`` name:
#: :class:`firmware_model.filters.interface.NavFilter` subclasses, entered by
#: :func:`firmware_model.filters.interface.register_filter` (typed loosely here, as the filter interface sits above
#: the configuration that selects it).
FILTER_VARIANTS: dict[str, type[Any]] = {}


@dataclass
class FirmwareConfig:
    """Firmware build/run-time parameters (units in the names)."""

    clock_hz: float = 300e6
    imu_rate_hz: float = 200.0
    gyro_output: str = "rate"  # "rate" (2^-14 deg/s) or "angle" (2^-21 deg per sample)
    gyro_counter_step: int = 10
    coning_samples: int = 0  # 0: automatic (2 with angle increments, 1 with rate output), or 1 / 2
    kf_predict_every: int = 20
    output_rate_hz: float = 100.0
    #: NMEA 0183 sentences of the navigation solution on the host UART, next to NAV_SOLUTION (docs/icd.md, "NMEA
    #: navigation output"): any of GGA, RMC, VTG, ZDA (at ``nmea_rate_hz``), HDT, THS, PASHR (at
    #: ``nmea_attitude_rate_hz``); empty: none
    nmea_sentences: tuple[str, ...] = ()
    nmea_rate_hz: float = 1.0
    nmea_attitude_rate_hz: float = 1.0
    nmea_talker: str = "GN"
    #: the UART the NMEA sentences leave on: the host UART (next to NAV_SOLUTION) or a second host port's
    nmea_uart: int = UART_HOST
    #: the ``$PSNS`` text output (docs/icd.md 7: $PSNSPOS, VEL, ATT, STA of the tick's NAV_SOLUTION) for terminal
    #: users, sentences groups per second on the NMEA UART (``nmea_uart``); 0: off. Divides the IMU rate; written
    #: on ticks that also send a NAV_SOLUTION
    text_rate_hz: float = 0.0
    align_time_s: float = 2.0
    alignment_heading: str = "auto"  # "auto", "psns" or "config"
    psns_align_timeout_s: float = 10.0
    psns_heading_sigma_deg: float = 0.5
    fine_align_time_s: float = 60.0
    initial_heading_deg: float = 0.0
    initial_heading_sigma_deg: float = 1.0
    precision: str = "float32"
    #: Precision of the strapdown's attitude quaternion and velocity accumulators (D-L.1): float64 keeps
    #: the 200 Hz increments (1e-7 rad of Earth rate per step) from being rounded away in float32.
    nav_state_precision: str = "float64"
    filter: str = "base"
    accel_volts_per_g: tuple[float, float, float] = ACCEL_VOLTS_PER_G
    #: measurement ranges of the units this build is fitted with (the emulator sets them from the configured IMU,
    #: emulator/dsp/firmware_setup.py); defaults as the datasheets give them (docs/sensors.md): the STIM210's
    #: +-400 deg/s and the Colibrys MS9030 (x, +-30 g) and the +-25 g parts (y, z). An IMU word
    #: beyond them (1 LSB of rounding allowed) is no measurement of that unit: refused with ``gyro_range`` /
    #: ``accel_range`` even below the 24-bit rail (firmware_model.input_guard, D-5.46)
    gyro_range_dps: float = 400.0
    accel_range_g: tuple[float, float, float] = (30.0, 25.0, 25.0)
    # process noise (sensor specifications)
    gyro_arw_deg_rt_h: float = 0.15
    gyro_bias_sigma_deg_h: float = 40.0 / 3.0
    gyro_bias_instability_deg_h: float = 20.0 / 3.0
    #: gyro scale-factor error (ppm) and misalignment (mrad), 1 sigma: attitude process noise per rotation angle
    #: (filters.base.BaseFilter.predict, "rotation-dependent noise")
    gyro_scale_factor_ppm: float = 0.0
    gyro_misalignment_mrad: float = 0.0
    #: the gyro bias the box's temperature gradient drives (deg/h, 1 sigma, in P0 with the turn-on bias) and the box's
    #: warm-up time constant (s) over which that gradient, and the bias with it, decays after power-on: > 0 adds
    #: the bias's in-run change to the gyro-bias rows of Q (filters.noise_model.warmup_gyro_bias_variance, D-5.27); 0: a
    #: constant gradient, the bias a turn-on constant (P0 only)
    gyro_temp_gradient_deg_h: float = 0.0
    gyro_temp_gradient_time_s: float = 0.0
    #: the gyro bias's flicker between the white equivalent's matching time and the random walk's correlation time as
    #: three augmented Gauss-Markov states (time constant and sigma from the bias instability and its correlation
    #: time, filters.noise_model.gyro_flicker_band, docs/decisions/filter-consistency.md D-5.28)
    gyro_flicker_states: bool = True
    accel_noise_ug_rt_hz: float = 100.0
    accel_bias_sigma_mg: float = 7.0 / 3.0
    accel_bias_instability_mg: float = 4.0 / 3.0
    bias_corr_time_s: float = 600.0
    accel_bias_corr_time_s: float = 600.0
    #: the spec sheet these figures come from (:class:`firmware_model.spec_sheet.SensorSpecSheet.config_fields`)
    spec_sheet: str = "default"
    # GNSS measurement noise (1 sigma per axis)
    gnss_pos_sigma_h_m: float = 4.08
    gnss_pos_sigma_v_m: float = 7.5
    gnss_vel_sigma_h_mps: float = 0.041
    gnss_vel_sigma_v_mps: float = 0.1
    gnss_max_age_s: float = 1.5
    #: GNSS receiver port (DSP UART3) line, for the first-byte time of an epoch (docs/icd.md "GNSS time tags")
    gnss_baud: int = 9600
    gnss_bits_per_byte: int = 10
    #: receiver output latency (s, epoch to the first byte of its output): the time tag without PPS is UTC plus
    #: the measured UTC-to-FPGA offset minus this (docs/icd.md "GNSS time tags")
    gnss_latency_s: float = 0.05
    #: an epoch whose composition is not complete is closed this long (s) after its first byte
    gnss_epoch_hold_s: float = 0.5
    #: a receiver clock step (docs/icd.md 5.1.3, D-5.39): an epoch whose first-byte-minus-time
    #: offset is this far (s) from the time base is refused until ``gnss_clock_rebase_epochs`` consecutive epochs
    #: agree on the new offset (within the same tolerance); the last of them re-bases. Above the write jitter and a
    #: 9600-baud burst's bound (a few hundred ms), below the 1 s of a leap second.
    gnss_clock_step_tol_s: float = 0.75
    gnss_clock_rebase_epochs: int = 5
    #: the firmware's GPS week era (as gpsd's build week): a receiver date before this GPS week, or 1024 weeks after
    #: it, is a week-rollover or RTC date and refused; week 2048 (2019-04-07, the last rollover) starts this one
    gnss_era_start_week: int = 2048
    #: a receiver date and time more than this (s) from the firmware's running UTC clock is refused (a rollover
    #: jumps by 1024 weeks, an RTC date by years); a clock step smaller than this is followed once re-based
    gnss_date_jump_tol_s: float = 86400.0
    #: the time-correlated part of the GNSS position error: white receiver noise per axis (the rest of
    #: ``gnss_pos_sigma_*`` is a first-order Gauss-Markov of ``gnss_pos_corr_time_s``, estimated as three augmented
    #: states when ``gnss_error_states``; docs/decisions/filter-consistency.md)
    gnss_pos_white_sigma_h_m: float = 1.0
    gnss_pos_white_sigma_v_m: float = 1.5
    gnss_pos_corr_time_s: float = 300.0
    #: a gap of position fixes longer than this (s) re-draws the correlated GNSS error states (a loss of lock; the
    #: filter forgets their estimate and correlations, D-5.17); 0 = never
    gnss_relock_gap_s: float = 0.0
    gnss_error_states: bool = True
    #: the receiver's HDOP at which the GNSS figures above hold (docs/decisions/sky-and-sheet-consistency.md D-5.42):
    #: a fix whose GGA / GNS reports a worse geometry has its position and velocity sigmas (white and correlated)
    #: scaled by ``HDOP / gnss_hdop_ref``, never below the sheet's (:func:`firmware_model.filters.gnss.gnss_dop_scale`);
    #: 0 = the reported HDOP is not used
    gnss_hdop_ref: float = 0.0
    #: the code multipath (range, 1 sigma, m) assumed on a fix from 4 satellites or fewer, whose GST cannot show it
    #: (no redundancy): ``HDOP x this / sqrt(2)`` per horizontal axis is added to the fix's figure in quadrature
    #: (:func:`firmware_model.filters.gnss.gnss_fix_scale`, D-5.51); 0 = none
    gnss_unverified_multipath_m: float = 0.0
    #: innovation gate of each GNSS row (normalised innovation squared, 1 dof) (docs/hostile-input.md): chi-square(1)
    #: at alpha = 1e-5 (4.4 sigma), now that the covariance is consistent with the sensors (it was 1e4 = 100 sigma
    #: while the filter treated the correlated GNSS error as white and refused every fix after an outage)
    gnss_gate_chi2: float = 19.51
    #: divergence detection (docs/hostile-input.md): consecutive refused GNSS fixes, or seconds of refused solar
    #: vectors with none accepted, after which the loop re-aligns (gravity + sun/GNSS); 0 turns a criterion off
    fdir_gnss_reject_limit: int = 30
    fdir_psns_reject_s: float = 30.0
    #: the solar criterion re-aligns only a box at rest by its own horizontal speed (m/s; D-5.43): the coarse
    #: alignment levels on the specific force, which in motion (a turn's centripetal acceleration) is not gravity;
    #: in motion a run of refused solar vectors with the GNSS still accepted is a sky the solve does not model, and the
    #: filter goes on without them; 0 = at any speed
    fdir_psns_realign_max_speed_mps: float = 0.5
    # PSNS
    psns_enabled: bool = True
    psns_baud: int = 115200  # DSP UART2 baud (for the exposure time tag, docs/architecture.md "Conventions")
    psns_bits_per_byte: int = 10
    psns_sigma_deg: float = 0.05  # solar-vector noise floor per axis, 1 sigma
    #: solve noise: variance per axis = psns_noise_scale * lambda_min / lambda_mid / n_used (rad^2), at least the floor
    psns_noise_scale: float = 1.0
    #: systematic solar-vector error per body axis (camera mount residual + sky model), 1 sigma, as three augmented
    #: Gauss-Markov states when ``psns_bias_states``
    psns_bias_sigma_deg: float = 0.2
    #: the part of ``psns_bias_sigma_deg`` that is the sky's (the rest is the camera mount's, isotropic in the body):
    #: the sky is symmetric about the solar meridian, so the filter puts its variance of both axes across the sun into
    #: the elevation axis (filters.base.BaseFilter, docs/decisions/filter-consistency.md D-5.16); 0 = isotropic
    psns_sky_bias_deg: float = 0.0
    #: the sky's error along the solar meridian (the solved sun's elevation), 1 sigma, in place of the
    #: ``psns_sky_bias_deg`` of that axis (D-5.33); 0 = ``sqrt(2) psns_sky_bias_deg`` (D-5.16's shape)
    psns_sky_bias_el_deg: float = 0.0
    #: correlation time (s) of the local-level solar-bias states (the sky's error follows the sun, D-5.33); 0 =
    #: ``psns_bias_corr_time_s``, which the body-frame states keep
    psns_sky_corr_time_s: float = 0.0
    #: the heading turn (deg) over which the sky's local-level error across the solar meridian decorrelates (the
    #: camera sees another part of the sky), a Gauss-Markov in the angle turned next to the one in time (D-5.33);
    #: 0 = none
    psns_sky_turn_corr_deg: float = 0.0
    #: the same along the solar meridian (the elevation axis); 0 = ``psns_sky_turn_corr_deg``
    psns_sky_turn_corr_el_deg: float = 0.0
    psns_bias_corr_time_s: float = 600.0
    psns_bias_states: bool = True
    psns_dop_min: float = 0.05
    psns_quality_max: float = 0.2
    psns_min_sun_elevation_deg: float = 5.0
    psns_gate_chi2: float = 16.27  # chi-square(3), alpha = 0.001 (docs/reference/algorithms.md 5.2)
    psns_max_age_s: float = 1.0
    camera: CameraGeometry = field(default_factory=CameraGeometry)
    #: multi-unit compass mountings C_u^b (n, 3, 3) as the firmware knows them (the nominal layout turned by each
    #: unit's calibrated installation angles, :func:`firmware_model.psns_geometry.calibrated_mountings`); None: the
    #: default 9 units, nominal
    compass_mountings: npt.NDArray[np.float64] | None = None
    #: multi-unit compass as the spec sheet states it (1 sigma per unit, deg): AOP noise ``compass_aop_sigma_deg`` at
    #: DOP ``compass_aop_dop_ref`` (growing as 1/DOP), the E-vector angle residual of the calibration and the units'
    #: installation residual per axis (the sun-elevation variant's R0, docs/decisions/filter-consistency.md D-5.19)
    compass_aop_sigma_deg: float = 0.1
    compass_aop_dop_ref: float = 0.5
    compass_aop_residual_deg: float = 0.0
    compass_installation_residual_deg: float = 0.13
    #: magnetometer hard iron h (nT, body axes) and soft iron W (3x3 row-major) from the calibration file; the
    #: consumer (:meth:`Navigation.mag_mean_nt`) returns ``W^-1 (m - h)``
    mag_hard_iron_nt: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mag_soft_iron: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    #: misalignment (E, N, U; deg, C_b^{n'} = (I - [phi x]) C_b^n) added to the coarse alignment: reproduces a
    #: paper's initial condition (e.g. Ge et al.: -0.9, 0.6, 0.7 deg)
    initial_misalignment_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: parameters of the filter variants (:mod:`firmware_model.variants`) and their mode manager
    variants: VariantParams = field(default_factory=VariantParams)

    def __post_init__(self) -> None:
        if self.precision not in ("float32", "float64"):
            raise FirmwareError(f"precision must be float32 or float64, got {self.precision!r}")
        if self.nav_state_precision not in ("float32", "float64"):
            raise FirmwareError(f"nav_state_precision must be float32 or float64, got {self.nav_state_precision!r}")
        if self.gyro_output not in ("rate", "angle"):
            raise FirmwareError(f"gyro_output must be 'rate' or 'angle', got {self.gyro_output!r}")
        if self.filter not in FILTER_VARIANTS:
            raise FirmwareError(f"filter variant {self.filter!r} is not available in this firmware build "
                                f"(available: {', '.join(sorted(FILTER_VARIANTS))})")
        w = np.asarray(self.mag_soft_iron, dtype=np.float64)
        if w.shape != (9,) or not np.all(np.isfinite(w)) or abs(float(np.linalg.det(w.reshape(3, 3)))) < 1e-6:
            raise FirmwareError(f"mag_soft_iron must be 9 finite numbers of an invertible 3x3, "
                                f"got {self.mag_soft_iron}")
        if self.alignment_heading not in ("auto", "psns", "config"):
            raise FirmwareError(f"alignment_heading must be auto, psns or config, got {self.alignment_heading!r}")
        if self.coning_samples not in (0, 1, 2):
            raise FirmwareError(f"coning_samples must be 0 (auto), 1 or 2, got {self.coning_samples}")
        ratio = self.imu_rate_hz / self.output_rate_hz
        if ratio < 1 or abs(ratio - round(ratio)) > 1e-9:
            raise FirmwareError("output_rate_hz must divide imu_rate_hz")
        unknown = set(self.nmea_sentences) - set(NMEA_NAV_SENTENCES)
        if unknown:
            raise FirmwareError(f"unknown NMEA output sentence(s) {', '.join(sorted(unknown))}; "
                                f"known: {', '.join(NMEA_NAV_SENTENCES)}")
        for name in ("nmea_rate_hz", "nmea_attitude_rate_hz"):
            r = self.imu_rate_hz / getattr(self, name)
            if r < 1 or abs(r - round(r)) > 1e-9:
                raise FirmwareError(f"{name} must divide imu_rate_hz ({self.imu_rate_hz:g} Hz)")
        if self.text_rate_hz:
            r = self.imu_rate_hz / self.text_rate_hz
            if self.text_rate_hz < 0 or r < 1 or abs(r - round(r)) > 1e-9:
                raise FirmwareError(f"text_rate_hz must divide imu_rate_hz ({self.imu_rate_hz:g} Hz)")
        if self.nmea_uart not in (UART_HOST, UART_PSNS, UART_GNSS):
            raise FirmwareError(f"nmea_uart must be a UART the firmware transmits on (0, 2 or 3), got {self.nmea_uart}")
        if len(self.nmea_talker) != 2 or not self.nmea_talker.isalpha() or not self.nmea_talker.isupper():
            raise FirmwareError(f"nmea_talker must be two capital letters, got {self.nmea_talker!r}")
        if self.kf_predict_every % self.subsamples:
            raise FirmwareError("kf_predict_every must be a multiple of the coning subsamples")

    @property
    def subsamples(self) -> int:
        """IMU samples per strapdown update (two-sample coning/sculling needs increments)."""
        if self.coning_samples:
            return self.coning_samples
        return 2 if self.gyro_output == "angle" else 1
