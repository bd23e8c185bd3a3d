"""Map a scenario onto the firmware's build/run-time configuration."""

from __future__ import annotations

from firmware_model import Firmware, FirmwareConfig

from .devices.sensors import accel_errors, gnss_config, gyro_errors
from .scenario.schema import Scenario

__all__ = ["firmware_config", "build_firmware"]


def firmware_config(scn: Scenario) -> FirmwareConfig:
    fw = scn.firmware
    gnss = gnss_config(scn).errors
    gyro = gyro_errors(scn)
    acc = accel_errors(scn)
    return FirmwareConfig(
        clock_hz=scn.dsp.clock_hz,
        imu_rate_hz=scn.sensors.imu.rate_hz,
        gyro_output=scn.sensors.imu.output,
        gyro_counter_step=int(round(2000 / scn.sensors.imu.rate_hz)),
        kf_predict_every=fw.kf_predict_every,
        output_rate_hz=fw.output_rate_hz,
        align_time_s=fw.alignment.time_s,
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
    )


def build_firmware(scn: Scenario) -> Firmware:
    """The firmware the virtual DSP hosts for this scenario."""
    return Firmware(firmware_config(scn))
