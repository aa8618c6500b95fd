"""Retargeting quality and speed: every humanoid x {walk, run} on the shared motion-capture clips.

Usage::

    python benchmarks/retarget_quality.py [--robots UnitreeH1 G1 ...] [--tasks walk run]
    python benchmarks/retarget_quality.py --figure UnitreeH1 --task walk --frame 60   # docs/retarget_<robot>.png

For each robot with a keypoint map (loco_il/motion/mocap/robot_maps.py) and each task, the task's
clips (``loco_il.motion.mocap.clips.TASK_CLIPS``: walk = DeepMimic walk repeated to 10 s + CMU 131_01/02,
run = DeepMimic run + jog, each repeated to 10 s) are retargeted at the robot's control rate with the
default options, without the dataset cache, and one line is printed:

* frames: retargeted frames (all clips);
* kp err: mean distance between the robot's keypoints and their targets (m);
* kp uni: the same against the uniformly scaled human keypoints (m; robot proportions included);
* slide: mean horizontal speed of the robot's ankle / toe points during their contacts (m/s);
* pen mean / max: depth of the lowest sole point below the floor (m);
* in lim: fraction of frames with every limited joint inside its range;
* term: fraction of transitions the task's termination rule would end (height / orientation bounds;
  "-" when the body has no such task: then its walk env is used);
* s: wall-clock seconds of the retargeting (one core).

Needs ../shared/mocap (or $LOCO_IL_MOCAP); robots whose model files cannot be loaded are reported
and skipped.  ``--figure`` renders one frame (MuJoCo's renderer when an OpenGL backend is available,
MUJOCO_GL=egl; a matplotlib stick figure otherwise) of the retargeted clip next to the source
skeleton (grey) and writes docs/retarget_<robot>.png.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from loco_il import LocoEnv  # noqa: E402
from loco_il.datasets.real import result_to_trajectories  # noqa: E402
from loco_il.motion.mocap.clips import TASK_CLIPS, find_motion_files, load_motion  # noqa: E402
from loco_il.motion.mocap.retarget import RobotKinematics, retarget_clip  # noqa: E402
from loco_il.motion.mocap.robot_maps import ROBOT_MAPS  # noqa: E402

BONES = [("l_hip", "r_hip"), ("l_hip", "l_knee"), ("l_knee", "l_ankle"), ("l_ankle", "l_toe"),
         ("r_hip", "r_knee"), ("r_knee", "r_ankle"), ("r_ankle", "r_toe"), ("hip_center", "torso"),
         ("torso", "neck"), ("neck", "head"), ("neck", "l_shoulder"), ("neck", "r_shoulder"),
         ("l_shoulder", "l_elbow"), ("l_elbow", "l_wrist"), ("r_shoulder", "r_elbow"), ("r_elbow", "r_wrist")]


def env_for(body: str, task: str):
    """(env, task registered?) -- the body's env for the task, else its walk (or only) env."""
    names = LocoEnv.get_all_task_names()
    for tid in (f"{body}.{task}.real", f"{body}.{task}.perfect"):
        if tid in names:
            return LocoEnv.make(tid), True
    fallback = [n for n in names if n.startswith(body + ".") and n.split(".")[0] == body]
    if not fallback:
        raise KeyError(f"{body} is not registered")
    walk = [n for n in fallback if ".walk." in n]
    return LocoEnv.make((walk or fallback)[0]), False


def run_one(body: str, task: str) -> dict:
    env, has_task = env_for(body, task)
    specs = TASK_CLIPS[task]
    paths = find_motion_files(specs, what=f"the {task} benchmark")
    kin = RobotKinematics(env)
    t0 = time.perf_counter()
    results = []
    for spec, path in zip(specs, paths):
        clip, n = load_motion(path, spec)
        results.append(retarget_clip(env, clip, n_cycles=n, kinematics=kin))
    seconds = time.perf_counter() - t0
    frames = np.array([r.metrics["frames"] for r in results], dtype=float)

    def avg(key):
        return float(np.average([r.metrics[key] for r in results], weights=frames))

    term = None
    if has_task:
        env.reset()
        term = result_to_trajectories(env, results).info["terminated_fraction"]
    return {"robot": body, "task": task, "frames": int(frames.sum()), "kp": avg("keypoint_error_m"),
            "kp_uni": avg("keypoint_error_uniform_m"), "slide": avg("foot_sliding_mps"),
            "pen_mean": avg("penetration_mean_m"), "pen_max": max(r.metrics["penetration_max_m"] for r in results),
            "in_lim": avg("in_limits_fraction"), "term": term, "seconds": seconds,
            "dropped": results[0].metrics["dropped_keypoints"]}


