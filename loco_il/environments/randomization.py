"""Domain randomization: draw physical parameters by editing a `mujoco.MjSpec` before it is compiled.

`LocoEnv.randomize()` copies the env's base spec, calls `DomainRandomization.apply(spec, rng)` and
recompiles, so everything the compiler derives (body masses and inertias from geom densities, joint
limits, actuator ranges) stays consistent. `reset()` re-randomizes every `every` episodes.

Config schema (YAML file or dict; every parameter is optional)::

    every: 1                 # re-randomize every N episodes (alias: interval)
    strict: true             # a name pattern that matches nothing is an error
    description: "..."       # free text
    mass:                    # one rule (a mapping) or a list of rules
      bodies: ["*"]          # fnmatch patterns over names; "!pattern" excludes
      scale: [0.8, 1.2]      # OR  add: [-0.5, 0.5]   (exactly one of the parameter's modes)
      shared: false          # one draw for all matched elements (true) or one per element
    friction:      {geoms: [...],  scale|add: DIST, component: sliding|all}
    damping:       {joints: [...], scale|add: DIST}      # also armature, stiffness, frictionloss
    joint_range:   {joints: [...], scale: DIST, about: centre|ref}
    limb_length:   {bodies: [...], scale: DIST, keep_clearance: true}
    actuator_gain: {actuators: [...], scale: DIST}
    gravity:       {scale: DIST}  or  {add: DIST}        # add: one draw per axis (x, y, z)

DIST is one of
    2.0                                  a constant
    [lo, hi]                             uniform on [lo, hi]
    {dist: uniform, low: lo, high: hi}
    {dist: loguniform, low: lo, high: hi}
    {dist: gaussian, mean: m, std: s, clip: [lo, hi]}   (clip optional; `normal` is an alias)

`scale` multiplies the current value, `add` adds a delta in the parameter's unit (kg for mass).
Meaning of each parameter:

* mass: a body's mass and inertia scale together by the drawn factor k. Where the compiler derives the
  inertial from geoms, their density (or explicit geom mass) is scaled so the compiler recomputes
  inertia consistently; bodies with an explicit inertial (and `inertiafromgeom` not "true") get
  mass and inertia scaled directly. Additive deltas are converted to a factor with the current mass.
* friction: the sliding coefficient (or all three with `component: all`) of matched geoms.
  MuJoCo uses the larger of two geoms' frictions in a contact (unless priorities differ).
* damping/armature/stiffness/frictionloss: joint coefficients (scalars in mujoco 3.x, arrays in 4.x:
  `scale` multiplies all coefficients, `add` shifts the first one); results are clipped at 0.
* joint_range: the width of limited hinge/slide ranges scales about the centre (default) or about the
  reference position clipped into the range (`about: ref`, keeps the initial pose inside the range).
* limb_length: the body's geometry is stretched by k about its joint anchor (first hinge/ball joint,
  else the body origin): capsule/cylinder lengths, `fromto` end points, box/ellipsoid half-sizes along
  the limb, geom and site positions, and child bodies are moved so that their joint anchors follow.
  Radii are unchanged; masses follow from the new volumes. With `keep_clearance` the root is then lifted
  or lowered so that the lowest collision geom at qpos0 keeps its original height above the ground.
* actuator_gain: the force per unit control: gainprm/biasprm of affine (motor, position, velocity)
  actuators, the peak force (or scale) of muscles.
* gravity: the gravity vector.

Models using the deprecated `settotalmass` are first rewritten with equivalent explicit densities,
so that a changed limb does not rescale all the others.
"""
from __future__ import annotations

import difflib
import fnmatch
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import mujoco
import numpy as np

CONFIG_DIR = Path(__file__).resolve().parent / "configs" / "randomization"
GENERIC_CONFIG = "generic"


class RandomizationConfigError(ValueError):
    """An invalid randomization config; the message names the offending key."""


