"""A benchmark protocol: which tasks, algorithms, budgets, seeds and evaluation settings make up a leaderboard.

A protocol is a YAML file in `experiment_configs/benchmark/` (or any path). Its keys:

    description: one line
    base: small                # optional: start from another protocol and replace/extend its keys
    seeds: [0, 1, 2]
    report_at: [100000, ...]   # env steps at which the table reports the score along the way
    eval: {episodes: 5, final_episodes: 10, seed: 1000}     # train.py eval.* of every run
    overrides: {logger: csv}   # further train.py key=value settings of every run
    families:                  # budget per algorithm family
      onpolicy: {algos: [gail, vail, gaifo], n_steps: 1000000, eval_every: 50000}
      offline: {algos: [bc], n_steps: 100000, eval_every: 10000, unit: gradient}
    variants:                  # extra rows: a documented setting of an algorithm under its own label
      lsiq_mixture_2critics_ln: {algo: lsiq, overrides: {algo.params.objective: mixture}, note: docs/...}
    parts:                     # the grid: tasks x labels, per dataset type
      real: {dataset: real, tasks: [Atlas.walk, ...], algorithms: [gail, ...]}

`load_protocol(name_or_path)` reads and checks it; every problem is a `ProtocolError` with a one-line message
naming the key and the fix. A `base` protocol's `results_dir` is not inherited (each protocol has its own runs).
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import yaml

from loco_il.benchmark import paths

DATASET_TYPES = ("real", "perfect", "preference")
UNITS = {"env": "env steps", "gradient": "gradient steps"}
TOP_KEYS = ("description", "base", "seeds", "results_dir", "report_at", "eval", "overrides", "families",
            "variants", "parts")
EVAL_KEYS = ("episodes", "final_episodes", "seed", "deterministic", "similarity", "max_points")
#: train.py keys the benchmark sets itself for every run (a protocol's `overrides` may not set them)
RESERVED_KEYS = ("task", "algo", "seed", "n_steps", "name", "results_dir", "eval.every", "hydra.sweep.dir",
                 "hydra.run.dir")


class ProtocolError(ValueError):
    """A protocol that cannot be used: one line naming the problem and the fix."""


@dataclass(frozen=True)
class Family:
    """The budget of a group of algorithms: training steps, evaluation interval, the steps' unit."""
    name: str
    algos: tuple[str, ...]
    n_steps: int
    eval_every: int
    unit: str                      # "env" or "gradient" (offline BC)
    report_at: tuple[int, ...]     # steps at which the table reports the score, within the budget

    @property
    def unit_label(self) -> str:
        return UNITS[self.unit]


@dataclass(frozen=True)
class Variant:
    """A row label running `algo` with extra train.py settings (a setting the project documents as better)."""
    label: str
    algo: str
    overrides: tuple[tuple[str, Any], ...]
    note: str


@dataclass(frozen=True)
class Part:
    """One block of the grid: every task with every label, on one dataset type."""
    name: str
    dataset: str
    tasks: tuple[str, ...]         # Task-IDs without the dataset type, e.g. "Atlas.walk"
    labels: tuple[str, ...]


@dataclass(frozen=True)
class Protocol:
    name: str
    path: Path
    description: str
    seeds: tuple[int, ...]
    results_dir: Path
    report_at: tuple[int, ...]
    eval: tuple[tuple[str, Any], ...]
    overrides: tuple[tuple[str, Any], ...]
    families: tuple[Family, ...]
    variants: tuple[Variant, ...]
    parts: tuple[Part, ...]

    def family_of(self, algo: str) -> Family:
        for fam in self.families:
            if algo in fam.algos:
                return fam
        raise KeyError(algo)

    def algo_of(self, label: str) -> str:
        """The train.py `algo=` of a row label (a variant's algorithm, or the label itself)."""
        for var in self.variants:
            if var.label == label:
                return var.algo
        return label

    def variant(self, label: str) -> Variant | None:
        return next((v for v in self.variants if v.label == label), None)


# ----------------------------------------------------------------------------- reading
def protocol_path(name_or_path: str | Path) -> Path:
    """`small` -> experiment_configs/benchmark/small.yaml; a path to a YAML file is taken as it is."""
    text = str(name_or_path)
    path = Path(text)
    if text.endswith((".yaml", ".yml")) or path.is_file():
        if not path.is_file():
            raise ProtocolError(f"protocol file {path} does not exist")
        return path
    path = paths.PROTOCOL_DIR / f"{text}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in paths.PROTOCOL_DIR.glob("*.yaml"))
        raise ProtocolError(f"unknown protocol {text!r}; known: {', '.join(known) or 'none'} "
                            f"(in {paths.relative(paths.PROTOCOL_DIR)}), or give a path to a protocol YAML file")
    return path