def table(robots, tasks) -> None:
    head = (f"{'robot':18s} {'task':5s} {'frames':>6s} {'kp err':>7s} {'kp uni':>7s} {'slide':>6s} "
            f"{'pen mean':>8s} {'pen max':>8s} {'in lim':>6s} {'term':>5s} {'s':>5s}")
    print(head)
    print("-" * len(head))
    total = 0.0
    for body in robots:
        for task in tasks:
            try:
                r = run_one(body, task)
            except Exception as exc:           # report and go on (missing model files, unregistered body)
                print(f"{body:18s} {task:5s} FAILED: {type(exc).__name__}: {exc}")
                continue
            total += r["seconds"]
            term = "-" if r["term"] is None else f"{r['term']:.3f}"
            print(f"{r['robot']:18s} {r['task']:5s} {r['frames']:6d} {r['kp']:7.4f} {r['kp_uni']:7.3f} "
                  f"{r['slide']:6.3f} {r['pen_mean']:8.5f} {r['pen_max']:8.5f} {r['in_lim']:6.3f} {term:>5s} "
                  f"{r['seconds']:5.1f}", flush=True)
    print(f"total retargeting time {total:.1f}s")


# ----------------------------------------------------------------------------- figure


def _human_segments(points: dict, frame: int, offset: np.ndarray) -> list:
    p = {k: v[frame] + offset for k, v in points.items()}
    if "l_hip" in p and "r_hip" in p:
        p["hip_center"] = 0.5 * (p["l_hip"] + p["r_hip"])
    return [(p[a], p[b]) for a, b in BONES if a in p and b in p]


def render_mujoco(env, res, frame: int, offset: np.ndarray, size=(720, 960)) -> np.ndarray:
    import mujoco

    m = env.model
    m.vis.global_.offwidth = max(m.vis.global_.offwidth, size[1])
    m.vis.global_.offheight = max(m.vis.global_.offheight, size[0])
    renderer = mujoco.Renderer(m, height=size[0], width=size[1])
    d = mujoco.MjData(m)
    d.qpos[:] = res.qpos[frame]
    mujoco.mj_forward(m, d)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    hc = 0.5 * (res.robot_points["l_hip"][frame] + res.robot_points["r_hip"][frame])
    height = ROBOT_MAPS[env.body_name].height
    cam.lookat[:] = hc + offset / 2 + np.array([0.0, 0.0, 0.05 * height])
    cam.distance = 2.6 * height + 0.8 * float(np.linalg.norm(offset))
    cam.azimuth, cam.elevation = 60.0, -12.0
    renderer.update_scene(d, camera=cam)
    scn = renderer.scene
    width = 0.025 * height
    for a, b in _human_segments(res.source_points, frame, offset):
        if scn.ngeom >= scn.maxgeom:
            break
        g = scn.geoms[scn.ngeom]
        mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                            np.array([0.55, 0.55, 0.6, 1.0], dtype=np.float32))
        mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_CAPSULE, width, a, b)
        scn.ngeom += 1
    img = renderer.render().copy()
    renderer.close()
    return img