# ====================================================================== distributions
@dataclass(frozen=True)
class Distribution:
    """A scalar distribution: constant, uniform, loguniform or gaussian (optionally clipped)."""

    kind: str
    a: float
    b: float = 0.0
    clip: tuple[float, float] | None = None

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.kind == "constant":
            out = np.full(n, self.a)
        elif self.kind == "uniform":
            out = rng.uniform(self.a, self.b, n)
        elif self.kind == "loguniform":
            out = np.exp(rng.uniform(math.log(self.a), math.log(self.b), n))
        else:  # gaussian
            out = rng.normal(self.a, self.b, n)
        if self.clip is not None:
            out = np.clip(out, *self.clip)
        return out

    @property
    def support(self) -> tuple[float, float]:
        """Smallest interval that contains every sample."""
        if self.kind == "constant":
            lo = hi = self.a
        elif self.kind in ("uniform", "loguniform"):
            lo, hi = self.a, self.b
        else:
            lo, hi = -math.inf, math.inf
        if self.clip is not None:
            lo, hi = max(lo, self.clip[0]), min(hi, self.clip[1])
        return lo, hi


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise RandomizationConfigError(f"{where}: expected a number, got {value!r}")
    if not math.isfinite(float(value)):
        raise RandomizationConfigError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _interval(value: Any, where: str) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise RandomizationConfigError(f"{where}: expected [low, high], got {value!r}")
    lo, hi = _number(value[0], f"{where}[0]"), _number(value[1], f"{where}[1]")
    if lo > hi:
        raise RandomizationConfigError(f"{where}: low {lo} is larger than high {hi}")
    return lo, hi


_DIST_KEYS = {"uniform": ("low", "high"), "loguniform": ("low", "high"), "gaussian": ("mean", "std"),
              "normal": ("mean", "std")}


