"""What every expert trainer shares: configuration, checkpoint/resume, evaluation, expert files, logging.

An algorithm (`ppo.PPOTrainer`, `sac.SACTrainer`) subclasses `ExpertTrainer` and supplies
  * `build()`               create its learner (called once, before a checkpoint is loaded)
  * `learner_state()` / `load_learner_state(state)`   everything of the learner a resume needs
  * `make_expert(metadata)` the current policy as a shippable `ExpertPolicy`
  * `start()`               (re)create and reset the training envs at the start of a session
  * `iterate()`             advance training by some env steps (updating `self.step`); returns stats
  * `progress_suffix(stats)` the algorithm's part of a progress line
The loop here (`train`) does the rest the same way for all of them: periodic deterministic
evaluations (`evals.jsonl`, `best.pt`), snapshots at fractions of the budget (for `preference`
datasets), atomic checkpoints every `checkpoint_minutes` and at the end, progress lines, and a final
JSON summary line. SIGINT (Ctrl-C) or SIGTERM ends the run at the end of the current iteration with a
checkpoint, so that nothing since the last periodic checkpoint is lost; a second Ctrl-C stops at once.

Files in `out_dir`: `checkpoint.pt`, `best.pt`, `final.pt`, `snapshots/step_XXXXXXXXX.pt`, `evals.jsonl`, and with
`keep_eval_policies=true` every evaluated policy as `evals/step_XXXXXXXXX.pt`.
"""
from __future__ import annotations

import collections
import dataclasses
import contextlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import torch

from loco_il.experts.policy import ExpertPolicy
from loco_il.utils.atomic import atomic_torch_save, atomic_write
from loco_il.utils.signals import stop_requests

CHECKPOINT_FORMAT = "loco_il.experts.checkpoint/v1"


@dataclass
class CommonConfig:
    """Options every expert trainer accepts (see configs/train.yaml)."""

    algo: str = "ppo"
    task: str = "Hopper.run"
    seed: int = 0
    out_dir: str = "runs/experts/Hopper.run/seed0"
    total_steps: int = 2_000_000
    num_envs: int = 16
    async_envs: Any = "auto"          # "auto" | True | False (yaml key: `async`)
    device: str = "auto"              # "auto" | "cpu" | "cuda": where the updates run; envs always on the CPU
    torch_threads: int = 1
    gamma: float = 0.99
    hidden: Sequence[int] = (64, 64)
    activation: str = "tanh"
    # bookkeeping
    checkpoint_minutes: float = 5.0
    eval_interval: int = 100_000      # env steps between evaluations (0: only at snapshots and the end)
    eval_episodes: int = 10
    eval_envs: int = 0                # 0: min(eval_episodes, num_envs)
    snapshot_every: float = 0.1       # fraction of total_steps between snapshots (0: none)
    snapshot_initial: bool = True     # also save the untrained policy as snapshots/step_000000000.pt
    keep_eval_policies: bool = False  # save every evaluated policy as evals/step_XXXXXXXXX.pt (model selection)
    log_interval_s: float = 10.0
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)

    #: options that must not change when a run is resumed (the network shapes, ...)
    RESUME_FIXED = ("hidden", "activation")

    @classmethod
    def from_mapping(cls, cfg: Mapping[str, Any]):
        data = dict(cfg)
        if "async" in data:
            data["async_envs"] = data.pop("async")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"unknown training option(s) {unknown} for algo={data.get('algo', cls.algo)}; "
                             f"known: {sorted(names)}")
        out = cls(**data)
        out.hidden = tuple(int(h) for h in out.hidden)
        out.env_kwargs = dict(out.env_kwargs or {})
        return out

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["hidden"] = list(self.hidden)
        d["env_kwargs"] = dict(self.env_kwargs)
        return d


def resolve_device(device: str) -> torch.device:
    """"auto" -> cuda when available, else cpu; "cuda" without CUDA falls back to the CPU with a message."""
    if device in ("auto", None, ""):
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if str(device).startswith("cuda") and not torch.cuda.is_available():
        print("[experts] device=cuda asked for but CUDA is not available: updating on the CPU", flush=True)
        return torch.device("cpu")
    return torch.device(device)


