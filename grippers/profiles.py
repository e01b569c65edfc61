"""Device profiles: what a model is, how to reach it, and the limits the library enforces.

A profile is a TOML file (YAML with the ``yaml`` extra) validated by the pydantic models below. Values are
in the units people read on datasheets (mm, mm/s, N, mA); the backends convert to SI once. Profiles are found
on a search path so users add their own without touching the package: an explicit file, then
``GRIPPERS_PROFILE_PATH`` (directories or files, ``os.pathsep``-separated), then the user's config directory
(``$XDG_CONFIG_HOME/grippers/profiles``, default ``~/.config/grippers/profiles``), then the folders installed
plugins declare (entry-point group ``grippers.profiles``), then the built-ins shipped as the data package
``grippers._profiles``. Which model validates a profile is its family's backend's to say (``profile_model``).
"""

from __future__ import annotations

import contextvars
import json
import logging
import os
import sys
import threading
import tomllib
import types
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Annotated, Any

from pydantic import ConfigDict, Field, TypeAdapter, ValidationError

from .errors import ProfileError

# The model lives in profile_model.py (no import circle); every name stays importable from here.
from .profile_model import (  # noqa: F401  (re-exported)
    MAX_ACCEL_MM_S2,
    MAX_FORCE_N,
    MAX_LENGTH_MM,
    MAX_SPEED_MM_S,
    MAX_TIME_SCALE,
    MAX_TIMEOUT_S,
    Accel,
    Baudrate,
    CanId,
    Connection,
    Force,
    Length,
    Limits,
    Mechanics,
    NonNegative,
    Port,
    Positive,
    PositiveAccel,
    PositiveForce,
    PositiveLength,
    PositiveSpeed,
    ProfileBase,
    Safety,
    Speed,
    Timeout,
    TimeScale,
    _key,
    _Model,
)

log = logging.getLogger(__name__)

PROFILE_SUFFIXES = (".toml", ".yaml", ".yml", ".json")

MAX_PROFILE_BYTES = 1 << 20  # 1 MiB: every shipped profile is under 2 kB; a bigger file is not a profile
# How many ``extends`` a profile may stand on (docs/profiles.md says so). Each level searches the profile path
# and validates its base, so a chain of 300 took two minutes to load (and ``profiles list`` loads every file):
# no real family tree of grippers is deeper than a handful (vendor, model, variant, site), so a deeper one is
# refused by name, in one short line (issue 33 §3: each level used to prefix its own file to the message).
MAX_EXTENDS_DEPTH = 16

# The families' own sections and profile models live with their backends (issue 28 §2: the backend declares
# its profile model, the only registry). Names that were once defined here (a family's profile class, its
# sections) stay importable from here: they are looked up in the modules of the installed families' models.


