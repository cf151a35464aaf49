"""Was a safety-filter veto for a real hazard, and did it miss one? Judged on the ground truth.

The filter (:class:`~negobs_gym.safety.BrakingSafetyFilter`) vetoes when the nearest detected
hazard along the corridor of the proposed steering is closer than R(v) (paper N, Eq. 18). A veto
is *false* when no true obstacle of the channel it came from lies in that corridor within the
distance it acted on plus a tolerance: the detectors reported what is not there. A step is a
*missed veto* when the filter let the action through while a true obstacle lay in that corridor
more than the same tolerance inside R(v): the detectors did not report it, or reported it farther
than it is. A veto's *error* is how much farther the filter put its hazard than the truth along the
same corridor: positive when it braked later than the ground truth would have made it. The scenario
runner and the campaigns' driven episodes count all three with these functions.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from negobs_gym.envs.base import NegObsEnv
from negobs_gym.eval.campaign import format_row
from negobs_gym.safety.corridor import Corridor

__all__ = [
    "FALSE_VETO_LATERAL_TOLERANCE_M",
    "FALSE_VETO_TOLERANCE_M",
    "VETO_COLUMNS",
    "VetoJudgement",
    "VetoTally",
    "format_veto_error",
    "is_false_veto",
    "is_missed_veto",
    "is_veto",
    "largest_veto_error_m",
    "veto_error_m",
    "veto_rows",
    "veto_truth_m",
]

#: A veto is false when the nearest true obstacle of the vetoing channel (negative, or positive
#: when the filter stopped for the positive channel) along the filter's corridor, widened by
#: :data:`FALSE_VETO_LATERAL_TOLERANCE_M`, is farther than the distance the filter acted on plus
#: this [m] (the detected near edge may lie up to a ring gap before the rim; the paper gives no
#: such figure, 2 m is the braking benchmark's tolerance).
FALSE_VETO_TOLERANCE_M = 2.0
#: Each side of the corridor is widened by this for that check [m]: a grid cell the filter reads
#: may lie up to its diagonal (0.28 m on paper N's 20 cm grid, Sec. 4) outside the outline the
#: detector drew, and that outline a cell or so outside the true rim (engineering choice).
FALSE_VETO_LATERAL_TOLERANCE_M = 0.5


def _field(record: Mapping[str, Any] | Any, name: str) -> Any:
    """A field of a decision record: ``info["safety"]`` (a dict) or a ``SafetyDecision``; None
    where the record has none (a filter of another kind)."""
    return record.get(name) if isinstance(record, Mapping) else getattr(record, name, None)


def is_veto(record: Mapping[str, Any] | Any | None) -> bool:
    """Whether a step's decision record (``info.get("safety")``; None: no filter) is a veto."""
    return record is not None and bool(_field(record, "vetoed"))


def veto_truth_m(env: NegObsEnv, record: Mapping[str, Any] | Any, info_before: Mapping[str, Any]) -> float:
    """Ground truth of the hazard distance a decision acted on, from the rear axle [m] (inf: none).

    Along the decision's corridor (``record["corridor"]``) widened by
    :data:`FALSE_VETO_LATERAL_TOLERANCE_M`, laid out from the pose where the filter decided
    (``info_before``: the info of the reset or step before), against the true outlines of the
    obstacles of the decision's channel (:meth:`NegObsEnv.true_hazard_distance_m`). A record
    without a corridor is judged straight ahead in the wheels' strip (``info_before``'s
    ``distance_to_<channel>_ahead_m``).
    """
    corridor: Corridor | None = _field(record, "corridor")
    if corridor is not None:
        widen_m = FALSE_VETO_LATERAL_TOLERANCE_M
        corridor = dataclasses.replace(corridor, half_width_m=corridor.half_width_m + widen_m)
    return _truth_m(env, corridor, info_before, _field(record, "hazard_channel") or "negative")


