"""The firmware's own sensor spec sheet: what the navigation computer's team knows about its sensors.

A real team configures its filter from the datasheets of the parts it bought and from its own bench and sky
tests, never from the error draws of the world its box will meet. :class:`SensorSpecSheet` is that knowledge,
typed; the emulator reads it from a YAML file (``firmware_model/spec_sheets/*.yaml`` or the user's file, chosen by
the scenario's ``firmware.spec_sheet``; :mod:`emulator.dsp.firmware_setup`) and hands it over as a dict: this
package does no file I/O. :meth:`SensorSpecSheet.config_fields` derives the filter's working figures
(:class:`firmware_model.config.FirmwareConfig` fields) from it, in one place:

* gyro / accelerometer noise: ARW and VRW as the white process noise of the attitude and velocity rows;
* in-run bias: a first-order Gauss-Markov of sigma ``bias_instability`` and correlation time ``bias_corr_time_s``
  (the Allan floor read as the flicker's stationary level), modelled in the filter as a random walk of the same
  short-term growth (``q = 2 sigma^2 / tau``); its stationary part enters ``P0`` with the turn-on repeatability and
  the environmental terms the datasheet gives (g-sensitivity at 1 g, temperature-gradient bias, scale factor at
  1 g for the accelerometers), all added in quadrature; the temperature-gradient bias changes in-run as the box
  warms up (``temp_gradient_time_s``, its warm-up time constant): that change as gyro-bias process noise (D-5.27,
  :func:`firmware_model.filters.noise_model.warmup_gyro_bias_variance`); the flicker's short-term motion (Allan
  floor 0.664 B at every averaging time) as a white-noise equivalent on the attitude and velocity rows, matched at the
  velocity-aiding time constant (docs/decisions/filter-consistency.md D-5.15);
* GNSS: the receiver's 95 % figures (horizontal 2DRMS -> sigma per axis = X / 2.448, vertical X / 2) split into a
  white part (``white_sigma_h_m`` / ``_v_m``: receiver noise and fast multipath) and a time-correlated remainder
  (atmosphere, orbit) of correlation time ``corr_time_s``, estimated as three augmented Gauss-Markov states
  (docs/decisions/filter-consistency.md); a gap of fixes longer than ``relock_gap_s`` is a loss of lock after which
  they restart as a fresh draw (D-5.17); a fix whose receiver reports an HDOP above ``hdop_ref`` has all of these
  sigmas scaled by ``HDOP / hdop_ref`` (D-5.42, :func:`firmware_model.filters.gnss.gnss_dop_scale`);
* PSNS: the solve's own noise from its eigenvalues (``noise_scale * lambda_min / lambda_mid / n_used``, see
  :func:`firmware_model.filters.solar.solar_noise_variance`), a floor, and the systematic solar-vector error (camera
  mount residual and lens-model residual of the calibration plus the sky's departure from the Rayleigh pattern, in
  quadrature) as three augmented states in
  the local-level frame, the sky's part once more on the axis across the solar meridian (D-5.16);
* multi-unit compass: each unit's AOP noise (``aop_sigma_deg`` at ``aop_dop_ref``, growing as 1/DOP) and the
  calibration's residual budget (E-vector angle residual per unit, installation residual per unit axis), from which
  the sun-elevation variant's Sage-Husa filter takes its nominal R (D-5.19,
  :func:`firmware_model.variants.sun_elevation.elevation_noise_variance`).

Every figure is 1 sigma per axis unless its name says 95 %. A sheet's ``sources`` mapping (``"section.key"`` -> the
published source of that figure, starting with its kind: ``datasheet:``, ``paper:``, ``standard:``, ``textbook:``
or ``assumed:``) says where each figure comes from; the bundled sheets carry one for every figure and none cites the
emulator's own output (issue 36; tests/firmware_model/test_spec_sheet_sources.py, docs/spec-sheet.md).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from .errors import FirmwareError

__all__ = ["AccelSpec", "CompassSpec", "GnssSpec", "GyroSpec", "PsnsSpec", "SensorSpecSheet", "SpecSheetError"]


class SpecSheetError(FirmwareError):
    """A spec sheet that is not well formed (the message names the field)."""


@dataclass(frozen=True)
class GyroSpec:
    """Rate gyro (per axis): ARW deg/sqrt(h); biases deg/h; correlation time s; g-sensitivity deg/h/g."""

    arw_deg_rt_h: float = 0.15
    bias_repeatability_deg_h: float = 13.333
    bias_instability_deg_h: float = 6.667
    bias_corr_time_s: float = 600.0
    g_sensitivity_deg_h_per_g: float = 0.0
    bias_temp_gradient_deg_h: float = 0.0
    #: the box's warm-up time constant (s): after power-on the temperature gradient, and the bias it drives, decays
    #: as ``exp(-t / tau)``; 0 = a constant gradient (the bias a turn-on constant, P0 only). D-5.27
    temp_gradient_time_s: float = 0.0
    #: scale-factor error (ppm) and axis misalignment (mrad), 1 sigma: attitude error that grows with the rotation
    scale_factor_ppm: float = 0.0
    misalignment_mrad: float = 0.0


@dataclass(frozen=True)
class AccelSpec:
    """Accelerometer (worst axis): VRW ug/sqrt(Hz); biases mg; correlation time s; scale-factor ppm."""

    vrw_ug_rt_hz: float = 100.0
    bias_repeatability_mg: float = 2.333
    bias_instability_mg: float = 1.333
    bias_corr_time_s: float = 600.0
    scale_factor_ppm: float = 0.0


@dataclass(frozen=True)
class GnssSpec:
    """GNSS receiver: 95 % accuracies (m, m/s), white receiver noise (m, per axis), error correlation time (s)."""

    horizontal_95_m: float = 10.0
    vertical_95_m: float = 15.0
    velocity_h_95_mps: float = 0.1
    velocity_v_95_mps: float = 0.2
    white_sigma_h_m: float = 1.0
    white_sigma_v_m: float = 1.5
    corr_time_s: float = 300.0
    #: time from a fix's UTC epoch to the first byte of its first message (s): dates fixes without PPS
    output_latency_s: float = 0.1
    #: a gap of position fixes longer than this (s) is a loss of lock: the receiver's solution after re-acquisition
    #: (another satellite set, a restarted code smoother) carries a fresh draw of the correlated error (0 = never)
    relock_gap_s: float = 5.0
    #: the HDOP at which the figures above hold: a fix reporting a larger HDOP has its sigmas scaled by
    #: ``HDOP / hdop_ref`` (sigma = DOP x UERE, the sheet's figures a floor; D-5.42); 0 = not used
    hdop_ref: float = 0.0
    #: the code multipath (range, 1 sigma, m) a fix from 4 satellites or fewer is assumed to carry: without a fifth
    #: satellite the receiver's residuals (and its GST) cannot show it (D-5.51); 0 = not assumed
    unverified_multipath_m: float = 0.0


@dataclass(frozen=True)
class PsnsSpec:
    """Polarization sensor: solve-noise scale (1), noise floor and systematic solar-vector error (deg per axis): the
    camera-to-body mount residual, the lens model's residual on the solved sun (focal length, principal point,
    distortion, polarizer angles as calibrated; 0: not stated) and the sky's departure from the Rayleigh pattern:
    ``sky_bias_deg`` on every local-level axis, ``sky_bias_elevation_deg`` its total along the solar meridian (the
    solved sun's elevation error; 0: not stated, then ``sqrt(2) sky_bias_deg``, the sky's variance of both axes
    across the sun put on the elevation axis, docs/decisions/filter-consistency.md D-5.16, D-5.33), correlation time
    ``bias_corr_time_s`` (of body-frame states; of the local-level ones too unless ``sky_corr_time_s`` is stated, a
    sky test's figure in that frame, D-5.33) and ``sky_turn_corr_deg`` / ``sky_turn_corr_elevation_deg`` the heading
    turn over which the local-level states decorrelate across / along the meridian (0: none / the same)."""

    noise_scale: float = 1.0
    noise_floor_deg: float = 0.05
    mount_residual_deg: float = 0.05
    lens_residual_deg: float = 0.0
    sky_bias_deg: float = 0.2
    sky_bias_elevation_deg: float = 0.0
    bias_corr_time_s: float = 600.0
    sky_corr_time_s: float = 0.0
    sky_turn_corr_deg: float = 0.0
    sky_turn_corr_elevation_deg: float = 0.0


@dataclass(frozen=True)
class CompassSpec:
    """Multi-unit polarization compass (per unit, 1 sigma, deg): AOP noise at a DOP (grows as 1/DOP), the E-vector
    angle residual left by the calibration (a constant per unit, e.g. Zhang et al.'s Table 2), and the installation
    residual per unit axis (the calibration report of the unit mountings, docs/calibration.md)."""

    aop_sigma_deg: float = 0.1
    aop_dop_ref: float = 0.5
    aop_residual_deg: float = 0.0
    installation_residual_deg: float = 0.13


@dataclass(frozen=True)
class SensorSpecSheet:
    """The sensors as the team's spec sheet states them (see module docstring)."""

    name: str = "default"
    gyro: GyroSpec = field(default_factory=GyroSpec)
    accel: AccelSpec = field(default_factory=AccelSpec)
    gnss: GnssSpec = field(default_factory=GnssSpec)
    psns: PsnsSpec = field(default_factory=PsnsSpec)
    compass: CompassSpec = field(default_factory=CompassSpec)
    #: ``"section.key"`` -> where that figure comes from (module docstring); empty for a sheet that gives none
    sources: dict[str, str] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, data: Any, source: str = "<spec sheet>") -> SensorSpecSheet:
        """Parse a spec sheet mapping; unknown or non-numeric fields and negative figures raise
        :class:`SpecSheetError` naming ``source`` and the field."""
        if not isinstance(data, dict):
            raise SpecSheetError(f"{source}: a spec sheet is a mapping of sections")
        sections = {"gyro": GyroSpec, "accel": AccelSpec, "gnss": GnssSpec, "psns": PsnsSpec,
                    "compass": CompassSpec}
        extra = set(data) - set(sections) - {"name", "description", "sources"}
        if extra:
            raise SpecSheetError(f"{source}: unknown sections {sorted(extra)}")
        parts: dict[str, Any] = {}
        for key, typ in sections.items():
            sec = data.get(key, {})
            if not isinstance(sec, dict):
                raise SpecSheetError(f"{source}: {key}: a mapping of figures")
            known = {f.name for f in fields(typ)}
            bad = set(sec) - known
            if bad:
                raise SpecSheetError(f"{source}: {key}: unknown fields {sorted(bad)} (known: {sorted(known)})")
            vals: dict[str, float] = {}
            for k, v in sec.items():
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                    raise SpecSheetError(f"{source}: {key}.{k}: a finite figure >= 0, got {v!r}")
                vals[k] = float(v)
            parts[key] = typ(**vals)
        for key, tau in (("gyro", parts["gyro"].bias_corr_time_s), ("accel", parts["accel"].bias_corr_time_s),
                         ("gnss", parts["gnss"].corr_time_s), ("psns", parts["psns"].bias_corr_time_s)):
            if tau <= 0:
                raise SpecSheetError(f"{source}: {key}: the correlation time must be > 0 s")
        if parts["compass"].aop_dop_ref <= 0:
            raise SpecSheetError(f"{source}: compass.aop_dop_ref: the DOP of the AOP figure must be > 0")
        sources = data.get("sources", {}) or {}
        if not isinstance(sources, dict):
            raise SpecSheetError(f"{source}: sources: a mapping of 'section.key' to the figure's source")
        known_keys = {f"{sec}.{f.name}" for sec, typ in sections.items() for f in fields(typ)}
        for k, v in sources.items():
            if k not in known_keys:
                raise SpecSheetError(f"{source}: sources: {k!r} is not a figure of the sheet")
            if not isinstance(v, str) or not v.strip():
                raise SpecSheetError(f"{source}: sources.{k}: a non-empty text")
        return cls(name=str(data.get("name", "unnamed")), **parts, sources={str(k): str(v) for k, v in sources.items()})

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def config_fields(self) -> dict[str, Any]:
        """The :class:`~firmware_model.config.FirmwareConfig` figures this sheet implies (module docstring)."""
        g, a, n, p, c = self.gyro, self.accel, self.gnss, self.psns, self.compass
        sh = n.horizontal_95_m / 2.448  # 2DRMS 95 % of a circular Gaussian -> sigma per axis
        sv = n.vertical_95_m / 2.0
        gyro_p0 = math.sqrt(g.bias_repeatability_deg_h**2 + g.bias_instability_deg_h**2
                            + g.g_sensitivity_deg_h_per_g**2 + g.bias_temp_gradient_deg_h**2)
        acc_p0 = math.sqrt(a.bias_repeatability_mg**2 + a.bias_instability_mg**2 + (a.scale_factor_ppm * 1e-3) ** 2)
        return {
            "spec_sheet": self.name,
            "gyro_arw_deg_rt_h": max(g.arw_deg_rt_h, 0.01),
            "gyro_bias_sigma_deg_h": max(gyro_p0, 0.1),
            "gyro_bias_instability_deg_h": max(g.bias_instability_deg_h, 0.05),
            "bias_corr_time_s": g.bias_corr_time_s,
            "accel_noise_ug_rt_hz": max(a.vrw_ug_rt_hz, 10.0),
            "accel_bias_sigma_mg": max(acc_p0, 0.05),
            "accel_bias_instability_mg": max(a.bias_instability_mg, 0.01),
            "accel_bias_corr_time_s": a.bias_corr_time_s,
            "gnss_pos_sigma_h_m": max(sh, 0.5),
            "gnss_pos_sigma_v_m": max(sv, 0.5),
            "gnss_pos_white_sigma_h_m": max(min(n.white_sigma_h_m, sh), 0.1),
            "gnss_pos_white_sigma_v_m": max(min(n.white_sigma_v_m, sv), 0.1),
            "gnss_pos_corr_time_s": n.corr_time_s,
            "gnss_vel_sigma_h_mps": max(n.velocity_h_95_mps / 2.448, 0.01),
            "gnss_vel_sigma_v_mps": max(n.velocity_v_95_mps / 2.0, 0.01),
            "gnss_latency_s": n.output_latency_s,
            "gnss_relock_gap_s": n.relock_gap_s,
            "gnss_hdop_ref": max(n.hdop_ref, 0.0),
            "gnss_unverified_multipath_m": max(n.unverified_multipath_m, 0.0),
            "psns_noise_scale": p.noise_scale,
            "psns_sigma_deg": max(p.noise_floor_deg, 0.001),
            "psns_bias_sigma_deg": math.hypot(p.mount_residual_deg, p.lens_residual_deg, p.sky_bias_deg),
            "psns_sky_bias_deg": p.sky_bias_deg,
            "psns_sky_bias_el_deg": p.sky_bias_elevation_deg,
            "psns_sky_corr_time_s": p.sky_corr_time_s,
            "psns_sky_turn_corr_deg": p.sky_turn_corr_deg,
            "psns_sky_turn_corr_el_deg": p.sky_turn_corr_elevation_deg,
            "psns_bias_corr_time_s": p.bias_corr_time_s,
            "gyro_scale_factor_ppm": g.scale_factor_ppm,
            "gyro_misalignment_mrad": g.misalignment_mrad,
            "gyro_temp_gradient_deg_h": g.bias_temp_gradient_deg_h,
            "gyro_temp_gradient_time_s": g.temp_gradient_time_s,
            "compass_aop_sigma_deg": max(c.aop_sigma_deg, 0.001),
            "compass_aop_dop_ref": c.aop_dop_ref,
            "compass_aop_residual_deg": c.aop_residual_deg,
            "compass_installation_residual_deg": c.installation_residual_deg,
        }
