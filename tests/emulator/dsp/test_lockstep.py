"""The lockstep firmware interface (docs/icd.md section 10): the example C firmware (examples/c_firmware, psns_nav)
in the virtual DSP's place in virtual time, in-process (shared library) and out-of-process (a child on a pipe).

**The closed-form bound of a static run.** psns_nav is a free-inertial strapdown started at the true attitude,
position and velocity, with the Earth rate and normal gravity compensated and no aiding. Its errors on a static box
obey the first-order error equations in the navigation frame (Titterton & Weston, 2nd ed., eqs. 12.6-12.8; psi-angle
form): ``phi' = -w_ie^n x phi - C_b^n b_g``, ``dv' = f^n x phi + C_b^n b_a - 2 w_ie^n x dv``, ``dp' = dv``, with
``b_g`` / ``b_a`` the gyro / accelerometer errors (here the turn-on biases the world drew, every other error set to
zero, plus half an LSB of quantisation per axis: 2^-15 deg/s for the gyro word, 0.5 x 4.096 V / 2^23 / (V/g) g for
the ADC code), ``|f^n| = g`` and ``|w_ie^n| = W`` (WGS-84 Earth rate). Taking norms, with ``beta_g = |b_g|`` and
``beta_a = |b_a|`` (the quantisation included) and Gronwall's inequality for the Earth-rate coupling:

    |phi(t)| <= beta_g (e^{W t} - 1) / W  ~=  beta_g t (1 + W t / 2)
    |dv(t)|  <= (beta_a t + g beta_g t^2 / 2) e^{2 W t}
    |dp(t)|  <= (beta_a t^2 / 2 + g beta_g t^3 / 6) e^{2 W t}

(the vertical channel's instability, ``dh'' = 2 g / R dh``, adds a factor ``cosh(sqrt(2 g / R) t)``, below 1.001 over
20 s, covered by the 1 % margin). The bound is computed from the drawn biases (the world's), never from the C
program's output; and since the biases are large, the errors must also reach a good part of the bound (a firmware
that integrated nothing, or only the gyro, would fail one side or the other).
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from emulator.assembly.session import Emulator, run_emulator
from emulator.cli.main import main as cli_main
from emulator.dsp.lockstep import ALLOW_FIRMWARE_ENV
from emulator.scenario import load_scenario
from emulator.scenario.loader import ScenarioError

ROOT = Path(__file__).resolve().parents[3]
OMEGA_IE = 7.2921151467e-5  # WGS-84 Earth rotation rate, rad/s
G = 9.80
ORIGIN = {"lat_deg": 39.979, "lon_deg": 116.339, "height_m": 50.0}
ATTITUDE = {"heading_deg": 30.0, "pitch_deg": 2.0, "roll_deg": -1.5}
#: every gyro error but the turn-on bias set to zero
GYRO_BIAS_ONLY = {"arw_deg_rt_h": 0.0, "bias_repeatability_deg_h": 300.0, "bias_instability_deg_h": 0.0,
                  "rate_random_walk_deg_h_rt_h": 0.0, "scale_factor_ppm": 0.0, "scale_asymmetry_ppm": 0.0,
                  "misalignment_mrad": 0.0, "nonlinearity_ppm_fs": 0.0, "bias_temp_coeff_deg_h_per_c": 0.0,
                  "bias_temp_gradient_deg_h": 0.0, "g_sensitivity_deg_h_per_g": 0.0}
#: every accelerometer error but the turn-on bias set to zero
ACCEL_BIAS_ONLY = {"bias_repeatability_mg": [1.0, 1.0, 1.0], "bias_instability_mg": [0.0, 0.0, 0.0],
                   "noise_ug_rt_hz": 0.0, "bias_random_walk_mg_rt_h": 0.0, "scale_factor_ppm": [0.0, 0.0, 0.0],
                   "scale_error_ppm": [0.0, 0.0, 0.0], "misalignment_mrad": 0.0, "bias_temp_coeff_mg_per_c": 0.0}
GYRO_Q_RAD_S = math.radians(2.0**-15)  # half the 2^-14 deg/s word
ACCEL_Q_MPS2 = 0.5 * 4.096 / 2**23 / 0.09 * 9.80665  # half an ADC code on the least sensitive axis (x)


@pytest.fixture(scope="module")
def c_firmware(tmp_path_factory) -> Path:
    """The example firmware's three builds (``make -C examples/c_firmware``) in a temporary directory."""
    if shutil.which(os.environ.get("CC", "gcc")) is None:
        pytest.skip("no C compiler (gcc) on this machine: the example C firmware cannot be built")
    build = tmp_path_factory.mktemp("c_firmware")
    subprocess.run(["make", "-s", "-C", str(ROOT / "examples" / "c_firmware"), f"BUILD={build}"], check=True,
                   timeout=120)
    return build


