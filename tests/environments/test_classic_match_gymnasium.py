"""The classic bodies reproduce Gymnasium v5's rewards and terminations step by step,
so returns on our tasks compare with published Hopper/Walker2d/... numbers."""
import gymnasium as gym
import numpy as np
import pytest

from loco_il import LocoEnv

CASES = [("Hopper", "Hopper-v5"), ("Walker2d", "Walker2d-v5"), ("HalfCheetah", "HalfCheetah-v5"),
         ("Ant", "Ant-v5"), ("Humanoid", "Humanoid-v5"), ("HumanoidStandup", "HumanoidStandup-v5"),
         ("InvertedPendulum", "InvertedPendulum-v5")]


@pytest.mark.parametrize("ours, theirs", CASES)
def test_rewards_and_terminations_equal_gymnasium_v5(ours, theirs):
    env = LocoEnv.make(ours, seed=0)
    ref = gym.make(theirs).unwrapped
    ref.reset(seed=0)
    env.reset()
    assert env.dt == pytest.approx(ref.dt)
    qpos, qvel = ref.data.qpos.copy(), ref.data.qvel.copy()
    env.set_sim_state(qpos, qvel)
    env.data.qacc_warmstart[:] = ref.data.qacc_warmstart   # the solver's warm start is part of the state
    rng = np.random.default_rng(0)
    lo, hi = env.model.actuator_ctrlrange.T
    for t in range(60):
        a = rng.uniform(-1, 1, env.model.nu)
        _, r_ours, term_ours, _ = env.step(a)
        _, r_ref, term_ref, _, _ = ref.step((lo + hi) / 2 + a * (hi - lo) / 2)
        assert r_ours == pytest.approx(r_ref, rel=1e-6, abs=1e-6), f"step {t}"
        assert term_ours == term_ref, f"step {t}"
        if term_ref:
            break
