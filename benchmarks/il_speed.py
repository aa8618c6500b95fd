"""Speed of the imitation-learning agents next to bare baselines, side by side in one process.

Part 1 -- off-policy update cost. One `update()` of each SAC-based agent (IQ-Learn, LS-IQ, LSIQ-fO, SQIL)
built from its `experiment_configs/algo/*.yaml` config ([256, 256] actor and critic, 256 agent + 256
expert samples per update) against a bare PyTorch SAC update written out below with the same networks on
the same 512 samples (replay gather, critic MSE to a soft target, actor loss, temperature loss,
Polyak step), with as many critic heads as the agent's config (`n_critics`: 2 = SAC's twin critic, 1 = one).
LSIQ-fO has one network more than SAC, its inverse dynamics model (IDM); "the same networks" then means the
bare SAC update plus a bare IDM regression step on 256 agent rows (row `bare SAC 1Q+IDM`); its ratio against
the bare SAC update without the IDM is printed below the table too.
Random data with Hopper's dimensions (obs 11, act 3). Timings after a warm-up, median of
`--reps` blocks of `--updates` updates; the agents and the bare update alternate block by block, so
machine load hits all of them alike. ratio = agent time / bare time (goal <= 1.2x).
Note that the IL critics do inherently more work than SAC's: IQ-Learn and LS-IQ (value term) evaluate
the critic also on (s, a~pi(s)) and IQ-Learn on (s', a'~pi) with gradient; LSIQ-fO trains an inverse
dynamics model every update.

`--critic-layer-norm` adds each agent with `critic_layer_norm=True` (rows '... LN': a LayerNorm after each
hidden layer of every critic head), each against the bare update with the same LayerNorm critic, and prints
what the LayerNorm costs each agent (LN / plain update time, same process).

`--unshared-forward` adds each agent as it was before the update shared the policy's forward at the batch's
states between the critic's V(s) term and the actor step (rows '... unshared': the critic runs its own forward
there; same numbers, one policy forward more per update), for an A/B of that change in one process.

`--device cuda` runs the networks, replay memory and updates on the GPU (timed blocks end with
`torch.cuda.synchronize()`); `--graphed-bare` adds the bare update replayed from a CUDA graph and the agents
with `cuda_graph=True`, each against the graphed bare update of its shape (rows '... graph').

Part 2 -- on-policy env throughput. Env steps/s of GAIL, VAIL and GAIfO driven by mushroom-rl's
`Core.learn(n_steps, n_steps_per_fit)` on `--task` (default `Hopper.run.perfect`; draw_action per step,
then every `n_steps_per_fit` steps the discriminator (every `train_disc_every`-th fit) and a TRPO step
with the value-function fit), against the bare environment stepped with uniform random actions (resets
included). ratio = agent steps/s / env steps/s (goal >= 0.7x). The expert data is the task's
`create_dataset()`, or with `--random-expert` random data of the task's shape (the speed does not
depend on its content; use it for tasks whose dataset is not cached, e.g. `--task Atlas.walk.perfect`).

    python benchmarks/il_speed.py [--updates 20 --reps 5] [--offpolicy ...] [--onpolicy gail vail gaifo]
                                  [--onpolicy-fits 6 --onpolicy-reps 3] [--task Hopper.run.perfect] [--random-expert]
                                  [--device cpu|cuda] [--compiled-bare] [--graphed-bare] [--critic-layer-norm]
                                  [--unshared-forward]
    (an empty `--offpolicy` or `--onpolicy` skips that part)
"""
from __future__ import annotations

import argparse
import copy
import statistics
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import torch
import yaml
from torch import nn
from mushroom_rl.core import Core, MDPInfo
from mushroom_rl.utils.spaces import Box

from loco_il.algorithms.factory import build_agent
from loco_il.algorithms.common.cuda_graph import GraphedStep, make_capturable
from loco_il.rl.networks import EnsembleQ, GaussianPolicy, mlp

ROOT = Path(__file__).resolve().parents[1]
OBS_DIM, ACT_DIM = 11, 3  # Hopper