def parse_distribution(value: Any, where: str = "distribution") -> Distribution:
    """Parse DIST (see the module docstring); errors name `where`."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return Distribution("constant", _number(value, where))
    if isinstance(value, (list, tuple)):
        lo, hi = _interval(value, where)
        return Distribution("uniform", lo, hi)
    if not isinstance(value, Mapping):
        raise RandomizationConfigError(f"{where}: expected a number, [low, high] or a mapping with 'dist', "
                                       f"got {value!r}")
    kind = value.get("dist")
    if kind not in _DIST_KEYS:
        raise RandomizationConfigError(f"{where}.dist: expected one of {sorted(_DIST_KEYS)}, got {kind!r}")
    needed = _DIST_KEYS[kind]
    allowed = {"dist", "clip", *needed}
    for key in value:
        if key not in allowed:
            raise RandomizationConfigError(f"{where}: unknown key {key!r} for dist {kind!r}; "
                                           f"valid keys: {', '.join(sorted(allowed))}")
    for key in needed:
        if key not in value:
            raise RandomizationConfigError(f"{where}: dist {kind!r} needs {key!r}")
    clip = _interval(value["clip"], f"{where}.clip") if "clip" in value else None
    if kind in ("gaussian", "normal"):
        mean, std = _number(value["mean"], f"{where}.mean"), _number(value["std"], f"{where}.std")
        if std < 0:
            raise RandomizationConfigError(f"{where}.std: must be >= 0, got {std}")
        return Distribution("gaussian", mean, std, clip)
    lo, hi = _interval([value["low"], value["high"]], f"{where}.low/high")
    if kind == "loguniform" and lo <= 0:
        raise RandomizationConfigError(f"{where}.low: loguniform needs low > 0, got {lo}")
    return Distribution(kind, lo, hi, clip)


# ====================================================================== parameters and rules
@dataclass(frozen=True)
class _ParamSpec:
    selector: str | None             # config key of the name patterns (None: global parameter)
    modes: tuple[str, ...]           # "scale" and/or "add"
    options: Mapping[str, Any]       # option name -> tuple of allowed values, or a type
    min_scale: float = 0.0           # scale factors must be >= (or > when positive) this
    positive: bool = False           # scale factors must be strictly positive


_JOINT_COEFF = _ParamSpec("joints", ("scale", "add"), {})
PARAMETERS: dict[str, _ParamSpec] = {
    "mass": _ParamSpec("bodies", ("scale", "add"), {}, positive=True),
    "friction": _ParamSpec("geoms", ("scale", "add"), {"component": ("sliding", "all")}),
    "damping": _JOINT_COEFF,
    "armature": _JOINT_COEFF,
    "stiffness": _JOINT_COEFF,
    "frictionloss": _JOINT_COEFF,
    "joint_range": _ParamSpec("joints", ("scale",), {"about": ("centre", "center", "ref")}),
    "limb_length": _ParamSpec("bodies", ("scale",), {"keep_clearance": bool}, positive=True),
    "actuator_gain": _ParamSpec("actuators", ("scale",), {}),
    "gravity": _ParamSpec(None, ("scale", "add"), {}),
}
TOP_LEVEL_KEYS = ("every", "interval", "strict", "description")


@dataclass(frozen=True)
class Rule:
    """One randomized parameter for the elements whose names match `patterns`."""

    param: str
    mode: str
    dist: Distribution
    patterns: tuple[str, ...] = ("*",)
    shared: bool = False
    options: Mapping[str, Any] = field(default_factory=dict)
    where: str = ""

    def option(self, name: str, default: Any) -> Any:
        return self.options.get(name, default)


def _suggest(key: str, options: Sequence[str]) -> str:
    close = difflib.get_close_matches(key, list(options), n=2, cutoff=0.5)
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""


def _patterns(value: Any, where: str) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, (list, tuple)) or not value or not all(isinstance(p, str) and p for p in value):
        raise RandomizationConfigError(f"{where}: expected a name pattern or a non-empty list of patterns "
                                       f"(e.g. ['*thigh*']), got {value!r}")
    return tuple(value)


def _parse_rule(param: str, cfg: Any, where: str) -> Rule:
    spec = PARAMETERS[param]
    if not isinstance(cfg, Mapping):
        raise RandomizationConfigError(f"{where}: expected a mapping like {{scale: [0.9, 1.1]}}, got {cfg!r}")
    allowed = set(spec.modes) | {"shared"} | set(spec.options) | ({spec.selector} if spec.selector else set())
    for key in cfg:
        if key not in allowed:
            raise RandomizationConfigError(f"{where}: unknown key {key!r}{_suggest(str(key), sorted(allowed))}; "
                                           f"valid keys for {param!r}: {', '.join(sorted(allowed))}")
    modes = [m for m in spec.modes if m in cfg]
    if len(modes) != 1:
        raise RandomizationConfigError(f"{where}: give exactly one of {', '.join(spec.modes)} "
                                       f"(got {', '.join(modes) or 'none'})")
    mode = modes[0]
    dist = parse_distribution(cfg[mode], f"{where}.{mode}")
    if mode == "scale":
        lo, _ = dist.support
        if spec.positive and lo <= 0:
            raise RandomizationConfigError(f"{where}.scale: {param} factors must be > 0, the lower bound is {lo}")
        if lo < 0:
            raise RandomizationConfigError(f"{where}.scale: factors must be >= 0, the lower bound is {lo}")
    options = {}
    for name, allowed_values in spec.options.items():
        if name not in cfg:
            continue
        value = cfg[name]
        if isinstance(allowed_values, type):
            if not isinstance(value, allowed_values):
                raise RandomizationConfigError(f"{where}.{name}: expected {allowed_values.__name__}, got {value!r}")
        elif value not in allowed_values:
            raise RandomizationConfigError(f"{where}.{name}: expected one of {', '.join(allowed_values)}, "
                                           f"got {value!r}")
        options[name] = value
    shared = cfg.get("shared", False)
    if not isinstance(shared, bool):
        raise RandomizationConfigError(f"{where}.shared: expected true or false, got {shared!r}")
    patterns = _patterns(cfg[spec.selector], f"{where}.{spec.selector}") if spec.selector in cfg else ("*",)
    return Rule(param, mode, dist, patterns, shared, options, where)


# ====================================================================== the randomization
@dataclass
class DomainRandomization:
    """Randomized physical parameters; `apply(spec, rng)` edits an `MjSpec` in place.

    Build it with `DomainRandomization.from_config(dict)` or `load_randomization(path_or_name, body)`.
    `every` is the re-randomization interval in episodes (the env's `randomize_every`).
    """

    rules: tuple[Rule, ...] = ()
    every: int = 1
    strict: bool = True
    description: str = ""
    source: str = ""

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any] | None, source: str = "") -> "DomainRandomization":
        where = f"randomization config{f' {source}' if source else ''}"
        if cfg is None:
            cfg = {}
        if not isinstance(cfg, Mapping):
            raise RandomizationConfigError(f"{where}: expected a mapping at the top level, got {type(cfg).__name__}")
        valid = sorted(PARAMETERS) + list(TOP_LEVEL_KEYS)
        for key in cfg:
            if key not in valid:
                raise RandomizationConfigError(f"{where}: unknown key {key!r}{_suggest(str(key), valid)}; "
                                               f"valid keys: {', '.join(valid)}")
        if "every" in cfg and "interval" in cfg:
            raise RandomizationConfigError(f"{where}: give 'every' or its alias 'interval', not both")
        every = cfg.get("every", cfg.get("interval", 1))
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise RandomizationConfigError(f"{where}.every: expected an integer >= 1 (episodes), got {every!r}")
        strict = cfg.get("strict", True)
        if not isinstance(strict, bool):
            raise RandomizationConfigError(f"{where}.strict: expected true or false, got {strict!r}")
        rules = []
        for param in cfg:
            if param not in PARAMETERS:
                continue
            entries = cfg[param]
            if isinstance(entries, Mapping):
                rules.append(_parse_rule(param, entries, f"{where}: {param}"))
            elif isinstance(entries, (list, tuple)) and entries:
                rules.extend(_parse_rule(param, e, f"{where}: {param}[{i}]") for i, e in enumerate(entries))
            else:
                raise RandomizationConfigError(f"{where}: {param}: expected a mapping or a list of mappings, "
                                               f"got {entries!r}")
        return cls(tuple(rules), every, strict, str(cfg.get("description", "")), source)

    @property
    def interval(self) -> int:
        return self.every

    # ------------------------------------------------------------------ applying
    def apply(self, spec: mujoco.MjSpec, rng: np.random.Generator) -> None:
        """Draw every rule's values from `rng` (in config order, elements in model order) and edit `spec`."""
        bake_total_mass(spec)
        keep = any(r.param == "limb_length" and r.option("keep_clearance", True) for r in self.rules)
        reference_low = lowest_point(spec) if keep else None
        for rule in self.rules:
            _APPLY[rule.param](self, spec, rule, rng)
        if reference_low is not None:
            restore_ground_clearance(spec, reference_low)

    def _select(self, items: Sequence[Any], rule: Rule, kind: str) -> list[Any]:
        names = [getattr(item, "name", "") or "" for item in items]
        chosen = select_names(names, rule.patterns)
        if self.strict:
            for pattern in rule.patterns:
                if not pattern.startswith("!") and not any(fnmatch.fnmatchcase(n, pattern) for n in names):
                    shown = ", ".join(repr(n) for n in names[:12] if n) + (" ..." if len(names) > 12 else "")
                    raise RandomizationConfigError(
                        f"{rule.where}: pattern {pattern!r} matches no {kind} of this model ({kind}: {shown}); "
                        f"fix the pattern or set strict: false")
        return [items[i] for i in chosen]

    def _draw(self, rule: Rule, rng: np.random.Generator, n: int) -> np.ndarray:
        values = rule.dist.sample(rng, 1 if rule.shared else n)
        return np.broadcast_to(values, (n,)) if rule.shared else values


def select_names(names: Sequence[str], patterns: Sequence[str]) -> list[int]:
    """Indices of names matching any pattern and no "!pattern" (only exclusions: start from all)."""
    include = [p for p in patterns if not p.startswith("!")]
    exclude = [p[1:] for p in patterns if p.startswith("!")]
    out = []
    for i, name in enumerate(names):
        if include and not any(fnmatch.fnmatchcase(name, p) for p in include):
            continue
        if any(fnmatch.fnmatchcase(name, p) for p in exclude):
            continue
        out.append(i)
    return out


def _bodies(spec: mujoco.MjSpec) -> list[Any]:
    return list(spec.bodies)[1:]   # without the world body


def _apply_mass(self: DomainRandomization, spec: mujoco.MjSpec, rule: Rule, rng: np.random.Generator) -> None:
    bodies = self._select(_bodies(spec), rule, "bodies")
    values = self._draw(rule, rng, len(bodies))
    model = spec.compile() if rule.mode == "add" else None
    for body, v in zip(bodies, values):
        if rule.mode == "add":
            mass = float(model.body_mass[body.id])
            if mass <= 0:
                continue
            k = (mass + v) / mass
        else:
            k = v
        scale_body_mass(spec, body, max(float(k), 1e-6))


def _apply_friction(self: DomainRandomization, spec: mujoco.MjSpec, rule: Rule, rng: np.random.Generator) -> None:
    geoms = self._select(list(spec.geoms), rule, "geoms")
    values = self._draw(rule, rng, len(geoms))
    every = rule.option("component", "sliding") == "all"
    for geom, v in zip(geoms, values):
        friction = np.array(geom.friction, dtype=float)
        idx = slice(None) if every else slice(0, 1)
        friction[idx] = friction[idx] * v if rule.mode == "scale" else friction[idx] + v
        geom.friction = np.maximum(friction, 0.0)


def _joint_coefficient(attr: str):
    def apply(self: DomainRandomization, spec: mujoco.MjSpec, rule: Rule, rng: np.random.Generator) -> None:
        joints = self._select(list(spec.joints), rule, "joints")
        values = self._draw(rule, rng, len(joints))
        for joint, v in zip(joints, values):
            if rule.mode == "scale":
                scale_attr(joint, attr, float(v))
            else:
                set_first(joint, attr, max(get_first(joint, attr) + float(v), 0.0))
    return apply


def _is_limited(spec: mujoco.MjSpec, joint: Any) -> bool:
    if joint.type not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
        return False
    lo, hi = np.asarray(joint.range, dtype=float)[:2]
    if joint.limited == mujoco.mjtLimited.mjLIMITED_TRUE:
        return True
    return (joint.limited == mujoco.mjtLimited.mjLIMITED_AUTO and bool(spec.compiler.autolimits) and lo < hi)


def _apply_joint_range(self: DomainRandomization, spec: mujoco.MjSpec, rule: Rule, rng: np.random.Generator) -> None:
    joints = [j for j in self._select(list(spec.joints), rule, "joints") if _is_limited(spec, j)]
    if not joints and self.strict:
        raise RandomizationConfigError(f"{rule.where}: the matched joints have no limited hinge/slide range")
    values = self._draw(rule, rng, len(joints))
    about = "ref" if rule.option("about", "centre") == "ref" else "centre"
    for joint, v in zip(joints, values):
        scale_joint_range(joint, float(v), about)


def _apply_limb_length(self: DomainRandomization, spec: mujoco.MjSpec, rule: Rule, rng: np.random.Generator) -> None:
    bodies = self._select(_bodies(spec), rule, "bodies")
    values = self._draw(rule, rng, len(bodies))
    model = spec.compile()
    for body, v in zip(bodies, values):
        scale_limb_length(spec, model, body, float(v))


def _apply_actuator_gain(self: DomainRandomization, spec: mujoco.MjSpec, rule: Rule,
                         rng: np.random.Generator) -> None:
    actuators = self._select(list(spec.actuators), rule, "actuators")
    values = self._draw(rule, rng, len(actuators))
    for act, v in zip(actuators, values):
        scale_actuator_gain(act, float(v))


def _apply_gravity(self: DomainRandomization, spec: mujoco.MjSpec, rule: Rule, rng: np.random.Generator) -> None:
    gravity = np.array(spec.option.gravity, dtype=float)
    if rule.mode == "scale":
        gravity = gravity * float(self._draw(rule, rng, 1)[0])
    else:
        gravity = gravity + self._draw(rule, rng, 3)
    spec.option.gravity = gravity


_APPLY = {"mass": _apply_mass, "friction": _apply_friction, "damping": _joint_coefficient("damping"),
          "armature": _joint_coefficient("armature"), "stiffness": _joint_coefficient("stiffness"),
          "frictionloss": _joint_coefficient("frictionloss"), "joint_range": _apply_joint_range,
          "limb_length": _apply_limb_length, "actuator_gain": _apply_actuator_gain, "gravity": _apply_gravity}


# ====================================================================== MjSpec edits (shared with variants.py)
def get_first(obj: Any, attr: str) -> float:
    """A coefficient that is a scalar in mujoco 3.x and an array (first entry) in newer versions."""
    value = getattr(obj, attr)
    return float(np.asarray(value, dtype=float).reshape(-1)[0]) if np.ndim(value) else float(value)


def set_first(obj: Any, attr: str, new: float) -> None:
    value = getattr(obj, attr)
    if np.ndim(value):
        arr = np.array(value, dtype=float)
        arr.reshape(-1)[0] = new
        setattr(obj, attr, arr)
    else:
        setattr(obj, attr, float(new))


def scale_attr(obj: Any, attr: str, k: float) -> None:
    """Multiply a scalar or every entry of an array coefficient by k."""
    value = getattr(obj, attr)
    setattr(obj, attr, np.asarray(value, dtype=float) * k if np.ndim(value) else float(value) * k)


def _explicit_inertial(spec: mujoco.MjSpec, body: Any) -> bool:
    mode = spec.compiler.inertiafromgeom
    if mode == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE:
        return False
    if mode == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE:
        return True
    return bool(body.explicitinertial)


def scale_body_mass(spec: mujoco.MjSpec, body: Any, k: float) -> None:
    """Scale a body's mass and inertia by k so that the compiler recomputes a consistent inertial."""
    if _explicit_inertial(spec, body):
        body.mass = float(body.mass) * k
        body.inertia = np.asarray(body.inertia, dtype=float) * k
        full = np.asarray(body.fullinertia, dtype=float)
        if np.isfinite(full).all():
            body.fullinertia = full * k
        return
    for geom in body.geoms:
        if np.isfinite(geom.mass):
            geom.mass = float(geom.mass) * k
        else:
            geom.density = float(geom.density) * k


def bake_total_mass(spec: mujoco.MjSpec) -> None:
    """Replace the deprecated `settotalmass` by the equivalent densities, so later edits stay local."""
    target = spec.compiler.settotalmass
    if target is None or not target > 0:
        return
    spec.compiler.settotalmass = -1
    total = float(spec.compile().body_mass.sum())
    if total <= 0:
        return
    for body in _bodies(spec):
        scale_body_mass(spec, body, target / total)


def scale_geom_friction(geom: Any, k: float, component: str = "sliding") -> None:
    friction = np.array(geom.friction, dtype=float)
    if component == "all":
        friction *= k
    else:
        friction[0] *= k
    geom.friction = friction


def scale_joint_range(joint: Any, k: float, about: str = "centre") -> None:
    """Scale the width of a joint range by k about its centre or about its (clipped) reference position."""
    lo, hi = (float(x) for x in np.asarray(joint.range, dtype=float)[:2])
    centre = (lo + hi) / 2 if about != "ref" else min(max(float(joint.ref), lo), hi)
    joint.range = np.array([centre + k * (lo - centre), centre + k * (hi - centre)])


def scale_actuator_gain(act: Any, k: float) -> None:
    """Scale the force per unit control of an actuator by k."""
    gain, bias = np.array(act.gainprm, dtype=float), np.array(act.biasprm, dtype=float)
    if act.gaintype == mujoco.mjtGain.mjGAIN_MUSCLE:
        idx = 2 if gain[2] > 0 else 3        # peak force, else the force scale
        gain[idx] *= k
        if act.biastype == mujoco.mjtBias.mjBIAS_MUSCLE:
            bias[idx] *= k
    elif act.gaintype in (mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtGain.mjGAIN_AFFINE):
        gain[:3] *= k
        if act.biastype == mujoco.mjtBias.mjBIAS_AFFINE:
            bias[:3] *= k
        elif act.biastype != mujoco.mjtBias.mjBIAS_NONE:
            raise ValueError(f"actuator_gain: cannot scale actuator {act.name!r} with bias type {act.biastype}; "
                             f"exclude it with '!{act.name}'")
    else:
        raise ValueError(f"actuator_gain: cannot scale actuator {act.name!r} with gain type {act.gaintype}; "
                         f"exclude it with '!{act.name}'")
    act.gainprm, act.biasprm = gain, bias


def _quat_mat(quat: np.ndarray) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, dtype=float))
    return mat.reshape(3, 3)