def render_sticks(env, res, frames, path: Path, title: str) -> None:
    """Side views (x-z) of the source skeleton (grey) next to the robot (blue) at several frames; each pair
    is drawn around its own hip centre, pairs left to right in time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kin = RobotKinematics(env)
    m, d = env.model, kin.data
    h = ROBOT_MAPS[env.body_name].height
    fig, ax = plt.subplots(figsize=(2.4 * len(frames), 3.6))
    for k, f in enumerate(frames):
        x0 = k * 1.3 * h
        hc_s = 0.5 * (res.source_points["l_hip"][f] + res.source_points["r_hip"][f])
        shift_s = np.array([x0 - 0.28 * h - hc_s[0], 0.0, 0.0])
        for i, (a, b) in enumerate(_human_segments(res.source_points, f, shift_s)):
            ax.plot([a[0], b[0]], [a[2], b[2]], color="0.5", lw=2.5, solid_capstyle="round",
                    label="source skeleton (scaled)" if k == i == 0 else None)
        kin.forward(res.qpos[f])
        hc_r = 0.5 * (res.robot_points["l_hip"][f] + res.robot_points["r_hip"][f])
        dx = x0 + 0.28 * h - hc_r[0]
        first = True
        for b in range(1, m.nbody):
            p = m.body_parentid[b]
            if p > 0:
                ax.plot([d.xpos[p, 0] + dx, d.xpos[b, 0] + dx], [d.xpos[p, 2], d.xpos[b, 2]], color="tab:blue", lw=2.5,
                        solid_capstyle="round", label=f"{env.body_name} (retargeted)" if k == 0 and first else None)
                first = False
        pts = kin.points()
        ax.plot(pts[:, 0] + dx, pts[:, 2], "o", color="tab:blue", ms=3)
        for s_ in kin.sole:
            w = kin._sole_world(s_)
            ax.plot(w[:, 0] + dx, w[:, 2], ".", color="tab:green", ms=2)
        ax.text(x0, -0.08 * h, f"t = {f * res.dt:.2f} s", ha="center", fontsize=8)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_aspect("equal")
    ax.set_ylim(-0.12 * h, 1.1 * h)
    ax.set_yticks([0, round(h / 2, 1), round(h, 1)])
    ax.set_ylabel("z (m)")
    ax.set_xticks([])
    ax.legend(loc="upper right", fontsize=7, ncol=2)
    ax.set_title(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure(body: str, task: str, frame: int, out: Path) -> Path:
    env, _ = env_for(body, task)
    spec = TASK_CLIPS[task][0]
    path = find_motion_files([spec])[0]
    clip, n = load_motion(path, spec)
    res = retarget_clip(env, clip, n_cycles=min(n, 2))
    frame = min(frame, res.n_frames - 1)
    cycle = int(round(clip.duration / res.dt))          # one gait cycle of the (looped) clip
    frames = [min(res.n_frames - 1, frame + k * cycle // 5) for k in range(5)]
    height = ROBOT_MAPS[body].height
    title = (f"{path.name} -> {body} ({task}): keypoint error {res.metrics['keypoint_error_m'] * 100:.1f} cm, "
             f"foot sliding {res.metrics['foot_sliding_mps'] * 100:.1f} cm/s, "
             f"penetration {res.metrics['penetration_max_m'] * 100:.1f} cm, "
             f"joints in limits {100 * res.metrics['in_limits_fraction']:.0f}% of frames")
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        import imageio.v2 as imageio
        offset = np.array([0.0, -0.9 * height, 0.0])     # the skeleton stands beside the robot
        img = render_mujoco(env, res, frame, offset)
        imageio.imwrite(out, img)
        print(f"rendered with MuJoCo ({os.environ.get('MUJOCO_GL', 'default GL')}): {title}")
    except Exception as exc:                              # no OpenGL here: a stick figure instead
        print(f"MuJoCo rendering unavailable ({type(exc).__name__}: {exc}); drawing stick figures")
        render_sticks(env, res, frames, out, title)
    print(f"wrote {out}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", nargs="*", default=sorted(ROBOT_MAPS))
    ap.add_argument("--tasks", nargs="*", default=["walk", "run"])
    ap.add_argument("--figure", metavar="ROBOT", help="render docs/retarget_<ROBOT>.png instead of the table")
    ap.add_argument("--task", default="walk")
    ap.add_argument("--frame", type=int, default=60)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    warnings.filterwarnings("ignore")
    if args.figure:
        figure(args.figure, args.task, args.frame, args.out or ROOT / "docs" / f"retarget_{args.figure}.png")
        return
    table(args.robots, args.tasks)


if __name__ == "__main__":
    main()
