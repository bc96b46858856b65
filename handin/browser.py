"""Finding a Chromium-based browser to print with, and driving it headless and offline.

Searched in order: an explicit path or command, ``$HW4_BROWSER``, chromium / google-chrome on the
PATH, a browser installed by Playwright (``~/.cache/ms-playwright``), the usual macOS locations.
In Google Colab, :func:`ensure_browser` installs Chromium through Playwright the first time.
"""

from __future__ import annotations

import glob
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

__all__ = ["BrowserNotFoundError", "PdfExportError", "CHROMIUM_FLAGS", "find_browser", "ensure_browser",
           "in_colab", "run_chromium", "print_playwright"]

BROWSER_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome", "msedge")
MAC_BROWSERS = ("/Applications/Google Chrome.app/Contents/MacOS/Google Chrome",
                "/Applications/Chromium.app/Contents/MacOS/Chromium")
BROWSER_HELP = ("no Chromium-based browser found. Install one:\n"
                "  Debian/Ubuntu:       apt-get install chromium\n"
                "  anywhere, incl. Colab: pip install playwright && python -m playwright install chromium\n"
                "or pass its path with --browser (or set HW4_BROWSER).")
# Flags that keep a headless Chromium quiet, offline and printable as root in a container.
CHROMIUM_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run", "--no-default-browser-check",
    "--disable-extensions", "--disable-default-apps", "--mute-audio", "--hide-scrollbars",
    "--disable-dev-shm-usage", "--allow-file-access-from-files",
    # Nothing may wait on the network: host names fail to resolve at once, and any request (an
    # IP address in a student's HTML output too) goes to a proxy port that refuses connections.
    "--host-resolver-rules=MAP * ~NOTFOUND", "--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>",
    "--disable-domain-reliability", "--disable-client-side-phishing-detection",
)


class BrowserNotFoundError(RuntimeError):
    """No Chromium-based browser could be found; the message says how to install one."""


class PdfExportError(RuntimeError):
    """The browser ran but produced no PDF; the message carries the end of its error output."""


def in_colab() -> bool:
    try:
        return importlib.util.find_spec("google.colab") is not None
    except (ImportError, ValueError):
        return False


def _playwright_browsers() -> list[str]:
    root = Path(os.environ.get("PLAYWRIGHT_BROWSERS_PATH") or Path.home() / ".cache" / "ms-playwright")
    # The full browser first: the headless shell prints too, but lacks some fonts on minimal systems.
    patterns = ("chromium-*/chrome-linux*/chrome",
                "chromium_headless_shell-*/chrome-linux*/headless_shell",
                "chromium_headless_shell-*/chrome-headless-shell-linux*/chrome-headless-shell",
                "chromium-*/chrome-mac*/Chromium.app/Contents/MacOS/Chromium")
    found = []
    for pattern in patterns:
        found += sorted(glob.glob(str(root / pattern)), reverse=True)  # newest revision first
    return found


def find_browser(browser: str | None = None) -> str:
    """Path of a Chromium-based browser able to print to PDF.

    Parameters
    ----------
    browser : str, optional
        A path or a command name to use instead of searching. Without it, ``$HW4_BROWSER``,
        then chromium / chromium-browser / google-chrome(-stable) on the PATH, then a browser
        installed by Playwright (``~/.cache/ms-playwright``), then the usual macOS locations.

    Raises
    ------
    BrowserNotFoundError
        When nothing is found; the message says how to install a browser.
    """
    if browser:
        path = browser if os.path.isfile(browser) and os.access(browser, os.X_OK) else shutil.which(browser)
        if not path:
            raise BrowserNotFoundError(f"browser: expected an executable path or command, got {browser!r}")
        return path
    env = os.environ.get("HW4_BROWSER")
    if env:
        return find_browser(env)
    for name in BROWSER_NAMES:
        if path := shutil.which(name):
            return path
    for path in _playwright_browsers() + list(MAC_BROWSERS):
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return path
    raise BrowserNotFoundError(BROWSER_HELP)


def ensure_browser(*, install: bool | None = None) -> str:
    """Like :func:`find_browser`, but installs Chromium through Playwright when none is found.

    Parameters
    ----------
    install : bool, optional
        Install when missing. By default only in Google Colab, where students cannot be asked
        to run apt-get; elsewhere a missing browser raises :class:`BrowserNotFoundError`.
    """
    try:
        return find_browser()
    except BrowserNotFoundError:
        if not (in_colab() if install is None else install):
            raise
    if importlib.util.find_spec("playwright") is None:
        subprocess.run([sys.executable, "-m", "pip", "install", "-q", "playwright"], check=True)
    deps = ["--with-deps"] if in_colab() else []
    subprocess.run([sys.executable, "-m", "playwright", "install", *deps, "chromium"], check=True)
    return find_browser()


def run_chromium(browser: str, url: str, out: Path, profile: str, timeout: float) -> subprocess.CompletedProcess:
    cmd = [browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--no-pdf-header-footer",
           "--print-to-pdf-no-header", f"--print-to-pdf={out}", "--run-all-compositor-stages-before-draw",
           # Virtual time runs MathJax's timers to completion before printing, without real waiting.
           "--virtual-time-budget=60000", url]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        # Chromium leaves helper processes behind; they share the session we started.
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise PdfExportError(f"the browser did not finish printing within {timeout:g} s "
                             f"(raise --timeout, or check {browser} runs headless)") from None
    return subprocess.CompletedProcess(cmd, proc.returncode, stdout, stderr)


def print_playwright(browser: str, url: str, out: Path, timeout: float) -> None:
    from playwright.sync_api import sync_playwright

    args = [f for f in CHROMIUM_FLAGS if f != "--headless"]
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=browser, headless=True, args=args, timeout=timeout * 1000)
        try:
            page = b.new_page()
            page.goto(url, wait_until="load", timeout=timeout * 1000)
            page.wait_for_function("document.documentElement.getAttribute('data-hw4-math') === 'done'",
                                   timeout=timeout * 1000)
            page.pdf(path=str(out), prefer_css_page_size=True, print_background=True)
        finally:
            b.close()