def _truth_m(env: NegObsEnv, corridor: Corridor | None, before: Mapping[str, Any], channel: str) -> float:
    """True distance from the rear axle to ``channel``'s nearest obstacle along ``corridor`` at the
    pose of ``before``; straight ahead in the wheels' strip when ``corridor`` is None."""
    if corridor is None:
        car = env.vehicle.config
        return float(before[f"distance_to_{channel}_ahead_m"]) + car.length_m - car.rear_overhang_m
    return env.true_hazard_distance_m(corridor, before["pose"], channel)


def is_false_veto(env: NegObsEnv, record: Mapping[str, Any] | Any, info_before: Mapping[str, Any]) -> bool:
    """The decision vetoed, and no true obstacle lies within the distance it acted on plus
    :data:`FALSE_VETO_TOLERANCE_M` along its corridor (:func:`veto_truth_m`). A veto for missing or
    stale perception acted on no distance (d = inf) and is never false."""
    if not is_veto(record):
        return False
    acted_on_m = float(_field(record, "hazard_distance_m"))
    return veto_truth_m(env, record, info_before) > acted_on_m + FALSE_VETO_TOLERANCE_M


def veto_error_m(
    env: NegObsEnv, record: Mapping[str, Any] | Any | None, info_before: Mapping[str, Any]
) -> float | None:
    """The distance a veto acted on minus the true distance to the nearest obstacle of its channel
    along the corridor it searched, not widened [m]: > 0 when the filter put the hazard farther
    than it is (it braked later than the truth would have made it), < 0 when nearer (the detected
    near edge before the rim). Not widened as for :func:`veto_truth_m`: a pit just beside the
    corridor, which the widening takes in, is not the hazard the filter braked for and would read
    as lateness. None when the record is no veto, the veto acted on no distance (missing or stale
    perception) or no true obstacle lies in the corridor (a false veto, or one for cells at its
    edge). A record without a corridor is judged straight ahead in the wheels' strip."""
    if not is_veto(record):
        return None
    acted_on_m = float(_field(record, "hazard_distance_m"))
    if not math.isfinite(acted_on_m):
        return None
    channel = _field(record, "hazard_channel") or "negative"
    return _error_m(acted_on_m, _truth_m(env, _field(record, "corridor"), info_before, channel))


def _error_m(acted_on_m: float, truth_m: float) -> float | None:
    """A veto's error: what it acted on minus the truth (None unless both are finite)."""
    return acted_on_m - truth_m if math.isfinite(acted_on_m) and math.isfinite(truth_m) else None


def largest_veto_error_m(errors: Iterable[float | None], missing: float | None = None) -> float | None:
    """The largest of ``errors`` (:func:`veto_error_m` per veto, or an episode's largest each, as a
    campaign CSV holds them), skipping None and NaN (no veto to judge); ``missing`` when none is
    left (None; a CSV cell takes NaN)."""
    return max((float(e) for e in errors if e is not None and not math.isnan(e)), default=missing)


def format_veto_error(error: float | None) -> str:
    """A veto error as the result lines print it: signed, in cm steps (``+1.90``), ``-`` for None."""
    return "-" if error is None else f"{error:+.2f}"


def is_missed_veto(
    env: NegObsEnv,
    record: Mapping[str, Any] | Any | None,
    info_before: Mapping[str, Any],
    *,
    positive: bool = False,
) -> bool:
    """The filter decided the step and let the action through, while a true obstacle lay along the
    corridor it searched (not widened) more than :data:`FALSE_VETO_TOLERANCE_M` inside R(v) at
    the decision's speed (``braking_distance_m``): a hazard it should have stopped for.

    Negative obstacles always; positive ones too with ``positive`` (a filter that stops for the
    positive channel, ``SafetyFilterConfig.stop_for_positive``). A record without a corridor is
    judged straight ahead in the wheels' strip. No record (no filter): False.
    """
    if record is None or is_veto(record):
        return False
    return _inside_braking_distance(_nearest_truth(env, record, info_before, positive)[0], record)


