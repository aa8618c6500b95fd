"""The training loop behind `train.py`: env + dataset + agent, chunked training, evaluation, checkpoints.

`run(cfg, run_dir)` with the composed config of `experiment_configs/config.yaml` (`Runner`, one method a step):

1. checks that the algorithm exists, takes the config's parameters and can learn from the Task-ID's dataset
   type (`check_dataset_type`), before anything slow happens (`_check_config`);
2. locks the run dir for this process (`lock.py`: a second process on it is refused) and resumes from
   `<run_dir>/checkpoint.pt` when there is one (`resume: auto`, the default, or `true`), verified against the
   sha256 in `checkpoint.json` (`checkpoint.py`); a finished run only prints its evaluation; a run dir whose
   checkpoint has a different config is refused (`_prepare_dir`, `_fork`);
3. builds the training env, the expert dataset (its `train` split; the `test` split is kept for the
   trajectory-similarity metrics) and the agent (`loco_il.algorithms.factory.build_agent`) (`_setup`), then
   loads the checkpoint's state into them (`_restore`);
4. trains in chunks: online agents through mushroom-rl's `Core.learn(n_steps=chunk, n_steps_per_fit=...)`,
   offline ones (BC) through `agent.pretrain(chunk)`; after each chunk it evaluates (every `eval.every`
   steps), logs, and checkpoints (every `checkpoint_every` steps) (`_loop`);
5. ends with a final evaluation (`eval.final_episodes` episodes + trajectory similarity), `final_agent.pt`,
   `eval.json` (`_finish`), and prints the result table.

Steps are env steps for online agents and gradient steps for offline ones (BC). A chunk never straddles an
evaluation or checkpoint point; evaluation and checkpoint intervals are rounded up to multiples of
`n_steps_per_fit`, so no collected transition is dropped (unless the budget itself is not a multiple)
(`Schedule`). `Core.learn` resets the env at the start of every chunk.
"""
from __future__ import annotations

import math
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import torch

from loco_il.experiment.checkpoint import (CHECKPOINT_NAME, CheckpointError, config_differences, has_checkpoint,
                                           load_checkpoint, load_run_checkpoint, restore, save_checkpoint)
from loco_il.experiment.lock import RunDirLockedError, run_dir_lock
from loco_il.experiment.logging import RunLogger, Stopwatch
from loco_il.experiment.machine import machine_record
from loco_il.utils.fileio import write_json
from loco_il.utils.hashing import ChecksumMismatchError, verify_sidecar, write_sidecar
from loco_il.utils.plain import to_plain
from loco_il.utils.signals import StopFlag, stop_requests

RUN_FILES = ("checkpoint.pt", "checkpoint.prev.pt", "checkpoint.pt.damaged", "checkpoint.json", "final_agent.pt",
             "final_agent.pt.sha256", "eval.json", "log.csv", "log.jsonl")
#: exit status of `train.py` when `stop_after_steps` stopped a run early (as if it had been killed)
STOPPED_EXIT_CODE = 3
#: exit status of `train.py` when SIGINT/SIGTERM stopped a run (after writing a checkpoint)
SIGNAL_EXIT_CODE = 130


#: sub-directory of a run dir with the checkpoints kept by `keep_checkpoints_above` (kept/step<N>.pt)
KEPT_DIR = "kept"


def keep_threshold(value: Any) -> float | None:
    """`keep_checkpoints_above` as a number (None: keep none); a clear error for anything else."""
    if value is None:
        return None
    try:
        threshold = float(value)
    except (TypeError, ValueError):
        raise ExperimentConfigError(f"keep_checkpoints_above={value!r}: expected a normalized score "
                                    f"(e.g. 0.9) or null") from None
    if math.isnan(threshold):
        raise ExperimentConfigError("keep_checkpoints_above=nan: expected a normalized score (e.g. 0.9) or null")
    return threshold


def keep_copy(run_dir: Path, step: int) -> Path:
    """Copy the run's checkpoint, just written at `step`, to kept/step<step>.pt (atomically: a kill mid-copy
    leaves no partial file under the final name)."""
    from loco_il.utils.atomic import atomic_copy
    dest = run_dir / KEPT_DIR / f"step{step}.pt"
    dest.parent.mkdir(exist_ok=True)
    atomic_copy(run_dir / CHECKPOINT_NAME, dest)
    write_sidecar(dest)   # verified when a fork starts from it
    return dest


def source_run_dir(checkpoint: Path) -> Path:
    """The run dir a checkpoint file belongs to: its folder, or the run dir above kept/."""
    parent = checkpoint.parent
    return parent.parent if parent.name == KEPT_DIR else parent


