"""What a user should know about the profile search path, said by ``profiles list`` and ``doctor`` alike.

A profile file of a plugin or on ``GRIPPERS_PROFILE_PATH`` that has a built-in profile's name replaces it
wherever the name is used (a ``wsg50.toml`` with 800 N where the built-in says 80 N), and a plugin's profile
folder that does not exist contributes nothing: both went unsaid (issue 43 §6).
"""

from __future__ import annotations


def profile_notes() -> list[str]:
    """One line per built-in profile replaced by a file, and per plugin profile folder that is missing."""
    from importlib import resources
    from pathlib import Path

    from grippers import profiles

    builtin = Path(str(resources.files("grippers._profiles"))).resolve()
    notes = []
    scan = profiles.scan_profiles()
    for loser, winner in scan.shadowed:
        if Path(loser).resolve().parent == builtin:
            notes.append(
                f"{winner} replaces the built-in profile {Path(loser).stem} (it is used by that name)"
            )
    for folder in profiles.plugin_profile_folders():
        if not folder.is_dir():
            notes.append(f"a plugin's profile folder does not exist: {folder}")
    return notes
