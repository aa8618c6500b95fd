"""`GraphedStep`: run a training step from a captured CUDA graph, one launch per step instead of one per kernel.

Why: the SAC-based updates of small networks are bound by kernel launches on a GPU. One update of [256, 256]
networks on 512 rows launches a few hundred small kernels from one CPU thread and took 6-9 ms on an H200; the
same update replayed from a CUDA graph took ~1 ms (benchmarks/RESULTS.md, "GPU: CUDA tests and one update").

What a captured step needs, and how the off-policy agents provide it:
  * fixed shapes and tensors that stay at their addresses: the replay memory and the networks are
    preallocated and updated in place; the step's only changing inputs are its batch indices, copied into
    the graph's own index tensors before each replay;
  * no host synchronisation inside the step (no `.item()`, no host-to-device copies): the indices are drawn
    and copied to the GPU outside it, and the step returns its logged values as GPU tensors;
  * Adam with `capturable=True` (its step counts live on the GPU) and lazily created state already in place:
    the first `n_warmup` calls run eagerly (real steps, on a side stream as capture requires), then the step
    is captured and replayed from then on.
Random numbers drawn inside the step (the policy's reparameterised samples) come from the CUDA generator,
whose offsets a replay advances as the eager step would.
"""
from __future__ import annotations

from typing import Any, Callable, Iterable

import torch


class GraphedStep:
    """Wraps `fn(*index_tensors) -> output`: eager for the first `n_warmup` calls, then captured once and replayed.

    The output of a replayed step is the captured one: the same tensors, overwritten by every replay.
    Call `reset()` whenever tensors the step reads were replaced rather than updated in place (e.g. an
    optimizer's state after `load_state_dict`): the next calls warm up and capture again."""

    def __init__(self, fn: Callable[..., Any], n_warmup: int = 3):
        if not torch.cuda.is_available():
            raise RuntimeError("GraphedStep needs a CUDA device")
        self.fn, self.n_warmup = fn, int(n_warmup)
        self.reset()

    def reset(self) -> None:
        self.graph: torch.cuda.CUDAGraph | None = None
        self.static_inputs: list[torch.Tensor] = []
        self.output: Any = None
        self.warmups_left = self.n_warmup

    def __call__(self, *inputs: torch.Tensor) -> Any:
        if self.graph is not None:
            for static, x in zip(self.static_inputs, inputs):
                static.copy_(x, non_blocking=True)
            self.graph.replay()
            return self.output
        side = torch.cuda.Stream()
        side.wait_stream(torch.cuda.current_stream())
        if self.warmups_left > 0:
            with torch.cuda.stream(side):
                out = self.fn(*inputs)
            torch.cuda.current_stream().wait_stream(side)
            self.warmups_left -= 1
            return out
        torch.cuda.synchronize()
        self.static_inputs = [x.clone() for x in inputs]
        graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(graph):
            self.output = self.fn(*self.static_inputs)
        self.graph = graph
        graph.replay()  # capture records the kernels without running them: this call's step runs now
        return self.output


def make_capturable(optimizers: Iterable[torch.optim.Optimizer]) -> None:
    """Set `capturable=True` and move the step counts to the parameters' device, as Adam needs inside a CUDA graph.
    Also right after `load_state_dict` of a state saved without it (the counts load onto the CPU)."""
    for opt in optimizers:
        for group in opt.param_groups:
            group["capturable"] = True
            for p in group["params"]:
                state = opt.state.get(p)
                if state and "step" in state and state["step"].device != p.device:
                    state["step"] = state["step"].to(p.device, torch.float32)