@pytest.fixture
def allow_firmware(monkeypatch):
    monkeypatch.setenv(ALLOW_FIRMWARE_ENV, "1")


def write_scenario(d: Path, lockstep: dict, duration_s: float = 20.0, seed: int = 7, **extra) -> Path:
    data: dict = {
        "name": "lockstep", "seed": seed, "epoch": "2019-09-18T02:30:00Z", "duration_s": duration_s, "mode": "fast",
        "origin": ORIGIN, "attitude": ATTITUDE, "motion": [{"static": {"duration_s": duration_s}}],
        "sensors": {"imu": {"gyro": GYRO_BIAS_ONLY, "accel": ACCEL_BIAS_ONLY}},
        "dsp": {"external": {"lockstep": lockstep}},
        **extra,
    }
    path = d / "lockstep.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def in_dir(c_firmware: Path, d: Path, name: str) -> str:
    """Copy a build of the example into the scenario's directory (the paths a scenario names stay inside it)."""
    shutil.copy2(c_firmware / name, d / name)
    return name


def run(path: Path, run_dir: Path) -> tuple[Emulator, dict]:
    emu = Emulator(load_scenario(path), run_dir)
    return emu, run_emulator(emu)


def nav_rows(run_dir: Path) -> list[dict[str, str]]:
    return list(csv.DictReader((run_dir / "nav.csv").read_text().splitlines()))


def test_a_static_run_stays_inside_the_closed_form_bound(c_firmware, tmp_path, allow_firmware):
    lib = in_dir(c_firmware, tmp_path, "libpsns_nav.so")
    emu, summary = run(write_scenario(tmp_path, {"library": lib}), tmp_path / "run")
    assert summary["lockstep"]["failed"] is False and summary["lockstep"]["transport"] == "in-process"
    rows = nav_rows(tmp_path / "run")
    assert len(rows) == summary["nav_frames"] >= 200 * 20 - 2  # one NAV_SOLUTION per IMU frame
    assert emu.sensors is not None
    beta_g = float(np.linalg.norm(emu.sensors.gyro.turn_on_bias)) + math.sqrt(3) * GYRO_Q_RAD_S
    beta_a = float(np.linalg.norm(emu.sensors.accel.turn_on_bias)) + math.sqrt(3) * ACCEL_Q_MPS2
    assert beta_g > math.radians(50 / 3600) and beta_a > 5e-4  # large biases: the errors are theirs
    t0 = float(rows[0]["time_s"])
    worst_ratio = {"att": 0.0, "vel": 0.0, "pos": 0.0}
    for r in rows[1:]:
        t = float(r["time_s"]) - t0
        grow = math.exp(2 * OMEGA_IE * t) * 1.01
        att_bound = beta_g * (math.exp(OMEGA_IE * t) - 1) / OMEGA_IE * 1.01 + math.radians(2e-5)  # + f32 angles
        vel_bound = (beta_a * t + G * beta_g * t * t / 2) * grow + 1e-6
        pos_bound = (beta_a * t * t / 2 + G * beta_g * t**3 / 6) * grow + 0.01  # + f32 height (50 m: 4e-6 m)
        att = math.radians(float(r["err_att_deg"]))
        vel = math.sqrt(sum(float(r[f"err_vel_{a}_mps"]) ** 2 for a in "enu"))
        pos = float(r["err_pos_m"])
        assert att <= att_bound, (t, att, att_bound)
        assert vel <= vel_bound, (t, vel, vel_bound)
        assert pos <= pos_bound, (t, pos, pos_bound)
        if t > 10:
            worst_ratio = {k: max(worst_ratio[k], v) for k, v in
                           (("att", att / att_bound), ("vel", vel / vel_bound), ("pos", pos / pos_bound))}
    print(f"beta_g {math.degrees(beta_g) * 3600:.1f} deg/h, beta_a {beta_a * 1e3 / 9.80665:.3f} mg; "
          f"largest share of the bound after 10 s: {worst_ratio}")
    # the errors are the biases': each reaches a good part of its bound (an integration that ignored the gyro or
    # the accelerometers, or got a sign wrong, would not)
    assert all(v > 0.25 for v in worst_ratio.values()), worst_ratio


