"""Every number a Python keyword gives has the command line's bound, refused with the keyword
and the limit named before any work (issue 38, item 2)."""

import time

import pytest

import kinecal


@pytest.fixture(scope="module")
def ge_a4() -> kinecal.Robot:
    return kinecal.Robot.builtin("ge-a4")


def test_a_model_choice_repeats_at_most_100_times(ge_a4: kinecal.Robot) -> None:
    sim = kinecal.simulate(ge_a4, 20, seed=3, noise={"length": 0.0005})
    started = time.monotonic()
    # It ran away (a billion rounds of fits).
    with pytest.raises(
        kinecal.KinecalError,
        match="^repeats: expected between 1 and 100 repeats, not 1000000000$",
    ):
        kinecal.calibrate(ge_a4, sim.measurements, choose=[], repeats=10**9)
    assert time.monotonic() - started < 30
    with pytest.raises(
        kinecal.KinecalError,
        match="^max_iterations: expected between 1 and 1000000 iterations, not 2000000$",
    ):
        kinecal.calibrate(ge_a4, sim.measurements, max_iterations=2_000_000)


def test_seeds_are_those_a_spec_file_holds(ge_a4: kinecal.Robot) -> None:
    with pytest.raises(
        kinecal.KinecalError,
        match=r"^seed: expected a seed between 0 and 9223372036854775807 \(the largest "
        r"integer a spec file holds\), not 9223372036854775808$",
    ):
        kinecal.simulate(ge_a4, 3, seed=2**63)
    a = kinecal.simulate(ge_a4, 3, seed=2**63 - 1, noise={"length": 0.01})
    b = kinecal.simulate(ge_a4, 3, seed=2**63 - 1, noise={"length": 0.01})
    assert a.measurements.to_csv(ge_a4) == b.measurements.to_csv(ge_a4)


def test_a_count_of_postures_beyond_the_limit_raises_naming_postures(
    ge_a4: kinecal.Robot,
) -> None:
    # It killed the interpreter (the postures were allocated before any check).
    with pytest.raises(
        kinecal.KinecalError,
        match="^postures: expected between 1 and 10000000 postures, not 1099511627776$",
    ):
        kinecal.simulate(ge_a4, 2**40)
