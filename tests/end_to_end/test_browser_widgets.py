"""One real browser: epipolarMatchGUI in JupyterLab, clicked in headless Chromium via Playwright.

What it proves that the Python-side tests cannot: the plotly FigureWidget renders in JupyterLab,
a mouse click on image 1 reaches the kernel, the kernel's answer (the epipolar line of the
clicked pixel) is drawn on image 2, and the static PNG under the widget is redrawn and saved
with the notebook (so its PDF carries the picks).

Needs, besides the kit's own dependencies: ``pip install jupyterlab playwright anywidget`` and
a Chromium (Debian: ``apt-get install chromium``; another path via $HW4_CHROMIUM).  Playwright's
own browser download is not used.  Skips, saying what is missing, otherwise.

The server listens on 127.0.0.1 only, on a free port, with a random token, is wrapped in
``timeout`` when the system has one, and is always shut down (REST shutdown, then its process
group) even when the test fails.
"""

from __future__ import annotations

import base64
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from core.paths import KIT_ROOT
from browser import CHROMIUM_ARGS, chromium_path

pytestmark = [pytest.mark.browser, pytest.mark.slow]

W, H = 160, 120
SERVER_LIFETIME_S = 300  # hard cap on the server, whatever happens to this process
STEP_TIMEOUT_MS = 120_000
def require_browser_stack() -> str:
    path = chromium_path()
    if path is None:
        pytest.skip("no Chromium found (apt-get install chromium, or set HW4_CHROMIUM)")
    pytest.importorskip("playwright.sync_api", reason="playwright not installed "
                        "(pip install playwright; its browser download is not needed)")
    pytest.importorskip("jupyterlab", reason="jupyterlab not installed (pip install jupyterlab)")
    pytest.importorskip("anywidget", reason="anywidget not installed: plotly's FigureWidget, "
                        "the clickable view, needs it (pip install anywidget)")
    return path


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def scene_F() -> np.ndarray:
    """F of two W x H cameras side by side, one turned a little: lines cross image 2."""
    from scenes.cameras import intrinsics, rotation_about

    K = intrinsics(100.0, W / 2, H / 2)
    R = rotation_about([0.2, 1.0, 0.1], 0.08)
    t = np.array([1.0, 0.15, 0.05])
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return np.linalg.inv(K).T @ tx @ R @ np.linalg.inv(K)


def write_notebook(path: Path, F: np.ndarray) -> None:
    import nbformat

    code = f"""import numpy as np
from starter.interactive import epipolarMatchGUI, epipolar_line
rng = np.random.default_rng(0)
I1, I2 = rng.random(({H}, {W})), (rng.random(({H}, {W}, 3)) * 255).astype(np.uint8)
F = np.array({F.tolist()!r})

def on_the_line(im1, im2, F, x1, y1):
    line = epipolar_line(F, x1, y1)
    p = np.array([x1, y1, 1.0])
    return p[:2] - line[:2] * (line @ p)

session = epipolarMatchGUI(I1, I2, F, on_the_line)"""
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(code)])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                 "language": "python"}
    nbformat.write(nb, path)


def _request(url: str, token: str, method: str = "GET", timeout: float = 5.0) -> int:
    req = urllib.request.Request(url, method=method, data=b"" if method == "POST" else None,
                                 headers={"Authorization": f"token {token}"})
    with urllib.request.urlopen(req, timeout=timeout) as resp:
        return resp.status


