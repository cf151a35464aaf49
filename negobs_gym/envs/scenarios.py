"""The registered envs: each a :class:`~negobs_gym.envs.base.NegObsEnv` naming its scenario spec.

The specs are TOML files in ``negobs_gym/spec/scenes`` (``negobs scenario show NAME``). The
shared parts of every manual below: the action is ``Box(-1, 1, (2,), float32)`` — ``action[0]``
longitudinal (> 0 throttle, < 0 brake, -1 full brake), ``action[1]`` steering (+1 = full left,
35 deg) at 10 Hz with 12 physics sub-steps; the observation is ``Dict(grid, state)``:

| key | space | content |
|---|---|---|
| ``grid`` | ``Box(0, 1, (4, 36, 16), uint8)`` | channels negative, positive, traversable, observed |
| ``state`` | ``Box(float32, (5,))`` | speed, yaw rate, steering angle, goal x, goal y |

The grid is the 20 cm vehicle-centred grid (25.6 m ahead, 3.2 m back, 6.4 m each side),
max-pooled 4 x 4. The state is in SI units, clipped to speed +-15 m/s, yaw rate +-3 rad/s,
steering +-1 rad and a goal vector (vehicle frame) of +-300 m.

Arguments of every env: ``overrides`` (single settings of the env's scenario changed, as the
commands' ``--set`` paths: ``{"observation.source": "oracle", "episode.time_limit_s": 20}`` or
``["start.speed_mps=[5.0, 7.0]"]``), ``render_mode`` (``"rgb_array"`` or ``"human"``) and
``scenario`` (another spec, name or TOML path).

Note on v0 builds: since the spec layer every env truncates at its spec's time limit itself
(same limits as before, now also when built directly) and reset casts one LiDAR frame instead of
two, so sensor-noise draws, and with them detector-grid rollouts, differ from earlier v0 builds.
"""

from __future__ import annotations

from negobs_gym.envs.base import NegObsEnv

__all__ = [
    "BrakingEnv",
    "BrakingV0Env",
    "OffroadNavEnv",
    "OffroadNavV1Env",
    "OffroadNavV2Env",
    "OffroadTrackEnv",
    "PaperTStraightEnv",
    "TrenchCrossingEnv",
]


class BrakingEnv(NegObsEnv):
    """Stop before a ditch at 25 km/h (``negobs_gym/Braking-v1``, spec ``braking_v1``).

    ## Description
    A straight rough track; a 1.0 m (along) x 3.0 m (across) x 0.8 m deep ditch, centred on the
    track, lies 20-40 m ahead (uniform, from the env's generator). The vehicle starts at 25 km/h,
    paper N §4's test speed. The task is to stop before the ditch; the Eq. 18 braking distance at
    25 km/h is R = 10.52 m, so a driver must brake while the ditch is still about 10 m away.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``, see :mod:`negobs_gym.envs.scenarios`.

    ## Observation Space
    ``Dict(grid, state)`` as in the table of :mod:`negobs_gym.envs.scenarios`; the grid comes
    from paper N's and paper T's detectors on the reduced rig.

    ## Rewards
    ``progress`` +1 per metre along the track; ``negative_entry`` -100 once; ``collision`` -100;
    ``time`` -0.01 per step; ``goal`` +50 at the far end; ``stopped`` +50 once, when the car has
    stood still (< 0.1 m/s) for 1 s with the ditch at most 11 m ahead of its bumper and without
    having entered it. Terms by name in ``info["rewards"]``.

    ## Starting State
    On the centre line at the start of the track, heading along it, 25 km/h after 0.25 s of
    suspension settling.

    ## Episode End
    Terminates on entering a negative obstacle, trapped, collision, rollover, reaching the goal,
    or stopping (standing 1 s); truncates after 15 s (150 steps), also when built directly.

    ## Arguments
    ``overrides``, ``render_mode``, ``scenario`` (see :mod:`negobs_gym.envs.scenarios`).

    ## Version History
    - v1: rewards and ends on stopping before the ditch (``stopped`` term and rule); the time
      limit is the env's own, so an overridden ``episode.time_limit_s`` is honoured.
    - v0: no reward for stopping (stopping only ended by the 15 s limit); terrain draws as v1.
      See the module note on v0 builds.
    """

    default_scenario = "braking_v1"


class BrakingV0Env(NegObsEnv):
    """``negobs_gym/Braking-v0`` (spec ``braking_v0``): :class:`BrakingEnv` without the ``stopped``
    reward and rule, kept for results reported on v0. See :class:`BrakingEnv` (manual and
    version history)."""

    default_scenario = "braking_v0"


class OffroadNavEnv(NegObsEnv):
    """Reach the goal along a winding off-road course (``negobs_gym/OffroadNav-v0``).

    ## Description
    A 120 m winding track (bends alternating left and right, heading 20-40 deg off +Y) with a bank
    on the left and a verge on the right; six negative obstacles (paper N's pit sizes +-20 %,
    1-2 m ditches, craters; 0.3-1.5 m deep) and four positive ones (rocks, boxes, mounds) within
    2 m of the centre line, laid out from the episode's seed.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``, see :mod:`negobs_gym.envs.scenarios`.

    ## Observation Space
    ``Dict(grid, state)`` as in the table of :mod:`negobs_gym.envs.scenarios`.

    ## Rewards
    ``progress`` +1 per metre; ``negative_entry`` -100; ``collision`` -100; ``time`` -0.01 per
    step; ``goal`` +50 on reaching the goal (3 m radius, 5 m before the end of the track).

    ## Starting State
    Standing on the centre line at the start, heading along the track.

    ## Episode End
    Terminates on entering a negative obstacle, trapped, collision, rollover or the goal;
    truncates after 60 s (600 steps).

    ## Arguments
    ``overrides``, ``render_mode``, ``scenario`` (see :mod:`negobs_gym.envs.scenarios`).

    ## Version History
    - v0: initial version (same terrain, rewards and limit since the spec layer; see the module
      note on v0 builds).
    """

    default_scenario = "offroad_nav_v0"