def load_cfg(name: str) -> dict:
    with open(ROOT / "experiment_configs" / "algo" / f"{name}.yaml") as fh:
        return yaml.safe_load(fh)


# ---------------------------------------------------------------------------- bare SAC
class BareSAC:
    """Minimal SAC update on preallocated replay tensors: the floor the agents are compared with.
    `n_critics` critic heads (2: SAC's twin critic; 1: one critic), the agents' `EnsembleQ`, with LayerNorm
    after each hidden layer when `layer_norm` (as the agents' `critic_layer_norm`)."""

    def __init__(self, n: int, batch: int, hidden=(256, 256), gamma=0.99, tau=0.005, lr=3e-4, seed=0,
                 n_critics: int = 2, idm: bool = False, layer_norm: bool = False, device: str = "cpu"):
        g = torch.Generator().manual_seed(seed)
        self.device = torch.device(device)
        # the replay tensors live on the update's device, as in the agents' TransitionBuffer
        self.obs = torch.randn(n, OBS_DIM, generator=g).to(self.device)
        self.next_obs = torch.randn(n, OBS_DIM, generator=g).to(self.device)
        self.act = (torch.rand(n, ACT_DIM, generator=g) * 2 - 1).to(self.device)
        self.rew = torch.randn(n, generator=g).to(self.device)
        self.absorbing = (torch.rand(n, generator=g) < 0.01).float().to(self.device)
        self.rng = np.random.default_rng(seed)
        self.batch, self.gamma, self.tau = batch, gamma, tau
        self.pi = GaussianPolicy(OBS_DIM, ACT_DIM, hidden, squash=True).to(self.device)
        self.q = EnsembleQ(OBS_DIM, ACT_DIM, hidden, n_heads=n_critics, layer_norm=layer_norm).to(self.device)
        self.q_targ = copy.deepcopy(self.q).requires_grad_(False)
        self.log_alpha = torch.zeros((), device=self.device, requires_grad=True)
        # foreach=True as in SACCore, so that the ratio measures the agents' overheads, not the optimizer kind
        self.pi_opt = torch.optim.Adam(self.pi.parameters(), lr=lr, foreach=True)
        self.q_opt = torch.optim.Adam(self.q.parameters(), lr=lr, foreach=True)
        self.a_opt = torch.optim.Adam([self.log_alpha], lr=lr, foreach=True)
        self.q_params, self.t_params = list(self.q.parameters()), list(self.q_targ.parameters())
        self.target_entropy = -float(ACT_DIM)
        self.idm = nn.Sequential(mlp(2 * OBS_DIM, ACT_DIM, hidden), nn.Tanh()).to(self.device) if idm else None
        if idm:
            self.idm_opt = torch.optim.Adam(self.idm.parameters(), lr=lr, foreach=True)

    def update(self) -> None:
        self.step(self.draw_indices())

    def draw_indices(self) -> torch.Tensor:
        """A batch of replay rows, drawn on the host and copied to the update's device (as the agents do)."""
        return torch.as_tensor(self.rng.integers(0, len(self.obs), size=self.batch)).to(self.device)

    def step(self, idx: torch.Tensor) -> None:
        """One SAC update on the replay rows `idx`."""
        s, a, r, s2, d = self.obs[idx], self.act[idx], self.rew[idx], self.next_obs[idx], self.absorbing[idx]
        if self.idm is not None:  # inverse dynamics regression on the agent half of the batch, as LSIQ-fO does
            h = self.batch // 2
            idm_loss = (self.idm(torch.cat([s[:h], s2[:h]], -1)) - a[:h]).pow(2).sum(-1).mean()
            self.idm_opt.zero_grad(set_to_none=True)
            idm_loss.backward()
            self.idm_opt.step()
        alpha = self.log_alpha.detach().exp()
        with torch.no_grad():
            a2, logp2 = self.pi.sample(s2)
            y = r + self.gamma * (1 - d) * (self.q_targ(s2, a2).amin(0) - alpha * logp2)
        q_loss = (self.q(s, a) - y).pow(2).mean(-1).sum()
        self.q_opt.zero_grad(set_to_none=True)
        q_loss.backward()
        self.q_opt.step()
        for p in self.q_params:
            p.requires_grad_(False)
        a_pi, logp = self.pi.sample(s)
        pi_loss = (alpha * logp - self.q(s, a_pi).amin(0)).mean()
        self.pi_opt.zero_grad(set_to_none=True)
        pi_loss.backward()
        self.pi_opt.step()
        for p in self.q_params:
            p.requires_grad_(True)
        a_loss = -(self.log_alpha.exp() * (logp.detach() + self.target_entropy)).mean()
        self.a_opt.zero_grad(set_to_none=True)
        a_loss.backward()
        self.a_opt.step()
        with torch.no_grad():
            torch._foreach_lerp_(self.t_params, self.q_params, self.tau)


