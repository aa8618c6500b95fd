"""`build_agent(name, env_info, cfg)`: an `ILAgent` from an `experiment_configs/algo/<name>.yaml` config.

Every algorithm config has the same shape (the keys the experiment runner reads):

    name: lsiq                 # registry name (loco_il.algorithms.ALGORITHMS)
    policy:                    # the GaussianPolicy: hidden sizes, init_log_std (unsquashed policies only),
                               # log_std_bounds (tanh-squashed policies only)
      hidden: [256, 256]
    core:                      # online algorithms only: how mushroom-rl's Core drives the agent
      n_steps_per_fit: 1
      n_env_steps: 1000000     # default training budget (env steps)
    pretrain_steps: 100000     # offline algorithms only (BC): default budget in gradient steps
    params: {...}              # keyword arguments of the agent's constructor; for the SAC-based agents also
                               # the ablations (common/ablations.py), flat keys gathered into one `Ablations`

The policy is tanh-squashed for the SAC-based agents (IQ-Learn, LS-IQ, SQIL: `OffPolicyILAgent`) and
unsquashed with a state-independent log-std for the others (BC, GAIL, VAIL, GAIfO), as their constructors
expect. Unknown constructor keywords fail here, naming the keyword and the agent's accepted ones
(`agent_kwargs`, which the experiment runner also calls before anything slow).
"""
from __future__ import annotations

import inspect
from typing import Any, Mapping

from loco_il.algorithms.common.ablations import ABLATION_NAMES, split_ablations
from loco_il.algorithms.common.agent_base import ALGORITHMS, ILAgent
from loco_il.algorithms.common.agent_base import get_algorithm as _get_registered
from loco_il.rl.networks import GaussianPolicy
from loco_il.utils.plain import to_plain

#: default training budget when an algorithm config gives none
DEFAULT_ENV_STEPS = 1_000_000


def import_all() -> dict[str, type[ILAgent]]:
    """Import every algorithm module of `loco_il.algorithms` (agents register themselves on import)."""
    import importlib
    import pkgutil

    import loco_il.algorithms as pkg
    for mod in pkgutil.iter_modules(pkg.__path__):
        if not mod.ispkg and mod.name != "factory":
            importlib.import_module(f"{pkg.__name__}.{mod.name}")
    return ALGORITHMS


def get_algorithm(name: str) -> type[ILAgent]:
    """`agent_base.get_algorithm` after importing every algorithm module."""
    import_all()
    return _get_registered(name)


def is_offpolicy(cls: type[ILAgent]) -> bool:
    from loco_il.algorithms.common.sac import OffPolicyILAgent
    return issubclass(cls, OffPolicyILAgent)


def is_offline(cls: type[ILAgent], cfg: Mapping[str, Any]) -> bool:
    """An agent trained without environment interaction: a class attribute `offline = True`, or one with
    `pretrain` and no `core.n_env_steps` in its config (BC)."""
    flag = getattr(cls, "offline", None)
    if flag is not None:
        return bool(flag)
    return hasattr(cls, "pretrain") and not (cfg.get("core") or {}).get("n_env_steps")


def default_budget(cfg: Mapping[str, Any]) -> int:
    """The algorithm's own training budget: `pretrain_steps` (offline) or `core.n_env_steps`."""
    cls = get_algorithm(cfg["name"])
    if is_offline(cls, cfg):
        return int(cfg.get("pretrain_steps") or 100_000)
    return int((cfg.get("core") or {}).get("n_env_steps") or DEFAULT_ENV_STEPS)


def steps_per_fit(cfg: Mapping[str, Any]) -> int:
    """`core.n_steps_per_fit` (1 for off-policy agents, the on-policy batch for GAIL/VAIL/GAIfO)."""
    cls = get_algorithm(cfg["name"])
    default = 1 if is_offpolicy(cls) else 1024
    return int((cfg.get("core") or {}).get("n_steps_per_fit") or default)


