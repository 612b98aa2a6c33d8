"""coupling.parallel and coupling.pin_workers in a scenario: booleans (parallel also
'threads'), bad values named."""

from __future__ import annotations

from pathlib import Path

import pytest

from orchestrator import load_scenario
from orchestrator.errors import ScenarioError

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jeffcott_runup_oil_bath.yaml"


def test_pin_workers_defaults_to_false_and_reads_a_boolean():
    assert load_scenario(SCENARIO).coupling.pin_workers is False
    assert load_scenario(SCENARIO, ["coupling.pin_workers=true"]).coupling.pin_workers is True


@pytest.mark.parametrize("key, allowed", [("pin_workers", "true or false"),
                                          ("parallel", "true, false or threads")])
@pytest.mark.parametrize("value", ["3", "thread", "Threads"])
def test_a_bad_value_is_refused_naming_the_key_and_the_choices(key, allowed, value):
    with pytest.raises(ScenarioError) as info:
        load_scenario(SCENARIO, [f"coupling.{key}={value}"])
    text = str(info.value)
    assert f"'coupling.{key}' must be {allowed} (got " in text and f"coupling.{key}={value}" in text


def test_parallel_reads_true_false_and_threads():
    hs = SCENARIO.with_name("jeffcott_runup_half_sommerfeld.yaml")     # no parallel key
    assert load_scenario(hs).coupling.parallel is True
    assert load_scenario(SCENARIO).coupling.parallel == "threads"      # shipped so (session 12)
    assert load_scenario(SCENARIO, ["coupling.parallel=false"]).coupling.parallel is False
    assert load_scenario(SCENARIO, ["coupling.parallel=threads"]).coupling.parallel == "threads"
