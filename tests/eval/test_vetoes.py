"""is_false_veto / is_missed_veto / veto_error_m: a veto judged against the true obstacles along
its corridor."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from negobs_gym.envs import NegObsEnv
from negobs_gym.eval.vetoes import (
    FALSE_VETO_LATERAL_TOLERANCE_M,
    FALSE_VETO_TOLERANCE_M,
    VetoTally,
    format_veto_error,
    is_false_veto,
    is_missed_veto,
    is_veto,
    largest_veto_error_m,
    veto_error_m,
    veto_truth_m,
)
from negobs_gym.safety import Corridor, SafetyDecision
from negobs_gym.spec import spec_from_toml
from tests.helpers import PITS_BESIDE_AND_AHEAD_SCENE


@pytest.fixture(scope="module")
def env_info() -> tuple[NegObsEnv, dict]:
    env = NegObsEnv(scenario=spec_from_toml(PITS_BESIDE_AND_AHEAD_SCENE))
    _, info = env.reset(seed=0)
    yield env, info
    env.close()


def _record(d_m: float, steer_rad: float | None, vetoed: bool = True, r_m: float = 8.0) -> dict:
    corridor = None if steer_rad is None else Corridor(steer_rad=steer_rad, wheelbase_m=2.8, half_width_m=1.2)
    return {
        "vetoed": vetoed,
        "hazard_distance_m": d_m,
        "braking_distance_m": r_m,
        "hazard_channel": "negative",
        "corridor": corridor,
    }


def test_a_veto_on_the_arc_towards_the_pit_is_real_and_straight_ahead_is_false(env_info) -> None:
    env, info = env_info
    left = _record(11.0, 0.18)  # R = 15 m: the arc runs through the pit 6 m left, 12 m on
    truth = veto_truth_m(env, left, info)
    assert 8.0 < truth < 13.0 and not is_false_veto(env, left, info)
    straight = _record(11.0, 0.0)  # the same distance straight ahead: the pit on the line is 30 m on
    assert veto_truth_m(env, straight, info) > 25.0 and is_false_veto(env, straight, info)
    # without a corridor (a filter of another kind): straight ahead, from info's gap
    assert veto_truth_m(env, _record(11.0, None), info) == pytest.approx(
        info["distance_to_negative_ahead_m"]
        + env.vehicle.config.length_m
        - env.vehicle.config.rear_overhang_m
    )
    assert is_false_veto(env, _record(11.0, None), info)


def test_the_tolerances_bound_what_counts_as_false(env_info) -> None:
    env, info = env_info
    truth = veto_truth_m(env, _record(0.0, 0.18), info)
    assert not is_false_veto(env, _record(truth - 1.9, 0.18), info)  # within 2 m before the rim
    assert is_false_veto(env, _record(truth - 2.1, 0.18), info)
    # the truth is taken along the filter's corridor widened by the lateral tolerance each side
    widened = Corridor(steer_rad=0.18, wheelbase_m=2.8, half_width_m=1.2 + FALSE_VETO_LATERAL_TOLERANCE_M)
    assert env.true_hazard_distance_m(widened, info["pose"]) == truth


def test_only_vetoes_are_judged() -> None:
    decision = SafetyDecision(
        vetoed=True, hazard_distance_m=3.0, braking_distance_m=5.0, speed_mps=0.0, safe_speed_mps=1.0,
        original_action=np.zeros(2, np.float32), applied_action=np.zeros(2, np.float32),
        perception_age_s=0.0, perception_stale=False,
    )  # fmt: skip
    assert is_veto(decision) and is_veto({"vetoed": True}) and not is_veto({"vetoed": False})
    assert not is_veto(None)  # no filter
    assert not is_false_veto(None, _record(math.inf, 0.0, vetoed=False), {})  # type: ignore[arg-type]


def test_a_step_let_through_with_a_true_hazard_well_inside_r_is_a_missed_veto(env_info) -> None:
    env, info = env_info
    truth = veto_truth_m(env, _record(0.0, 0.18), info)  # the left pit along the arc, widened
    along = env.true_hazard_distance_m(_record(0.0, 0.18)["corridor"], info["pose"])  # as searched
    assert along >= truth
    passed = dict(_record(math.inf, 0.18, vetoed=False))
    assert is_missed_veto(env, {**passed, "braking_distance_m": along + FALSE_VETO_TOLERANCE_M + 0.1}, info)
    assert not is_missed_veto(
        env, {**passed, "braking_distance_m": along + FALSE_VETO_TOLERANCE_M - 0.1}, info
    )
    vetoed = _record(along, 0.18, vetoed=True, r_m=along + 10.0)
    assert not is_missed_veto(env, vetoed, info)  # it stopped for it
    assert not is_missed_veto(env, None, info)  # no filter
    # the rock on the line 8 m on: missed only by a filter that stops for positive obstacles
    straight = _record(math.inf, 0.0, vetoed=False, r_m=20.0)
    rock_m = env.true_hazard_distance_m(straight["corridor"], info["pose"], "positive")
    assert rock_m < 12.0 and not is_missed_veto(env, straight, info)  # the pit on the line is 30 m on
    assert is_missed_veto(env, straight, info, positive=True)


def test_a_vetos_error_is_the_distance_it_acted_on_minus_the_truth(env_info) -> None:
    env, info = env_info
    truth = env.true_hazard_distance_m(_record(0.0, 0.18)["corridor"], info["pose"])  # not widened
    assert truth >= veto_truth_m(env, _record(0.0, 0.18), info)
    assert veto_error_m(env, _record(truth + 1.5, 0.18), info) == pytest.approx(1.5)  # saw it late
    assert veto_error_m(env, _record(truth - 0.3, 0.18), info) == pytest.approx(-0.3)  # early
    assert veto_error_m(env, _record(truth, 0.18, vetoed=False), info) is None  # let through
    assert veto_error_m(env, _record(math.inf, 0.18), info) is None  # stale perception, no distance
    # no true obstacle along a corridor to the right: a false veto, no error to give
    assert math.isinf(veto_truth_m(env, _record(0.0, -0.3), info))
    assert veto_error_m(env, _record(5.0, -0.3), info) is None
    assert veto_error_m(env, None, info) is None  # no filter
    # a wide straight corridor that ends 0.25 m short of the left pit: widened, it takes the pit in
    # (the veto is not false), but the error is judged in the corridor as searched, whose nearest
    # true pit is the one on the line 30 m on: far beyond d, so early, not late
    wide = {**_record(11.0, 0.0), "corridor": Corridor(steer_rad=0.0, wheelbase_m=2.8, half_width_m=5.0)}
    assert not is_false_veto(env, wide, info)
    assert veto_error_m(env, wide, info) < -15.0


def test_the_largest_veto_error_skips_what_cannot_be_judged() -> None:
    assert largest_veto_error_m([-0.3, None, 1.9, math.nan, 0.07]) == 1.9
    assert largest_veto_error_m([None, math.nan]) is None and largest_veto_error_m([]) is None
    assert math.isnan(largest_veto_error_m([None], math.nan))  # a CSV cell's "no veto to judge"
    assert largest_veto_error_m([0.0], math.nan) == 0.0
    assert format_veto_error(1.9) == "+1.90" and format_veto_error(-0.34) == "-0.34"
    assert format_veto_error(None) == "-"


def test_a_tally_judges_each_step_once(env_info) -> None:
    env, info = env_info
    truth = env.true_hazard_distance_m(_record(0.0, 0.18)["corridor"], info["pose"])
    tally = VetoTally()
    steps = [
        _record(truth + 0.4, 0.18),  # a real veto, 0.4 m late
        _record(11.0, 0.0),  # a false one: the pit on the line is 30 m on
        _record(math.inf, 0.18, vetoed=False, r_m=truth + FALSE_VETO_TOLERANCE_M + 0.1),  # missed
        _record(math.inf, 0.18, vetoed=False, r_m=1.0),  # let through, nothing near
        None,  # no filter
    ]
    judged = [tally.add(env, record, info, step) for step, record in enumerate(steps, start=1)]
    assert judged == [(True, False), (True, False), (False, True), (False, False), (False, False)]
    assert tally.vetoed_steps == [1, 2] and tally.missed_steps == [3] and tally.false_vetoes == 1
    assert tally.max_error_m == pytest.approx(0.4) and len(tally.errors_m) == 2  # the false one: -18 m
    assert VetoTally().max_error_m is None
    # each veto and missed veto kept, with what it was judged on
    late, false, missed = tally.judgements
    assert [j.step for j in tally.judgements] == [1, 2, 3]
    assert (late.vetoed, false.vetoed, missed.vetoed) == (True, True, False)
    assert late.true_distance_m == truth == missed.true_distance_m and late.error_m == pytest.approx(0.4)
    assert not late.false_veto and false.false_veto and false.error_m < -15.0  # the pit on the line
    assert missed.error_m is None and missed.channel == "negative"
    assert missed.braking_distance_m == truth + FALSE_VETO_TOLERANCE_M + 0.1
    assert late.speed_mps == info["speed_mps"]  # a record without its speed: the step before's
    assert all(math.isnan(v) for v in late.proposed_action + late.applied_action)  # nor its actions
    # an onset is a veto whose step before was no veto: step 2 held the brake step 1 began
    assert (late.onset, false.onset, missed.onset) == (True, False, False)
    assert tally.add(env, _record(truth - 0.1, 0.18), info, 6) == (True, False)
    assert tally.judgements[-1].onset and tally.onset_errors_m == pytest.approx([0.4, -0.1])
    assert tally.veto_events == 2  # steps 1-2 and step 6


def test_a_judgement_keeps_the_filters_speed_and_actions(env_info) -> None:
    env, info = env_info
    corridor = Corridor(steer_rad=0.18, wheelbase_m=2.8, half_width_m=1.2)
    decision = SafetyDecision(
        vetoed=True, hazard_distance_m=9.0, braking_distance_m=10.5, speed_mps=6.9, safe_speed_mps=5.0,
        original_action=np.array([1.0, 0.5], np.float32), applied_action=np.array([-1.0, 0.5], np.float32),
        perception_age_s=0.0, perception_stale=False, hazard_channel="negative", corridor=corridor,
    )  # fmt: skip
    tally = VetoTally()
    assert tally.add(env, decision, info, 7) == (True, False)
    (judged,) = tally.judgements
    assert judged.speed_mps == 6.9 and judged.proposed_action == (1.0, 0.5)
    assert judged.applied_action == (-1.0, 0.5) and judged.step == 7
    assert judged.error_m == pytest.approx(veto_error_m(env, decision, info))
    assert tally.add(env, decision.as_dict(), info, 8) == (True, False)  # info["safety"] alike
    assert judged.onset and tally.judgements[1] == dataclasses.replace(judged, step=8, onset=False)  # held
