"""Where ``selftest --write-profile FILE`` writes: everything about FILE is checked before anything moves, and
the file is written whole or not at all.

Issue 33 §1: the target was checked after the run (homing twice, three moves), so a directory, an upper-case
``.TOML``, a chain one level too deep or the base profile's own file failed only then, some of them leaving a
file that nothing could load (the base's own file became a profile extending itself); an existing file or a
symbolic link's target was overwritten without asking. Here:

* before the first motion, :func:`check_target` refuses what cannot end in a loadable profile: the name's
  suffix (the search path takes ``.toml``, lower case), a directory, a symbolic link (never written through),
  an existing file without ``--force``, a folder that cannot be written, and a profile that would not load:
  a stand-in with the same ``extends`` and name is loaded through the profile loader, so the loader's own
  rules (the base found by its name, the chain's depth, the name) decide, and a FILE that the base stands on
  (its own file, or one it extends) is refused;
* after the run, :meth:`ProfileTarget.write` loads the real text the same way, writes it to a temporary
  file in FILE's folder and renames it over FILE, so a reader never sees half a profile and a failure leaves
  FILE as it was.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .output import UsageError

SUFFIX = ".toml"  # what the profile search path takes (grippers/profiles.py PROFILE_SUFFIXES, lower case)
HEADER = (
    "# Written by `grippers selftest`: the base profile with what was measured on this unit.\n"
    "# `extends` names the base: keep this file on the profile search path (docs/profiles.md).\n"
)


@dataclass(frozen=True)
class ProfileTarget:
    """A ``--write-profile`` FILE that passed :func:`check_target`."""

    given: str  # as the user wrote it, for messages
    path: Path  # absolute, not resolved (a link is refused, never followed)
    base: Any  # the ProfileBase the written profile extends
    name: str  # the written profile's name
    force: bool  # --force: an existing file may be replaced

    def write(self, document: dict[str, Any]) -> str:
        """Write ``document`` (from :func:`~grippers.cli.selftest_checks.measured_profile`) as FILE; returns
        FILE. What is written must load through the loader every command uses; FILE is replaced by a rename,
        so it is either the old file or the whole new one."""
        from .toml_out import dumps

        _check_kind(self.given, self.path)  # again: minutes have passed since the first check
        _check_free(self.given, self.path, self.force, after_run=True)
        text = HEADER + dumps(document)
        _loads_as_written(self, text)
        folder = self.path.parent
        try:
            fd, temporary = tempfile.mkstemp(dir=folder, prefix=f".{self.path.name}.", suffix=".tmp")
        except OSError as exc:
            raise UsageError(f"{self.given}: cannot write in {folder}: {exc.strerror or exc}") from None
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(text)
                fh.flush()
                os.fsync(fh.fileno())
            os.chmod(temporary, 0o666 & ~_umask())  # as open() would have made it
            if self.force:
                os.replace(temporary, self.path)
            else:
                _place_new(temporary, self.path)
        except FileExistsError:
            raise UsageError(
                f"{self.given}: a file of that name appeared during the run; it is kept (--force replaces it)"
            ) from None
        except OSError as exc:
            raise UsageError(f"{self.given}: cannot write: {exc.strerror or exc}") from None
        finally:
            if os.path.lexists(temporary):
                os.unlink(temporary)
        return str(self.path)


def check_target(given: str, base: Any, name: str, *, force: bool) -> ProfileTarget:
    """Everything about ``--write-profile FILE`` that can be known before the run; raises UsageError."""
    if not given.endswith(SUFFIX):
        raise UsageError(
            f"--write-profile {given}: a profile file's name must end in {SUFFIX} (lower case: the profile "
            "search path takes no other)"
        )
    target = ProfileTarget(given, Path(os.path.abspath(given)), base, name, force)
    _check_kind(given, target.path)
    folder = target.path.parent
    if not folder.is_dir():
        raise UsageError(f"--write-profile {given}: no folder {folder}")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"--write-profile {given}: cannot write in {folder}")
    _loads_as_written(target, None)  # before the file's existence: --force cannot help a file the base needs
    _check_free(given, target.path, force, after_run=False)
    return target


def _check_kind(given: str, path: Path) -> None:
    if path.is_symlink():
        raise UsageError(
            f"--write-profile {given}: is a symbolic link (to {os.readlink(path)}); selftest does not write "
            "through a link: give the file itself or a new name"
        )
    if path.is_dir():
        raise UsageError(f"--write-profile {given}: is a directory; give a file name ending in {SUFFIX}")
    if os.path.lexists(path) and not path.is_file():
        raise UsageError(f"--write-profile {given}: exists and is not a regular file")


def _check_free(given: str, path: Path, force: bool, *, after_run: bool) -> None:
    if force or not os.path.lexists(path):
        return
    if after_run:
        raise UsageError(
            f"--write-profile {given}: a file of that name appeared during the run; it is kept (--force "
            "replaces it)"
        )
    raise UsageError(
        f"--write-profile {given}: the file exists; add --force to replace it (it is replaced whole, once "
        "the run has ended), or give a new name"
    )


def _loads_as_written(target: ProfileTarget, text: str | None) -> None:
    """Load ``text`` (None: a stand-in with the same ``extends`` and name) from a private folder through the
    profile loader, and check what it stands on: the base the user ran with, found by its name, and not FILE.

    Resolving ``extends`` does not depend on where the file lies (docs/profiles.md: the search path, without
    the file itself), so the private copy loads as FILE will."""
    from grippers.errors import ProfileError
    from grippers.profiles import extends_chain

    from .toml_out import dumps

    base, given = target.base, target.given
    _check_base_is_found(base)
    if text is None:
        text = dumps({"extends": base.name, "name": target.name})
    with tempfile.TemporaryDirectory(prefix="grippers-selftest-") as private:
        trial = Path(private) / target.path.name
        trial.write_text(text, encoding="utf-8")
        try:
            chain = extends_chain(trial)
        except ProfileError as exc:
            message = exc.message.replace(str(trial), given)
            raise UsageError(f"--write-profile {given}: the profile would not load: {message}") from None
    stands_on = {os.path.realpath(f) for f in chain[1:]}
    if os.path.realpath(target.path) in stands_on:
        raise UsageError(
            f"--write-profile {given}: is the file of the base profile {base.name!r} (or of one it extends); "
            "the written profile extends it, so it must stay: give another file"
        )


def _check_base_is_found(base: Any) -> None:
    """The written profile names its base, so the base must be what its name finds on the search path: a base
    read from a file elsewhere would make the written file unloadable, or stand it on another profile."""
    from grippers.errors import ProfileError
    from grippers.profiles import load_profile

    try:
        found = load_profile(base.name)
    except ProfileError:
        found = None
    if found is None or (
        base.path and found.path and os.path.realpath(found.path) != os.path.realpath(base.path)
    ):
        raise UsageError(
            f"--write-profile: the profile {base.name!r} (from {base.path}) is not the one its name finds on "
            "the search path, so a profile extending it would not load; put its folder on "
            "GRIPPERS_PROFILE_PATH (docs/profiles.md)"
        )


def _place_new(temporary: str, path: Path) -> None:
    """Move ``temporary`` to ``path`` unless a file of that name appeared meanwhile (FileExistsError)."""
    try:
        os.link(temporary, path)  # atomic, and never replaces
    except FileExistsError:
        raise
    except OSError:  # a file system without hard links: the check and the rename are then two steps
        if os.path.lexists(path):
            raise FileExistsError(path) from None
        os.replace(temporary, path)


def _umask() -> int:
    """The process's umask (read by setting it, so set back at once): mkstemp makes files 0600."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
