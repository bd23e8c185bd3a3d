"""Array types of the firmware model's annotations (one place, used by every module).

The kernels work in the build's working precision (float32 or float64, ``FirmwareConfig.precision``), so most
arrays are :data:`FloatArray`; latitude/longitude/height and other double-precision quantities are
:data:`F64Array`. :data:`FloatDtype` is the scalar type that selects a precision (``np.float32`` or
``np.float64``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["BoolArray", "F64Array", "FloatArray", "FloatDtype", "IntArray"]

#: an array of the working precision (float32 or float64)
FloatArray = npt.NDArray[np.floating[Any]]
#: a float64 array (position, Earth quantities, reference computations)
F64Array = npt.NDArray[np.float64]
#: the scalar type naming a precision: ``np.float32`` or ``np.float64``
FloatDtype = type[np.floating[Any]]
IntArray = npt.NDArray[np.integer[Any]]
BoolArray = npt.NDArray[np.bool_]
