"""Experts: the policies that generate the `perfect` and `preference` datasets, and their training.

    from loco_il.experts import load_expert
    expert = load_expert("runs/experts/Hopper.run/seed0/best.pt")
    action = expert(obs)                      # deterministic (Gaussian mean), in [-1, 1]

* `files.py`     where a task's expert is found (shipped, ``$LOCO_IL_EXPERTS``) and how it is loaded
* `registry.py`  built-in experts that need no file (`trot.py`: the quadrupeds' trot controller)
* `policy.py`    `ExpertPolicy` and its file format; `tracking/`: motion-tracking experts

Train with `python -m loco_il.experts train task=Hopper.run total_steps=2000000 num_envs=16 out_dir=...`.
"""
from loco_il.experts.policy import ExpertPolicy, load_expert

__all__ = ["ExpertPolicy", "load_expert", "PPO", "PPOTrainer", "TrainConfig", "compute_gae", "train"]


def __getattr__(name: str):   # the trainer pulls in the env stack; import it on first use
    if name in ("PPO", "PPOTrainer", "TrainConfig", "compute_gae", "train", "RunningMeanStd"):
        from loco_il.experts import ppo
        return getattr(ppo, name)
    raise AttributeError(name)
