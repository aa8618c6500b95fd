"""Signals and async vector envs: the trainer (parent) keeps its Ctrl-C handler, the workers ignore it."""
import os
import signal
import time

import numpy as np

from loco_il.experts.vec import make_vec_env

TASK = "InvertedPendulum.balance"


def test_async_workers_ignore_sigint_and_parent_keeps_its_handler():
    def handler(signum, frame):  # stands in for the trainer's "stop after this iteration"
        pass

    previous = signal.signal(signal.SIGINT, handler)
    envs = make_vec_env(TASK, 2, async_mode=True)
    try:
        # AsyncVectorEnv builds one env in the parent to read the spaces: that must not touch the handler
        assert signal.getsignal(signal.SIGINT) is handler
        envs.reset(seed=0)
        for process in envs.processes:
            os.kill(process.pid, signal.SIGINT)
        time.sleep(0.5)
        obs, *_ = envs.step(np.zeros(envs.action_space.shape, dtype=np.float32))
        assert obs.shape[0] == 2 and all(p.is_alive() for p in envs.processes)
    finally:
        envs.close()
        signal.signal(signal.SIGINT, previous)


def test_sync_envs_leave_signals_alone():
    before = signal.getsignal(signal.SIGINT)
    envs = make_vec_env(TASK, 2, async_mode=False)
    envs.close()
    assert signal.getsignal(signal.SIGINT) is before
