"""The filter variants of the source papers, each registered in :data:`firmware_model.FILTER_VARIANTS`.

===================  ===============================================  ====================================
``firmware.filter``  module                                           source
===================  ===============================================  ====================================
``dual_vector``      :mod:`~firmware_model.variants.dual_vector`      patent CN (Guo et al. 2021)
``kmeans_3d``        :mod:`~firmware_model.variants.kmeans_3d`        Yang et al. 2020
``federated``        :mod:`~firmware_model.variants.federated`        Ge et al.; Carlson 1990
``sun_elevation``    :mod:`~firmware_model.variants.sun_elevation`    Zhang et al. 2021 (Sensors 21:1055)
===================  ===============================================  ====================================

All of them route their measurement decisions through the shared
:class:`~firmware_model.variants.mode_manager.ModeManager` (events with reasons) and charge C674x cycles like
the base filter. Parameters: :mod:`~firmware_model.variants.params`. Derivations: ``docs/variants.md``.
"""

from __future__ import annotations

from .mode_manager import ModeManager
from .params import (
    DualVectorParams,
    FederatedParams,
    KmeansParams,
    ModeManagerParams,
    SunElevationParams,
    VariantParams,
)

__all__ = [
    "DualVectorParams",
    "FederatedParams",
    "KmeansParams",
    "ModeManager",
    "ModeManagerParams",
    "SunElevationParams",
    "VariantParams",
]
