"""``grippers profiles [list|show NAME|validate FILE...|schema|path]``: the device profiles, and checks.

Validation reports every problem of every file, one line each, and exits 1 if any file is invalid, so it can
gate a CI job that ships custom profiles. ``schema`` prints the profiles' JSON Schema for editors.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING, Any

from .output import EXIT_FAILED, EXIT_OK, PROFILES_SCHEMA_ID, UsageError, table, to_plain, write_json

if TYPE_CHECKING:
    from grippers.profiles import ProfileBase

HELP = "list the device profiles, show one, validate profile files, or print their JSON Schema"
EXAMPLE = (
    "grippers profiles list\n"
    "         grippers profiles show PROFILE\n"
    "         grippers profiles validate my-gripper.toml\n"
    "         grippers profiles schema > profile.schema.json\n"
    "         grippers profiles path            (where profiles are searched)"
)

ACTIONS = ("list", "show", "validate", "schema", "path")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", nargs="?", choices=ACTIONS, default="list", help="default: list")
    parser.add_argument(
        "names", nargs="*", metavar="NAME|FILE", help="profile name (show) or files (validate)"
    )
    parser.add_argument("--json", action="store_true", help="print JSON (schema in docs/cli.md)")


def summary(profile: ProfileBase) -> dict[str, Any]:
    m = profile.mechanics
    return {
        "name": profile.name,
        "family": profile.family,
        "vendor": profile.vendor,
        "model": profile.model,
        "aliases": list(profile.aliases),
        "stroke_mm": m.stroke_mm,
        "max_force_n": profile.limits().max_force,
        "url": profile.url,
        "path": profile.path,
    }


def _origin(path: str | None) -> str:
    """'built-in' for the profiles shipped in the package, else the file that shadows or adds one."""
    from importlib import resources
    from pathlib import Path

    if path is None:
        return "-"
    builtin = Path(str(resources.files("grippers._profiles"))).resolve()
    return "built-in" if Path(path).resolve().parent == builtin else path


def run(args: argparse.Namespace) -> int:
    from grippers import profiles

    if args.action in ("list", "schema", "path") and args.names:
        raise UsageError(f"{args.action} takes no names")
    if args.action == "list":
        scan = profiles.scan_profiles()  # one bad file is named below, the rest still listed
        rows = [summary(p) for p in sorted(scan.profiles, key=lambda p: (p.family, p.name))]
        for _file, problem in scan.problems:
            print(f"grippers: skipped: {problem}", file=sys.stderr)
        from .profile_notes import profile_notes

        for note in profile_notes():
            print(f"grippers profiles: note: {note}", file=sys.stderr)
        if args.json:
            document: dict[str, Any] = {"schema": PROFILES_SCHEMA_ID, "profiles": rows}
            if scan.problems:
                bad = scan.problems
                document["skipped"] = [{"file": f, "valid": False, "problems": [why]} for f, why in bad]
            write_json(document)
        else:
            headers = ["NAME", "FAMILY", "VENDOR", "MODEL", "STROKE", "FORCE", "FROM"]
            print(
                table(
                    [
                        [
                            r["name"],
                            r["family"],
                            r["vendor"],
                            r["model"],
                            f"{r['stroke_mm']:g} mm",
                            f"{r['max_force_n']:g} N",
                            _origin(r["path"]),
                        ]
                        for r in rows
                    ],
                    headers,
                )
            )
        return EXIT_OK
    if args.action == "path":
        entries = [str(p) for p in profiles.search_path()] + ["<built-in>"]
        if args.json:
            write_json({"schema": PROFILES_SCHEMA_ID, "search_path": entries})
        else:
            print("\n".join(entries))
        return EXIT_OK
    if args.action == "schema":
        print(json.dumps(profiles.json_schema(), indent=2))
        return EXIT_OK
    if args.action == "show":
        if len(args.names) != 1:
            raise UsageError("show takes one profile name or file")
        profile = profiles.load_profile(args.names[0])
        plain = to_plain(profile.model_dump(mode="json"))
        if args.json:
            write_json({"schema": PROFILES_SCHEMA_ID, "profile": plain})
        else:
            from .toml_out import dumps

            # TOML, so that `show NAME > my.toml` is a file `validate` accepts and that loads back the same.
            print(f"# profile {profile.name}, read from {_origin(profile.path)}")
            print(dumps(plain), end="")
        return EXIT_OK
    if not args.names:
        raise UsageError("validate takes one or more profile files")
    results = []
    for path in args.names:
        problems = profiles.validate_file(path)
        results.append({"file": path, "valid": not problems, "problems": problems})
    if args.json:
        write_json({"schema": PROFILES_SCHEMA_ID, "validation": results})
    else:
        for r in results:
            if r["valid"]:
                print(f"{r['file']}: ok")
            for problem in r["problems"]:
                print(problem if problem.startswith(r["file"]) else f"{r['file']}: {problem}")
    return EXIT_OK if all(r["valid"] for r in results) else EXIT_FAILED
