"""Division-of-focal-plane polarization camera (Sony IMX250MZR) on the RS232 PSNS port.

Geometry and conventions (``docs/architecture.md``, section "Conventions"):

* camera frame c: +z optical axis, +x along columns (x = 1..nx), +y along rows (y = 1..ny);
  the lens (:mod:`emulator.devices.camera.optics`) maps a pixel to its view ray through its principal point,
  radial distortion and projection (pinhole or equidistant fisheye); with the defaults (centred, undistorted)
  pixel (x, y) looks along ``(Dx (x - (nx+1)/2), Dy (y - (ny+1)/2), f)`` (base paper Eq. 4);
* micro-polarizers per 2x2 super-pixel: (row 0, col 0) = 90 deg, (0, 1) = 45, (1, 0) = 135,
  (1, 1) = 0 (the layout polanalyser expects); angles from +x towards +y;
* the E-vector reaches the sensor plane through the lens by the meridional-plane rule (s kept, p scaled by
  the cosine of the chief-ray angle; :mod:`emulator.devices.camera.optics`); with a thin lens (the default
  ``exit_pupil_m`` None) that is the orthographic projection ``(E_x, E_y)`` of the paper;
  ``psi = atan2(E_y, E_x)``, Malus ``I_theta = S0/2 [1 + D DOP cos 2(psi - theta)]`` with
  ``D = (ER - 1)/(ER + 1)``, then the sensor's fixed pattern (orientation error, extinction spread, PRNU,
  dark signal, crosstalk, vignetting: :class:`emulator.devices.camera.optics.SensorDefects`);
* on-camera processing ``S0 = (I0+I45+I90+I135)/2``, ``S1 = I0 - I90``, ``S2 = I45 - I135``,
  ``DOP = sqrt(S1^2 + S2^2)/S0``, ``psi = atan2(S2, S1)/2``; on the wire ``AOP = 90 deg - psi``
  wrapped to (-90, 90] (from image +y towards +x, base paper Eq. 5);
* mounting: ``C_c^b`` (nominal rotation and a small installation error from the scenario);
* ``latency_us`` runs from the middle of the exposure to the start bit of the frame's first byte.

Sensor (``docs/reference/algorithms.md`` 2.2-2.3, reference values of its simulation):
2448 x 2048 pixels of 3.45 um, full well 10 000 e-, read noise 5 e-, 12-bit ADC, extinction
ratio 300 at 525 nm, over wavelength and under the sky's spectrum an effective 281 (:mod:`.spectral`).
The sky (``emulator.world.sky``) gives DOP, E-vector and a relative radiance; the
exposure is taken as auto-exposed so that unpolarized sky of radiance 1 puts ``signal_e``
electrons into a pixel behind an ideal polarizer (``S0/2``; default half the full well).

Observation points. The image is read out as a grid of ``grid`` points. Each point integrates
``n + 1`` super-pixel columns and rows (``n = bin_superpixels``) with separable weights
``[3/4, 1, ..., 1, 1/4]``: a box of ``n`` super-pixels linearly interpolated by half a
super-pixel, so that the weighted centroid of the super-pixel centres (which sit on half-integer
pixel coordinates) is the integer pixel ``(x_px, y_px)`` that the frame reports. Inside one
super-pixel the 0/90 and 45/135 pixels sit symmetrically about its centre, so with a smooth sky
the first-order pixel-offset errors cancel in ``S1`` and ``S2``; what remains is second order in
the window size (a test bounds it).

Fidelity:

``full``
    renders the whole 2448 x 2048 mosaic (every super-pixel sees the sky along its own centre
    ray; shot noise as a Gaussian of variance ``mean + read_noise^2`` electrons, drawn from a
    16-bit inverse-CDF table; rounding to 12-bit DN with clipping), then runs the on-camera
    processing on the mosaic exactly as the real camera would.
``binned``
    evaluates the sky only along the ray of each observation point and draws the window means
    directly: each channel mean is Gaussian with the variance of the same weighted sum of
    independent pixels, ``kappa ((mean + read^2) g^2 + 1/12)`` DN^2 (g = DN per electron,
    1/12 the rounding, ``kappa = sum w^2 / (sum w)^2``). A test shows that both fidelities give
    the same AOP/DOP statistics.
"""

from .device import PolarizationCamera
from .geometry import (
    CHANNEL_OFFSETS,
                       IMX250MZR_NX,
                       IMX250MZR_NY,
                       IMX250MZR_PIXEL_M,
    CameraConfig,
    CameraGeometry,
    PointObservations,
    mounting_matrix,
    rotation_vector_matrix,
    stokes_superpixel,
    wire_aop_cdeg,
)
from .model import PolarizationCameraModel

__all__ = [
                       "CHANNEL_OFFSETS",
                       "IMX250MZR_NX",
                       "IMX250MZR_NY",
                       "IMX250MZR_PIXEL_M",
                       "CameraConfig",
                       "CameraGeometry",
                       "PointObservations",
                       "PolarizationCamera",
                       "PolarizationCameraModel",
                       "mounting_matrix",
                       "rotation_vector_matrix",
                       "stokes_superpixel",
                       "wire_aop_cdeg",
]