def slim_checkpoint(src: str | Path, dst: str | Path) -> dict[str, Any]:
    """Copy an expert-training checkpoint without its replay memory (SAC's is ~250 bytes per transition).

    The copy resumes like any checkpoint saved with `checkpoint_replay=false`: the run refills the replay
    memory (`learning_starts` steps; by the current policy, or by `refill_from`'s policy files) before
    updates go on. Use it to move a run to another machine or to keep a long run's state small enough to
    store. Returns the step and both sizes."""
    data = torch.load(src, map_location="cpu", weights_only=True)
    if data.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{src} is not an expert-training checkpoint of this version")
    if isinstance(data.get("agent"), dict) and data["agent"].get("replay") is not None:
        data["agent"]["replay"] = None
    atomic_torch_save(data, dst)
    return {"step": int(data["step"]), "bytes_before": Path(src).stat().st_size, "bytes_after": Path(dst).stat().st_size}


class ExpertTrainer:
    """Train an expert for one Task-ID into `cfg.out_dir`; resumes from `out_dir/checkpoint.pt` if present."""

    config_class: type[CommonConfig] = CommonConfig
    name = "expert"

    def __init__(self, cfg: CommonConfig | Mapping[str, Any], log: Callable[[str], None] | None = None):
        from loco_il.environments import LocoEnv
        from loco_il.experts.vec import make_vec_env

        self.cfg = cfg if isinstance(cfg, self.config_class) else self.config_class.from_mapping(cfg)
        cfg = self.cfg
        self.log = log or (lambda s: print(s, flush=True))
        torch.set_num_threads(max(1, int(cfg.torch_threads)))
        probe = LocoEnv.make(cfg.task, **cfg.env_kwargs)
        self.task_id = probe.task_id
        self.obs_dim = probe.obs_spec.dim
        self.act_dim = probe.info.action_space.shape[0]
        self.horizon = probe.info.horizon
        self.body_extra = probe.body.extra   # per-body facts (e.g. a servo robot's "home_action"), computed lazily
        probe.stop()
        self.out_dir = Path(cfg.out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.ckpt_path = self.out_dir / "checkpoint.pt"
        self.device = resolve_device(cfg.device)

        torch.manual_seed(cfg.seed)
        self.step = 0
        self.iteration = 0
        self.wall_time = 0.0          # summed over all sessions of this run
        self.best_eval = -math.inf
        self.last_eval: dict[str, Any] | None = None
        self.last_eval_step = -1
        self.last_snapshot_step = -1
        self.recent: collections.deque = collections.deque(maxlen=50)   # (return, length) of finished episodes
        self.resumed_from: int | None = None
        self._make_vec = make_vec_env
        self.envs = None
        self.eval_envs = None
        self.build()
        if self.ckpt_path.exists():
            self._load_checkpoint()

    # ------------------------------------------------------------------ the algorithm's part
    def build(self) -> None:
        raise NotImplementedError

    def learner_state(self) -> dict[str, Any]:
        raise NotImplementedError

    def load_learner_state(self, state: Mapping[str, Any]) -> None:
        raise NotImplementedError

    def make_expert(self, metadata: Mapping[str, Any] | None = None) -> ExpertPolicy:
        raise NotImplementedError

    def start(self) -> None:
        raise NotImplementedError

    def iterate(self) -> Mapping[str, float]:
        raise NotImplementedError

    def progress_suffix(self, stats: Mapping[str, float]) -> str:
        return ""

    def describe(self) -> str:
        """One line saying how this run is set up (printed at the start)."""
        return f"{self.cfg.num_envs} envs, update on {self.device}"

    def make_envs(self, num_envs: int, purpose: str):
        """The vector env for training (`purpose="train"`) or evaluation ("eval"): copies of the task env."""
        return self._make_vec(self.task_id, num_envs, self.cfg.async_envs, autoreset=True,
                              env_kwargs=self.cfg.env_kwargs)

    def eval_act(self, expert: Any) -> Callable[[np.ndarray], np.ndarray]:
        """What acts in the evaluation envs: batched observations -> batched actions."""
        return expert.act

    # ------------------------------------------------------------------ training envs
    def reset_envs(self, salt: int) -> None:
        """Create the training envs on first use; reset them with seeds drawn from (cfg.seed, salt)."""
        cfg = self.cfg
        if self.envs is None:
            self.envs = self.make_envs(cfg.num_envs, "train")
        base = int(np.random.SeedSequence([cfg.seed, salt]).generate_state(1)[0]) % (2 ** 31 - cfg.num_envs)
        self._obs, _ = self.envs.reset(seed=[base + i for i in range(cfg.num_envs)])
        self._ep_ret = np.zeros(cfg.num_envs)
        self._ep_len = np.zeros(cfg.num_envs, dtype=np.int64)

    def track_episodes(self, reward: np.ndarray, ended: np.ndarray) -> None:
        """Add one step's rewards to the running episode returns; log the episodes that `ended`."""
        self._ep_ret += reward
        self._ep_len += 1
        for i in np.flatnonzero(ended):
            self.recent.append((float(self._ep_ret[i]), int(self._ep_len[i])))
            self._ep_ret[i], self._ep_len[i] = 0.0, 0

    # ------------------------------------------------------------------ checkpoints
    def save_checkpoint(self) -> None:
        data = {"format": CHECKPOINT_FORMAT, "algo": self.cfg.algo, "task_id": self.task_id,
                "config": self.cfg.to_dict(), "step": self.step, "iteration": self.iteration,
                "wall_time": self.wall_time + self._session_time(), "agent": self.learner_state(),
                "rng": {"torch": torch.get_rng_state()}, "best_eval": self.best_eval,
                "last_eval": self.last_eval, "last_eval_step": self.last_eval_step,
                "last_snapshot_step": self.last_snapshot_step,
                "recent": [list(map(float, r)) for r in self.recent]}
        atomic_torch_save(data, self.ckpt_path)
        self._last_ckpt_time = time.time()

    def _load_checkpoint(self) -> None:
        data = torch.load(self.ckpt_path, map_location="cpu", weights_only=True)
        if data.get("format") != CHECKPOINT_FORMAT:
            raise ValueError(f"{self.ckpt_path} is not an expert-training checkpoint of this version")
        if data.get("algo", "ppo") != self.cfg.algo:
            raise ValueError(f"{self.ckpt_path} is a {data.get('algo', 'ppo')} run, not {self.cfg.algo}; "
                             "use another out_dir")
        if data["task_id"] != self.task_id:
            raise ValueError(f"{self.ckpt_path} belongs to {data['task_id']}, not {self.task_id}; "
                             "use another out_dir")
        old, new = data["config"], self.cfg.to_dict()
        for key in self.cfg.RESUME_FIXED:
            if old.get(key) != new[key]:
                raise ValueError(f"cannot resume {self.ckpt_path}: {key} was {old.get(key)!r}, now {new[key]!r}")
        self.load_learner_state(data["agent"])
        self.step, self.iteration = int(data["step"]), int(data["iteration"])
        self.wall_time = float(data["wall_time"])
        self.best_eval = float(data["best_eval"])
        self.last_eval = data["last_eval"]
        self.last_eval_step = int(data["last_eval_step"])
        self.last_snapshot_step = int(data["last_snapshot_step"])
        self.recent.extend(tuple(r) for r in data["recent"])
        torch.set_rng_state(data["rng"]["torch"])
        self.resumed_from = self.step
        self._drop_evals_after(self.step)

    def _drop_evals_after(self, step: int) -> None:
        """Evaluations logged after the checkpoint belong to steps that will be re-run: drop them, so that
        `evals.jsonl` holds one row per evaluated step of the history that continues."""
        for kept_policy in (self.out_dir / "evals").glob("step_*.pt"):   # keep_eval_policies files likewise
            if int(kept_policy.stem.split("_")[1]) > step:
                kept_policy.unlink()
        path = self.out_dir / "evals.jsonl"
        if not path.exists():
            return
        rows = [line for line in path.read_text().splitlines() if line.strip()]
        kept = [line for line in rows if json.loads(line)["step"] <= step]
        if len(kept) < len(rows):
            atomic_write(path, lambda f: f.write("".join(line + "\n" for line in kept).encode()))
            self.log(f"[{self.cfg.algo}] dropped {len(rows) - len(kept)} evaluation(s) logged after step {step} "
                     "(they are re-run)")

    # ------------------------------------------------------------------ evaluation and expert files
    def metadata(self, ev: Mapping[str, Any] | None) -> dict[str, Any]:
        return {"task_id": self.task_id, "training_steps": self.step, "algorithm": self.name,
                "eval_return": None if ev is None else ev["return_mean"],
                "eval_return_std": None if ev is None else ev["return_std"],
                "eval_episodes": None if ev is None else ev["episodes"], "seed": self.cfg.seed,
                "total_steps": self.cfg.total_steps}

    def evaluate(self) -> dict[str, Any]:
        """Deterministic episodes of the current policy (normalizers, if any, frozen)."""
        from loco_il.experts.vec import evaluate_episodes
        cfg = self.cfg
        if self.eval_envs is None:
            n = cfg.eval_envs or min(cfg.eval_episodes, cfg.num_envs)
            self.eval_envs = self.make_envs(max(1, n), "eval")
        expert = self.make_expert()
        t0 = time.time()
        returns, lengths, terminated = evaluate_episodes(self.eval_act(expert), self.eval_envs, cfg.eval_episodes,
                                                         seed=10_000 + 1000 * cfg.seed)
        ev = {"step": self.step, "return_mean": float(returns.mean()), "return_std": float(returns.std()),
              "length_mean": float(lengths.mean()), "episodes": int(len(returns)), "terminated": int(terminated.sum()),
              "returns": [float(r) for r in returns], "eval_time_s": round(time.time() - t0, 3)}
        self.last_eval, self.last_eval_step = ev, self.step
        with open(self.out_dir / "evals.jsonl", "a") as f:
            f.write(json.dumps({k: v for k, v in ev.items() if k != "returns"}) + "\n")
        expert.metadata.update(self.metadata(ev))      # the policy just evaluated, saved as is below
        if cfg.keep_eval_policies:
            # best.pt is chosen on 10 episodes; keeping every evaluated policy lets a later, longer
            # evaluation pick the most reliable one (the mean of a few episodes hides rare early ends)
            expert.save(self.out_dir / "evals" / f"step_{self.step:09d}.pt")
        if ev["return_mean"] > self.best_eval:
            self.best_eval = ev["return_mean"]
            expert.save(self.out_dir / "best.pt")
        return ev

    def _snapshot_thresholds(self) -> list[int]:
        f = self.cfg.snapshot_every
        if not f or f <= 0:
            return []
        k = int(math.floor(1.0 / f + 1e-9))
        return [int(round(i * f * self.cfg.total_steps)) for i in range(1, k + 1)]

    def _maybe_snapshot(self) -> None:
        due = [s for s in self._snapshot_thresholds() if self.last_snapshot_step < s <= self.step]
        initial = self.cfg.snapshot_initial and self.step == 0 and self.last_snapshot_step < 0 \
            and self.cfg.snapshot_every
        if not due and not initial:
            return
        ev = self.last_eval if self.last_eval_step == self.step else self.evaluate()
        meta = self.metadata(ev)
        meta["fraction"] = round(self.step / max(1, self.cfg.total_steps), 4)
        self.make_expert(meta).save(self.out_dir / "snapshots" / f"step_{self.step:09d}.pt")
        self.last_snapshot_step = self.step

    # ------------------------------------------------------------------ main loop
    def _session_time(self) -> float:
        return time.time() - self._t0 if hasattr(self, "_t0") else 0.0

    def train(self, callback: Callable[["ExpertTrainer"], None] | None = None) -> dict[str, Any]:
        """Train until `cfg.total_steps`; returns the final summary (also printed as the last JSON line).

        `callback(trainer)` runs after every iteration (after any checkpoint of that iteration).
        """
        cfg = self.cfg
        self._t0 = self._last_ckpt_time = self._last_log = time.time()
        self._last_log_step = -1
        self._timers: dict[str, float] = collections.defaultdict(float)
        start_step = self.step
        tag = f"[{cfg.algo}]"
        if self.resumed_from is not None:
            self.log(f"{tag} resuming {self.task_id} from {self.ckpt_path} at step {self.step}")
        self.log(f"{tag} {self.task_id}: obs {self.obs_dim}, act {self.act_dim}, {self.describe()}, "
                 f"total {cfg.total_steps} steps -> {self.out_dir}")
        final_ev: dict[str, Any] | None = None
        with contextlib.ExitStack() as stack:
            stop = stack.enter_context(stop_requests(lambda msg: self.log(f"{tag} {msg}")))
            stack.callback(self.close)
            if self.step < cfg.total_steps:
                self._maybe_snapshot()
                self.start()
            stats: Mapping[str, float] = {}
            while self.step < cfg.total_steps:
                t0 = time.time()
                stats = self.iterate()
                t1 = time.time()
                self.iteration += 1
                if cfg.eval_interval and self.step - max(self.last_eval_step, 0) >= cfg.eval_interval:
                    self.evaluate()
                self._maybe_snapshot()
                now = time.time()
                self._timers["train"] += t1 - t0
                self._timers["eval"] += now - t1
                if now - self._last_log >= cfg.log_interval_s:
                    self._progress(start_step, stats)
                    self._last_log, self._last_log_step = now, self.step
                if now - self._last_ckpt_time >= cfg.checkpoint_minutes * 60:
                    self.save_checkpoint()
                if callback is not None:
                    callback(self)
                if stop.signal is not None:
                    break
            if stop.signal is not None:
                self.save_checkpoint()
                self.log(f"{tag} stopped by {stop.signal} at step {self.step}: checkpoint saved; "
                         "run the same command again to resume")
                final_ev = self.last_eval
            else:
                final_ev = self.last_eval if (self.last_eval_step == self.step and self.last_eval) \
                    else self.evaluate()
                self._maybe_snapshot()
                if stats and self._last_log_step != self.step:
                    self._progress(start_step, stats)
                self.save_checkpoint()
                self.make_expert(self.metadata(final_ev)).save(self.out_dir / "final.pt")
        session = self._session_time()
        final = dict.fromkeys(("eval_return_mean", "eval_return_std", "eval_episodes"))   # stopped before any eval
        if final_ev is not None:
            final.update(eval_return_mean=round(final_ev["return_mean"], 2),
                         eval_return_std=round(final_ev["return_std"], 2), eval_episodes=final_ev["episodes"])
        summary = {"task_id": self.task_id, "algo": cfg.algo, "stopped_by_signal": stop.signal, **final,
                   "best_eval_return": round(self.best_eval, 2), "env_steps": self.step,
                   "wall_time_s": round(self.wall_time + session, 1), "session_wall_time_s": round(session, 1),
                   "steps_per_s": round((self.step - start_step) / max(session, 1e-9), 1),
                   "resumed_from": self.resumed_from, "device": str(self.device), "num_envs": cfg.num_envs,
                   "out_dir": str(self.out_dir), "best_path": str(self.out_dir / "best.pt")}
        self.log(json.dumps(summary))
        return summary

    def _progress(self, start_step: int, stats: Mapping[str, float]) -> None:
        elapsed = self._session_time()
        sps = (self.step - start_step) / max(elapsed, 1e-9)
        rets = [r for r, _ in self.recent]
        ret = f"{np.mean(rets):.1f} (n={len(rets)})" if rets else "n/a"
        length = f"{np.mean([n for _, n in self.recent]):.0f}" if rets else "n/a"
        ev = f"{self.last_eval['return_mean']:.1f}" if self.last_eval else "n/a"
        total = sum(self._timers.values()) or 1.0
        split = " ".join(f"{k} {100 * v / total:.0f}%" for k, v in self._timers.items())
        self.log(f"[{self.cfg.algo}] step {self.step}/{self.cfg.total_steps} "
                 f"({100 * self.step / self.cfg.total_steps:.0f}%) | {sps:.0f} steps/s | return {ret} len {length} | "
                 f"eval {ev} (best {self.best_eval:.1f}) | t {self.wall_time + elapsed:.0f}s ({split}) | "
                 f"{self.progress_suffix(stats)}")

    def close(self) -> None:
        for attr in ("envs", "eval_envs"):
            env = getattr(self, attr, None)
            if env is not None:
                env.close()
                setattr(self, attr, None)
