"""GAIfO: Generative Adversarial Imitation from Observation (Torabi et al. 2018), TRPO policy step.

GAIL with a discriminator on state transitions D(s, s') instead of (s, a): it needs no expert actions,
so it also learns from 'real' (motion-capture) datasets. Loss and reward are GAIL's:
BCE with expert label 1 and r = -log(1 - D(s, s')).
"""
from __future__ import annotations

from typing import ClassVar

from loco_il.algorithms.gail import GAIL


class GAIfO(GAIL):
    name: ClassVar[str] = "gaifo"
    display_name: ClassVar[str] = "GAIfO"

    def __init__(self, mdp_info, policy_module, device: str = "cpu", seed: int | None = None, **kwargs):
        for fixed in ("use_actions", "use_next_states"):
            if fixed in kwargs:
                raise TypeError(f"GAIfO always discriminates (s, s'); {fixed!r} cannot be set")
        super().__init__(mdp_info, policy_module, device, seed, use_actions=False, use_next_states=True, **kwargs)
