"""The base class of every imitation-learning agent in loco_il.

`ILAgent` is a mushroom-rl 1.10.1 `Agent`, so `mushroom_rl.core.Core` can drive it:
Core calls `agent.episode_start()`, `agent.draw_action(state)`, `agent.fit(dataset, **info)`
(dataset = list of `(s, a, r, s', absorbing, last)` tuples), reads `agent.preprocessors`,
sets `agent.next_action = None` and calls `agent.stop()`.

What the base class adds:
  * a registry `ALGORITHMS` of concrete agents by their lower-case `name`
    (a subclass registers itself by defining the class attribute `name`);
  * `supported_datasets` / `check_dataset_type` (which dataset types an agent can learn from);
  * `draw_action` from a torch `GaussianPolicy` (stochastic while training, the mean
    action when `agent.deterministic = True`). Agents act once per environment step, one observation at
    a time, where a torch forward costs about as much as a physics step (op dispatch, not arithmetic):
    for a CPU policy that offers `numpy_mean_log_std()` (GaussianPolicy, ObsNormalizedPolicy) the mean
    and log-std are computed with numpy on views of the parameters (`networks.NumpyMLP`), rebuilt when a
    parameter's storage is replaced; the exploration noise still comes from the agent's seeded torch
    generator, so the actions are those of the torch forward (float32 rounding aside) and reproducible.
    GPU policies and other modules use the torch forward (`_act_torch`);
  * checkpointing: `state_dict` / `load_state_dict` cover every registered module, optimizer,
    plain attribute (counters, temperature, ...) and the RNG states; `save(path)` writes them
    atomically together with the constructor arguments, so both `SomeAgent.load(path)`
    (builds a new agent) and `agent.load(path)` (restores in place) work.
    mushroom-rl's own `Agent.save/load` is not used (its torch loading breaks on torch >= 2.6).

Subclasses call `self._register_checkpoint(name, obj)` for every nn.Module / optimizer /
object with `state_dict()`/`load_state_dict()`, and `self._register_checkpoint_attr(name)`
for plain attributes (ints, floats, tensors, numpy arrays) that must survive a round trip.
The expert data is not part of a checkpoint: call `set_expert` again before resuming training.
"""
from __future__ import annotations

import os
from typing import Any, ClassVar

import numpy as np
import torch
from mushroom_rl.core import Agent
from torch import nn

from loco_il.environments.registry import DATASET_TYPES
from loco_il.rl.optim import load_optimizer_state
from loco_il.utils.atomic import atomic_torch_save


#: registry of concrete agents: lower-case name -> class
ALGORITHMS: dict[str, type["ILAgent"]] = {}


def get_algorithm(name: str) -> type["ILAgent"]:
    """Look an agent class up by its registry name (case-insensitive)."""
    try:
        return ALGORITHMS[name.lower()]
    except KeyError:
        raise KeyError(f"unknown algorithm {name!r}; known: {sorted(ALGORITHMS)}") from None


class _ModulePolicy:
    """The minimal mushroom-rl policy interface (`draw_action`, `reset`) around an agent's actor."""

    def __init__(self, agent: "ILAgent"):
        self._agent = agent

    def draw_action(self, state) -> np.ndarray:
        return self._agent._act(state)

    def reset(self) -> None:
        pass


class _HybridMethod:
    """`Cls.load(path)` calls the class-level function, `instance.load(path)` the instance one."""

    def __init__(self, cls_func, inst_func):
        self._cls_func, self._inst_func = cls_func, inst_func

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self._cls_func.__get__(objtype, type(objtype))
        return self._inst_func.__get__(obj, objtype)


