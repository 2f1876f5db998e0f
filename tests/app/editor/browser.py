"""Driving the editor's page in headless Chromium (Playwright + Debian's chromium): the browser
test and the README screenshot (bench/editor.py) share these steps.

Never `playwright install`: the browser is the system's (`apt-get install -y chromium`).
"""
from __future__ import annotations

import re
import socket
from pathlib import Path

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync"]
VIEWPORT = {"width": 1280, "height": 800}


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def launch(playwright):
    """Headless Debian chromium (FileNotFoundError naming the install if it is missing)."""
    if not CHROMIUM.exists():
        raise FileNotFoundError(f"{CHROMIUM} is missing: apt-get install -y chromium (as root; "
                                "`make setup` does it)")
    return playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)


def mesh_status(version: int, resolution: int) -> re.Pattern:
    """The panel's status line once the scene shows that version at that resolution."""
    return re.compile(rf"mesh: version {int(version)}, {int(resolution)}\^3, \d+ faces")


def open_editor(page, url: str, resolution: int, timeout_s: float = 60.0) -> None:
    """Load the editor and wait until its first mesh (version 0, `resolution`) is shown."""
    page.goto(url)
    wait_for_mesh(page, 0, resolution, timeout_s)
    # hide notices (a headless browser gets "software WebGL rendering detected")
    page.add_style_tag(content=".mantine-Notification-root { display: none !important; }")


def wait_for_mesh(page, version: int, resolution: int, timeout_s: float = 60.0) -> str:
    """Wait until the server reports the mesh of document `version` at `resolution`."""
    line = page.get_by_text(mesh_status(version, resolution))
    line.wait_for(timeout=timeout_s * 1000)
    return line.inner_text()


def number_box(page, label: str):
    """The number box beside the slider labelled `label` (viser: label row, slider, box)."""
    return page.locator(f"xpath=//label[normalize-space()='{label}']"
                        "/ancestor::div[.//input[@type='text']][1]//input[@type='text']").first


def set_number(page, label: str, value: float) -> None:
    """Type a value into the number box of the slider labelled `label` (and press Enter)."""
    box = number_box(page, label)
    box.fill(str(value))
    box.press("Enter")


def click(page, name: str) -> None:
    page.locator("button", has_text=name).first.click()


def wait_for_message(page, pattern: str, timeout_s: float = 30.0) -> str:
    """Wait for the panel's message line to match `pattern` (a regex); returns its text."""
    line = page.get_by_text(re.compile(pattern))
    line.first.wait_for(timeout=timeout_s * 1000)
    return line.first.inner_text()