def _nearest_truth(
    env: NegObsEnv, record: Mapping[str, Any] | Any, info_before: Mapping[str, Any], positive: bool
) -> tuple[float, str]:
    """The nearest true obstacle along the decision's corridor as searched (negative; positive too
    with ``positive``): its distance [m] (inf: none) and channel."""
    channels = ("negative", "positive") if positive else ("negative",)
    corridor = _field(record, "corridor")
    return min((_truth_m(env, corridor, info_before, channel), channel) for channel in channels)


def _inside_braking_distance(truth_m: float, record: Mapping[str, Any] | Any) -> bool:
    """A true obstacle more than :data:`FALSE_VETO_TOLERANCE_M` inside the decision's R(v)."""
    return truth_m + FALSE_VETO_TOLERANCE_M < float(_field(record, "braking_distance_m"))


@dataclass(frozen=True)
class VetoJudgement:
    """One veto or missed veto judged on the ground truth (a row of a campaign's ``vetoes.csv``).

    Attributes:
        step: The episode's step (1-based) the filter decided.
        vetoed: True: a veto; False: a missed veto (:func:`is_missed_veto`).
        speed_mps: The forward speed the filter decided at (the record's ``speed_mps``; the step
            before's ``info["speed_mps"]`` for a record without one).
        braking_distance_m: R(v) at that speed (paper N, Eq. 18).
        hazard_distance_m: The distance the filter acted on (inf: nothing detected in the
            corridor, or missing or stale perception).
        true_distance_m: The nearest true obstacle of ``channel`` along the corridor as searched,
            not widened (inf: none): what :func:`veto_error_m` and :func:`is_missed_veto` compare
            with.
        channel: The veto's hazard channel (``negative`` when it gave none); for a missed veto the
            channel of the nearest true obstacle.
        false_veto: :func:`is_false_veto`.
        perception_stale: The filter braked for missing or stale perception.
        proposed_action: The driver's action (longitudinal, steering; NaN where the record has none).
        applied_action: The action the env received.
        onset: A veto whose step before was not vetoed: the filter's decision to start braking
            (a run of consecutive vetoes is one braking event; the ones after it hold the brake).
    """

    step: int
    vetoed: bool
    speed_mps: float
    braking_distance_m: float
    hazard_distance_m: float
    true_distance_m: float
    channel: str
    false_veto: bool
    perception_stale: bool
    proposed_action: tuple[float, float]
    applied_action: tuple[float, float]
    onset: bool = False

    @property
    def error_m(self) -> float | None:
        """:func:`veto_error_m` of a veto (None for a missed veto, d = inf or no true obstacle)."""
        return _error_m(self.hazard_distance_m, self.true_distance_m) if self.vetoed else None


def _action(record: Mapping[str, Any] | Any, name: str) -> tuple[float, float]:
    action = _field(record, name)
    return (math.nan, math.nan) if action is None else (float(action[0]), float(action[1]))