class StopRequested(Exception):
    """`stop_after_steps` was reached: the run stops like a killed one (no checkpoint of the last chunk)."""


class StoppedBySignal(Exception):
    """SIGINT/SIGTERM arrived: the run stopped after the agent's next fit, with a checkpoint."""

    def __init__(self, message: str, signal_name: str):
        super().__init__(message)
        self.signal_name = signal_name


class _StopAtFit(Exception):
    """Raised by the Core's fit callback once a stop signal has arrived: ends `Core.learn` right after a fit,
    so every collected transition has been fitted and the checkpoint is consistent."""


class ExperimentConfigError(ValueError):
    """A config that cannot run (unknown algorithm or Task-ID, algorithm/dataset mismatch): one-line message."""


def seed_everything(seed: int) -> None:
    import random
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def overridden_keys(cli_overrides: Sequence[str], prefix: str = "algo.") -> list[str]:
    """Dotted keys (below `prefix`) that the command line set, e.g. `algo.params.lr=1e-4` -> `params.lr`."""
    keys = []
    for item in cli_overrides:
        key = item.split("=", 1)[0].lstrip("+~")
        if key.startswith(prefix):
            keys.append(key[len(prefix):])
    return keys


def apply_per_algo(cfg: dict, cli_overrides: Sequence[str] = ()) -> dict:
    """Merge `cfg["per_algo"][<algo name>]` (per-task tuning from a task file) into `cfg["algo"]`.

    Precedence: algo/<name>.yaml < per_algo entry < command line (`algo.*` overrides keep their values).
    The entry's `n_steps` is the task's default budget for that algorithm (see `Runner.budget`).
    """
    from omegaconf import OmegaConf
    entry = dict((cfg.get("per_algo") or {}).get(cfg["algo"]["name"]) or {})
    entry.pop("n_steps", None)
    if not entry:
        return cfg
    original = OmegaConf.create(cfg["algo"])
    merged = OmegaConf.merge(original, OmegaConf.create(entry))
    for key in overridden_keys(cli_overrides):
        value = OmegaConf.select(original, key, default=None)
        OmegaConf.update(merged, key, value, force_add=True)
    out = dict(cfg)
    out["algo"] = OmegaConf.to_container(merged, resolve=True)
    return out


# ----------------------------------------------------------------------------- training starts
INIT_STATES = ("default", "dataset")


def check_init_state(init_state: str) -> str:
    if init_state not in INIT_STATES:
        raise ExperimentConfigError(f"init_state={init_state!r}: expected one of {', '.join(INIT_STATES)}")
    return init_state


def training_start_sampler(env: Any, init_state: str, dcfg: Mapping[str, Any], train: Any):
    """The training env's `init_state_sampler` for `init_state` (None: the body's own start state).

    "dataset": every training episode starts from a uniformly drawn state of the expert train split, as
    LocoMuJoCo does; states are rebuilt from full observations (a `.pomdp` task's masked train split is
    loaded again with `full_obs=True`). Evaluation episodes keep the body's own start state, so that scores
    stay comparable with runs that start there.
    """
    from loco_il.datasets import create_dataset
    from loco_il.datasets.loading import dataset_kwargs
    from loco_il.datasets.providers import dataset_init_state_sampler
    if check_init_state(init_state) == "default":
        return None
    full = train
    if train.obs_dim != env.full_obs_spec.dim:
        full = create_dataset(env, split="train", full_obs=True, **{**dataset_kwargs(dcfg), "verbose": False})
    return dataset_init_state_sampler(env=env, trajs=full)


def dataset_type_of(task_id: str) -> str:
    from loco_il.environments.registry import parse_task_id
    return parse_task_id(task_id).dataset


