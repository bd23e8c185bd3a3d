"""Map a scenario onto the firmware's build/run-time configuration."""

from __future__ import annotations

import math

from firmware_model import Firmware, FirmwareConfig
from firmware_model.attitude import a2mat
from firmware_model.psns_geometry import CameraGeometry

from .devices.sensors import accel_errors, gnss_config, gyro_errors
from .scenario.schema import Scenario

__all__ = ["firmware_config", "build_firmware"]

DEG = math.pi / 180.0


def _camera(scn: Scenario) -> CameraGeometry:
    c = scn.firmware.psns.camera
    return CameraGeometry(
        nx=c.nx, ny=c.ny, dx_m=c.pixel_um * 1e-6, dy_m=c.pixel_um * 1e-6, focal_m=c.focal_mm * 1e-3,
        projection=c.projection,
        c_c_b=a2mat(c.mounting_pitch_deg * DEG, c.mounting_roll_deg * DEG, c.mounting_yaw_deg * DEG),
    )


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
        gyro_counter_step=int(round(2000 / scn.sensors.imu.rate_hz)),
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
        psns_baud=scn.fpga.uarts[psns_uart].baud,
        psns_sigma_deg=fw.psns.sigma_deg,
        psns_dop_min=fw.psns.dop_min,
        psns_quality_max=fw.psns.quality_max,
        psns_min_sun_elevation_deg=fw.psns.min_sun_elevation_deg,
        psns_gate_chi2=fw.psns.gate_chi2,
        camera=_camera(scn),
    )


def build_firmware(scn: Scenario) -> Firmware:
    """The firmware the virtual DSP hosts for this scenario."""
    return Firmware(firmware_config(scn))