def test_lockstep_runs_are_deterministic_and_both_transports_agree(c_firmware, tmp_path, allow_firmware):
    lib = in_dir(c_firmware, tmp_path, "libpsns_nav.so")
    prog = in_dir(c_firmware, tmp_path, "psns_nav_lockstep")
    a = tmp_path / "a"
    a.mkdir()
    b = tmp_path / "b"  # the second run of the same scenario file (the capture's header names the scenario's directory)
    b.mkdir()
    shutil.copy2(tmp_path / lib, a / lib)
    scn_a = write_scenario(a, {"library": lib}, duration_s=5.0)
    scn_b = scn_a
    proc_dir = tmp_path / "p"
    proc_dir.mkdir()
    shutil.copy2(tmp_path / prog, proc_dir / prog)
    scn_p = write_scenario(proc_dir, {"command": [prog]}, duration_s=5.0)
    _, sa = run(scn_a, a / "run")
    run(scn_b, b / "run")
    _, sp = run(scn_p, proc_dir / "run")
    assert sa["nav_frames"] == 1000
    for name in ("nav.csv", "capture.psnscap"):
        assert (a / "run" / name).read_bytes() == (b / "run" / name).read_bytes(), name
    # the other transport: the same frames at the same instants (its capture's header names the other scenario)
    assert (a / "run" / "nav.csv").read_bytes() == (proc_dir / "run" / "nav.csv").read_bytes()
    assert sp["lockstep"]["transport"] == "out-of-process" and sp["lockstep"]["exit"] == 0
    # the reported cycles went through the DSP timing model and the cycle table
    task = {t["task"]: t for t in sa["dsp"]["tasks"]}["lockstep_step"]
    assert task["calls"] == sa["lockstep"]["steps"] == sa["dsp"]["ticks"] == 1000
    assert 4000 < task["cycles_avg"] < 10000 and sa["dsp"]["deadline_misses"] == 0


def test_reported_cycles_become_late_output_and_deadline_misses(c_firmware, tmp_path, allow_firmware):
    """At a DSP clock of 1 MHz the example's ~7800 cycles per step take 7.8 ms, longer than the 5 ms IMU period:
    every tick is late, exactly as the built-in firmware's would be (emulator/dsp/host.py), and the NAV_SOLUTIONs
    leave UART0 that much later."""
    lib = in_dir(c_firmware, tmp_path, "libpsns_nav.so")
    fast = tmp_path / "fast"
    slow = tmp_path / "slow"
    for d in (fast, slow):
        d.mkdir()
        shutil.copy2(tmp_path / lib, d / lib)
    _, s_fast = run(write_scenario(fast, {"library": lib}, duration_s=2.0), fast / "run")
    _, s_slow = run(write_scenario(slow, {"library": lib}, duration_s=2.0, **{"dsp": {
        "clock_hz": 1e6, "external": {"lockstep": {"library": lib}}}}), slow / "run")
    assert s_fast["dsp"]["deadline_misses"] == 0
    assert s_slow["dsp"]["deadline_misses"] > 100 and s_slow["lockstep"]["deadline_misses"] > 100
    r_fast, r_slow = nav_rows(fast / "run"), nav_rows(slow / "run")
    lat_fast = float(r_fast[5]["arrival_s"]) - float(r_fast[5]["time_s"])
    lat_slow = float(r_slow[5]["arrival_s"]) - float(r_slow[5]["time_s"])
    cycles = {t["task"]: t for t in s_slow["dsp"]["tasks"]}["lockstep_step"]["cycles_max"]
    assert lat_slow - lat_fast > 0.9 * cycles / 1e6 - cycles / 300e6


