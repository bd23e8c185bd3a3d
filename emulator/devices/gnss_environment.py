"""The GNSS antenna's surroundings: open sky, suburbs, urban canyon (docs/sensors.md, "The envelope").

A receiver's error budget depends less on the receiver than on where its antenna is. Each environment changes the
``field`` receiver (:mod:`emulator.devices.gnss`) in four ways:

- **geometry and the DOP law**: fewer satellites and a worse HDOP (drawn once per run in the environment's range;
  Kaplan & Hegarty, *Understanding GPS/GNSS*, 3rd ed. 2017, ch. 7, for DOP against visible satellites). The receiver
  reports that HDOP and its errors follow it: a position error is the range error mapped through the geometry,
  sigma = DOP x UERE (Kaplan & Hegarty ch. 7; GPS SPS Performance Standard, 5th ed. 2020, whose position accuracy is
  stated the same way). The receiver's own figures (slow part, white part, velocity) are its errors at the geometry
  its configuration reports (``hdop``, 0.8 for ``field``) and scale by ``HDOP / hdop``; the environment's code
  multipath is a range error (1 sigma, m: decimetres in open sky, metres in suburbs, several metres in a street
  canyon) that replaces the receiver's own, a Gauss-Markov process per axis of HDOP x range / sqrt(2) horizontally
  and the receiver's vertical-to-horizontal ratio times that vertically;
- **a NLOS bias**: in a canyon the signals that arrive only by reflection are all delayed, so the solution is pushed
  away from the buildings by a bias that lasts as long as the geometry (Groves 2011, "Shadow matching", J. Navig.
  64(3) 417: across-street errors of tens of metres): a constant horizontal offset per run, its size drawn from the
  environment's range and its direction uniform;
- **NLOS outliers**: episodes (Poisson in time, each 3-20 s long) during which a reflected-only satellite enters the
  solution and the position jumps by a Gaussian offset of the environment's size (Hsu 2018, "Analysis and modeling
  GPS NLOS effect in highly urbanized area", GPS Solut. 22:7: NLOS pseudorange errors of tens of metres).

What the receiver *reports* of its errors (GST, D-4.14): its own figures at the geometry it reports, plus the
multipath as it sees it in its pseudorange residuals (:meth:`GnssEnvironmentProcess.reported_std_m`): a variance
estimated from the residuals' ``n - 4`` degrees of freedom per epoch over a smoothing window of
:data:`RESIDUAL_WINDOW_EPOCHS` epochs, so a scaled chi-square draw around the truth; with 4 satellites or fewer there
is no redundancy and no multipath in the estimate (RAIM needs a fifth satellite: Kaplan & Hegarty ch. 11). An
outlier episode (one reflected-only satellite in an overdetermined solution) raises the residuals the same way, so
its size enters the estimate while it lasts (the residual test of RAIM: Kaplan & Hegarty ch. 11); the constant NLOS
bias does not: a solution whose every signal is delayed alike has consistent residuals (Groves 2011).

The figures are in :data:`ENVIRONMENTS` (ranges from the papers above, the exact values are design values [D]).
The receiver calls :meth:`GnssEnvironmentProcess.position_offset` once per fix (a small hook in ``gnss.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .gnss import GnssErrors

__all__ = ["ENVIRONMENTS", "RESIDUAL_WINDOW_EPOCHS", "GnssEnvironment", "GnssEnvironmentProcess",
           "environment_errors"]

#: epochs over which the receiver smooths its residual-based estimate of its range errors (GST) [D]
RESIDUAL_WINDOW_EPOCHS = 10


@dataclass(frozen=True)
class GnssEnvironment:
    """One kind of surroundings (see module docstring). Lengths m (1 sigma per axis unless a range), times s."""

    name: str
    #: code multipath, a range error (1 sigma, m); in position HDOP x this / sqrt(2) per horizontal axis
    multipath_range_m: float
    multipath_corr_time_s: float
    nlos_bias_h_m: tuple[float, float]
    nlos_rate_hz: float
    nlos_sigma_h_m: float
    nlos_sigma_v_m: float
    nlos_duration_s: tuple[float, float]
    num_sats: tuple[int, int]
    hdop: tuple[float, float]


#: the environments of the envelope (module docstring; docs/sensors.md "The envelope" gives the sources)
ENVIRONMENTS: dict[str, GnssEnvironment] = {
    "open_sky": GnssEnvironment("open_sky", 0.5, 15.0, (0.0, 0.0), 0.0, 0.0, 0.0, (0.0, 0.0),
                                (10, 14), (0.7, 1.0)),
    "suburban": GnssEnvironment("suburban", 2.0, 20.0, (0.0, 3.0), 1.0 / 300.0, 8.0, 12.0, (3.0, 15.0),
                                (7, 10), (1.2, 2.0)),
    "urban_canyon": GnssEnvironment("urban_canyon", 5.0, 30.0, (3.0, 15.0), 1.0 / 60.0, 20.0, 30.0,
                                    (3.0, 20.0), (4, 7), (2.0, 5.0)),
}


def environment_errors(env: GnssEnvironment, e: GnssErrors, hdop: float, hdop_receiver: float) -> GnssErrors:
    """The receiver's figures in ``env`` under the geometry ``hdop`` it reports (sigma = DOP x UERE, module
    docstring): its own position (slow and white parts) and velocity figures, stated at ``hdop_receiver``, times
    ``hdop / hdop_receiver``; its multipath process replaced by the environment's range error through ``hdop``
    (per horizontal axis HDOP x range / sqrt(2), vertically times the receiver's vertical-to-horizontal ratio) at the
    environment's correlation time."""
    if not (hdop > 0.0 and hdop_receiver > 0.0):
        raise ValueError(f"HDOP must be > 0 (got {hdop}, receiver's {hdop_receiver})")
    k = hdop / hdop_receiver
    mp_h = hdop * env.multipath_range_m / math.sqrt(2.0)
    v_over_h = e.pos_sigma_v_m / e.pos_sigma_h_m if e.pos_sigma_h_m > 0.0 else 1.0
    return replace(e, pos_sigma_h_m=e.pos_sigma_h_m * k, pos_sigma_v_m=e.pos_sigma_v_m * k,
                   multipath_sigma_h_m=mp_h, multipath_sigma_v_m=mp_h * v_over_h,
                   multipath_corr_time_s=env.multipath_corr_time_s, vel_sigma_h_mps=e.vel_sigma_h_mps * k,
                   vel_sigma_v_mps=e.vel_sigma_v_mps * k)


class GnssEnvironmentProcess:
    """One run in an environment: the NLOS bias, the geometry (drawn at construction) and the outlier episodes.

    Parameters
    ----------
    env : the environment.
    rng : its own random stream (the receiver's stream is not touched).
    residual_rng : the stream of the receiver's residual-based estimate (:meth:`reported_std_m`; its own, so reporting
        GST or not leaves the errors unchanged); None: the estimate is the multipath's sigma itself (no draw).
    """

    def __init__(self, env: GnssEnvironment, rng: np.random.Generator,
                 residual_rng: np.random.Generator | None = None) -> None:
        self.env = env
        self.rng = rng
        self.residual_rng = residual_rng
        az = rng.uniform(0.0, 2.0 * math.pi)
        size = rng.uniform(*env.nlos_bias_h_m)
        #: the constant NLOS bias, ENU m
        self.bias_enu = np.array([size * math.sin(az), size * math.cos(az), 0.0])
        self.num_sats = int(rng.integers(env.num_sats[0], env.num_sats[1] + 1))
        self.hdop = float(rng.uniform(*env.hdop))
        self._episode_end = -math.inf
        self._episode_offset = np.zeros(3)
        #: outlier episodes started so far, and fixes they touched
        self.episodes = 0
        self.outlier_fixes = 0
        #: the last fix was inside an outlier episode
        self.in_episode = False

    def reported_std_m(self, e: GnssErrors, num_sats: int) -> tuple[float, float, float]:
        """The receiver's own estimate of its latitude, longitude and altitude errors (m, 1 sigma) for GST, given its
        figures ``e`` at the reported geometry and ``num_sats`` satellites (module docstring, D-4.14):
        ``sqrt(sigma^2 + m^2 chi2_k / k)`` with ``m`` the multipath's sigma (and an outlier episode's, while the
        last :meth:`position_offset` was in one) and ``k = (num_sats - 4)`` x :data:`RESIDUAL_WINDOW_EPOCHS` (``m``
        not seen with ``num_sats <= 4``)."""
        k = max(num_sats - 4, 0) * RESIDUAL_WINDOW_EPOCHS
        f = 1.0  # without a stream of its own: the multipath's sigma itself
        if k == 0:
            f = 0.0
        elif self.residual_rng is not None:
            f = float(self.residual_rng.chisquare(k)) / k
        mh2, mv2 = e.multipath_sigma_h_m**2, e.multipath_sigma_v_m**2
        if self.in_episode:  # a reflected-only satellite in the solution: its residual shows (module docstring)
            mh2 += self.env.nlos_sigma_h_m**2
            mv2 += self.env.nlos_sigma_v_m**2
        h = math.sqrt(e.pos_sigma_h_m**2 + f * mh2)
        v = math.sqrt(e.pos_sigma_v_m**2 + f * mv2)
        return h, h, v

    def position_offset(self, t: float, dt: float) -> np.ndarray:
        """What the surroundings add to the fix at ``t`` (s) after ``dt`` (s) since the last one: ENU m, (3,)."""
        env = self.env
        if (t >= self._episode_end and env.nlos_rate_hz > 0.0
                and self.rng.uniform() < -math.expm1(-env.nlos_rate_hz * max(dt, 0.0))):
                self.episodes += 1
                self._episode_end = t + self.rng.uniform(*env.nlos_duration_s)
                self._episode_offset = self.rng.standard_normal(3) * np.array(
                    [env.nlos_sigma_h_m, env.nlos_sigma_h_m, env.nlos_sigma_v_m])
        self.in_episode = t < self._episode_end
        if self.in_episode:
            self.outlier_fixes += 1
            return self.bias_enu + self._episode_offset
        return self.bias_enu.copy()
