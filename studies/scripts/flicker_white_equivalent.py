"""How well the flicker bias's white-noise equivalent (D-5.15, D-5.25) bounds a flicker bias, in one velocity channel.

``python -m studies.scripts.flicker_white_equivalent [--runs 40] [--factors 1,2,3]``: a single velocity channel
aided by a
velocity measurement of sigma ``r`` at 1 Hz (the GNSS velocity), the accelerometer error the world's model draws
(a turn-on bias, the flicker bank of ``emulator.devices.imu.FlickerBank`` with the paper accelerometer's B = 1.333 mg
and 600 s, white noise of 100 ug/sqrt(Hz)), and the filter's model of it (``[dv, nabla]``: velocity white PSD
``VRW^2 + (0.664 B)^2 T_m``, the bias a random walk of ``2 B^2 / tau``, as
``firmware_model.filters.noise_model.spec_process_noise`` builds the rows). For the horizontal (0.041 m/s: the
world's paper GNSS; 0.053: the default sheet's) and the vertical (0.1 m/s) figures, the matching time
``T_m = (r / (0.664 B)^2)^(1/3)`` (``flicker_match_s``) times each factor: prints
the velocity NEES (mean of ``(e / sigma)^2`` after 10 s over ``runs`` 120 s runs), the RMS error and the mean sigma.
A one-dimensional check (no level, no height): docs/decisions/filter-consistency.md D-5.25 quotes it.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from emulator.devices.imu import FlickerBank

G = 9.80665
B = 1.3333e-3 * G  # bias instability (m/s^2): the paper accelerometers' worst axis
TAU = 600.0  # top of the flicker band (s)
VRW = 100e-6 * G  # m/s/sqrt(s)
TURN_ON = 2.333e-3 * G  # m/s^2, 1 sigma
FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi) * B  # Allan floor 0.664 B


def channel_nees(sig_r: float, t_match: float, runs: int, dur_s: float = 120.0, dt: float = 0.01,
                 after_s: float = 10.0) -> tuple[float, float, float]:
    """(NEES, RMS error m/s, mean sigma m/s) of the velocity of the 2-state filter over ``runs`` seeded runs."""
    qv = VRW**2 + FLOOR**2 * t_match
    qb = 2.0 * B**2 / TAU
    phi = np.array([[1.0, 1.0], [0.0, 1.0]])  # 1 s steps: dv += nabla
    q = np.array([[qv + qb / 3.0, qb / 2.0], [qb / 2.0, qb]])
    h = np.array([1.0, 0.0])
    z2, err, sig = [], [], []
    n = int(dur_s / dt)
    per_s = round(1.0 / dt)
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        bank = FlickerBank(np.array([B]), TAU)
        bank.init_stationary(rng)
        a = (TURN_ON * rng.standard_normal() + bank.block(rng.standard_normal((n, len(bank.taus), 1)), dt)[:, 0]
             + VRW / math.sqrt(dt) * rng.standard_normal(n))
        v = np.cumsum(a) * dt  # the INS velocity error the filter estimates
        x = np.zeros(2)
        P = np.diag([0.1**2, TURN_ON**2 + B**2])
        for k in range(1, int(dur_s)):
            x = phi @ x
            P = phi @ P @ phi.T + q
            truth = v[k * per_s - 1]
            s = float(h @ P @ h) + sig_r**2
            K = P @ h / s
            x = x + K * (truth + sig_r * rng.standard_normal() - float(h @ x))
            P = P - np.outer(K, h @ P)
            if k >= after_s:
                e = float(x[0]) - truth
                z2.append(e * e / P[0, 0])
                err.append(e)
                sig.append(math.sqrt(P[0, 0]))
    return float(np.mean(z2)), math.sqrt(float(np.mean(np.square(err)))), float(np.mean(sig))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--factors", default="1,2,3", help="multiples of the matching time")
    args = ap.parse_args(argv)
    for sig_r in (0.041, 0.053, 0.1):
        t0 = (sig_r**2 / FLOOR**2) ** (1.0 / 3.0)
        for f in (float(x) for x in args.factors.split(",")):
            nees, rms, sg = channel_nees(sig_r, t0 * f, args.runs)
            print(f"r {sig_r:.3f} m/s  T_m {t0 * f:5.2f} s ({f:g} x)  NEES {nees:.2f}  RMS error {rms:.4f} m/s  "
                  f"mean sigma {sg:.4f} m/s")


if __name__ == "__main__":
    main()