# ----------------------------------------------------------------------------- the run
@dataclass(frozen=True)
class Schedule:
    """When a run evaluates and checkpoints, in steps (env steps online, gradient steps offline)."""
    budget: int
    eval_every: int
    checkpoint_every: int
    unit: int   # n_steps_per_fit (online) or 1 (offline): the intervals are multiples of it

    def next_chunk(self, step: int) -> int:
        """Steps from `step` to the next evaluation point, checkpoint point or the end, whichever comes first."""
        next_eval = (step // self.eval_every + 1) * self.eval_every
        next_ckpt = (step // self.checkpoint_every + 1) * self.checkpoint_every
        return min(next_eval, next_ckpt, self.budget) - step

    def evaluates_at(self, step: int) -> bool:
        return step % self.eval_every == 0 or step == self.budget

    def checkpoints_at(self, step: int) -> bool:
        return step % self.checkpoint_every == 0 or step == self.budget


class Runner:
    """One run of `train.py` in its run dir: `run()` checks the config, then resumes or sets the run up (`_setup`,
    `_restore`), trains in chunks (`_loop`) and scores the result (`_finish`)."""

    def __init__(self, cfg: Any, run_dir: str | Path, cli_overrides: Sequence[str] = ()):
        self.cfg = apply_per_algo(to_plain(cfg), cli_overrides)
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        c = self.cfg
        self.task_id = str(c["task_id"])
        self.algo_cfg = dict(c["algo"])
        self.name = str(c.get("name") or self.algo_cfg["name"])
        self.seed = int(c.get("seed", 0))
        self.eval_cfg = dict(c.get("eval") or {})
        self.log_cfg = dict(c.get("logger") or {})

    # ------------------------------------------------------------------ budget and chunking
    def budget(self) -> int:
        from loco_il.algorithms import factory
        if self.cfg.get("n_steps") is not None:
            return int(self.cfg["n_steps"])
        entry = (self.cfg.get("per_algo") or {}).get(self.algo_cfg["name"]) or {}
        if entry.get("n_steps") is not None:
            return int(entry["n_steps"])
        return factory.default_budget(self.algo_cfg)

    def _schedule(self) -> Schedule:
        """The budget and the evaluation and checkpoint intervals, rounded up to multiples of the unit
        (n_steps_per_fit online, 1 offline) so that no collected transition is dropped."""
        from loco_il.algorithms import factory
        budget = self.budget()
        unit = 1 if self.offline else factory.steps_per_fit(self.algo_cfg)
        every = self.eval_cfg.get("every")
        if not every:   # the algorithm's epoch (LocoMuJoCo evaluates once per epoch), at least 10 per run
            epoch = (self.algo_cfg.get("core") or {}).get("n_steps_per_epoch")
            every = min(int(epoch), max(1, budget // 10)) if epoch else max(1, budget // 10)
        ckpt = self.cfg.get("checkpoint_every") or every
        round_up = lambda n: max(unit, int(math.ceil(int(n) / unit)) * unit)  # noqa: E731
        return Schedule(budget, round_up(every), round_up(ckpt), unit)

    # ------------------------------------------------------------------ resume
    def _prepare_dir(self) -> dict | None:
        """The checkpoint to resume from (None: fresh start)."""
        from loco_il.experiment.config_schema import ConfigValueError, resume_mode
        try:
            mode = resume_mode(self.cfg.get("resume", "auto"))
        except ConfigValueError as exc:
            raise ExperimentConfigError(str(exc)) from None
        if mode == "never":
            for name in RUN_FILES:
                (self.run_dir / name).unlink(missing_ok=True)
            shutil.rmtree(self.run_dir / "wandb", ignore_errors=True)
            return None
        if not has_checkpoint(self.run_dir):
            if mode == "must":
                raise CheckpointError(f"resume=true but {self.run_dir / CHECKPOINT_NAME} does not exist (nothing to "
                                      f"resume); use resume=auto or resume=false")
            for name in RUN_FILES:   # leftovers of a run killed before its first checkpoint
                (self.run_dir / name).unlink(missing_ok=True)
            return self._fork() if self.cfg.get("fork_from") else None
        ckpt, _ = load_run_checkpoint(self.run_dir, note=lambda msg: print(f"[loco_il] {msg}", flush=True))
        diffs = config_differences(ckpt.get("config") or {}, self.cfg)
        if diffs:
            raise CheckpointError(
                f"{self.run_dir} holds a run with a different configuration:\n  " + "\n  ".join(diffs) +
                "\nTo continue that run, use its settings; to start over in this dir, add resume=false; "
                "otherwise choose another dir (name=<label> or hydra.run.dir=<dir>).")
        return ckpt

    def _fork(self) -> dict:
        """A new run that starts from another run's checkpoint (`fork_from`: its run dir or checkpoint file):
        its weights, optimizer states, replay, counters and log rows up to that step, trained on with this
        config (e.g. an ablation branched from step N instead of repeated from 0). State in the checkpoint
        wins over initial values in the config (init_alpha, ...); the algorithm and task must be the same."""
        src = Path(str(self.cfg["fork_from"])).expanduser()
        src_ckpt = src / CHECKPOINT_NAME if src.is_dir() else src
        if not (src_ckpt.is_file() or (src_ckpt.name == CHECKPOINT_NAME and has_checkpoint(src_ckpt.parent))):
            raise CheckpointError(f"fork_from={src}: no checkpoint there (expected {src_ckpt})")
        if src_ckpt.name == CHECKPOINT_NAME:   # a run dir's own checkpoint: verified against its checkpoint.json
            ckpt, src_ckpt = load_run_checkpoint(src_ckpt.parent, repair=False,
                                                 note=lambda msg: print(f"[loco_il] fork_from: {msg}", flush=True))
        else:   # a kept copy: verified against the checksum file next to it
            try:
                verify_sidecar(src_ckpt)
            except ChecksumMismatchError as exc:
                raise CheckpointError(f"fork_from={src}: {exc}") from None
            ckpt = load_checkpoint(src_ckpt)
        old = ckpt.get("config") or {}
        for key, new in (("task_id", self.task_id), ("algo.name", self.algo_cfg["name"])):
            head, _, tail = key.partition(".")
            was = (old.get(head) or {}).get(tail) if tail else old.get(head)
            if was != new:
                raise CheckpointError(f"fork_from={src}: that run has {key}={was!r}, this one {new!r}; a fork "
                                      f"continues the same algorithm on the same task")
        src_dir = source_run_dir(src_ckpt)
        for name in ("log.csv", "log.jsonl"):   # the curve up to the fork point (truncated to its step later)
            if (src_dir / name).is_file():
                shutil.copyfile(src_dir / name, self.run_dir / name)
        diffs = [d for d in config_differences(old, self.cfg) if not d.startswith("fork_from")]
        print(f"[loco_il] forking {src_ckpt} at step {ckpt['counters']['step']}; changed settings:\n  "
              + ("\n  ".join(diffs) or "none"), flush=True)
        return dict(ckpt, wandb_id=None, finished=False, forked=True)   # a new W&B run, not the source's

    # ------------------------------------------------------------------ main
    def run(self) -> dict:
        """Train, resume or report the run. A SIGINT/SIGTERM from the start on, also during the setup (which can
        take minutes when a dataset is generated), stops the run at the first fit after it, with a checkpoint."""
        self.logger = None

        def note(msg: str) -> None:
            line = f"[loco_il] {msg}"
            if self.logger is not None:
                self.logger.write(line)
            else:
                print(line, flush=True)

        with run_dir_lock(self.run_dir), stop_requests(note) as stop:
            return self._run(stop)

    def _run(self, stop: StopFlag) -> dict:
        """The steps of the module docstring, in order; the envs and the logger are closed however the loop ends."""
        torch.set_num_threads(int(self.cfg.get("torch_threads") or 1))
        self._check_config()
        ckpt = self._prepare_dir()
        finished = self._finished_result(ckpt)
        if finished is not None:
            return finished
        self._write_config()
        self._setup()
        self._restore(ckpt)
        self._open_log(ckpt)
        self.clock = Stopwatch(self.wall_before)   # run time so far, carried over from the checkpoint
        try:
            self._loop(stop)
            result = self._finish()
        finally:
            self.logger.close()
            self.env.stop()
            self.eval_env.stop()
        self._save_checkpoint(finished=True)
        self._print_table(result)
        return result

    def _check_config(self) -> None:
        """Fail before anything slow: the algorithm and its parameters, the Task-ID's dataset type, `init_state`
        and `keep_checkpoints_above`."""
        from loco_il.algorithms import factory
        c = self.cfg
        try:
            cls = factory.get_algorithm(self.algo_cfg["name"])
            cls.check_dataset_type(dataset_type_of(self.task_id))
            factory.agent_kwargs(cls, self.algo_cfg)
            self.init_state = check_init_state(str(c.get("init_state") or "default"))
            self.keep_above = keep_threshold(c.get("keep_checkpoints_above"))
        except (KeyError, ValueError) as exc:
            raise ExperimentConfigError(str(exc.args[0]) if exc.args else str(exc)) from exc
        self.offline = factory.is_offline(cls, self.algo_cfg)

    def _finished_result(self, ckpt: dict | None) -> dict | None:
        """The final evaluation of a run that already finished its budget (printed again), else None."""
        if not (ckpt is not None and ckpt.get("finished") and (self.run_dir / "eval.json").is_file()
                and int(ckpt["counters"]["step"]) >= self.budget()):   # a larger n_steps trains on
            return None
        import json
        result = json.loads((self.run_dir / "eval.json").read_text())
        print(f"[loco_il] {self.run_dir} already finished ({result.get('steps')} steps); final evaluation:")
        self._print_table(result)
        return result

    def _setup(self) -> None:
        """The training and evaluation envs, the expert data (train and test splits), the agent and the schedule."""
        from loco_il.algorithms import factory
        from loco_il.datasets.loading import load_datasets
        from loco_il.environments.registry import make
        c = self.cfg
        seed_everything(self.seed)
        self.env = make(self.task_id, seed=self.seed)
        self.eval_env = make(self.task_id, seed=self.seed + 1)
        self.train_data, self.test_data = load_datasets(self.env, c.get("dataset") or {})
        self.env.init_state_sampler = training_start_sampler(self.env, self.init_state, c.get("dataset") or {},
                                                             self.train_data)
        seed_everything(self.seed)   # the same initial weights whether the dataset was generated or cached
        self.agent = factory.build_agent(self.algo_cfg["name"], self.env.info, self.algo_cfg, seed=self.seed,
                                         device=str(c.get("device") or "cpu"))
        self.agent.set_expert(self.train_data)
        self.schedule = self._schedule()

    def _restore(self, ckpt: dict | None) -> None:
        """Counters, run time, W&B id and the training returns since the last evaluation: fresh, or those of `ckpt`
        (a resume or a fork), whose agent and env state are loaded too."""
        self.counters = {"step": 0, "env_steps": 0, "episodes": 0, "n_evals": 0, "critic_diverged_at": None}
        self.wall_before, self.wandb_id = 0.0, None
        self.window: dict[str, list] = {"returns": []}   # training returns since the last evaluation
        if ckpt is None:
            return
        try:
            restore(ckpt, agent=self.agent, env=self.env)
        except RuntimeError as exc:   # load_state_dict: missing / unexpected keys, other shapes
            if not ckpt.get("forked"):
                raise
            raise CheckpointError(f"fork_from={self.cfg['fork_from']}: its agent state does not fit this config's "
                                  f"networks ({str(exc).splitlines()[0]} ...); a fork may change learning "
                                  "settings, not network sizes or the number of critics") from exc
        self.counters.update(ckpt["counters"])
        self.wall_before, self.wandb_id = float(ckpt.get("wall_time", 0.0)), ckpt.get("wandb_id")
        self.window["returns"] = list((ckpt.get("extra") or {}).get("train_returns", []))

    def _open_log(self, ckpt: dict | None) -> None:
        """The run's logger (log files, W&B, progress bar), its rows past the checkpoint dropped, and the run's
        opening lines."""
        c, step, budget = self.cfg, int(self.counters["step"]), self.schedule.budget
        train = self.train_data
        self.logger = logger = RunLogger(
            self.run_dir, c, wandb_cfg=self.log_cfg.get("wandb"), progress=self.log_cfg.get("progress", "auto"),
            total=budget, initial=step, wandb_id=self.wandb_id, run_name=f"{self.name}/{self.task_id}/seed{self.seed}",
            unit="update" if self.offline else "step")
        if ckpt is not None:
            logger.truncate(step)
            logger.write(f"[loco_il] {'forked from ' + str(c['fork_from']) if ckpt.get('forked') else 'resuming'} "
                         f"{self.run_dir} at step {step}/{budget}")
        logger.write(f"[loco_il] {self.name} on {self.task_id} (seed {self.seed}): {budget} "
                     f"{'gradient' if self.offline else 'env'} steps, {train.n_trajectories} expert episodes "
                     f"({train.n_transitions} transitions); run dir {self.run_dir}")
        if self.env.init_state_sampler is not None:
            logger.write("[loco_il] training episodes start from states of the expert train split (init_state=dataset)")

    def _save_checkpoint(self, finished: bool = False) -> None:
        c = self.cfg
        save_checkpoint(self.run_dir / CHECKPOINT_NAME, agent=self.agent, env=self.env, counters=self.counters,
                        wall_time=self.clock(), config=c, wandb_id=self.logger.wandb_id, finished=finished,
                        extra=None if finished else {"train_returns": self.window["returns"]},
                        include_replay=bool(c.get("checkpoint_replay", True)))

    def _loop(self, stop: StopFlag) -> None:
        """Train chunk by chunk up to the budget; after each chunk, evaluate, checkpoint, keep a copy and stop when
        due. A chunk never straddles an evaluation or checkpoint point."""
        schedule, counters = self.schedule, self.counters
        core = None if self.offline else self._make_core(stop)
        step = int(counters["step"])
        last_t, last_step = self.clock(), step
        while step < schedule.budget:
            done, fit_info = self._train_chunk(core, schedule.next_chunk(step), stop)
            step += done
            counters["step"] = step
            if not self.offline:
                counters["env_steps"] += done
            row = None
            # done == 0: a signal during the setup stopped an offline run before its first step; nothing to evaluate
            if done and schedule.evaluates_at(step):
                now = self.clock()
                row = self._evaluate_row(now, (step - last_step) / max(now - last_t, 1e-9), fit_info)
                last_t, last_step = self.clock(), step   # steps/s without the evaluation's time
                self._log_evaluation(row)
            score = None if row is None else row.get("normalized_score")   # None on tasks without baselines
            keep = self.keep_above is not None and score is not None and score >= self.keep_above
            # a stop signal ends the chunk at the next fit and checkpoints there: within seconds
            # instead of up to a whole interval later (a scheduler's SIGTERM grace is often short)
            if schedule.checkpoints_at(step) or stop.signal is not None or keep:
                self._save_checkpoint()
            if keep:
                path = keep_copy(self.run_dir, step)
                self.logger.write(f"[loco_il] normalized score {score:.3f} >= {self.keep_above}: "
                                  f"checkpoint kept as {path} (fork_from={path} branches from it)")
            self._stop_if_asked(stop, step)

    def _log_evaluation(self, row: dict) -> None:
        from loco_il.experiment.scoring import identical_episodes_note
        self.counters["n_evals"] += 1
        self.logger.log(row)
        score, ema = row.get("normalized_score"), row.get("normalized_score_ema")
        identical = identical_episodes_note({"episodes": row["eval_episodes"],
                                             "distinct_episodes": row["eval_distinct_episodes"]})
        self.logger.write(f"[loco_il] step {row['step']}: eval return {row['eval_return_mean']:.2f} ± "
                          f"{row['eval_return_std']:.2f}" + (f", normalized {score:.3f}" if score is not None else "")
                          + (f", actor average {ema:.3f}" if ema is not None else "")
                          + (" (all episodes identical)" if identical else ""))
        self._note_critic_divergence(row)

    def _note_critic_divergence(self, row: dict) -> None:
        """Warn once when an off-policy learner's critic has left the values its rewards allow: every evaluation
        from then on scores a policy trained on a diverged critic. The first such step goes into eval.json."""
        check = getattr(self.agent, "critic_divergence", None)
        if check is None or "fit/q_mean" not in row or self.counters.get("critic_diverged_at") is not None:
            return
        note = check(row["fit/q_mean"])
        if note is not None:
            self.counters["critic_diverged_at"] = row["step"]
            self.logger.write(f"[loco_il] warning at step {row['step']}: {note}; its evaluations from here on score "
                              "a policy trained on a diverged critic (eval.json: critic_diverged_at)")

    def _stop_if_asked(self, stop: StopFlag, step: int) -> None:
        """End the run like a killed one when a stop signal arrived or `stop_after_steps` is reached."""
        budget, stop_after = self.schedule.budget, self.cfg.get("stop_after_steps")
        if stop.signal is not None and step < budget:
            raise StoppedBySignal(f"stopped by {stop.signal} at step {step}/{budget}, checkpoint "
                                  f"saved (re-run the same command to resume)", str(stop.signal))
        if stop_after is not None and step >= int(stop_after) and step < budget:
            raise StopRequested(f"stop_after_steps={stop_after}: stopped at step {step}/{budget} "
                                f"(re-run the same command to resume)")

    # ------------------------------------------------------------------ pieces
    def _make_core(self, stop: StopFlag):
        from mushroom_rl.core import Core
        state = {"ret": 0.0, "steps": 0}
        logger, window, counters = self.logger, self.window, self.counters

        def on_step(samples):
            for s in samples:
                state["ret"] += float(s[2])
                if s[-1]:
                    window["returns"].append(state["ret"])
                    counters["episodes"] += 1
                    state["ret"] = 0.0
            on_step.k += 1
            state["steps"] += len(samples)
            if on_step.k >= 200:
                logger.progress(on_step.k, train_return=np.mean(window["returns"][-10:]) if window["returns"] else None)
                on_step.k = 0

        def stop_at_fit(_dataset) -> None:
            if stop.signal is not None:
                raise _StopAtFit

        on_step.k = 0
        core = Core(self.agent, self.env, callback_step=on_step, callbacks_fit=[stop_at_fit])
        self._on_step, self._step_state = on_step, state
        return core

    def _train_chunk(self, core, n: int, stop: StopFlag) -> tuple[int, dict]:
        """Train for `n` steps, or fewer when a stop signal arrives (then up to the next fit);
        returns (steps done, the last fit's info)."""
        agent = self.agent
        if self.offline:
            done, loss = 0, None
            while done < n and stop.signal is None:
                k = min(100, n - done)
                loss = agent.pretrain(k)
                done += k
                self.logger.progress(k, loss=loss)
            return done, {"bc_loss": loss}
        self._step_state["ret"] = 0.0            # Core.learn starts a fresh episode
        self._step_state["steps"] = 0
        try:
            core.learn(n_steps=n, n_steps_per_fit=self.schedule.unit, quiet=True)
            done = n
        except _StopAtFit:
            done = self._step_state["steps"]
        self.logger.progress(self._on_step.k)
        self._on_step.k = 0
        info = getattr(agent, "last_fit_info", None) or getattr(agent, "last_info", None) or {}
        return done, dict(info)

    def _evaluate_row(self, wall: float, sps: float, fit_info: dict) -> dict:
        from loco_il.experiment.scoring import evaluate_agent, evaluate_averaged_actor, normalized
        ev, counters = self.eval_cfg, self.counters
        eval_args = (int(ev.get("episodes", 5)), int(ev.get("seed", 1000)), bool(ev.get("deterministic", True)))
        res = evaluate_agent(self.agent, self.eval_env, *eval_args)
        ema = evaluate_averaged_actor(self.agent, self.eval_env, *eval_args)
        score, _, _ = normalized(self.task_id, res["return_mean"])
        updates = getattr(self.agent, "n_updates", None)
        if updates is None:
            updates = getattr(self.agent, "n_fits", None)
        returns = self.window["returns"]
        row = {"step": counters["step"], "env_steps": counters["env_steps"], "updates": updates,
               "episodes": counters["episodes"], "wall_time": round(wall, 3), "steps_per_s": round(sps, 2),
               "train_return": float(np.mean(returns)) if returns else None,
               "eval_return_mean": res["return_mean"], "eval_return_std": res["return_std"],
               "eval_episodes": res["episodes"], "eval_terminated": res["terminated"],
               "eval_length_mean": res["length_mean"],
               "eval_distinct_episodes": res["distinct_episodes"], "normalized_score": score}
        if ema is not None:   # the actor's moving average (algo.params.actor_ema), same episodes
            row.update({"eval_ema_return_mean": ema["return_mean"], "eval_ema_length_mean": ema["length_mean"],
                        "normalized_score_ema": normalized(self.task_id, ema["return_mean"])[0]})
        row.update({f"fit/{k}": v for k, v in fit_info.items()})
        self.window["returns"] = []
        self.logger.progress(0, eval_return=res["return_mean"], steps_per_s=sps)
        return row

    def _finish(self) -> dict:
        """The final evaluation (with trajectory similarity), `final_agent.pt` and `eval.json`."""
        from loco_il.environments.registry import task_key
        from loco_il.experiment.scoring import evaluate_agent, evaluate_averaged_actor, normalized, trajectory_similarity
        agent, eval_env, counters, wall = self.agent, self.eval_env, self.counters, self.clock()
        ev = self.eval_cfg
        sim_on = bool(ev.get("similarity", True))
        eval_args = (int(ev.get("final_episodes", 10)), int(ev.get("seed", 1000)), bool(ev.get("deterministic", True)))
        res = evaluate_agent(agent, eval_env, *eval_args, collect_obs=sim_on)
        ema = evaluate_averaged_actor(agent, eval_env, *eval_args)
        score, note, base = normalized(self.task_id, res["return_mean"])
        env = self.env
        result = {"task_id": env.task_id,
                  "task": task_key(env.task_id) + (".pomdp" if env.task_id.endswith(".pomdp") else ""),
                  "dataset_type": env.dataset_type, "algorithm": self.algo_cfg["name"], "name": self.name,
                  "seed": self.seed, "steps": counters["step"], "env_steps": counters["env_steps"],
                  "step_unit": "gradient steps" if self.offline else "env steps",
                  "wall_time": round(wall, 3), **{k: v for k, v in res.items() if k != "obs"},
                  "normalized_score": score, "normalized_score_note": note, "baseline": base,
                  "expert_dataset_return": self.train_data.info.get("expert_return_mean"),
                  # the first evaluation step at which the critic had diverged (off-policy learners), else None
                  "critic_diverged_at": counters.get("critic_diverged_at"),
                  "n_expert_trajectories": self.train_data.n_trajectories,
                  "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                  # where the final evaluation ran (a resumed run may have trained elsewhere before)
                  "finished_on": machine_record(str(self.cfg.get("device") or "cpu"))}
        if ema is not None:
            result["ema_actor"] = {"return_mean": ema["return_mean"], "return_std": ema["return_std"],
                                   "length_mean": ema["length_mean"],
                                   "normalized_score": normalized(self.task_id, ema["return_mean"])[0]}
        if sim_on:
            ref = self.test_data if self.test_data is not None and self.test_data.n_transitions else self.train_data
            result["similarity"] = trajectory_similarity(
                res["obs"], ref.obs, self.train_data.obs if ref is not self.train_data else None,
                int(ev.get("max_points", 1000)), seed=self.seed)
            result["similarity"]["reference"] = "test split" if ref is not self.train_data else "train split"
        agent.save(self.run_dir / "final_agent.pt")
        write_sidecar(self.run_dir / "final_agent.pt")   # verified whenever the policy is loaded
        write_json(self.run_dir / "eval.json", result)
        self.logger.summary({"final_return_mean": result["return_mean"], "final_return_std": result["return_std"],
                             "final_normalized_score": score})
        return result

    def _write_config(self) -> None:
        import yaml

        from loco_il.utils.atomic import atomic_open
        with atomic_open(self.run_dir / "config.yaml", "w") as fh:
            yaml.safe_dump(self.cfg, fh, sort_keys=False)

    @staticmethod
    def _print_table(result: Mapping[str, Any]) -> None:
        from loco_il.experiment.scoring import format_eval_table
        print("\nFinal evaluation\n" + format_eval_table([result]), flush=True)


def run(cfg: Any, run_dir: str | Path, cli_overrides: Sequence[str] = ()) -> dict:
    """Train (or resume, or report a finished run in) `run_dir`; returns the final evaluation.

    `cli_overrides`: the command line's overrides (Hydra's `overrides.task`), so that `algo.*` values
    given there win over a task file's `per_algo` entry."""
    return Runner(cfg, run_dir, cli_overrides).run()


#: set in a process once a stop signal has ended one of its jobs: a sweep's later jobs in that process (Hydra's
#: basic launcher runs them one after another) do not start, so `kill` stops the sweep, not only its current job
_signal_stop: list[str] = []


@dataclass
class JobOutcome:
    """How one `train.py` job ended: its exit status and, for a failure, the one-line error (sweep summaries)."""
    code: int
    error: str | None = None
    task_id: str = "?"
    name: str = "?"
    seed: Any = "?"


def run_job(cfg: Any, run_dir: str | Path, cli_overrides: Sequence[str] = (), catch_all: bool = False) -> JobOutcome:
    """`run` for command-line use: the config validated first, one-line messages and exit codes for expected
    failures. `catch_all` (sweeps): an unexpected exception is printed with its traceback and becomes a failed
    outcome, so the other jobs still run and the summary names it."""
    from loco_il.datasets.trajectory import DatasetError
    from loco_il.experiment.config_schema import ConfigValueError, validate_config
    plain = to_plain(cfg, loose=True)   # for the outcome's labels, also of a config that does not resolve
    outcome = JobOutcome(0, task_id=str(plain.get("task_id", "?")), name=str(plain.get("name", "?")),
                         seed=plain.get("seed", "?"))

    def failed(code: int, message: str, prefix: str = "[loco_il] error: ") -> JobOutcome:
        print(f"{prefix}{message}", file=sys.stderr, flush=True)
        outcome.code, outcome.error = code, message
        return outcome

    if _signal_stop:
        return failed(SIGNAL_EXIT_CODE, f"not started: an earlier job of this sweep was {_signal_stop[0]}",
                      "[loco_il] ")
    try:
        run(validate_config(cfg), run_dir, cli_overrides)
    except StoppedBySignal as exc:
        _signal_stop.append(f"stopped by {exc.signal_name}")
        return failed(SIGNAL_EXIT_CODE, str(exc), "[loco_il] ")
    except StopRequested as exc:
        return failed(STOPPED_EXIT_CODE, str(exc), "[loco_il] ")
    except (ConfigValueError, CheckpointError, DatasetError, ExperimentConfigError, RunDirLockedError) as exc:
        return failed(2, str(exc))
    except Exception as exc:  # noqa: BLE001 - sweeps only: the traceback is printed, the summary names the job
        if not catch_all:
            raise
        import traceback
        traceback.print_exc()
        return failed(1, f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}")
    return outcome


def main_with_exit_codes(cfg: Any, run_dir: str | Path, cli_overrides: Sequence[str] = ()) -> int:
    """`run_job`'s exit status."""
    return run_job(cfg, run_dir, cli_overrides).code


__all__ = ["run", "Runner", "Schedule", "StopRequested", "StoppedBySignal", "ExperimentConfigError",
           "STOPPED_EXIT_CODE", "SIGNAL_EXIT_CODE", "main_with_exit_codes", "run_job", "JobOutcome"]
