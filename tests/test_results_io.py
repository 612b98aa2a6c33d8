"""The one reader of a run folder (RunDirectory, CoSimResult.load), the one JSON sanitiser and
the monolithic reference's model registry."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from orchestrator import CoSimResult, Status, run
from orchestrator.reference.models import MODELS, load_model_file, register_model
from orchestrator.results.jsonsafe import plain
from orchestrator.results.run_directory import RunDirectory
from orchestrator.scenario import ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario


def test_loaded_result_equals_the_run(test_fmus, tmp_path):
    sc = Scenario(name="two-mass", stop_time=0.05,
                  fmus=(FmuSpec(name="left", path=test_fmus["LeftMass"], parameters={"x1_0": 1.0}),
                        FmuSpec(name="right", path=test_fmus["RightMass"])),
                  connections=(ConnectionSpec(src="left.x1", dst="right.x1"),
                               ConnectionSpec(src="right.F", dst="left.F")),
                  coupling=CouplingSpec(macro_step=1e-3), output=OutputSpec(signals=("left.x1", "right.F")))
    res = run(sc, out_dir=tmp_path, progress=False)
    back = CoSimResult.load(tmp_path)
    assert back.status is res.status is Status.FINISHED and back.message == res.message
    np.testing.assert_array_equal(back.t, res.t)           # repr() in the CSV round-trips exactly
    assert list(back.outputs) == list(res.outputs)
    for k in res.outputs:
        np.testing.assert_array_equal(back.outputs[k], res.outputs[k])
    assert back.stats["macro_steps"] == res.stats["macro_steps"] and back.end_time == res.end_time
    run_dir = RunDirectory(tmp_path)
    assert run_dir.summary()["output"]["rows"] == len(res.t) and run_dir.field_files() == []


def test_load_of_a_folder_without_summary_is_failed(tmp_path):
    (tmp_path / "results.csv").write_text("time,a.y\n0.0,1.0\n0.1,2.0\n0.2")   # truncated last line
    res = CoSimResult.load(tmp_path)
    assert res.status is Status.FAILED and res.t.tolist() == [0.0, 0.1] and res.outputs["a.y"].tolist() == [1.0, 2.0]


def test_json_policies():
    x = {"a": math.nan, "b": [math.inf, -math.inf, 1.5], "c": np.float64(2.0), "d": np.int64(3), "e": np.bool_(True)}
    assert plain(x, "string") == {"a": "nan", "b": ["inf", "-inf", 1.5], "c": 2.0, "d": 3, "e": True}
    assert plain(x, "null") == {"a": None, "b": [None, None, 1.5], "c": 2.0, "d": 3, "e": True}
    assert plain(x, "null-nan") == {"a": None, "b": ["inf", "-inf", 1.5], "c": 2.0, "d": 3, "e": True}
    json.dumps(plain(x, "null"), allow_nan=False)
    with pytest.raises(ValueError, match="nonfinite"):
        plain(x, "zero")


def test_two_mass_models_come_from_the_tests_not_from_production():
    """conftest.py registers them; the production registry knows only our own models."""
    import orchestrator.reference.models as models
    assert "LeftMass" in MODELS and "RightMass" in MODELS
    assert "LeftMassAdapter" not in dir(models) and "RightMassAdapter" not in dir(models)
    with pytest.raises(TypeError, match="callable"):
        register_model("X", 3)


def test_a_model_file_without_register_is_refused(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("x = 1\n")
    with pytest.raises(ImportError, match="register"):
        load_model_file(f)
