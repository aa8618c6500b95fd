"""The ablations of the SAC-based learners (`OffPolicyILAgent`): changes to a method, each off by default, that test
a hypothesis about why a learner leaves the expert (docs/algorithms.md, docs/research/ls-iq-stability.md).

They are one `Ablations` argument of the agent, apart from the method's own options, so that the constructor
shows which settings define the method and which probe it. In the configs they stay flat keys of `algo.params`
(`algo.params.conservative_weight=5`, as any other parameter); `split_ablations` gathers them.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable, Mapping


@dataclass(frozen=True)
class Ablations:
    """Every default is "off": `Ablations()` trains the method as configured.

    freeze_replay: new transitions are no longer stored, so the updates go on over the replay memory as it is
        (e.g. for a fork of a run): whether a change of behaviour comes from the data the agent collects or from
        the updates themselves.
    conservative_weight: w > 0 adds w times CQL's critic penalty (`sac.conservative_penalty`) at the agent batch's
        states, with `conservative_actions` uniform random actions against the stored one; `conservative_hinge`
        clips each state's term at 0. It tests whether a critic that ranks actions the agent never took above its
        own (the "Q gap" of benchmarks/offpolicy_diagnostics.py) is what makes a learner leave the expert; it
        costs one more critic forward on (K + 1) x batch_size rows per update.
    actor_bc_alpha: the actor's loss becomes TD3+BC's, SAC's loss scaled by actor_bc_alpha / mean |Q| plus the
        squared distance of the policy's mean action to the expert's action at the expert batch's states
        (`sac.bc_regularized_actor_loss`): a policy constraint that tests whether anchoring the actor at the
        demonstrations keeps it at the expert. None: off. Needs the expert's actions.
    critic_layer_norm: a LayerNorm after each hidden layer of every critic head, as in Ball et al. 2023 (RLPD),
        where it keeps a critic trained on offline (here: expert) data from extrapolating to large values on
        actions the data does not cover.
    """

    freeze_replay: bool = False
    conservative_weight: float = 0.0
    conservative_actions: int = 10
    conservative_hinge: bool = False
    actor_bc_alpha: float | None = None
    critic_layer_norm: bool = False

    def __post_init__(self) -> None:
        # values from a config may be ints for floats (`conservative_weight=5`): stored as the declared type
        casts: dict[str, Callable[[Any], Any]] = {"freeze_replay": bool, "conservative_weight": float,
                                                  "conservative_actions": int, "conservative_hinge": bool,
                                                  "critic_layer_norm": bool}
        for name, cast in casts.items():
            object.__setattr__(self, name, _cast(name, getattr(self, name), cast))
        if self.actor_bc_alpha is not None:
            object.__setattr__(self, "actor_bc_alpha", _cast("actor_bc_alpha", self.actor_bc_alpha, float))
            if not self.actor_bc_alpha > 0.0:
                raise ValueError(f"actor_bc_alpha must be > 0 (or None: off), got {self.actor_bc_alpha}")
        if self.conservative_weight < 0.0 or self.conservative_actions < 1:
            raise ValueError("conservative_weight must be >= 0 and conservative_actions >= 1, got "
                             f"{self.conservative_weight} and {self.conservative_actions}")


def _cast(name: str, value: Any, cast: Callable[[Any], Any]) -> Any:
    try:
        return cast(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={value!r}: expected {'true or false' if cast is bool else 'a number'}") from None


#: the ablations' names, as config keys (`algo.params.<name>`)
ABLATION_NAMES: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(Ablations))


def split_ablations(params: Mapping[str, Any]) -> tuple[Ablations, dict[str, Any]]:
    """(the `Ablations` among an algorithm config's flat `params`, the other params)."""
    chosen = {k: v for k, v in params.items() if k in ABLATION_NAMES}
    return Ablations(**chosen), {k: v for k, v in params.items() if k not in ABLATION_NAMES}


__all__ = ["Ablations", "ABLATION_NAMES", "split_ablations"]
