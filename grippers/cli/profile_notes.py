"""What a user should know about the profile search path, said by ``profiles list``, ``doctor`` and ``info``.

A profile file of a plugin or on ``GRIPPERS_PROFILE_PATH`` that has a built-in profile's name replaces it
wherever the name is used (a ``wsg50.toml`` with 800 N where the built-in says 80 N), and a plugin's profile
folder that does not exist contributes nothing: both went unsaid (issue 43 §6).
"""

from __future__ import annotations


def profile_notes() -> list[str]:
    """One line per built-in profile replaced by a file, and per plugin profile folder that is missing."""
    from grippers import profiles

    notes = [_replaces(winner, name) for name, winner in _replaced_builtins().items()]
    for folder in profiles.plugin_profile_folders():
        if not folder.is_dir():
            notes.append(f"a plugin's profile folder does not exist: {folder}")
    return notes


def replaced_note(profile: str | None) -> str | None:
    """The line for ``grippers info``: said when the gripper's profile is a file replacing a built-in one."""
    winner = _replaced_builtins().get(profile or "")
    return None if winner is None else _replaces(winner, profile or "")


def _replaces(winner: str, name: str) -> str:
    return f"{winner} replaces the built-in profile {name} (it is used by that name)"


def _replaced_builtins() -> dict[str, str]:
    """Built-in profile name -> the file that replaces it."""
    from importlib import resources
    from pathlib import Path

    from grippers import profiles

    builtin = Path(str(resources.files("grippers._profiles"))).resolve()
    return {
        Path(loser).stem: winner
        for loser, winner in profiles.scan_profiles().shadowed
        if Path(loser).resolve().parent == builtin
    }