def _merge(base: Mapping[str, Any], top: Mapping[str, Any]) -> dict[str, Any]:
    """`top` over `base`: mappings are merged key by key, anything else is replaced."""
    out = dict(base)
    for key, value in top.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def _read_raw(path: Path, chain: tuple[Path, ...] = ()) -> dict[str, Any]:
    if path.resolve() in chain:
        raise ProtocolError(f"{path}: `base` protocols form a cycle ({' -> '.join(p.stem for p in chain)}); "
                            f"remove one `base:`")
    try:
        raw = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as exc:
        raise ProtocolError(f"{path}: not valid YAML ({str(exc).splitlines()[0]}); fix the file") from None
    if not isinstance(raw, dict):
        raise ProtocolError(f"{path}: a protocol is a mapping of keys ({', '.join(TOP_KEYS)}); fix the file")
    base = raw.pop("base", None)
    if base is None:
        return raw
    base = str(base)
    if base.endswith((".yaml", ".yml")) and not Path(base).is_absolute():
        base = str(path.parent / base)          # a base file named relatively lies next to this protocol
    parent = _read_raw(protocol_path(base), chain + (path.resolve(),))
    parent.pop("results_dir", None)   # each protocol keeps its own runs
    parent.pop("description", None)
    return _merge(parent, raw)


def load_protocol(name_or_path: str | Path, check_tasks: bool = True) -> Protocol:
    """Read and check a protocol. `check_tasks=False` skips the Task-ID and algorithm checks that import the
    environments and learners (for tools that only read finished runs)."""
    path = protocol_path(name_or_path)
    raw = _read_raw(path)
    return _Checker(path, raw).protocol(check_tasks)


# ----------------------------------------------------------------------------- checking
def _known_algos() -> list[str]:
    return sorted(p.stem for p in (paths.ROOT / "experiment_configs" / "algo").glob("*.yaml"))


def _close(name: str, choices: Sequence[str]) -> str:
    near = difflib.get_close_matches(name, list(choices), n=3, cutoff=0.6)
    return f"did you mean {', '.join(near)}? " if near else ""