def _joint_anchor(body: Any) -> np.ndarray:
    """The point a limb rotates about, in the body frame: its first hinge/ball joint, else its origin."""
    for joint in body.joints:
        if joint.type in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_BALL):
            return np.array(joint.pos, dtype=float)
    return np.zeros(3)


_LENGTH_TYPES = (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER)
_AXIS_TYPES = (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_ELLIPSOID)


def scale_limb_length(spec: mujoco.MjSpec, model: mujoco.MjModel, body: Any, k: float) -> None:
    """Stretch a body's limb by k about its joint anchor (see the module docstring).

    `model` is `spec` compiled before this edit (for element ids and orientations).
    """
    anchor = _joint_anchor(body)
    stretch = lambda p: anchor + k * (np.asarray(p, dtype=float) - anchor)  # noqa: E731
    children = list(body.bodies)
    child_anchors = []
    for child in children:
        rot = _quat_mat(model.body_quat[child.id])
        child_anchors.append(model.body_pos[child.id] + rot @ _joint_anchor(child))
    direction = (np.mean(child_anchors, axis=0) - anchor) if child_anchors else None

    for geom in body.geoms:
        fromto = np.asarray(geom.fromto, dtype=float)
        if np.isfinite(fromto).all():
            geom.fromto = np.concatenate([stretch(fromto[:3]), stretch(fromto[3:])])
            continue
        old_pos = np.array(geom.pos, dtype=float)
        geom.pos = stretch(old_pos)
        size = np.array(geom.size, dtype=float)
        if geom.type in _LENGTH_TYPES:
            size[1] *= k
        elif geom.type in _AXIS_TYPES:
            d = direction if direction is not None else old_pos - anchor
            if np.linalg.norm(d) > 1e-9:
                rot = _quat_mat(model.geom_quat[geom.id])
                size[int(np.argmax(np.abs(rot.T @ d)))] *= k
        geom.size = size
    for site in body.sites:
        site.pos = stretch(site.pos)
    if _explicit_inertial(spec, body):
        body.ipos = stretch(body.ipos)
    for child, old in zip(children, child_anchors):
        delta = stretch(old) - old
        if child.frame is not None:   # child.pos is expressed in its frame
            delta = _quat_mat(child.frame.quat).T @ delta
        child.pos = np.asarray(child.pos, dtype=float) + delta


