"""Polarization-sensor faults: clouds, an occluded sun, blocked units, installation errors."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from protocols.constants import DEG

from ..world.sky import SkyModel, SunOccluder, textured_cloud
from .base import Injector, bind_error, injects
from .targets import FaultTargets

__all__ = ["PsnsCloudCover", "PsnsInstallationError", "PsnsSunOccluded", "PsnsUnitBlocked"]


def _psns(targets: FaultTargets, kind: str) -> tuple[Any, Any]:
    s = targets.sensors
    cam = getattr(s, "psns", None) if s is not None else None
    comp = getattr(s, "compass", None) if s is not None else None
    if cam is None and comp is None:
        raise bind_error(kind, "needs a modelled polarization sensor (camera or compass) on a mem:// psns link")
    return cam, comp


@injects("psns_cloud_cover")
class PsnsCloudCover(Injector):
    effect_keys: tuple[str, ...] = ("rays_in_cloud",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        _psns(self.targets, self.kind)
        sky = self.targets.sensors.sky if self.targets.sensors is not None else None
        if sky is None:
            raise bind_error(self.kind, "needs the sky model of the modelled polarization sensor")
        self.sky: SkyModel = sky
        self.cloud: Any = None

    @property
    def target(self) -> str:
        s = self.spec
        return f"sky around az {s.az_deg:g} deg, el {s.el_deg:g} deg"

    def on(self, t: float) -> None:
        s = self.spec
        self.cloud = textured_cloud(self.rng, s.az_deg * DEG, s.el_deg * DEG, s.radius_deg * DEG, s.dop_scale,
                                    s.aop_sigma_deg * DEG, s.intensity_scale, 0.0, math.inf, s.drift_az_dps * DEG)
        self.sky.clouds.append(self.cloud)

    def off(self, t: float) -> None:
        if self.cloud in self.sky.clouds:
            self.sky.clouds.remove(self.cloud)

    def _counts(self) -> dict[str, int]:
        return {"rays_in_cloud": self.cloud.hits if self.cloud is not None else 0}

    def start(self, t: float) -> None:
        self.on(t)  # the cloud (and its counter) exists from now on
        self._c0 = self._counts()
        self.active = True
        self.t_on = t


@injects("psns_sun_occluded")
class PsnsSunOccluded(PsnsCloudCover):
    effect_keys: tuple[str, ...] = ("rays_near_sun_hidden",)

    @property
    def target(self) -> str:
        return f"sky within {self.spec.radius_deg:g} deg of the sun"

    def on(self, t: float) -> None:
        s = self.spec
        self.cloud = SunOccluder(s.radius_deg * DEG, s.dop_scale, s.intensity_scale)
        self.sky.sun_occluders.append(self.cloud)

    def off(self, t: float) -> None:
        if self.cloud in self.sky.sun_occluders:
            self.sky.sun_occluders.remove(self.cloud)

    def _counts(self) -> dict[str, int]:
        return {"rays_near_sun_hidden": self.cloud.hits if self.cloud is not None else 0}


@injects("psns_unit_blocked")
class PsnsUnitBlocked(Injector):
    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.cam, self.comp = _psns(self.targets, self.kind)
        self.effect_keys = ("unit_readings_blocked",) if self.comp is not None else ("frames_blocked",)
        if self.comp is not None and self.kind == "psns_unit_blocked":
            n = len(self.comp.model.mountings)
            units = self.spec.units
            self.units = list(range(n)) if units is None else list(units)
            bad = [u for u in self.units if u >= n]
            if bad:
                raise bind_error(self.kind, f"blocks units {bad}, but the compass has units 0..{n - 1}")

    @property
    def target(self) -> str:
        if self.comp is not None:
            u = self.spec.units
            return "compass units " + ("all" if u is None else ", ".join(str(x) for x in u))
        return "polarization camera"

    def on(self, t: float) -> None:
        if self.comp is not None:  # the compass's own blocked-units schedule: a window from now
            end = self.spec.end_s(self.targets.duration_s)
            self.comp.model.block_units(self.units, t, max(end, t + 1e-9))
        else:
            self.cam.set_blocked(True)

    def off(self, t: float) -> None:
        if self.comp is None:
            self.cam.set_blocked(False)

    def _counts(self) -> dict[str, int]:
        if self.comp is not None:
            return {"unit_readings_blocked": self.comp.model.blocked_readings}
        return {"frames_blocked": self.cam.frames_blocked}


@injects("psns_installation_error")
class PsnsInstallationError(PsnsUnitBlocked):
    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.effect_keys = ("frames_with_error",)

    @property
    def target(self) -> str:
        return "compass mounting" if self.comp is not None else "camera mounting"

    def on(self, t: float) -> None:
        rv = np.asarray(self.spec.rotation_deg, dtype=np.float64) * DEG
        (self.comp if self.comp is not None else self.cam).model.set_mounting_error(rv)

    def off(self, t: float) -> None:
        (self.comp if self.comp is not None else self.cam).model.set_mounting_error(None)

    def _counts(self) -> dict[str, int]:
        if self.comp is not None:
            return {"frames_with_error": self.comp.model.readings_with_mounting_error}
        return {"frames_with_error": self.cam.model.frames_with_mounting_error}
