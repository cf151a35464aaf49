"""SB3 callbacks of :func:`negobs_gym.policies.training.train`: progress bar, evaluation, checkpoints.

SB3's own ``progress_bar=True`` needs ``rich`` besides tqdm, and its ``EvalCallback`` reports the
return only, so these three are small callbacks of our own. Files are written atomically.
"""

from __future__ import annotations

import logging
import math
import re
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback
from tqdm.auto import tqdm

from negobs_gym.core.files import write_atomic, write_text_atomic
from negobs_gym.eval.campaign import format_row, read_csv
from negobs_gym.eval.vetoes import largest_veto_error_m

log = logging.getLogger(__name__)

__all__ = [
    "EVAL_COLUMNS",
    "CheckpointCallback",
    "CriticWarmupCallback",
    "EvalCallback",
    "ProgressBarCallback",
    "latest_checkpoint",
]

#: Columns of ``eval.csv``, one row per evaluation (sums over its episodes, progress a mean);
#: ``off_track`` counts the episodes with a step off the track (on OffroadTrack-v0 the rule ends them);
#: ``false_vetoes`` / ``missed_vetoes`` as :mod:`negobs_gym.eval.vetoes` judges the filter's steps,
#: ``max_veto_error_m`` the largest veto error of the evaluation's episodes (NaN: no veto to judge).
EVAL_COLUMNS = (
    "step",
    "episodes",
    "goal",
    "entries",
    "collisions",
    "rollovers",
    "trapped",
    "off_track",
    "mean_progress_m",
    "vetoes",
    "false_vetoes",
    "missed_vetoes",
    "max_veto_error_m",
    "cost",
    "wall_s",
)

_CHECKPOINT = re.compile(r"^model_(\d+)\.zip$")


class ProgressBarCallback(BaseCallback):
    """A tqdm bar over env steps (starts at the model's step count when resuming)."""

    def __init__(self, total_steps: int, enabled: bool = True) -> None:
        super().__init__()
        self.total_steps = total_steps
        self.enabled = enabled
        self._bar: Any = None

    def _on_training_start(self) -> None:
        self._bar = tqdm(
            total=self.total_steps, initial=self.num_timesteps, unit="step", disable=not self.enabled
        )

    def _on_step(self) -> bool:
        self._bar.update(self.num_timesteps - self._bar.n)
        return True

    def _on_training_end(self) -> None:
        self._bar.close()


def save_model_atomic(model: Any, path: Path) -> Path:
    """``model.save`` written atomically (never a partial zip, :func:`write_atomic`)."""
    return write_atomic(path, model.save)


def latest_checkpoint(directory: Path) -> Path | None:
    """The ``model_<steps>.zip`` with the most steps in ``directory``, or None."""
    found = [(int(m.group(1)), p) for p in directory.glob("model_*.zip") if (m := _CHECKPOINT.match(p.name))]
    return max(found)[1] if found else None


