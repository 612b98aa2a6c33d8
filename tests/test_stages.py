"""orchestrator.coupling.stages: which subsystems may step at the same time."""

from orchestrator.coupling.stages import Stage, stages
from orchestrator.coupling.schemes import GaussSeidel, Jacobi

RUNUP = [("rotor", "bearing1"), ("rotor", "bearing2"), ("bearing1", "rotor"), ("bearing2", "rotor")]


def test_gauss_seidel_runup_steps_the_bearings_together():
    order = ["rotor", "bearing1", "bearing2"]
    got = stages(order, RUNUP, GaussSeidel(order).uses_new_value)
    assert got == [Stage(("rotor",), False), Stage(("bearing1", "bearing2"), False)]
    assert not got[0].concurrent(startup=False) and got[1].concurrent(startup=True)


def test_jacobi_is_one_stage_but_sequential_in_startup_steps():
    order = ["rotor", "bearing1", "bearing2"]
    (only,) = stages(order, RUNUP, Jacobi().uses_new_value)
    assert only.names == tuple(order) and only.linked
    assert only.concurrent(startup=False) and not only.concurrent(startup=True)


def test_a_chain_in_gauss_seidel_order_is_sequential():
    order = ["a", "b", "c"]
    got = stages(order, [("a", "b"), ("b", "c")], GaussSeidel(order).uses_new_value)
    assert [s.names for s in got] == [("a",), ("b",), ("c",)]
    # the same chain stepped against the order uses only old values: one stage, linked
    rev = ["c", "b", "a"]
    (one,) = stages(rev, [("a", "b"), ("b", "c")], GaussSeidel(rev).uses_new_value)
    assert one.names == ("c", "b", "a") and one.linked


def test_a_consumer_of_an_earlier_stage_joins_the_current_one():
    order = ["src", "x", "y", "z"]
    links = [("src", "x"), ("src", "y"), ("y", "z"), ("src", "z")]
    got = stages(order, links, GaussSeidel(order).uses_new_value)
    assert [s.names for s in got] == [("src",), ("x", "y"), ("z",)]