def random_mdp_info() -> MDPInfo:
    return MDPInfo(Box(-np.inf * np.ones(OBS_DIM), np.inf * np.ones(OBS_DIM)),
                   Box(-np.ones(ACT_DIM), np.ones(ACT_DIM)), gamma=0.99, horizon=1000, dt=0.008)


def make_offpolicy_agent(name: str, n_replay: int, seed: int = 0, device: str = "cpu", cuda_graph: bool = False,
                        critic_layer_norm: bool = False, unshared_forward: bool = False):
    cfg = load_cfg("lsiq" if name == "lsiqfo" else name)
    cfg["name"] = name
    cfg["params"]["replay_capacity"] = n_replay
    cfg["params"]["cuda_graph"] = cuda_graph
    cfg["params"]["critic_layer_norm"] = critic_layer_norm
    agent = build_agent(name, random_mdp_info(), cfg, seed=seed, device=device)
    rng = np.random.default_rng(seed)
    n_exp = 10_000
    expert = SimpleNamespace(obs=rng.standard_normal((n_exp, OBS_DIM)), next_obs=rng.standard_normal((n_exp, OBS_DIM)),
                             actions=rng.uniform(-1, 1, (n_exp, ACT_DIM)), absorbing=rng.random(n_exp) < 0.01,
                             last=np.zeros(n_exp, bool), rewards=np.zeros(n_exp), info={})
    if name == "lsiqfo":
        expert.actions = None
    agent.set_expert(expert)
    agent.replay.add(rng.standard_normal((n_replay, OBS_DIM)), rng.standard_normal((n_replay, OBS_DIM)),
                     (rng.random(n_replay) < 0.01).astype(np.float32), rng.uniform(-1, 1, (n_replay, ACT_DIM)))
    if unshared_forward:  # the critic ignores the update's policy forward and runs its own (the code before sharing)
        loss_of = type(agent).critic_loss
        agent.critic_loss = lambda expert, policy, pi_obs=None: loss_of(agent, expert, policy)
    return agent


class GraphedBareSAC(BareSAC):
    """The bare SAC update replayed from a CUDA graph through the agents' own `GraphedStep` (3 eager updates,
    then capture): the floor of the agents with `cuda_graph=True`."""

    def __init__(self, n: int, batch: int, device: str = "cuda", **kwargs):
        super().__init__(n, batch, device=device, **kwargs)
        if self.device.type != "cuda":
            raise ValueError("GraphedBareSAC needs a CUDA device")
        make_capturable([self.pi_opt, self.q_opt, self.a_opt] + ([self.idm_opt] if self.idm is not None else []))
        self.graphed = GraphedStep(self.step)
        for _ in range(self.graphed.n_warmup + 1):  # warm up and capture, so that timing sees replays only
            self.update()
        before = self.q_params[0].detach().clone()
        self.update()
        torch.cuda.synchronize()
        if torch.equal(before, self.q_params[0]) or not torch.isfinite(self.q_params[0]).all():
            raise RuntimeError("a replay of the captured update did not update the critic")

    def update(self) -> None:
        self.graphed(self.draw_indices())