@pytest.fixture
def jupyterlab(tmp_path):
    """A JupyterLab server on 127.0.0.1 serving tmp_path; yields (base_url, token, root)."""
    require_browser_stack()
    port, token = free_port(), secrets.token_hex(16)
    root = tmp_path / "root"
    root.mkdir()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(KIT_ROOT), env.get("PYTHONPATH")]))
    for var, sub in [("JUPYTER_RUNTIME_DIR", "runtime"), ("JUPYTER_CONFIG_DIR", "config"),
                     ("JUPYTERLAB_SETTINGS_DIR", "settings"),
                     ("JUPYTERLAB_WORKSPACES_DIR", "workspaces")]:
        env[var] = str(tmp_path / sub)
    (tmp_path / "config").mkdir()
    # nothing to fetch from outside: no news feed, no update check
    (tmp_path / "config" / "jupyter_lab_config.json").write_text(json.dumps({"LabApp": {
        "news_url": None, "check_for_updates_class": "jupyterlab.NeverCheckForUpdate"}}))
    cmd = [sys.executable, "-m", "jupyterlab", "--no-browser", "--ip=127.0.0.1",
           f"--port={port}", "--ServerApp.port_retries=0", f"--IdentityProvider.token={token}",
           f"--ServerApp.root_dir={root}", "--LabApp.expose_app_in_browser=True"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.append("--allow-root")
    if shutil.which("timeout"):
        cmd = [shutil.which("timeout"), "-k", "10", str(SERVER_LIFETIME_S)] + cmd
    log = open(tmp_path / "jupyterlab.log", "wb")
    proc = subprocess.Popen(cmd, cwd=root, env=env, stdout=log, stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL, start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90
        while True:
            if proc.poll() is not None:
                pytest.fail(f"JupyterLab exited early:\n{(tmp_path / 'jupyterlab.log').read_text()}")
            try:
                if _request(f"{base}/api/status", token) == 200:
                    break
            except OSError:
                pass
            if time.monotonic() > deadline:
                pytest.fail("JupyterLab did not answer within 90 s")
            time.sleep(0.5)
        yield base, token, root
    finally:
        try:  # a clean shutdown also stops the kernel it started
            _request(f"{base}/api/shutdown", token, method="POST")
            proc.wait(timeout=20)
        except Exception:
            pass
        if proc.poll() is None:
            for sig, wait in ((signal.SIGTERM, 10), (signal.SIGKILL, 10)):
                try:
                    os.killpg(proc.pid, sig)
                    proc.wait(timeout=wait)
                    break
                except (ProcessLookupError, subprocess.TimeoutExpired):
                    continue
        log.close()


def _pick_state(page) -> dict | None:
    return page.evaluate("""() => {
        const el = document.querySelector('.hw4-pick');
        return el ? Object.assign({}, el.dataset) : null;
    }""")


def _shapes_in_image2(page) -> list[dict]:
    """Bounding boxes of the layout shapes (epipolar lines) and of image 2's plot area."""
    return page.evaluate("""() => {
        const area = document.querySelector('rect.nsewdrag[data-subplot="x2y2"]')
                                 .getBoundingClientRect();
        return Array.from(document.querySelectorAll('.shapelayer path')).map(p => {
            const b = p.getBoundingClientRect();
            return {left: b.left, right: b.right, top: b.top, bottom: b.bottom,
                    area: {left: area.left, right: area.right, top: area.top,
                           bottom: area.bottom}};
        });
    }""")


def _click_and_wait(page, box, fx, fy, previous: dict | None) -> dict:
    """Click image 1 at a fraction (fx, fy) of its plot area; return the new pick's state."""
    x, y = box["x"] + fx * box["width"], box["y"] + fy * box["height"]
    for _attempt in range(2):  # one retry: a first click can land before plotly's hover is live
        page.mouse.move(x, y)
        page.wait_for_timeout(300)
        page.mouse.click(x, y)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            state = _pick_state(page)
            if state is not None and state != previous:
                return state
            page.wait_for_timeout(200)
    pytest.fail(f"no pick after clicking image 1 at {fx:.2f}, {fy:.2f}")


def _snapshot_src(page) -> str:
    imgs = page.query_selector_all(".jp-OutputArea-output img")
    assert len(imgs) == 1, f"expected one static PNG under the widget, found {len(imgs)}"
    return imgs[0].get_attribute("src")


def test_clicking_image_1_draws_its_epipolar_line_in_image_2(jupyterlab):
    import nbformat
    from playwright.sync_api import sync_playwright

    base, token, root = jupyterlab
    F = scene_F()
    write_notebook(root / "epipolar.ipynb", F)
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium_path(), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1300, "height": 1000})
            page.set_default_timeout(STEP_TIMEOUT_MS)
            page.goto(f"{base}/lab/tree/epipolar.ipynb?token={token}")
            page.wait_for_function("""() => {
                const w = window.jupyterapp && window.jupyterapp.shell.currentWidget;
                const k = w && w.sessionContext && w.sessionContext.session
                          && w.sessionContext.session.kernel;
                return k && k.status === 'idle';
            }""")
            page.evaluate("window.jupyterapp.commands.execute('notebook:run-all-cells')")
            page.wait_for_selector('rect.nsewdrag[data-subplot="xy"]')
            page.wait_for_selector('rect.nsewdrag[data-subplot="x2y2"]')
            page.wait_for_selector(".hw4-status")
            page.wait_for_selector(".jp-OutputArea-output img")
            first_png = _snapshot_src(page)
            assert _shapes_in_image2(page) == []

            box = page.query_selector('rect.nsewdrag[data-subplot="xy"]').bounding_box()
            states = []
            for fx, fy in [(0.30, 0.40), (0.72, 0.65)]:
                state = _click_and_wait(page, box, fx, fy, states[-1] if states else None)
                states.append(state)
                # the kernel got the pixel under the mouse (image spans -0.5 .. W - 0.5)
                x1, y1 = int(state["x1"]), int(state["y1"])
                assert abs(x1 - (fx * W - 0.5)) <= 1.5 and abs(y1 - (fy * H - 0.5)) <= 1.5
                # ... and answered with the line F x1, whose ends are drawn on image 2
                line = np.array([float(v) for v in state["line"].split(",")])
                expected = F @ [x1, y1, 1.0]
                assert np.allclose(np.cross(line, expected), 0,
                                   atol=1e-6 * np.linalg.norm(expected))
                ends = np.array([float(v) for v in state["ends"].split(",")]).reshape(2, 2)
                for x, y in ends:
                    assert abs(line @ [x, y, 1.0]) < 1e-4
                match = np.array([float(v) for v in state["match"].split(",")])
                assert abs(line @ [*match, 1.0]) < 1e-4
                # The pick's state is set before plotly redraws the figure: on a loaded machine
                # the new line may come a moment later (CI once counted 1 of 2 lines here).
                deadline = time.monotonic() + 30
                while len(shapes := _shapes_in_image2(page)) != len(states) and time.monotonic() < deadline:
                    page.wait_for_timeout(200)
                assert len(shapes) == len(states)
                s = shapes[-1]
                a = s["area"]
                assert a["left"] - 2 <= s["left"] and s["right"] <= a["right"] + 2
                assert a["top"] - 2 <= s["top"] and s["bottom"] <= a["bottom"] + 2
                # a line that crosses image 2 spans it from border to border
                assert max(s["right"] - s["left"], s["bottom"] - s["top"]) > \
                    0.5 * min(a["right"] - a["left"], a["bottom"] - a["top"])
            assert states[0]["line"] != states[1]["line"]

            # the static PNG under the widget follows the picks, and is what gets saved.  Each pick
            # redraws it, the last one possibly a moment after its line (a CI run once saved the
            # second pick's PNG while the first's was taken as the latest): wait until it changed
            # and then held still for 1.5 s.
            deadline = time.monotonic() + 30
            latest_png, still_since = first_png, time.monotonic()
            while time.monotonic() < deadline:
                page.wait_for_timeout(200)
                now = _snapshot_src(page)
                if now != latest_png:
                    latest_png, still_since = now, time.monotonic()
                elif latest_png != first_png and time.monotonic() - still_since > 1.5:
                    break
            assert latest_png != first_png
            page.evaluate("window.jupyterapp.commands.execute('docmanager:save')")
            deadline = time.monotonic() + 30
            saved = None
            while time.monotonic() < deadline:
                nb = nbformat.read(root / "epipolar.ipynb", as_version=4)
                pngs = [o["data"]["image/png"] for o in nb.cells[0].get("outputs", [])
                        if "image/png" in o.get("data", {})]
                if pngs:
                    saved = pngs[-1]
                    if _snapshot_src(page).endswith(saved.strip()):
                        break
                page.wait_for_timeout(300)
            assert saved is not None, "the saved notebook has no PNG output"
            assert _snapshot_src(page).endswith(saved.strip()), "the saved PNG is not the one shown"
            assert base64.b64decode(saved)[:4] == b"\x89PNG"
        finally:
            browser.close()
