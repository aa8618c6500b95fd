"""Motion-tracking experts: PPO learns to follow a task's reference motion (its retargeted motion capture),
then the policy, with its reference and PD conversion, acts in the task env as the `perfect` expert.

* `reference.py`  one cycle of the reference motion, looped, time-scaled to the task's speed
* `settings.py`   reward weights and scales, start states, early termination, PD gains (`TrackingSettings`)
* `reward.py`     DeepMimic's tracking reward
* `controller.py` phase clock + PD targets -> the env's actions (stable PD for torque motors)
* `env.py`        `TrackingEnv`, the training / evaluation env
* `expert.py`     `TrackingExpert`, the shippable env-level expert and its file format
* `trainer.py`    `TrackingTrainer` (`python -m loco_il.experts train task=Atlas.walk algo=tracking`)
"""
