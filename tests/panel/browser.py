"""Playwright driving Debian's chromium (``/usr/bin/chromium``), for the ``browser`` tests.

They run through scripts/run-browser-tests.sh, which installs chromium and Playwright and sets
``GRIPPERS_BROWSER_TESTS=1``; in the main suite they skip with a reason naming the script. Never a browser
that Playwright downloads: ``executable_path`` is the Debian package's.
"""

from __future__ import annotations

import os
from typing import Any

import pytest

ENV = "GRIPPERS_BROWSER_TESTS"
CHROMIUM = os.environ.get("GRIPPERS_CHROMIUM", "/usr/bin/chromium")
SKIP_REASON = (
    f"browser tests: run scripts/run-browser-tests.sh (sets {ENV}=1; Debian's chromium and Playwright)"
)

browser_only = [
    pytest.mark.browser,
    pytest.mark.skipif(os.environ.get(ENV) != "1", reason=SKIP_REASON),
]


class Tab:
    """A page of the panel, with the console errors and page errors it produced."""

    def __init__(self, page: Any) -> None:
        self.page = page
        self.errors: list[str] = []
        page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: self.errors.append(str(e)))

    def card(self, name: str) -> Any:
        return self.page.get_by_role("region", name=name, exact=True)

    def readout(self, name: str, label: str) -> Any:
        return self.card(name).get_by_label(label, exact=True)

    def press(self, name: str, button: str) -> None:
        self.card(name).get_by_role("button", name=button, exact=True).click()

    def fill(self, name: str, label: str, value: float) -> None:
        self.card(name).get_by_label(label, exact=True).fill(str(value))

    def alert(self, name: str) -> Any:
        return self.card(name).get_by_role("alert")