@dataclass
class VetoTally:
    """One episode's filtered steps judged on the ground truth, step by step (:meth:`add`): each
    veto and missed veto as a :class:`VetoJudgement`, and from them the vetoed and missed steps,
    the false vetoes and each judged veto's error. The scenario runner and the campaigns' driven
    episodes keep one per episode.

    ``positive``: the filter stops for positive obstacles too (missed vetoes count them).
    """

    positive: bool = False
    judgements: list[VetoJudgement] = field(default_factory=list)

    def add(
        self,
        env: NegObsEnv,
        record: Mapping[str, Any] | Any | None,
        info_before: Mapping[str, Any],
        step: int,
    ) -> tuple[bool, bool]:
        """Judge ``step``'s decision record (``info.get("safety")``; None: no filter) made at the
        pose of ``info_before``; returns (vetoed, missed veto)."""
        if record is None:
            return False, False
        vetoed = is_veto(record)
        if vetoed:
            channel = _field(record, "hazard_channel") or "negative"
            truth_m = _truth_m(env, _field(record, "corridor"), info_before, channel)
            false_veto = is_false_veto(env, record, info_before)
        else:
            truth_m, channel = _nearest_truth(env, record, info_before, self.positive)
            false_veto = False
            if not _inside_braking_distance(truth_m, record):  # let through, rightly
                return False, False
        speed_mps = _field(record, "speed_mps")
        last = self.judgements[-1] if self.judgements else None
        held = last is not None and last.vetoed and last.step == step - 1
        self.judgements.append(
            VetoJudgement(
                step=step,
                vetoed=vetoed,
                speed_mps=float(info_before["speed_mps"] if speed_mps is None else speed_mps),
                braking_distance_m=float(_field(record, "braking_distance_m")),
                hazard_distance_m=float(_field(record, "hazard_distance_m")),
                true_distance_m=float(truth_m),
                channel=channel,
                false_veto=false_veto,
                perception_stale=bool(_field(record, "perception_stale")),
                proposed_action=_action(record, "original_action"),
                applied_action=_action(record, "applied_action"),
                onset=vetoed and not held,
            )
        )
        return vetoed, not vetoed

    @property
    def vetoed_steps(self) -> list[int]:
        """The steps whose action the filter replaced."""
        return [j.step for j in self.judgements if j.vetoed]

    @property
    def missed_steps(self) -> list[int]:
        """The steps the filter let through with a true hazard well inside R(v)."""
        return [j.step for j in self.judgements if not j.vetoed]

    @property
    def false_vetoes(self) -> int:
        """Vetoes with no true obstacle where the filter saw its hazard."""
        return sum(j.false_veto for j in self.judgements)

    @property
    def errors_m(self) -> list[float]:
        """Each judged veto's error (:attr:`VetoJudgement.error_m`), in step order."""
        return [e for e in (j.error_m for j in self.judgements) if e is not None]

    @property
    def onset_errors_m(self) -> list[float]:
        """The judged errors of the onset vetoes (:attr:`VetoJudgement.onset`) alone: where each
        braking event began, against the truth."""
        return [e for e in (j.error_m for j in self.judgements if j.onset) if e is not None]

    @property
    def veto_events(self) -> int:
        """Braking events: runs of consecutive vetoed steps, one per onset veto."""
        return sum(j.onset for j in self.judgements)

    @property
    def max_error_m(self) -> float | None:
        """The largest judged veto error (None: no veto to judge)."""
        return largest_veto_error_m(self.errors_m)


#: ``vetoes.csv`` of the braking and policy campaigns and of ``negobs scenario run --out``: one row
#: per veto (``kind`` = ``veto``) and per missed veto (``missed``) of the filtered episodes, judged
#: on the ground truth (:class:`VetoJudgement`; ``error_m`` NaN where there is none to give;
#: ``onset`` 1 for a veto that began a braking event)
VETO_COLUMNS = (
    "episode",
    "filter",
    "seed",
    "step",
    "kind",
    "onset",
    "speed_mps",
    "braking_distance_m",
    "hazard_distance_m",
    "true_distance_m",
    "error_m",
    "channel",
    "false_veto",
    "perception_stale",
    "proposed_longitudinal",
    "proposed_steer",
    "applied_longitudinal",
    "applied_steer",
)


def veto_rows(key: str, filter_label: str, seed: int, judgements: Sequence[VetoJudgement]) -> list[str]:
    """An episode's vetoes and missed vetoes (a :class:`VetoTally`'s ``judgements``) as rows
    of :data:`VETO_COLUMNS`."""
    return [
        format_row(
            [
                *(key, filter_label, seed, j.step, "veto" if j.vetoed else "missed", j.onset, j.speed_mps),
                *(j.braking_distance_m, j.hazard_distance_m, j.true_distance_m),
                *(math.nan if j.error_m is None else j.error_m, j.channel, j.false_veto, j.perception_stale),
                *j.proposed_action,
                *j.applied_action,
            ]
        )
        for j in judgements
    ]