def compiled_bare_sac(n_replay: int, device: str = "cpu") -> BareSAC:
    """The bare SAC update with `torch.compile`d critic forward and policy sample (backward through AOTAutograd):
    whether compiling pays for these small networks on this machine."""
    bare = BareSAC(n_replay, 512, device=device)
    bare.q.forward = torch.compile(bare.q.forward)
    bare.pi.sample = torch.compile(bare.pi.sample)
    t0 = time.perf_counter()
    for _ in range(3):
        bare.update()
    print(f"# torch.compile warm-up (compilation): {time.perf_counter() - t0:.1f} s", flush=True)
    return bare


def row_name(name: str, layer_norm: bool = False, graphed: bool = False, unshared: bool = False) -> str:
    """A timed row's label: `name` plus the variant suffixes (' LN' LayerNorm critic, ' graph' CUDA graph,
    ' unshared' the policy forward not shared)."""
    return name + (" LN" if layer_norm else "") + (" graph" if graphed else "") + (" unshared" if unshared else "")


def bare_name(n_critics: int, idm: bool = False, graphed: bool = False, layer_norm: bool = False) -> str:
    shape = ("bare SAC" if n_critics == 2 else f"bare SAC {n_critics}Q") + ("+IDM" if idm else "")
    return row_name(shape, layer_norm, graphed)


def bench_offpolicy(names, updates: int, reps: int, with_compiled: bool = False,
                    device: str = "cpu", with_graphed: bool = False, with_layer_norm: bool = False,
                    with_unshared: bool = False) -> dict[str, float]:
    """Median seconds per update of each agent and of the bare SAC update with the same critic (number of heads,
    LayerNorm or not; each agent's ratio is taken against that one), all on `device`."""
    n_replay = 20_000
    variants = [(ln, g, u) for ln in (False, True)[:1 + with_layer_norm] for g in (False, True)[:1 + with_graphed]
                for u in (False, True)[:1 + with_unshared]]
    agents = {row_name(name, ln, g, u): make_offpolicy_agent(name, n_replay, device=device, cuda_graph=g,
                                                             critic_layer_norm=ln, unshared_forward=u)
              for ln, g, u in variants for name in names}
    # the bare update each agent is compared with: same critic, plus the IDM step where the agent has one
    shapes = {row: (agent.sac.critic.n_heads, hasattr(agent, "idm"), agent.cuda_graph,
                    any(isinstance(m, nn.LayerNorm) for m in agent.sac.critic.modules()))
              for row, agent in agents.items()}
    wanted = {(2, False, False, False)} | set(shapes.values()) | {(n, False, g, ln) for n, _, g, ln in shapes.values()}
    wanted |= {(2, False, g, ln) for _, _, g, ln in shapes.values()}
    bare_kind = {False: BareSAC, True: GraphedBareSAC}
    runners = {bare_name(*shape): bare_kind[shape[2]](n_replay, 512, n_critics=shape[0], idm=shape[1],
                                                      layer_norm=shape[3], device=device).update
               for shape in sorted(wanted, reverse=True)}
    if with_compiled:
        runners["compiled"] = compiled_bare_sac(n_replay, device).update
    # CUDA runs asynchronously: a block's time counts only once its kernels have finished
    sync = torch.cuda.synchronize if torch.device(device).type == "cuda" else (lambda: None)
    runners.update({name: agent.update for name, agent in agents.items()})
    for fn in runners.values():  # warm-up
        for _ in range(10):
            fn()
    times: dict[str, list[float]] = {k: [] for k in runners}
    for _ in range(reps):
        for key, fn in runners.items():
            sync()
            start = time.perf_counter()
            for _ in range(updates):
                fn()
            sync()
            times[key].append((time.perf_counter() - start) / updates)
    med = {k: statistics.median(v) for k, v in times.items()}
    print("\n## Off-policy: one update, [256, 256] networks, 256 agent + 256 expert samples "
          f"(bare SAC: batch 512), median of {reps} x {updates} updates, device {device}, 1 CPU thread")
    print(f"{'agent':<22}{'ms/update':>9}{'ratio':>8}  against     (goal <= 1.2x)")
    for k, v in med.items():
        # a bare row is read against the bare twin-critic update without LayerNorm of its kind (eager or graphed)
        base = bare_name(*shapes.get(k, (2, False, k.endswith(" graph"), False)))
        print(f"{k:<22}{1e3 * v:>9.2f}{v / med[base]:>8.2f}  {base}")
    for k, (n, idm, graphed, ln) in shapes.items():
        if idm:
            base = bare_name(n, graphed=graphed, layer_norm=ln)
            print(f"{k} against {base} (SAC's networks only, without the IDM step): {med[k] / med[base]:.2f}")
    for name in names:
        if with_graphed:
            print(f"{name}: eager / graphed update time {med[name] / med[name + ' graph']:.2f}x")
        if with_layer_norm:
            print(f"{name}: LayerNorm / plain critic update time {med[name + ' LN'] / med[name]:.2f}x")
        if with_unshared:
            print(f"{name}: unshared / shared policy forward, update time {med[name + ' unshared'] / med[name]:.2f}x")
    return med