class CheckpointCallback(BaseCallback):
    """Saves ``<directory>/model_<steps>.zip`` every ``every`` env steps (atomically)."""

    def __init__(self, directory: Path, every: int) -> None:
        super().__init__()
        self.directory = Path(directory)
        self.every = every
        self._next = 0

    def _on_training_start(self) -> None:
        self._next = (self.num_timesteps // self.every + 1) * self.every

    def _on_step(self) -> bool:
        if self.num_timesteps >= self._next:
            path = save_model_atomic(self.model, self.directory / f"model_{self.num_timesteps}.zip")
            log.debug("checkpoint %s", path)
            self._next = (self.num_timesteps // self.every + 1) * self.every
        return True


class EvalCallback(BaseCallback):
    """Every ``every`` env steps (and at the end; at the start too with ``at_start``) runs
    ``evaluate(model)`` and appends a row to ``csv``.

    ``evaluate`` returns the per-episode metrics of the episode loop
    (:meth:`negobs_gym.eval.episode.EpisodeResult.metrics`). Rows of ``csv`` from an earlier
    run at fewer steps are kept (resume); the file is rewritten atomically each time.
    """

    def __init__(
        self,
        evaluate: Callable[[Any], Sequence[dict[str, Any]]],
        csv: Path,
        every: int,
        at_start: bool = False,
    ) -> None:
        super().__init__()
        self.at_start = at_start
        self.evaluate = evaluate
        self.csv = Path(csv)
        self.every = every
        self._next = 0
        self._last = -1
        self._rows: list[str] = []
        self.last: dict[str, float] = {}

    def _on_training_start(self) -> None:
        self._next = (self.num_timesteps // self.every + 1) * self.every
        self._rows = []
        if self.csv.exists():
            for row in read_csv(self.csv):
                if int(row["step"]) <= self.num_timesteps:  # a column the run's version lacked stays empty
                    self._rows.append(format_row(row.get(c, "") for c in EVAL_COLUMNS))
        if self.at_start:
            self.run()

    def _on_step(self) -> bool:
        if self.num_timesteps >= self._next:
            self.run()
            self._next = (self.num_timesteps // self.every + 1) * self.every
        return True

    def _on_training_end(self) -> None:
        if self._last != self.num_timesteps:
            self.run()

    def run(self) -> dict[str, float]:
        """Evaluate now; the row written (also kept in :attr:`last`)."""
        start = time.perf_counter()
        episodes = self.evaluate(self.model)
        n = len(episodes)
        row = {
            "step": self.num_timesteps,
            "episodes": n,
            "goal": sum(bool(e["goal"]) for e in episodes),
            "entries": sum(bool(e["entered"]) for e in episodes),
            "collisions": sum(bool(e["collision"]) for e in episodes),
            "rollovers": sum(bool(e["rollover"]) for e in episodes),
            "trapped": sum(bool(e["trapped"]) for e in episodes),
            "off_track": sum(int(e["off_track_steps"]) > 0 for e in episodes),
            "mean_progress_m": sum(float(e["progress_m"]) for e in episodes) / max(n, 1),
            "vetoes": sum(int(e["vetoes"]) for e in episodes),
            "false_vetoes": sum(int(e["false_vetoes"]) for e in episodes),
            "missed_vetoes": sum(int(e["missed_vetoes"]) for e in episodes),
            "max_veto_error_m": largest_veto_error_m((e["max_veto_error_m"] for e in episodes), math.nan),
            "cost": sum(float(e["cost"]) for e in episodes),
            "wall_s": time.perf_counter() - start,
        }
        self._rows.append(format_row(row[c] for c in EVAL_COLUMNS))
        write_text_atomic(self.csv, "\n".join([",".join(EVAL_COLUMNS), *self._rows]) + "\n")
        for key in ("goal", "entries", "collisions", "off_track", "mean_progress_m", "vetoes", "cost"):
            self.logger.record(f"eval/{key}", row[key])
        log.info(
            "eval at %d steps: goal %d/%d, entries %d, collisions %d, progress %.1f m, vetoes %d",
            *(row[k] for k in ("step", "goal", "episodes", "entries", "collisions")),
            *(row[k] for k in ("mean_progress_m", "vetoes")),
        )
        self._last = self.num_timesteps
        self.last = {k: float(v) for k, v in row.items()}
        return row


class CriticWarmupCallback(BaseCallback):
    """Freezes everything but the value function for the updates of the first ``steps`` env steps.

    SB3's PPO updates right after each rollout, so the choice is made at each rollout's end from
    the step count: a resumed run inside the warm-up freezes again, one past it does not. Frozen
    parameters get no gradient, so Adam leaves them (and their moments) as they are.
    """

    #: Parameter name prefixes of an SB3 ``ActorCriticPolicy`` that make up the value function.
    VALUE_PARAMETERS = ("mlp_extractor.value_net.", "value_net.")

    def __init__(self, steps: int) -> None:
        super().__init__()
        self.steps = steps

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        frozen = self.num_timesteps <= self.steps
        for name, parameter in self.model.policy.named_parameters():
            parameter.requires_grad_(not frozen or name.startswith(self.VALUE_PARAMETERS))

    def _on_training_end(self) -> None:
        for parameter in self.model.policy.parameters():
            parameter.requires_grad_(True)
