"""The browser and the PDF tools the tests drive: Debian's chromium, MathJax, poppler.
"""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest
from handin import browser, mathjax


CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync"]


def chromium_path() -> str | None:
    for candidate in (os.environ.get("HW4_CHROMIUM"), shutil.which("chromium"),
                      shutil.which("chromium-browser"), "/usr/bin/chromium"):
        if candidate and os.path.exists(candidate):
            return candidate
    return None


def browser_or_skip() -> str:
    try:
        return browser.find_browser()
    except browser.BrowserNotFoundError:
        pytest.skip("no Chromium-based browser: apt-get install chromium, or "
                    "pip install playwright && python -m playwright install chromium")


def mathjax_or_skip():
    try:
        return mathjax.find_mathjax()
    except mathjax.MathJaxNotFoundError:
        pytest.skip("no local MathJax: pip install jupyter-server-mathjax (or apt-get install libjs-mathjax)")


def poppler_or_skip():
    if not (shutil.which("pdftotext") and shutil.which("pdfimages")):
        pytest.skip("poppler-utils (pdftotext, pdfimages) not installed: apt-get install poppler-utils")


def pages_of(path) -> list[str]:
    text = subprocess.run(["pdftotext", "-enc", "UTF-8", str(path), "-"], check=True,
                          capture_output=True, text=True).stdout
    return text.split("\f")[:-1] if text.endswith("\f") else text.split("\f")


def first_line(page: str) -> str:
    return next((line.strip() for line in page.splitlines() if line.strip()), "")
