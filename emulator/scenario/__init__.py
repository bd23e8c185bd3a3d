"""Scenario files: schema, loading with file/line/column errors."""

from __future__ import annotations

from .loader import load_scenario, load_yaml_with_marks, validate_scenario_data
from .schema import Scenario

__all__ = ["Scenario", "load_scenario", "load_yaml_with_marks", "validate_scenario_data"]
