"""iMuJoCo-style morphology variants of Hopper, Walker2d and HalfCheetah.

A variant is named `<category>_<percent>_<limb>` and selected in a Task-ID after the body name,
e.g. `Hopper-massdec_25_leg.run.perfect`. Categories (the four families of the iMuJoCo benchmark,
Patacchiola et al., CoLLAs 2023):

* `massinc` / `massdec`: the limb's mass (and with it its inertia) is scaled by 1 +/- p/100
  (geom densities are scaled and the compiler recomputes the inertial).
* `leninc` / `lendec`: the limb is stretched by 1 +/- p/100 about its joint: capsule lengths, geom and
  site positions and the offsets of child bodies scale, so the next joint really is closer or further
  (see `randomization.scale_limb_length`). The root is then shifted vertically so that the lowest
  geom keeps its original height above the ground at the start of an episode.
* `rangedec`: the joint's range of motion shrinks to (1 - p/100) of its width, towards the joint's
  reference position (which stays inside the range, so the initial pose is still valid).
* `frictioninc` / `frictiondec`: the sliding friction of the parts that touch the floor is scaled by
  1 +/- p/100; those geoms get contact priority, so their value (not the floor's) governs the contact.

The grid (category x percent x limb) is generated from the tables below:

    category                 percents      applied to
    massinc, massdec         25, 50        MASS limbs
    leninc, lendec           25            LENGTH limbs
    rangedec                 25, 50, 75    RANGE groups
    frictioninc, frictiondec 25, 50        CONTACT groups

    body         MASS                        LENGTH                          RANGE                   CONTACT
    Hopper       torso thigh leg foot (4)    torso thigh leg foot (4)         thigh leg foot (3)      foot (1)
    Walker2d     torso + 3 right + 3 left    same 7 bodies                    the 6 leg joints        feet (1: both)
    HalfCheetah  torso + 6 leg bodies (7)    the 6 leg bodies                 thighs shins feet (3)   feet (1: both)

which gives Hopper 4*4 + 2*4 + 3*3 + 4*1 = 37, Walker2d 4*7 + 2*7 + 3*6 + 4 = 64 and HalfCheetah
4*7 + 2*6 + 3*3 + 4 = 53 variants: the per-body counts the iMuJoCo authors report (37 Hopper,
53 HalfCheetah, 64 Walker2d; 154 in total). iMuJoCo does not publish its exact list, so this grid is
ours; it reproduces the benchmark's categories and scale, not its individual models. Walker2d's
right-side limbs carry the model's own names (thigh, leg, foot), the left ones `*_left`;
HalfCheetah's range groups narrow the joint of the back and the front leg together (`thighs` = bthigh
and fthigh, ...).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Mapping

import mujoco

from loco_il.environments.randomization import (bake_total_mass, lowest_point, restore_ground_clearance,
                                                scale_body_mass, scale_geom_friction, scale_joint_range,
                                                scale_limb_length)
from loco_il.environments.registry import UnknownTaskError, _suggest

PERCENTS: dict[str, tuple[int, ...]] = {
    "mass": (25, 50),
    "length": (25,),
    "range": (25, 50, 75),
    "friction": (25, 50),
}
CATEGORIES: dict[str, tuple[str, int]] = {   # name -> (family, sign)
    "massinc": ("mass", +1), "massdec": ("mass", -1),
    "leninc": ("length", +1), "lendec": ("length", -1),
    "rangedec": ("range", -1),
    "frictioninc": ("friction", +1), "frictiondec": ("friction", -1),
}
_NAME = re.compile(r"^(?P<category>[a-z]+)_(?P<percent>\d+)_(?P<limb>\w+)$")


class UnknownVariantError(UnknownTaskError):
    """An unknown or malformed variant name; the message names close valid variants."""


@dataclass(frozen=True)
class VariantTable:
    """Which model elements each limb name of a body refers to, per family."""

    mass: Mapping[str, tuple[str, ...]]       # limb -> body names
    length: Mapping[str, tuple[str, ...]]     # limb -> body names
    range: Mapping[str, tuple[str, ...]]      # group -> joint names
    friction: Mapping[str, tuple[str, ...]]   # contact group -> geom names

    def groups(self, family: str) -> Mapping[str, tuple[str, ...]]:
        return getattr(self, family)


def _each(*names: str) -> dict[str, tuple[str, ...]]:
    return {n: (n,) for n in names}


_WALKER_LIMBS = ("torso", "thigh", "leg", "foot", "thigh_left", "leg_left", "foot_left")
_CHEETAH_LEGS = ("bthigh", "bshin", "bfoot", "fthigh", "fshin", "ffoot")

TABLES: dict[str, VariantTable] = {
    "Hopper": VariantTable(
        mass=_each("torso", "thigh", "leg", "foot"),
        length=_each("torso", "thigh", "leg", "foot"),
        range={"thigh": ("thigh_joint",), "leg": ("leg_joint",), "foot": ("foot_joint",)},
        friction={"foot": ("foot_geom",)}),
    "Walker2d": VariantTable(
        mass=_each(*_WALKER_LIMBS),
        length=_each(*_WALKER_LIMBS),
        range={limb: (f"{limb}_joint",) for limb in _WALKER_LIMBS[1:]},
        friction={"feet": ("foot_geom", "foot_left_geom")}),
    "HalfCheetah": VariantTable(
        mass=_each("torso", *_CHEETAH_LEGS),
        length=_each(*_CHEETAH_LEGS),
        range={"thighs": ("bthigh", "fthigh"), "shins": ("bshin", "fshin"), "feet": ("bfoot", "ffoot")},
        friction={"feet": ("bfoot", "ffoot")}),
}


def list_variants(body_name: str) -> list[str]:
    """All variant names of a body, sorted ([] for bodies without variants)."""
    table = TABLES.get(body_name)
    if table is None:
        return []
    names = []
    for category, (family, _) in CATEGORIES.items():
        for percent in PERCENTS[family]:
            names.extend(f"{category}_{percent}_{limb}" for limb in table.groups(family))
    return sorted(names)


@dataclass(frozen=True)
class Variant:
    body: str
    name: str
    category: str
    family: str
    percent: int
    limb: str
    factor: float              # multiplier of the mass, length, range width or friction
    targets: tuple[str, ...]   # names of the edited bodies, joints or geoms


def parse_variant(body_name: str, variant: str) -> Variant:
    """Check a variant name and say what it changes; unknown names raise `UnknownVariantError`."""
    known = list_variants(body_name)
    if not known:
        raise UnknownVariantError(f"{body_name} has no morphology variants (bodies with variants: "
                                  f"{', '.join(sorted(TABLES))}); got {variant!r}")
    if variant not in known:
        match = _NAME.match(variant or "")
        hint = ""
        if match is None or match["category"] not in CATEGORIES:
            hint = f" Names are <category>_<percent>_<limb> with category in {', '.join(CATEGORIES)}."
        raise UnknownVariantError(f"unknown variant {variant!r} of {body_name}; closest: "
                                  f"{_suggest(variant, known)}.{hint} See list_variants({body_name!r}) "
                                  f"for all {len(known)}.")
    match = _NAME.match(variant)
    category, percent, limb = match["category"], int(match["percent"]), match["limb"]
    family, sign = CATEGORIES[category]
    factor = 1.0 + sign * percent / 100.0
    return Variant(body_name, variant, category, family, percent, limb, factor,
                   TABLES[body_name].groups(family)[limb])


def _find(spec: mujoco.MjSpec, kind: str, name: str):
    element = getattr(spec, kind)(name)
    if element is None:
        raise KeyError(f"variant needs the {kind} {name!r}, which this model does not have")
    return element


def apply_variant(spec: mujoco.MjSpec, body_name: str, variant: str) -> Variant:
    """Edit `spec` into the named variant (before compiling) and return its description."""
    v = parse_variant(body_name, variant)
    bake_total_mass(spec)
    if v.family == "mass":
        for name in v.targets:
            scale_body_mass(spec, _find(spec, "body", name), v.factor)
    elif v.family == "length":
        reference_low = lowest_point(spec)
        model = spec.compile()
        for name in v.targets:
            scale_limb_length(spec, model, _find(spec, "body", name), v.factor)
        restore_ground_clearance(spec, reference_low)
    elif v.family == "range":
        for name in v.targets:
            scale_joint_range(_find(spec, "joint", name), v.factor, about="ref")
    else:
        geoms = [_find(spec, "geom", name) for name in v.targets]
        top = max(int(g.priority) for g in spec.geoms)
        condim = max(int(g.condim) for g in spec.geoms)
        for geom in geoms:
            scale_geom_friction(geom, v.factor)
            # higher priority: this geom's friction (not the larger of the pair) is used in its contacts;
            # its condim is raised to the largest in the model, which the pair would have used anyway
            geom.priority = top + 1
            geom.condim = max(int(geom.condim), condim)
    return v


__all__ = ["CATEGORIES", "PERCENTS", "TABLES", "UnknownVariantError", "Variant", "apply_variant",
           "list_variants", "parse_variant"]
