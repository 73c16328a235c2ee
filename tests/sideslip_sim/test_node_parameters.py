"""The sim node's parameters as data: the declared table and its defaults, the typed and
checked SimParams built from declared values, and the stream they name (no ROS)."""

from __future__ import annotations

import dataclasses

import pytest

from sideslip_msgs_py.sample import SensorNoiseSigma
from sideslip_sim.maneuvers import ManeuverError
from sideslip_sim.node_parameters import (
    PARAMETERS,
    ParameterError,
    SigmaOverride,
    SimParams,
    help_page,
    open_stream,
)
from sideslip_sim.stream import ManeuverSpec

DECLARED = {p.name: p.default for p in PARAMETERS}


def _params(**changed: object) -> SimParams:
    return SimParams.from_values(DECLARED | changed)


def test_the_declared_defaults_build_the_default_params() -> None:
    assert _params() == SimParams()
    assert SimParams().maneuver == ManeuverSpec() and SimParams().decimation == 1


def test_declared_values_reach_their_fields_and_groups() -> None:
    params = _params(
        scenario="sine_steer",
        **{"sigma.stl_m": 0.001, "maneuver.speed_kmh": 60.0, "rate_hz": 100.0},
    )
    assert params.scenario == "sine_steer" and params.decimation == 4
    assert params.sigma == SigmaOverride(stl_m=0.001)
    assert params.maneuver == ManeuverSpec(speed_kmh=60.0)


def test_the_help_page_lists_every_parameter_with_its_default() -> None:
    page = help_page()
    for p in PARAMETERS:
        assert f"  {p.name} ({p.type_name}, default {p.default!r})" in page


@pytest.mark.parametrize(
    ("changed", "message"),
    [
        ({"real_time_factor": -1.0}, "real_time_factor must be >= 0, got -1.0"),
        ({"real_time_factor": float("nan")}, "real_time_factor must be >= 0, got nan"),
        ({"rate_hz": 300.0}, "rate_hz must be 400 or 400/k, got 300.0"),
        ({"rate_hz": 0.0}, "rate_hz must be 400 or 400/k, got 0.0"),
        (
            {"wait_for_subscribers_timeout_s": float("inf")},
            "wait_for_subscribers_timeout_s must be finite and >= 0, got inf",
        ),
        ({"imu.frame": "tilted"}, "imu.*: IMU frame 'tilted': must be one of level, body"),
        (
            {"imu.position_x_m": 7.0},
            "imu.*: IMU position x = 7.0 m: must be finite and within ±5 m of the CG",
        ),
    ],
)
def test_values_the_node_cannot_run_with_are_refused_naming_them(changed, message) -> None:
    with pytest.raises(ParameterError) as caught:
        _params(**changed)
    assert str(caught.value) == message


def test_sigma_overrides_replace_only_the_profile_values_they_give() -> None:
    profile = SensorNoiseSigma.paper()
    assert SigmaOverride().applied_to(profile) == profile
    assert SigmaOverride(velocity_mps=0.5, stl_m=0.0).applied_to(profile) == (
        dataclasses.replace(profile, velocity_mps=0.5, stl_m=0.0)
    )


def test_the_stream_holds_the_named_runs_vehicle_noise_and_rate() -> None:
    params = _params(scenario="straight", noise="none", loop=True, rate_hz=200.0)
    stream = open_stream(params)
    assert [m.family for m in stream.runs] == ["straight"]
    assert stream.vehicle.name == "paper_sedan" and stream.sigma == SensorNoiseSigma.none()
    assert stream.loop and stream.decimation == 2 and stream.ground_truth


def test_the_stream_publishes_what_sideslip_generate_writes_for_that_imu() -> None:
    from sideslip_sim.imu_mounting import ImuMounting
    from sideslip_sim.sensors import add_noise, exact_samples, run_seed
    from sideslip_sim.simulate import simulate

    params = _params(scenario="sine_steer", **{"imu.frame": "body", "imu.position_x_m": 0.6})
    stream = open_stream(params)
    assert stream.imu == ImuMounting((0.6, 0.0), "body")
    chunk = next(iter(stream))
    run = stream.runs[0]
    want = add_noise(
        exact_samples(simulate(stream.vehicle, run), imu=stream.imu),
        stream.sigma,
        run_seed(params.seed, run.name),
    )
    assert (chunk.samples.y_a_mps2 == want.y_a_mps2).all()
    assert (chunk.samples.x_a_mps2 == want.x_a_mps2).all()


def test_a_bad_scenario_or_noise_profile_is_refused_naming_it() -> None:
    with pytest.raises(ManeuverError, match="unknown scenario 'scen9'"):
        open_stream(_params(scenario="scen9"))
    with pytest.raises(ValueError, match="unknown noise profile 'loud'"):
        open_stream(_params(noise="loud"))
