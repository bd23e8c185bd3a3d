"""Map a scenario onto the firmware's build/run-time configuration."""

from __future__ import annotations

import math

from firmware_model import Firmware, FirmwareConfig
from firmware_model.attitude import a2mat, yaw_from_heading
from firmware_model.psns_geometry import CameraGeometry
from firmware_model.variants.common import compass_mountings
from firmware_model.variants.params import (
    DualVectorParams,
    FederatedParams,
    KmeansParams,
    ModeManagerParams,
    SunElevationParams,
    VariantParams,
)

from ..devices.sensors import accel_errors, camera_config, gnss_config, gyro_errors
from ..scenario.schema import Scenario

__all__ = ["build_firmware", "firmware_config"]

DEG = math.pi / 180.0


def _camera(scn: Scenario) -> CameraGeometry:
    """The firmware's camera calibration: the nominal design of ``sensors.camera`` unless overridden."""
    cal = scn.firmware.psns.camera
    nominal = CameraGeometry()
    heading = pitch = roll = 0.0
    if scn.sensors.camera is not None:
        cc = camera_config(scn)
        m = scn.sensors.camera.mounting
        nominal = CameraGeometry(nx=cc.nx, ny=cc.ny, dx_m=cc.pixel_m, dy_m=cc.pixel_m, focal_m=cc.focal_m,
                                 projection=cc.lens)
        heading, pitch, roll = m.heading_deg, m.pitch_deg, m.roll_deg  # installation error: unknown to the DSP
    pick = lambda v, default: default if v is None else v  # noqa: E731
    pixel_m = cal.pixel_um * 1e-6 if cal.pixel_um is not None else nominal.dx_m
    return CameraGeometry(
        nx=pick(cal.nx, nominal.nx), ny=pick(cal.ny, nominal.ny), dx_m=pixel_m, dy_m=pixel_m,
        focal_m=cal.focal_mm * 1e-3 if cal.focal_mm is not None else nominal.focal_m,
        projection=pick(cal.projection, nominal.projection),
        c_c_b=a2mat(pick(cal.mounting_pitch_deg, pitch) * DEG, pick(cal.mounting_roll_deg, roll) * DEG,
                    yaw_from_heading(pick(cal.mounting_heading_deg, heading) * DEG)),
    )


def _variant_params(scn: Scenario) -> VariantParams:
    """``firmware.variants`` -> :class:`firmware_model.variants.params.VariantParams` (same field names)."""
    v = scn.firmware.variants
    fed = v.federated.model_dump()
    fed["subfilters"] = tuple(fed["subfilters"])
    if fed["initial_attitude_sigma_deg"] is not None:
        fed["initial_attitude_sigma_deg"] = tuple(fed["initial_attitude_sigma_deg"])
    return VariantParams(
        mode_manager=ModeManagerParams(**v.mode_manager.model_dump()),
        dual_vector=DualVectorParams(**v.dual_vector.model_dump()),
        kmeans_3d=KmeansParams(**v.kmeans_3d.model_dump()),
        federated=FederatedParams(**fed),
        sun_elevation=SunElevationParams(**v.sun_elevation.model_dump()),
    )


def _compass_mountings(scn: Scenario):
    """The compass's nominal unit layout as the firmware knows it (no installation error); None: default 9."""
    c = scn.sensors.compass
    if c is None or c.units is None:
        return None
    return compass_mountings([(u.zenith_deg, u.azimuth_deg) for u in c.units])


def firmware_config(scn: Scenario) -> FirmwareConfig:
    fw = scn.firmware
    gnss = gnss_config(scn).errors
    gyro = gyro_errors(scn)
    acc = accel_errors(scn)
    psns_uart = scn.fpga.routing.get("psns", "uart2")
    psns_enabled = fw.psns.enabled if fw.psns.enabled is not None else scn.links.psns is not None
    return FirmwareConfig(
        clock_hz=scn.dsp.clock_hz,
        imu_rate_hz=scn.sensors.imu.rate_hz,
        gyro_output=scn.sensors.imu.output,
        gyro_counter_step=round(2000 / scn.sensors.imu.rate_hz),
        coning_samples=fw.coning_samples,
        kf_predict_every=fw.kf_predict_every,
        output_rate_hz=fw.output_rate_hz,
        align_time_s=fw.alignment.time_s,
        alignment_heading=fw.alignment.heading_source,
        psns_align_timeout_s=fw.alignment.psns_timeout_s,
        psns_heading_sigma_deg=fw.alignment.psns_heading_sigma_deg,
        fine_align_time_s=fw.alignment.fine_time_s,
        initial_heading_deg=fw.alignment.heading_deg,
        initial_heading_sigma_deg=fw.alignment.heading_sigma_deg,
        precision=fw.precision,
        nav_state_precision=fw.nav_state_precision,
        filter=fw.filter,
        gyro_arw_deg_rt_h=max(gyro.arw_deg_rt_h, 0.01),
        gyro_bias_sigma_deg_h=max(gyro.bias_repeatability_deg_h, 1.0),
        gyro_bias_instability_deg_h=max(gyro.bias_instability_deg_h, 0.1),
        accel_noise_ug_rt_hz=max(acc.noise_ug_rt_hz, 10.0),
        accel_bias_sigma_mg=max(max(acc.bias_repeatability_mg), 0.1),
        accel_bias_instability_mg=max(max(acc.bias_instability_mg), 0.01),
        bias_corr_time_s=gyro.bias_corr_time_s,
        gnss_pos_sigma_h_m=max(gnss.pos_sigma_h_m, 0.5),
        gnss_pos_sigma_v_m=max(gnss.pos_sigma_v_m, 0.5),
        gnss_vel_sigma_h_mps=max(gnss.vel_sigma_h_mps, 0.01),
        gnss_vel_sigma_v_mps=max(gnss.vel_sigma_v_mps, 0.01),
        psns_enabled=psns_enabled,
        # an EMIFA UART core has no line baud of its own: the firmware's default line then dates the frames
        psns_baud=scn.fpga.uarts[psns_uart].baud or FirmwareConfig.psns_baud,
        psns_sigma_deg=fw.psns.sigma_deg,
        psns_dop_min=fw.psns.dop_min,
        psns_quality_max=fw.psns.quality_max,
        psns_min_sun_elevation_deg=fw.psns.min_sun_elevation_deg,
        psns_gate_chi2=fw.psns.gate_chi2,
        camera=_camera(scn),
        compass_mountings=_compass_mountings(scn),
        initial_misalignment_deg=(fw.alignment.misalignment_deg[0], fw.alignment.misalignment_deg[1],
                                  fw.alignment.misalignment_deg[2]),
        variants=_variant_params(scn),
    )


def build_firmware(scn: Scenario) -> Firmware:
    """The firmware the virtual DSP hosts for this scenario."""
    return Firmware(firmware_config(scn))