class ILAgent(Agent):
    """Base of all loco_il agents; see the module docstring."""

    name: ClassVar[str] = ""
    display_name: ClassVar[str] = ""  # for messages; defaults to the class name
    supported_datasets: ClassVar[frozenset[str]] = frozenset()

    # ------------------------------------------------------------------ registry
    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "name" in cls.__dict__ and cls.name:
            key = cls.name.lower()
            if key in ALGORITHMS and ALGORITHMS[key].__qualname__ != cls.__qualname__:
                raise ValueError(f"algorithm name {key!r} registered twice "
                                 f"({ALGORITHMS[key].__qualname__} and {cls.__qualname__})")
            ALGORITHMS[key] = cls
            if not set(cls.supported_datasets).issubset(DATASET_TYPES):
                raise ValueError(f"{cls.__qualname__}.supported_datasets has unknown types")

    @classmethod
    def pretty_name(cls) -> str:
        return cls.display_name or cls.__name__

    @classmethod
    def check_dataset_type(cls, dataset_type: str) -> None:
        """Raise ValueError if this agent cannot learn from `dataset_type` datasets."""
        if dataset_type not in DATASET_TYPES:
            raise ValueError(f"unknown dataset type {dataset_type!r}; expected one of {sorted(DATASET_TYPES)}")
        if dataset_type in cls.supported_datasets:
            return
        able = [f"{c.pretty_name()} (algo={n})" for n, c in sorted(ALGORITHMS.items())
                if dataset_type in c.supported_datasets]
        hint = " (it has no expert actions)" if dataset_type == "real" else ""
        raise ValueError(f"{cls.pretty_name()} cannot learn from a '{dataset_type}' dataset{hint}; "
                         f"algorithms that can: {', '.join(able) if able else 'none registered'}")

    # ------------------------------------------------------------------ construction
    def __new__(cls, *args, **kwargs):
        obj = super().__new__(cls)
        obj._init_args = (args, dict(kwargs))  # kept so that `Cls.load(path)` can rebuild the agent
        return obj

    def __init__(self, mdp_info, policy_module: nn.Module, device: str = "cpu", seed: int | None = None):
        super().__init__(mdp_info, _ModulePolicy(self))
        self.device = torch.device(device)
        self.policy_module = policy_module.to(self.device)
        self.deterministic = False
        self.seed = seed
        self.rng = np.random.default_rng(seed)  # replay sampling etc.
        # exploration noise of draw_action; kept on the CPU so it is identical on every device
        self.torch_generator = torch.Generator()
        if seed is not None:
            self.torch_generator.manual_seed(seed)
            torch.manual_seed(seed)  # the reparameterized samples inside updates use the global RNG
        else:
            self.torch_generator.seed()
        self.expert = None
        self._numpy_actor: tuple | None = None  # (mean_log_std, viewed tensors, their data_ptrs), see _act
        self._ckpt_objects: dict[str, Any] = {}
        self._ckpt_attrs: list[str] = []
        self._register_checkpoint("policy", self.policy_module)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_numpy_actor"] = None  # closures over numpy views: rebuilt on the next action
        return state

    def _register_checkpoint(self, key: str, obj: Any) -> None:
        """Include `obj.state_dict()` (module, optimizer, buffer, ...) in checkpoints under `key`."""
        if key in self._ckpt_objects:
            raise ValueError(f"checkpoint key {key!r} registered twice")
        self._ckpt_objects[key] = obj

    def _register_checkpoint_attr(self, *names: str) -> None:
        """Include the plain attributes `names` (numbers, tensors, arrays) in checkpoints."""
        self._ckpt_attrs.extend(n for n in names if n not in self._ckpt_attrs)

    # ------------------------------------------------------------------ data
    def set_expert(self, expert) -> None:
        """Give the agent its demonstrations (`loco_il.datasets.Trajectories`-like: `.obs`,
        `.next_obs`, `.actions` (None for real datasets), `.absorbing`, `.last`)."""
        if getattr(expert, "actions", None) is None and "real" not in self.supported_datasets:
            raise ValueError(f"{self.pretty_name()} needs expert actions, the expert data has none")
        self.expert = expert

    @staticmethod
    def parse_dataset(dataset) -> dict[str, np.ndarray]:
        """mushroom-rl's list of `(s, a, r, s', absorbing, last)` tuples -> dict of stacked arrays."""
        s, a, r, s2, ab, last = zip(*dataset)
        return {"obs": np.asarray(s, dtype=np.float64), "actions": np.asarray(a, dtype=np.float64),
                "rewards": np.asarray(r, dtype=np.float64), "next_obs": np.asarray(s2, dtype=np.float64),
                "absorbing": np.asarray(ab, dtype=bool), "last": np.asarray(last, dtype=bool)}

    def to_tensor(self, x) -> torch.Tensor:
        return torch.as_tensor(np.asarray(x), dtype=torch.float32, device=self.device)

    # ------------------------------------------------------------------ acting
    def draw_action(self, state) -> np.ndarray:
        if self.phi is not None:
            state = self.phi(state)
        if self.next_action is not None:
            action, self.next_action = self.next_action, None
            return action
        return self._act(state)

    _NO_NUMPY_ACTOR = (None, (), ())  # the policy module has no numpy forward (GPU, other structure)

    def _numpy_mean_log_std(self):
        """The policy's numpy forward, rebuilt when one of the viewed tensors got a new storage (TRPO's
        `vector_to_parameters`), or None when the torch forward must be used."""
        cached = self._numpy_actor
        if cached is not None:
            fn, tensors, ptrs = cached
            if all(t.data_ptr() == p for t, p in zip(tensors, ptrs)):
                return fn
        fn, tensors = None, ()
        builder = getattr(self.policy_module, "numpy_mean_log_std", None)
        if builder is not None and self.device.type == "cpu":
            try:
                fn, tensors = builder()
            except TypeError:
                pass
        self._numpy_actor = (fn, tensors, tuple(t.data_ptr() for t in tensors)) if fn else self._NO_NUMPY_ACTOR
        return fn

    def _act(self, state) -> np.ndarray:
        # the hot path of every environment step (see the module docstring)
        mean_log_std = self._numpy_mean_log_std()
        if mean_log_std is None:
            return self._act_torch(state)
        mean, log_std = mean_log_std(np.asarray(state, dtype=np.float32).reshape(-1))
        if self.deterministic:
            pre = mean
        else:  # the same draws as _act_torch's, from the same generator
            noise = torch.randn((1, mean.shape[0]), generator=self.torch_generator).numpy()[0]
            pre = mean + np.exp(log_std) * noise
        action = np.tanh(pre) if getattr(self.policy_module, "squash", False) else pre
        return action.astype(np.float64)

    @torch.inference_mode()
    def _act_torch(self, state) -> np.ndarray:
        # no autograd bookkeeping, no distribution object
        obs = torch.as_tensor(state if isinstance(state, np.ndarray) else np.asarray(state),
                              dtype=torch.float32).reshape(1, -1)
        if self.device.type != "cpu":
            obs = obs.to(self.device)
        module = self.policy_module
        mean_log_std = getattr(module, "_mean_log_std", None)
        if mean_log_std is not None:
            loc, log_std = mean_log_std(obs)
            scale = None if self.deterministic else log_std.exp()
        else:
            dist = module.distribution(obs)
            loc, scale = dist.loc, dist.scale
        if self.deterministic:
            pre = loc
        else:
            noise = torch.randn(loc.shape, generator=self.torch_generator)
            if self.device.type != "cpu":
                noise = noise.to(self.device)
            pre = loc + scale * noise
        action = torch.tanh(pre) if getattr(module, "squash", False) else pre
        return action[0].cpu().numpy().astype(np.float64)

    def fit(self, dataset, **info):
        raise NotImplementedError

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict:
        state = {key: obj.state_dict() for key, obj in self._ckpt_objects.items()}
        state["attrs"] = {n: getattr(self, n) for n in self._ckpt_attrs}
        state["deterministic"] = self.deterministic
        state["rng"] = {"numpy": self.rng.bit_generator.state,
                        "torch_generator": self.torch_generator.get_state(),
                        "torch_global": torch.get_rng_state()}
        if torch.cuda.is_available() and self.device.type == "cuda":
            state["rng"]["cuda"] = torch.cuda.get_rng_state_all()
        return state

    def load_state_dict(self, state: dict) -> None:
        missing = set(self._ckpt_objects) - set(state)
        if missing:
            raise KeyError(f"checkpoint lacks {sorted(missing)}")
        for key, obj in self._ckpt_objects.items():
            if isinstance(obj, torch.optim.Optimizer):
                load_optimizer_state(obj, state[key])
            else:
                obj.load_state_dict(state[key])
        for n, value in state["attrs"].items():
            current = getattr(self, n, None)
            if isinstance(current, torch.Tensor) and isinstance(value, torch.Tensor):
                with torch.no_grad():
                    current.copy_(value)  # keep the identity (optimizers may hold it)
            else:
                setattr(self, n, value)
        self.deterministic = state["deterministic"]
        rng = state["rng"]
        self.rng.bit_generator.state = rng["numpy"]
        self.torch_generator.set_state(rng["torch_generator"])
        torch.set_rng_state(rng["torch_global"])
        if "cuda" in rng and torch.cuda.is_available():
            torch.cuda.set_rng_state_all(rng["cuda"])

    def save(self, path: str | os.PathLike) -> None:
        """Write the constructor arguments and `state_dict()` atomically to `path`."""
        args, kwargs = self._init_args
        atomic_torch_save({"algorithm": self.name, "class": type(self), "init_args": args,
                           "init_kwargs": kwargs, "state": self.state_dict()}, path)

    @classmethod
    def _saved_init_kwargs(cls, kwargs: dict) -> dict:
        """The constructor keyword arguments of an agent file, as this class's constructor takes them now
        (a subclass whose arguments changed converts those of older files here)."""
        return kwargs

    @staticmethod
    def _read_checkpoint(path) -> dict:
        return torch.load(path, map_location="cpu", weights_only=False)

    def _load_in_place(self, path: str | os.PathLike) -> "ILAgent":
        self.load_state_dict(self._read_checkpoint(path)["state"])
        return self

    def _load_new(cls, path: str | os.PathLike, device: str | None = None) -> "ILAgent":
        ckpt = cls._read_checkpoint(path)
        agent_cls = ckpt["class"]
        if not issubclass(agent_cls, cls):
            raise TypeError(f"{path} holds a {agent_cls.__name__}, not a {cls.__name__}")
        kwargs = agent_cls._saved_init_kwargs(dict(ckpt["init_kwargs"]))
        if device is not None:
            kwargs["device"] = device
            if torch.device(device).type != "cuda" and kwargs.get("cuda_graph"):
                kwargs["cuda_graph"] = False  # a CUDA-graph run read on another device: the same updates, eager
        agent = agent_cls(*ckpt["init_args"], **kwargs)
        agent.load_state_dict(ckpt["state"])
        return agent

    load = _HybridMethod(_load_new, _load_in_place)