def build_policy(cls: type[ILAgent], obs_dim: int, act_dim: int, policy_cfg: Mapping[str, Any]) -> GaussianPolicy:
    pc = dict(policy_cfg or {})
    hidden = tuple(int(h) for h in pc.pop("hidden", (256, 256)))
    init_log_std = float(pc.pop("init_log_std", 0.0))
    squash = is_offpolicy(cls)
    bounds = pc.pop("log_std_bounds", None)
    extra = {}
    if bounds is not None:
        if not squash:
            raise ValueError(f"policy.log_std_bounds: {cls.__name__}'s policy has a free (unclamped) log-std; "
                             "the bounds apply to the tanh-squashed policies of the off-policy learners")
        if len(bounds) != 2:
            raise ValueError(f"policy.log_std_bounds must be [min, max], got {bounds}")
        extra["log_std_bounds"] = (float(bounds[0]), float(bounds[1]))
    if pc:
        raise ValueError(f"unknown policy keys {sorted(pc)} (known: hidden, init_log_std, log_std_bounds)")
    return GaussianPolicy(obs_dim, act_dim, hidden=hidden, squash=squash, init_log_std=init_log_std, **extra)


def _constructor_params(cls: type[ILAgent]) -> tuple[set[str], bool]:
    """The keyword names `cls`'s constructors take along the MRO (down to the first without **kwargs), and whether
    that chain still ends in **kwargs (then any name passes)."""
    accepted: set[str] = set()
    open_kwargs = False
    for klass in cls.__mro__:
        if klass is object or "__init__" not in vars(klass):
            continue
        sig = inspect.signature(klass.__init__)
        accepted.update(n for n, p in sig.parameters.items() if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL))
        if not any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values()):
            open_kwargs = False
            break
        open_kwargs = True
        if klass is ILAgent:
            break
    return accepted - {"self", "mdp_info", "policy_module", "device", "seed"}, open_kwargs


def agent_kwargs(cls: type[ILAgent], cfg: Mapping[str, Any]) -> dict[str, Any]:
    """The keyword arguments of `cls`'s constructor from an algorithm config's `params`: YAML lists as tuples (for
    Sequence arguments), and for an agent that takes `ablations` (the SAC-based ones) the flat ablation keys
    gathered into one `Ablations`. ValueError (one line) for a key the constructor does not take or an ablation
    value out of range."""
    params = dict(cfg.get("params") or {})
    for key, value in params.items():  # YAML lists -> tuples for Sequence arguments
        if isinstance(value, list):
            params[key] = tuple(value)
    accepted, open_kwargs = _constructor_params(cls)
    takes_ablations = "ablations" in accepted
    if takes_ablations:   # configs give the ablations as flat keys, not as one `ablations` mapping
        accepted = (accepted - {"ablations"}) | set(ABLATION_NAMES)
    unknown = sorted(set(params) - accepted)
    if unknown and not open_kwargs:
        raise ValueError(f"{cls.pretty_name()} has no parameter(s) {unknown}; accepted: {sorted(accepted)}")
    if takes_ablations:
        ablations, params = split_ablations(params)
        params["ablations"] = ablations
    return params


def build_agent(name: str | None, env_info: Any, cfg: Mapping[str, Any], *, seed: int | None = None,
                device: str = "cpu") -> ILAgent:
    """Build the agent described by an algorithm config (see the module docstring)."""
    cfg = {} if cfg is None else to_plain(cfg)
    name = name or cfg.get("name")
    cls = get_algorithm(name)
    obs_dim = int(env_info.observation_space.shape[0])
    act_dim = int(env_info.action_space.shape[0])
    policy = build_policy(cls, obs_dim, act_dim, cfg.get("policy") or {})
    return cls(env_info, policy, device=device, seed=seed, **agent_kwargs(cls, cfg))


__all__ = ["build_agent", "agent_kwargs", "get_algorithm", "import_all", "build_policy", "default_budget",
           "steps_per_fit", "is_offline", "is_offpolicy"]