def _geom_bottom(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> float:
    centre, rot, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
    gtype = model.geom_type[g]
    up = rot[2]   # world z expressed in the geom frame
    if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
        return centre[2] - size[0]
    if gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return centre[2] - abs(up[2]) * size[1] - size[0]
    if gtype == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return centre[2] - abs(up[2]) * size[1] - size[0] * math.sqrt(max(0.0, 1 - up[2] ** 2))
    if gtype == mujoco.mjtGeom.mjGEOM_BOX:
        return centre[2] - float(np.abs(up) @ size)
    if gtype == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return centre[2] - float(np.linalg.norm(up * size))
    aabb = model.geom_aabb[g]   # centre and half-sizes in the geom frame (meshes, height fields)
    return centre[2] + float(up @ aabb[:3]) - float(np.abs(up) @ aabb[3:])


def lowest_point(spec: "mujoco.MjSpec | mujoco.MjModel") -> float:
    """Height of the lowest collision geom of the moving bodies at qpos0 (of a spec or a compiled model)."""
    model = spec.compile() if isinstance(spec, mujoco.MjSpec) else spec
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    heights = [_geom_bottom(model, data, g) for g in range(model.ngeom)
               if model.geom_bodyid[g] != 0 and (model.geom_contype[g] or model.geom_conaffinity[g])]
    return min(heights) if heights else 0.0


def restore_ground_clearance(spec: mujoco.MjSpec, reference_low: float) -> float:
    """Shift floating roots vertically so the lowest collision geom is back at `reference_low`.

    Free-joint roots move their body position; roots on a vertical slide joint also shift its `ref`,
    so that the joint coordinate still equals the height (the quantity health checks look at).
    Returns the applied shift.
    """
    model = spec.compile()
    dz = reference_low - lowest_point(model)
    if abs(dz) < 1e-9:
        return 0.0
    for body in spec.worldbody.bodies:
        joints = list(body.joints)
        free = any(j.type == mujoco.mjtJoint.mjJNT_FREE for j in joints)
        rot = _quat_mat(model.body_quat[body.id])
        vertical = [j for j in joints if j.type == mujoco.mjtJoint.mjJNT_SLIDE
                    and abs((rot @ np.asarray(j.axis, dtype=float))[2]) > 1 - 1e-6]
        if not free and not vertical:
            continue
        pos = np.array(body.pos, dtype=float)
        pos[2] += dz
        body.pos = pos
        for joint in vertical:
            axis_z = (rot @ np.asarray(joint.axis, dtype=float))[2] / np.linalg.norm(joint.axis)
            joint.ref = float(joint.ref) + dz / axis_z
    return dz


# ====================================================================== loading
def available_configs() -> list[str]:
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))


