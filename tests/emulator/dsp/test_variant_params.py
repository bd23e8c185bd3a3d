"""The filter variants' parameters have one source: firmware_model/variants/params.py.

The scenario section ``firmware.variants`` is generated from it (emulator/scenario/variants_schema.py, by
``python -m emulator.dsp.variant_params``) and mapped back by name; these tests fail when the generated module is
stale, when a default or a bound of the scenario differs from the firmware's declaration, or when a field exists on
one side only.
"""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import fields

import pytest
from pydantic import ValidationError

from emulator.dsp.variant_params import GENERATED, render, sections, spec_name, variant_params
from emulator.scenario import variants_schema
from emulator.scenario.variants_schema import VariantsSpec
from firmware_model.variants.params import VariantParams, bounds_of


def test_the_scenario_section_is_generated_from_the_declarations():
    assert GENERATED.read_text(encoding="utf-8") == render(), "run: python -m emulator.dsp.variant_params"


def test_check_mode_reports_a_stale_module(tmp_path, monkeypatch):
    import emulator.dsp.variant_params as vp

    stale = tmp_path / "variants_schema.py"
    stale.write_text(render().replace("ge=2", "ge=3"), encoding="utf-8")
    monkeypatch.setattr(vp, "GENERATED", stale)
    assert vp.main(["--check"]) == 1
    monkeypatch.setattr(vp, "GENERATED", GENERATED)
    assert vp.main(["--check"]) == 0


def test_the_generated_module_never_imports_the_firmware():
    # the scenario layer sits below the world and the sensors, which never import firmware_model
    assert "firmware_model" not in "".join(
        line for line in GENERATED.read_text(encoding="utf-8").splitlines() if line.startswith(("import", "from")))


def test_same_fields_and_defaults_on_both_sides():
    assert list(VariantsSpec.model_fields) == list(sections())
    for key, cls in sections().items():
        spec = getattr(variants_schema, spec_name(cls))
        assert list(spec.model_fields) == [f.name for f in fields(cls)], key
    assert variant_params(VariantsSpec()) == VariantParams()


def _outside(value: float, integer: bool, up: bool, strict: bool) -> float:
    """The nearest value beyond a bound (``strict``: the bound itself is already outside)."""
    if strict:
        return value
    step = 1 if integer else max(abs(value) * 1e-9, 1e-12)
    return value + step if up else value - step


def _inside(value: float, integer: bool, up: bool, strict: bool) -> float:
    if not strict:
        return value
    step = 1 if integer else max(abs(value) * 1e-9, 1e-12)
    return value - step if up else value + step


@pytest.mark.parametrize("key", list(sections()))
def test_every_declared_bound_is_the_scenarios_bound(key):
    """Each limit of each parameter: the last value inside is accepted and mapped to the firmware unchanged, the
    first value outside is refused, as the declaration says."""
    cls = sections()[key]
    spec_cls = getattr(variants_schema, spec_name(cls))
    checked = 0
    for f in fields(cls):
        b = bounds_of(f)
        integer = isinstance(f.default, int) and not isinstance(f.default, bool)
        for lo_hi, up, strict in ((b.ge, False, False), (b.gt, False, True), (b.le, True, False), (b.lt, True, True)):
            if lo_hi is None:
                continue
            inside = _inside(lo_hi, integer, up, strict)
            got = variant_params(VariantsSpec.model_validate({key: {f.name: inside}}))
            assert math.isclose(getattr(getattr(got, key), f.name), inside), (key, f.name)
            with pytest.raises(ValidationError):
                spec_cls.model_validate({f.name: _outside(lo_hi, integer, up, strict)})
            checked += 1
        if b.choices is not None:
            for c in b.choices:
                assert getattr(variant_params(VariantsSpec.model_validate({key: {f.name: c}})), key) == cls(
                    **{f.name: c})
            with pytest.raises(ValidationError):
                spec_cls.model_validate({f.name: 0.02})
            checked += 1
        if b.min_items is not None:
            with pytest.raises(ValidationError):
                spec_cls.model_validate({f.name: []})
            checked += 1
    assert checked > 0


def test_a_list_in_the_scenario_is_a_tuple_in_the_firmware():
    got = variant_params(VariantsSpec.model_validate({"federated": {"subfilters": ["pol_mimu"],
                                                                    "initial_attitude_sigma_deg": [1, 2, 3]}}))
    assert got.federated.subfilters == ("pol_mimu",)
    assert got.federated.initial_attitude_sigma_deg == (1.0, 2.0, 3.0)


def test_the_command_line_check_passes_on_the_tree():
    out = subprocess.run([sys.executable, "-m", "emulator.dsp.variant_params", "--check"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
