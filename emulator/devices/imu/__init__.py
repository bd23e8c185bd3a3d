"""Inertial sensors: the STIM210 gyro (RS422 datagrams) and the analog accelerometers.

Both sample the same truth (:class:`ImuTruthTap`) over the FPGA's trigger interval
``[t_prev, t]``: the STIM210 in *average angular rate* output (the mean rate over the
interval, TS1524 section 7.5.2.2) and the accelerometers through the FPGA's oversampling ADC,
whose boxcar average over the same interval is the mean specific force (docs/decisions/world-and-sensors.md D4).

Error model (:class:`InertialErrorModel`, one per sensor triad; figures in the YAML presets of
``emulator/presets/imu.yaml``, sources in ``docs/sensors.md``). For the true mean input ``x``
(rad/s or m/s^2, body axes) over an interval of length ``dt``::

    y = (I + S + M) x + A |x| + NL(x) + b_0 + b_T(T, dT/dt) + G f + b_flicker(t) + b_rrw(t) + n_white

* ``S`` diagonal scale-factor errors and ``M`` off-diagonal axis misalignments (random constants
  per unit), ``A`` the scale-factor asymmetry (half the difference between the positive and
  negative scale factors), ``NL`` a terminal-based cubic nonlinearity
  ``k FS (3 sqrt(3)/2)(u^3 - u)``, ``u = x/FS`` (zero at 0 and +-FS, peak ``k FS``);
* ``b_0`` the turn-on bias (bias repeatability), ``b_T`` the residual temperature bias
  (coefficient times ``T - T_cal`` plus a gradient term times ``dT/dt``), ``G f`` the gyro's
  linear-acceleration sensitivity;
* ``b_flicker`` the in-run bias instability: flicker (1/f) noise approximated by a bank of
  first-order Gauss-Markov processes, two per decade of correlation time from 0.3 s to
  ``bias_corr_time_s``, scaled so that the flat part of its Allan deviation equals
  ``0.664 B`` (IEEE Std 952: the Allan-deviation floor of bias instability ``B``);
* ``b_rrw`` a random walk of rate random walk ``K`` (Allan deviation ``K sqrt(tau/3)``);
* ``n_white`` white noise of density ``N`` (angle / velocity random walk): the mean over ``dt``
  has variance ``N^2/dt`` (Allan deviation ``N/sqrt(tau)``).

Then the range (saturation) and the 24-bit words (STIM: 2^-14 deg/s; accelerometers: volts
through the 24-bit ADC). The stochastic part is generated vectorised in blocks of 200 samples
(:meth:`InertialErrorModel.noise`), which is the same code that the Allan-deviation test runs
over a two-hour record.

The paper's "< X" limits are 3 sigma (docs/decisions/world-and-sensors.md D1): the presets hold ``X / 3``.
"""

from .accelerometers import AnalogAccelerometers
from .allan import allan_deviation
from .error_model import (
    AccelErrors,
    FlickerBank,
    GyroErrors,
    ImuTemperature,
    InertialErrorModel,
    accel_error_model,
    gyro_error_model,
)
from .injected import InjectedFaults
from .lookahead import ImuTruthTap
from .stim210 import Stim210Gyro

__all__ = [
                          "AccelErrors",
                          "AnalogAccelerometers",
                          "FlickerBank",
                          "GyroErrors",
                          "ImuTemperature",
                          "ImuTruthTap",
                          "InertialErrorModel",
                          "InjectedFaults",
                          "Stim210Gyro",
                          "accel_error_model",
                          "allan_deviation",
                          "gyro_error_model",
]
