"""Rendering: RGB frames headless (MUJOCO_GL=egl or osmesa) and a passive viewer where a display exists."""
from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import mujoco
import numpy as np

from loco_il.environments.episodes import UniformRandomPolicy, run_episode

if TYPE_CHECKING:
    from loco_il.environments.base import LocoEnv


def _tracking_camera(env: "LocoEnv") -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    cam.trackbodyid = env._root_body
    # scale with the robot's size (its root height), not the scene extent, which the floor dominates
    height = float(np.clip(env.data.xpos[env._root_body, 2], 0.3, 1.5))
    cam.distance = 3.0 * height
    cam.elevation = -15.0
    cam.azimuth = 90.0  # side view of motion along +x
    return cam


def render_frame(env: "LocoEnv") -> np.ndarray | None:
    """One frame for `render_mode="rgb_array"`; opens/syncs a window for `"human"`."""
    if env.render_mode == "human":
        if env._viewer is None:
            from mujoco import viewer
            env._viewer = viewer.launch_passive(env.model, env.data)
        env._viewer.sync()
        return None
    if env._renderer is None:
        height, width = env.render_size
        env.model.vis.global_.offwidth = max(env.model.vis.global_.offwidth, width)
        env.model.vis.global_.offheight = max(env.model.vis.global_.offheight, height)
        env._renderer = mujoco.Renderer(env.model, height=height, width=width)
        env._camera = _tracking_camera(env)
    env._renderer.update_scene(env.data, camera=env._camera)
    return env._renderer.render().copy()


def record_episode(env: "LocoEnv", policy: Callable[[np.ndarray], np.ndarray] | None, path: str | os.PathLike | None,
                   max_steps: int | None = None, fps: int | None = None, seed: int = 0,
                   strip: str | os.PathLike | None = None, strip_frames: int = 6) -> dict:
    """Run one episode from `env.seed(seed); env.reset()` (`loco_il.environments.episodes.run_episode`: random
    actions if `policy` is None; a policy's `start_episode(env, seed)` hook is called after the reset), write an mp4
    to `path` and/or a PNG strip of `strip_frames` evenly spaced frames to `strip`; return
    {'return', 'steps', 'path', 'strip'}."""
    import imageio

    if policy is None:
        policy = UniformRandomPolicy(env.info.action_space.shape, np.random.default_rng(seed))
    frames: list[np.ndarray] = []
    previous = env.render_mode
    env.render_mode = "rgb_array"
    try:       # a frame of the start state and one after every step
        episode = run_episode(env, policy, seed, max_steps or env.info.horizon,
                              on_state=lambda e: frames.append(e.render()))
    finally:
        env.render_mode = previous
    out = {"return": episode.ret, "steps": episode.length, "path": None, "strip": None}
    if path is not None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fps = fps or int(round(1.0 / env.dt))
        tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
        imageio.mimsave(tmp, frames, fps=fps, macro_block_size=1)
        os.replace(tmp, path)
        out["path"] = str(path)
    if strip is not None:
        strip = Path(strip)
        strip.parent.mkdir(parents=True, exist_ok=True)
        picks = np.linspace(0, len(frames) - 1, max(1, int(strip_frames))).round().astype(int)
        tmp = strip.with_name(f".{strip.stem}.tmp{strip.suffix}")
        imageio.imwrite(tmp, np.concatenate([frames[i] for i in picks], axis=1), extension=strip.suffix)
        os.replace(tmp, strip)
        out["strip"] = str(strip)
    return out
