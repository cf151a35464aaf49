"""Registered ids keep Gymnasium's promise: a version replaces the one before it of the same task,
another task has its own name, and an old id of a renamed task warns once and builds the same env."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import gymnasium as gym
import pytest
from gymnasium.envs.registration import find_highest_version, load_env_creator, parse_env_id

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.envs.scenarios import OffroadNavV2Env
from negobs_gym.registration import ALIASES, ENV_SPECS, SCENES

IDS = [spec[0] for spec in ENV_SPECS]


def _newer_version(env_id: str) -> int | None:
    """The highest version of ``env_id``'s name among the registered ids, where above its own."""
    ns, name, version = parse_env_id(env_id)
    highest = max(parse_env_id(i)[2] for i in IDS if parse_env_id(i)[:2] == (ns, name))
    return highest if highest > version else None


def _make_recording(env_id: str) -> tuple[gym.Env, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = gym.make(env_id)
    return env, [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]


@pytest.mark.parametrize("env_id", IDS)
def test_an_id_warns_out_of_date_only_when_its_own_task_has_a_newer_version(env_id: str) -> None:
    env, deprecations = _make_recording(env_id)
    env.close()
    newer = _newer_version(env_id)
    if newer is None:  # the current version of its task, e.g. OffroadNav-v1 and OffroadTrack-v0
        assert deprecations == []
    else:  # e.g. OffroadNav-v0: upgrade to OffroadNav-v1, the same task
        assert len(deprecations) == 1
        assert f"{env_id} is out of date" in deprecations[0] and f"version `v{newer}`" in deprecations[0]


def test_the_offroad_tasks_have_their_own_names_and_versions() -> None:
    assert find_highest_version("negobs_gym", "OffroadNav") == 1  # an alias adds no OffroadNav-v2
    assert find_highest_version("negobs_gym", "OffroadTrack") == 0
    for old_id, new_id, _ in ALIASES:
        assert old_id in gym.registry and old_id not in IDS and new_id in IDS
        assert gym.spec(old_id).id == new_id  # the alias holds the new id's spec
        assert SCENES[old_id] == SCENES[new_id]


# a fresh process, with Python's default warning filters: they show a DeprecationWarning only where
# it points at __main__ (the caller's line), and the alias's warning is once per process
_ALIAS_RUN = """
import json, warnings
import gymnasium as gym, negobs_gym
from negobs_gym.envs import make_env
made = []
env = gym.make({old!r})
made.append(env.spec.id)
env = gym.make({old!r})  # another line: Python's per-line "default" action would show it again
made.append(env.spec.id)
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    for make in (gym.make, make_env):
        made.append(make({old!r}).spec.id)
print(json.dumps([made, [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]]))
"""


@pytest.mark.parametrize(("old_id", "new_id"), [alias[:2] for alias in ALIASES])
def test_an_old_id_warns_once_per_process_at_the_callers_line(old_id: str, new_id: str) -> None:
    done = subprocess.run(
        [sys.executable, "-c", _ALIAS_RUN.format(old=old_id)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    made, later = json.loads(done.stdout.strip().splitlines()[-1])
    assert made == [new_id] * 4 and later == []
    shown = [line for line in done.stderr.splitlines() if "DeprecationWarning" in line]
    assert len(shown) == 1
    first_make = _ALIAS_RUN.splitlines().index("env = gym.make({old!r})") + 1
    assert shown[0].startswith(f"<string>:{first_make}: DeprecationWarning: {old_id} is now {new_id}")


@pytest.mark.parametrize(("old_id", "new_id"), [alias[:2] for alias in ALIASES])
def test_an_old_id_builds_the_new_env_with_no_version_warning(old_id: str, new_id: str) -> None:
    env, deprecations = _make_recording(old_id)
    env.close()
    assert env.spec.id == new_id and isinstance(env.unwrapped, OffroadNavV2Env)
    assert not [message for message in deprecations if "out of date" in message]
    assert load_env_creator(gym.spec(old_id).entry_point).__mro__[1] is load_env_creator(
        gym.spec(new_id).entry_point
    )  # the new id's class, under a subclass that only warns