def test_a_lockstep_scenario_never_loads_code_without_allow_firmware(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv(ALLOW_FIRMWARE_ENV, raising=False)
    (tmp_path / "libbogus.so").write_bytes(b"not a library: loading it would fail loudly")
    path = write_scenario(tmp_path, {"library": "libbogus.so"}, duration_s=1.0)
    assert cli_main(["validate", str(path)]) == 0  # validating never loads it
    rc = cli_main(["run", str(path), "--out", str(tmp_path / "run"), "--quiet", "--no-report"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "--allow-firmware" in err and "libbogus.so" in err
    assert not (tmp_path / "run" / "summary.json").exists()


@pytest.mark.parametrize("case", ["outside", "both", "neither", "absolute"])
def test_lockstep_paths_are_validated(tmp_path, case):
    lock = {"outside": {"library": "../elsewhere/libx.so"}, "both": {"library": "a.so", "command": ["b"]},
            "neither": {}, "absolute": {"command": ["/bin/sh", "-c", "true"]}}[case]
    want = {"outside": "outside the scenario's directory", "both": "exactly one of library",
            "neither": "exactly one of library", "absolute": "outside the scenario's directory"}[case]
    with pytest.raises(ScenarioError, match=want):
        load_scenario(write_scenario(tmp_path, lock, duration_s=1.0))


@pytest.mark.realtime
def test_lockstep_in_realtime_mode_is_paced_by_the_wall_clock(c_firmware, tmp_path, allow_firmware):
    """The same interface in realtime mode: the emulator's loop follows the wall clock, the firmware is stepped
    at each IMU frame's instant (the output is the fast mode's, frame for frame)."""
    import time

    lib = in_dir(c_firmware, tmp_path, "libpsns_nav.so")
    path = write_scenario(tmp_path, {"library": lib}, duration_s=2.0)
    emu = Emulator(load_scenario(path), tmp_path / "rt", mode="realtime")
    t0 = time.monotonic()
    s_rt = run_emulator(emu)
    wall = time.monotonic() - t0
    assert wall >= 1.9 and s_rt["nav_frames"] == 400 and s_rt["lockstep"]["failed"] is False
    run(path, tmp_path / "fast")
    cols = slice(0, 24)  # the NAV_SOLUTION fields (time_s .. deadline_misses), not the arrival times
    fast_rows = [r.split(",")[cols] for r in (tmp_path / "fast" / "nav.csv").read_text().splitlines()]
    rt_rows = [r.split(",")[cols] for r in (tmp_path / "rt" / "nav.csv").read_text().splitlines()]
    assert rt_rows == fast_rows


def test_the_header_and_the_emulator_agree_on_the_config_layout(tmp_path):
    """psns_fw_config as the C compiler lays it out (offsetof, sizeof) is the emulator's CONFIG_STRUCT, field for
    field (docs/icd.md section 10.2), and the header's own version is the emulator's."""
    from emulator.dsp.lockstep import ABI_VERSION, CONFIG_STRUCT, LockstepConfig

    cc = os.environ.get("CC", "gcc")
    if shutil.which(cc) is None:
        pytest.skip("no C compiler (gcc) on this machine")
    names = ["abi_version", "clock_hz", "imu_rate_hz", "flags", "lat_deg", "lon_deg", "height_m", "heading_deg",
             "pitch_deg", "roll_deg"]
    src = tmp_path / "layout.c"
    src.write_text('#include <stddef.h>\n#include <stdio.h>\n#include "psns_fw.h"\nint main(void) {\n'
                   '  printf("%u %zu", PSNS_FW_ABI_VERSION, sizeof(psns_fw_config));\n'
                   + "".join(f'  printf(" %zu", offsetof(psns_fw_config, {n}));\n' for n in names)
                   + "  return 0;\n}\n")
    exe = tmp_path / "layout"
    subprocess.run([cc, "-std=c99", "-Wall", "-Werror", "-I", str(ROOT / "firmware_abi"), "-o", str(exe), str(src)],
                   check=True, timeout=60)
    version, size, *offsets = (int(x) for x in subprocess.run([str(exe)], capture_output=True, check=True,
                                                               timeout=10).stdout.split())
    assert version == ABI_VERSION and size == CONFIG_STRUCT.size == 64
    assert offsets == [0, 4, 8, 12, 16, 24, 32, 40, 48, 56]
    packed = LockstepConfig(300e6, 200, 39.9, 116.3, 50.0, 30.0, 2.0, -1.5, flags=1).pack()
    assert packed[4:8] == (300_000_000).to_bytes(4, "little") and packed[12:16] == (1).to_bytes(4, "little")
    assert LockstepConfig.unpack(packed).pack() == packed
