"""A Gradescope-ready PDF of the student's notebooks, made without TeX and without internet.

The notebooks are joined into one document in manifest order, turned into HTML by nbconvert
(:mod:`handin.html`, with a cover from :mod:`handin.cover`) and printed by a headless Chromium
(:mod:`handin.browser`); math is typeset by a local MathJax 2 (:mod:`handin.mathjax`) and the
browser cannot reach the network at all.  What nbconvert's own PDF routes get wrong for this
homework is fixed on the way: every question starts a new page, every output has one printable
form, long code lines and outputs wrap instead of being cut.

Public API: :func:`build_pdf`, :func:`html_to_pdf`, :func:`main` (``python -m handin pdf``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from .browser import BrowserNotFoundError, PdfExportError, ensure_browser, find_browser, print_playwright, run_chromium
from .code_zip import build_code_zip
from .html import notebooks_to_html
from .mathjax import MathJaxNotFoundError

__all__ = ["build_pdf", "html_to_pdf", "add_arguments", "main"]


def html_to_pdf(html_path, out, *, browser: str | None = None, timeout: float = 180.0,
                engine: str = "cli") -> Path:
    """Print an HTML file to PDF with a headless Chromium, offline.

    Parameters
    ----------
    html_path : str or Path
        The page to print (local images and scripts only: no host name resolves).
    out : str or Path
        The PDF to write.
    browser : str, optional
        Browser path or command (default :func:`find_browser`).
    timeout : float
        Seconds before the browser is stopped.
    engine : {"cli", "playwright"}
        "cli" runs ``chromium --print-to-pdf`` with a virtual-time budget: MathJax's timers run
        to completion before printing without real waiting (measured: a budget of 10 ms prints
        blank math, 500 ms is enough for 300 formulas; 60 s is used). "playwright" drives the same
        browser through Playwright and waits for MathJax's own end signal; it needs
        ``pip install playwright`` and is slower, since MathJax's pauses then take real time.

    Raises
    ------
    BrowserNotFoundError, PdfExportError
    """
    if engine not in ("cli", "playwright"):
        raise ValueError(f"engine: expected 'cli' or 'playwright', got {engine!r}")
    timeout = float(timeout)
    if not timeout > 0:
        raise ValueError(f"timeout: expected a positive number of seconds, got {timeout!r}")
    browser = find_browser(browser)
    out = Path(out).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    url = Path(html_path).resolve().as_uri()
    tmp_out = out.with_name(out.name + ".part")
    tmp_out.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="hw4-chromium-") as profile:
        if engine == "playwright":
            try:
                print_playwright(browser, url, tmp_out, timeout)
            except Exception as exc:
                raise PdfExportError(f"printing with Playwright and {browser} failed: {exc}") from exc
            detail = ""
        else:
            proc = run_chromium(browser, url, tmp_out, profile, timeout)
            detail = "\n".join(proc.stderr.strip().splitlines()[-15:])
    if not tmp_out.is_file() or tmp_out.read_bytes()[:5] != b"%PDF-":
        tmp_out.unlink(missing_ok=True)
        raise PdfExportError(f"{browser} wrote no PDF. Its last messages:\n{detail}")
    tmp_out.replace(out)
    return out


def build_pdf(notebooks, out, *, name: str | None = None, browser: str | None = None,
              timeout: float = 180.0, engine: str = "cli", keep_html: bool = False,
              already_reported=()) -> Path:
    """Export the student's notebooks to one Gradescope-ready PDF.

    Parameters
    ----------
    notebooks : str or Path or list of str/Path
        A folder holding the homework notebooks (``q2_eightpoint.ipynb`` ...; other notebooks
        there are left out with a warning) or a list of notebook files (all are included, the
        homework ones first in manifest order).
    out : str or Path
        The PDF to write; its folder is created.
    name : str, optional
        The student's name for the cover (default: ``STUDENT_NAME`` from the notebooks).
    browser : str, optional
        Chromium path or command (default :func:`find_browser`).
    timeout : float
        Seconds allowed to the browser.
    engine : {"cli", "playwright"}
        How the browser is driven, see :func:`html_to_pdf`.
    keep_html : bool
        Also keep the printed HTML beside the PDF (``out`` with suffix ``.html``), for debugging.
    already_reported : iterable of str
        Warnings the caller has already shown (the code zip's report lists the same files left
        out): these are not printed again.

    Returns
    -------
    Path
        The PDF written. Files left out are reported on stderr, each once.

    Raises
    ------
    ValueError
        When ``notebooks`` holds no readable notebook or names a missing file.
    BrowserNotFoundError, MathJaxNotFoundError, PdfExportError
        With a message saying how to fix it.
    """
    out = Path(out)
    if out.suffix.lower() != ".pdf":
        raise ValueError(f"out: expected a path ending in .pdf, got {str(out)!r}")
    browser = find_browser(browser) if browser else ensure_browser()  # fail before the slower HTML step
    page, warnings = notebooks_to_html(notebooks, name=name)
    said = set(already_reported)
    for w in dict.fromkeys(warnings):
        if w not in said:
            print(f"warning: {w}", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="hw4-pdf-") as tmp:
        html_path = Path(tmp) / "hw4.html"
        html_path.write_text(page, encoding="utf-8")
        if keep_html:
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(html_path, out.with_suffix(".html"))
        return html_to_pdf(html_path, out, browser=browser, timeout=timeout, engine=engine)


# ----------------------------------------------------------------------------- command line

def _default_source() -> Path:
    local = Path("notebooks")
    return local if local.is_dir() and any(local.glob("q*.ipynb")) else Path(".")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``python -m handin pdf [NOTEBOOK_DIR or files...] --out hw4.pdf [--name NAME]
    [--code-zip hw4_code.zip]``."""
    p.add_argument("notebooks", nargs="*", type=Path,
                   help="a folder of notebooks or notebook files (default: ./notebooks if present, else .)")
    p.add_argument("--out", type=Path, default=Path("hw4.pdf"), help="PDF to write (default hw4.pdf)")
    p.add_argument("--name", help="your name for the cover (default: STUDENT_NAME in the notebooks)")
    p.add_argument("--code-zip", type=Path, metavar="ZIP", help="also write the code zip for the autograder")
    p.add_argument("--max-mb", type=float, default=50.0, help="size cap of the code zip in MB (default 50)")
    p.add_argument("--browser", help="Chromium/Chrome executable (default: searched)")
    p.add_argument("--timeout", type=float, default=180.0, help="seconds allowed to the browser (default 180)")
    p.add_argument("--engine", choices=("cli", "playwright"), default="cli",
                   help="drive the browser from its command line (default) or through Playwright")
    p.add_argument("--keep-html", action="store_true", help="keep the printed HTML beside the PDF")


def main(args: argparse.Namespace) -> int:
    """Run ``python -m handin pdf``: 0 done, 1 code zip over its size cap, 2 nothing written."""
    source = args.notebooks or _default_source()
    if isinstance(source, list) and len(source) == 1:
        source = source[0]
    try:
        said = []
        if args.code_zip:
            report = build_code_zip(source, args.code_zip, max_mb=args.max_mb)
            print(report)
            said = report.warnings  # the PDF leaves out the same files: one warning each is enough
        pdf = build_pdf(source, args.out, name=args.name, browser=args.browser, timeout=args.timeout,
                        engine=args.engine, keep_html=args.keep_html, already_reported=said)
    except (ValueError, BrowserNotFoundError, MathJaxNotFoundError, PdfExportError,
            subprocess.CalledProcessError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {pdf}")
    return 1 if args.code_zip and report.too_large else 0