class _Checker:
    def __init__(self, path: Path, raw: dict[str, Any]):
        self.path, self.raw = path, raw
        self.where = paths.relative(path)
        self.own_report_at: dict[str, tuple[int, ...] | None] = {}

    def fail(self, message: str) -> ProtocolError:
        return ProtocolError(f"{self.where}: {message}")

    def protocol(self, check_tasks: bool) -> Protocol:
        unknown = sorted(set(self.raw) - set(TOP_KEYS))
        if unknown:
            raise self.fail(f"unknown key {unknown[0]!r}; a protocol has: {', '.join(TOP_KEYS)}")
        algos = _known_algos()
        families = self.families(algos)
        family_algos = {a for f in families for a in f.algos}
        variants = self.variants(algos, family_algos)
        parts = self.parts(family_algos, {v.label for v in variants})
        report_at = self.steps_list(self.raw.get("report_at", []), "report_at")
        families = tuple(self.with_report_at(f, report_at) for f in families)
        name = self.path.stem
        results_dir = Path(self.raw.get("results_dir") or paths.LOGS_DIR / name)
        if not results_dir.is_absolute():
            results_dir = paths.ROOT / results_dir
        proto = Protocol(name=name, path=self.path, description=str(self.raw.get("description") or ""),
                         seeds=self.seeds(), results_dir=results_dir, report_at=report_at, eval=self.eval(),
                         overrides=self.overrides(self.raw.get("overrides"), "overrides"), families=families,
                         variants=variants, parts=parts)
        if check_tasks:
            self.check_tasks(proto)
        return proto

    # ---------------------------------------------------------------- pieces
    def seeds(self) -> tuple[int, ...]:
        seeds = self.raw.get("seeds")
        if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) and s >= 0 for s in seeds):
            raise self.fail(f"seeds must be a non-empty list of integers >= 0, e.g. [0, 1, 2]; got {seeds!r}")
        if len(set(seeds)) != len(seeds):
            raise self.fail(f"seeds {seeds} repeat a seed; list each once")
        return tuple(seeds)

    def steps_list(self, value: Any, key: str) -> tuple[int, ...]:
        if not isinstance(value, list) or not all(isinstance(v, int) and v > 0 for v in value):
            raise self.fail(f"{key} must be a list of positive step counts, e.g. [100000, 300000]; got {value!r}")
        return tuple(sorted(set(value)))

    def eval(self) -> tuple[tuple[str, Any], ...]:
        ev = self.raw.get("eval") or {}
        if not isinstance(ev, dict):
            raise self.fail(f"eval must be a mapping of train.py eval.* settings; got {ev!r}")
        for key in ev:
            if key == "every":
                raise self.fail("eval.every is set per family (families.<name>.eval_every); remove it from eval")
            if key not in EVAL_KEYS:
                raise self.fail(f"unknown eval key {key!r}; allowed: {', '.join(EVAL_KEYS)}")
        return tuple(sorted(ev.items()))

    def overrides(self, value: Any, key: str) -> tuple[tuple[str, Any], ...]:
        value = value or {}
        if not isinstance(value, dict):
            raise self.fail(f"{key} must be a mapping of train.py settings (e.g. {{logger: csv}}); got {value!r}")
        for k in value:
            if str(k) in RESERVED_KEYS or str(k).startswith("eval."):
                raise self.fail(f"{key} sets {k!r}, which the protocol itself decides (tasks, families, seeds, "
                                f"eval); set it there instead")
        return tuple((str(k), v) for k, v in value.items())

    def families(self, algos: Sequence[str]) -> tuple[Family, ...]:
        raw = self.raw.get("families")
        if not isinstance(raw, dict) or not raw:
            raise self.fail("families must map a family name to {algos, n_steps, eval_every}; none given")
        out, seen = [], {}
        for name, spec in raw.items():
            if not isinstance(spec, dict):
                raise self.fail(f"families.{name} must be a mapping {{algos, n_steps, eval_every}}; got {spec!r}")
            extra = sorted(set(spec) - {"algos", "n_steps", "eval_every", "unit", "report_at"})
            if extra:
                raise self.fail(f"families.{name}: unknown key {extra[0]!r}; allowed: algos, n_steps, eval_every, "
                                f"unit, report_at")
            members = spec.get("algos")
            if not isinstance(members, list) or not members:
                raise self.fail(f"families.{name}.algos must list algorithms, e.g. [gail, vail]")
            for algo in members:
                if algo not in algos:
                    raise self.fail(f"families.{name}: unknown algorithm {algo!r}; {_close(str(algo), algos)}"
                                    f"known: {', '.join(algos)} (experiment_configs/algo/)")
                if algo in seen:
                    raise self.fail(f"algorithm {algo!r} is in families {seen[algo]} and {name}; keep it in one")
                seen[algo] = name
            for key in ("n_steps", "eval_every"):
                if not isinstance(spec.get(key), int) or spec[key] <= 0:
                    raise self.fail(f"families.{name}.{key} must be a positive integer; got {spec.get(key)!r}")
            if spec["eval_every"] > spec["n_steps"]:
                raise self.fail(f"families.{name}.eval_every ({spec['eval_every']}) exceeds its n_steps "
                                f"({spec['n_steps']}); lower it")
            unit = spec.get("unit", "env")
            if unit not in UNITS:
                raise self.fail(f"families.{name}.unit must be env or gradient; got {unit!r}")
            own = spec.get("report_at")
            self.own_report_at[str(name)] = (None if own is None
                                             else self.steps_list(own, f"families.{name}.report_at"))
            out.append(Family(name=str(name), algos=tuple(members), n_steps=spec["n_steps"],
                              eval_every=spec["eval_every"], unit=unit, report_at=()))
        return tuple(out)

    def with_report_at(self, fam: Family, report_at: tuple[int, ...]) -> Family:
        """The family's report steps within its budget, each on its evaluation grid: its own `report_at`, else
        the protocol's (env steps, so not for a family counted in gradient steps)."""
        own = self.own_report_at.get(fam.name)
        steps = own if own is not None else (report_at if fam.unit == "env" else ())
        steps = tuple(s for s in steps if s <= fam.n_steps)
        for s in steps:
            if s % fam.eval_every:
                raise self.fail(f"report_at {s} is not a multiple of families.{fam.name}.eval_every "
                                f"({fam.eval_every}), so no evaluation falls on it; change one of them")
        return Family(fam.name, fam.algos, fam.n_steps, fam.eval_every, fam.unit, steps)

    def variants(self, algos: Sequence[str], family_algos: set[str]) -> tuple[Variant, ...]:
        raw = self.raw.get("variants") or {}
        if not isinstance(raw, dict):
            raise self.fail(f"variants must map a row label to {{algo, overrides, note}}; got {raw!r}")
        out = []
        for label, spec in raw.items():
            if label in algos:
                raise self.fail(f"variant label {label!r} is an algorithm's name; give the variant its own label")
            if not isinstance(spec, dict) or "algo" not in spec:
                raise self.fail(f"variants.{label} must name its algorithm: {{algo: <name>, overrides: {{...}}}}")
            if spec["algo"] not in family_algos:
                raise self.fail(f"variants.{label}.algo {spec['algo']!r} is in no family; add it to one "
                                f"(families.<name>.algos)")
            extra = sorted(set(spec) - {"algo", "overrides", "note"})
            if extra:
                raise self.fail(f"variants.{label}: unknown key {extra[0]!r}; allowed: algo, overrides, note")
            out.append(Variant(str(label), str(spec["algo"]), self.overrides(spec.get("overrides"),
                                                                             f"variants.{label}.overrides"),
                               str(spec.get("note") or "")))
        return tuple(out)

    def parts(self, family_algos: set[str], variant_labels: set[str]) -> tuple[Part, ...]:
        raw = self.raw.get("parts")
        if not isinstance(raw, dict) or not raw:
            raise self.fail("parts must map a part name to {dataset, tasks, algorithms}; none given")
        labels_known = sorted(family_algos | variant_labels)
        out = []
        for name, spec in raw.items():
            if not isinstance(spec, dict):
                raise self.fail(f"parts.{name} must be a mapping {{dataset, tasks, algorithms}}; got {spec!r}")
            extra = sorted(set(spec) - {"dataset", "tasks", "algorithms"})
            if extra:
                raise self.fail(f"parts.{name}: unknown key {extra[0]!r}; allowed: dataset, tasks, algorithms")
            if spec.get("dataset") not in DATASET_TYPES:
                raise self.fail(f"parts.{name}.dataset must be one of {', '.join(DATASET_TYPES)}; "
                                f"got {spec.get('dataset')!r}")
            tasks, labels = spec.get("tasks"), spec.get("algorithms")
            if not isinstance(tasks, list) or not tasks or not all(isinstance(t, str) for t in tasks):
                raise self.fail(f"parts.{name}.tasks must list Task-IDs without the dataset type, e.g. [Atlas.walk]")
            if not isinstance(labels, list) or not labels:
                raise self.fail(f"parts.{name}.algorithms must list algorithms or variant labels")
            for label in labels:
                if label not in labels_known:
                    raise self.fail(f"parts.{name}: unknown algorithm {label!r}; {_close(str(label), labels_known)}"
                                    f"add it to a family (families.<name>.algos) or to variants")
            for seq, what in ((tasks, "task"), (labels, "algorithm")):
                dup = sorted({x for x in seq if seq.count(x) > 1})
                if dup:
                    raise self.fail(f"parts.{name} lists {what} {dup[0]!r} twice; list it once")
            out.append(Part(str(name), spec["dataset"], tuple(tasks), tuple(labels)))
        return tuple(out)

    def check_tasks(self, proto: Protocol) -> None:
        """Every Task-ID exists, every algorithm can learn from its part's dataset type, and no task file tunes
        an algorithm for a task (a protocol runs every algorithm with its documented defaults)."""
        from loco_il import get_all_task_names
        from loco_il.algorithms.factory import get_algorithm
        valid = set(get_all_task_names())
        for part in proto.parts:
            for task in part.tasks:
                task_id = f"{task}.{part.dataset}"
                if task_id not in valid:
                    raise self.fail(f"parts.{part.name}: unknown task {task!r} ({task_id} is no Task-ID); "
                                    f"{_close(task_id, sorted(valid))}list them with "
                                    f"`python -c 'import loco_il; print(loco_il.get_all_task_names())'`")
            for label in part.labels:
                algo = proto.algo_of(label)
                if part.dataset not in get_algorithm(algo).supported_datasets:
                    raise self.fail(f"parts.{part.name}: {label} cannot learn from '{part.dataset}' datasets "
                                    f"(no expert actions); remove it from this part")
                self.check_task_files(part, algo)

    def check_task_files(self, part: Part, algo: str) -> None:
        for task in part.tasks:
            task_id = f"{task}.{part.dataset}"
            file = paths.ROOT / "experiment_configs" / "task" / f"{task_id}.yaml"
            if file.is_file() and algo in ((yaml.safe_load(file.read_text()) or {}).get("per_algo") or {}):
                raise self.fail(f"parts.{part.name}: {paths.relative(file)} tunes {algo} for {task_id} "
                                f"(per_algo), but a protocol runs every algorithm with its defaults; drop the "
                                f"task from the part or the per_algo entry from the file")


__all__ = ["Protocol", "Family", "Variant", "Part", "ProtocolError", "load_protocol", "protocol_path",
           "DATASET_TYPES"]
