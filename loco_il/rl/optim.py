"""Optimizer state loading that keeps the configured hyper-parameters (used by every learner's resume and fork)."""
from __future__ import annotations

import torch


def load_optimizer_state(optimizer: torch.optim.Optimizer, state: dict) -> None:
    """Load an optimizer's moments and step counts from `state`, keeping its configured hyper-parameters.

    torch's `Optimizer.load_state_dict` also restores the saved learning rate (every param-group setting),
    so a `fork_from` with a changed `actor_lr` or `critic_lr` would silently train with the source run's
    rates. The configuration is the source of truth; for a plain resume the two agree.
    """
    configured = [{k: v for k, v in group.items() if k != "params"} for group in optimizer.param_groups]
    optimizer.load_state_dict(state)
    for group, settings in zip(optimizer.param_groups, configured):
        group.update(settings)
