"""Reinforcement-learning building blocks below the experts and the imitation learners: networks (`networks`),
the replay memory (`replay`), the SAC core (`sac`) and optimizer-state loading (`optim`). Nothing here knows
about environments, datasets or imitation."""