# ---------------------------------------------------------------------------- on-policy
def bench_env(env, n_steps: int, seed: int = 0) -> float:
    rng = np.random.default_rng(seed)
    env.seed(seed)
    env.reset()
    horizon = env.info.horizon
    actions = rng.uniform(-1, 1, (n_steps, env.info.action_space.shape[0]))
    t_ep = 0
    start = time.perf_counter()
    for a in actions:
        _, _, absorbing, _ = env.step(a)
        t_ep += 1
        if absorbing or t_ep >= horizon:
            env.reset()
            t_ep = 0
    return n_steps / (time.perf_counter() - start)


def bench_onpolicy(names, n_fits: int, reps: int, expert, task: str, device: str = "cpu") -> None:
    from loco_il import LocoEnv
    env = LocoEnv.make(task)
    rows = []
    rates: dict[str, list[float]] = {"bare env": []}
    cores = {}
    for name in names:
        cfg = load_cfg(name)
        agent = build_agent(name, env.info, cfg, seed=0, device=device)
        agent.set_expert(expert)
        spf = int(cfg["core"]["n_steps_per_fit"])
        cores[name] = (Core(agent, env), spf)
        rates[name] = []
    for name, (core, spf) in cores.items():  # warm-up: one fit each
        core.learn(n_steps=spf, n_steps_per_fit=spf, quiet=True)
    bench_env(env, 2000)
    for _ in range(reps):
        for name, (core, spf) in cores.items():
            n = n_fits * spf
            start = time.perf_counter()
            core.learn(n_steps=n, n_steps_per_fit=spf, quiet=True)
            rates[name].append(n / (time.perf_counter() - start))
        rates["bare env"].append(bench_env(env, n_fits * 1024))
    # breakdown: the per-step cost of draw_action alone next to env.step, and the fit cost per env step
    obs = env.reset()
    act_us = {}
    for name, (core, spf) in cores.items():
        agent = core.agent
        t = []
        for _ in range(5):
            start = time.perf_counter()
            for _ in range(200):
                agent.draw_action(obs)
            t.append((time.perf_counter() - start) / 200)
        act_us[name] = 1e6 * statistics.median(t)
    med = {k: statistics.median(v) for k, v in rates.items()}
    base = med["bare env"]
    env_us = 1e6 / base
    print(f"\n## On-policy: env steps/s on {task}, Core.learn with n_steps_per_fit from the configs, "
          f"{n_fits} fits per block, median of {reps} blocks, networks on {device}, 1 CPU thread")
    print(f"{'agent':<10}{'steps/s':>10}{'ratio':>8}  (goal >= 0.7x)")
    for k, v in med.items():
        print(f"{k:<10}{v:>10.0f}{v / base:>8.2f}")
    print(f"\nper env step: env.step {env_us:.0f} us (random actions, resets included)")
    print(f"{'agent':<10}{'draw_action us':>16}{'fit us/step':>13}{'bound w/o fit':>15}{'bound 2 cores':>15}")
    for name, a in act_us.items():
        total_us = 1e6 / med[name]
        fit_us = max(0.0, total_us - env_us - a)
        print(f"{name:<10}{a:>16.0f}{fit_us:>13.0f}{env_us / (env_us + a):>15.2f}"
              f"{min(1.0, 2 * env_us / total_us):>15.2f}")
    print("(fit us/step = 1/steps_per_s - env.step - draw_action; 'bound w/o fit' = the ratio a free fit would give;\n"
          " 'bound 2 cores' = the ratio if all of this work were split perfectly over two cores, 2 env.step / "
          "(1/steps_per_s))")
    print(f"goal 0.7x leaves {env_us * (1 / 0.7 - 1):.0f} us per env step for draw_action + fit + Core together")
    rows.append(med)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--updates", type=int, default=20)
    parser.add_argument("--reps", type=int, default=5)
    parser.add_argument("--offpolicy", nargs="*", default=["iqlearn", "lsiq", "lsiqfo", "sqil"])
    parser.add_argument("--onpolicy", nargs="*", default=["gail", "vail", "gaifo"])
    parser.add_argument("--onpolicy-fits", type=int, default=6, help="fits per timed block (6 = 2 disc steps)")
    parser.add_argument("--onpolicy-reps", type=int, default=3)
    parser.add_argument("--task", default="Hopper.run.perfect", help="on-policy part: the environment")
    parser.add_argument("--compiled-bare", action="store_true",
                        help="off-policy part: also time the bare SAC update with torch.compile'd networks (row 'compiled')")
    parser.add_argument("--random-expert", action="store_true",
                        help="on-policy part: random expert data of the task's shape instead of its dataset")
    parser.add_argument("--graphed-bare", action="store_true",
                        help="off-policy part, CUDA only: also time the bare SAC update replayed from a CUDA graph "
                             "and the agents with cuda_graph=True (rows '... graph')")
    parser.add_argument("--critic-layer-norm", action="store_true",
                        help="off-policy part: also time each agent with critic_layer_norm=True (rows '... LN') "
                             "against the bare update with the same LayerNorm critic")
    parser.add_argument("--unshared-forward", action="store_true",
                        help="off-policy part: also time each agent with the policy forward at the batch's states "
                             "not shared between critic and actor (rows '... unshared'), an A/B of that change")
    parser.add_argument("--device", default="cpu", help="torch device of the networks and updates (cpu, cuda)")
    args = parser.parse_args()
    if torch.device(args.device).type == "cuda" and not torch.cuda.is_available():
        parser.error(f"--device {args.device}: torch {torch.__version__} sees no CUDA device")
    if args.graphed_bare and torch.device(args.device).type != "cuda":
        parser.error("--graphed-bare needs --device cuda (CUDA graphs)")
    torch.set_num_threads(1)
    torch.manual_seed(0)
    gpu = f", {torch.cuda.get_device_name(args.device)}" if torch.device(args.device).type == "cuda" else ""
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, device {args.device}{gpu}")
    if args.offpolicy:
        bench_offpolicy(args.offpolicy, args.updates, args.reps, args.compiled_bare, args.device, args.graphed_bare,
                        args.critic_layer_norm, args.unshared_forward)
    if args.onpolicy:
        from loco_il import LocoEnv
        if args.random_expert:
            info = LocoEnv.make(args.task).info
            obs_dim, act_dim = info.observation_space.shape[0], info.action_space.shape[0]
            rng = np.random.default_rng(0)
            n = 20_000
            expert = SimpleNamespace(obs=rng.standard_normal((n, obs_dim)), next_obs=rng.standard_normal((n, obs_dim)),
                                     actions=rng.uniform(-1, 1, (n, act_dim)), absorbing=np.zeros(n, bool),
                                     last=np.zeros(n, bool), rewards=np.zeros(n), info={})
        else:
            expert = LocoEnv.make(args.task).create_dataset(verbose=False)
        bench_onpolicy(args.onpolicy, args.onpolicy_fits, args.onpolicy_reps, expert, args.task, args.device)


if __name__ == "__main__":
    main()
