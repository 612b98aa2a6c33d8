"""coupling.parallel and coupling.pin_workers in a scenario: booleans, bad values named."""

from __future__ import annotations

from pathlib import Path

import pytest

from orchestrator import load_scenario
from orchestrator.errors import ScenarioError

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jeffcott_runup_oil_bath.yaml"


def test_pin_workers_defaults_to_false_and_reads_a_boolean():
    assert load_scenario(SCENARIO).coupling.pin_workers is False
    assert load_scenario(SCENARIO, ["coupling.pin_workers=true"]).coupling.pin_workers is True


@pytest.mark.parametrize("key", ["pin_workers", "parallel"])
def test_a_non_boolean_is_refused_naming_the_key(key):
    with pytest.raises(ScenarioError) as info:
        load_scenario(SCENARIO, [f"coupling.{key}=3"])
    text = str(info.value)
    assert f"'coupling.{key}' must be true or false (got 3" in text and f"coupling.{key}=3" in text
