"""Reference motion: what the robots should move like, below the experts that follow it and the datasets
that record it.

* :mod:`loco_il.motion.mocap`  human motion capture (BVH, DeepMimic), the task's clips (:mod:`.mocap.clips`,
  the shipped files in ``mocap/data/``) and their retargeting to each robot (:mod:`.mocap.retarget`);
* :mod:`loco_il.motion.gait`   the quadrupeds' trot generator (CPG, leg IK, PD/Raibert controller).

This layer may import `loco_il.environments` (and `loco_il.utils`) only.
"""