class OffroadNavV1Env(NegObsEnv):
    """``negobs_gym/OffroadNav-v1`` (spec ``offroad_nav_v1``): :class:`OffroadNavEnv`'s course and
    task for learned policies.

    Changes against v0: ``state`` gains the route, the centre-line points 5, 10 and 15 m ahead in
    the vehicle frame (``ObservationConfig.route_points_m``; 11 values: speed, yaw rate, steering,
    goal x, goal y, then x, y of each route point); ``grid`` keeps the ``negative`` and ``positive``
    channels, ``Box(0, 1, (2, 36, 16), uint8)``; being trapped costs -50 once
    (``RewardConfig.trapped``); standing still for 1 s ends the episode (rule ``stopped``), and
    costs -50 when a negative obstacle is at most 11 m ahead (``RewardConfig.stopped``: go around
    it; stopping is the safety filter's job); an oracle grid (``source="oracle"``, ablations and
    training) shows obstacles only within 14 m, as far as the detectors find them reliably
    (``ObservationConfig.oracle_range_m``). Terrain draws, the other rewards and rules and the
    60 s limit are v0's. Why: docs/training.md.
    """

    default_scenario = "offroad_nav_v1"


class OffroadTrackEnv(NegObsEnv):
    """Stay on the track to the goal (``negobs_gym/OffroadTrack-v0``, spec ``offroad_nav_v2``):
    :class:`OffroadNavV1Env`'s course where leaving the track ends the episode. A task of its own
    (the old id ``negobs_gym/OffroadNav-v2`` is an alias that warns once).

    Changes against OffroadNav-v1: rule ``off_track`` terminates the episode when the car's centre
    is farther from the centre line than half the 6 m track width. On v1 the right side is open
    ground and the obstacles lie within 2 m of the centre line, so a policy could reach the goal
    driving beside the track without meeting one (the policies trained on v1 do:
    docs/notebook/training_studies.md). Every obstacle a car cannot drive over leaves at least 1.5 m
    between its side and one edge of the track (200 courses measured), so the 2 m wide car passes it
    with its centre on the track. Leaving the track costs 100 (``RewardConfig.off_track``), as an
    entry does: without it PPO learns to leave the track rather than risk an obstacle
    (docs/notebook/training_studies.md). Terrain draws, observation, the other rewards and rules and
    the 60 s limit are v1's.
    """

    default_scenario = "offroad_nav_v2"


#: The class's name while the task was registered as OffroadNav-v2; kept for code that names it.
OffroadNavV2Env = OffroadTrackEnv


class TrenchCrossingEnv(NegObsEnv):
    """A trench too wide to cross (``negobs_gym/TrenchCrossing-v0``).

    ## Description
    A straight rough 6 m track; 30 m ahead a 3 m long, 1 m deep trench spans the track and both
    verges. A full-size car that drives in is trapped.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``, see :mod:`negobs_gym.envs.scenarios`.

    ## Observation Space
    ``Dict(grid, state)`` as in the table of :mod:`negobs_gym.envs.scenarios`.

    ## Rewards
    ``progress`` +1 per metre; ``negative_entry`` -100; ``collision`` -100; ``time`` -0.01 per
    step; ``goal`` +50 (unreachable past the trench).

    ## Starting State
    Standing on the centre line at the start, heading along the track.

    ## Episode End
    Terminates on entering a negative obstacle, trapped, collision, rollover or the goal;
    truncates after 30 s (300 steps).

    ## Arguments
    ``overrides``, ``render_mode``, ``scenario`` (see :mod:`negobs_gym.envs.scenarios`).

    ## Version History
    - v0: initial version (same terrain, rewards and limit since the spec layer; see the module
      note on v0 builds).
    """

    default_scenario = "trench_crossing_v0"


class PaperTStraightEnv(NegObsEnv):
    """Paper T's straight track between two earth banks (``negobs_gym/PaperTStraight-v0``).

    ## Description
    An 80 m straight track with 1.5 m grass verges and 0.8 m earth banks on both sides, the
    scene paper T's boundary detection is shown on; drive to the end.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``, see :mod:`negobs_gym.envs.scenarios`.

    ## Observation Space
    ``Dict(grid, state)`` as in the table of :mod:`negobs_gym.envs.scenarios`.

    ## Rewards
    ``progress`` +1 per metre; ``negative_entry`` -100; ``collision`` -100; ``time`` -0.01 per
    step; ``goal`` +50 at the far end.

    ## Starting State
    Standing on the centre line at the start, heading along the track.

    ## Episode End
    Terminates on entering a negative obstacle, trapped, collision, rollover or the goal;
    truncates after 30 s (300 steps).

    ## Arguments
    ``overrides``, ``render_mode``, ``scenario`` (see :mod:`negobs_gym.envs.scenarios`).

    ## Version History
    - v0: initial version (same terrain, rewards and limit since the spec layer; see the module
      note on v0 builds).
    """

    default_scenario = "paper_t_straight_v0"