def load_randomization(cfg: "str | Path | Mapping[str, Any] | DomainRandomization",
                       body_name: str | None = None) -> DomainRandomization:
    """A `DomainRandomization` from a dict, a YAML path or a named config.

    Names: "default" is `configs/randomization/<body_name>.yaml` if it exists, else `generic.yaml`;
    any other bare name is `configs/randomization/<name>.yaml` (see `available_configs()`).
    """
    if isinstance(cfg, DomainRandomization):
        return cfg
    if isinstance(cfg, Mapping):
        return DomainRandomization.from_config(cfg)
    if not isinstance(cfg, (str, Path)):
        raise RandomizationConfigError(f"randomization must be a dict, a YAML path or a config name, got {cfg!r}")
    text = str(cfg)
    path = Path(text)
    if not path.suffix and "/" not in text and "\\" not in text:
        name = text
        if name == "default":
            name = body_name if body_name and (CONFIG_DIR / f"{body_name}.yaml").exists() else GENERIC_CONFIG
        path = CONFIG_DIR / f"{name}.yaml"
        if not path.exists():
            names = available_configs()
            raise RandomizationConfigError(f"no randomization config named {text!r}{_suggest(text, names)}; "
                                           f"named configs: default, {', '.join(names)}")
    if not path.exists():
        raise RandomizationConfigError(f"randomization config file {str(path)!r} does not exist")
    import yaml
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        raise RandomizationConfigError(f"randomization config {str(path)!r} is not valid YAML: {err}") from None
    return DomainRandomization.from_config(data, source=str(path))