def __getattr__(name: str) -> Any:
    if not name.startswith("_"):
        import importlib

        for model in installed_profile_models():
            module = importlib.import_module(model.__module__)
            if hasattr(module, name):
                return getattr(module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


Profile = ProfileBase  # the type users annotate with


# --- loading --------------------------------------------------------------------------------------------
#
# Every lookup walks the search path in order and the first file that declares the name (or an alias) wins,
# whether it is valid or not: a user's file that lowers a limit is never passed over for a built-in. Files
# are parsed once per modification (cache keyed by path, mtime, size and inode), and a file larger than
# MAX_PROFILE_BYTES is refused unread, so a stray 50 MB file on the path costs a stat(), not a parse.


def _profile_model(family: Any) -> type[ProfileBase]:
    """The model a profile of ``family`` is validated with: the one its backend declares (the only registry,
    issue 28), or the generic :class:`ProfileBase` for a backend whose ``profile_model`` is None."""
    from .backends import available_backends, find_backend

    if isinstance(family, str) and family:
        backend = find_backend(family)
        if backend is not None:
            model = getattr(backend, "profile_model", None)
            return model if model is not None else ProfileBase
    known = ", ".join(available_backends())
    raise ValueError(f"family: unknown family {family!r} (installed: {known}; others come from backends)")


def installed_profile_models() -> list[type[ProfileBase]]:
    """The profile model of every installed family (built in or plugin) that declares one, once each.

    A backend that cannot be imported (an optional dependency missing) is skipped with a log line: the models
    of the others are still what ``grippers profiles schema`` shows.
    """
    from .backends import available_backends, find_backend

    models: list[type[ProfileBase]] = []
    for family in available_backends():
        try:
            backend = find_backend(family)
        except Exception as exc:  # a broken or half-installed plugin must not hide the others
            log.warning("skipping the profile model of family %r: %s", family, exc)
            continue
        model = getattr(backend, "profile_model", None)
        if model is not None and model not in models:
            models.append(model)
    return models


Stamp = tuple[int, int, int]  # st_mtime_ns, st_size, st_ino

_cache_lock = threading.Lock()
_raw_cache: dict[str, tuple[Stamp, dict[str, Any] | ProfileError]] = {}
_profile_cache: dict[str, tuple[tuple[tuple[str, Stamp], ...], ProfileBase]] = {}


CACHE_ENTRIES = 512  # files remembered; the oldest is forgotten first


def _remember(cache: dict[str, Any], key: str, value: Any) -> None:
    with _cache_lock:
        cache.pop(key, None)
        cache[key] = value
        while len(cache) > CACHE_ENTRIES:
            del cache[next(iter(cache))]


def _stamp(path: Path) -> Stamp:
    try:
        st = path.stat()
    except FileNotFoundError:
        raise ProfileError(f"{path}: profile file not found") from None
    except OSError as exc:
        raise ProfileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    return (st.st_mtime_ns, st.st_size, st.st_ino)


def _read(path: Path) -> dict[str, Any]:
    """Parse one file (size-bounded); no cache, no validation."""
    try:
        with path.open("rb") as f:
            blob = f.read(MAX_PROFILE_BYTES + 1)
    except FileNotFoundError:
        raise ProfileError(f"{path}: profile file not found") from None
    except OSError as exc:
        raise ProfileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if len(blob) > MAX_PROFILE_BYTES:
        raise ProfileError(
            f"{path}: larger than {MAX_PROFILE_BYTES} bytes, the most a profile may have; not read"
        )
    try:
        text = blob.decode("utf-8")
        if path.suffix == ".toml":
            data: Any = tomllib.loads(text)
        elif path.suffix == ".json":
            data = json.loads(text)
        elif path.suffix in (".yaml", ".yml"):
            try:
                import yaml
            except ImportError:
                raise ProfileError(f"{path}: YAML profiles need: pip install 'grippers[yaml]'") from None
            data = yaml.safe_load(text)
        else:
            raise ProfileError(f"{path}: not a profile file (expected one of {', '.join(PROFILE_SUFFIXES)})")
    except UnicodeDecodeError as exc:
        raise ProfileError(f"{path}: not UTF-8 text: {exc.reason} at byte {exc.start}") from None
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ProfileError(f"{path}: not valid {path.suffix[1:].upper()}: {exc}") from None
    except ProfileError:
        raise
    except Exception as exc:  # YAML's errors, without importing yaml here; RecursionError of deep JSON
        raise ProfileError(f"{path}: cannot parse: {exc}") from None
    if not isinstance(data, dict):
        raise ProfileError(f"{path}: a profile is a mapping of fields, not {type(data).__name__}")
    return data


def _raw(path: Path) -> dict[str, Any]:
    """The file's mapping, parsed once per modification. Callers must not mutate it."""
    key, stamp = os.path.abspath(path), _stamp(path)
    with _cache_lock:
        hit = _raw_cache.get(key)
    if hit is None or hit[0] != stamp:
        try:
            value: dict[str, Any] | ProfileError = _read(path)
        except ProfileError as exc:
            value = exc
        hit = (stamp, value)
        _remember(_raw_cache, key, hit)
    if isinstance(hit[1], ProfileError):
        raise ProfileError(str(hit[1])) from None  # a fresh one: re-raising one object grows its traceback
    return hit[1]


def _declared(path: Path, names_only: bool = False) -> set[str]:
    """The lookup keys a file declares: its name and aliases (raises the file's ProfileError)."""
    data = _raw(path)
    aliases = data.get("aliases")
    names = [data.get("name"), *(aliases if isinstance(aliases, list) and not names_only else [])]
    return {_key(n) for n in names if isinstance(n, str)}


def _merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """``override`` over ``base``: tables merge key by key, everything else is replaced."""
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def _find(name: str, skip: set[str], *, names_only: bool = False) -> tuple[Path | None, Path | None]:
    """The first file on the search path declaring ``name``, not in ``skip``; and the first one in ``skip``
    that declares it (to tell a cycle from a missing base)."""
    key, skipped = _key(name), None
    for path, absolute, every, names in _scan_index.get() or _index_files():
        declared = names if names_only else every
        if declared is None:
            if _key(path.stem) == key:
                _declared(path, names_only)  # meant to be that profile, and broken: raise its ProfileError
            continue
        if key in declared:
            if absolute in skip:
                skipped = skipped or path
                continue
            return path, skipped
    return None, skipped


_Indexed = tuple[Path, str, set[str] | None, set[str] | None]  # path, its absolute form, names+aliases, names

# The search path's files and the names they declare, while scan_profiles() runs: every ``extends`` of every
# file is looked up here instead of stat-ing and reading the whole path again (a 300-file chain made the
# listing cubic in the number of files).
_scan_index: contextvars.ContextVar[list[_Indexed] | None] = contextvars.ContextVar(
    "_scan_index", default=None
)


def _index_files() -> Iterator[_Indexed]:
    for path in _candidate_files():
        every: set[str] | None
        names: set[str] | None
        try:
            every, names = _declared(path), _declared(path, names_only=True)
        except ProfileError:
            every = names = None
        yield path, os.path.abspath(path), every, names


class _ChainTooDeep(ProfileError):
    """More than :data:`MAX_EXTENDS_DEPTH` levels: raised once, where the cap is passed, naming the top."""


def _load(path: Path, chain: tuple[str, ...]) -> tuple[ProfileBase, tuple[tuple[str, Stamp], ...]]:
    """Validate one file, its ``extends`` resolved; returns the stamps of every file it was built from."""
    where = str(path)
    me = os.path.abspath(path)
    data = _raw(path)
    stamps: tuple[tuple[str, Stamp], ...] = ((me, _stamp(path)),)
    base_name = data.get("extends")
    if base_name is not None:
        if not isinstance(base_name, str) or not base_name.strip():
            raise ProfileError(f"{where}: extends: must be the name of a profile, not {base_name!r}")
        if len(chain) >= MAX_EXTENDS_DEPTH:
            raise _ChainTooDeep(
                f"{chain[0]}: more than {MAX_EXTENDS_DEPTH} levels of extends (down to {where}); "
                f"at most {MAX_EXTENDS_DEPTH}: flatten the chain"
            )
        skip = {*chain, me}
        base_path, in_chain = _find(base_name, skip)
        if base_path is None:
            if in_chain is not None:
                files = " -> ".join([*chain, me, os.path.abspath(in_chain)])
                raise ProfileError(f"{where}: extends: {base_name!r} makes a cycle ({files})")
            raise ProfileError(f"{where}: extends: no profile named {base_name!r} ({_describe_path()})")
        try:
            base, base_stamps = _load(base_path, (*chain, me))
        except _ChainTooDeep:
            raise  # already names the top file and the cap: not one more prefix per level
        except ProfileError as exc:
            raise ProfileError(f"{where}: extends {base_name!r}: {exc}") from None
        inherited = base.model_dump(mode="python", exclude={"aliases"})  # aliases stay with the base
        data = _merge(inherited, data)
        stamps += base_stamps
    return parse_profile(data, where), stamps


def _format_errors(where: str, exc: ValidationError) -> str:
    parts = []
    for err in exc.errors(include_url=False):
        loc = ".".join(str(p) for p in err["loc"]) or "(top level)"
        msg = str(err["msg"]).removeprefix("Value error, ")
        parts.append(f"{loc}: {msg}" if err["loc"] else msg)
    return f"{where}: " + "; ".join(parts)


class GenericProfile(ProfileBase):
    """A profile read without its family's model: identity, mechanics, safety and connection; the family's own
    sections are dropped, not refused. What a ``zenoh://`` client makes of a served profile when the vendor's
    plugin is not installed here (issue 28 §3: any process can use a served gripper)."""

    model_config = ConfigDict(extra="ignore", frozen=True)


def parse_profile(data: dict[str, Any], where: str = "<profile>", *, generic: bool = False) -> ProfileBase:
    """Validate a mapping as a profile of its family; errors name ``where``, the field and the rule.

    With ``generic=True`` a family that is not installed here is read as a :class:`GenericProfile` instead of
    refused (a profile served by another process, already validated there by its family's model).
    """
    if not isinstance(data, dict):
        raise ProfileError(f"{where}: a profile is a mapping of fields, not {type(data).__name__}")
    try:
        model = _profile_model(data.get("family"))
    except ValueError as exc:
        if not generic:
            raise ProfileError(f"{where}: {exc}") from None
        model = GenericProfile
    try:
        profile = model.model_validate(data)
    except ValidationError as exc:
        raise ProfileError(_format_errors(where, exc)) from None
    return profile.model_copy(update={"path": where})


def load_file(path: str | os.PathLike[str]) -> ProfileBase:
    """One profile file, validated (its ``extends`` resolved); cached until it or a base changes."""
    p = Path(path)
    key = os.path.abspath(p)
    with _cache_lock:
        hit = _profile_cache.get(key)
    if hit is not None:
        try:
            fresh = all(_stamp(Path(f)) == stamp for f, stamp in hit[0])
        except ProfileError:
            fresh = False
        if fresh:
            return hit[1]
    # Only valid profiles are remembered here: a parse error is remembered by _raw (the costly part), and a
    # validation error may depend on a base file that is fixed later.
    profile, stamps = _load(p, ())
    _remember(_profile_cache, key, (stamps, profile))
    return profile


def extends_chain(path: str | os.PathLike[str]) -> list[str]:
    """The files a profile file is built from, as absolute paths: itself first, its base, the base's base.

    For a writer that must not replace a file its own result would stand on (``selftest --write-profile``
    onto the base's file left a profile extending itself, issue 33 §1). Raises the file's ProfileError."""
    _profile, stamps = _load(Path(path), ())
    return [file for file, _stamp in stamps]


def validate_file(path: str | os.PathLike[str]) -> list[str]:
    """Every problem in one profile file, one line each; empty when it is valid."""
    try:
        load_file(path)
    except ProfileError as exc:
        return [str(exc)]
    return []


def user_profile_dir() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "grippers" / "profiles"


def _files_in(entry: Path) -> list[Path]:
    try:
        if entry.is_file():
            return [entry]
        if entry.is_dir():
            return sorted(p for p in entry.iterdir() if p.suffix in PROFILE_SUFFIXES and p.is_file())
    except OSError as exc:  # an unreadable directory on the path is skipped, not fatal
        log.warning("skipping %s on the profile path: %s", entry, exc.strerror or exc)
    return []


PROFILES_ENTRY_POINT_GROUP = "grippers.profiles"

_plugin_folder_cache: dict[tuple[str, ...], list[Path]] = {}


def _folder_of(value: Any) -> list[Path]:
    """The folders an entry point of :data:`PROFILES_ENTRY_POINT_GROUP` names: a package (its own folder), a
    path, or a list of paths (or a callable returning one of these)."""
    if callable(value) and not isinstance(value, type):
        value = value()
    if isinstance(value, types.ModuleType):
        return [Path(str(resources.files(value)))] if getattr(value, "__path__", None) else []
    if isinstance(value, (str, os.PathLike)):
        return [Path(value)]
    if isinstance(value, (list, tuple)):
        return [folder for item in value for folder in _folder_of(item)]
    return []


def plugin_profile_folders() -> list[Path]:
    """The profile folders installed plugins contribute, in the entry-point group ``grippers.profiles``::

        [project.entry-points."grippers.profiles"]
        acme = "acme_grippers.profiles"   # a package whose folder holds the family's .toml files

    Searched by name after ``GRIPPERS_PROFILE_PATH`` and the user folder, before the built-ins, so an
    installed plugin's profiles open by name (``sim://NAME``, ``profiles list``) with no environment variable.
    Found once per ``sys.path`` (the entry points are read from the installed distributions' metadata).
    """
    key = tuple(sys.path)
    cached = _plugin_folder_cache.get(key)
    if cached is not None:
        return list(cached)
    from importlib.metadata import entry_points

    folders: list[Path] = []
    for ep in sorted(entry_points(group=PROFILES_ENTRY_POINT_GROUP), key=lambda e: e.name):
        try:
            found = _folder_of(ep.load())
        except Exception as exc:  # one broken plugin must not hide every other profile
            log.warning("skipping the profile folder of plugin %r (%s): %s", ep.name, ep.value, exc)
            continue
        folders.extend(f for f in found if f not in folders)
    with _cache_lock:
        _plugin_folder_cache.clear()
        _plugin_folder_cache[key] = folders
    return list(folders)


def search_path() -> list[Path]:
    """Directories and files searched for profiles, first match wins (the built-ins come last):
    ``GRIPPERS_PROFILE_PATH``, the user folder, then the folders installed plugins contribute."""
    entries = [Path(e) for e in os.environ.get("GRIPPERS_PROFILE_PATH", "").split(os.pathsep) if e]
    entries.append(user_profile_dir())
    entries.extend(plugin_profile_folders())
    return entries


def _builtin_files() -> list[Path]:
    root = resources.files("grippers._profiles")
    return sorted(Path(str(p)) for p in root.iterdir() if p.name.endswith(PROFILE_SUFFIXES))


def _candidate_files() -> Iterator[Path]:
    for entry in search_path():
        yield from _files_in(entry)
    yield from _builtin_files()


@dataclass(frozen=True)
class ProfileScan:
    """Every profile on the search path (first of each name), and the files that failed, with why."""

    profiles: list[ProfileBase]
    problems: list[tuple[str, str]]  # (file, the ProfileError's message)
    shadowed: list[tuple[str, str]]  # (file, the file whose profile of the same name wins)


def scan_profiles() -> ProfileScan:
    """What ``grippers profiles list`` shows: one bad file is named, the rest are listed."""
    seen: dict[str, ProfileBase] = {}
    problems: list[tuple[str, str]] = []
    shadowed: list[tuple[str, str]] = []
    index = list(_index_files())
    token = _scan_index.set(index)
    try:
        for path, *_ in index:
            try:
                profile = load_file(path)
            except ProfileError as exc:
                problems.append((str(path), str(exc)))
                continue
            if profile.name in seen:
                shadowed.append((str(path), str(seen[profile.name].path)))
            else:
                seen[profile.name] = profile
    finally:
        _scan_index.reset(token)
    return ProfileScan(list(seen.values()), problems, shadowed)


def list_profiles(*, strict: bool = False) -> list[ProfileBase]:
    """Every profile on the search path; the first of each name wins (a user's file shadows a built-in).

    Files that do not validate are skipped and logged (``scan_profiles`` returns them); ``strict=True``
    raises the first one's ProfileError instead.
    """
    scan = scan_profiles()
    for _file, problem in scan.problems:
        if strict:
            raise ProfileError(problem)
        _warn_once(problem)
    return scan.profiles


_warned: dict[str, None] = {}


def _warn_once(problem: str) -> None:
    """Log a skipped file once per problem, not at every open() of a gripper found by its device type."""
    with _cache_lock:
        if problem in _warned:
            return
        _warned[problem] = None
        while len(_warned) > CACHE_ENTRIES:
            del _warned[next(iter(_warned))]
    log.warning("skipping a profile that does not validate: %s", problem)


def _looks_like_path(name: str) -> bool:
    return name.endswith(PROFILE_SUFFIXES) or os.sep in name or "/" in name


def load_profile(name: str | os.PathLike[str]) -> ProfileBase:
    """A profile by file path, name or alias (``wsg50``, ``WSG 50``, ``msg-150``).

    The first file on the search path that declares the name or alias wins, and if that file is invalid its
    error is raised: falling back to a later file (a built-in) would silently drop the user's limits.

    Raises:
        ProfileError: no profile of that name ("known: ..."), a file that is not found or does not parse,
            or one that does not validate (the message names the file, the field and the rule).
    """
    text = os.fspath(name)
    if _looks_like_path(text):
        return load_file(text)
    path, _ = _find(text, set())
    if path is not None:
        declared = _raw(path).get("name")
        if isinstance(declared, str) and _key(declared) != _key(text):
            # Reached by an alias: the profile of that name that comes first wins, so a user's file named
            # like a built-in is used whichever of the built-in's aliases is asked for.
            path = _find(declared, set(), names_only=True)[0] or path
        return load_file(path)
    names = ", ".join(sorted(p.name for p in list_profiles()))
    raise ProfileError(f"no profile named {text!r} (known: {names}; search path: {_describe_path()})")


def _describe_path() -> str:
    return os.pathsep.join(str(p) for p in search_path()) + os.pathsep + "<built-in>"


def json_schema() -> dict[str, Any]:
    """JSON Schema of every installed family's profile, for editors (``grippers profiles schema``).

    The union of the models the backends declare; told apart by ``family`` when every model fixes it to one
    value (a ``Literal``), else a plain union (a plugin's model may leave ``family`` a free string).
    """
    models = installed_profile_models() or [ProfileBase]
    if len(models) == 1:
        return TypeAdapter(models[0]).json_schema()
    union: Any = models[0]
    for model in models[1:]:
        union = union | model
    try:
        return TypeAdapter(Annotated[union, Field(discriminator="family")]).json_schema()
    except Exception:  # pydantic refuses a discriminator a model does not fix: say "any of" instead
        return TypeAdapter(union).json_schema()
