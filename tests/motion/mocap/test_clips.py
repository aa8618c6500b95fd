"""Which clips a task uses and where their files are found (`loco_il.motion.mocap.clips`)."""
from __future__ import annotations

from loco_il.motion.mocap.clips import PACKAGED_MOCAP, ClipSpec, find_motion_files


def test_user_mocap_folder_adds_clips(tmp_path, monkeypatch):
    """$LOCO_IL_MOCAP adds clips: a file there is found, and the task's own clips still come from the package."""
    user = tmp_path / "my_clips"
    (user / "mine").mkdir(parents=True)
    own = user / "mine" / "walk_copy.txt"
    own.write_bytes((PACKAGED_MOCAP / "deepmimic" / "humanoid3d_walk.txt").read_bytes())
    monkeypatch.setenv("LOCO_IL_MOCAP", str(user))
    assert find_motion_files([ClipSpec("mine/walk_copy.txt")]) == [own]
    assert find_motion_files([ClipSpec("deepmimic/humanoid3d_walk.txt")]) == [
        PACKAGED_MOCAP / "deepmimic" / "humanoid3d_walk.txt"]
